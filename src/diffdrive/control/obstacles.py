"""Obstacles as a clearance field: how far each point of the plane is from the nearest one.

``Obstacles`` holds the signed clearance (m) on a grid of nodes: node ``(i, j)`` (row, column)
lies at ``origin + resolution * (j, i)``, so row 0 is the lowest ``y``; positive outside the
obstacles, negative inside. Between nodes the clearance is bilinear, and outside the grid the
nearest edge node's holds (so give the grid a margin). A controller asks it where a robot of
radius ``r`` would touch (clearance < ``r``).

Made from:

- circles (``from_circles``): exact at every node, the distance to the nearest circle's edge;
- an occupancy grid (``from_occupancy``, a boolean array, True occupied, row 0 the lowest
  ``y``): each cell's centre is a node; the clearance is the Euclidean distance transform
  (scipy) between cell centres less half a cell, so a free cell next to an occupied one has
  half a cell;
- a ROS map (``read_map``): the ``map.yaml`` that ROS map servers (map_server, Nav2's
  map_saver) write and the image it names, read as they read it (``mode: trinary``: a pixel is
  occupied above ``occupied_thresh``, free below ``free_thresh``; unknown counts as occupied;
  ``negate`` honoured; the image's top row is the map's highest ``y``). A rotated origin
  (``yaw`` other than 0) is refused: map servers do not rotate the image either.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from diffdrive._validate import check_samples, floats, positive

__all__ = ["Obstacles", "read_map"]


@dataclass(frozen=True, eq=False)
class Obstacles:
    """The signed clearance ``clearance`` ``(H, W)`` (m) at nodes ``origin + resolution *
    (j, i)`` (see the module)."""

    clearance: np.ndarray
    origin: tuple[float, float]
    resolution: float

    def __post_init__(self) -> None:
        grid = np.ascontiguousarray(self.clearance, dtype=float)
        if grid.ndim != 2 or min(grid.shape) < 2:
            raise ValueError(f"clearance must be a grid (H, W) of 2 x 2 or more, got {grid.shape}")
        if not np.all(np.isfinite(grid)):
            raise ValueError("clearance must be finite")
        origin = floats("origin", self.origin)
        if origin.shape != (2,) or not np.all(np.isfinite(origin)):
            raise ValueError(f"origin must be a finite (x, y) in m, got {self.origin!r}")
        grid.setflags(write=False)
        object.__setattr__(self, "clearance", grid)
        object.__setattr__(self, "origin", (float(origin[0]), float(origin[1])))
        object.__setattr__(self, "resolution", positive("resolution", self.resolution))

    @classmethod
    def from_circles(
        cls,
        centres: object,
        radii: object,
        *,
        resolution: float = 0.05,
        bounds: tuple[float, float, float, float] | None = None,
        margin: float = 2.0,
    ) -> Obstacles:
        """Circles of ``centres`` ``(N, 2)`` and ``radii`` ``(N,)`` (m) on a grid of
        ``resolution`` m over ``bounds`` ``(x_min, y_min, x_max, y_max)`` (default: the
        circles' extent and ``margin`` m around it)."""
        points = floats("centres", centres).reshape(-1, 2)
        sizes = np.broadcast_to(floats("radii", radii), (len(points),))
        if not (np.all(np.isfinite(points)) and np.all(np.isfinite(sizes)) and np.all(sizes > 0)):
            raise ValueError("centres must be finite and radii finite and > 0")
        resolution = positive("resolution", resolution)
        if bounds is None:
            if not len(points):
                raise ValueError("no circles: give bounds for an empty field")
            low, high = (points - sizes[:, None]).min(0), (points + sizes[:, None]).max(0)
            bounds = (low[0] - margin, low[1] - margin, high[0] + margin, high[1] + margin)
        x0, y0, x1, y1 = (float(b) for b in bounds)
        if not (x1 > x0 and y1 > y0 and all(map(math.isfinite, (x0, y0, x1, y1)))):
            raise ValueError(f"bounds must be finite (x_min, y_min, x_max, y_max), got {bounds}")
        cols, rows = math.ceil((x1 - x0) / resolution) + 1, math.ceil((y1 - y0) / resolution) + 1
        check_samples(rows * cols * max(len(points), 1), "the circles' grid", "a coarser grid")
        xs, ys = x0 + resolution * np.arange(cols), y0 + resolution * np.arange(rows)
        field = np.full((rows, cols), np.hypot(x1 - x0, y1 - y0) + 2 * margin)
        for (cx, cy), r in zip(points, sizes, strict=True):
            edge = np.hypot(xs[None, :] - cx, ys[:, None] - cy) - r
            np.minimum(field, edge, out=field)
        return cls(field, (x0, y0), resolution)

    @classmethod
    def from_occupancy(cls, occupied: object, origin: object, resolution: float) -> Obstacles:
        """An occupancy grid ``occupied`` ``(H, W)`` (True: occupied; row 0 the lowest ``y``)
        whose cell ``(0, 0)`` has its centre at ``origin`` ``(x, y)`` (m), cells ``resolution``
        m wide. Needs scipy."""
        from scipy.ndimage import distance_transform_edt

        cells = np.asarray(occupied)
        if cells.ndim != 2 or cells.dtype != bool:
            raise ValueError(
                f"occupied must be a boolean grid (H, W), got {cells.dtype} {cells.shape}"
            )
        resolution = positive("resolution", resolution)
        if not cells.any():
            field = np.full(cells.shape, resolution * float(sum(cells.shape)))
        elif cells.all():
            field = np.full(cells.shape, -resolution * float(sum(cells.shape)))
        else:
            outside = distance_transform_edt(~cells) * resolution - 0.5 * resolution
            inside = distance_transform_edt(cells) * resolution - 0.5 * resolution
            field = np.where(cells, -inside, outside)
        return cls(field, tuple(floats("origin", origin).tolist()), resolution)

    def clearance_at(self, points: object) -> np.ndarray:
        """The clearance (m) at ``points`` ``(..., 2)``: bilinear between nodes, the edge held
        outside (as the compiled MPPI cycle reads it)."""
        xy = floats("points", points)
        rows, cols = self.clearance.shape
        gx = np.clip((xy[..., 0] - self.origin[0]) / self.resolution, 0.0, cols - 1.0)
        gy = np.clip((xy[..., 1] - self.origin[1]) / self.resolution, 0.0, rows - 1.0)
        i = np.minimum(gy.astype(int), rows - 2)
        j = np.minimum(gx.astype(int), cols - 2)
        fy, fx = gy - i, gx - j
        g = self.clearance
        top = g[i, j] + fx * (g[i, j + 1] - g[i, j])
        bottom = g[i + 1, j] + fx * (g[i + 1, j + 1] - g[i + 1, j])
        return top + fy * (bottom - top)


def read_map(path: str | Path) -> Obstacles:
    """The ``Obstacles`` of a ROS map: ``path`` is its ``map.yaml`` (see the module). Needs
    PyYAML, Pillow and scipy."""
    import yaml
    from PIL import Image

    path = Path(path)
    try:
        meta = yaml.safe_load(path.read_text())
    except yaml.YAMLError as error:
        raise ValueError(f"{path}: not YAML: {error}") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: a map.yaml holds keys (image, resolution, origin, ...)")
    for key in ("image", "resolution", "origin"):
        if key not in meta:
            raise ValueError(
                f"{path}: the map's {key} is missing (image, resolution and origin are required)"
            )
    origin = meta["origin"]
    if not (isinstance(origin, list) and len(origin) in (2, 3)):
        raise ValueError(f"{path}: origin must be [x, y, yaw], got {origin!r}")
    if len(origin) == 3 and float(origin[2]) != 0.0:
        raise ValueError(
            f"{path}: origin yaw {origin[2]} is not 0: a rotated map is not read "
            "(map servers do not rotate the image either)"
        )
    mode = meta.get("mode", "trinary")
    if mode not in ("trinary", "scale"):
        raise ValueError(f"{path}: mode {mode!r} is not read (trinary or scale)")
    resolution = positive(f"{path}: resolution", meta["resolution"])
    occupied_at, free_at = (
        float(meta.get("occupied_thresh", 0.65)),
        float(meta.get("free_thresh", 0.196)),
    )
    image_path = path.parent / str(meta["image"])
    try:
        with Image.open(image_path) as image:
            pixels = np.asarray(image.convert("L"), dtype=float)
    except (OSError, ValueError) as error:
        raise ValueError(f"{path}: its image {image_path} could not be read: {error}") from None
    # Dark is occupied: p = (255 - pixel) / 255, or pixel / 255 when negated.
    p = pixels / 255.0 if int(meta.get("negate", 0)) else (255.0 - pixels) / 255.0
    # Free only below free_thresh: unknown (between) counts as occupied, as a planner would.
    occupied = ~(p < free_at) if mode == "trinary" else p > occupied_at
    # The image's top row is the highest y; cell (0, 0)'s centre half a cell in from origin.
    centre = (float(origin[0]) + 0.5 * resolution, float(origin[1]) + 0.5 * resolution)
    return Obstacles.from_occupancy(occupied[::-1].copy(), centre, resolution)
