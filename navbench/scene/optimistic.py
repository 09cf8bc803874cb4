"""An expert that knows only what the agent has seen: geodesics on an *optimistic* map.

The greedy follower (:mod:`navbench.scene.follower`) plans on the true navigability grid, so it walks
straight to the one door that leads to the goal even when that door has never been in view. A policy
that sees only depth, GPS+compass and its own history cannot infer such labels, and imitating them
teaches it an average of incompatible actions. :class:`OptimisticFollower` labels instead with the
shortest path on the map *as seen so far*: cells that some depth frame has covered keep their true
navigability, cells never seen count as free (the classic optimistic planner). Its labels are a
function of the observation history, which is what a recurrent policy can learn to reproduce.

``SeenMask.update`` marks grid cells covered by a depth frame: inside the horizontal field of view,
in front of the camera and no farther than the depth measured in their image column around the
horizon row (plus a margin, so the obstacle's own cells count as seen).

On several storeys (:class:`LayeredOptimisticFollower`, an episode the env runs on a
:class:`~navbench.scene.layers.LayeredNav`) the map is the layered surfaces made optimistic the same
way: every span and, on each storey's floor, a *virtual* node in every cell with no surface within the
agent's height of that floor (a wall, furniture, a stairwell) are passable until a frame covers them
(the cell in view, at most the agent's height above or below its own surface); covered, they keep
their true navigability (virtual nodes: none). Which surfaces exist and how stairs and ramps join the
storeys is known, as a floor plan shows; what stands on a storey is learnt by looking. Geodesics use
the same 32 lattice directions and 3-D step lengths as the true surfaces.
"""

from __future__ import annotations

import math

import numpy as np
import skfmm
from scipy.sparse import csgraph

from navbench.scene.follower import GreedyFollower
from navbench.scene.layers import LayeredNav, LayerView, _FieldView, _joins, _lattice
from navbench.scene.navigability import GeodesicField, NavGrid

_GOAL_DISC_CELLS = 1.5


