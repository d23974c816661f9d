"""Calibration while the robot drives: recursive least squares on the kinematics' linear form.

Over an interval in which the wheels turn ``dphi_l``, ``dphi_r`` (rad) and a reference (motion
capture, scan matching, visual odometry) measures the robot's motion, a distance ``s`` and a
turn ``dtheta`` (the SE(2) logarithm of the relative pose), the kinematics are linear in two
pairs of unknowns (Antonelli, Chiaverini and Fusco, IEEE T-RO 21(5), 2005; Censi, Franchi,
Marchionni and Oriolo, IEEE T-RO 29(2), 2013):

    s      = r_l dphi_l / 2 + r_r dphi_r / 2            in (r_l, r_r)
    dtheta = c_r dphi_r - c_l dphi_l,  c = r / track     in (c_l, c_r)

``OnlineCalibrator`` keeps a recursive least-squares estimate of each pair, starting from the
nominal robot with a relative prior ``prior_sigma``, with measurement noise ``sigma_distance``
(m) and ``sigma_turn`` (rad) per measurement. A measurement spans ``window`` updates: their
wheel increments summed and their relative poses composed. Over one control cycle the encoder
ticks' rounding and the reference's jitter are large against the motion, and, being in the
regressors too, they bias the fit: streaming the OptiOdom circular experiments one 50 ms cycle
at a time leaves the track 1.9 % and 12.9 % from whole-path least squares, 20 cycles at a time
0.23 % and 0.15 % (``examples/online_calibration.py``).

Each measurement is gated first: its innovation squared over its predicted variance is
chi-square with one degree of freedom, and past ``gate`` (10.83: 0.1 % of good measurements)
it is left out and counted (a jump of the reference, a slip). The defaults suit a motion-
capture reference and 20 cycles of 50 ms; noise set far below the real one makes the gate
refuse good measurements, and an estimate with many refused is not to be trusted.

The track width is ``(r_l + r_r) / (c_l + c_r)``; the parameters' covariance comes from the two
estimates' through that map. With the same data, window and prior, the estimate equals the
batch weighted least squares of all the measurements at once (``batch_solution``).
"""

from __future__ import annotations

import numpy as np

from diffdrive import batch
from diffdrive._validate import finite, positive, whole
from diffdrive.model import DiffDrive
from diffdrive.types import Pose

__all__ = ["OnlineCalibrator"]

GATE = 10.83  # chi-square, one degree of freedom: P(score > 10.83) = 0.001


