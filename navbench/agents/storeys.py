"""Routes of the memory agent over the joined walkable surfaces of a multi-storey scene.

GPS gives the agent its xz, not the surface it stands on. :class:`Storeys` keeps that surface with a
:class:`~navbench.scene.layers.LayerView` (the one of the agent's cell nearest in height to where it last
stood), so the camera's height, and with it the visibility test, the detector's backprojection and the STOP
radius, follows the agent up a flight of stairs or a ramp.

A target (a goal candidate's cloud) stands on the storey under it: the highest navigable surface within
``reach`` (xz) of it at most ``max_climb`` above its lowest point. Its *floor points* are its cloud's points
dropped onto that surface; the geodesic field to them over the surfaces (:class:`~navbench.scene.layers.
LayeredField`) ranks candidates (route lengths through the stairs, not the straight line through a ceiling)
and, while the agent stands on another storey, gives the PointNav policy its next goal: the point ``ahead``
metres along the shortest path (down the field), so the policy drives the flight instead of to the point
under (or over) the target.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from navbench.localize.fusion import GoalCandidate
from navbench.scene.follower import GreedyFollower
from navbench.scene.layers import LayeredField, LayeredNav, LayerView
from navbench.scene.pose import quat_from_yaw

_FLOOR_POINTS = 64  # cloud points dropped onto the target's storey (a subsample: the field's goals)
_CARROT_TRIES = 12  # points along the path tried for a straight walk, farthest first


class Storeys:
    """The agent's surface and its routes over ``nav`` for one episode started at ``start``."""

    def __init__(self, nav: LayeredNav, start, forward_step: float = 0.25, turn_angle_deg: float = 30.0,
                 reach: float = 1.5, ahead: float = 2.0, climb_ahead: float = 1.0):
        self.nav, self.view = nav, LayerView(nav, start)
        self.forward_step, self.turn_angle_deg = float(forward_step), float(turn_angle_deg)
        self.reach, self.ahead, self.climb_ahead = float(reach), float(ahead), float(climb_ahead)
        self._floors: dict[int, float] = {}  # id(candidate) -> the height of its storey's surface
        self._followers: dict[int, GreedyFollower] = {}  # id(candidate) -> its follower over the surfaces
        span = nav.span_of(start, max_dist=nav.cell_size)
        self.height = float(nav.height[span]) if span >= 0 else float(np.asarray(start, np.float64)[1])

    def track(self, position: np.ndarray) -> np.ndarray:
        """``position`` (xz from GPS) with y the height of the surface the agent stands on."""
        self.view.track(position)
        span = self.view.locate(float(position[0]), float(position[2]))
        if span >= 0:
            self.height = float(self.nav.height[span])
        return np.array([position[0], self.height, position[2]], np.float64)

    def floor(self, c: GoalCandidate) -> float:
        """The height of the surface of the storey candidate ``c`` stands on (module docstring)."""
        key = id(c)
        if key not in self._floors:
            nav = self.nav
            pts = np.asarray(c.points, np.float64).reshape(-1, 3)
            pts = pts if len(pts) else np.asarray(c.centre, np.float64).reshape(1, 3)
            spans = np.flatnonzero(nav.navigable)
            xz = nav.xz(nav.cell[spans])
            centre = pts.mean(axis=0)
            near = np.hypot(xz[:, 0] - centre[0], xz[:, 1] - centre[2]) <= self.reach
            h = nav.height[spans[near]]
            h = h[h <= pts[:, 1].min() + nav.config.max_climb]
            self._floors[key] = float(h.max()) if len(h) else float(pts[:, 1].min())
        return self._floors[key]

    def floor_points(self, c: GoalCandidate) -> np.ndarray:
        pts = np.asarray(c.points, np.float64).reshape(-1, 3)
        pts = pts if len(pts) else np.asarray(c.centre, np.float64).reshape(1, 3)
        pts = pts[np.linspace(0, len(pts) - 1, min(len(pts), _FLOOR_POINTS)).astype(int)].copy()
        pts[:, 1] = self.floor(c)
        return pts

    def field(self, c: GoalCandidate) -> LayeredField:
        return self.nav.distance_field(self.floor_points(c))

    def elsewhere(self, c: GoalCandidate) -> bool:
        """Whether the agent stands on another storey (or a flight between) than candidate ``c``."""
        return abs(self.height - self.floor(c)) > self.nav.config.max_climb / 2  # a stair's last tread too

    def lengths(self, position: np.ndarray, cands: Sequence[GoalCandidate]) -> np.ndarray:
        """Geodesic length (m) from ``position`` (on the agent's surface) to each candidate's floor points;
        inf where the surfaces do not join them."""
        out = np.full(len(cands), np.inf)
        span = self.nav.span_of(np.array([position[0], self.height, position[2]]), max_dist=self.nav.cell_size)
        if span < 0:
            return out
        for j, c in enumerate(cands):
            out[j] = float(self.field(c).values[span])
        return out

    def _descend(self, span: int, values: np.ndarray, length: float) -> list[int]:
        """Spans along the shortest path down ``values`` from ``span``, about ``length`` metres of it."""
        g, out, walked = self.nav.graph, [span], 0.0
        while walked < length:
            idx, w = g.indices[g.indptr[span]:g.indptr[span + 1]], g.data[g.indptr[span]:g.indptr[span + 1]]
            if not len(idx):
                break
            k = int(np.argmin(values[idx] + w))
            if not values[idx[k]] < values[span]:
                break
            span, walked = int(idx[k]), walked + float(w[k])
            out.append(span)
        return out

    def carrot(self, position: np.ndarray, c: GoalCandidate) -> np.ndarray | None:
        """The farthest point at most ``ahead`` metres along the shortest path from ``position`` to candidate
        ``c`` that a straight walk from ``position`` reaches (a path bending round the side of a flight
        gives a point the policy can drive straight to, not one beyond the flight's edge); None where the
        surfaces do not join them."""
        field = self.field(c)
        x, z = float(position[0]), float(position[2])
        span = self.view.locate(x, z)
        if span < 0 or not np.isfinite(field.values[span]):
            return None
        path = self._descend(span, field.values, self.ahead)
        for k in range(len(path) - 1, 0, -max(1, len(path) // _CARROT_TRIES)):
            target = self.nav.position(path[k])
            end, _, _, stopped = self.nav._straight(span, x, z, float(target[0]), float(target[2]))
            if not stopped and end == path[k]:
                return target
        return self.nav.position(path[min(1, len(path) - 1)])

    def climb(self, position: np.ndarray, yaw: float, c: GoalCandidate) -> int | None:
        """The next action up (or down) a flight of stairs or a ramp towards candidate ``c``, or None off
        one: where the next ``climb_ahead`` metres of the shortest path change height. There the agent
        steps the path with the geodesic follower over the surfaces: a PointNav policy that learnt on
        flat floors reads the risers ahead as an obstacle and turns away."""
        field = self.field(c)
        span = self.view.locate(float(position[0]), float(position[2]))
        if span < 0 or not np.isfinite(field.values[span]):
            return None
        heights = self.nav.height[self._descend(span, field.values, self.climb_ahead)]
        if float(np.ptp(heights)) <= self.nav.config.max_climb / 2:
            return None
        follower = self._followers.get(id(c))
        if follower is None:
            follower = self._followers[id(c)] = GreedyFollower(
                self.view, self.floor_points(c), self.nav.cell_size, forward_step=self.forward_step,
                turn_angle_deg=self.turn_angle_deg)
        return int(follower.next_action(position, quat_from_yaw(yaw)))

    def path(self, position: np.ndarray, c: GoalCandidate, spacing: float = 1.0) -> np.ndarray:
        """Points (K, 3) every ``spacing`` metres along the shortest path to candidate ``c``; (0, 3) if none."""
        field = self.field(c)
        span = self.view.locate(float(position[0]), float(position[2]))
        if span < 0 or not np.isfinite(field.values[span]):
            return np.zeros((0, 3))
        spans = self._descend(span, field.values, np.inf)
        pts = np.array([self.nav.position(s) for s in spans])
        step = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        along = np.concatenate([[0.0], np.cumsum(step)])
        keep = np.unique(np.searchsorted(along, np.arange(spacing, along[-1], spacing)))
        return np.vstack([pts[keep], pts[-1:]]) if len(pts) > 1 else np.zeros((0, 3))

    def tour(self, position: np.ndarray, spacing: float = 2.0) -> list[np.ndarray]:
        """Points spread over the surface the agent stands on (one navigable span per ``spacing`` metre square
        of its joined component, on its storey), nearest first in a greedy tour from ``position``: where to
        look when no candidate stands on a surface joined to the agent's."""
        nav = self.nav
        span = self.view.locate(float(position[0]), float(position[2]))
        if span < 0:
            return []
        idx = np.flatnonzero((nav.component == nav.component[span])
                             & (np.abs(nav.height - nav.height[span]) <= nav.config.max_climb))
        xz = nav.xz(nav.cell[idx])
        _, first = np.unique(np.floor(xz / spacing).astype(np.int64), axis=0, return_index=True)
        pts = [nav.position(int(s)) for s in idx[np.sort(first)]]
        out, here = [], np.asarray(position, np.float64)
        while pts:
            k = int(np.argmin([np.hypot(p[0] - here[0], p[2] - here[2]) for p in pts]))
            here = pts.pop(k)
            out.append(here)
        return out
