"""Test settings: hypothesis profiles (deterministic under CI)."""

import os

from hypothesis import HealthCheck, settings

settings.register_profile(
    "ci", derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile("dev", deadline=None, max_examples=100)
settings.load_profile("ci" if os.environ.get("CI") else "dev")

TWIN_TEST = "test_the_odometry_tests_pass_on_the_twin"


def pytest_collection_modifyitems(config, items):
    """The pure-Python twin's run of the odometry tests (``test_odometry_python``) goes first,
    so that it runs in a process of its own beside the rest of the suite instead of after it.
    In one process the run starts now; under pytest-xdist every worker collects every test,
    so the worker given the test (the first one, as it comes first) starts the run itself."""
    twins = [item for item in items if item.name == TWIN_TEST]
    if not twins:
        return
    items[:] = twins + [item for item in items if item.name != TWIN_TEST]
    if "PYTEST_XDIST_WORKER" not in os.environ:
        from test_odometry_python import start_twin_run

        start_twin_run()


def pytest_sessionfinish(session, exitstatus):
    """Stop the twin's run if the session ended before its test read it (``-x``, Ctrl-C)."""
    module = __import__("sys").modules.get("test_odometry_python")
    run = getattr(module, "_TWIN", {}).get("run") if module else None
    if run is not None and run.returncode is None:
        run.kill()
        run.communicate()
