"""Navigability grid, geodesic distances and collision-checked motion for one floor of a scene.

A :class:`NavGrid` is a 2-D occupancy grid over the xz plane at one floor level, built from any
triangle mesh (world frame, y up). It plays the role of Habitat's navmesh: point queries, snapping,
sampling, islands, geodesic distances (fast marching, cached per goal set) and the agent's motion
with and without wall sliding.

Grid layout: ``navigable[i, j]`` is the cell whose centre is at world
``x = origin[0] + j * cell_size``, ``z = origin[1] + i * cell_size`` (rows follow +z, columns +x);
a world point belongs to the cell whose centre is nearest. All positions returned have
``y = floor_height``; the y of query points is ignored (one floor per grid), except that goals on another
storey of a multi-storey mesh never count (:meth:`NavGrid.on_storey`).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import skfmm
import trimesh
from scipy import ndimage
from scipy.spatial import cKDTree

from navbench.scene.asset import SceneError

# A surface is floor-like if its normal is within ~45 deg of vertical.
_HORIZONTAL_NY = 0.7
# Cells the goal's exact-distance disc spans in the fast-marching initialisation (see distance_field).
_GOAL_DISC_CELLS = 1.5
# Slowest speed of a clearance-weighted field (distance_field(margin=...)), on the navigable boundary.
_MIN_SPEED = 0.3


def grid_cells(lo: np.ndarray, hi: np.ndarray, cs: float) -> tuple[int, int, np.ndarray, np.ndarray, np.ndarray]:
    """(width, height, origin, x, z of every cell centre, row-major) of a grid of ``cs`` cells over the
    bounds ``lo``-``hi``. One ring of cells lies beyond the bounds, so the border is never free; cell *edges*
    (not centres) fall on the bounds, so a floor ending at the bounds ends between two centres."""
    w = int(math.ceil((hi[0] - lo[0]) / cs - 1e-9)) + 2
    h = int(math.ceil((hi[2] - lo[2]) / cs - 1e-9)) + 2
    origin = np.array([lo[0] - cs / 2, lo[2] - cs / 2])
    jj, ii = np.meshgrid(np.arange(w), np.arange(h))
    return w, h, origin, origin[0] + jj.ravel() * cs, origin[1] + ii.ravel() * cs


@dataclass(frozen=True)
class NavGridConfig:
    agent_height: float = 0.88
    agent_radius: float = 0.18
    max_climb: float = 0.2
    cell_size: float = 0.05
    largest_island: bool = True
    floor_height: float | None = None  # None: the floor level with the largest walkable area
    max_goal_snap: float = 1.0  # goals (and off-grid starts) farther than this from any navigable cell are ignored
    field_cache_size: int = 32

    def __post_init__(self) -> None:
        for name in ("agent_height", "agent_radius", "cell_size", "max_goal_snap"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"NavGridConfig.{name} must be a positive number, got {value}")
        if not (math.isfinite(self.max_climb) and 0 <= self.max_climb < self.agent_height):
            raise ValueError(f"NavGridConfig.max_climb must be in [0, agent_height), got {self.max_climb}")
        if self.floor_height is not None and not math.isfinite(self.floor_height):
            raise ValueError(f"NavGridConfig.floor_height must be finite or None, got {self.floor_height}")


def storey_levels(heights: np.ndarray, config: NavGridConfig) -> list[np.ndarray]:
    """Heights of walkable surface samples grouped into levels, bottom-up: sorted heights split where two
    consecutive ones are more than half ``max_climb`` apart. A level that still spans more than the agent's
    height is a continuous slope (a ramp, a flight of steps) chaining the floors it joins: it is split again
    where a bin of half ``max_climb`` holds under 5% of its fullest bin's samples (the slope's), and those
    samples dropped. The grid and the layered surfaces find storeys by this one rule."""
    h = np.sort(np.asarray(heights, np.float64).ravel())
    step = config.max_climb / 2 if config.max_climb > 0 else config.cell_size
    out = []
    for level in np.split(h, np.flatnonzero(np.diff(h) > step) + 1):
        if len(level) == 0 or level[-1] - level[0] <= config.agent_height:
            out.append(level)
            continue
        b = np.floor((level - level[0]) / step).astype(np.int64)
        counts = np.bincount(b)
        dense = counts[b] >= 0.05 * counts.max()
        lv, lb = level[dense], b[dense]
        out += np.split(lv, np.flatnonzero(np.diff(lb) > 1) + 1)
    return [lv for lv in out if len(lv)]



def storey_floors(heights: np.ndarray, config: NavGridConfig) -> np.ndarray:
    """Median heights, bottom-up, of the :func:`storey_levels` holding at least 5% of the largest one's samples:
    the floors (and large walkable tops) a treads', landings' or ramp's few samples never make."""
    levels = storey_levels(heights, config)
    if not levels:
        return np.zeros(0)
    counts = np.array([len(lv) for lv in levels])
    return np.array([float(np.median(lv)) for lv in levels])[counts >= 0.05 * counts.max()]

def _points(p, name: str) -> np.ndarray:
    """Float (3,) or (N, 3) array of finite xyz coordinates, or ValueError naming the value."""
    a = np.asarray(p, dtype=float)
    if a.ndim not in (1, 2) or a.shape[-1] != 3:
        raise ValueError(f"{name} must be an xyz point (3,) or points (N, 3), got shape {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} has non-finite coordinates: {a.tolist()}")
    return a


