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
"""

from __future__ import annotations

import math

import numpy as np
import skfmm

from navbench.scene.follower import GreedyFollower
from navbench.scene.navigability import GeodesicField, NavGrid

_GOAL_DISC_CELLS = 1.5


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
        d = np.asarray(depth01, np.float32)
        d = d[..., 0] if d.ndim == 3 else d
        H, W = d.shape
        r0 = max(0, H // 2 - self.horizon_rows // 2)
        band = d[r0:r0 + self.horizon_rows]
        # 0 = nearer than min_depth, 1 = nothing within max_depth: both clip to the range's ends.
        col = self.min_depth + np.median(band, axis=0) * (self.max_depth - self.min_depth)
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
        fwd = -(dx * math.sin(yaw) + dz * math.cos(yaw))  # the agent faces -z at yaw 0
        lat = dx * math.cos(yaw) - dz * math.sin(yaw)  # +x is right at yaw 0
        ok = fwd > 1e-6
        ratio = np.where(ok, lat / np.maximum(fwd, 1e-6), np.inf)
        ok &= np.abs(ratio) < self.tan_half
        fx = (W / 2.0) / self.tan_half
        u = np.clip(np.round((W - 1) / 2.0 + fx * np.where(ok, ratio, 0.0)).astype(np.int64), 0, W - 1)
        ok &= fwd <= col[u] + self.margin
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
