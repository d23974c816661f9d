"""Pictures of trajectories: a figure of path, heading and wheel velocities; an animation.

Needs matplotlib (``pip install 'diffdrive[plot]'``), imported only here. The wheel velocities
of a trajectory file are recovered from its poses: each step's relative pose, through the SE(2)
logarithm, is the twist held over it, and inverse kinematics turns that into wheel velocities.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from diffdrive import batch
from diffdrive._optional import optional
from diffdrive._progress import progress_bar
from diffdrive.model import Robot

__all__ = [
    "animate",
    "animation_writer",
    "plot_error_bands",
    "plot_plan",
    "plot_trajectory",
    "wheel_velocities_of",
]

_ROBOT_COLOUR = "0.25"


def _figure(**options):
    """A matplotlib Figure that draws off-screen, without pyplot: the user's backend and
    pyplot's list of open figures are left alone."""
    figure = optional("matplotlib.figure", "plot", "drawing figures").Figure
    return figure(**options)


def _three_panels():
    """A figure with the path on the left, two panels stacked on the right."""
    figure = _figure(figsize=(12, 5), layout="constrained")
    grid = figure.add_gridspec(2, 2, width_ratios=[1.2, 1])
    panels = [figure.add_subplot(grid[:, 0]), figure.add_subplot(grid[0, 1])]
    return figure, (*panels, figure.add_subplot(grid[1, 1]))


def plot_plan(plan, output: str | Path, followed=None) -> None:
    """Draw a ``control.Plan`` to ``output``: the path (and the true paths of a
    ``control.FollowResult``'s robots), each wheel's velocity and each wheel's voltage (or
    acceleration, without a feedforward) over time, with the limits dashed."""
    figure, (path, wheels_ax, effort) = _three_panels()
    if followed is not None:
        for n, poses in enumerate(followed.poses[:20]):
            label = f"followed ({len(followed.poses)} robots)" if n == 0 else None
            path.plot(poses[:, 0], poses[:, 1], color="tab:orange", alpha=0.5, label=label)
    path.plot(plan.poses[:, 0], plan.poses[:, 1], color="tab:blue", label="plan")
    path.plot(*plan.poses[0, :2], "o", color="tab:green", label="start")
    path.plot(*plan.poses[-1, :2], "s", color="tab:red", label="end")
    path.set_aspect("equal", adjustable="datalim")
    path.set(xlabel="x, m", ylabel="y, m", title="planned path")
    path.legend(loc="best")
    limits = plan.limits
    wheels = plan.wheel_velocities
    volts = plan.voltages
    second, name, bound = (
        (volts, "wheel voltage, V", limits.max_voltage)
        if volts is not None
        else (
            plan.wheel_accelerations,
            "wheel acceleration, rad/s^2",
            limits.max_wheel_acceleration,
        )
    )
    for panel, values, top in (
        (wheels_ax, wheels, limits.max_wheel_velocity),
        (effort, second, bound),
    ):
        panel.plot(plan.times, values[:, 0], label="left")
        panel.plot(plan.times, values[:, 1], label="right")
        if top is not None:
            for sign in (1, -1):
                panel.axhline(sign * top, color="0.4", linestyle="--", linewidth=1)
        panel.legend(loc="best")
    wheels_ax.set(ylabel="wheel velocity, rad/s", title="each wheel within its limits (dashed)")
    effort.set(xlabel="t, s", ylabel=name)
    for ax in (path, wheels_ax, effort):
        ax.grid(True, alpha=0.3)
    figure.savefig(output, dpi=100)


def wheel_velocities_of(robot: Robot, times: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Wheel velocities ``(T, 2)`` rad/s held over each step of poses ``(T+1, 3)``."""
    steps = batch.relative_to(poses[1:], poses[:-1])
    twists = batch.log(steps) / np.diff(times)[:, None]
    return batch.to_wheel_velocities(robot, twists)


def _draw_robot(ax, robot: Robot, pose: np.ndarray) -> None:
    """The robot's outline (a box the size of its track) and its heading, at ``pose``."""
    half = robot.track_width / 2
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half], [-half, -half]])
    world = batch.transform_points(pose, corners)
    ax.plot(world[:, 0], world[:, 1], color=_ROBOT_COLOUR, linewidth=1)
    nose = batch.transform_points(pose, np.array([[0.0, 0.0], [1.4 * half, 0.0]]))
    ax.plot(nose[:, 0], nose[:, 1], color=_ROBOT_COLOUR, linewidth=1.5)


def _centre_of_curvature(ax, robot: Robot, pose: np.ndarray, wheels: np.ndarray) -> None:
    """The instantaneous centre of rotation when it is within a few metres of the robot."""
    centre = batch.instantaneous_center(robot, wheels)
    if np.all(np.isfinite(centre)) and np.hypot(*centre) < 3.0:
        world = batch.transform_points(pose, centre)
        ax.plot(*world, "+", color="tab:red", markersize=8)


