"""Synthetic obstacle courses to test a controller on: a corridor cluttered with circles, with
a way through.

``cluttered_corridor`` draws a straight corridor (walls at ``y = +-width/2``, from ``x = 0`` to
``length``) and ``count`` circles in it, keeping only draws where a robot of radius
``footprint`` (plus ``slack``) has a way from the start ``(0, 0)`` to the goal ``(length,
0)`` (the clearance grid's free nodes connected, diagonal neighbours included) and where start
and goal are clear. ``Course.touches`` judges poses by the exact geometry (circles and walls),
not by the grid a controller reads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diffdrive._validate import floats, positive, whole
from diffdrive.control.obstacles import Obstacles

__all__ = ["Course", "cluttered_corridor"]


@dataclass(frozen=True, eq=False)
class Course:
    """A corridor ``length`` x ``width`` (m) along x from the origin, circles ``centres``
    ``(N, 2)`` and ``radii`` ``(N,)`` (m) in it, and its ``obstacles`` grid."""

    length: float
    width: float
    centres: np.ndarray
    radii: np.ndarray
    obstacles: Obstacles

    @property
    def start(self) -> np.ndarray:
        """The start pose ``(3,)``: the origin, facing along x."""
        return np.array([0.0, 0.0, 0.0])

    @property
    def goal(self) -> np.ndarray:
        """The goal pose ``(3,)``: ``length`` m along x."""
        return np.array([self.length, 0.0, 0.0])

    def clearance(self, points: object) -> np.ndarray:
        """The exact clearance (m) at ``points`` ``(..., 2)``: to the nearest circle or wall."""
        xy = floats("points", points)
        walls = 0.5 * self.width - np.abs(xy[..., 1])
        if not len(self.radii):
            return walls
        gaps = np.linalg.norm(xy[..., None, :] - self.centres, axis=-1) - self.radii
        return np.minimum(walls, gaps.min(axis=-1))

    def touches(self, poses: object, footprint: float) -> np.ndarray:
        """Whether a robot of radius ``footprint`` (m) at each of ``poses`` ``(..., 3)``
        overlaps a circle or a wall."""
        return self.clearance(floats("poses", poses)[..., :2]) < footprint


def cluttered_corridor(
    rng: np.random.Generator,
    *,
    length: float = 12.0,
    width: float = 3.0,
    count: int = 8,
    radii: tuple[float, float] = (0.15, 0.4),
    footprint: float = 0.35,
    slack: float = 0.1,
    resolution: float = 0.05,
) -> Course:
    """A random course (see the module): ``count`` circles of radii uniform in ``radii`` (m),
    centres uniform over ``x`` in ``[1.5, length - 1.5]`` and across the corridor, redrawn
    until a robot of radius ``footprint + slack`` has a way through."""
    length, width = positive("length", length), positive("width", width)
    count = whole("count", count)
    low, high = radii
    if not 0 < low <= high:
        raise ValueError(f"radii must be (smallest, largest) > 0, got {radii!r}")
    if 2 * (footprint + slack) >= width:
        raise ValueError(f"a robot of radius {footprint} m + {slack} m does not fit in {width} m")
    for _ in range(1000):
        sizes = rng.uniform(low, high, count)
        centres = np.column_stack(
            [rng.uniform(1.5, length - 1.5, count), rng.uniform(-0.5, 0.5, count) * width]
        )
        course = _course(length, width, centres, sizes, resolution)
        if _way_through(course, footprint + slack):
            return course
    raise ValueError(f"no way through after 1000 draws of {count} circles: fewer or smaller")


def _course(length, width, centres, sizes, resolution) -> Course:
    """The course and its grid, a metre beyond the corridor's ends."""
    bounds = (-1.0, -0.5 * width - 0.5, length + 1.0, 0.5 * width + 0.5)
    circles = Obstacles.from_circles(centres, sizes, resolution=resolution, bounds=bounds)
    rows, cols = circles.clearance.shape
    ys = bounds[1] + resolution * np.arange(rows)
    walls = np.broadcast_to((0.5 * width - np.abs(ys))[:, None], (rows, cols))
    grid = Obstacles(np.minimum(circles.clearance, walls), circles.origin, resolution)
    return Course(length, width, centres, sizes, grid)


def _way_through(course: Course, radius: float) -> bool:
    """Whether the grid's nodes clear by ``radius`` connect the start to the goal (scipy's
    connected components, diagonal neighbours included)."""
    from scipy.ndimage import label

    grid = course.obstacles
    parts, _ = label(grid.clearance >= radius, structure=np.ones((3, 3)))

    def part(point: np.ndarray) -> int:
        i = round((point[1] - grid.origin[1]) / grid.resolution)
        return int(parts[i, round((point[0] - grid.origin[0]) / grid.resolution)])

    return part(course.start) != 0 and part(course.start) == part(course.goal)
