"""Online 2-D occupancy grid from depth + pose, with frontiers and path distances (VLFM-style mapping).

The grid covers the xz plane around the episode's start (``size`` metres square, ``cell_size`` cells);
cell ``(row, col)`` spans ``x in origin_x + col * cell``, ``z in origin_z + row * cell``. Each cell is
*unknown*, *free* or *occupied*; *explored* = free or occupied.

One depth frame updates the grid (all vectorised, no per-pixel Python):

1. With the camera level (a pure yaw, as the agent's is), every image column is one horizontal ray
   direction, so each pixel's horizontal range is ``depth * sqrt(1 + ((u - cx) / fx)^2)`` and its height
   above the floor is ``camera_height + (cy - v) * depth / fy``.
2. Obstacle pixels: measured depth (normalised value in (0, 1): 0 is "nearer than min_depth or nothing
   hit" and 1 is "at or beyond max_depth", neither a surface position) whose height lies in
   ``[obstacle_min_height, obstacle_max_height]`` and range <= ``max_range``.
3. A polar scan: per column, free space reaches the nearest obstacle hit, or, without a hit, the
   farthest range any valid pixel of that column saw (a clipped max-depth pixel proves its ray free
   up to ``max_depth``), capped at ``max_range``. The fan of these end points around the camera is
   filled free with ``cv2.fillPoly``; obstacle pixels are then marked occupied (sticky: a cell once
   seen as obstacle stays so, since the scenes are static). The agent's own footprint is always free.

Planning: *traversable* = free cells farther than ``agent_radius`` from every occupied cell (the
obstacles inflated by the radius). Unknown space is NOT traversable: the agent plans only over space it
has seen free; frontiers lie on that space's boundary, so every reachable frontier has a finite path
distance. Path distances are geodesics from the fast marching method (scikit-fmm, ~0.1-1% error;
8-connected Dijkstra overestimates by 4-8%), computed on the explored bounding box only.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import cv2
import numpy as np
import skfmm
from sklearn.cluster import KMeans
from threadpoolctl import ThreadpoolController

from navbench.scene.pose import vector_length

UNKNOWN, FREE, OCCUPIED = 0, 1, 2

_KMEANS_CACHE_SIZE = 256  # split results kept per map: most frontier clusters come back unchanged next step
_threadpools: ThreadpoolController | None = None


def _split_cluster(cells: np.ndarray, k: int) -> np.ndarray:
    """K-means labels of one long frontier cluster's cells (deterministic: ``random_state=0``).

    Run on one OpenMP thread: the clusters are a few hundred cells, for which sklearn's threads cost ~15x
    the work itself (they spin between its many tiny parallel loops). The labels are the same for any
    thread count: the cells are integers, so every centre sum is exact in any order."""
    global _threadpools
    if _threadpools is None:
        _threadpools = ThreadpoolController()
    with _threadpools.limit(limits=1, user_api="openmp"):
        return KMeans(n_clusters=k, n_init=1, random_state=0).fit_predict(cells.astype(np.float64))


class OccupancyError(ValueError):
    """Bad occupancy-map input (config value, depth shape); the message names the value."""


@dataclass(frozen=True)
class OccupancyConfig:
    cell_size: float = 0.05  # m; doorways (>= 0.9 m) keep >= 10 traversable cells after inflation
    size: float = 40.0  # m; square extent of the grid, centred on the episode start
    obstacle_min_height: float = 0.15  # m above the floor; lower things (rugs, thresholds) are driven over
    obstacle_max_height: float = 0.88  # m; the agent's height: anything higher passes above it (VLFM's value)
    agent_radius: float = 0.18  # m; obstacle inflation for planning
    # m; extra clearance planned paths keep from obstacles (shortest paths otherwise graze every corner at
    # exactly the agent radius, and a discrete forward step then bumps it); callers may plan without it
    planning_margin: float = 0.1
    max_range: float = 5.0  # m; the depth sensor's range: beyond it nothing is mapped
    min_frontier_size: float = 0.3  # m; frontier clusters with fewer cells than this / cell_size are noise
    # m; longer clusters (e.g. the whole 5 m ring after a look-around in a big room) are split by k-means
    # into pieces of about this many cells * cell_size, so each piece has a meaningful midpoint
    max_frontier_size: float = 3.0

    def __post_init__(self) -> None:
        if not 0.0 < self.cell_size < self.size:
            raise OccupancyError(f"OccupancyConfig needs 0 < cell_size < size, got {self.cell_size}, {self.size}")
        if not 0.0 <= self.obstacle_min_height < self.obstacle_max_height:
            raise OccupancyError(f"OccupancyConfig obstacle band is empty: [{self.obstacle_min_height}, "
                                 f"{self.obstacle_max_height}]")
        if self.max_range <= 0.0 or self.agent_radius < 0.0:
            raise OccupancyError(f"OccupancyConfig needs max_range > 0 and agent_radius >= 0, got "
                                 f"{self.max_range}, {self.agent_radius}")


@dataclass(frozen=True)
class Frontier:
    """One frontier cluster: its cells, the goal cell (reachable cell nearest the cluster's centroid,
    VLFM's frontier midpoint) and the path distance from the agent to that goal cell."""

    cells: np.ndarray  # (N, 2) int (row, col)
    goal_cell: tuple[int, int]
    goal: np.ndarray  # world [x, y, z] of the goal cell's centre (y = floor)
    distance: float  # m, path distance from the agent (inf when unreachable)

    @property
    def size(self) -> int:
        return len(self.cells)


class OccupancyMap:
    """The online grid. ``reset(origin)`` centres it on a world point; ``update`` integrates one frame."""

    def __init__(self, config: OccupancyConfig = OccupancyConfig()):
        self.config = config
        self.n = int(math.ceil(config.size / config.cell_size))
        # (cells bytes, shape, k) -> k-means labels: a pure function of the cells, so kept across steps
        self._splits: OrderedDict[tuple, np.ndarray] = OrderedDict()
        self._clear_for: np.ndarray | None = None  # the occupied mask self._clear was computed from
        self._clear: np.ndarray | None = None
        self.reset(np.zeros(3))

    # ------------------------------------------------------------------------------------ frames
    def reset(self, centre: np.ndarray) -> None:
        centre = np.asarray(centre, np.float64)
        half = self.n * self.config.cell_size / 2.0
        self.origin = np.array([centre[0] - half, centre[2] - half])  # world (x, z) of cell (0, 0)'s corner
        self.floor_y = float(centre[1])
        self.grid = np.zeros((self.n, self.n), np.uint8)

    def to_cell(self, xz: np.ndarray) -> np.ndarray:
        """World (..., 2) [x, z] -> integer cells (..., 2) [row, col] (may lie outside the grid)."""
        xz = np.asarray(xz, np.float64)
        cr = np.floor((xz - self.origin) / self.config.cell_size).astype(np.int64)  # (col, row)
        return cr[..., ::-1]

    def to_world(self, cells: np.ndarray) -> np.ndarray:
        """Cells (..., 2) [row, col] -> world (..., 3) cell centres on the floor."""
        rc = np.asarray(cells, np.float64)
        x = self.origin[0] + (rc[..., 1] + 0.5) * self.config.cell_size
        z = self.origin[1] + (rc[..., 0] + 0.5) * self.config.cell_size
        return np.stack([x, np.full_like(x, self.floor_y), z], axis=-1)

    def inside(self, cells: np.ndarray) -> np.ndarray:
        cells = np.asarray(cells)
        return (cells >= 0).all(axis=-1) & (cells < self.n).all(axis=-1)

    @property
    def free(self) -> np.ndarray:
        return self.grid == FREE

    @property
    def occupied(self) -> np.ndarray:
        return self.grid == OCCUPIED

    @property
    def explored(self) -> np.ndarray:
        return self.grid != UNKNOWN

    # ------------------------------------------------------------------------------------ update
    def update(self, depth_norm: np.ndarray, K: np.ndarray, position: np.ndarray, yaw: float,
               camera_height: float, min_depth: float, max_depth: float) -> None:
        """Integrate one depth frame.

        ``depth_norm`` (H, W) or (H, W, 1): Habitat-normalised depth in [0, 1] over [min_depth, max_depth];
        ``position``: the agent's world position on the floor, ``yaw`` its heading; the camera is
        ``camera_height`` above the floor, level, looking along the heading.
        """
        cfg = self.config
        d = np.asarray(depth_norm, np.float64)
        if d.ndim == 3 and d.shape[-1] == 1:
            d = d[..., 0]
        if d.ndim != 2:
            raise OccupancyError(f"depth must be (H, W) or (H, W, 1), got shape {np.shape(depth_norm)}")
        h, w = d.shape
        z = d * (max_depth - min_depth) + min_depth  # metres along the optical axis
        valid = d > 0.0  # 0: nearer than min_depth or nothing hit - no range information either way
        clipped = d >= 1.0  # at or beyond max_depth: the ray is free up to max_depth, the surface unknown
        tan_u = (np.arange(w) - K[0, 2]) / K[0, 0]  # per column: x / depth in the camera frame
        rng = z * np.sqrt(1.0 + tan_u**2)[None, :]  # horizontal range of every pixel
        height = camera_height + (K[1, 2] - np.arange(h))[:, None] / K[1, 1] * z
        obstacle = valid & ~clipped & (height >= cfg.obstacle_min_height) & \
            (height <= cfg.obstacle_max_height) & (rng <= cfg.max_range)

        hit = np.where(obstacle, rng, np.inf).min(axis=0)
        seen = np.where(valid, rng, 0.0).max(axis=0)
        free_r = np.minimum(np.where(np.isfinite(hit), hit, seen), cfg.max_range)

        # Camera-frame ray directions (x right, -z forward) -> world xz by the heading.
        c, s = math.cos(yaw), math.sin(yaw)
        norm = np.sqrt(1.0 + tan_u**2)
        rx, rz = tan_u / norm, -1.0 / norm
        wx, wz = c * rx + s * rz, -s * rx + c * rz  # rotation by yaw about +y
        px, pz = float(position[0]), float(position[2])
        ends = np.stack([px + free_r * wx, pz + free_r * wz], axis=1)
        fan = np.vstack([[px, pz], ends])
        shift = 4  # sub-cell polygon vertices (cv2 fixed point)
        pts = np.round((fan - self.origin) / cfg.cell_size * (1 << shift)).astype(np.int32)
        free_mask = np.zeros_like(self.grid)
        cv2.fillPoly(free_mask, [pts.reshape(-1, 1, 2)], 1, lineType=cv2.LINE_8, shift=shift)
        # The fill lies within the fan's bounding box (vertices rounded to cells, plus a cell of slack): only
        # that part of the grid needs updating.
        lo = np.maximum((pts.min(axis=0) >> shift) - 2, 0)
        hi = np.minimum((pts.max(axis=0) >> shift) + 3, self.n)  # (x, y) = (col, row)
        box = (slice(lo[1], hi[1]), slice(lo[0], hi[0]))
        sub = self.grid[box]
        sub[(free_mask[box] > 0) & (sub != OCCUPIED)] = FREE

        rows, cols = np.nonzero(obstacle)
        if len(rows):
            pr = rng[rows, cols] / norm[cols]  # depth again (exact: rng / norm == z)
            ox = px + pr * (c * tan_u[cols] - s)
            oz = pz + pr * (-s * tan_u[cols] - c)
            cells = self.to_cell(np.stack([ox, oz], axis=1))
            cells = cells[self.inside(cells)]
            self.grid[cells[:, 0], cells[:, 1]] = OCCUPIED
        self.mark_footprint(position)

    def mark_footprint(self, position: np.ndarray) -> None:
        """The agent stands here: its disk is free (it would otherwise stay unknown below the camera's view)."""
        cell = self.to_cell(np.asarray(position, np.float64)[[0, 2]])
        r = max(1, int(round(self.config.agent_radius / self.config.cell_size)))
        # The disk drawn in a patch around it (integer centre and radius: the same cells as on the whole grid).
        r0, c0 = max(int(cell[0]) - r - 1, 0), max(int(cell[1]) - r - 1, 0)
        r1, c1 = min(int(cell[0]) + r + 2, self.n), min(int(cell[1]) + r + 2, self.n)
        if r0 >= r1 or c0 >= c1:
            return
        disk = np.zeros((r1 - r0, c1 - c0), np.uint8)
        cv2.circle(disk, (int(cell[1]) - c0, int(cell[0]) - r0), r, 1, -1)
        sub = self.grid[r0:r1, c0:c1]
        sub[(disk > 0) & (sub != OCCUPIED)] = FREE

    def mark_occupied(self, point: np.ndarray) -> None:
        """Mark the cell of a world point occupied (e.g. a bump the depth camera could not see)."""
        cell = self.to_cell(np.asarray(point, np.float64)[[0, 2]])
        if self.inside(cell):
            self.grid[cell[0], cell[1]] = OCCUPIED

    def line_of_sight(self, a: np.ndarray, b: np.ndarray, traversable: np.ndarray) -> bool:
        """True when the straight segment between world points ``a`` and ``b`` crosses only traversable cells."""
        a, b = np.asarray(a, np.float64)[[0, 2]], np.asarray(b, np.float64)[[0, 2]]
        n = max(2, int(math.ceil(vector_length(b - a) / (self.config.cell_size / 2))) + 1)
        cells = self.to_cell(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
        if not self.inside(cells).all():
            return False
        return bool(traversable[cells[:, 0], cells[:, 1]].all())

    # ---------------------------------------------------------------------------------- planning
    def _window(self, margin: int = 2) -> tuple[slice, slice]:
        """Bounding box of the explored cells plus a margin: all planning happens inside it."""
        rows = np.flatnonzero(self.grid.any(axis=1))  # explored = nonzero
        cols = np.flatnonzero(self.grid.any(axis=0))
        if not len(rows):
            return slice(0, 0), slice(0, 0)
        return (slice(max(rows[0] - margin, 0), min(rows[-1] + margin + 1, self.n)),
                slice(max(cols[0] - margin, 0), min(cols[-1] + margin + 1, self.n)))

    def traversable(self, inflation: float | None = None) -> np.ndarray:
        """Free cells farther than ``inflation`` (default: agent radius + planning margin) from every
        occupied cell."""
        r = self.config.agent_radius + self.config.planning_margin if inflation is None else inflation
        free = self.free
        if r <= 0.0:
            return free
        clear = self.clearance()
        if clear is None:
            return free
        return free & (clear * self.config.cell_size > r)

    def _traversable_in(self, rs: slice, cs: slice, inflation: float | None = None) -> np.ndarray:
        """``traversable(inflation)[rs, cs]``, computed on that window only (a new array)."""
        r = self.config.agent_radius + self.config.planning_margin if inflation is None else inflation
        free = self.grid[rs, cs] == FREE
        if r <= 0.0:
            return free
        clear = self.clearance()
        if clear is None:
            return free
        return free & (clear[rs, cs] * self.config.cell_size > r)

    def clearance(self) -> np.ndarray | None:
        """Distance (cells; cv2's 5x5 L2 chamfer) from every cell to the nearest occupied cell, None while
        nothing is occupied. Read-only: the transform is kept and handed out again until the occupied cells
        change (of the whole 800 x 800 grid it was the planner's largest cost, and the agent plans up to
        three times a step, most steps mapping no new obstacle)."""
        occupied = self.occupied
        if self._clear_for is not None and np.array_equal(occupied, self._clear_for):
            return self._clear
        clear = None
        if occupied.any():
            clear = cv2.distanceTransform(np.where(occupied, 0, 1).astype(np.uint8), cv2.DIST_L2, 5)
            clear.flags.writeable = False
        self._clear_for, self._clear = occupied, clear
        return clear

    def path_distance(self, source: np.ndarray, inflation: float | None = None) -> np.ndarray:
        """Geodesic distance (m) over traversable cells from the world point ``source`` to every cell
        (inf where unreachable or outside the explored window). The free cells of the agent's footprint
        around the source always count as traversable: the agent may stand closer to a wall than the
        inflated map allows, and must still be able to plan its way out."""
        out = np.full((self.n, self.n), np.inf)
        src = self.to_cell(np.asarray(source, np.float64)[[0, 2]])
        if not self.inside(src):
            return out
        rs, cs = self._window()
        trav = self._traversable_in(rs, cs, inflation)
        r0, c0 = int(src[0]) - rs.start, int(src[1]) - cs.start
        if not (0 <= r0 < trav.shape[0] and 0 <= c0 < trav.shape[1]):
            return out
        foot = np.zeros(trav.shape, np.uint8)
        cv2.circle(foot, (c0, r0), max(1, int(round(self.config.agent_radius / self.config.cell_size))), 1, -1)
        trav |= (foot > 0) & (self.grid[rs, cs] == FREE)
        trav[r0, c0] = True
        phi = np.ones(trav.shape)
        phi[r0, c0] = -1.0
        try:
            dist = skfmm.distance(np.ma.MaskedArray(phi, ~trav), dx=self.config.cell_size)
        except ValueError:  # skfmm refuses a field whose zero contour touches only masked cells
            return out
        d = np.ma.filled(dist, np.inf).astype(np.float64)
        # skfmm measures to the zero contour, half a cell from the source centre; the source is at 0.
        d[trav] += self.config.cell_size / 2.0
        d[r0, c0] = 0.0
        out[rs, cs] = d
        return out

    def frontier_mask(self) -> np.ndarray:
        """Free cells 8-adjacent to unknown space and not 8-adjacent to an occupied cell."""
        mask = np.zeros(self.grid.shape, bool)
        rs, cs = self._window()
        if rs.start < rs.stop and cs.start < cs.stop:
            mask[rs, cs] = self._frontier_mask_in(rs, cs)
        return mask

    def _frontier_mask_in(self, rs: slice, cs: slice) -> np.ndarray:
        """:meth:`frontier_mask` inside the explored window (all free cells are there, each with its 8
        neighbours: the window's margin is 2; where it ends at the grid's edge, so does the full grid)."""
        grid = self.grid[rs, cs]
        k = np.ones((3, 3), np.uint8)
        near_unknown = cv2.dilate((grid == UNKNOWN).astype(np.uint8), k) > 0
        near_occupied = cv2.dilate((grid == OCCUPIED).astype(np.uint8), k) > 0
        return (grid == FREE) & near_unknown & ~near_occupied

    def frontiers(self, distance: np.ndarray | None = None, exclude: np.ndarray | None = None) -> list[Frontier]:
        """Frontier clusters (8-connected components of :meth:`frontier_mask` minus the ``exclude`` mask,
        with at least ``min_frontier_size / cell_size`` cells; longer ones split into pieces of about
        ``max_frontier_size``), nearest first by ``distance`` (a :meth:`path_distance` field; without
        one, all distances are inf)."""
        cfg = self.config
        # The mask is built in the explored window, but labelled on the whole grid: cv2 numbers the components
        # in an order that depends on the image (its size, parity, stripes), and that order breaks distance ties.
        rs, cs = self._window()
        if not (rs.start < rs.stop and cs.start < cs.stop):
            return []
        window = self._frontier_mask_in(rs, cs)
        if exclude is not None:
            window &= ~exclude[rs, cs]
        mask = np.zeros(self.grid.shape, np.uint8)
        mask[rs, cs] = window
        n_lab, labels = cv2.connectedComponents(mask, connectivity=8)
        min_cells = max(1, int(round(cfg.min_frontier_size / cfg.cell_size)))
        max_cells = max(min_cells, int(round(cfg.max_frontier_size / cfg.cell_size)))
        out: list[Frontier] = []
        if n_lab <= 1:
            return out
        rows, cols = np.nonzero(labels[rs, cs])  # every label lies in the window; raster order as on the grid
        lab = labels[rs, cs][rows, cols]
        rows, cols = rows + rs.start, cols + cs.start
        order = np.argsort(lab, kind="stable")
        rows, cols, lab = rows[order], cols[order], lab[order]
        splits = np.flatnonzero(np.diff(lab)) + 1
        pieces: list[np.ndarray] = []
        for r, c in zip(np.split(rows, splits), np.split(cols, splits)):
            if len(r) < min_cells:
                continue
            cells = np.stack([r, c], axis=1)
            k = int(math.ceil(len(cells) / max_cells))
            if k == 1:
                pieces.append(cells)
                continue
            parts = self._split(cells, k)
            pieces.extend(cells[parts == i] for i in range(k) if (parts == i).any())
        for cells in pieces:
            r, c = cells[:, 0], cells[:, 1]
            d = distance[r, c] if distance is not None else np.full(len(r), np.inf)
            pool = np.flatnonzero(np.isfinite(d))
            if not len(pool):
                pool = np.arange(len(r))
            centroid = cells.mean(axis=0)
            j = pool[int(np.argmin(((cells[pool] - centroid) ** 2).sum(axis=1)))]
            out.append(Frontier(cells, (int(r[j]), int(c[j])), self.to_world(cells[j]), float(d[j])))
        out.sort(key=lambda f: f.distance)
        return out

    def _split(self, cells: np.ndarray, k: int) -> np.ndarray:
        """:func:`_split_cluster`, remembered for the last ``_KMEANS_CACHE_SIZE`` distinct clusters."""
        key = (cells.tobytes(), cells.shape, cells.dtype.str, k)
        parts = self._splits.get(key)
        if parts is None:
            parts = self._splits[key] = _split_cluster(cells, k)
            if len(self._splits) > _KMEANS_CACHE_SIZE:
                self._splits.popitem(last=False)
        else:
            self._splits.move_to_end(key)
        return parts


def trace_path(distance: np.ndarray, target: tuple[int, int], max_cells: int = 100_000) -> np.ndarray:
    """Cells (N, 2) from the source of a :meth:`OccupancyMap.path_distance` field to ``target``, by steepest
    descent from the target over 8-neighbours (empty when the target is unreachable)."""
    r, c = target
    if not np.isfinite(distance[r, c]):
        return np.zeros((0, 2), np.int64)
    path = [(r, c)]
    n0, n1 = distance.shape
    for _ in range(max_cells):
        if distance[r, c] <= 0.0:
            break
        r0, r1, c0, c1 = max(r - 1, 0), min(r + 2, n0), max(c - 1, 0), min(c + 2, n1)
        patch = distance[r0:r1, c0:c1]
        i = int(np.argmin(patch))
        nr, nc = r0 + i // patch.shape[1], c0 + i % patch.shape[1]
        if distance[nr, nc] >= distance[r, c]:
            break  # a local minimum of the discrete field: close enough to the source
        r, c = nr, nc
        path.append((r, c))
    return np.asarray(path[::-1], np.int64)
