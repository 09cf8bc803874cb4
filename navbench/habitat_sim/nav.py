"""``habitat_sim.nav``: the path finder, shortest-path queries and the greedy geodesic follower over navbench's
navigability grid (:class:`navbench.scene.navigability.NavGrid`).

habitat-sim answers these queries on a Detour navmesh; here they are answered on navbench's grid of the scene's
main storey, with habitat-sim's conventions (``navmesh-spec.md``: §4 geodesics, §5 try_step, §6 other queries):

* ``geodesic_distance`` is navbench's geodesic field at the snapped start (what navbench's own env measures
  ``d0`` and distance to goal with), ``inf`` when no end is reachable; query points are taken to 10
  micrometres. ``points`` is the string-pulled polyline down the field (computed when first read).
* snapping searches within :data:`SNAP_RADIUS` metres in xz of the point and 4 m in y (Detour's query box
  ``(2, 4, 2)``), and returns NaNs when nothing navigable lies there.
* ``try_step`` / ``try_step_no_sliding`` are the grid's collision rule (navbench's own motion) and return the
  start unchanged when it or the target is off the navigable area or on another island.
* ``NavMeshSettings`` maps to :class:`~navbench.scene.navigability.NavGridConfig` (agent radius, height, max
  climb, cell size); the grid's walkable slope is fixed at 45 degrees, so another ``agent_max_slope`` is refused.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from navbench.habitat_sim import errors
from navbench.habitat_sim import magnum as mn
from navbench.habitat_sim.config import NavMeshSettings
from navbench.habitat_sim.scene import SceneNode
from navbench.scene.navigability import NavGrid, NavGridConfig

SNAP_RADIUS = 2.0  # metres in xz (Detour's findNearestPoly half extents: 2, 4, 2)
SNAP_HEIGHT = 4.0
QUERY_DECIMALS = 5  # find_path's points, in metres: episode files' precision
WALKABLE_SLOPE_DEG = 45.0  # navbench's floor-like test: a normal within 45 degrees of vertical

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


class ShortestPath:
    """A query from ``requested_start`` to ``requested_end``; ``find_path`` fills ``geodesic_distance`` and
    ``points``."""

    def __init__(self) -> None:
        self.requested_start = np.zeros(3, np.float32)
        self.requested_end = np.zeros(3, np.float32)
        self.geodesic_distance = math.inf
        self._points: Any = []

    @property
    def points(self) -> list[np.ndarray]:
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


class PathFinder:
    """habitat-sim's ``PathFinder`` over a :class:`NavGrid` (``load_grid``); queries before a grid is loaded
    answer as habitat-sim's do without a navmesh (not navigable, NaN points, inf distances)."""

    def __init__(self) -> None:
        self._grid: NavGrid | None = None
        self._settings: NavMeshSettings | None = None
        self._rng = np.random.default_rng(0)
        self._island_radius: dict[int, float] = {}

    # ------------------------------------------------------------------ loading
    def load_grid(self, grid: NavGrid, settings: NavMeshSettings | None = None) -> None:
        self._grid = grid
        self._settings = settings
        self._island_radius = {}

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
        """navbench's grid behind this path finder."""
        if self._grid is None:
            raise RuntimeError("PathFinder: no navigability loaded")
        return self._grid

    def seed(self, new_seed: int) -> None:
        """Seeds :meth:`get_random_navigable_point`."""
        self._rng = np.random.default_rng(int(new_seed))

    # ------------------------------------------------------------------ snapping
    def _snap(self, p: np.ndarray) -> np.ndarray | None:
        g = self._grid
        if g is None or not np.isfinite(p).all() or abs(p[1] - g.floor_height) > SNAP_HEIGHT:
            return None
        s = g.snap_point(p, SNAP_RADIUS)
        return s if np.isfinite(s).all() else None

    def snap_point(self, point, island_index: int = -1) -> mn.Vector3:
        p = _vec(point)
        s = self._snap(p)
        if s is not None and island_index != -1 and self.get_island(s) != island_index:
            s = None
        return mn.Vector3(np.full(3, np.nan) if s is None else s)

    def is_navigable(self, point, max_y_delta: float = 0.5) -> bool:
        p = _vec(point)
        s = self._snap(p)
        return s is not None and abs(s[1] - p[1]) <= max_y_delta and math.hypot(s[0] - p[0], s[2] - p[2]) <= 0.01

    def get_island(self, point) -> int:
        """The point's island (0-based), -1 when it does not snap."""
        s = self._snap(_vec(point))
        return -1 if s is None else self.grid.island_id(s) - 1

    @property
    def num_islands(self) -> int:
        return 0 if self._grid is None else int(self._grid.islands.max(initial=0))

    def island_radius(self, point) -> float:
        """The radius of the circle about the island's centroid containing all of its cells, 0 off the grid."""
        s = self._snap(_vec(point))
        if s is None:
            return 0.0
        g = self.grid
        label = g.island_id(s)
        if label not in self._island_radius:
            ii, jj = np.nonzero(g.islands == label)
            xz = np.column_stack([g.origin[0] + jj * g.cell_size, g.origin[1] + ii * g.cell_size])
            centre = xz.mean(axis=0)
            r = float(np.sqrt(((xz - centre) ** 2).sum(axis=1)).max()) + g.cell_size / math.sqrt(2.0)
            self._island_radius[label] = r
        return self._island_radius[label]

    def distance_to_closest_obstacle(self, pt, max_search_radius: float = 2.0) -> float:
        """xz distance from the snapped point to the navigable area's edge, capped at ``max_search_radius``."""
        s = self._snap(_vec(pt))
        if s is None:
            return math.inf
        g = self.grid
        i, j = (int(v) for v in g.world_to_grid(s))
        edge = float(g.navigable_clearance()[i, j]) - g.cell_size / 2.0
        return float(min(max(edge, 0.0), max_search_radius))

    # ------------------------------------------------------------------ sampling
    def get_random_navigable_point(self, max_tries: int = 10, island_index: int = -1) -> mn.Vector3:
        if self._grid is None:
            return mn.Vector3(np.full(3, np.nan))
        for _ in range(max(1, int(max_tries))):
            p = self._grid.sample_navigable_point(self._rng)
            if island_index == -1 or self._grid.island_id(p) - 1 == island_index:
                return mn.Vector3(p)
        return mn.Vector3(np.full(3, np.nan))

    def get_random_navigable_point_near(self, circle_center, radius: float, max_tries: int = 100,
                                        island_index: int = -1) -> mn.Vector3:
        c = _vec(circle_center)
        for _ in range(max(1, int(max_tries))):
            p = np.asarray(self.get_random_navigable_point(1, island_index), np.float64)
            if np.isfinite(p).all() and math.hypot(p[0] - c[0], p[2] - c[2]) <= radius:
                return mn.Vector3(p)
        return mn.Vector3(np.full(3, np.nan))

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
        start = self._snap(np.round(_vec(path.requested_start), QUERY_DECIMALS))
        valid = [k for k, e in enumerate(ends) if self._snap(e) is not None]
        if start is None or not valid:
            return False
        field = self.grid.distance_field(ends[valid])
        d = float(field.distance(start))
        if not math.isfinite(d):
            return False
        path.geodesic_distance = d
        if isinstance(path, MultiGoalShortestPath):
            path.closest_end_point_index = valid[self._nearest_end(field, ends[valid], start)]
        path._points = lambda: self._polyline(field, start)
        return True

    def _nearest_end(self, field, ends: np.ndarray, start: np.ndarray) -> int:
        """Index into ``ends`` of the end the shortest path reaches: the one nearest the path's last point."""
        if len(ends) == 1:
            return 0
        last = self._polyline(field, start)[-1]
        return int(np.argmin(np.hypot(ends[:, 0] - last[0], ends[:, 2] - last[2])))

    def _polyline(self, field, start: np.ndarray) -> list[np.ndarray]:
        """Points from ``start`` to the field's nearest goal: down the field's values from cell to neighbouring
        cell until the goal is in straight navigable line, then each point joined to the farthest later one in
        straight navigable line."""
        g = self.grid
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
        return [np.asarray(q, np.float32) for q in out]

    # ------------------------------------------------------------------ motion
    def _step(self, start, end, sliding: bool) -> mn.Vector3:
        s, e = _vec(start), _vec(end)
        ss, se = self._snap(s), self._snap(e)
        g = self._grid
        if ss is None or se is None or g is None or g.island_id(ss) != g.island_id(se):
            return mn.Vector3(s)
        new, _ = g.try_step(ss, e, sliding=sliding)
        return mn.Vector3(new)

    def try_step(self, start, end) -> mn.Vector3:
        """Where an agent moving from ``start`` towards ``end`` ends up, sliding along walls."""
        return self._step(start, end, sliding=True)

    def try_step_no_sliding(self, start, end) -> mn.Vector3:
        """Where an agent moving from ``start`` towards ``end`` ends up, stopping at the first wall."""
        return self._step(start, end, sliding=False)

    # ------------------------------------------------------------------ maps
    def get_bounds(self) -> tuple[mn.Vector3, mn.Vector3]:
        """The navigable area's (min, max) corners; y is the storey's floor height."""
        g = self.grid
        ii, jj = np.nonzero(g.navigable)
        cs = g.cell_size
        lo = (g.origin[0] + jj.min() * cs - cs / 2, g.floor_height, g.origin[1] + ii.min() * cs - cs / 2)
        hi = (g.origin[0] + jj.max() * cs + cs / 2, g.floor_height, g.origin[1] + ii.max() * cs + cs / 2)
        return mn.Vector3(lo), mn.Vector3(hi)

    def get_topdown_view(self, meters_per_pixel: float, height: float, eps: float = 0.5) -> np.ndarray:
        """bool ``[z, x]`` image: ``is_navigable((x, height, z), eps)`` on a grid of ``meters_per_pixel`` from the
        bounds' min corner (navmesh-spec §6 ``getTopDownView``)."""
        lo, hi = (np.asarray(v, np.float64) for v in self.get_bounds())
        x_res = int(abs(hi[0] - lo[0]) / meters_per_pixel)
        z_res = int(abs(hi[2] - lo[2]) / meters_per_pixel)
        g = self.grid
        if abs(height - g.floor_height) > eps:
            return np.zeros((z_res, x_res), dtype=bool)
        x = (lo[0] + np.arange(x_res) * np.float32(meters_per_pixel)).astype(np.float32)
        z = (lo[2] + np.arange(z_res) * np.float32(meters_per_pixel)).astype(np.float32)
        zz, xx = np.meshgrid(z.astype(np.float64), x.astype(np.float64), indexing="ij")
        return g._navigable_xz(xx, zz)


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
