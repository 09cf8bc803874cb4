"""``habitat_sim.nav``: the path finder, shortest-path queries and the greedy geodesic follower over navbench's
navigability: the grid of each storey (:class:`navbench.scene.navigability.NavGrid`) and, on a scene of several
storeys, the walkable surfaces joining them over stairs and ramps (:class:`navbench.scene.layers.LayeredNav`).

habitat-sim answers these queries on a Detour navmesh (``src/esp/nav/PathFinder.cpp``, bound in
``src/esp/bindings/ShortestPathBindings.cpp``); here they are answered as navbench's own env answers them, with
habitat-sim's conventions (``navmesh-spec.md``: §4 geodesics, §5 try_step, §6 other queries, §7 sampling):

* A point is located as ``projectToPoly`` does: on the grid of the storey its height stands on, the point itself
  when navigable, else the nearest navigable cell centre inside Detour's query box (half extents 2, 4, 2 m);
  on a scene of several storeys, a point on a flight or a ramp (off every storey's grid) on the joined surfaces.
  Nothing in the box: NaNs, ``inf``, not navigable.
* ``geodesic_distance`` is navbench's: the storey grid's geodesic field at the located start; when an end lies on
  another storey the joined surfaces reach, their field (as navbench's env measures an episode across storeys);
  ``inf`` when no end is reachable. Query points are taken to 10 micrometres. ``points`` is the string-pulled
  polyline down the field (computed when first read).
* ``try_step`` / ``try_step_no_sliding`` are the grid's collision rule (navbench's own motion) and return the
  start unchanged when it or the target is not located or on another island; a step that the storey's grid stops
  and the joined surfaces carry onto a stair or a ramp is taken on them.
* ``get_bounds`` is the scene mesh's box (what habitat-sim reports for a navmesh it builds); random points are
  uniform over the main storey's navigable cells, from a numpy generator ``seed`` seeds; islands are the main
  storey grid's.
* ``NavMeshSettings`` maps to :class:`~navbench.scene.navigability.NavGridConfig` (agent radius, height, max
  climb, cell size); the grid's walkable slope is fixed at 45 degrees, so another ``agent_max_slope`` is refused.
"""

from __future__ import annotations

import math
import os
from functools import partial
from typing import Any

import numpy as np

from navbench.habitat_sim import errors
from navbench.habitat_sim import magnum as mn
from navbench.habitat_sim.config import NavMeshSettings
from navbench.habitat_sim.scene import SceneNode
from navbench.scene.layers import LayeredNav
from navbench.scene.navigability import NavGrid, NavGridConfig

# projectToPoly's findNearestPoly half extents (PathFinder.cpp: polyPickExt = {2, 4, 2})
SNAP_EXTENT = 2.0
SNAP_HEIGHT = 4.0
NAVIGABLE_XZ = 0.01  # isNavigable: the snapped point within 1 cm of the query in xz (PathFinder.cpp)
QUERY_DECIMALS = 5  # find_path's points, in metres: episode files' precision
WALKABLE_SLOPE_DEG = 45.0  # navbench's floor-like test: a normal within 45 degrees of vertical
_JOINED: dict[tuple, bool] = {}  # PathFinder._stairs_join, by scene and floor
_LAYERS: dict[tuple, LayeredNav] = {}  # PathFinder._layered, the last two scenes

__all__ = ["GreedyFollowerCodes", "GreedyGeodesicFollowerImpl", "MultiGoalShortestPath", "NavMeshSettings",
           "PathFinder", "ShortestPath", "nav_grid_config"]


def nav_grid_config(settings: NavMeshSettings | None) -> NavGridConfig:
    """navbench's grid configuration for habitat-sim's navmesh settings (None: habitat-sim's defaults)."""
    s = settings if settings is not None else NavMeshSettings()
    if abs(float(s.agent_max_slope) - WALKABLE_SLOPE_DEG) > 1e-6:
        raise ValueError(f"NavMeshSettings.agent_max_slope={s.agent_max_slope}: navbench's navigability has a fixed "
                         f"walkable slope of {WALKABLE_SLOPE_DEG:g} degrees")
    if s.include_static_objects:
        raise ValueError("NavMeshSettings.include_static_objects=True: navbench's habitat_sim covers navigation "
                         "(no static objects beside the scene mesh)")
    return NavGridConfig(agent_height=float(s.agent_height), agent_radius=float(s.agent_radius),
                         max_climb=float(s.agent_max_climb), cell_size=float(s.cell_size))


def _vec(p) -> np.ndarray:
    a = np.asarray(p, dtype=np.float64).reshape(-1)
    if a.shape != (3,):
        raise ValueError(f"expected an (x, y, z) point, got {np.asarray(p).tolist()}")
    return a


def _nan3() -> mn.Vector3:
    return mn.Vector3(np.full(3, np.nan))


def _xz(a, b) -> float:
    return math.hypot(float(a[0]) - float(b[0]), float(a[2]) - float(b[2]))