def plot_trajectory(
    robot: Robot,
    times: np.ndarray,
    poses: np.ndarray,
    output: str | Path,
    truth: tuple[np.ndarray, np.ndarray] | None = None,
    robots_drawn: int = 6,
    assumed: str | None = None,
) -> None:
    """Draw path, heading and wheel velocities to ``output`` (PNG or SVG, by its suffix).

    The wheel velocities are the ``robot``'s along the path; ``assumed`` says on the figure
    which robot that was when the user did not give one.

    The path has equal axes, start and end marked, the robot drawn at ``robots_drawn`` poses
    with its centre of curvature (+) where that is near. ``truth`` is ``(times, poses)`` of a
    ground truth to draw underneath. Poses ``(N, T+1, 3)`` of ``N`` robots draw the fan of
    their paths and headings, and the spread of their final positions (mean and 2-sigma
    ellipse) instead of the wheel velocities.
    """
    poses = np.asarray(poses, dtype=float)
    if poses.ndim == 3:
        _plot_many(times, poses, output, truth)
        return
    figure, (path, heading, wheels_ax) = _three_panels()
    if truth is not None:
        path.plot(truth[1][:, 0], truth[1][:, 1], color="0.6", linewidth=3, label="ground truth")
        heading.plot(truth[0], np.degrees(truth[1][:, 2]), color="0.6", linewidth=3)
    path.plot(poses[:, 0], poses[:, 1], color="tab:blue", label="trajectory")
    path.plot(*poses[0, :2], "o", color="tab:green", label="start")
    path.plot(*poses[-1, :2], "s", color="tab:red", label="end")
    wheels = wheel_velocities_of(robot, times, poses)
    # Spaced evenly along the path, so that a spin in place does not pile them up.
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poses[:, :2], axis=0).T))])
    marks = np.linspace(0.0, travelled[-1], robots_drawn)
    drawn = np.minimum(np.searchsorted(travelled, marks), len(poses) - 2)
    for k in drawn:
        _draw_robot(path, robot, poses[k])
        _centre_of_curvature(path, robot, poses[k], wheels[k])
    path.set_aspect("equal", adjustable="datalim")
    path.set(xlabel="x, m", ylabel="y, m", title="path (+: centre of curvature)")
    path.legend(loc="best")
    heading.plot(times, np.degrees(poses[:, 2]), color="tab:blue")
    heading.set(ylabel="heading, deg", title="heading and wheel velocities")
    wheels_ax.step(times[:-1], wheels[:, 0], where="post", label="left")
    wheels_ax.step(times[:-1], wheels[:, 1], where="post", label="right")
    wheels_ax.set(xlabel="t, s", ylabel="wheel velocity, rad/s")
    if assumed is not None:
        wheels_ax.set_title(f"wheels of {assumed}", fontsize="small")
    wheels_ax.legend(loc="best")
    for ax in (path, heading, wheels_ax):
        ax.grid(True, alpha=0.3)
    figure.savefig(output, dpi=100)


def plot_error_bands(
    times: np.ndarray,
    estimate: np.ndarray,
    covariances: np.ndarray,
    truth: np.ndarray,
    output: str | Path,
    title: str = "",
) -> float:
    """Each error of ``estimate`` ``(T+1, 3)`` against ``truth`` (x, y in m, heading in deg)
    over ``times`` with the estimate's plus/minus 2-sigma band from ``covariances``
    ``(T+1, 3, 3)``; returns the share of poses with every error inside its band. A truth
    without headings (all NaN, as GPS fixes) has its x and y errors drawn alone."""
    error = truth - estimate
    error[:, 2] = np.degrees(batch.wrap_angle(error[:, 2]))
    sigma = np.sqrt(np.maximum(np.einsum("tii->ti", covariances), 0.0))
    sigma[:, 2] = np.degrees(sigma[:, 2])
    axes_drawn = 2 if np.isnan(truth[:, 2]).all() else 3
    figure = _figure(figsize=(10, 2.4 * axes_drawn), layout="constrained")
    axes = figure.subplots(axes_drawn, 1, sharex=True)
    labels = ("x error, m", "y error, m", "heading error, deg")
    for ax, k, label in zip(axes, range(axes_drawn), labels, strict=False):
        ax.fill_between(
            times,
            -2 * sigma[:, k],
            2 * sigma[:, k],
            color="tab:blue",
            alpha=0.2,
            label="plus/minus 2 sigma",
        )
        ax.plot(times, error[:, k], color="tab:red", linewidth=1, label="error")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="upper left")
    axes[-1].set_xlabel("t, s")
    drawn = slice(0, axes_drawn)
    inside = float(np.mean(np.all(np.abs(error[:, drawn]) <= 2 * sigma[:, drawn], axis=1)))
    what = "all three" if axes_drawn == 3 else "both"
    axes[0].set_title(
        f"{title + chr(10) if title else ''}errors and their 2-sigma bands: {inside:.0%} of "
        f"poses inside {what}"
    )
    figure.savefig(output, dpi=100)
    return inside


