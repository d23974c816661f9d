"""The differential-drive robot: geometry and kinematics on scalar values.

Conventions (see docs/conventions.md): body x forward, y left; the left wheel is on +y; the
reference point lies ``axle_offset`` m ahead of the axle midpoint. With wheel angular
velocities ``wl``, ``wr`` (rad/s):

    vx    = (r_r*wr + r_l*wl) / 2
    omega = (r_r*wr - r_l*wl) / track_width
    vy    = axle_offset * omega        (no lateral slip at the wheels)

The Modern Robotics form (seeds 001, 004) builds the same maps from each wheel's frame:
``h_matrix`` (body twist to wheel velocities), ``constraint_matrix`` (no lateral slip) and
``f_matrix`` (wheel velocities back to the body twist, honouring both).

Every robot model (``DiffDrive`` here, ``diffdrive.skid_steer.SkidSteer``) answers the questions
of ``Robot``: its ``equivalent`` differential drive and the ``reference_offset`` of the point
that drive moves, so that the step, the estimators and calibration run on any model without
asking which one it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from diffdrive._arrays import components, namespace
from diffdrive._step import wheel_move
from diffdrive._validate import finite, length
from diffdrive.types import Pose, Twist, TwistLike, WheelsLike, WheelVelocities

__all__ = ["DiffDrive", "ReferencePoint", "Robot", "check_robot", "geometry_of"]


class ReferencePoint:
    """The one place of the shift between a model's body origin and the point ``(0,
    reference_offset)`` of the body (m) that its equivalent drive moves (0 for a
    ``DiffDrive``, which moves its body origin). Poses and twists are one (``Pose``,
    ``Twist`` or 3 numbers) or arrays ``(..., 3)`` of any array library."""

    __slots__ = ()

    @property
    def reference_offset(self) -> float:
        """0 m: the equivalent drive moves the body origin itself."""
        return 0.0

    def to_reference(self, poses: Any) -> Any:
        """The equivalent drive's poses for the body poses ``poses``."""
        return _moved_pose(poses, self.reference_offset)

    def from_reference(self, poses: Any) -> Any:
        """The body poses for the equivalent drive's poses ``poses``."""
        return _moved_pose(poses, -self.reference_offset)

    def twist_to_reference(self, twists: Any) -> Any:
        """The twists of the equivalent drive's point for the body origin's ``twists``."""
        return _moved_twist(twists, -self.reference_offset)

    def twist_from_reference(self, twists: Any) -> Any:
        """The body origin's twists for those of the equivalent drive's point: a rigid
        shift ``offset`` m to the right, so ``vx`` gains ``offset * omega``."""
        return _moved_twist(twists, self.reference_offset)

    def jacobian_to_reference(self, theta: Any) -> np.ndarray:
        """d(``to_reference(pose)``)/d(pose) at headings ``theta`` (rad, any shape):
        ``(..., 3, 3)``."""
        return _offset_jacobian(theta, self.reference_offset)

    def jacobian_from_reference(self, theta: Any) -> np.ndarray:
        """d(``from_reference(pose)``)/d(pose) at headings ``theta``: ``(..., 3, 3)``."""
        return _offset_jacobian(theta, -self.reference_offset)

    def covariance_to_reference(self, theta: Any, covariances: Any) -> np.ndarray:
        """Body-origin pose covariances ``(..., 3, 3)`` at headings ``theta`` (rad), moved to
        the equivalent drive's point (``J C J^T``; the heading is the same at both points)."""
        return _moved_covariance(self.jacobian_to_reference, theta, covariances, self)

    def covariance_from_reference(self, theta: Any, covariances: Any) -> np.ndarray:
        """The equivalent drive's point's pose covariances ``(..., 3, 3)`` at headings
        ``theta``, moved to the body origin."""
        return _moved_covariance(self.jacobian_from_reference, theta, covariances, self)


def _offset_jacobian(theta: Any, offset: float) -> np.ndarray:
    """d(pose composed with (0, offset, 0))/d(pose) at headings ``theta``: ``(..., 3, 3)``."""
    theta = np.asarray(theta, dtype=float)
    jacobian = np.broadcast_to(np.eye(3), (*theta.shape, 3, 3)).copy()
    jacobian[..., 0, 2] = -offset * np.cos(theta)
    jacobian[..., 1, 2] = -offset * np.sin(theta)
    return jacobian


