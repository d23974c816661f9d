"""The model behind ``calibration.reference``: what the wheels, the reference and the gyro
say each stretch between two readings should show, the residuals' covariance (block banded
for poses; dense, with the gyro heading's random walk, for positions) and the Gauss-Newton
fit of the generalised least squares. See ``calibration.reference`` for the why."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diffdrive import batch
from diffdrive.estimation.imu import Gyro
from diffdrive.estimation.odometry import Odometry
from diffdrive.integrate import Method
from diffdrive.model import DiffDrive
from diffdrive.sensor_noise import WheelNoise
from diffdrive.simulation import dead_reckon
from diffdrive.types import Pose

PARAMETERS = (
    "left_radius",
    "right_radius",
    "track",
    "lever_x",
    "lever_y",
    "yaw",
    "offset",
    "gyro_scale",
    "gyro_bias",
    "gyro_offset",
    "heading",
)
RELATIVE = ("left_radius", "right_radius", "track")  # fitted relative to their value
_STEPS = np.array([1e-6, 1e-6, 1e-6, 1e-5, 1e-5, 1e-6, 1e-5, 1e-6, 1e-7, 1e-5, 1e-6])
_LEFT, _RIGHT, _TRACK, _LX, _LY, _YAW, _OFFSET, _SCALE, _BIAS, _GYRO_OFFSET, _HEADING = range(11)


@dataclass(frozen=True)
class Log:
    """What a calibration reads: the wheels, the reference, the gyro, the noise."""

    robot: DiffDrive
    times: np.ndarray
    increments: np.ndarray
    stamps: np.ndarray
    readings: np.ndarray  # (K, 3) poses or (K, 2) positions
    sigma: np.ndarray  # (3,) (x, y, theta): a position's theta 0
    wheels: WheelNoise
    gyro: Gyro | None
    gyro_noise: float  # angle random walk, rad/sqrt(s)
    method: Method

    @property
    def poses(self) -> bool:
        """Whether the reference reads poses (else positions)."""
        return self.readings.shape[1] == 3


def _drive(log: Log, values: np.ndarray) -> DiffDrive:
    return log.robot.with_geometry(*values[:3])


def _gyro_turn(log: Log, values: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """The turn (rad) the gyro says the robot made from each ``start`` to ``end`` (the
    wheels' clock)."""
    assert log.gyro is not None
    shift = values[_GYRO_OFFSET]
    turned = log.gyro.angles(end + shift) - log.gyro.angles(start + shift)
    return (turned - values[_BIAS] * (end - start)) / (1.0 + values[_SCALE])


def _interpolated(times: np.ndarray, poses: np.ndarray, at: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(at, times, poses[:, i]) for i in range(poses.shape[1])], axis=-1)


def _sensor_poses(log: Log, values: np.ndarray) -> np.ndarray:
    """The sensor's poses ``(K, 3)`` at its readings as the wheels tell them, in the frame
    of the wheels' start."""
    odometry = _interpolated(log.times, _wheel_poses(log, values), log.stamps - values[_OFFSET])
    return batch.compose(odometry, np.broadcast_to(values[_LX : _YAW + 1], odometry.shape))


def _wheel_poses(log: Log, values: np.ndarray) -> np.ndarray:
    """The wheels' dead reckoning ``(T+1, 3)`` from the origin."""
    return dead_reckon(_drive(log, values), log.increments, np.zeros(3), log.method)


def antenna_positions(log: Log, values: np.ndarray) -> np.ndarray:
    """The antenna's positions ``(K, 2)`` at its readings in the reference's frame, up to a
    shift: the wheels' travel along the gyro's heading (the wheels' own without a gyro), the
    lever arm turned with it."""
    drive = _drive(log, values)
    if log.gyro is None:
        wheel_poses = _wheel_poses(log, values)
        heading = wheel_poses[:, 2]
    else:
        heading = _gyro_turn(log, values, np.full(len(log.times), log.times[0]), log.times)
    heading = heading + values[_HEADING]
    arcs = log.increments * np.array([drive.left_wheel_radius, drive.right_wheel_radius])
    travel = arcs.mean(axis=1)
    middle = 0.5 * (heading[1:] + heading[:-1])
    steps = travel[:, None] * np.column_stack([np.cos(middle), np.sin(middle)])
    path = np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
    c, s = np.cos(heading), np.sin(heading)
    lever = values[_LX : _LY + 1]
    antenna = path + np.column_stack([c * lever[0] - s * lever[1], s * lever[0] + c * lever[1]])
    return _interpolated(log.times, antenna, log.stamps - values[_OFFSET])