class GeodesicField:
    """Geodesic distance (metres) from every navigable cell to the nearest goal of one goal set.

    ``values[i, j]`` is the distance at cell centre (i, j), ``inf`` on cells not navigable or on an
    island without a goal. Point queries interpolate bilinearly between cell centres; within a few
    cells of a goal they use the exact straight-line distance to it, so the value near the goal
    (where success is decided) does not suffer from the cone-shaped field's interpolation error.
    """

    def __init__(self, grid: NavGrid, goals: np.ndarray, values: np.ndarray, near_goal: np.ndarray):
        self.grid = grid
        self.goals = goals  # (G, 3) goal points actually used (snapped where needed), y = floor
        self.values = values
        self._near_goal = near_goal  # (H, W) int32: index of a goal within a few cells, else -1
        self._ox, self._oz = float(grid.origin[0]), float(grid.origin[1])
        self._cs = grid.cell_size
        self._h, self._w = values.shape

    def distance(self, p) -> float:
        """Geodesic distance from ``p`` to the nearest goal; ``math.inf`` if ``p`` is off every goal's island."""
        x, z = float(p[0]), float(p[2])
        if not (math.isfinite(x) and math.isfinite(z)):
            raise ValueError(f"point has non-finite coordinates: {list(p)}")
        return self._distance_xz(x, z)

    def _distance_xz(self, x: float, z: float) -> float:
        # Same arithmetic as NavGrid._cell (divide, not multiply by the inverse): at exact half-cell
        # coordinates the two would otherwise round to different cells, and a position try_step
        # accepted could read as off-grid (inf).
        gx, gz = (x - self._ox) / self._cs, (z - self._oz) / self._cs
        ic, jc = int(math.floor(gz + 0.5)), int(math.floor(gx + 0.5))
        h, w = self._h, self._w
        if not (0 <= ic < h and 0 <= jc < w):
            return math.inf
        vals = self.values
        if vals[ic, jc] == math.inf:
            return math.inf
        i0, j0 = int(math.floor(gz)), int(math.floor(gx))
        fz, fx = gz - i0, gx - j0
        total = 0.0
        weight = 0.0
        for di, wi in ((0, 1.0 - fz), (1, fz)):
            i = i0 + di
            if wi <= 0.0 or not 0 <= i < h:
                continue
            for dj, wj in ((0, 1.0 - fx), (1, fx)):
                j = j0 + dj
                if wj <= 0.0 or not 0 <= j < w:
                    continue
                v = vals[i, j]
                if v != math.inf:
                    total += wi * wj * v
                    weight += wi * wj
        d = total / weight  # the nearest corner is finite and has weight >= 1/4
        g = self._near_goal[ic, jc]
        if g >= 0:
            goal = self.goals[g]
            d = min(d, math.hypot(x - goal[0], z - goal[2]))
        return d

    def descent_direction(self, p) -> np.ndarray:
        """Unit xz direction ``(x, 0, z)`` of steepest descent at ``p`` (zeros if undefined)."""
        x, z = float(p[0]), float(p[2])
        e = 0.5 * self.grid.cell_size
        gx = self._distance_xz(x + e, z) - self._distance_xz(x - e, z)
        gz = self._distance_xz(x, z + e) - self._distance_xz(x, z - e)
        n = math.hypot(gx, gz)
        if not math.isfinite(n) or n == 0.0:
            return np.zeros(3)
        return np.array([-gx / n, 0.0, -gz / n])


