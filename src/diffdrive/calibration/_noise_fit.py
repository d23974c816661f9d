"""The likelihood behind ``noise.identify``: each group's window errors, the matrices its
covariance is linear in, and Fisher scoring over the ten parameters.

The parameters ``theta`` (``PARAMETERS``): each wheel's random-walk constant (m), the six
entries of the geometry's relative covariance ``G`` (left radius, right radius, track: three
variances, three covariances) and the reference's two variances. A group's stacked window
errors ``e`` are Gaussian with covariance ``sum_p theta_p B_p``: the wheels' parts block
diagonal by run, the geometry's ``J G J^T`` across every run of the group (one draw of the
geometry a group), the reference's shared by neighbouring windows of a run.
"""

from __future__ import annotations

import numpy as np

from diffdrive import batch
from diffdrive.estimation.odometry import Odometry
from diffdrive.integrate import Method
from diffdrive.model import DiffDrive, geometry_of
from diffdrive.sensor_noise import WheelNoise
from diffdrive.simulation import dead_reckon
from diffdrive.types import Pose

PARAMETERS = (
    "k_left",
    "k_right",
    "radius_left",
    "radius_right",
    "track",
    "radii",
    "left_track",
    "right_track",
    "reference",
    "reference_heading",
)
# Where each of the geometry's entries sits in G (row, column): the variances, then the pairs.
GEOMETRY = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
_STEP = 1e-6  # relative: the geometry's finite differences


def geometry_covariance(theta: np.ndarray) -> np.ndarray:
    """The geometry's relative covariance ``(3, 3)`` in ``theta``."""
    matrix = np.zeros((3, 3))
    for (row, column), value in zip(GEOMETRY, theta[2:8], strict=True):
        matrix[row, column] = matrix[column, row] = value
    return matrix


def _with_geometry(theta: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    out = theta.copy()
    out[2:8] = [matrix[row, column] for row, column in GEOMETRY]
    return out


def bounds(poses: np.ndarray, count: int) -> np.ndarray:
    """``count + 1`` pose indices cutting the run into windows of equal travelled distance."""
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poses[:, :2], axis=0).T))])
    wanted = travelled[-1] * np.arange(1, count + 1) / count
    inner = np.clip(np.searchsorted(travelled, wanted), 1, len(poses) - 1)
    return np.unique(np.concatenate([[0], inner]))


def _run_terms(robot: DiffDrive, increments, truth, count: int, method: Method):
    """One run's window errors ``(3W,)``, its wheels' and reference's matrices ``(4, 3W,
    3W)`` and the Jacobian ``(3W, 3)`` of its errors on the relative geometry."""
    start = truth[0]
    poses = dead_reckon(robot, increments, start, method)
    cut = bounds(poses, count)
    a, b = cut[:-1], cut[1:]
    windows = len(a)
    moved = batch.relative_to(poses[b], poses[a])
    error = batch.relative_to(truth[b], truth[a]) - moved
    error[:, 2] = batch.wrap_angle(error[:, 2])
    wheels = np.zeros((2, 3 * windows, 3 * windows))
    for side, noise in enumerate((WheelNoise(1.0, 0.0), WheelNoise(0.0, 1.0))):
        for w in range(windows):
            odometry = Odometry(robot, method, Pose(), wheel_noise=noise)
            rows = increments[a[w] : b[w]]
            odometry.update_arrays("increments", rows[:, 0], rows[:, 1])
            wheels[side, 3 * w : 3 * w + 3, 3 * w : 3 * w + 3] = odometry.covariance
    base = np.array(geometry_of(robot)[:3])
    jacobian = np.zeros((3 * windows, 3))
    for index in range(3):
        step = np.zeros(3)
        step[index] = _STEP
        shifted = dead_reckon(
            robot.with_geometry(*(base * (1.0 + step))), increments, start, method
        )
        jacobian[:, index] = ((batch.relative_to(shifted[b], shifted[a]) - moved) / _STEP).ravel()
    # The reference's noise at both ends of each window, through the relative motion,
    # linearised at the reference: (position, heading) parts.
    at_a, at_b = batch.relative_jacobians(truth[b], truth[a])
    ends = np.zeros((2, 3 * windows, 3 * (windows + 1)))
    for w in range(windows):
        rows = slice(3 * w, 3 * w + 3)
        for part, columns in ((0, slice(0, 2)), (1, slice(2, 3))):
            ends[part, rows, 3 * w : 3 * w + 3][:, columns] = at_a[w][:, columns]
            ends[part, rows, 3 * w + 3 : 3 * w + 6][:, columns] = at_b[w][:, columns]
    reference = [part @ part.T for part in ends]
    return error.ravel(), np.array([*wheels, *reference]), jacobian