def turn_variances(log: Log, values: np.ndarray, angles_at: np.ndarray | None = None) -> np.ndarray:
    """Each stretch's wheels-against-gyro turn residual's variance ``(K-1,)`` rad^2 at
    ``values``: the wheels' turn (each wheel's ``k |arc|`` over the track squared) and the
    gyro's angle random walk over the stretch, its scale taken off. ``angles_at``: the values
    whose radii make the wheels' noise (``k`` m of travel) their angles' (default
    ``values``): the noise is the encoders', whatever radius the fit tries, so only the
    radius over the track that turns it into a turn moves with the fit."""
    drive = _drive(log, values)
    measured = drive if angles_at is None else _drive(log, angles_at)
    radii = np.array([drive.left_wheel_radius, drive.right_wheel_radius])
    their = np.array([measured.left_wheel_radius, measured.right_wheel_radius])
    k = np.array([log.wheels.left, log.wheels.right])
    arcs = np.abs(log.increments) @ (k * radii * radii / their)
    summed = np.concatenate([[0.0], np.cumsum(arcs)])
    cut = np.clip(np.searchsorted(log.times, log.stamps), 0, len(log.times) - 1)
    wheels = np.diff(summed[cut]) / drive.track_width**2
    return wheels + log.gyro_noise**2 * np.diff(log.stamps) / (1.0 + values[_SCALE]) ** 2


def _residuals(
    log: Log, values: np.ndarray, shrink: float, anchor: np.ndarray | None = None
) -> np.ndarray:
    """Each stretch's residual ``(K-1, m)``, measured less predicted. ``anchor``: the values
    the weights were taken at; the wheels-against-gyro rows are then scaled by their standard
    deviation there over their standard deviation at ``values`` (see ``fit``)."""
    parts = []
    if log.poses:
        sensor = _sensor_poses(log, values)
        predicted = batch.relative_to(sensor[1:], sensor[:-1])
        # A reading's heading noise turns the displacement it measures: on average it is
        # the true one times E[cos n] = exp(-sigma^2 / 2).
        predicted[:, :2] *= shrink
        measured = batch.relative_to(log.readings[1:], log.readings[:-1])
        error = measured - predicted
        error[:, 2] = batch.wrap_angle(error[:, 2])
        parts.append(error)
    else:
        antenna = antenna_positions(log, values)
        parts.append(np.diff(log.readings, axis=0) - np.diff(antenna, axis=0))
    if log.gyro is not None:
        # The wheels' turn against the gyro's, each timed against the wheels, over stretches
        # of the wheels' own clock (the readings' stamps as they are): windows that moved with
        # the reference's offset would make the fit depend on which noise fell inside them,
        # and the reference's own turn would tie its noise to the gyro's comparison.
        wheels = np.diff(np.interp(log.stamps, log.times, _wheel_poses(log, values)[:, 2]))
        turned = _gyro_turn(log, values, log.stamps[:-1], log.stamps[1:])
        compared = wheels - turned
        if anchor is not None:
            there, here = turn_variances(log, anchor), turn_variances(log, values, anchor)
            known = (there > 0.0) & (here > 0.0)
            compared[known] *= np.sqrt(there[known] / here[known])
        parts.append(compared[:, None])
    return np.concatenate(parts, axis=1)


def _adjoint_inverse(mount: np.ndarray) -> np.ndarray:
    """How a small motion of the robot's frame shows in the sensor's: Ad(E^-1) ``(3, 3)``."""
    x, y, yaw = batch.inverse(mount)
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, y], [s, c, -x], [0.0, 0.0, 1.0]])