class OnlineCalibrator:
    """Recursive least-squares calibration of a ``DiffDrive`` (see the module)."""

    def __init__(
        self,
        nominal: DiffDrive,
        *,
        sigma_distance: float = 3e-3,
        sigma_turn: float = 2e-2,
        prior_sigma: float = 0.1,
        gate: float = GATE,
        window: int = 20,
    ) -> None:
        if not isinstance(nominal, DiffDrive):
            raise TypeError(f"nominal must be a DiffDrive, got {type(nominal).__name__}")
        self.nominal = nominal
        self.noise = (
            _variance("sigma_distance", sigma_distance),
            _variance("sigma_turn", sigma_turn),
        )
        self.gate = positive("gate", gate)
        prior = positive("prior_sigma", prior_sigma)
        radii = np.array([nominal.left_wheel_radius, nominal.right_wheel_radius])
        self.estimates = [radii.copy(), radii / nominal.track_width]
        with np.errstate(over="ignore", under="ignore"):  # refused below, not warned about
            self.covariances = [np.diag((prior * e) ** 2) for e in self.estimates]
        for covariance in self.covariances:
            if not (np.all(np.isfinite(covariance)) and np.all(np.diag(covariance) > 0)):
                raise ValueError(
                    f"prior_sigma {prior_sigma!r} gives a prior variance that is not a finite "
                    "number > 0 for this robot"
                )
        # The prior, kept: batch_solution starts from it, as this estimator did.
        self._prior = ([e.copy() for e in self.estimates], [p.copy() for p in self.covariances])
        self.window = whole("window", window, smallest=1)
        self.accepted = 0  # measurements, each of `window` updates
        self.rejected = 0
        self._gathered = (np.zeros(2), np.zeros(3), 0)  # wheels, relative pose, updates

    def update(self, left: float, right: float, relative_pose: object) -> bool:
        """One interval: wheel-angle increments (rad) and the reference's relative pose
        ``(dx, dy, dtheta)`` in the frame at the interval's start. Every ``window``-th update
        completes a measurement; returns False when the gate refused it, True otherwise. A
        refused input (not finite, or one whose window or estimate would overflow) raises
        ``ValueError`` and changes nothing."""
        left, right = finite("left", left), finite("right", right)
        try:
            pose = Pose.coerce(relative_pose, "relative_pose").to_array()
        except (TypeError, ValueError, OverflowError):
            pose = np.full(1, np.nan)
        if pose.shape != (3,) or not np.all(np.isfinite(pose)):
            raise ValueError(f"relative_pose must be 3 finite numbers, got {relative_pose!r}")
        wheels, motion, count = self._gathered
        with np.errstate(over="ignore", invalid="ignore"):  # refused below, not warned about
            wheels, motion = wheels + np.array([left, right]), batch.compose(motion, pose)
        if not (np.all(np.isfinite(wheels)) and np.all(np.isfinite(motion))):
            raise ValueError(
                "the window's summed wheel increments or composed poses overflow; refused, "
                "nothing changed"
            )
        if count + 1 < self.window:
            self._gathered = (wheels, motion, count + 1)
            return True
        accepted = self._measure(float(wheels[0]), float(wheels[1]), motion)
        self._gathered = (np.zeros(2), np.zeros(3), 0)
        return accepted

    def _measure(self, left: float, right: float, relative_pose: np.ndarray) -> bool:
        """Gate and apply one measurement; ``ValueError`` (nothing changed) where the gate's
        score or the new estimate would not be finite."""
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # refused below
            motion = batch.log(relative_pose)
            rows = (np.array([0.5 * left, 0.5 * right]), np.array([-left, right]))
            values = (motion[0], motion[2])
            pairs = list(
                zip(rows, values, self.estimates, self.covariances, self.noise, strict=True)
            )
            scores = [(v - h @ e) ** 2 / (h @ p @ h + n) for h, v, e, p, n in pairs]
            updated = []
            for h, v, e, p, n in pairs:
                gain = p @ h / (h @ p @ h + n)
                updated.append((e + gain * (v - h @ e), p - np.outer(gain, h @ p)))
        finite = all(np.isfinite(scores)) and all(
            np.all(np.isfinite(e)) and np.all(np.isfinite(p)) for e, p in updated
        )
        if not finite:
            raise ValueError(
                "this measurement would make the estimate overflow (wheel increments or a "
                "relative pose too large for the noise given); refused, nothing changed"
            )
        if max(scores) > self.gate:
            self.rejected += 1
            return False
        self.estimates = [e for e, _ in updated]
        self.covariances = [p for _, p in updated]
        self.accepted += 1
        return True

    @property
    def parameters(self) -> np.ndarray:
        """``[left_wheel_radius, right_wheel_radius, track_width]``, m."""
        (r_l, r_r), (c_l, c_r) = self.estimates
        return np.array([r_l, r_r, (r_l + r_r) / (c_l + c_r)])

    @property
    def robot(self) -> DiffDrive:
        """The robot with the radii and track estimated so far (the nominal axle offset)."""
        left, right, track = self.parameters
        return DiffDrive(
            left_wheel_radius=left,
            right_wheel_radius=right,
            track_width=track,
            axle_offset=self.nominal.axle_offset,
        )

    @property
    def covariance(self) -> np.ndarray:
        """3x3 over ``[left_wheel_radius, right_wheel_radius, track_width]``, m^2."""
        (r_l, r_r), (c_l, c_r) = self.estimates
        radius_sum, rate_sum = r_l + r_r, c_l + c_r
        jacobian = np.array(
            [
                [1, 0, 0, 0],
                [0, 1, 0, 0],
                [1 / rate_sum, 1 / rate_sum, -radius_sum / rate_sum**2, -radius_sum / rate_sum**2],
            ]
        )
        joint = np.zeros((4, 4))
        joint[:2, :2], joint[2:, 2:] = self.covariances
        return jacobian @ joint @ jacobian.T

    def batch_solution(self, increments: object, relative_poses: object) -> np.ndarray:
        """The same prior, noise and window, all measurements at once (weighted least
        squares): ``[left_wheel_radius, right_wheel_radius, track_width]``. No gating; the
        updates after the last whole window are not used, as online."""
        wheels, poses = np.asarray(increments, dtype=float), np.asarray(relative_poses, float)
        whole_windows = len(wheels) // self.window * self.window
        summed = wheels[:whole_windows].reshape(-1, self.window, 2).sum(axis=1)
        blocks = poses[:whole_windows].reshape(-1, self.window, 3)
        composed = blocks[:, 0]
        for k in range(1, self.window):
            composed = batch.compose(composed, blocks[:, k])
        motion = batch.log(composed)
        estimates, covariances = self._prior  # the prior, as this estimator started
        designs = (0.5 * summed, summed * np.array([-1.0, 1.0]))
        solved = []
        for k, (design, values) in enumerate(
            zip(designs, (motion[:, 0], motion[:, 2]), strict=True)
        ):
            information = np.linalg.inv(covariances[k])
            normal = information + design.T @ design / self.noise[k]
            right = information @ estimates[k] + design.T @ values / self.noise[k]
            solved.append(np.linalg.solve(normal, right))
        (r_l, r_r), (c_l, c_r) = solved
        return np.array([r_l, r_r, (r_l + r_r) / (c_l + c_r)])


def _variance(name: str, sigma: float) -> float:
    """``sigma ** 2``, refused by name unless a finite number > 0 (1e-200 squares to 0)."""
    sigma = positive(name, sigma)
    variance = sigma * sigma  # not **: a float's power raises where the product gives inf
    if not (0.0 < variance < float("inf")):
        raise ValueError(
            f"{name} {sigma!r} squares to {variance!r}: give a noise of 1e-150 to 1e150"
        )
    return variance