class NavGrid:
    """Walkable cells of one floor of a mesh, eroded by the agent radius (see :meth:`from_mesh`)."""

    def __init__(self, free: np.ndarray, navigable: np.ndarray, origin, cell_size: float,
                 floor_height: float, config: NavGridConfig = NavGridConfig(), storey_top: float = math.inf):
        self.free = np.asarray(free, dtype=bool)  # walkable floor with headroom, before erosion
        self.navigable = np.asarray(navigable, dtype=bool)
        self.origin = np.asarray(origin, dtype=float).reshape(2)  # (x, z) of the centre of cell [0, 0]
        self.cell_size = float(cell_size)
        self.floor_height = float(floor_height)
        # The next walkable level up (another storey's floor, or a roof); inf on a single-storey mesh.
        self.storey_top = float(storey_top)
        self.config = config
        if self.free.shape != self.navigable.shape or self.free.ndim != 2:
            raise ValueError(f"free {self.free.shape} and navigable {self.navigable.shape} must be equal 2-D shapes")
        # Islands are labelled whether or not only the largest one was kept.
        self.islands, self.num_islands = ndimage.label(self.navigable)  # 4-connected; 0 = not navigable
        self._fields: OrderedDict[bytes, GeodesicField] = OrderedDict()
        self._snap_index: np.ndarray | None = None
        self._snap_dist: np.ndarray | None = None
        self._flat_navigable: np.ndarray | None = None
        self._clearance: np.ndarray | None = None
        self._nav_clearance: np.ndarray | None = None

    # ------------------------------------------------------------------ construction

    @classmethod
    def from_mesh(cls, mesh: trimesh.Trimesh, config: NavGridConfig = NavGridConfig()) -> NavGrid:
        """Build the grid of one floor of ``mesh``.

        Method:

        1. Floor level (unless ``config.floor_height`` is given): vertical rays on a coarse grid
           collect every floor-like hit (normal within 45 deg of vertical, either winding) that has
           at least ``agent_height`` of headroom up to the next surface. Hit heights are grouped into
           levels (gaps > max_climb / 2 separate levels); among the levels holding at least half as
           many hits as the largest, the lowest wins (so a roof or a ceiling slab's top, which is as
           large as the floor, does not), and its median height is ``floor_height``.
        2. Surface: per cell, a ray cast down from ``floor_height + max_climb`` must first hit a
           floor-like face at most ``max_climb`` below the floor level.
        3. Headroom: every triangle is clipped to the band ``(floor + max_climb, floor + agent_height]``
           and its xz footprint rasterised (OpenCV fills the polygon and draws its outline, so thin
           vertical walls block the cells they pass through). A ray cast up from the band's bottom
           whose first hit is the back of an upward-facing face starts inside a closed solid
           (a wardrobe, a thick wall), whose outline alone would leave its inside free; that cell is
           blocked too. Normals are assumed to point out of solids (true for GLB/trimesh meshes).
        4. ``free`` = surface and headroom; ``navigable`` = free cells whose centre's clearance (see
           :meth:`_clearance`: Euclidean distance to the head-band geometry's outline, or to the
           floor's edge) is at least ``agent_radius - cell_size / 2``, keeping the
           largest 4-connected island if ``config.largest_island``. The half cell centres the
           grid's boundary on the radius contour: a point belongs to its nearest cell, so the
           navigable area reaches half a cell past the outermost navigable centres, and geodesics
           (computed through navigable centres) are neither shortened nor lengthened on average.
           Of those, only cells near the area Recast's erosion keeps stay (see :meth:`_navmesh_topology`):
           a passage or pocket too narrow for Habitat's navmesh is not navigable here either.
        """
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise SceneError(f"navigability needs a non-empty trimesh.Trimesh, got {type(mesh).__name__}")
        cs = config.cell_size
        lo, hi = mesh.bounds
        if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
            raise SceneError("mesh has non-finite vertex coordinates")
        normals_y = np.asarray(mesh.face_normals)[:, 1]

        floor = config.floor_height if config.floor_height is not None else cls._floor_level(mesh, normals_y, config)

        w, h, origin, xs, zs = grid_cells(lo, hi, cs)

        band_lo = floor + config.max_climb
        band_hi = floor + config.agent_height
        eps = 1e-4
        # 2. surface under each cell
        origins = np.column_stack([xs, np.full(xs.shape, band_lo + eps), zs])
        tri = mesh.ray.intersects_first(origins, np.tile([0.0, -1.0, 0.0], (len(origins), 1)))
        hit = np.flatnonzero(tri >= 0)
        tri = tri[hit]
        flat = np.abs(normals_y[tri]) >= _HORIZONTAL_NY
        hit, tri = hit[flat], tri[flat]
        # Height of the hit from the face's plane (n . p = n . v0), well defined for floor-like faces.
        nrm = np.asarray(mesh.face_normals)[tri]
        v0 = np.asarray(mesh.vertices)[np.asarray(mesh.faces)[tri, 0]]
        y_hit = v0[:, 1] + (nrm[:, 0] * (v0[:, 0] - xs[hit]) + nrm[:, 2] * (v0[:, 2] - zs[hit])) / nrm[:, 1]
        surface = np.zeros(h * w, dtype=bool)
        surface[hit[y_hit >= floor - config.max_climb - eps]] = True
        surface = surface.reshape(h, w)

        # 3. geometry in the head band
        blocked, outline = cls._rasterise_band(mesh, band_lo + eps, band_hi, origin, cs, (h, w))
        cand = np.flatnonzero(surface.ravel() & ~blocked.ravel())
        if len(cand):
            tri = mesh.ray.intersects_first(origins[cand], np.tile([0.0, 1.0, 0.0], (len(cand), 1)))
            inside = (tri >= 0) & (normals_y[np.maximum(tri, 0)] > 0.1)
            blocked.ravel()[cand[inside]] = True
        free = surface & ~blocked
        if not free.any():
            raise SceneError(f"mesh has no walkable floor with {config.agent_height} m headroom at floor height "
                             f"{floor:.3f}")

        # 4. erosion by the agent radius, islands
        clearance = cls._clearance(free, blocked, surface, outline, cs, config.agent_radius)
        navigable = free & (clearance >= config.agent_radius - 0.5 * cs - 1e-9) & cls._navmesh_topology(free, config)
        if not navigable.any():
            raise SceneError(f"no floor space at height {floor:.3f} is wide enough for an agent of radius "
                             f"{config.agent_radius} m")
        if config.largest_island:
            labels, n = ndimage.label(navigable)
            if n > 1:
                sizes = np.bincount(labels.ravel())
                sizes[0] = 0
                navigable = labels == int(np.argmax(sizes))
        grid = cls(free, navigable, origin, cs, floor, config, cls.storey_top_for(mesh, floor, config))
        grid._clearance = clearance
        return grid

    @staticmethod
    def _floor_level(mesh: trimesh.Trimesh, normals_y: np.ndarray, config: NavGridConfig) -> float:
        lo, hi = mesh.bounds
        extent = max(hi[0] - lo[0], hi[2] - lo[2])
        step = max(4 * config.cell_size, extent / 150.0)  # at most ~150 x 150 multi-hit rays
        xs = np.arange(lo[0] + step / 2, hi[0], step)
        zs = np.arange(lo[2] + step / 2, hi[2], step)
        if len(xs) == 0:
            xs = np.array([(lo[0] + hi[0]) / 2])
        if len(zs) == 0:
            zs = np.array([(lo[2] + hi[2]) / 2])
        gx, gz = np.meshgrid(xs, zs)
        origins = np.column_stack([gx.ravel(), np.full(gx.size, hi[1] + 1.0), gz.ravel()])
        locs, ray_idx, tri_idx = mesh.ray.intersects_location(
            origins, np.tile([0.0, -1.0, 0.0], (len(origins), 1)), multiple_hits=True)
        if len(ray_idx) == 0:
            raise SceneError("mesh has no walkable floor: no surface below any vertical ray")
        # Sort hits per ray from the top down; the headroom of a hit is the gap to the hit above it.
        order = np.lexsort((-locs[:, 1], ray_idx))
        ys, rays, tris = locs[order, 1], ray_idx[order], tri_idx[order]
        above = np.full(len(ys), np.inf)
        same_ray = rays[1:] == rays[:-1]
        above[1:][same_ray] = ys[:-1][same_ray]
        walkable = (np.abs(normals_y[tris]) >= _HORIZONTAL_NY) & (above - ys >= config.agent_height)
        heights = np.sort(ys[walkable])
        if len(heights) == 0:
            raise SceneError(f"mesh has no walkable floor: no horizontal surface with {config.agent_height} m headroom")
        levels = storey_levels(heights, config)
        counts = np.array([len(lv) for lv in levels])
        first = int(np.flatnonzero(counts >= 0.5 * counts.max())[0])  # levels are sorted bottom-up
        return float(np.median(levels[first]))

    @classmethod
    def floor_for(cls, mesh: trimesh.Trimesh, y: float, config: NavGridConfig = NavGridConfig()) -> float:
        """Height of the floor a point at height ``y`` stands on (a multi-floor scan's storey).

        Same walkable hits as the default floor choice (see :meth:`from_mesh`), grouped into levels;
        among levels holding at least 5% of the largest one's hits, the highest at most ``max_climb``
        above ``y`` wins, else the nearest; its median height is returned.
        """
        medians = cls._levels(mesh, config)
        if medians is None:
            return cls._floor_level(mesh, np.asarray(mesh.face_normals)[:, 1], config)
        below = medians[medians <= y + config.max_climb]
        return float(below.max()) if len(below) else float(medians[np.argmin(np.abs(medians - y))])

    @classmethod
    def floor_within(cls, mesh: trimesh.Trimesh, lo: float, hi: float, config: NavGridConfig = NavGridConfig()
                     ) -> float | None:
        """Height of the lowest walkable level (as :meth:`floor_for` groups them) between ``lo - max_climb``
        and ``hi``: the floor of a room whose box spans ``[lo, hi]``. A box built from a room's faces (an MP3D
        region, an HM3D room) starts at the underside of its floor slab, below the floor, so ``lo`` itself is
        no floor hint. None when no level lies in the range, or the mesh is too small to tell."""
        medians = cls._levels(mesh, config)
        if medians is None:
            return None
        inside = medians[(medians >= lo - config.max_climb) & (medians <= hi)]
        return float(inside.min()) if len(inside) else None

    @classmethod
    def storey_top_for(cls, mesh: trimesh.Trimesh, floor: float, config: NavGridConfig = NavGridConfig()) -> float:
        """Height of the lowest walkable level more than ``agent_height`` above ``floor`` (the next storey's
        floor, or a roof), ``inf`` if there is none: points from there up belong to another storey."""
        medians = cls._levels(mesh, config)
        above = medians[medians > floor + config.agent_height] if medians is not None else np.zeros(0)
        return float(above.min()) if len(above) else math.inf

    @staticmethod
    def _levels(mesh: trimesh.Trimesh, config: NavGridConfig) -> np.ndarray | None:
        """Median heights of the walkable levels holding at least 5% of the largest one's hits (bottom-up);
        None if the mesh is too small for the coarse ray grid."""
        normals_y = np.asarray(mesh.face_normals)[:, 1]
        lo, hi = mesh.bounds
        extent = max(hi[0] - lo[0], hi[2] - lo[2])
        step = max(4 * config.cell_size, extent / 150.0)
        gx, gz = np.meshgrid(np.arange(lo[0] + step / 2, hi[0], step), np.arange(lo[2] + step / 2, hi[2], step))
        origins = np.column_stack([gx.ravel(), np.full(gx.size, hi[1] + 1.0), gz.ravel()])
        if len(origins) == 0:
            return None
        locs, ray_idx, tri_idx = mesh.ray.intersects_location(
            origins, np.tile([0.0, -1.0, 0.0], (len(origins), 1)), multiple_hits=True)
        order = np.lexsort((-locs[:, 1], ray_idx))
        ys, rays, tris = locs[order, 1], ray_idx[order], tri_idx[order]
        above = np.full(len(ys), np.inf)
        same_ray = rays[1:] == rays[:-1]
        above[1:][same_ray] = ys[:-1][same_ray]
        heights = np.sort(ys[(np.abs(normals_y[tris]) >= _HORIZONTAL_NY) & (above - ys >= config.agent_height)])
        if len(heights) == 0:
            raise SceneError(f"mesh has no walkable floor: no horizontal surface with {config.agent_height} m headroom")
        return storey_floors(heights, config)

    @staticmethod
    def _navmesh_topology(free: np.ndarray, config: NavGridConfig) -> np.ndarray:
        """Cells within ``k - 1`` cells of one Recast's erosion keeps, ``k = ceil(agent_radius / cell_size)``.

        Habitat's navmesh (Recast, ``walkableRadius = ceil(radius / cs)`` voxels on the same lattice) keeps
        a walkable voxel only if it is ``k`` voxel steps from every voxel bordering an obstacle voxel, i.e.
        ``k + 1`` cells from every non-free cell; obstacle voxels are every cell a triangle touches, so a
        passage needs ~0.45 m of free floor where the exact clearance admits 0.36 m. Keeping the cells
        within ``k - 1`` cells of that eroded area leaves the boundary along walls where the exact
        clearance puts it and removes only the passages and pockets the navmesh does not have.
        """
        k = int(math.ceil(config.agent_radius / config.cell_size - 1e-9))
        core = ndimage.distance_transform_edt(free) >= k + 1
        if not core.any():
            return core
        return ndimage.distance_transform_edt(~core) <= k - 1 + 1e-9

    @staticmethod
    def _clearance(free: np.ndarray, blocked: np.ndarray, surface: np.ndarray, outline: np.ndarray,
                   cs: float, radius: float) -> np.ndarray:
        """Distance (m) from each free cell centre to the nearest obstacle or floor edge; 0 elsewhere.

        Near obstacles it is the distance to the outlines of the head-band footprints, sampled at
        most one cell apart (at the agent radius, ~3.6 cells away, that is exact to ~cs/30). Cell-level
        distances would place a wall up to half a cell off and bias every geodesic that turns round it.
        Far from obstacles (where it
        cannot decide navigability) it is the distance to the nearest blocked cell centre. A floor's
        edge lies between its last floor cell centre and the first floorless one: half a cell nearer
        than the floorless cell.
        """
        clearance = ndimage.distance_transform_edt(~blocked) * cs
        # A blocked cell is within cs / sqrt(2) of the geometry that blocked it; beyond this margin
        # the cell-level value cannot change which cells are navigable.
        near = free & (clearance < radius + 1.5 * cs)
        if len(outline) and near.any():
            ii, jj = np.nonzero(near)
            d, _ = cKDTree(outline).query(np.column_stack([jj, ii]).astype(float))
            clearance[ii, jj] = d * cs
        edge = ndimage.distance_transform_edt(surface) * cs - 0.5 * cs
        return np.where(free, np.minimum(clearance, edge), 0.0)

    @staticmethod
    def _rasterise_band(mesh: trimesh.Trimesh, y0: float, y1: float, origin: np.ndarray, cs: float,
                        shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Cells whose column between heights y0 and y1 meets a triangle of the mesh, and points
        (in (col, row) cell units) every quarter cell along the outlines of those footprints."""
        blocked = np.zeros(shape, dtype=np.uint8)
        faces = np.asarray(mesh.faces)
        vy = np.asarray(mesh.vertices)[:, 1][faces]
        tri = np.asarray(mesh.vertices)[faces[(vy.max(axis=1) >= y0) & (vy.min(axis=1) <= y1)]]
        if len(tri) == 0:
            return blocked.astype(bool), np.zeros((0, 2))
        # Triangle ∩ slab is convex; its corners are the triangle's corners inside the slab and the
        # crossings of its edges with the two planes. Collect those (up to 9) per triangle.
        a = tri
        b = np.roll(tri, -1, axis=1)
        ya, yb = a[:, :, 1], b[:, :, 1]
        pts = [a]
        valid = [(ya >= y0) & (ya <= y1)]
        dy = yb - ya
        safe = np.where(np.abs(dy) > 1e-12, dy, 1.0)
        for plane in (y0, y1):
            t = (plane - ya) / safe
            ok = (np.abs(dy) > 1e-12) & (t >= 0.0) & (t <= 1.0)
            pts.append(a + t[:, :, None] * (b - a))
            valid.append(ok)
        pts = np.concatenate(pts, axis=1)[:, :, [0, 2]]  # (T, 9, 2) in xz
        valid = np.concatenate(valid, axis=1)
        keep = valid.any(axis=1)
        pts, valid = pts[keep], valid[keep]
        # Pixel coordinates: column = x, row = z, pixel centres at integers.
        px = (pts - origin) / cs
        centre = (px * valid[:, :, None]).sum(axis=1) / valid.sum(axis=1)[:, None]
        ang = np.arctan2(px[:, :, 1] - centre[:, None, 1], px[:, :, 0] - centre[:, None, 0])
        ang[~valid] = np.inf
        order = np.argsort(ang, axis=1)
        px = np.take_along_axis(px, order[:, :, None], axis=1)
        nvalid = valid.sum(axis=1)
        # Pad invalid slots with the first corner: repeated corners do not change a convex polygon.
        pad = np.arange(px.shape[1])[None, :] >= nvalid[:, None]
        px = np.where(pad[:, :, None], px[:, :1], px)
        # Footprints within one cell are marked directly; the rest go through OpenCV one by one
        # (its multi-polygon fill is even-odd, which would punch holes where triangles overlap).
        cell = np.floor(px + 0.5).astype(np.int64)
        cmin, cmax = cell.min(axis=1), cell.max(axis=1)
        single = (cmin == cmax).all(axis=1)
        r, c = cmin[single, 1], cmin[single, 0]
        inb = (r >= 0) & (r < shape[0]) & (c >= 0) & (c < shape[1])
        blocked[r[inb], c[inb]] = 1
        shift = 4
        fixed = np.round(px[~single] * (1 << shift)).astype(np.int32)
        for poly in fixed:
            cv2.fillConvexPoly(blocked, poly, 1, lineType=cv2.LINE_8, shift=shift)
        # Outline samples: every footprint corner, plus points at most a cell apart on longer edges.
        corners = px[~pad]
        start = px.reshape(-1, 2)
        delta = np.roll(px, -1, axis=1).reshape(-1, 2) - start
        n = np.ceil(np.hypot(delta[:, 0], delta[:, 1])).astype(np.int64)
        long = n > 1
        start, delta, n = start[long], delta[long], n[long]
        seg = np.repeat(np.arange(len(n)), n - 1)
        t = (np.arange(len(seg)) - np.repeat(np.cumsum(n - 1) - (n - 1), n - 1) + 1) / n[seg]
        outline = np.concatenate([corners, start[seg] + t[:, None] * delta[seg]])
        # Shared corners of dense meshes repeat many times; duplicates only slow the tree down.
        q = np.round(outline * 16).astype(np.int64)
        _, keep = np.unique(q[:, 0] * (1 << 32) + q[:, 1], return_index=True)
        return blocked.astype(bool), outline[keep]

    # ------------------------------------------------------------------ persistence

    def save(self, path: str | Path) -> None:
        """Write the grid to an ``.npz`` file (geodesic fields are not saved; the build's wall clearance, which
        sliding steps along, is, so a grid read back slides exactly as the one built)."""
        extra = {} if self._clearance is None else {"clearance": self._clearance}
        np.savez_compressed(
            Path(path), free=self.free, navigable=self.navigable, origin=self.origin,
            cell_size=np.float64(self.cell_size), floor_height=np.float64(self.floor_height),
            storey_top=np.float64(self.storey_top), config=np.array(json.dumps(dataclasses.asdict(self.config))),
            **extra)

    @classmethod
    def load(cls, path: str | Path) -> NavGrid:
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                config = NavGridConfig(**json.loads(str(data["config"])))
                grid = cls(data["free"], data["navigable"], data["origin"], float(data["cell_size"]),
                           float(data["floor_height"]), config, float(data["storey_top"]))
                if "clearance" in data.files:
                    clearance = np.asarray(data["clearance"], np.float64)
                    if clearance.shape != grid.free.shape:
                        raise ValueError(f"clearance {clearance.shape} does not match the grid {grid.free.shape}")
                    grid._clearance = clearance
                return grid
        except FileNotFoundError:
            raise SceneError(f"{path}: navigation grid file not found") from None
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise SceneError(f"{path}: corrupt navigation grid ({type(exc).__name__}: {exc})") from None

    # ------------------------------------------------------------------ coordinates

    @property
    def shape(self) -> tuple[int, int]:
        return self.navigable.shape

    def world_to_grid(self, points) -> np.ndarray:
        """Integer ``(row, col)`` indices of the cells containing ``points`` ((3,) or (N, 3)); may be out of range."""
        p = _points(points, "points")
        ij = np.stack([(p[..., 2] - self.origin[1]) / self.cell_size,
                       (p[..., 0] - self.origin[0]) / self.cell_size], axis=-1)
        return np.floor(ij + 0.5).astype(np.int64)

    def grid_to_world(self, ij) -> np.ndarray:
        """World points (cell centres, y = floor_height) of ``(row, col)`` indices ((2,) or (N, 2))."""
        a = np.asarray(ij, dtype=float)
        if a.shape[-1] != 2 or not np.isfinite(a).all():
            raise ValueError(f"grid indices must be finite (row, col) pairs, got {a.tolist()}")
        return np.stack([self.origin[0] + a[..., 1] * self.cell_size,
                         np.full(a.shape[:-1], self.floor_height),
                         self.origin[1] + a[..., 0] * self.cell_size], axis=-1)

    def _cell(self, x: float, z: float) -> tuple[int, int] | None:
        i = int(math.floor((z - self.origin[1]) / self.cell_size + 0.5))
        j = int(math.floor((x - self.origin[0]) / self.cell_size + 0.5))
        h, w = self.navigable.shape
        return (i, j) if 0 <= i < h and 0 <= j < w else None

    def _navigable_xz(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        i = np.floor((z - self.origin[1]) / self.cell_size + 0.5).astype(np.int64)
        j = np.floor((x - self.origin[0]) / self.cell_size + 0.5).astype(np.int64)
        h, w = self.navigable.shape
        inside = (i >= 0) & (i < h) & (j >= 0) & (j < w)
        out = np.zeros(i.shape, dtype=bool)
        out[inside] = self.navigable[i[inside], j[inside]]
        return out

    # ------------------------------------------------------------------ point queries

    def is_navigable(self, p) -> bool:
        p = _points(p, "point")
        cell = self._cell(p[0], p[2])
        return cell is not None and bool(self.navigable[cell])

    def _snap_tables(self) -> tuple[np.ndarray, np.ndarray]:
        if self._snap_index is None:
            dist, idx = ndimage.distance_transform_edt(~self.navigable, return_indices=True)
            self._snap_dist, self._snap_index = dist * self.cell_size, idx
        return self._snap_dist, self._snap_index

    def _snap_xz(self, x: float, z: float, max_dist: float) -> tuple[float, float] | None:
        """The point itself if navigable, else the nearest navigable cell centre within max_dist."""
        cell = self._cell(x, z)
        if cell is not None and self.navigable[cell]:
            return x, z
        if cell is None:
            # Off the grid: clamp to the border (never navigable), then measure from the real point.
            h, w = self.navigable.shape
            cell = (min(max(int(round((z - self.origin[1]) / self.cell_size)), 0), h - 1),
                    min(max(int(round((x - self.origin[0]) / self.cell_size)), 0), w - 1))
        _, idx = self._snap_tables()
        i, j = int(idx[0][cell]), int(idx[1][cell])
        cs = self.cell_size
        rho = math.hypot(self.origin[0] + j * cs - x, self.origin[1] + i * cs - z)
        if rho > max_dist + cs:
            return None
        # The table gives the navigable cell nearest to the point's *cell*; the one nearest to the
        # point itself lies within rho of it, so search that window exactly.
        k = int(math.ceil(rho / cs)) + 1
        h, w = self.navigable.shape
        i0, i1 = max(cell[0] - k, 0), min(cell[0] + k + 1, h)
        j0, j1 = max(cell[1] - k, 0), min(cell[1] + k + 1, w)
        ii, jj = np.nonzero(self.navigable[i0:i1, j0:j1])
        dist = np.hypot(self.origin[0] + (jj + j0) * cs - x, self.origin[1] + (ii + i0) * cs - z)
        best = int(np.argmin(dist))
        if dist[best] > max_dist:
            return None
        return float(self.origin[0] + (jj[best] + j0) * cs), float(self.origin[1] + (ii[best] + i0) * cs)

    def snap_point(self, p, max_dist: float | None = None) -> np.ndarray:
        """``p`` itself (y = floor) if navigable, else the nearest navigable cell centre.

        Like Habitat's ``snap_point``, returns a NaN point when nothing navigable lies within
        ``max_dist`` metres (None: no limit).
        """
        p = _points(p, "point")
        if p.ndim != 1:
            raise ValueError(f"snap_point takes one xyz point, got shape {p.shape}")
        snapped = self._snap_xz(float(p[0]), float(p[2]), math.inf if max_dist is None else float(max_dist))
        if snapped is None:
            return np.full(3, np.nan)
        return np.array([snapped[0], self.floor_height, snapped[1]])

    def sample_navigable_point(self, rng: np.random.Generator) -> np.ndarray:
        """A uniformly random navigable point (uniform over navigable cells, jittered inside the cell)."""
        if self._flat_navigable is None:
            self._flat_navigable = np.flatnonzero(self.navigable)
        k = int(self._flat_navigable[rng.integers(len(self._flat_navigable))])
        i, j = divmod(k, self.navigable.shape[1])
        dx, dz = rng.uniform(-0.49, 0.49, size=2) * self.cell_size
        return np.array([self.origin[0] + j * self.cell_size + dx, self.floor_height,
                         self.origin[1] + i * self.cell_size + dz])

    def sample_tight_point(self, rng: np.random.Generator, max_clearance: float) -> np.ndarray | None:
        """The centre of a uniformly random navigable cell within ``max_clearance`` metres of the
        navigable area's edge (the grid is eroded by the agent's radius, so the body is then at most that
        far from an obstacle); None if the grid has no such cell."""
        cells = np.flatnonzero((self.navigable_clearance() <= max_clearance + 1e-9) & self.navigable)
        if len(cells) == 0:
            return None
        i, j = divmod(int(cells[rng.integers(len(cells))]), self.navigable.shape[1])
        return np.array([self.origin[0] + j * self.cell_size, self.floor_height, self.origin[1] + i * self.cell_size])

    def island_id(self, p) -> int:
        """Label (>= 1) of the 4-connected navigable island containing ``p``; 0 if not navigable."""
        p = _points(p, "point")
        cell = self._cell(p[0], p[2])
        return 0 if cell is None else int(self.islands[cell])

    def same_island(self, a, b) -> bool:
        ia = self.island_id(a)
        return ia != 0 and ia == self.island_id(b)

    @staticmethod
    def euclidean_distance(a, b) -> float:
        """Straight-line distance in the xz plane."""
        a, b = _points(a, "a"), _points(b, "b")
        return float(math.hypot(a[0] - b[0], a[2] - b[2]))

    # ------------------------------------------------------------------ geodesics

    def distance_field(self, goals, margin: float = 0.0) -> GeodesicField:
        """Geodesic distance field to the nearest of ``goals`` ((3,) or (N, 3)), LRU-cached per goal set.

        ``margin > 0`` gives a *clearance-weighted* field for steering instead: the travel time at a
        speed of 1 m/s in the open that falls linearly to ``_MIN_SPEED`` on cells closer than ``margin``
        to the navigable boundary. Its shortest paths keep that much extra room from walls and corners
        where they can (doorways, wider than the agent by more than 2 x margin, stay at full speed), so
        an agent that follows them a few centimetres off cannot clip a corner. Its values are not
        metres: success and SPL always use the plain field.

        Goals on a navigable cell are used exactly. A goal off the navigable area is replaced by
        its snapped point (nearest navigable cell centre), with nothing added for the snap, as
        Habitat's path finder does; goals more than ``config.max_goal_snap`` from any navigable cell,
        and goals on another storey (see :meth:`on_storey`), are ignored (all ignored: the field is inf
        everywhere).

        The field is ``skfmm.distance`` (second order) on the grid with non-navigable cells masked.
        The zero level set is made exact at the goals: phi = |x - g| - r with r = 1.5 cells around
        each goal (only on the goal's island, so it cannot leak across a wall), and r is added back.
        """
        g = _points(goals, "goals").reshape(-1, 3)
        key = np.round(g[:, [0, 2]] * 1000.0).astype(np.int64).tobytes() + np.float64(margin).tobytes()
        field = self._fields.get(key)
        if field is not None:
            self._fields.move_to_end(key)
            return field
        field = self._compute_field(g, margin)
        self._fields[key] = field
        while len(self._fields) > self.config.field_cache_size:
            self._fields.popitem(last=False)
        return field

    def _compute_field(self, goals: np.ndarray, margin: float = 0.0) -> GeodesicField:
        cs = self.cell_size
        h, w = self.navigable.shape
        used = []
        for x, z in goals[self.on_storey(goals)][:, [0, 2]]:
            snapped = self._snap_xz(float(x), float(z), self.config.max_goal_snap)
            if snapped is not None:
                used.append(snapped)
        near_goal = np.full((h, w), -1, dtype=np.int32)
        values = np.full((h, w), np.inf)
        if not used:
            return GeodesicField(self, np.zeros((0, 3)), values, near_goal)
        used = np.unique(np.round(np.array(used), 9), axis=0)
        gxz = used
        goal_pts = np.column_stack([gxz[:, 0], np.full(len(gxz), self.floor_height), gxz[:, 1]])

        r = _GOAL_DISC_CELLS * cs
        k = int(math.ceil(_GOAL_DISC_CELLS)) + 2
        offs = np.arange(-k, k + 1)
        ci = np.floor((gxz[:, 1] - self.origin[1]) / cs + 0.5).astype(np.int64)
        cj = np.floor((gxz[:, 0] - self.origin[0]) / cs + 0.5).astype(np.int64)
        ii = (ci[:, None, None] + offs[None, :, None]) + 0 * offs[None, None, :]
        jj = (cj[:, None, None] + offs[None, None, :]) + 0 * offs[None, :, None]
        gidx = np.broadcast_to(np.arange(len(gxz))[:, None, None], ii.shape)
        ii, jj, gidx = ii.ravel(), jj.ravel(), gidx.ravel()
        ok = (ii >= 0) & (ii < h) & (jj >= 0) & (jj < w)
        ii, jj, gidx = ii[ok], jj[ok], gidx[ok]
        goal_island = self.islands[ci, cj]
        ok = self.islands[ii, jj] == goal_island[gidx]
        ii, jj, gidx = ii[ok], jj[ok], gidx[ok]
        dist = np.hypot(self.origin[0] + jj * cs - gxz[gidx, 0], self.origin[1] + ii * cs - gxz[gidx, 1])

        # Per cell keep the nearest goal (sort by distance, first occurrence per cell wins).
        order = np.argsort(dist, kind="stable")
        flat = (ii * w + jj)[order]
        _, first = np.unique(flat, return_index=True)
        sel = order[first]
        near_goal.ravel()[ii[sel] * w + jj[sel]] = gidx[sel]
        phi = np.ones((h, w))
        phi.ravel()[ii[sel] * w + jj[sel]] = np.minimum(dist[sel] - r, 1.0)
        phi = np.ma.MaskedArray(phi, mask=~self.navigable)
        if margin > 0:
            speed = np.clip(self.navigable_clearance() / margin, _MIN_SPEED, 1.0)
            d = skfmm.travel_time(phi, speed, dx=cs, order=2)
        else:
            d = skfmm.distance(phi, dx=cs, order=2)
        d = np.ma.filled(d, np.inf) + r
        # Inside the zero level set skfmm returns minus the distance to the set's boundary, which for a
        # dense goal set (ObjectNav view points) is far more than r: use the exact distance to the
        # nearest goal there instead (every inside cell is within r of a goal, so it is known).
        inside = phi < 0
        exact = np.full((h, w), np.inf)
        exact.ravel()[ii[sel] * w + jj[sel]] = dist[sel]
        d = np.where(inside, exact, d)
        reachable = np.isin(self.islands, np.unique(goal_island))
        values = np.where(reachable & self.navigable & np.isfinite(d), d, np.inf)
        return GeodesicField(self, goal_pts, values, near_goal)

    def on_storey(self, points) -> np.ndarray:
        """Per point (N, 3), whether its height puts it on this grid's storey: no more than half the agent's
        height below the floor, and below the next walkable level up (less ``max_climb``). Goals elsewhere
        (a view point of the same category on another storey) are not on this grid and never count."""
        y = _points(points, "points").reshape(-1, 3)[:, 1]
        return (y >= self.floor_height - self.config.agent_height / 2) & \
            (y < self.storey_top - self.config.max_climb)

    def geodesic_distance(self, start, goals) -> float:
        """Shortest navigable path length from ``start`` to the nearest of ``goals``; ``math.inf`` if unreachable.

        A start off the navigable area is snapped like a goal (within ``config.max_goal_snap``).
        """
        s = _points(start, "start")
        if s.ndim != 1:
            raise ValueError(f"start must be one xyz point, got shape {s.shape}")
        field = self.distance_field(goals)
        x, z = float(s[0]), float(s[2])
        snapped = self._snap_xz(x, z, self.config.max_goal_snap)
        if snapped is None:
            return math.inf
        return field._distance_xz(*snapped)

    # ------------------------------------------------------------------ motion

    def _clearance_map(self) -> np.ndarray:
        if self._clearance is None:
            self._clearance = ndimage.distance_transform_edt(self.free) * self.cell_size
        return self._clearance

    def navigable_clearance(self) -> np.ndarray:
        """Per cell, metres to the nearest non-navigable cell (0 off the navigable area)."""
        if self._nav_clearance is None:
            self._nav_clearance = ndimage.distance_transform_edt(self.navigable) * self.cell_size
        return self._nav_clearance

    def _straight(self, x0: float, z0: float, x1: float, z1: float) -> tuple[float, float, bool]:
        """Furthest point along the segment that stays navigable; (x, z, stopped short)."""
        length = math.hypot(x1 - x0, z1 - z0)
        if length == 0.0:
            return x0, z0, False
        clearance = self.navigable_clearance()
        start = self._cell(x0, z0)
        # Every sample's cell centre lies within length + 1.5 cells of the start cell's centre; if
        # all cells that close are navigable, the whole segment is (the common case, kept cheap).
        if start is not None and clearance[start] > length + 1.5 * self.cell_size:
            return x1, z1, False
        n = max(1, int(math.ceil(length / (0.25 * self.cell_size))))
        t = np.arange(1, n + 1) / n
        ok = self._navigable_xz(x0 + t * (x1 - x0), z0 + t * (z1 - z0))
        if ok.all():
            return x1, z1, False
        bad = int(np.argmin(ok))
        t_good, t_bad = (t[bad - 1] if bad > 0 else 0.0), float(t[bad])
        # Refine the stopping point between the last free and the first blocked sample.
        for _ in range(6):
            tm = 0.5 * (t_good + t_bad)
            cell = self._cell(x0 + tm * (x1 - x0), z0 + tm * (z1 - z0))
            if cell is not None and self.navigable[cell]:
                t_good = tm
            else:
                t_bad = tm
        return x0 + t_good * (x1 - x0), z0 + t_good * (z1 - z0), True

    def try_step(self, position, target, sliding: bool = False) -> tuple[np.ndarray, bool]:
        """Move from ``position`` towards ``target``; returns (new position with y = floor, collided).

        Without sliding (the Habitat ObjectNav default) the agent moves along the segment as far as
        it stays navigable (checked every quarter cell, then refined) and ``collided`` is True if it
        stopped short. With sliding, the remaining motion after the stop is re-tried along the wall
        (its projection on the wall tangent, from the clearance gradient) and along each axis; the
        candidate that gets furthest is taken, and ``collided`` is still True.
        """
        p = _points(position, "position")
        q = _points(target, "target")
        if p.ndim != 1 or q.ndim != 1:
            raise ValueError(f"try_step takes single xyz points, got shapes {p.shape} and {q.shape}")
        x0, z0, x1, z1 = float(p[0]), float(p[2]), float(q[0]), float(q[2])
        x, z, collided = self._straight(x0, z0, x1, z1)
        if collided and sliding:
            rx, rz = x1 - x, z1 - z
            candidates = [(rx, 0.0), (0.0, rz)]
            cell = self._cell(x, z)
            if cell is not None:
                clearance = self._clearance_map()
                i, j = cell
                h, w = clearance.shape
                gx = clearance[i, min(j + 1, w - 1)] - clearance[i, max(j - 1, 0)]
                gz = clearance[min(i + 1, h - 1), j] - clearance[max(i - 1, 0), j]
                gn = math.hypot(gx, gz)
                if gn > 0:
                    nx, nz = gx / gn, gz / gn  # points away from the obstacle
                    dot = rx * nx + rz * nz
                    if dot < 0:
                        candidates.append((rx - dot * nx, rz - dot * nz))
            best = (x, z)
            best_d = 0.0
            for dx, dz in candidates:
                sx, sz, _ = self._straight(x, z, x + dx, z + dz)
                d = math.hypot(sx - x, sz - z)
                if d > best_d + 1e-12:
                    best, best_d = (sx, sz), d
            x, z = best
        return np.array([x, self.floor_height, z]), collided