NOISES = ("wheels", "gyro", "reference", "reference_heading")  # the residuals' noise terms


@dataclass(frozen=True)
class Part:
    """One term of the residuals' covariance: its diagonal blocks ``(K-1, m, m)``, the blocks
    just below them ``(K-2, m, m)`` and, for positions, a ``dense`` ``(m(K-1), m(K-1))``
    remainder (the heading's random walk) or None."""

    diagonal: np.ndarray
    below: np.ndarray
    dense: np.ndarray | None = None

    def scaled(self, factor: float) -> Part:
        """This term times ``factor``."""
        dense = None if self.dense is None else factor * self.dense
        return Part(factor * self.diagonal, factor * self.below, dense)

    def __add__(self, other: Part) -> Part:
        dense = self.dense if other.dense is None else other.dense
        if self.dense is not None and other.dense is not None:
            dense = self.dense + other.dense
        return Part(self.diagonal + other.diagonal, self.below + other.below, dense)

    def times(self, vectors: np.ndarray) -> np.ndarray:
        """This term times ``vectors`` ``(m(K-1), p)``."""
        count, size = self.diagonal.shape[:2]
        blocks = vectors.reshape(count, size, -1)
        out = self.diagonal @ blocks
        out[1:] += self.below @ blocks[:-1]
        out[:-1] += self.below.transpose(0, 2, 1) @ blocks[1:]
        out = out.reshape(vectors.shape)
        return out if self.dense is None else out + self.dense @ vectors

    def matrix(self) -> np.ndarray:
        """This term as a dense matrix ``(m(K-1), m(K-1))``."""
        count, size = self.diagonal.shape[:2]
        out = np.zeros((count * size, count * size)) if self.dense is None else self.dense.copy()
        for k in range(count):
            out[size * k : size * (k + 1), size * k : size * (k + 1)] += self.diagonal[k]
            if k + 1 < count:
                block = self.below[k]
                out[size * (k + 1) : size * (k + 2), size * k : size * (k + 1)] += block
                out[size * k : size * (k + 1), size * (k + 1) : size * (k + 2)] += block.T
        return out