def depth_columns(depth01: np.ndarray, min_depth: float, max_depth: float, horizon_rows: int) -> np.ndarray:
    """Depth (m) in each image column of a normalised depth frame (H, W[, 1]): the median of the
    ``horizon_rows`` rows around the horizon."""
    d = np.asarray(depth01, np.float32)
    d = d[..., 0] if d.ndim == 3 else d
    H = d.shape[0]
    r0 = max(0, H // 2 - horizon_rows // 2)
    band = d[r0:r0 + horizon_rows]
    # 0 = nearer than min_depth, 1 = nothing within max_depth: both clip to the range's ends.
    return min_depth + np.median(band, axis=0) * (max_depth - min_depth)


def in_view(dx: np.ndarray, dz: np.ndarray, yaw: float, col: np.ndarray, tan_half: float, margin: float) -> np.ndarray:
    """Whether points at offsets (dx, dz) from the camera are covered by a frame of column depths ``col``:
    inside the horizontal field of view, in front, and no farther than their column's depth plus ``margin``."""
    W = len(col)
    fwd = -(dx * math.sin(yaw) + dz * math.cos(yaw))  # the agent faces -z at yaw 0
    lat = dx * math.cos(yaw) - dz * math.sin(yaw)  # +x is right at yaw 0
    ok = fwd > 1e-6
    ratio = np.where(ok, lat / np.maximum(fwd, 1e-6), np.inf)
    ok &= np.abs(ratio) < tan_half
    fx = (W / 2.0) / tan_half
    u = np.clip(np.round((W - 1) / 2.0 + fx * np.where(ok, ratio, 0.0)).astype(np.int64), 0, W - 1)
    ok &= fwd <= col[u] + margin
    return ok


class SeenMask:
    """Grid cells of ``navgrid`` covered by any depth frame so far (see module docstring)."""

    def __init__(self, navgrid: NavGrid, hfov_deg: float, min_depth: float, max_depth: float,
                 margin: float = 0.15, horizon_rows: int = 5):
        self.grid = navgrid
        self.seen = np.zeros(navgrid.navigable.shape, bool)
        self.tan_half = math.tan(math.radians(hfov_deg) / 2.0)
        self.min_depth, self.max_depth = min_depth, max_depth
        self.margin, self.horizon_rows = margin, horizon_rows
        h, w = self.seen.shape
        self._ii, self._jj = np.mgrid[0:h, 0:w]

    def update(self, depth01: np.ndarray, position, yaw: float) -> np.ndarray:
        """Mark the cells this normalised depth frame (H, W[, 1]) covers; returns the newly seen mask."""
        col = depth_columns(depth01, self.min_depth, self.max_depth, self.horizon_rows)
        g = self.grid
        cs = g.cell_size
        px, pz = float(position[0]), float(position[2])
        reach = self.max_depth + self.margin
        i0 = max(0, int((pz - reach - g.origin[1]) / cs))
        i1 = min(self.seen.shape[0], int((pz + reach - g.origin[1]) / cs) + 2)
        j0 = max(0, int((px - reach - g.origin[0]) / cs))
        j1 = min(self.seen.shape[1], int((px + reach - g.origin[0]) / cs) + 2)
        if i0 >= i1 or j0 >= j1:
            return np.zeros_like(self.seen)
        dx = g.origin[0] + self._jj[i0:i1, j0:j1] * cs - px
        dz = g.origin[1] + self._ii[i0:i1, j0:j1] * cs - pz
        ok = in_view(dx, dz, yaw, col, self.tan_half, self.margin)
        window = self.seen[i0:i1, j0:j1]
        new = ok & ~window
        window |= ok
        out = np.zeros_like(self.seen)
        out[i0:i1, j0:j1] = new
        return out


def optimistic_field(navgrid: NavGrid, goal, seen: np.ndarray) -> GeodesicField:
    """Geodesic field to ``goal`` where unseen cells are passable and seen ones keep their navigability."""
    g = navgrid
    cs = g.cell_size
    passable = g.navigable | ~seen
    h, w = passable.shape
    gx, gz = float(goal[0]), float(goal[2])
    gi, gj = (gz - g.origin[1]) / cs, (gx - g.origin[0]) / cs
    k = int(math.ceil(_GOAL_DISC_CELLS)) + 2
    ii, jj = np.mgrid[max(0, int(gi) - k):min(h, int(gi) + k + 2), max(0, int(gj) - k):min(w, int(gj) + k + 2)]
    dist = np.hypot(g.origin[0] + jj * cs - gx, g.origin[1] + ii * cs - gz)
    r = _GOAL_DISC_CELLS * cs
    phi = np.ones((h, w))
    phi[ii, jj] = np.minimum(dist - r, 1.0)
    near_goal = np.full((h, w), -1, np.int32)
    near_goal[ii, jj] = 0
    if not (phi < 0).any() or not passable[phi < 0].any():
        return GeodesicField(g, np.zeros((0, 3)), np.full((h, w), np.inf), np.full((h, w), -1, np.int32))
    d = skfmm.distance(np.ma.MaskedArray(phi, mask=~passable), dx=cs, order=1)
    d = np.ma.filled(d, np.inf) + r
    exact = np.full((h, w), np.inf)
    exact[ii, jj] = dist
    d = np.where(phi < 0, exact, d)
    values = np.where(passable & np.isfinite(d), d, np.inf)
    goal_pt = np.array([[gx, g.floor_height, gz]])
    return GeodesicField(g, goal_pt, values, near_goal)


class OptimisticFollower(GreedyFollower):
    """The greedy follower planning on the optimistic map of what ``observe`` has shown it.

    Call :meth:`observe` with each depth frame before :meth:`next_action`. Motion is still simulated
    on the true grid (a blocked step is known to be blocked), and success is decided on the true
    geodesic distance, as the environment decides it.
    """

    def __init__(self, navgrid: NavGrid, goal, success_distance: float, hfov_deg: float, min_depth: float,
                 max_depth: float, **kwargs):
        super().__init__(navgrid, goal, success_distance, **kwargs)
        self.true_field = self.field
        self.goal = np.asarray(goal, float).reshape(-1, 3)[0]
        self.mask = SeenMask(navgrid, hfov_deg, min_depth, max_depth)
        self.field = optimistic_field(navgrid, self.goal, self.mask.seen)

    def observe(self, depth01: np.ndarray, position, yaw: float) -> None:
        new = self.mask.update(depth01, position, yaw)
        # Seeing free cells changes nothing (unseen cells already count as free): replan only when
        # an obstacle appeared.
        if (new & ~self.navgrid.navigable).any():
            self.field = optimistic_field(self.navgrid, self.goal, self.mask.seen)
            self._plan_xz = None

    def next_action(self, position, rotation_xyzw) -> int:
        p = np.asarray(position, float)
        if self.true_field.distance(p) < self.success_distance:
            self.turns_ahead = 0
            return 0  # STOP
        return super().next_action(position, rotation_xyzw)


class LayeredSeen:
    """The optimistic map over a :class:`LayeredNav` (module docstring): nodes, what is seen, and fields."""

    def __init__(self, nav: LayeredNav, hfov_deg: float, min_depth: float, max_depth: float,
                 margin: float = 0.15, horizon_rows: int = 5):
        self.nav = nav
        c = nav.config
        h, w = nav.shape
        cells, heights, smooths = [nav.cell], [nav.height], [nav.smooth]
        for floor in nav.storeys():
            # Virtual floor nodes where the cell has no surface within the agent's height of the floor: there
            # no real span is within a step of the virtual node, so every join to it is unambiguous (a stair's
            # lower treads keep their joins to each other, the floor under its high end is blocked).
            has = np.zeros(h * w, bool)
            has[nav.cell[np.abs(nav.height - floor) < c.agent_height]] = True
            free = np.flatnonzero(~has)
            cells.append(free)
            heights.append(np.full(len(free), floor))
            smooths.append(np.full(len(free), floor))
        cell, height, smooth = np.concatenate(cells), np.concatenate(heights), np.concatenate(smooths)
        order = np.lexsort((height, cell))
        self.cell, self.height, self.smooth = cell[order], height[order], smooth[order]
        m = len(order)
        rank = np.empty(m, np.int64)
        rank[order] = np.arange(m)
        self.node_of_span = rank[:len(nav.cell)]
        self.navigable = np.zeros(m, bool)
        self.navigable[self.node_of_span] = nav.navigable
        xz = nav.xz(self.cell)
        self.x, self.z = xz[:, 0], xz[:, 1]
        self.nbr = _joins(self.cell, self.height, h, w, c.max_climb)
        self.seen = np.zeros(m, bool)
        self.tan_half = math.tan(math.radians(hfov_deg) / 2.0)
        self.min_depth, self.max_depth = min_depth, max_depth
        self.margin, self.horizon_rows = margin, horizon_rows

    def update(self, depth01: np.ndarray, position, yaw: float, surface_y: float) -> np.ndarray:
        """Mark the nodes this frame covers, seen from ``position`` (xz) on a surface at ``surface_y``;
        returns the newly seen nodes' indices."""
        col = depth_columns(depth01, self.min_depth, self.max_depth, self.horizon_rows)
        px, pz = float(position[0]), float(position[2])
        reach = self.max_depth + self.margin
        cand = np.flatnonzero(~self.seen & (np.abs(self.x - px) <= reach) & (np.abs(self.z - pz) <= reach) &
                              (np.abs(self.height - surface_y) <= self.nav.config.agent_height))
        new = cand[in_view(self.x[cand] - px, self.z[cand] - pz, yaw, col, self.tan_half, self.margin)]
        self.seen[new] = True
        return new

    def field(self, goal: np.ndarray) -> _OptimisticLayeredField:
        """Geodesic distance over the nodes passable on the map as seen so far to ``goal``."""
        passable = self.navigable | ~self.seen
        graph = _lattice(self.nbr, passable, self.cell, self.smooth, self.nav.shape[1], self.nav.cell_size)
        span = self.nav.span_of(goal)
        values = np.full(len(self.cell), np.inf)
        if span >= 0:
            node = int(self.node_of_span[span])
            values = csgraph.dijkstra(graph, indices=node, directed=True)
            values += math.hypot(self.x[node] - goal[0], self.z[node] - goal[2])
        return _OptimisticLayeredField(self, graph, values, goal, span)


class _OptimisticLayeredField:
    """A :class:`~navbench.scene.layers.LayeredField` over the optimistic nodes (seen through ``_FieldView``)."""

    def __init__(self, seen: LayeredSeen, graph, values: np.ndarray, goal: np.ndarray, goal_span: int):
        self._seen, self._graph, self.values = seen, graph, values
        self.goals = np.asarray(goal, float).reshape(1, 3)
        self._goal_span = goal_span

    def distance_on(self, s: int, p: np.ndarray) -> float:
        """Distance from point ``p`` standing on span ``s`` (inf if ``s`` < 0), as the true field measures it."""
        if s < 0:
            return math.inf
        m, nav, g = self._seen, self._seen.nav, self._graph
        node = int(m.node_of_span[s])
        cand = np.concatenate([[node], g.indices[g.indptr[node]:g.indptr[node + 1]]])
        legs = np.sqrt((m.x[cand] - p[0]) ** 2 + (m.z[cand] - p[2]) ** 2 + (m.smooth[cand] - m.smooth[node]) ** 2)
        best = float(np.min(self.values[cand] + legs))
        gs, q = self._goal_span, self.goals[0]
        if math.isfinite(best) and gs >= 0 and nav.component[gs] == nav.component[s] and \
                abs(nav.height[gs] - nav.height[s]) <= nav.config.max_climb and \
                math.hypot(q[0] - p[0], q[2] - p[2]) <= 2 * nav.config.agent_radius:
            best = math.hypot(q[0] - p[0], q[2] - p[2])
        return best


class LayeredOptimisticFollower(GreedyFollower):
    """:class:`OptimisticFollower` on several storeys: moves over a :class:`LayerView`, plans on
    :class:`LayeredSeen`'s optimistic map, and decides success on the true layered distance."""

    def __init__(self, view: LayerView, goal, success_distance: float, hfov_deg: float, min_depth: float,
                 max_depth: float, **kwargs):
        super().__init__(view, goal, success_distance, **kwargs)  # type: ignore[arg-type]  # NavGrid's interface
        self.view = view
        self.true_field = self.field
        self.goal = np.asarray(goal, float).reshape(-1, 3)[0]
        self.map = LayeredSeen(view.nav, hfov_deg, min_depth, max_depth)
        self.field = _FieldView(view, self.map.field(self.goal))  # type: ignore[arg-type]

    def observe(self, depth01: np.ndarray, position, yaw: float) -> None:
        new = self.map.update(depth01, position, yaw, self.view.surface_height)
        if (~self.map.navigable[new]).any():  # an obstacle appeared: replan (seen free nodes change nothing)
            self.field = _FieldView(self.view, self.map.field(self.goal))  # type: ignore[arg-type]
            self._plan_xz = None

    def next_action(self, position, rotation_xyzw) -> int:
        if self.true_field.distance(np.asarray(position, float)) < self.success_distance:
            self.turns_ahead = 0
            return 0  # STOP
        return super().next_action(position, rotation_xyzw)
