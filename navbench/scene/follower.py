"""Greedy geodesic follower: the oracle that drives an agent to the nearest goal, like Habitat's
ShortestPathFollower, but planning over the exact discrete motion model.

Actions are Habitat's: 0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT (+turn about +y, counter-clockwise seen
from above), 3 TURN_RIGHT. Turns are free for SPL (only translation counts as path length), so the
follower decides which *heading* the next forward step should take and turns towards it:

- Far from the goal it picks the reachable heading whose forward step (simulated with
  :meth:`NavGrid.try_step`, so collisions count) lowers the geodesic distance the most, preferring
  fewer turns on near ties. Turning does not move the agent, so the choice is remembered until the
  next forward step and the agent can never oscillate between left and right turns.
- Within ``endgame_steps`` forward steps of the success radius it searches sequences of
  (heading, forward step) exhaustively, pruned by the geodesic lower bound, for the fewest forward
  steps that end inside the success distance (ties: fewest turns). This is what makes small success
  distances (0.1 m with 0.25 m steps) reachable without wandering around the goal.
"""

from __future__ import annotations

import math

import numpy as np

from navbench.scene.navigability import NavGrid
from navbench.scene.pose import wrap_angle, yaw_from_quat

STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT = 0, 1, 2, 3
_NUDGES = tuple((dx, dz) for dx in (-1e-4, 0.0, 1e-4) for dz in (-1e-4, 0.0, 1e-4) if dx or dz)  # metres

# Metres of progress one extra turn is worth when two headings are nearly as good (tie-break only).
_TURN_PENALTY = 0.002