def components(log: Log, values: np.ndarray) -> dict[str, Part]:
    """The residuals' covariance by the noise it comes from (``NOISES``, those the log has,
    each linear in its variance at the log's figures) and ``"product"``, the reference's
    heading noise times its position noise."""
    drive = _drive(log, values)
    at = log.stamps - values[_OFFSET]
    cut = np.clip(np.searchsorted(log.times, at), 0, len(log.times) - 1)
    count = len(at) - 1
    wheel = np.zeros((count, 3, 3))  # each stretch's odometry covariance, its start's frame
    for k in range(count):
        odometry = Odometry(drive, log.method, Pose(), wheel_noise=log.wheels)
        rows = log.increments[cut[k] : cut[k + 1]]
        if len(rows):
            odometry.update_arrays("increments", rows[:, 0], rows[:, 1])
        wheel[k] = odometry.covariance
    gyro = log.gyro_noise**2 * np.diff(at) / (1.0 + values[_SCALE]) ** 2
    size = (3 if log.poses else 2) + (log.gyro is not None)
    own = {name: np.zeros((count, size, size)) for name in ("wheels", "gyro", "product")}
    if log.poses:
        # The Jacobians at the motion the wheels predict, not at the noisy readings: weights
        # that moved with the noise would bias the fit. (Noise as round in x as in y does not
        # mind the frame.)
        sensor = _sensor_poses(log, values)
        at_start, at_end = batch.relative_jacobians(sensor[1:], sensor[:-1])
        adjoint = _adjoint_inverse(values[_LX : _YAW + 1])
        own["wheels"][:, :3, :3] = adjoint @ wheel @ adjoint.T
        # The start's heading noise turns the ends' position noise: a product of noises,
        # small beside either, but the first-order noise of a long stretch of residuals
        # telescopes away along the path (the readings' distance is known to its ends'),
        # and this does not: it bounds what the path's length can tell.
        own["product"][:, 0, 0] = 2.0 * (log.sigma[2] * log.sigma[1]) ** 2
        own["product"][:, 1, 1] = 2.0 * (log.sigma[2] * log.sigma[0]) ** 2
        if log.gyro is not None:  # the wheels' turn against the gyro's: no reference noise
            quiet = np.zeros((count, 1, 3))
            at_start = np.concatenate([at_start, quiet], axis=1)
            at_end = np.concatenate([at_end, quiet], axis=1)
    else:
        at_start = np.zeros((count, size, 3))
        at_start[:, 0, 0] = at_start[:, 1, 1] = -1.0
        at_end = -at_start
        # The wheels' travel noise along the path, as round: a small share beside the fixes'.
        own["wheels"][:, 0, 0] = own["wheels"][:, 1, 1] = 0.5 * (wheel[:, 0, 0] + wheel[:, 1, 1])
    if log.gyro is not None:  # the wheels' turn against the gyro's
        own["wheels"][:, -1, -1] = wheel[:, 2, 2]
        if log.poses:  # for positions, _heading_walk's
            own["gyro"][:, -1, -1] = gyro
    quiet = np.zeros((max(count - 1, 0), size, size))
    parts = {name: Part(blocks, quiet) for name, blocks in own.items()}
    for name, variances in (
        ("reference", np.square([log.sigma[0], log.sigma[1], 0.0])),
        ("reference_heading", np.array([0.0, 0.0, log.sigma[2] ** 2])),
    ):
        noise = np.diag(variances)
        diagonal = at_start @ noise @ at_start.transpose(0, 2, 1)
        diagonal += at_end @ noise @ at_end.transpose(0, 2, 1)
        parts[name] = Part(diagonal, at_start[1:] @ noise @ at_end[:-1].transpose(0, 2, 1))
    if not log.poses:
        walk = _heading_walk(log, values, wheel[:, 2, 2])
        with_gyro = log.gyro is not None
        parts["gyro" if with_gyro else "wheels"] += Part(0 * own["gyro"], quiet, walk)
    kept = {"wheels": True, "gyro": log.gyro is not None, "reference": True}
    kept.update(reference_heading=log.poses, product=log.poses)
    return {name: part for name, part in parts.items() if kept[name]}


def _total(parts: dict[str, Part]) -> Part:
    total = None
    for part in parts.values():
        total = part if total is None else total + part
    assert total is not None
    return total


def _padded(blocks: np.ndarray, extra: np.ndarray) -> np.ndarray:
    """``blocks`` ``(K, 3, 3)`` with one more row and column holding ``extra`` ``(K,)``."""
    out = np.zeros((len(blocks), 4, 4))
    out[:, :3, :3] = blocks
    out[:, 3, 3] = extra
    return out


def _banded(diagonal: np.ndarray, below: np.ndarray) -> np.ndarray:
    """The block tridiagonal covariance in the lower banded form ``(2m, mK)`` that
    ``scipy.linalg.cholesky_banded`` takes."""
    count, size = len(diagonal), diagonal.shape[1]
    banded = np.zeros((2 * size, size * count))
    starts = size * np.arange(count)
    for row in range(size):
        for column in range(size):
            if row >= column:
                banded[row - column, starts + column] = diagonal[:, row, column]
            banded[size + row - column, starts[:-1] + column] = below[:, row, column]
    return banded


