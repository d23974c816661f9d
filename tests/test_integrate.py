"""One integration step: seed 000's Euler update, rk2, and the exact arc."""

import math

import pytest

from diffdrive import Pose, Twist, integrate, se2


def test_euler_steps_match_seed_000_by_hand():
    # x(t+h) = x + h v cos(theta); y(t+h) = y + h v sin(theta); theta(t+h) = theta + h omega.
    h, v, omega = 0.1, 1.0, 1.0
    pose = integrate.step(Pose(), Twist(v, 0.0, omega), h, "euler")
    assert pose == Pose(0.1, 0.0, 0.1)
    pose = integrate.step(pose, Twist(v, 0.0, omega), h, "euler")
    assert pose.x == pytest.approx(0.1 + 0.1 * math.cos(0.1), abs=1e-15)
    assert pose.y == pytest.approx(0.1 * math.sin(0.1), abs=1e-15)
    assert pose.theta == pytest.approx(0.2, abs=1e-15)


def test_rk2_uses_the_mid_step_heading():
    pose = integrate.step(Pose(0, 0, 0.4), Twist(2.0, 0.0, 1.0), 0.2, "rk2")
    assert pose.x == pytest.approx(0.4 * math.cos(0.5), abs=1e-15)
    assert pose.y == pytest.approx(0.4 * math.sin(0.5), abs=1e-15)
    assert pose.theta == pytest.approx(0.6, abs=1e-15)


def test_exact_is_the_exponential():
    start, twist = Pose(1.0, 2.0, 0.5), Twist(1.0, 0.2, 0.8)
    assert integrate.step(start, twist, 0.3) == start.compose(se2.exp(twist, 0.3))


@pytest.mark.parametrize("method", integrate.METHODS)
def test_methods_agree_on_a_straight_line(method):
    assert integrate.step(Pose(), Twist(1.0), 2.0, method) == Pose(2.0, 0.0, 0.0)


def test_unknown_method_lists_the_choices():
    with pytest.raises(ValueError, match="method must be one of euler, rk2, exact; got 'rk4'"):
        integrate.step(Pose(), Twist(1.0), 0.1, "rk4")  # type: ignore[arg-type]