def group_terms(robot: DiffDrive, runs, count: int, method: Method):
    """A group's stacked window errors ``(n,)`` and the ten matrices ``(10, n, n)`` theta
    weighs, its runs' windows one after the other."""
    made = [_run_terms(robot, increments, truth, count, method) for increments, truth in runs]
    size = sum(len(error) for error, _, _ in made)
    parts = np.zeros((10, size, size))
    jacobian = np.concatenate([j for _, _, j in made])
    at = 0
    for error, own, _ in made:
        block = slice(at, at + len(error))
        parts[0, block, block], parts[1, block, block] = own[0], own[1]
        parts[8, block, block], parts[9, block, block] = own[2], own[3]
        at += len(error)
    for index, (row, column) in enumerate(GEOMETRY):
        outer = np.outer(jacobian[:, row], jacobian[:, column])
        parts[2 + index] = outer if row == column else outer + outer.T
    return np.concatenate([error for error, _, _ in made]), parts


def _sigma(parts: np.ndarray, theta: np.ndarray) -> np.ndarray:
    sigma = np.tensordot(theta, parts, axes=1)
    return sigma + np.eye(len(sigma)) * 1e-18 * max(1.0, float(np.abs(sigma).max()))


def _information(parts: np.ndarray, inverse: np.ndarray) -> np.ndarray:
    """One group's ``0.5 tr(S^-1 B_a S^-1 B_b)`` ``(10, 10)``, by matrix products."""
    weighted = inverse @ parts  # (10, n, n)
    flat = weighted.reshape(len(parts), -1)
    return 0.5 * flat @ weighted.transpose(0, 2, 1).reshape(len(parts), -1).T


def fisher(data, theta: np.ndarray, fitted: np.ndarray, inverses=None) -> np.ndarray:
    """The expected information ``(10, 10)`` on theta, zero outside the fitted parameters
    (``inverses``: each group's covariance inverted at theta, when at hand)."""
    information = np.zeros((10, 10))
    for index, (_, parts) in enumerate(data):
        inverse = np.linalg.inv(_sigma(parts, theta)) if inverses is None else inverses[index]
        information += _information(parts, inverse)
    information[~fitted, :] = 0.0
    information[:, ~fitted] = 0.0
    return information


def _likelihood_and_gradient(data, theta, fitted):
    """The log likelihood, its gradient ``(10,)`` and each group's inverted covariance
    (``-inf`` and no inverses where a covariance is not positive definite)."""
    total, gradient, inverses = 0.0, np.zeros(10), []
    for error, parts in data:
        sigma = _sigma(parts, theta)
        try:
            factor = np.linalg.cholesky(sigma)
        except np.linalg.LinAlgError:
            return -np.inf, gradient, None
        inverse = np.linalg.inv(sigma)
        whitened = inverse @ error
        count, size = len(parts), len(error)
        total -= np.sum(np.log(np.diag(factor))) + 0.5 * error @ whitened
        spread = (parts.reshape(count * size, size) @ whitened).reshape(count, size) @ whitened
        gradient += 0.5 * (spread - parts.reshape(count, -1) @ inverse.ravel())
        inverses.append(inverse)
    gradient[~fitted] = 0.0
    return total, gradient, inverses


def start(data, fitted: np.ndarray) -> np.ndarray:
    """Moment matching: each fitted variance's scale from its own share alone, divided among
    them; the geometry's covariances 0."""
    theta = np.zeros(10)
    variances = fitted.copy()
    variances[5:8] = False
    for index in np.flatnonzero(variances):
        numerator = sum(float(e @ parts[index] @ e) for e, parts in data)
        denominator = sum(float(np.sum(parts[index] * parts[index])) for _, parts in data)
        theta[index] = max(numerator / denominator, 0.0) if denominator > 0 else 0.0
    theta[variances] = np.maximum(theta[variances], 1e-12) / max(1, int(variances.sum()))
    return theta


def _feasible(theta: np.ndarray) -> np.ndarray:
    """theta with the wheels' and the reference's terms >= 0 and the geometry's covariance
    positive semi-definite (its negative eigenvalues cut to 0)."""
    out = theta.copy()
    out[[0, 1, 8, 9]] = np.maximum(out[[0, 1, 8, 9]], 0.0)
    values, vectors = np.linalg.eigh(geometry_covariance(out))
    if values[0] < 0.0:
        out = _with_geometry(out, (vectors * np.maximum(values, 0.0)) @ vectors.T)
    return out


def fit(data, theta: np.ndarray, fitted: np.ndarray, iterations: int) -> np.ndarray:
    """Fisher scoring on theta, kept feasible, each step halved until the likelihood rises;
    done when a step moves theta by under 1e-8 of its size or gains under 1e-9 in log
    likelihood."""
    active = np.ix_(fitted, fitted)
    best, gradient, inverses = _likelihood_and_gradient(data, theta, fitted)
    for _ in range(iterations):
        information = fisher(data, theta, fitted, inverses)
        step = np.zeros(10)
        step[fitted] = np.linalg.lstsq(information[active], gradient[fitted], rcond=None)[0]
        scale = 1.0
        while scale > 1e-6:
            trial = _feasible(theta + scale * step)
            value, trial_gradient, trial_inverses = _likelihood_and_gradient(data, trial, fitted)
            if value >= best:
                break
            scale *= 0.5
        else:
            break
        change = np.abs(trial - theta).max() / max(float(np.abs(theta).max()), 1e-300)
        gain = value - best
        theta, best, gradient, inverses = trial, value, trial_gradient, trial_inverses
        if change < 1e-8 or gain < 1e-9:
            break
    return theta