def _moved_covariance(jacobian, theta: Any, covariances: Any, point: ReferencePoint) -> np.ndarray:
    """``covariances`` through ``jacobian(theta)``; a copy where the two points are one."""
    matrix = np.array(covariances, dtype=float)
    if not point.reference_offset:
        return matrix
    moved = jacobian(theta)
    return moved @ matrix @ np.swapaxes(moved, -1, -2)


def _moved_pose(poses: Any, offset: float) -> Any:
    """``poses`` composed with ``(0, offset, 0)``: the pose of the point ``offset`` m left."""
    if isinstance(poses, Pose | tuple | list):
        pose = Pose.coerce(poses, "pose")
        return pose.compose(Pose(0.0, offset, 0.0)) if offset else pose
    if not offset:
        return poses
    xp = namespace(poses)
    p = components(xp, poses, "poses", "x, y, theta")
    c, s = xp.cos(p[..., 2]), xp.sin(p[..., 2])  # the pose moved (0, offset) in its own frame
    return xp.stack([p[..., 0] - s * offset, p[..., 1] + c * offset, p[..., 2]], axis=-1)


def _moved_twist(twists: Any, offset: float) -> Any:
    """``twists`` with ``vx`` plus ``offset * omega`` (m; the same rigid body, another point)."""
    if isinstance(twists, Twist | tuple | list):
        twist = Twist.coerce(twists, "twist")
        return Twist(twist.vx + offset * twist.omega, twist.vy, twist.omega) if offset else twist
    if not offset:
        return twists
    xp = namespace(twists)
    forward = twists[..., 0] + offset * twists[..., 2]
    return xp.stack([forward, twists[..., 1], twists[..., 2]], axis=-1)


