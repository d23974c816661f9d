"""The public surface a user holds: no two public objects share a name with different
meanings, and the twins, array twins and fits' internals are private."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from collections import defaultdict

import diffdrive

# Names that mean the same in both places, by design: the batch functions are the scalar
# ones over arrays, distributed.monte_carlo is monte_carlo over Dask, and each command-line
# module registers its subcommand through add_to.
SAME_MEANING = {
    "delta": {"diffdrive.integrate", "diffdrive.batch.integrate"},
    "step": {"diffdrive.integrate", "diffdrive.batch.integrate"},
    "wrap_angle": {"diffdrive.angles", "diffdrive.batch.se2"},
    "monte_carlo": {"diffdrive.montecarlo", "diffdrive.distributed"},
    **{
        name: {"diffdrive.se2", "diffdrive.batch.se2"}
        for name in (
            "exp", "log", "from_matrix", "to_matrix", "pose_derivative", "rotation_matrix", "sinc",
        )
    },
}  # fmt: skip


def public_modules():
    """Every module a user can import without a leading underscore on its path."""
    for found in pkgutil.walk_packages(diffdrive.__path__, "diffdrive."):
        if any(part.startswith("_") for part in found.name.split(".")):
            continue
        if found.name == "diffdrive.learn.page":  # a marimo notebook, run by marimo
            continue
        yield importlib.import_module(found.name)


def defined_names() -> dict[str, set[str]]:
    """Each public function's and class's name, with the modules that define one."""
    where: dict[str, set[str]] = defaultdict(set)
    for module in public_modules():
        for name, value in vars(module).items():
            if name.startswith("_") or not (inspect.isfunction(value) or inspect.isclass(value)):
                continue
            if value.__module__ == module.__name__:
                where[name].add(module.__name__)
    return where


def test_no_two_public_objects_share_a_name_with_different_meanings():
    shared = {
        name: modules
        for name, modules in defined_names().items()
        if len(modules) > 1
        and modules != SAME_MEANING.get(name)
        and not all(m.startswith("diffdrive.cli.") for m in modules)
    }
    assert shared == {}


def test_the_twins_and_the_fits_internals_are_private():
    """The pure-Python twins of the C cores, the MPPI cycle's array twin and the fits'
    internals sit in private modules, and no face exports them."""
    private = {
        "estimation": ("_odometry_python", "_estimator_python"),
        "calibration": ("_noise_fit", "_reference_model", "_reference_noise"),
        "control": ("_mppi_arrays",),
    }
    for package, modules in private.items():
        for module in modules:
            importlib.import_module(f"diffdrive.{package}.{module}")
    names = {m.name for m in pkgutil.walk_packages(diffdrive.__path__, "diffdrive.")}
    twins = [n for n in names if n.endswith(("_python", "_arrays", "_fit", "_model", "_noise"))]
    public_twins = [n for n in twins if not n.rsplit(".", 1)[1].startswith("_")]
    assert public_twins == ["diffdrive.sensor_noise"]  # the noise values, not a twin
    for module in public_modules():
        exported = getattr(module, "__all__", ())
        assert not [name for name in exported if name.startswith(("Python", "_"))], module


def test_the_entry_points_take_at_most_ten_parameters_and_no_unchecked_keywords():
    """Where a face needs more, its settings go into a value (``EstimatorSettings``,
    ``ReferenceSettings``, ``FollowSettings``, ``MPPISampling`` and ``Avoidance``)."""
    from diffdrive.calibration import calibrate_to_reference
    from diffdrive.control import MPPI, follow
    from diffdrive.estimation import PoseEstimator, estimate_trajectory, gyro_odometry

    faces = (
        calibrate_to_reference,
        follow,
        MPPI,
        PoseEstimator,
        estimate_trajectory,
        gyro_odometry,
    )
    for face in faces:
        parameters = inspect.signature(face).parameters.values()
        assert len(parameters) <= 10, face
        assert not any(p.kind is p.VAR_KEYWORD for p in parameters), face