class GreedyFollower:
    """Chooses the next action towards the nearest of ``goals`` (see module docstring)."""

    def __init__(self, navgrid: NavGrid, goals, success_distance: float, forward_step: float = 0.25,
                 turn_angle_deg: float = 30.0, sliding: bool = False, endgame_steps: int = 4,
                 clearance_margin: float = 0.0):
        if not (math.isfinite(success_distance) and success_distance > 0):
            raise ValueError(f"success_distance must be a positive number, got {success_distance}")
        if not (math.isfinite(forward_step) and forward_step > 0):
            raise ValueError(f"forward_step must be a positive number, got {forward_step}")
        if not (math.isfinite(turn_angle_deg) and 0 < turn_angle_deg <= 180):
            raise ValueError(f"turn_angle_deg must be in (0, 180], got {turn_angle_deg}")
        self.navgrid = navgrid
        self.field = navgrid.distance_field(goals)
        # Far from the goal, steer on a field that keeps clearance_margin of extra room from obstacles
        # where it can (NavGrid.distance_field explains); the endgame and STOP use true distances.
        self._steer = navgrid.distance_field(goals, clearance_margin) if clearance_margin > 0 else None
        self.success_distance = float(success_distance)
        self.forward_step = float(forward_step)
        self.turn = math.radians(turn_angle_deg)
        self.sliding = sliding
        self.endgame_steps = int(endgame_steps)
        # Headings reachable by k turns, k in [-K, K]; for angles dividing 360 deg, M of them are distinct.
        self._num_headings = max(1, round(2 * math.pi / self.turn))
        self._plan_xz: tuple[float, float] | None = None
        self._plan_yaw = 0.0
        self._yaw0 = 0.0  # heading the current plan's offsets are relative to
        # Turns between the heading at the last next_action and the heading its plan takes (0 after a
        # FORWARD or STOP): imitation training gives the steps of a long turn more weight.
        self.turns_ahead = 0

    @property
    def steer(self):
        """The field the greedy step and the beam search descend (``field`` unless a margin is set)."""
        return self.field if self._steer is None else self._steer

    def observe(self, depth01, position, yaw: float) -> None:
        """Take in a depth frame: nothing to do for a follower that knows the whole map (see
        :class:`navbench.scene.optimistic.OptimisticFollower`, which plans on what it has seen)."""

    def distance(self, position) -> float:
        """Geodesic distance from ``position`` to the nearest goal (inf if unreachable)."""
        return self.field.distance(position)

    def next_action(self, position, rotation_xyzw) -> int:
        """Next action for an agent at ``position`` with rotation ``[x, y, z, w]``.

        STOP when the geodesic distance to the nearest goal is below the success distance, and also
        when no goal is reachable (nothing better can be done; the episode fails either way).
        """
        p = np.asarray(position, dtype=float)
        if p.shape != (3,) or not np.isfinite(p).all():
            raise ValueError(f"position must be a finite xyz point, got {np.asarray(position).tolist()}")
        yaw = yaw_from_quat(rotation_xyzw)
        x, z = float(p[0]), float(p[2])
        d = self.field._distance_xz(x, z)
        if d == math.inf:  # on a cell's edge, read a hair off it: a float32 GPS reading rounds across the edge
            x, z = min(((x + dx, z + dz) for dx, dz in _NUDGES), key=lambda q: self.field._distance_xz(*q))
            d = self.field._distance_xz(x, z)
        self.turns_ahead = 0
        if d < self.success_distance or d == math.inf:
            return STOP
        if self._plan_xz is None or abs(self._plan_xz[0] - x) > 1e-9 or abs(self._plan_xz[1] - z) > 1e-9:
            self._plan_yaw = self._plan(x, z, yaw, d)
            self._plan_xz = (x, z)
        k = round(wrap_angle(self._plan_yaw - yaw) / self.turn)
        self.turns_ahead = abs(k)
        if k == 0:
            self._plan_xz = None  # the agent moves: plan afresh at the next position
            return MOVE_FORWARD
        return TURN_LEFT if k > 0 else TURN_RIGHT

    # ------------------------------------------------------------------ planning

    def _turns(self, m: int) -> int:
        """Turns needed to change heading by m lattice steps."""
        m %= self._num_headings
        return min(m, self._num_headings - m)

    def _step(self, x: float, z: float, yaw: float) -> tuple[float, float]:
        tx, tz = x - self.forward_step * math.sin(yaw), z - self.forward_step * math.cos(yaw)
        if not self.sliding:
            x1, z1, _ = self.navgrid._straight(x, z, tx, tz)
            return x1, z1
        q, _ = self.navgrid.try_step((x, 0.0, z), (tx, 0.0, tz), sliding=True)
        return float(q[0]), float(q[2])

    def _plan(self, x: float, z: float, yaw: float, d: float) -> float:
        """Absolute heading the next forward step should take."""
        self._yaw0 = yaw
        if d - self.success_distance <= self.endgame_steps * self.forward_step:
            m = self._search(x, z, yaw, d)
            if m is not None:
                return yaw + m * self.turn
        return self._greedy(x, z, yaw)

    def _lattice(self) -> list[int]:
        """Heading offsets in lattice steps, fewest turns first, left before right on ties."""
        n = self._num_headings
        offsets = sorted(range(n), key=lambda m: (self._turns(m), -1 if 0 < m <= n // 2 else 1))
        return [m if m <= n // 2 else m - n for m in offsets]

    def _greedy(self, x: float, z: float, yaw: float) -> float:
        d = self.steer._distance_xz(x, z)
        best_score, best_d, best_m = math.inf, math.inf, 0
        for m in self._lattice():
            x1, z1 = self._step(x, z, yaw + m * self.turn)
            d1 = self.steer._distance_xz(x1, z1)
            score = d1 + _TURN_PENALTY * abs(m)
            if score < best_score:
                best_score, best_d, best_m = score, d1, m
        if d - best_d >= 0.5 * self.forward_step:
            return yaw + best_m * self.turn
        # Little progress from any single step: typically the agent stands on the navigable
        # boundary at a corner and the way on starts with a step sideways. Look a few steps ahead.
        return yaw + self._beam(x, z) * self.turn

    def _beam(self, x: float, z: float, width: int = 12, depth: int = 3) -> int:
        """First heading offset of the best sequence found by a beam search over forward steps."""
        lattice = self._lattice()
        beam = [(self.steer._distance_xz(x, z), x, z, 0, None)]  # (distance, x, z, last offset, first offset)
        best = (math.inf, 0)
        for _ in range(depth):
            children = []
            for _, px, pz, prev, first in beam:
                for m in lattice:
                    qx, qz = self._step(px, pz, self._yaw0 + m * self.turn)
                    if abs(qx - px) + abs(qz - pz) < 1e-6:
                        continue
                    dq = self.steer._distance_xz(qx, qz)
                    f = m if first is None else first
                    children.append((dq + _TURN_PENALTY * self._turns(m - prev), qx, qz, m, f))
            if not children:
                break
            children.sort(key=lambda c: c[0])
            beam = children[:width]
            if beam[0][0] < best[0]:
                best = (beam[0][0], beam[0][4])
        return best[1]

    def _search(self, x: float, z: float, yaw: float, d: float) -> int | None:
        """First heading offset of the shortest (then least-turning) sequence that reaches the goal."""
        s, st = self.success_distance, self.forward_step
        lattice = self._lattice()
        n_min = max(1, math.ceil((d - s) / st - 1e-9))
        cache: dict[tuple[float, float, int], tuple[float, float, float]] = {}

        def step(px: float, pz: float, m: int) -> tuple[float, float, float]:
            key = (px, pz, m % self._num_headings)
            hit = cache.get(key)
            if hit is None:
                qx, qz = self._step(px, pz, yaw + m * self.turn)
                hit = (qx, qz, self.field._distance_xz(qx, qz))
                cache[key] = hit
            return hit

        for n in range(n_min, min(n_min + 2, self.endgame_steps + 1) + 1):
            best: list = [None]  # (forward steps, turns, first heading offset)

            def dfs(px: float, pz: float, prev: int, left: int, used: int, turns: int, first: int | None) -> None:
                for m in lattice:
                    t = turns + self._turns(m - prev)
                    b = best[0]  # noqa: B023 (dfs runs within this iteration)
                    if b is not None and (used + 1, t) >= b[:2]:
                        continue
                    qx, qz, dq = step(px, pz, m)
                    if abs(qx - px) + abs(qz - pz) < 1e-6:
                        continue  # blocked: a wasted step
                    f = m if first is None else first
                    if dq < s:
                        best[0] = (used + 1, t, f)  # noqa: B023
                        continue
                    if left > 1 and dq - s <= (left - 1) * st + 1e-9:
                        dfs(qx, qz, m, left - 1, used + 1, t, f)

            dfs(x, z, 0, n, 0, 0, None)
            if best[0] is not None:
                return best[0][2]
        return None


class WaypointFollower:
    """Drives through ``waypoints`` in order with a :class:`GreedyFollower` to each, and STOPs within
    ``stop_radius`` of the last: a VLN reference-path follower (VLN-CE's gt paths are a shortest-path follower's
    rollout through the reference path that ends within 0.5 m of the goal, jacobkrantz/VLN-CE
    ``habitat_extensions/config/default.py``).

    A waypoint counts as passed within ``waypoint_radius`` (xz) or when its follower would STOP; one that is off
    the navigable space (no finite distance) is dropped, and one not reached within ``max_waypoint_steps``
    actions is given up."""

    def __init__(self, navgrid: NavGrid, waypoints, forward_step: float = 0.25, turn_angle_deg: float = 30.0,
                 sliding: bool = False, waypoint_radius: float = 0.5, stop_radius: float = 0.5,
                 max_waypoint_steps: int = 80):
        self.navgrid = navgrid
        self.waypoints = [np.asarray(w, np.float64).reshape(3) for w in waypoints]
        self.forward_step, self.turn_angle_deg, self.sliding = forward_step, turn_angle_deg, sliding
        self.waypoint_radius, self.stop_radius = waypoint_radius, stop_radius
        self.max_waypoint_steps = max_waypoint_steps
        self._follower: GreedyFollower | None = None
        self._steps_on = 0

    def _next(self, position: np.ndarray) -> GreedyFollower | None:
        while self.waypoints:
            last = len(self.waypoints) == 1
            wp = self.waypoints[0]
            if not last and math.hypot(position[0] - wp[0], position[2] - wp[2]) < self.waypoint_radius:
                self.waypoints.pop(0)
                continue
            f = GreedyFollower(self.navgrid, wp.reshape(1, 3), self.stop_radius if last else self.waypoint_radius,
                               forward_step=self.forward_step, turn_angle_deg=self.turn_angle_deg,
                               sliding=self.sliding)
            if not math.isfinite(f.distance(position)):
                self.waypoints.pop(0)  # not on this navigable space
                continue
            self._steps_on = 0
            return f
        return None

    def next_action(self, position, rotation_xyzw) -> int:
        p = np.asarray(position, np.float64)
        for _ in range(len(self.waypoints) + 1):
            if self._follower is None:
                self._follower = self._next(p)
                if self._follower is None:
                    return STOP
            last = len(self.waypoints) == 1
            action = int(self._follower.next_action(p, rotation_xyzw))
            self._steps_on += 1
            if action != STOP and self._steps_on <= self.max_waypoint_steps:
                return action
            if last:
                return STOP
            self.waypoints.pop(0)  # reached (or given up): on to the next one
            self._follower = None
        return STOP
