"""Signatures of the C extension ``diffdrive.backends._odometry`` (``_odometry.c``,
``_estimator.c``, ``_partition.c``), for type checkers and editors. Use ``diffdrive.Odometry``,
which subclasses ``OdometryCore``."""

from typing import Any

from diffdrive.backends.settings import CoreSettings, OdometrySettings

Covariance = tuple[float, float, float, float, float, float, float, float, float]

class OdometryCore:
    """The state and update of diffdrive.Odometry; use that class."""

    def __init__(self, settings: OdometrySettings) -> None: ...  # at the origin
    def update_ticks(self, left: Any, right: Any, t: float | None = None) -> Any:
        """Absolute encoder counter readings."""
    def update_increments(self, left: float, right: float, t: float | None = None) -> Any:
        """Wheel-angle increments since the last update, rad."""
    def update_positions(self, left: float, right: float, t: float | None = None) -> Any:
        """Accumulated wheel angles, rad."""
    def update_velocities(self, left: float, right: float, dt: float) -> Any:
        """Wheel velocities, rad/s, held over dt s."""
    def _run(
        self,
        kind: int,
        lefts: list[Any],
        rights: list[Any],
        thirds: list[Any],
        poses: Any,  # a writable C-contiguous float64 buffer (n, 3)
        covariances: Any,  # the same (n, 9), or None
    ) -> tuple[int, str] | None: ...
    def _state(self) -> tuple[float, float, float, float, float]:
        """``(x, y, theta, distance, time)``."""
    def _covariance(self) -> Covariance: ...
    def _window_velocities(self) -> tuple[float, float, float] | None: ...
    def _wheel_arcs(self) -> tuple[float, float]: ...
    def _snapshot(self) -> bytes: ...
    def _restore(self, snapshot: bytes) -> None: ...
    def _set_pose(self, x: float, y: float, theta: float, covariance: Covariance) -> None: ...
    def _jacobians(
        self, left: float, right: float
    ) -> tuple[Covariance, tuple[float, float, float, float, float, float]]: ...

class EstimatorCore:
    """The state, history and updates of PoseEstimator; use that class."""

    def __init__(self, wheels: OdometryCore, settings: CoreSettings) -> None: ...
    def update_ticks(
        self,
        left: Any,
        right: Any,
        t: Any,
        *,
        gyro_angle: Any = None,
        gyro_rate: Any = None,
        commanded: Any = None,
    ) -> None: ...
    def update_positions(
        self,
        left: Any,
        right: Any,
        t: Any,
        *,
        gyro_angle: Any = None,
        gyro_rate: Any = None,
        commanded: Any = None,
    ) -> None: ...
    def update_increments(
        self,
        left: Any,
        right: Any,
        t: Any,
        *,
        gyro_angle: Any = None,
        gyro_rate: Any = None,
        commanded: Any = None,
    ) -> None: ...
    def update_velocities(
        self,
        left: Any,
        right: Any,
        dt: Any,
        *,
        gyro_angle: Any = None,
        gyro_rate: Any = None,
        commanded: Any = None,
    ) -> None: ...
    def _add_fast(
        self, kind: int, t: Any, value: Any, covariance: Any, lever_arm: Any
    ) -> bool | None: ...
    def _add(self, measurement: Any) -> bool: ...
    def _state_now(self) -> tuple[float, ...]: ...
    def _covariance_now(self) -> tuple[float, ...]: ...
    def _counts(self) -> tuple[int, int]: ...
    def _history_start(self) -> float: ...
    def _slip(self) -> tuple[bool, float, float]: ...
    def _pose_at(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]: ...
    def _run_log(self, log: Any, out: Any, smooth: bool) -> int:
        """As ``diffdrive.estimation._estimator_python.EstimatorCore._run_log``: ``log`` a
        ``backends.settings.LogArrays``, ``out`` a ``PassArrays``, each read by name."""

def _partition(
    along: Any,  # (n, 2) float64, C-contiguous
    weight: Any,  # the same
    penalty: float,
    edge_cost: float,
    longest: int,
    start: Any,  # (n + 1,) float64, filled
) -> None:
    """``diffdrive.estimation.episodes.partition``'s dynamic programme."""