def _near_segment(points: np.ndarray, a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    """Whether every one of ``points`` lies within ``tol`` of the segment from ``a`` to ``b``."""
    ab = b - a
    t = np.clip((points - a) @ ab / max(float(ab @ ab), 1e-18), 0.0, 1.0)
    return bool((np.linalg.norm(points - (a + t[:, None] * ab), axis=1) <= tol).all())


class ShortestPath:
    """A query from ``requested_start`` to ``requested_end``; ``find_path`` fills ``geodesic_distance`` and
    ``points``."""

    def __init__(self) -> None:
        self.requested_start = np.zeros(3, np.float32)
        self.requested_end = np.zeros(3, np.float32)
        self.geodesic_distance = math.inf
        self._points: Any = []

    @property
    def points(self) -> list[mn.Vector3]:
        if callable(self._points):
            self._points = self._points()
        return self._points

    @points.setter
    def points(self, value) -> None:
        self._points = list(value)


class MultiGoalShortestPath:
    """A query from ``requested_start`` to the nearest of ``requested_ends`` ((N, 3) float32);
    ``closest_end_point_index`` is -1 when none is reachable."""

    def __init__(self) -> None:
        self.requested_start = np.zeros(3, np.float32)
        self._ends = np.zeros((0, 3), np.float32)
        self.geodesic_distance = math.inf
        self.closest_end_point_index = -1
        self._points: Any = []

    @property
    def requested_ends(self) -> np.ndarray:
        return self._ends

    @requested_ends.setter
    def requested_ends(self, ends) -> None:
        self._ends = np.asarray(ends, dtype=np.float32).reshape(-1, 3)

    points = ShortestPath.points


Engine = NavGrid | LayeredNav


class PathFinder:
    """habitat-sim's ``PathFinder`` over a scene's navigability (``load_grid``: the main storey's grid, and the
    scene whose other storeys and stairs it builds when a query reaches them); queries before anything is loaded
    answer as habitat-sim's do without a navmesh (not navigable, NaN points, inf distances)."""

    def __init__(self) -> None:
        self._grid: NavGrid | None = None
        self._asset: Any = None
        self._settings: NavMeshSettings | None = None
        self._rng = np.random.default_rng(0)
        self._reset_caches()

    def _reset_caches(self) -> None:
        self._storeys: dict[float, NavGrid] = {}
        self._floors: np.ndarray | None = None
        self._layers: LayeredNav | None = None
        self._island_radius: dict[tuple[int, int], float] = {}

    # ------------------------------------------------------------------ loading
    def load_grid(self, grid: NavGrid, settings: NavMeshSettings | None = None, asset: Any = None) -> None:
        """Answer on ``grid`` (the main storey's); with the scene ``asset`` it was built from, also on the scene's
        other storeys and the stairs and ramps joining them."""
        self._grid = grid
        self._settings = settings
        self._asset = asset
        self._reset_caches()

    def load_nav_mesh(self, path: str) -> bool:
        raise NotImplementedError(f"PathFinder.load_nav_mesh({path!r}): navbench's habitat_sim builds its "
                                  "navigability from the scene mesh and does not read Detour .navmesh files")

    @property
    def is_loaded(self) -> bool:
        return self._grid is not None

    @property
    def nav_mesh_settings(self) -> NavMeshSettings | None:
        return self._settings

    @property
    def grid(self) -> NavGrid:
        """navbench's grid of the main storey behind this path finder."""
        if self._grid is None:
            raise RuntimeError("PathFinder: no navigability loaded")
        return self._grid

    def seed(self, new_seed: int) -> None:
        """Seeds :meth:`get_random_navigable_point` and :meth:`get_random_navigable_point_near`."""
        self._rng = np.random.default_rng(int(new_seed))

    # ------------------------------------------------------------------ storeys
    def _multi_storey(self) -> bool:
        """Whether the scene has a walkable level above the main storey (then stairs may join them)."""
        return self._asset is not None and self._grid is not None and math.isfinite(self._grid.storey_top)

    def _grid_for(self, y: float) -> NavGrid:
        """The grid of the storey a point at height ``y`` stands on, chosen as navbench's env chooses an episode's
        (:func:`navbench.scene.cache.navgrid_for` with the height as its hint), each built once."""
        g = self.grid
        c = g.config
        if self._asset is None or abs(y - g.floor_height) <= c.agent_height / 2:
            return g
        if self._floors is None:
            levels = NavGrid._levels(self._asset.mesh, c)
            self._floors = np.array([g.floor_height]) if levels is None or not len(levels) else levels
        floors = self._floors
        below = floors[floors <= y + c.max_climb]
        floor = round(float(below.max() if len(below) else floors[np.argmin(np.abs(floors - y))]), 4)
        if abs(floor - g.floor_height) <= c.max_climb / 2:
            return g
        if floor not in self._storeys:
            from navbench.scene.cache import navgrid_for

            self._storeys[floor] = navgrid_for(self._asset, c, floor_hint=float(y))
        return self._storeys[floor]

    def _scene_key(self, *extra) -> tuple:
        """The scene file (path, size, mtime) and the grid's build settings, for memos kept across reloads."""
        st = os.stat(self._asset.path)
        return (str(self._asset.path), st.st_size, st.st_mtime_ns, self.grid.config, *extra)

    def _stairs_join(self, g: NavGrid) -> bool:
        """Whether a stair or a ramp joins storey ``g``'s floor (a joined surface holds spans on that floor and
        off it): only then can a step its grid stops go on over the joined surfaces. A roof counts as a level
        above (:meth:`_multi_storey`) but joins nothing. Memoised per scene across reloads (each reconfigure
        reloads the scene; only the scene's first stopped step pays for the joined surfaces)."""
        if not self._multi_storey():
            return False
        key = self._scene_key(g.floor_height)
        if key not in _JOINED:
            lay = self._layered()
            nav = lay.component >= 0
            floor = nav & (np.abs(lay.height - g.floor_height) <= g.config.max_climb / 2)
            _JOINED[key] = bool(np.intersect1d(lay.component[floor], lay.component[nav & ~floor]).size)
        return _JOINED[key]

    def _layered(self) -> LayeredNav:
        """The scene's joined walkable surfaces (disk-cached as navbench's env caches them; the last two scenes'
        kept in memory, so that switching back and forth between episodes' scenes does not rebuild them)."""
        if self._layers is None:
            from navbench.scene.cache import layers_for

            key = self._scene_key()
            if key not in _LAYERS:
                if len(_LAYERS) >= 2:
                    _LAYERS.pop(next(iter(_LAYERS)))
                _LAYERS[key] = layers_for(self._asset, self.grid.config)
            self._layers = _LAYERS[key]
        return self._layers

    # ------------------------------------------------------------------ locating
    @staticmethod
    def _snap_grid(g: NavGrid, p: np.ndarray) -> np.ndarray | None:
        """``p`` on ``g`` (y the floor's): itself if navigable, else the nearest navigable cell centre inside the
        query box; None when there is none or the floor is more than 4 m off in height."""
        if abs(p[1] - g.floor_height) > SNAP_HEIGHT:
            return None
        x, z = float(p[0]), float(p[2])
        s = g._snap_xz(x, z, SNAP_EXTENT)  # the nearest within 2 m: inside the box, and nearest in it
        if s is None:  # only the box's corners are left
            cs, (h, w) = g.cell_size, g.navigable.shape
            i0 = max(int(math.ceil((z - SNAP_EXTENT - g.origin[1]) / cs)), 0)
            i1 = min(int(math.floor((z + SNAP_EXTENT - g.origin[1]) / cs)) + 1, h)
            j0 = max(int(math.ceil((x - SNAP_EXTENT - g.origin[0]) / cs)), 0)
            j1 = min(int(math.floor((x + SNAP_EXTENT - g.origin[0]) / cs)) + 1, w)
            if i0 >= i1 or j0 >= j1:
                return None
            ii, jj = np.nonzero(g.navigable[i0:i1, j0:j1])
            if len(ii) == 0:
                return None
            cx, cz = g.origin[0] + (jj + j0) * cs, g.origin[1] + (ii + i0) * cs
            k = int(np.argmin(np.hypot(cx - x, cz - z)))
            s = (float(cx[k]), float(cz[k]))
        return np.array([s[0], g.floor_height, s[1]])

    def _locate(self, p: np.ndarray) -> tuple[Engine, np.ndarray] | None:
        """Where ``p`` stands (see the module docstring): the engine that answers for it and the located point."""
        if self._grid is None or not np.isfinite(p).all():
            return None
        g = self._grid_for(float(p[1]))
        s = self._snap_grid(g, p)
        # off the storey's floor in height, or nothing of it near: maybe on a stair or a ramp
        if self._multi_storey() and (s is None or abs(p[1] - g.floor_height) > g.config.max_climb / 2):
            lay = self._layered()
            span = lay.span_of(p, max_dist=SNAP_EXTENT)
            if span >= 0:
                q = lay.position(span)
                if lay.span_of(p, max_dist=0.0) == span:  # on the span's own cell: the point itself
                    q = np.array([p[0], q[1], p[2]])
                # a stair or a ramp (off the storey's floor) nearer than the grid's point
                off_floor = abs(q[1] - g.floor_height) > g.config.max_climb / 2
                if off_floor and (s is None or _xz(q, p) < _xz(s, p) - 1e-9):
                    return lay, q
        return None if s is None else (g, s)

    def _island(self, engine: Engine, q: np.ndarray) -> int:
        """Label of the island (a grid's) or joined surface (the layered surfaces') ``q`` stands on."""
        if isinstance(engine, NavGrid):
            return engine.island_id(q)
        s = engine.span_of(q, max_dist=engine.cell_size)
        return -1 if s < 0 else int(engine.component[s])

    def snap_point(self, point, island_index: int = -1) -> mn.Vector3:
        loc = self._locate(_vec(point))
        if loc is None or (island_index != -1 and self.get_island(loc[1]) != island_index):
            return _nan3()
        return mn.Vector3(loc[1])

    def is_navigable(self, point, max_y_delta: float = 0.5) -> bool:
        """Whether the located point is within ``max_y_delta`` of ``point`` in height and 1 cm of it in xz."""
        p = _vec(point)
        loc = self._locate(p)
        return loc is not None and abs(loc[1][1] - p[1]) <= max_y_delta and _xz(loc[1], p) <= NAVIGABLE_XZ

    def get_island(self, point) -> int:
        """The island (0-based, the main storey grid's) of the point's located position; -1 when it is not located
        there."""
        loc = self._locate(_vec(point))
        return -1 if loc is None or loc[0] is not self._grid else self.grid.island_id(loc[1]) - 1

    @property
    def num_islands(self) -> int:
        return 0 if self._grid is None else int(self._grid.islands.max(initial=0))

    def _check_island(self, island_index: int) -> None:
        if island_index != -1 and not 0 <= int(island_index) < self.num_islands:
            raise ValueError(f"island_index {island_index} not a valid index for this island system "
                             f"({self.num_islands} islands)")

    @staticmethod
    def _cells(engine: Engine, label: int) -> np.ndarray:
        """(x, y, z) of the cell centres of island ``label`` of a grid (0: all its navigable cells) or of the
        joined surface ``label`` of the layered surfaces."""
        if isinstance(engine, NavGrid):
            g = engine
            ii, jj = np.nonzero(g.navigable if label == 0 else g.islands == label)
            return np.column_stack([g.origin[0] + jj * g.cell_size, np.full(len(ii), g.floor_height),
                                    g.origin[1] + ii * g.cell_size])
        spans = np.flatnonzero(engine.navigable & (engine.component == label))
        xz = engine.xz(engine.cell[spans])
        return np.column_stack([xz[:, 0], engine.height[spans], xz[:, 1]])

    def island_radius(self, pt) -> float:
        """The radius of a sphere about the island's centroid containing all of it (habitat-sim's
        ``IslandSystem``): of the island the point is located on, a storey grid's or the joined surfaces' (0 when
        it is not located), or of the main storey's island ``pt`` given as an index."""
        if isinstance(pt, (int, np.integer)):
            self._check_island(int(pt))
            engine, label = self.grid, int(pt) + 1
        else:
            loc = self._locate(_vec(pt))
            if loc is None:
                return 0.0
            engine, label = loc[0], self._island(*loc)
        key = (id(engine), label)
        if key not in self._island_radius:
            xyz = self._cells(engine, label)
            r = float(np.linalg.norm(xyz - xyz.mean(axis=0), axis=1).max()) if len(xyz) else 0.0
            self._island_radius[key] = r + engine.cell_size / math.sqrt(2.0)
        return self._island_radius[key]

    @property
    def navigable_area(self) -> float:
        """Square metres of the main storey's navigable area."""
        return self.island_area(-1)

    def island_area(self, island_index: int = -1) -> float:
        """Square metres of the main storey's island ``island_index`` (-1: of all its islands)."""
        if self._grid is None:
            return 0.0
        self._check_island(island_index)
        return float(len(self._cells(self._grid, island_index + 1))) * self._grid.cell_size ** 2

    def distance_to_closest_obstacle(self, pt, max_search_radius: float = 2.0) -> float:
        """xz distance from the located point to the navigable area's edge, ``max_search_radius`` when the edge
        is farther; ``inf`` when the point is not located (habitat-sim's ``findDistanceToWall``)."""
        loc = self._locate(_vec(pt))
        if loc is None:
            return math.inf
        engine, q = loc
        r = float(max_search_radius)
        if isinstance(engine, NavGrid):
            g = engine
            cs, (h, w) = g.cell_size, g.navigable.shape
            i, j = (int(v) for v in g.world_to_grid(q))
            if g.navigable_clearance()[i, j] - math.sqrt(2.0) * cs >= r:  # the edge's cells are farther than r
                return r
            k = int(math.ceil(r / cs)) + 1
            i0, i1, j0, j1 = i - k, i + k + 1, j - k, j + k + 1
            window = np.zeros((2 * k + 1, 2 * k + 1), bool)  # cells off the grid are no floor
            window[max(i0, 0) - i0:min(i1, h) - i0, max(j0, 0) - j0:min(j1, w) - j0] = \
                g.navigable[max(i0, 0):min(i1, h), max(j0, 0):min(j1, w)]
            ii, jj = np.nonzero(~window)
            cx, cz = g.origin[0] + (jj + j0) * cs, g.origin[1] + (ii + i0) * cs
        else:  # the joined surfaces: a cell with no navigable span within a step (and the slope) of the point's
            lay = engine
            cs, (h, w) = lay.cell_size, lay.shape
            k = int(math.ceil(r / cs)) + 1
            i, j = lay._cell_ij(float(q[0]), float(q[2]))
            jj, ii = np.meshgrid(np.arange(j - k, j + k + 1), np.arange(i - k, i + k + 1))
            cx, cz = lay.origin[0] + jj * cs, lay.origin[1] + ii * cs
            free = np.zeros(ii.shape, bool)
            for a, b in zip(*np.nonzero((ii >= 0) & (ii < h) & (jj >= 0) & (jj < w))):
                c = int(ii[a, b] * w + jj[a, b])
                own = np.arange(int(lay._start[c]), int(lay._start[c] + lay._count[c]))
                reach = lay.config.max_climb + math.hypot(cx[a, b] - q[0], cz[a, b] - q[2])
                free[a, b] = bool((lay.navigable[own] & (np.abs(lay.height[own] - q[1]) <= reach)).any())
            cx, cz = cx[~free], cz[~free]
        if len(cx) == 0:
            return r
        # distance to the nearest non-navigable cell's square: the navigable area is the union of its cells'
        dx = np.maximum(np.abs(cx - q[0]) - cs / 2, 0.0)
        dz = np.maximum(np.abs(cz - q[2]) - cs / 2, 0.0)
        return float(min(float(np.hypot(dx, dz).min()), r))

    # ------------------------------------------------------------------ sampling
    def _draw(self, xyz: np.ndarray, cs: float) -> np.ndarray:
        k = int(self._rng.integers(len(xyz)))
        dx, dz = self._rng.uniform(-0.49, 0.49, size=2) * cs
        return xyz[k] + np.array([dx, 0.0, dz])

    def get_random_navigable_point(self, max_tries: int = 10, island_index: int = -1) -> mn.Vector3:
        """A point uniform over the navigable area (of island ``island_index``, -1: all), seeded by :meth:`seed`;
        NaNs when ``max_tries`` allows no draw (every draw succeeds otherwise)."""
        if self._grid is None:
            return _nan3()
        self._check_island(island_index)
        if max_tries <= 0:
            return _nan3()
        if island_index == -1:  # the grid's own sampler
            return mn.Vector3(self._grid.sample_navigable_point(self._rng))
        return mn.Vector3(self._draw(self._cells(self._grid, island_index + 1), self._grid.cell_size))

    def get_random_navigable_point_near(self, circle_center, radius: float, max_tries: int = 100,
                                        island_index: int = -1) -> mn.Vector3:
        """A random navigable point strictly within ``radius`` of ``circle_center`` in xz (any height): drawn over
        the navigable cells the circle reaches, up to ``max_tries`` draws; NaNs when none lands inside."""
        if self._grid is None:
            return _nan3()
        self._check_island(island_index)
        c = _vec(circle_center)
        xyz, cs = self._cells(self.grid, island_index + 1), self.grid.cell_size
        xyz = xyz[np.hypot(xyz[:, 0] - c[0], xyz[:, 2] - c[2]) < float(radius) + cs / math.sqrt(2.0)]
        if len(xyz) == 0:
            return _nan3()
        for _ in range(int(max_tries)):
            p = self._draw(xyz, cs)
            if (p[0] - c[0]) ** 2 + (p[2] - c[2]) ** 2 < float(radius) ** 2:
                return mn.Vector3(p)
        return _nan3()

    # ------------------------------------------------------------------ paths
    def find_path(self, path: ShortestPath | MultiGoalShortestPath) -> bool:
        """Fill ``path`` (see the module docstring); True when an end is reachable."""
        # habitat-lab narrows episode points to float32; to the 10 micrometres episode files are written to, they
        # are the file's numbers again, so the grid's goal snapping (exact at cell edges) sees what navbench's env sees
        if isinstance(path, MultiGoalShortestPath):
            ends = np.round(np.asarray(path.requested_ends, np.float64).reshape(-1, 3), QUERY_DECIMALS)
        elif isinstance(path, ShortestPath):
            ends = np.round(_vec(path.requested_end), QUERY_DECIMALS)[None, :]
        else:
            raise TypeError(f"find_path takes a ShortestPath or a MultiGoalShortestPath, got {type(path).__name__}")
        path.geodesic_distance = math.inf
        path._points = []
        if isinstance(path, MultiGoalShortestPath):
            path.closest_end_point_index = -1
        loc = self._locate(np.round(_vec(path.requested_start), QUERY_DECIMALS))
        valid = [k for k, e in enumerate(ends) if np.isfinite(e).all() and self._locate(e) is not None]
        if loc is None or not valid:
            return False
        engine, start = loc
        targets = ends[valid]
        if isinstance(engine, NavGrid) and self._multi_storey():
            # as navbench's env chooses an episode's engine: an end on another storey the joined surfaces reach
            # from the start puts the query on them (ends on storeys nothing joins never count, on either)
            off = ~engine.on_storey(targets)
            if off.any():
                lay = self._layered()
                on = lay.snap_point(start, SNAP_EXTENT)
                if np.isfinite(on).all() and lay.reaches_any(on, targets[off]):
                    engine = lay
                    if lay.span_of(start, max_dist=0.0) < 0:
                        start = on
        field = engine.distance_field(targets)
        d = float(field.distance(start))
        if not math.isfinite(d):
            return False
        path.geodesic_distance = d
        line = partial(self._polyline if isinstance(engine, NavGrid) else self._layered_polyline, engine, field, start)
        if isinstance(path, MultiGoalShortestPath):
            last = line()[-1] if len(targets) > 1 else targets[0]
            path.closest_end_point_index = valid[int(np.argmin(np.hypot(targets[:, 0] - last[0],
                                                                          targets[:, 2] - last[2])))]
        path._points = line
        return True

    @staticmethod
    def _polyline(g: NavGrid, field, start: np.ndarray) -> list[mn.Vector3]:
        """Points from ``start`` to the field's nearest goal on grid ``g``: down the field's values from cell to
        neighbouring cell until the goal is in straight navigable line, then each point joined to the farthest
        later one in straight navigable line."""
        cs = g.cell_size
        y = g.floor_height
        goals = field.goals
        values = field.values
        h, w = values.shape
        p = np.array([start[0], y, start[2]])
        trail = [p]
        i, j = (int(v) for v in g.world_to_grid(p))
        first = True
        while True:
            near = goals[np.argmin(np.hypot(goals[:, 0] - p[0], goals[:, 2] - p[2]))]
            if not g._straight(p[0], p[2], near[0], near[2])[2]:
                trail.append(np.array([near[0], y, near[2]]))
                break
            best = (values[i, j], i, j)
            for di in (-1, 0, 1):
                for dj in (-1, 0, 1):
                    ni, nj = i + di, j + dj
                    # a diagonal move only between navigable orthogonal neighbours: consecutive points stay in
                    # straight navigable line
                    if 0 <= ni < h and 0 <= nj < w and values[ni, nj] < best[0] and \
                            (di == 0 or dj == 0 or (g.navigable[ni, j] and g.navigable[i, nj])):
                        best = (values[ni, nj], ni, nj)
            if first:  # the start's own cell centre first: the start lies in that cell
                best, first = (values[i, j], i, j), False
            elif (best[1], best[2]) == (i, j):  # a minimum short of the goal: end at the nearest goal
                trail.append(np.array([near[0], y, near[2]]))
                break
            i, j = best[1], best[2]
            p = np.array([g.origin[0] + j * cs, y, g.origin[1] + i * cs])
            trail.append(p)
        out = [trail[0]]
        i = 0
        while i < len(trail) - 1:
            j = i + 1
            while j + 1 < len(trail) and not g._straight(trail[i][0], trail[i][2], trail[j + 1][0],
                                                        trail[j + 1][2])[2]:
                j += 1
            out.append(trail[j])
            i = j
        return [mn.Vector3(np.asarray(q, np.float32)) for q in out]

    @staticmethod
    def _layered_polyline(lay: LayeredNav, field, start: np.ndarray) -> list[mn.Vector3]:
        """Points from ``start`` to the field's nearest goal on the joined surfaces: span to span down the
        field's values (each step the one that reaches the goal shortest), at the surface's height smoothed over
        treads (a flight of steps is the ramp through it, as a navmesh's polygons over it are), each point joined
        to the farthest later one the trail between them stays within half a cell of."""
        g = lay.graph
        s = lay.span_of(start, max_dist=SNAP_EXTENT)
        trail = [np.asarray(start, np.float64)]
        goal_spans = set(int(v) for v in field._goal_spans)
        while s >= 0 and s not in goal_spans:
            row = slice(g.indptr[s], g.indptr[s + 1])
            t, wt = g.indices[row], g.data[row]
            if len(t) == 0:
                break
            k = int(np.argmin(field.values[t] + wt))
            if not field.values[t[k]] < field.values[s]:
                break
            s = int(t[k])
            xz = lay.xz(lay.cell[s])
            trail.append(np.array([xz[0], lay.smooth[s], xz[1]]))
        goals = field.goals
        last = trail[-1]
        trail.append(goals[int(np.argmin(np.hypot(goals[:, 0] - last[0], goals[:, 2] - last[2])))])
        pts = np.array(trail)
        out = [0]
        while out[-1] < len(pts) - 1:  # each point joined to the farthest later one the trail stays near
            i, j = out[-1], out[-1] + 1
            while j + 1 < len(pts) and _near_segment(pts[i + 1:j + 1], pts[i], pts[j + 1], lay.cell_size / 2):
                j += 1
            out.append(j)
        return [mn.Vector3(np.asarray(pts[k], np.float32)) for k in out]

    # ------------------------------------------------------------------ motion
    def _step(self, start, end, sliding: bool) -> mn.Vector3:
        s, e = _vec(start), _vec(end)
        ls, le = self._locate(s), self._locate(e)
        if ls is None or le is None:
            return mn.Vector3(s)
        engine, ss = ls
        if isinstance(engine, NavGrid):
            if le[0] is engine and engine.island_id(ss) == engine.island_id(le[1]):
                new, collided = engine.try_step(ss, e, sliding=sliding)
                if not (collided and self._stairs_join(engine)):
                    return mn.Vector3(new)
            elif not self._multi_storey():
                return mn.Vector3(s)
            else:
                new = s
            # the storey's grid stops the step (or the target is off it): the joined surfaces may carry it onto a
            # stair or a ramp, off the storey's floor
            lay = self._layered()
            if self._island(lay, ss) != self._island(lay, e if le[0] is lay else le[1]):
                return mn.Vector3(new)
            up, _ = lay.try_step(ss, e, sliding=sliding)
            off_floor = abs(up[1] - engine.floor_height) > engine.config.max_climb / 2
            return mn.Vector3(up if off_floor else new)
        if self._island(engine, ss) != self._island(engine, le[1]):
            return mn.Vector3(s)
        new, _ = engine.try_step(ss, e, sliding=sliding)
        return mn.Vector3(new)

    def try_step(self, start, end) -> mn.Vector3:
        """Where an agent moving from ``start`` towards ``end`` ends up, sliding along walls."""
        return self._step(start, end, sliding=True)

    def try_step_no_sliding(self, start, end) -> mn.Vector3:
        """Where an agent moving from ``start`` towards ``end`` ends up, stopping at the first wall."""
        return self._step(start, end, sliding=False)

    # ------------------------------------------------------------------ maps
    def get_bounds(self) -> tuple[mn.Vector3, mn.Vector3]:
        """(min, max) corners of the scene mesh's box, what habitat-sim reports for the navmesh it builds from a
        scene (``PathFinder::Impl::build``); without the scene, of the grid's extent at its floor's height."""
        if self._asset is not None:
            lo, hi = np.asarray(self._asset.mesh.bounds, np.float64)
            return mn.Vector3(lo), mn.Vector3(hi)
        g = self.grid
        cs = g.cell_size
        h, w = g.navigable.shape
        lo = (g.origin[0] + cs / 2, g.floor_height, g.origin[1] + cs / 2)
        hi = (g.origin[0] + (w - 1.5) * cs, g.floor_height, g.origin[1] + (h - 1.5) * cs)
        return mn.Vector3(lo), mn.Vector3(hi)

    def get_topdown_view(self, meters_per_pixel: float, height: float, eps: float = 0.5) -> np.ndarray:
        """bool ``[z, x]`` image: ``is_navigable((x, height, z), eps)`` on a grid of ``meters_per_pixel`` from the
        bounds' min corner (navmesh-spec §6 ``getTopDownView``)."""
        lo, hi = (np.asarray(v, np.float64) for v in self.get_bounds())
        x_res = int(np.float32(abs(hi[0] - lo[0])) / np.float32(meters_per_pixel))
        z_res = int(np.float32(abs(hi[2] - lo[2])) / np.float32(meters_per_pixel))
        # float32 accumulation from the min corner, as getTopDownView steps
        x = np.cumsum(np.concatenate([[np.float32(lo[0])], np.full(max(x_res - 1, 0), np.float32(meters_per_pixel))])
                      .astype(np.float32), dtype=np.float32)[:x_res]
        z = np.cumsum(np.concatenate([[np.float32(lo[2])], np.full(max(z_res - 1, 0), np.float32(meters_per_pixel))])
                      .astype(np.float32), dtype=np.float32)[:z_res]
        zz, xx = np.meshgrid(z.astype(np.float64), x.astype(np.float64), indexing="ij")
        g = self._grid_for(float(height))
        view = g._navigable_xz(xx, zz) if abs(height - g.floor_height) <= eps else np.zeros((z_res, x_res), bool)
        if self._multi_storey():  # the stairs and ramps within eps of the slice, off the storey's floor
            lay = self._layered()
            spans = lay.walkable()
            spans = spans[(np.abs(lay.height[spans] - height) <= eps) &
                          (np.abs(lay.height[spans] - g.floor_height) > g.config.max_climb / 2)]
            if len(spans):
                i = np.floor((zz - lay.origin[1]) / lay.cell_size + 0.5).astype(np.int64)
                j = np.floor((xx - lay.origin[0]) / lay.cell_size + 0.5).astype(np.int64)
                view |= np.isin(i * lay.shape[1] + j, lay.cell[spans]) & (i >= 0) & (j >= 0) & (j < lay.shape[1])
        return view


class GreedyFollowerCodes:
    ERROR = -1
    STOP = 0
    FORWARD = 1
    LEFT = 2
    RIGHT = 3


class GreedyGeodesicFollowerImpl:
    """habitat-sim's ``GreedyGeodesicFollowerImpl`` (``src/esp/nav/GreedyFollower.cpp``): at each step, of the
    primitives ``[LEFT] * n + [FORWARD]`` and ``[RIGHT] * n + [FORWARD]`` for turns ``n * turn < pi``, take the
    first action of the one with the best reward ``(d0 - d1) / forward - 0.0125 n - 0.25 collided - 0.05 (close to
    an obstacle)``; STOP within ``goal_dist``; a left-right thrashing run of ``thrashing_threshold`` actions is
    broken by playing the whole chosen primitive."""

    COLLISION_COST = 0.25
    CLOSE_TO_OBSTACLE = 0.2

    def __init__(self, pathfinder: PathFinder, move_forward, turn_left, turn_right, goal_dist: float,
                 forward_amount: float, turn_amount: float, fix_thrashing: bool = True,
                 thrashing_threshold: int = 16) -> None:
        self.pathfinder = pathfinder
        self._forward, self._left, self._right = move_forward, turn_left, turn_right
        self.goal_dist, self.forward_amount, self.turn_amount = goal_dist, forward_amount, turn_amount
        self.fix_thrashing, self.thrashing_threshold = fix_thrashing, thrashing_threshold
        self._actions: list[int] = []
        self._thrashing_actions: list[int] = []

    def reset(self) -> None:
        self._actions.clear()
        self._thrashing_actions.clear()

    def _geo(self, start, end) -> float:
        p = ShortestPath()
        p.requested_start, p.requested_end = np.asarray(start, np.float32), np.asarray(end, np.float32)
        self.pathfinder.find_path(p)
        return p.geodesic_distance

    def _reward(self, node: SceneNode, d0: float, end, prim_len: int) -> float:
        dummy = SceneNode()
        dummy.translation, dummy.rotation = mn.Vector3(node.translation), mn.Quaternion(node.rotation.vector,
                                                                                       node.rotation.scalar)
        collided = self._forward(dummy)
        d1 = self._geo(dummy.translation, end)
        obstacle = self.pathfinder.distance_to_closest_obstacle(dummy.translation, 1.1 * self.CLOSE_TO_OBSTACLE)
        return ((d0 - d1) / self.forward_amount - 0.0125 * prim_len - (self.COLLISION_COST if collided else 0.0)
                - (0.05 if obstacle < self.CLOSE_TO_OBSTACLE else 0.0))

    def _best_prim(self, rotation: mn.Quaternion, position, end, d0: float) -> list[int]:
        if d0 == math.inf:
            return [GreedyFollowerCodes.ERROR]
        if d0 < self.goal_dist:
            return [GreedyFollowerCodes.STOP]
        best_reward, best = -self.COLLISION_COST, []
        left, right = SceneNode(), SceneNode()
        for n in (left, right):
            n.translation, n.rotation = mn.Vector3(position), mn.Quaternion(rotation.vector, rotation.scalar)
        left_prim: list[int] = []
        right_prim: list[int] = []
        angle = 0.0
        while angle < math.pi:
            for node, prim in ((left, left_prim), (right, right_prim)):
                reward = self._reward(node, d0, end, len(prim))
                if reward > best_reward:
                    best_reward, best = reward, [*prim, GreedyFollowerCodes.FORWARD]
            if best_reward > 0.99:
                break
            left_prim.append(GreedyFollowerCodes.LEFT)
            self._left(left)
            right_prim.append(GreedyFollowerCodes.RIGHT)
            self._right(right)
            angle += self.turn_amount
        return best

    def _is_thrashing(self) -> bool:
        a = self._actions
        if len(a) < self.thrashing_threshold:
            return False
        last = a[-1]
        thrashing = last in (GreedyFollowerCodes.LEFT, GreedyFollowerCodes.RIGHT)
        i = 2
        while i < self.thrashing_threshold + 1 and thrashing:
            prev = a[-i]
            thrashing = (prev == GreedyFollowerCodes.RIGHT and last == GreedyFollowerCodes.LEFT) or \
                (prev == GreedyFollowerCodes.LEFT and last == GreedyFollowerCodes.RIGHT)
            last = prev
            i += 1
        return thrashing

    def next_action_along(self, rotation: mn.Quaternion, position, end) -> int:
        d0 = self._geo(position, end)
        if self.fix_thrashing and self._thrashing_actions:
            action = self._thrashing_actions.pop()
        else:
            prim = self._best_prim(rotation, position, end, d0)
            if not prim:
                action = GreedyFollowerCodes.ERROR
            elif self.fix_thrashing and self._is_thrashing():
                self._thrashing_actions = prim[::-1]
                action = self._thrashing_actions.pop()
            else:
                action = prim[0]
        self._actions.append(action)
        return action


class GreedyGeodesicFollower:
    """habitat-sim's ``GreedyGeodesicFollower``: the actions of an agent's action space (by ``ActionSpec.name``)
    that greedily follow the geodesic to a goal; ``next_action_along`` raises
    :class:`~navbench.habitat_sim.errors.GreedyFollowerError` when the goal is unreachable."""

    def __init__(self, pathfinder: PathFinder, agent, goal_radius: float | None = None, *, stop_key=None,
                 forward_key=None, left_key=None, right_key=None, fix_thrashing: bool = True,
                 thrashing_threshold: int = 16) -> None:
        self.pathfinder = pathfinder
        self.agent = agent
        self.last_goal: np.ndarray | None = None
        self.action_mapping: dict[int, Any] = {GreedyFollowerCodes.STOP: stop_key}
        key, self.forward_spec = self._find_action("move_forward")
        self.action_mapping[GreedyFollowerCodes.FORWARD] = key if forward_key is None else forward_key
        key, self.left_spec = self._find_action("turn_left")
        self.action_mapping[GreedyFollowerCodes.LEFT] = key if left_key is None else left_key
        key, self.right_spec = self._find_action("turn_right")
        self.action_mapping[GreedyFollowerCodes.RIGHT] = key if right_key is None else right_key
        self.goal_radius = 0.75 * self.forward_spec.amount if goal_radius is None else goal_radius
        self.impl = GreedyGeodesicFollowerImpl(
            pathfinder, lambda n: agent.controls(n, "move_forward", self.forward_spec, True),
            lambda n: agent.controls(n, "turn_left", self.left_spec, True),
            lambda n: agent.controls(n, "turn_right", self.right_spec, True),
            self.goal_radius, self.forward_spec.amount, math.radians(self.left_spec.amount), fix_thrashing,
            thrashing_threshold)

    def _find_action(self, name: str):
        found = [(k, spec.actuation) for k, spec in self.agent.agent_config.action_space.items() if spec.name == name]
        if len(found) != 1:
            raise ValueError(f"Could not find an action spec corresponding to {name}")
        return found[0]

    def next_action_along(self, goal_pos) -> Any:
        if self.last_goal is None or not np.allclose(goal_pos, self.last_goal):
            self.reset()
            self.last_goal = np.asarray(goal_pos)
        node = self.agent.scene_node
        action = self.impl.next_action_along(node.rotation, node.absolute_translation, np.asarray(goal_pos))
        if action == GreedyFollowerCodes.ERROR:
            raise errors.GreedyFollowerError()
        return self.action_mapping[action]

    def reset(self) -> None:
        self.impl.reset()
        self.last_goal = None
