"""Route lengths over the keyframe memory: how far a goal candidate is along where the pre-scan walked.

The memory agent drives to its goal candidates nearest first. In a house the straight line is a poor
"nearest": a desk just behind the bedroom wall is near in a straight line and a long walk round by the
door. The memory knows where the camera went, and that is free space: the keyframes are posed along one
continuous walk through every room, so consecutive keyframes (less than ``max_step`` apart: no gap in
the walk) and any two keyframes within ``link_radius`` of each other are joined. ``link_radius`` is
below the 0.36 m that two camera positions on either side of a wall are at least apart (twice the
agent's radius), so no link crosses a wall.

A point (the agent's floor position) enters this graph at the keyframes that saw it: its camera-height
point projects into the keyframe's image within ``max_sight`` with nothing nearer in the stored depth
(a line of sight, so the straight leg there is free at camera height), and at keyframes within
``link_radius``. For the same reason two keyframes one of which sees the other's camera are joined
(a straight segment instead of the walk's way round through room centres). A candidate is left at
its supporting keyframes (:attr:`GoalCandidate.keyframe_ids`, which saw it). The route length is the
shortest entry leg + walk + exit leg, all measured in xz.

Height: a memory may span storeys. Keyframes within ``link_radius`` and lines of sight join only cameras
at most ``max_climb`` apart in height (one surface, or a step: a camera above another on the next storey,
or one seen across a stairwell, is not a walk away); consecutive keyframes join where the walk between them
rises no steeper than 45 deg plus a step (the steepest the joined surfaces admit: a flight of stairs, a
ramp), so a memory's storeys join only where the pre-scan walked between them, and a cut in the scan
between storeys nothing joins stays a gap. A point enters only at keyframes whose floor (camera height
less ``camera_height``) is within half ``camera_height`` of its own (the tolerance within which the env
takes a point to stand on a grid's floor).

Only stored poses and depths are used: nothing reads the simulator's navigability or the episode's
goals. A point no keyframe saw, or a candidate in a part of the graph the point's entries do not reach,
gets ``inf`` (callers fall back to the straight line).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from navbench.localize.fusion import GoalCandidate
from navbench.localize.geometry import project, world_to_camera
from navbench.memory.store import KeyframeStore


@dataclass(frozen=True)
class RouteConfig:
    link_radius: float = 0.35  # m (xz): keyframes this close are joined (module docstring)
    max_step: float = 0.6  # m (xz): consecutive keyframes farther apart are a gap in the walk, not joined
    max_sight: float = 6.0  # m: a keyframe sees a point only this far along its optical axis
    depth_tolerance: float = 0.2  # m: the stored depth may be this much nearer than the point
    max_climb: float = 0.2  # m: the most two joined cameras' heights differ by, beyond a walked slope's rise


class KeyframeRoutes:
    """Route lengths from a point to goal candidates over a keyframe store's pose graph."""

    def __init__(self, store: KeyframeStore, camera_height: float, config: RouteConfig = RouteConfig()):
        self.store, self.camera_height, self.config = store, float(camera_height), config
        poses = store.poses()
        n = len(poses)
        self._positions = poses[:, :3, 3] if n else np.zeros((0, 3))
        self._xz = self._positions[:, [0, 2]]
        self._world_to_cam = np.stack([world_to_camera(p) for p in poses]) if n else np.zeros((0, 4, 4))
        self._depth: dict[int, np.ndarray] = {}  # keyframe -> stored depth, loaded when first needed
        # with / without the lines of sight -> (edges, weights), built when first needed
        self._graphs: dict[bool, tuple[np.ndarray, np.ndarray]] = {}

    def _visible(self, i: int, points: np.ndarray) -> np.ndarray:
        """Which of ``points`` (M, 3) keyframe ``i`` has a line of sight to, within ``max_sight``."""
        cfg, intr = self.config, self.store.intrinsics(i)
        uv, z, in_view = project(points, intr.K, self._world_to_cam[i], intr.width, intr.height)
        ok = in_view & (z <= cfg.max_sight)
        if not ok.any():
            return ok
        depth = self._depth.get(i)
        if depth is None:
            depth = self._depth[i] = self.store.depth(i).astype(np.float16)
        u = np.clip(np.rint(uv[ok, 0]).astype(int), 0, depth.shape[1] - 1)
        v = np.clip(np.rint(uv[ok, 1]).astype(int), 0, depth.shape[0] - 1)
        d = depth[v, u].astype(np.float64)
        ok[ok] = (d == 0.0) | (d >= z[ok] - cfg.depth_tolerance)  # 0: no surface hit along the ray
        return ok

    def sees(self, point: np.ndarray) -> np.ndarray:
        """Indices of the keyframes with a line of sight to ``point`` (world, any height) within ``max_sight``."""
        T, p = self._world_to_cam, np.asarray(point, np.float64).reshape(1, 3)
        z = -(T[:, 2, :3] @ p[0] + T[:, 2, 3])  # depth along each optical axis
        near = np.flatnonzero((z > 0) & (z <= self.config.max_sight))
        return np.asarray([i for i in near if self._visible(int(i), p)[0]], dtype=np.int64)

    def graph(self, sight: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """The pose graph's undirected edges (E, 2) and their xz lengths (E,): consecutive keyframes,
        keyframes within ``link_radius``, and (``sight``) keyframes one of which sees the other's camera."""
        if sight not in self._graphs:
            n, cfg = len(self._xz), self.config
            pairs = cKDTree(self._xz).query_pairs(cfg.link_radius, output_type="ndarray").reshape(-1, 2) \
                if n else np.zeros((0, 2), np.int64)
            step = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1) if n > 1 else np.zeros((0, 2), np.int64)
            step = step[np.linalg.norm(self._xz[step[:, 0]] - self._xz[step[:, 1]], axis=1) <= cfg.max_step]
            # The walk alone makes long detours of short trips (it goes room centre to room centre);
            # a line of sight between two cameras is a straight free segment at camera height.
            seen = [np.stack([np.full(len(js), i), js], axis=1)
                    for i in range(n) if sight and len(js := np.flatnonzero(self._visible(i, self._positions)))]
            y = self._positions[:, 1]
            level = np.concatenate([pairs, *seen]).astype(np.int64).reshape(-1, 2)
            level = level[np.abs(y[level[:, 0]] - y[level[:, 1]]) <= cfg.max_climb]
            rise = np.abs(y[step[:, 0]] - y[step[:, 1]])
            step = step[rise <= np.linalg.norm(self._xz[step[:, 0]] - self._xz[step[:, 1]], axis=1) + cfg.max_climb]
            edges = np.sort(np.concatenate([level, step]).astype(np.int64), axis=1)
            # Each pair once: a sparse matrix built from repeated (i, j) entries sums their weights.
            edges = np.unique(edges[edges[:, 0] != edges[:, 1]], axis=0)
            # Joined keyframes at one place (a look-around) get a tiny positive weight: csgraph drops
            # explicit zeros as non-edges.
            w = np.maximum(np.linalg.norm(self._xz[edges[:, 0]] - self._xz[edges[:, 1]], axis=1), 1e-6)
            self._graphs[sight] = edges, w
        return self._graphs[sight]

    def _search(self, position: np.ndarray, sight: bool = True) -> tuple[np.ndarray, np.ndarray] | None:
        """Shortest walks from floor point ``position`` over the graph (``sight``: with its lines of sight):
        (distance, predecessor) per keyframe (the query point is node ``n``), or None when no keyframe saw
        the point."""
        n = len(self._xz)
        if n == 0:
            return None
        position = np.asarray(position, np.float64)
        eye = position + np.array([0.0, self.camera_height, 0.0])
        near = np.flatnonzero(np.linalg.norm(self._xz - position[[0, 2]], axis=1) <= self.config.link_radius)
        entries = np.union1d(self.sees(eye), near).astype(np.int64)
        entries = entries[np.abs(self._positions[entries, 1] - eye[1]) <= self.camera_height / 2]
        if not len(entries):
            return None
        edges, weights = self.graph(sight)
        # One extra node (n) for the query point, joined to its entries by the straight legs.
        legs = np.maximum(np.linalg.norm(self._xz[entries] - position[[0, 2]], axis=1), 1e-6)
        rows = np.concatenate([edges[:, 0], np.full(len(entries), n)])
        cols = np.concatenate([edges[:, 1], entries])
        graph = coo_matrix((np.concatenate([weights, legs]), (rows, cols)), shape=(n + 1, n + 1)).tocsr()
        return dijkstra(graph, directed=False, indices=n, return_predecessors=True)

    def _exit(self, dist: np.ndarray, c: GoalCandidate) -> tuple[float, int]:
        """(route length, exit keyframe) to candidate ``c`` given the walks ``dist``; (inf, -1) if none."""
        n = len(self._xz)
        ids = np.asarray(c.keyframe_ids, dtype=np.int64)
        ids = ids[(ids >= 0) & (ids < n)]
        if not len(ids):
            return np.inf, -1
        total = dist[ids] + np.linalg.norm(self._xz[ids] - np.asarray(c.centre, np.float64)[[0, 2]], axis=1)
        k = int(np.argmin(total))
        return (float(total[k]), int(ids[k])) if np.isfinite(total[k]) else (np.inf, -1)

    def lengths(self, position: np.ndarray, candidates: Sequence[GoalCandidate]) -> np.ndarray:
        """Route length (m) from floor point ``position`` to each candidate; ``inf`` where there is none."""
        out = np.full(len(candidates), np.inf)
        found = self._search(position) if len(candidates) else None
        if found is not None:
            for j, c in enumerate(candidates):
                out[j] = self._exit(found[0], c)[0]
        return out

    def path(self, position: np.ndarray, candidate: GoalCandidate) -> np.ndarray:
        """The keyframe camera positions (K, 3), projected to ``position``'s floor height, along the shortest
        route from floor point ``position`` to ``candidate``, in walking order and ending at the keyframe
        that saw it; (0, 3) where there is none. Between keyframes the route keeps to the walk (and to
        keyframes within ``link_radius``): a line of sight at camera height can pass over a table the
        body cannot, and a path is for driving, where a length only ranks candidates."""
        found = self._search(position, sight=False)
        if found is None:
            return np.zeros((0, 3))
        dist, pred = found
        _, k = self._exit(dist, candidate)
        n, nodes = len(self._xz), []
        while 0 <= k < n:  # back along the predecessors to the query point (node n)
            nodes.append(k)
            k = int(pred[k])
        pts = self._positions[nodes[::-1]].copy()
        pts[:, 1] = float(np.asarray(position, np.float64)[1])
        return pts