def _plot_many(times: np.ndarray, poses: np.ndarray, output, truth) -> None:
    """Many robots: their paths, their headings, and where they end."""
    figure, (path, heading, spread) = _three_panels()
    alpha = max(0.05, min(0.8, 20.0 / len(poses)))
    if truth is not None:
        path.plot(truth[1][..., 0].T, truth[1][..., 1].T, color="0.6", linewidth=3)
    path.plot(poses[..., 0].T, poses[..., 1].T, color="tab:blue", linewidth=0.8, alpha=alpha)
    path.plot(*poses[0, 0, :2], "o", color="tab:green", label="start")
    path.set_aspect("equal", adjustable="datalim")
    path.set(xlabel="x, m", ylabel="y, m", title=f"paths of {len(poses)} robots")
    path.legend(loc="best")
    heading.plot(times, np.degrees(poses[..., 2]).T, color="tab:blue", linewidth=0.8, alpha=alpha)
    heading.set(xlabel="t, s", ylabel="heading, deg", title="headings")
    ends = poses[:, -1, :2]
    spread.plot(ends[:, 0], ends[:, 1], ".", color="tab:red", alpha=alpha, label="final positions")
    mean = ends.mean(axis=0)
    if len(ends) > 2:
        values, vectors = np.linalg.eigh(np.cov(ends.T))
        angle = np.linspace(0, 2 * np.pi, 100)
        circle = np.stack([np.cos(angle), np.sin(angle)])
        ellipse = mean[:, None] + vectors @ (2 * np.sqrt(np.maximum(values, 0))[:, None] * circle)
        spread.plot(*ellipse, color="k", linewidth=1, label="2 sigma")
    spread.plot(*mean, "+", color="k", markersize=10, label="mean")
    spread.set_aspect("equal", adjustable="datalim")
    spread.set(xlabel="x, m", ylabel="y, m", title="where they end")
    spread.legend(loc="best")
    for ax in (path, heading, spread):
        ax.grid(True, alpha=0.3)
    figure.savefig(output, dpi=100)


def animation_writer(output: str | Path) -> tuple[str, Path]:
    """The matplotlib writer for ``output`` and the file it will write.

    ``.mp4`` uses ffmpeg when matplotlib finds it; anything else, or an ``.mp4`` without
    ffmpeg, becomes an animated GIF written by Pillow (the name then ends in ``.gif``).
    """
    from matplotlib import animation

    output = Path(output)
    if output.suffix == ".mp4" and animation.writers.is_available("ffmpeg"):
        return "ffmpeg", output
    return "pillow", output.with_suffix(".gif")


def animate(
    robot: Robot,
    times: np.ndarray,
    poses: np.ndarray,
    output: str | Path,
    writer: str = "pillow",
    frames: int = 120,
    fps: int = 20,
    progress: bool = False,
) -> None:
    """Write an animation of the robot driving ``poses`` to ``output`` with ``writer``;
    ``progress`` shows a bar of the frames written on standard error."""
    from matplotlib import animation

    figure = _figure(figsize=(6, 6), layout="constrained")
    ax = figure.add_subplot()
    margin = robot.track_width
    ax.set_xlim(poses[:, 0].min() - margin, poses[:, 0].max() + margin)
    ax.set_ylim(poses[:, 1].min() - margin, poses[:, 1].max() + margin)
    ax.set_aspect("equal")
    ax.set(xlabel="x, m", ylabel="y, m")
    ax.grid(True, alpha=0.3)
    ax.plot(poses[:, 0], poses[:, 1], color="0.8")
    (trail,) = ax.plot([], [], color="tab:blue")
    (body,) = ax.plot([], [], color=_ROBOT_COLOUR, linewidth=1.5)
    label = ax.set_title("")
    half = robot.track_width / 2
    # The box, a break (NaN: no line back to the centre), then the heading from the centre.
    outline = np.array(
        [
            [-half, -half],
            [half, -half],
            [half, half],
            [-half, half],
            [-half, -half],
            [np.nan, np.nan],
            [0, 0],
            [1.4 * half, 0],
        ]
    )
    indices = np.linspace(0, len(poses) - 1, min(frames, len(poses))).round().astype(int)

    def draw(k: int):
        trail.set_data(poses[: k + 1, 0], poses[: k + 1, 1])
        world = batch.transform_points(poses[k], outline)
        body.set_data(world[:, 0], world[:, 1])
        label.set_text(f"t = {times[k]:.2f} s")
        return trail, body, label

    movie = animation.FuncAnimation(figure, draw, frames=indices, blit=False)
    bar = progress_bar(progress, total=len(indices), desc="animate", unit="frame")
    try:
        movie.save(
            output,
            writer=writer,
            fps=fps,
            progress_callback=None if bar is None else lambda *_: bar.update(),
        )
    finally:
        if bar is not None:
            bar.close()