def _heading_walk(log: Log, values: np.ndarray, wheel_turn: np.ndarray) -> np.ndarray:
    """For positions: the covariance ``(m(K-1), m(K-1))`` the heading's own random walk adds.
    The heading that turns the wheels' travel is the gyro's (the wheels' own without one),
    integrated from the start: its noise over stretch ``i`` (variance ``q_i``: the gyro's
    angle random walk, or the wheels' turn noise) turns every later stretch's predicted
    displacement, ``u_k = J (A_k+1 - A_k)`` times the sum of the earlier ones; with a gyro it
    is also the gyro's side of stretch ``i``'s turn residual."""
    antenna = antenna_positions(log, values)
    moved = np.diff(antenna, axis=0)
    turned = np.column_stack([-moved[:, 1], moved[:, 0]])  # d(displacement)/d(heading)
    count = len(moved)
    if log.gyro is None:
        variances = wheel_turn
    else:
        variances = log.gyro_noise**2 * np.diff(log.stamps) / (1.0 + values[_SCALE]) ** 2
    size = 2 if log.gyro is None else 3
    # Stretches k and l share the walk of every stretch before both: its variance summed,
    # S[min(k, l)], O(K^2) where the loadings' product would be O(K^3).
    shared = np.concatenate([[0.0], np.cumsum(variances)])[:-1]
    order = np.arange(count)
    common = shared[np.minimum.outer(order, order)]
    out = np.zeros((count, size, count, size))
    out[:, :2, :, :2] = np.einsum("ka,lb,kl->kalb", turned, turned, common)
    if log.gyro is not None:
        # The gyro's side of stretch k's turn residual against every later displacement.
        later = (order[:, None] < order[None, :]) * -variances[:, None]  # (k, l): k before l
        out[:, 2, :, :2] = later[:, :, None] * turned[None, :, :]
        out[:, :2, :, 2] = np.einsum("kla->lak", out[:, 2, :, :2])
        out[order, 2, order, 2] = variances
    return out.reshape(count * size, count * size)


class _Weights:
    """The residuals' covariance factored: block banded (poses), or dense with the heading's
    random walk (positions); ``solve(b)`` is ``covariance^-1 b``."""

    def __init__(self, covariance: Part) -> None:
        from scipy.linalg import cho_factor, cholesky_banded

        count, size = covariance.diagonal.shape[:2]
        self.size = count * size  # the residuals it weighs
        self.banded = covariance.dense is None
        if self.banded:
            self.factor = cholesky_banded(
                _banded(covariance.diagonal, covariance.below), lower=True, check_finite=False
            )
            return
        # Built here from checked readings: the finiteness scan would cost a tenth of the fit.
        self.factor = cho_factor(covariance.matrix(), lower=True, check_finite=False)

    def solve(self, right: np.ndarray) -> np.ndarray:
        from scipy.linalg import cho_solve, cho_solve_banded

        if self.banded:
            return cho_solve_banded((self.factor, True), right, check_finite=False)
        return cho_solve(self.factor, right, check_finite=False)


class Runs:
    """Each run's residual covariance by its terms (``components``) and its factor: runs are
    independent, so their covariance is block diagonal."""

    def __init__(self, terms: list[dict[str, Part]], anchor: np.ndarray) -> None:
        self.components = terms
        self.parts = [_Weights(_total(parts)) for parts in terms]
        self.anchor = anchor  # the values the covariance was taken at

    @classmethod
    def of(cls, logs: list[Log], values: np.ndarray) -> Runs:
        """The runs' covariance at ``values``, the noise at each log's figures."""
        return cls([components(log, values) for log in logs], values.copy())

    def solve(self, right: np.ndarray) -> np.ndarray:
        """The covariance's inverse times ``right`` ``(n, ...)``."""
        return np.concatenate(
            [p.solve(b) for p, b in zip(self.parts, self._split(right), strict=True)]
        )

    def times(self, name: str, right: np.ndarray) -> np.ndarray:
        """The covariance's ``name`` term (``NOISES``) times ``right`` ``(n, p)``; 0 where a
        run has none."""
        pieces = []
        for parts, piece in zip(self.components, self._split(right), strict=True):
            pieces.append(parts[name].times(piece) if name in parts else 0.0 * piece)
        return np.concatenate(pieces)

    def _split(self, right: np.ndarray) -> list[np.ndarray]:
        return np.split(right, np.cumsum([part.size for part in self.parts])[:-1], axis=0)


