"""A voltage-driven wheel: kS, kv, kA identified from a log, and the feedforward they give.

The model, per wheel: ``V = kS sgn(v) + kV v + kA dv/dt`` (volts; ``v`` in the log's unit of
velocity, m/s or rad/s), the form of WPILib's ``SimpleMotorFeedforward`` and SysId. Sampled
with the voltage held over each step of ``dt`` s, the velocity obeys exactly
``v_{k+1} = alpha v_k + beta (V_k - kS sgn v_k)`` with ``alpha = exp(-kV dt / kA)`` and
``beta = (1 - alpha) / kV``; a least-squares fit of ``v_{k+1}`` on ``(v_k, V_k, sgn v_k)``
gives them back (SysId's regression; Rasmussen and Peters, "System Identification", WPILib
docs). SysId takes the measurement's delay from hardware presets; here it comes from the data:
the voltages are shifted by each delay on a grid (a tenth of a step, up to ``max_delay``) and
the fit with the least residual kept (``identify_drivetrain``: the same on a drivetrain's
linear and angular channels, WPILib's four-constant form). Samples where the wheel stands
still or nearly (``|v|`` below ``still``, default 0.02: a few times the velocity's noise) are
left out: the friction is not ``kS sgn v`` there, and a noisy sign there pulls kS down by a
sixth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from diffdrive._validate import finite, positive
from diffdrive.model import Robot
from diffdrive.types import TwistLike

__all__ = [
    "DrivetrainResponse",
    "Feedforward",
    "VoltageResponse",
    "identify_drivetrain",
    "identify_voltage_response",
]


@dataclass(frozen=True)
class Feedforward:
    """``ks`` (V; SysId's kS), ``kv`` (V per unit of velocity; kv), ``ka`` (V per unit of
    acceleration; kA): the voltage that holds a velocity and acceleration."""

    ks: float
    kv: float
    ka: float

    def __post_init__(self) -> None:
        # The signs are checked where they matter (a DriveModel, a plan's voltage limit): an
        # identification on noisy data may find a small negative kS and must report it.
        for name in ("ks", "kv", "ka"):
            finite(name, getattr(self, name))

    def per_radian(self, radius: float) -> Feedforward:
        """These gains, identified on a wheel's surface speed (V s/m, V s^2/m, as SysId and
        WPILib give them), for the wheel's angular velocity (V s/rad, V s^2/rad) at
        ``radius`` m: ``kV r`` and ``kA r``; kS stays."""
        r = positive("radius", radius)
        return Feedforward(self.ks, self.kv * r, self.ka * r)

    def voltage(self, velocity: object, acceleration: object = 0.0) -> np.ndarray:
        """``kS sgn(v) + kV v + kA a`` for velocities and accelerations (arrays broadcast)."""
        v = np.asarray(velocity, dtype=float)
        return self.ks * np.sign(v) + self.kv * v + self.ka * np.asarray(acceleration, float)

    def wheel_voltages(
        self, robot: Robot, twist: TwistLike, twist_rate: TwistLike = (0.0, 0.0, 0.0)
    ) -> tuple[float, float]:
        """The two wheels' voltages ``(left, right)`` that drive ``robot`` at ``twist`` while
        it changes at ``twist_rate`` (``(vx, vy, omega)`` per s), with these gains identified
        on wheel velocities in rad/s: the wheels' velocities and accelerations by inverse
        kinematics (linear, so the twist's rate maps as the twist does)."""
        wheels = robot.to_wheel_velocities(twist)
        rates = robot.to_wheel_velocities(twist_rate)
        return (
            float(self.voltage(wheels.left, rates.left)),
            float(self.voltage(wheels.right, rates.right)),
        )


@dataclass(frozen=True, eq=False)
class VoltageResponse:
    """``identify_voltage_response``'s result: the ``feedforward`` gains, the measurement
    ``delay`` (s) found, the ``covariance`` (3, 3) of (kS, kv, kA) by the delta method from the
    regression's, and the one-step ``rmse`` of the velocity."""

    feedforward: Feedforward
    delay: float
    covariance: np.ndarray
    rmse: float


def _regression(times, voltages, velocities, delay, still):
    """The least squares of ``v_{k+1}`` on ``(v_k, V_k, sgn v_k)`` with the voltages as the
    wheel felt them ``delay`` s before the velocity was measured: the coefficients, their
    covariance, the residual sum and the step."""
    index = np.searchsorted(times, times - delay, side="right") - 1
    held = np.where(index >= 0, voltages[np.maximum(index, 0)], 0.0)
    moving = np.abs(velocities[:-1]) > still
    design = np.column_stack([velocities[:-1], held[:-1], np.sign(velocities[:-1])])[moving]
    target = velocities[1:][moving]
    found, *_ = np.linalg.lstsq(design, target, rcond=None)
    residual = float(np.sum((design @ found - target) ** 2))
    dof = max(len(target) - 3, 1)
    covariance = np.linalg.pinv(design.T @ design) * residual / dof
    return found, covariance, residual, len(target)


def identify_voltage_response(
    times: object,
    voltages: object,
    velocities: object,
    *,
    max_delay: float = 0.1,
    still: float = 0.02,
) -> VoltageResponse:
    """kS, kV and kA of a wheel from its ``voltages`` (V) and measured ``velocities`` at
    evenly spaced ``times`` (s), the measurement's delay found on the way (see the module).
    ``ValueError`` names what the log lacks: both directions, and acceleration."""
    times = np.asarray(times, dtype=float)
    voltages = np.asarray(voltages, dtype=float)
    velocities = np.asarray(velocities, dtype=float)
    if times.ndim != 1 or voltages.shape != times.shape or velocities.shape != times.shape:
        raise ValueError(
            f"times, voltages and velocities must be (N,) alike, got {times.shape}, "
            f"{voltages.shape} and {velocities.shape}"
        )
    if len(times) < 20 or not all(np.all(np.isfinite(a)) for a in (times, voltages, velocities)):
        raise ValueError("times, voltages and velocities must be finite, 20 samples or more")
    steps = np.diff(times)
    step = float(np.mean(steps))
    if np.any(steps <= 0) or np.abs(steps - step).max() > 0.01 * step:
        raise ValueError("the samples must be evenly spaced (to 1 %): resample the log")
    if not (math.isfinite(max_delay) and max_delay >= 0.0):
        raise ValueError(f"max_delay must be finite and >= 0 s, got {max_delay}")
    if not (np.any(velocities > still) and np.any(velocities < -still)):
        raise ValueError(
            "kS needs the wheel driven both ways: the log must hold forward and backward motion"
        )
    best = None
    for delay in np.arange(0.0, max_delay + 1e-12, step / 10.0):
        found = _regression(times, voltages, velocities, delay, still)
        if best is None or found[2] < best[1][2]:
            best = (delay, found)
    delay, (coefficients, covariance, residual, count) = best  # type: ignore[misc]
    alpha, beta, gamma = (float(c) for c in coefficients)
    if not 0.0 < alpha < 1.0 or beta <= 0.0:
        raise ValueError(
            "the log does not show the wheel accelerating under the voltage (the fit's decay "
            f"{alpha:.4g} is not in (0, 1)): it must hold changes of voltage, as SysId's "
            "dynamic steps"
        )
    kv = (1.0 - alpha) / beta
    ka = -kv * step / math.log(alpha)
    ks = -gamma / beta
    # The delta method: d(ks, kv, ka)/d(alpha, beta, gamma).
    dkv = np.array([-1.0 / beta, -(1.0 - alpha) / beta**2, 0.0])
    dka = -step * (dkv / math.log(alpha) - kv / (alpha * math.log(alpha) ** 2) * np.eye(3)[0])
    dks = np.array([0.0, gamma / beta**2, -1.0 / beta])
    jacobian = np.array([dks, dkv, dka])
    return VoltageResponse(
        Feedforward(ks, kv, ka),
        float(delay),
        jacobian @ covariance @ jacobian.T,
        math.sqrt(residual / count),
    )


@dataclass(frozen=True, eq=False)
class DrivetrainResponse:
    """``identify_drivetrain``'s result: the ``linear`` and ``angular`` channels' responses
    (WPILib's four-constant drivetrain form, plus each channel's kS): the linear in the wheels'
    mean velocity and voltage, the angular in half their difference."""

    linear: VoltageResponse
    angular: VoltageResponse


def identify_drivetrain(
    times: object,
    voltages: object,
    velocities: object,
    **options,
) -> DrivetrainResponse:
    """The linear and angular responses of a drivetrain from its wheels' ``voltages``
    ``(N, 2)`` (left, right; V) and measured ``velocities`` ``(N, 2)`` (wheel surface speeds,
    m/s, or rad/s) at evenly spaced ``times`` ``(N,)``: ``identify_voltage_response`` on the
    mean of the two (the linear channel) and on half their difference, right less left (the
    angular one, the wheels' speed from turning). ``options`` go to it. The log must drive
    both channels both ways (straight runs and turns)."""
    volts = np.asarray(voltages, dtype=float)
    speeds = np.asarray(velocities, dtype=float)
    if volts.ndim != 2 or volts.shape[1:] != (2,) or speeds.shape != volts.shape:
        raise ValueError(
            f"voltages and velocities must be (N, 2) alike, got {volts.shape} and {speeds.shape}"
        )
    channels = {}
    for name, mix in (("linear", np.array([0.5, 0.5])), ("angular", np.array([-0.5, 0.5]))):
        try:
            channels[name] = identify_voltage_response(times, volts @ mix, speeds @ mix, **options)
        except ValueError as exc:
            raise ValueError(f"the {name} channel: {exc}") from None
    return DrivetrainResponse(channels["linear"], channels["angular"])
