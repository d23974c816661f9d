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
    """The pure-Python twin's run of the odometry tests (``test_odometry_python``) goes first:
    its test runs them in a process of its own, so that under pytest-xdist it works beside
    the rest of the suite rather than after it. Collecting starts no process."""
    twins = [item for item in items if item.name == TWIN_TEST]
    items[:] = twins + [item for item in items if item.name != TWIN_TEST]