@dataclass(frozen=True, slots=True, init=False)
class DiffDrive(ReferencePoint):
    """A two-wheeled differential-drive robot.

    Give either ``wheel_radius`` (both wheels) or ``left_wheel_radius`` and
    ``right_wheel_radius`` (m); either ``track_width``, the **full** distance between the two
    wheel contact points (m), or ``half_track``, half of it (m; the seeds write it ``b``,
    ``d``, ``D`` or ``L``); and optionally the ``axle_offset`` (m) of the reference point ahead
    of the axle midpoint.
    """

    left_wheel_radius: float
    right_wheel_radius: float
    track_width: float
    axle_offset: float

    # How far calibration may move the track from its nominal value, as factors.
    TRACK_RANGE: ClassVar[tuple[float, float]] = (0.5, 1.5)

    def __init__(
        self,
        wheel_radius: float | None = None,
        track_width: float | None = None,
        *,
        left_wheel_radius: float | None = None,
        right_wheel_radius: float | None = None,
        axle_offset: float = 0.0,
        half_track: float | None = None,
    ) -> None:
        left, right = wheel_radii(wheel_radius, left_wheel_radius, right_wheel_radius)
        if (track_width is None) == (half_track is None):
            raise ValueError(
                "give either track_width (the full wheel-to-wheel distance) or half_track "
                "(half of it), not both"
                if half_track is not None
                else "track_width (the full wheel-to-wheel distance) or half_track is required"
            )
        if half_track is not None:
            track_width = 2.0 * length("half_track", half_track)
        object.__setattr__(self, "left_wheel_radius", left)
        object.__setattr__(self, "right_wheel_radius", right)
        object.__setattr__(self, "track_width", length("track_width", track_width))
        object.__setattr__(self, "axle_offset", finite("axle_offset", axle_offset))

    @property
    def half_track(self) -> float:
        """Half the track width, m: the seeds' ``b``, ``d``, ``D`` or ``L``."""
        return 0.5 * self.track_width

    @property
    def wheel_radius(self) -> float:
        """The mean of the two wheel radii, m (the radius itself when they are equal)."""
        return 0.5 * (self.left_wheel_radius + self.right_wheel_radius)

    # -- the questions every robot model answers (``Robot``) ---------------------------------

    @property
    def equivalent(self) -> DiffDrive:
        """Itself: a differential drive is its own equivalent drive."""
        return self

    def with_geometry(
        self,
        left_wheel_radius: float,
        right_wheel_radius: float,
        track_width: float,
        axle_offset: float | None = None,
    ) -> DiffDrive:
        """This robot with other wheel radii and track (m), and ``axle_offset`` if given."""
        return replace(
            self,
            left_wheel_radius=left_wheel_radius,
            right_wheel_radius=right_wheel_radius,
            track_width=track_width,
            axle_offset=self.axle_offset if axle_offset is None else axle_offset,
        )

    def settings(self) -> dict[str, float]:
        """The robot file's keys for this robot (``diffdrive.io.write_robot``)."""
        return {
            "left_wheel_radius": self.left_wheel_radius,
            "right_wheel_radius": self.right_wheel_radius,
            "track_width": self.track_width,
            "axle_offset": self.axle_offset,
        }

    # -- (v, omega) form: seeds 002 and 003 -------------------------------------------------

    def to_twist(self, wheels: WheelsLike) -> Twist:
        """Body twist of the reference point from the wheel velocities (forward kinematics).

        ``wheels`` is a ``WheelVelocities`` or two numbers ``(left, right)``, rad/s.
        """
        wheels = WheelVelocities.coerce(wheels, "wheels")
        return Twist(
            *wheel_move(
                self.left_wheel_radius,
                self.right_wheel_radius,
                self.track_width,
                self.axle_offset,
                wheels.left,
                wheels.right,
            )
        )

    def to_wheel_velocities(self, twist: TwistLike) -> WheelVelocities:
        """Wheel velocities that drive ``twist`` (inverse kinematics).

        A differential drive cannot choose ``vy``: it is ``axle_offset * omega``. The given
        ``vy`` is not used (it is the part of the twist the wheels cannot produce; see
        ``constraint_matrix``). ``twist`` is a ``Twist`` or three numbers ``(vx, vy, omega)``.
        """
        twist = Twist.coerce(twist, "twist")
        half_turn = 0.5 * self.track_width * twist.omega
        return WheelVelocities(
            (twist.vx - half_turn) / self.left_wheel_radius,
            (twist.vx + half_turn) / self.right_wheel_radius,
        )

    def to_twist_matrix(self) -> np.ndarray:
        """2x2 matrix from ``[wl, wr]`` to ``[vx, omega]`` (seed 003's kinematic equation)."""
        r_l, r_r, w = self.left_wheel_radius, self.right_wheel_radius, self.track_width
        return np.array([[r_l / 2.0, r_r / 2.0], [-r_l / w, r_r / w]])

    def to_wheel_velocities_matrix(self) -> np.ndarray:
        """2x2 matrix from ``[vx, omega]`` to ``[wl, wr]`` (seed 003's inverse kinematics)."""
        r_l, r_r, half = self.left_wheel_radius, self.right_wheel_radius, self.track_width / 2
        return np.array([[1.0 / r_l, -half / r_l], [1.0 / r_r, half / r_r]])

    # -- turning: seed 002 ------------------------------------------------------------------

    def turning_radius(self, wheels: WheelsLike) -> float:
        """Signed radius of the axle midpoint's path, m: ``v/omega`` (seed 002's ``R``).

        Positive when turning left (centre on +y), ``+-inf`` when driving straight, ``0`` when
        spinning in place, and NaN when the robot stands still (no centre exists).
        """
        return path_radius(self.to_twist(wheels))

    def instantaneous_center(self, wheels: WheelsLike) -> tuple[float, float]:
        """The instantaneous centre of curvature in the body frame, ``(x, y)`` in m.

        It lies on the axle line, ``(-axle_offset, turning_radius)``: ``y`` is infinite when
        driving straight and NaN when standing still.
        """
        return (-self.axle_offset, self.turning_radius(wheels))

    # -- Modern Robotics form: seeds 001 and 004 ---------------------------------------------

    def wheel_frames(self) -> tuple[Pose, Pose]:
        """The (left, right) wheel frames in the body frame: position m, heading rad.

        Both wheels roll along body x, at ``x = -axle_offset`` and ``y = +-track_width/2``
        (seed 001's ``T_b1``, ``T_b2``; seed 004's ``T_bl``, ``T_br`` with its sides swapped).
        """
        half = 0.5 * self.track_width
        return (Pose(-self.axle_offset, half, 0.0), Pose(-self.axle_offset, -half, 0.0))

    def _radii(self) -> tuple[float, float]:
        return (self.left_wheel_radius, self.right_wheel_radius)

    def h_matrix(self) -> np.ndarray:
        """2x3 ``H`` with ``[wl, wr] = H @ V_b``, ``V_b = (omega, vx, vy)`` in Modern Robotics
        order.

        Row i is ``(1/r_i) * [x_i sin(b_i) - y_i cos(b_i), cos(b_i), sin(b_i)]`` for wheel i
        at ``(x_i, y_i)`` rolling along heading ``b_i``: its rolling speed, by the adjoint map
        ``V_i = [Ad_T_ib] V_b``.
        """
        rows = []
        for frame, radius in zip(self.wheel_frames(), self._radii(), strict=True):
            c, s = math.cos(frame.theta), math.sin(frame.theta)
            rows.append([(frame.x * s - frame.y * c) / radius, c / radius, s / radius])
        return np.array(rows)

    def constraint_matrix(self) -> np.ndarray:
        """2x3 ``Q`` with ``Q @ V_b = 0`` for every twist the wheels allow (no lateral slip).

        Row i is the sideways velocity of wheel i in its own frame:
        ``[x_i cos(b_i) + y_i sin(b_i), -sin(b_i), cos(b_i)]``. With ``axle_offset = D`` both
        rows are ``[-D, 0, 1]``, i.e. ``vy = D*omega``.
        """
        rows = []
        for frame in self.wheel_frames():
            c, s = math.cos(frame.theta), math.sin(frame.theta)
            rows.append([frame.x * c + frame.y * s, -s, c])
        return np.array(rows)

    def f_matrix(self) -> np.ndarray:
        """3x2 ``F`` with ``V_b = F @ [wl, wr]``, Modern Robotics order: the true inverse.

        ``F = N (H N)^-1``, where the columns of ``N`` span the twists that satisfy the
        no-slip constraint. So ``H F = I`` and ``Q F = 0`` for any axle offset. With the
        reference point on the axle it equals seed 004's pseudo-inverse ``H^T (H H^T)^-1``;
        with an offset the pseudo-inverse returns ``vy = 0`` and breaks the constraint.
        """
        q = self.constraint_matrix()
        _, singular, vt = np.linalg.svd(q)
        rank = int(np.sum(singular > 1e-12 * max(1.0, singular[0])))
        null_space = vt[rank:].T  # 3 x 2 for a differential drive
        return null_space @ np.linalg.inv(self.h_matrix() @ null_space)

    def pseudo_inverse_matrix(self) -> np.ndarray:
        """3x2 ``H+ = H^T (H H^T)^-1`` of seed 004. Right only when ``axle_offset == 0``."""
        h = self.h_matrix()
        return h.T @ np.linalg.inv(h @ h.T)