def residuals(logs: list[Log], values: np.ndarray, anchor: np.ndarray | None = None) -> np.ndarray:
    """Every run's stretches' residuals, flattened ``(n,)`` (``anchor``: ``_residuals``')."""
    parts = [
        _residuals(log, values, float(np.exp(-0.5 * log.sigma[2] ** 2)), anchor) for log in logs
    ]
    return np.concatenate([part.ravel() for part in parts])


def jacobian(
    logs: list[Log], values: np.ndarray, fitted: np.ndarray, anchor: np.ndarray | None = None
) -> np.ndarray:
    """The residuals' derivatives ``(n, E)`` in the ``fitted`` parameters, by central
    differences: the interpolation in time has kinks."""
    columns = []
    for index in np.flatnonzero(fitted):
        step = _STEPS[index] * (values[index] if PARAMETERS[index] in RELATIVE else 1.0)
        ahead, behind = values.copy(), values.copy()
        ahead[index] += step
        behind[index] -= step
        change = residuals(logs, ahead, anchor) - residuals(logs, behind, anchor)
        columns.append(change / (2 * step))
    return np.column_stack(columns)


class DivergedError(ValueError):
    """The fit left the robots there are (a radius or the track at or below 0); ``went``
    says where it went."""

    def __init__(self, message: str, went: str = "") -> None:
        super().__init__(message)
        self.went = went


@dataclass(frozen=True)
class Fit:
    """What ``fit`` found: the ``values``, their ``covariance`` (inflated by ``chi2`` where
    above 1) and the ``information`` it inverts, the residuals' ``chi2`` per degree of freedom,
    and at the values the ``residual`` ``(n,)``, its ``slope`` ``(n, E)`` and the ``weights``
    (``Runs``)."""

    values: np.ndarray
    covariance: np.ndarray
    information: np.ndarray
    chi2: float
    residual: np.ndarray
    slope: np.ndarray
    weights: Runs


def fit(logs: list[Log], values: np.ndarray, fitted: np.ndarray, iterations: int) -> Fit:
    """Gauss-Newton on the generalised least squares over the runs' ``logs``, the weights
    taken at the first and the once-improved values.

    The wheels-against-gyro rows regress the gyro's turn on the wheels' noisy one, whose
    noise grows as the track shrinks: with their weights held where they were taken, the fit
    is ordinary least squares on a noisy regressor and the track comes out high (errors in
    variables). So those rows are scaled by their standard deviation where the weights were
    taken over their standard deviation at the values tried, and their weight moves with the
    track: the objective is then Deming's (Deming 1943; ``track_from_gyro`` does the same
    for the gyro alone), and Gauss-Newton's derivatives carry the weight's change too."""
    weights = Runs.of(logs, values)
    for round_ in range(iterations):
        if round_ == 1:
            weights = Runs.of(logs, values)
        anchor = weights.anchor
        slope = jacobian(logs, values, fitted, anchor)
        weighted = weights.solve(slope)
        information = slope.T @ weighted
        moved = -weighted.T @ residuals(logs, values, anchor)
        step = np.linalg.lstsq(information, moved, rcond=None)[0]
        values = values.copy()
        values[fitted] += step
        if np.any(values[:3] <= 0.0):
            went = (
                f"the radii and track went to {values[0]:.3g}, {values[1]:.3g} and "
                f"{values[2]:.3g} m"
            )
            raise DivergedError(
                f"the calibration did not converge: {went}. Do the wheels' increments count "
                "forward driving as positive, each wheel? Else the log may not show them, or its "
                "noise is not what is stated",
                went,
            )
        spread = np.sqrt(np.maximum(np.diag(np.linalg.pinv(information)), 1e-300))
        if round_ >= 2 and np.max(np.abs(step) / spread) < 1e-6:
            break
    base = residuals(logs, values, weights.anchor)
    slope = jacobian(logs, values, fitted, weights.anchor)
    information = slope.T @ weights.solve(slope)
    chi2 = float(base @ weights.solve(base)) / max(1, len(base) - int(fitted.sum()))
    covariance = np.linalg.pinv(information) * max(1.0, chi2)
    return Fit(values, covariance, information, chi2, base, slope, weights)
