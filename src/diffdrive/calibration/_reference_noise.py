"""The noise of a calibration against a reference, identified from its own log: the wheels'
random-walk constant, the gyro's angle random walk and the reference's position and heading
noise, each a term of the residuals' covariance that is linear in its variance
(``_reference_model.components``).

Restricted maximum likelihood (REML, Patterson and Thompson 1971) over the terms' scale
factors, by Fisher scoring: the likelihood of the residuals once the calibrated parameters are
fitted out, so a stretch's noise is not read as smaller than it is by the fit having bent to
it. Its traces are Hutchinson's estimates over seeded random signs: the covariance is block
banded (poses) or dense and of the order of the readings, and a trace of its inverse would
need the inverse itself. The fit and the scoring alternate until the scales stop moving.

A term the log barely shows, or shows only in a sum with another (the gyro's noise and the
wheels' turn noise on a drive at one speed, say), comes out with a wide standard error; past
``UNDETERMINED`` of its variance the report says the log did not determine it. Its figure
still weighs the fit, since holding it at a figure stated would bias the others'.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from diffdrive.calibration._reference_model import NOISES, Fit, Log, Part, Runs, fit
from diffdrive.sensor_noise import WheelNoise

UNDETERMINED = 0.5  # a variance's relative standard error past which the log does not set it
PROBES = 32  # random-sign vectors for each trace
ROUNDS = 6  # fits and scorings, at most
SCORINGS = 8  # Fisher steps for each fit, at most
_FLOOR = 0.1  # a step may shrink a variance to this share of itself, not below


@dataclass(frozen=True)
class IdentifiedNoise:
    """The noise terms (``NOISES``) as found: ``values`` (the wheels' ``k`` in m both wheels
    scaled alike, the gyro's angle random walk in rad/s/sqrt(Hz), the reference's position
    noise in m and heading noise in rad), their ``standard_errors`` (same units), and those
    ``undetermined``: the log sets them to no better than ``UNDETERMINED`` of their variance
    (it sees their sum with another's, say). Every term's figure, determined or not, weighs
    the fit: a figure held where the log cannot set it would bias the others'."""

    values: dict[str, float]
    standard_errors: dict[str, float]
    undetermined: tuple[str, ...]


def identify(
    logs: list[Log], values: np.ndarray, fitted: np.ndarray, iterations: int, terms: tuple[str, ...]
) -> tuple[list[Log], Fit, IdentifiedNoise]:
    """The logs with the noise ``terms`` (of ``NOISES``) identified where the logs have them,
    the others at their figures; the calibration's fit under it, and the noise found."""
    names = [name for name in NOISES if name in terms and _present(logs, name)]
    if not names:
        raise ValueError(
            f"identify_noise names {', '.join(terms)}: this log has none of them at a figure "
            f"above 0 (it has {', '.join(name for name in NOISES if _present(logs, name))})"
        )
    logs, result, errors = _alternate(logs, values, fitted, iterations, names)
    found = _figures(logs[0])
    return (
        logs,
        result,
        IdentifiedNoise(
            {name: found[name] for name in names},
            {name: _figure_error(name, found[name], errors[name]) for name in names},
            tuple(name for name in names if errors[name] > UNDETERMINED),
        ),
    )


def _present(logs: list[Log], name: str) -> bool:
    """Whether every log has the term, at a figure above 0 to scale."""
    return all(_figures(log).get(name, 0.0) > 0.0 for log in logs)


def _figures(log: Log) -> dict[str, float]:
    """A log's noise figures by term (``IdentifiedNoise.values``' units)."""
    figures = {"wheels": float(max(log.wheels.k)), "reference": float(log.sigma[0])}
    if log.gyro is not None:
        figures["gyro"] = log.gyro_noise
    if log.poses:
        figures["reference_heading"] = float(log.sigma[2])
    return figures


def _figure_error(name: str, figure: float, relative_variance_error: float) -> float:
    """A figure's standard error from its variance's relative one: ``k`` is itself a variance
    rate; the others are square roots of one."""
    return figure * relative_variance_error * (1.0 if name == "wheels" else 0.5)


def _rescaled(log: Log, scales: dict[str, float]) -> Log:
    """``log`` with each term's variance times its scale."""
    root = {name: float(np.sqrt(value)) for name, value in scales.items()}
    sigma = log.sigma.copy()
    sigma[:2] *= root.get("reference", 1.0)
    sigma[2] *= root.get("reference_heading", 1.0)
    wheels = WheelNoise(*(scales.get("wheels", 1.0) * log.wheels.k))
    return replace(
        log, sigma=sigma, wheels=wheels, gyro_noise=log.gyro_noise * root.get("gyro", 1.0)
    )


def _alternate(logs, values, fitted, iterations, names):
    """Fit, score the terms ``names``, rescale; until the scales stop moving. The logs
    rescaled, the last fit and each term's variance's relative standard error."""
    errors = dict.fromkeys(names, 0.0)
    for _ in range(ROUNDS):
        # Each fit from the same start: a parameter the log barely sees (a clock) can settle
        # anywhere along its flat valley, and its wanderings would move the noise found.
        result = fit(logs, values, fitted, iterations)
        scales, errors = _score(result, names)
        if all(abs(scales[name] - 1.0) < max(0.02, errors[name] / 4) for name in names):
            return logs, result, errors
        logs = [_rescaled(log, scales) for log in logs]
    return logs, fit(logs, values, fitted, iterations), errors


def _score(result: Fit, names: list[str]) -> tuple[dict[str, float], dict[str, float]]:
    """REML's scale for each term's variance under ``result``'s residuals and each scale's
    relative standard error (the inverse Fisher information's)."""
    rng = np.random.default_rng(0)
    probes = rng.choice([-1.0, 1.0], size=(len(result.residual), PROBES))
    terms = result.weights.components
    scales = np.ones(len(names))
    for _ in range(SCORINGS):
        factors = dict(zip(names, scales.tolist(), strict=True))
        weights = Runs([_scaled_terms(parts, factors) for parts in terms], result.weights.anchor)
        slopes = [_slope(result.weights, names, scales, name) for name in names]
        project = _projector(weights, result.slope)
        seen = project(result.residual[:, None])[:, 0]
        through = project(probes)
        gradient, fisher = np.zeros(len(names)), np.zeros((len(names), len(names)))
        moved = [slope(probes) for slope in slopes]
        back = [project(vectors) for vectors in moved]
        for i, slope in enumerate(slopes):
            trace = np.sum(through * moved[i]) / PROBES
            gradient[i] = 0.5 * (seen @ slope(seen[:, None])[:, 0] - trace)
            turned = slope(through)
            for j in range(len(names)):
                fisher[i, j] = 0.5 * np.sum(turned * back[j]) / PROBES
        fisher = 0.5 * (fisher + fisher.T)
        step = np.linalg.solve(fisher, gradient)
        new = np.maximum(scales + step, _FLOOR * scales)
        done = np.max(np.abs(new - scales) / scales) < 1e-2
        scales = new
        if done:
            break
    spread = np.sqrt(np.maximum(np.diag(np.linalg.inv(fisher)), 0.0)) / scales
    return dict(zip(names, scales.tolist(), strict=True)), dict(zip(names, spread, strict=True))


def _scaled_terms(parts: dict[str, Part], scales: dict[str, float]) -> dict[str, Part]:
    """A run's terms each times its scale, the product term times both of its factors'."""
    both = scales.get("reference", 1.0) * scales.get("reference_heading", 1.0)
    return {
        name: part.scaled(both if name == "product" else scales.get(name, 1.0))
        for name, part in parts.items()
    }


def _slope(unit: Runs, names: list[str], scales: np.ndarray, name: str):
    """The covariance's derivative in ``name``'s scale, as a product with vectors: its own
    term at the logs' figures (``unit``'s), and the product term's share where ``name`` is
    one of the reference's."""
    partner = {"reference": "reference_heading", "reference_heading": "reference"}.get(name)
    if partner is None or not any("product" in parts for parts in unit.components):
        return lambda vectors: unit.times(name, vectors)
    other = scales[names.index(partner)] if partner in names else 1.0
    return lambda vectors: unit.times(name, vectors) + other * unit.times("product", vectors)


def _projector(weights: Runs, slope: np.ndarray):
    """REML's ``P = W - W J (J' W J)^-1 J' W`` as a product with vectors, ``W`` the
    covariance's inverse and ``J`` the residuals' slope in the fitted parameters."""
    weighted = weights.solve(slope)
    inverse = np.linalg.pinv(slope.T @ weighted)
    return lambda vectors: weights.solve(vectors) - weighted @ (inverse @ (weighted.T @ vectors))