def wheel_radii(
    wheel_radius: float | None, left: float | None, right: float | None
) -> tuple[float, float]:
    """``(left, right)`` wheel radii, m, from one radius or both, checked."""
    if wheel_radius is not None:
        if left is not None or right is not None:
            raise ValueError(
                "give either wheel_radius or left_wheel_radius and right_wheel_radius, not both"
            )
        radius = length("wheel_radius", wheel_radius)
        return radius, radius
    if left is None or right is None:
        raise ValueError("give wheel_radius, or both left_wheel_radius and right_wheel_radius")
    return length("left_wheel_radius", left), length("right_wheel_radius", right)


def path_radius(twist: Twist) -> float:
    """Signed radius ``vx / omega`` of a path, m: ``+-inf`` straight, NaN standing still."""
    if twist.omega != 0.0:
        return twist.vx / twist.omega
    return math.copysign(math.inf, twist.vx) if twist.vx != 0.0 else math.nan


@runtime_checkable
class Robot(Protocol):
    """What every robot model answers; what the whole-path functions take.

    A model moves its body as a differential drive, ``equivalent``, moves the point
    ``(0, reference_offset)`` of the body (m); a new model that gives these (and inherits
    ``ReferencePoint``, the shift between the two points) needs no edits anywhere else.
    ``track_width`` is the equivalent drive's (what calibration fits); ``with_geometry`` is the
    same model with other radii, track and equivalent axle offset; ``settings`` its robot-file
    keys.
    """

    TRACK_RANGE: ClassVar[tuple[float, float]]

    @property
    def left_wheel_radius(self) -> float:
        """The left wheel's radius, m."""
        ...

    @property
    def right_wheel_radius(self) -> float:
        """The right wheel's radius, m."""
        ...

    @property
    def track_width(self) -> float:
        """The equivalent differential drive's full track, m (what calibration fits)."""
        ...

    @property
    def equivalent(self) -> DiffDrive:
        """The differential drive that moves this robot's body alike."""
        ...

    @property
    def reference_offset(self) -> float:
        """How far the point this model moves lies from the equivalent drive's, m (body y)."""
        ...

    def to_reference(self, poses: Any) -> Any:
        """The equivalent drive's poses ``(..., 3)`` as this model's reference point's."""
        ...

    def from_reference(self, poses: Any) -> Any:
        """This model's reference point's poses ``(..., 3)`` as the equivalent drive's."""
        ...

    def twist_to_reference(self, twists: Any) -> Any:
        """The equivalent drive's body twists ``(..., 3)`` at this model's reference point."""
        ...

    def twist_from_reference(self, twists: Any) -> Any:
        """Body twists ``(..., 3)`` at this model's reference point, at the equivalent drive's."""
        ...

    def jacobian_to_reference(self, theta: Any) -> np.ndarray:
        """d(``to_reference(pose)``)/d(pose) at headings ``theta``: ``(..., 3, 3)``."""
        ...

    def jacobian_from_reference(self, theta: Any) -> np.ndarray:
        """d(``from_reference(pose)``)/d(pose) at headings ``theta``: ``(..., 3, 3)``."""
        ...

    def covariance_to_reference(self, theta: Any, covariances: Any) -> np.ndarray:
        """Body pose covariances ``(..., 3, 3)`` at the equivalent drive's point."""
        ...

    def covariance_from_reference(self, theta: Any, covariances: Any) -> np.ndarray:
        """The equivalent drive's point's pose covariances ``(..., 3, 3)`` at the body's."""
        ...

    def with_geometry(
        self,
        left_wheel_radius: float,
        right_wheel_radius: float,
        track_width: float,
        axle_offset: float | None = None,
    ) -> Robot:
        """The same model with other radii and track (m), and axle offset where given."""
        ...

    def settings(self) -> dict[str, float]:
        """The model's robot-file keys and values (SI units)."""
        ...

    def to_twist(self, wheels: WheelsLike) -> Twist:
        """The body twist of wheel velocities ``(left, right)`` rad/s."""
        ...

    def to_wheel_velocities(self, twist: TwistLike) -> WheelVelocities:
        """The wheel velocities (rad/s) that drive a body twist."""
        ...

    def turning_radius(self, wheels: WheelsLike) -> float:
        """The signed turning radius (m, centre on the left when positive) of wheel velocities."""
        ...


def check_robot(robot: object, name: str = "robot") -> Robot:
    """``robot`` if it is a robot model; ``TypeError`` naming ``name`` and what it got if not."""
    if not isinstance(robot, Robot):
        raise TypeError(
            f"{name} must be a robot model (DiffDrive, SkidSteer), got {type(robot).__name__}"
        )
    return robot


def geometry_of(robot: Robot) -> tuple[float, float, float, float]:
    """``(left_wheel_radius, right_wheel_radius, track_width, axle_offset)`` (m) of the robot's
    equivalent drive: the one geometry row the cores, kernels and fits take."""
    drive = check_robot(robot).equivalent
    return (drive.left_wheel_radius, drive.right_wheel_radius, drive.track_width, drive.axle_offset)
