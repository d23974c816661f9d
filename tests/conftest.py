"""Test settings: hypothesis profiles (deterministic under CI)."""

import os

from hypothesis import HealthCheck, settings

settings.register_profile(
    "ci", derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile("dev", deadline=None, max_examples=100)
settings.load_profile("ci" if os.environ.get("CI") else "dev")


def pytest_collection_modifyitems(config, items):
    """Start the pure-Python twin's run of the odometry tests now, beside the suite, when its
    test is selected (``test_odometry_python.start_twin_run``)."""
    if any(item.name == "test_the_odometry_tests_pass_on_the_twin" for item in items):
        from test_odometry_python import start_twin_run

        start_twin_run()


def pytest_sessionfinish(session, exitstatus):
    """Stop the twin's run if the session ended before its test read it (``-x``, Ctrl-C)."""
    module = __import__("sys").modules.get("test_odometry_python")
    run = getattr(module, "_TWIN", {}).get("run") if module else None
    if run is not None and run.poll() is None:
        run.kill()
        run.communicate()
