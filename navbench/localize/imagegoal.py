"""Where an ImageNav goal image was taken, from the keyframe memory: no map, only stored posed RGB-D keyframes.

ImageNav's goal is a camera position (success: STOP within 0.2 m of where the goal image was taken), so the
localiser's object candidates do not answer it. Under oracle perception (instance ids, :func:`estimate_camera`):

1. **Retrieve** the keyframes most like the goal image: histogram intersection of their instance-id pixel counts.
2. **Render from memory**: the keyframes' depth, back-projected with their ids (every ``stride``-th pixel), is a
   labelled point cloud; a candidate camera (level, at the keyframes' camera height, position x z and yaw) sees
   the nearest point at each pixel of a small image. A pose scores the intersection over union of the object
   pixels its view and the goal image agree on (:func:`match_score`; structure, -1, looks alike from many places).
3. **Search** the pose: a coarse grid round each retrieved keyframe, then two finer grids round the best pose.

With real embedding models the memory holds no instance ids: the estimate is the camera position of the keyframe
the FAISS index retrieves for the goal image (:func:`retrieved_camera`), which is as near as the pre-scan came.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from navbench.localize.geometry import backproject, world_to_camera
from navbench.memory.prescan import Memory
from navbench.render.camera import camera_pose
from navbench.scene.pose import quat_from_yaw


@dataclass(frozen=True)
class ImageGoalConfig:
    stride: int = 6  # keyframe pixels back-projected into the memory's cloud (every stride-th row and column)
    top_k: int = 2  # retrieved keyframes the search starts round
    radius: float = 8.0  # cloud points farther than this (xz) from the retrieved keyframes are left out
    # (half-width m, step m, yaw half-width deg, yaw step deg, rendered image side px, cloud voxel m) of each
    # search stage; a yaw half-width of 180 searches every heading
    stages: tuple[tuple[float, float, float, float, int, float], ...] = (
        (1.2, 0.4, 180.0, 30.0, 16, 0.25), (0.4, 0.1, 20.0, 5.0, 24, 0.15), (0.1, 0.05, 5.0, 2.5, 32, 0.1))


@dataclass
class MemoryCloud:
    """The memory's keyframes as one labelled point cloud, and each keyframe's instance-id pixel counts."""
    points: np.ndarray  # (N, 3) world
    ids: np.ndarray  # (N,) instance id, -1 structure
    histograms: list[dict[int, float]]  # per keyframe: id -> share of its object pixels
    camera_y: np.ndarray  # (K,) keyframe camera heights (world y)
    positions: np.ndarray  # (K, 3) keyframe camera positions
    yaws: np.ndarray  # (K,)
    _voxels: dict[float, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)

    def voxels(self, voxel: float) -> tuple[np.ndarray, np.ndarray]:
        """The cloud with one point per ``voxel``-sided cube (kept once made)."""
        if voxel not in self._voxels:
            self._voxels[voxel] = voxel_downsample(self.points, self.ids, voxel)
        return self._voxels[voxel]


_CLOUDS: dict[tuple[str, int], MemoryCloud] = {}


def memory_cloud(memory: Memory, stride: int = 6) -> MemoryCloud:
    """The labelled cloud of ``memory`` (built once per process and memory)."""
    key = (str(memory.directory), stride)
    if key in _CLOUDS:
        return _CLOUDS[key]
    store = memory.store
    pts, ids, hists = [], [], []
    for k in range(len(store)):
        depth, kid = store.depth(k), store.instance_ids(k)
        mask = np.zeros(depth.shape, bool)
        mask[stride // 2::stride, stride // 2::stride] = True
        valid = mask & (depth > 0.1) & (depth < 20.0)
        pts.append(backproject(depth, valid, store.K(k), store.pose(k)))
        ids.append(kid[valid])
        hists.append(_histogram(kid[mask]))
    poses = store.poses()
    fwd = -poses[:, :3, 2]  # the camera looks along -z
    cloud = MemoryCloud(np.concatenate(pts), np.concatenate(ids).astype(np.int32), hists, poses[:, 1, 3].copy(),
                        poses[:, :3, 3].copy(), np.arctan2(-fwd[:, 0], -fwd[:, 2]))
    _CLOUDS[key] = cloud
    return cloud


def _histogram(ids: np.ndarray) -> dict[int, float]:
    values, counts = np.unique(ids[ids >= 0], return_counts=True)
    total = counts.sum()
    return {int(v): float(c) / total for v, c in zip(values, counts)} if total else {}


def similarity(a: dict[int, float], b: dict[int, float]) -> float:
    """Histogram intersection of two instance-id pixel shares (1: the same objects in the same proportions)."""
    return sum(min(p, b[i]) for i, p in a.items() if i in b)


def render_ids(points: np.ndarray, ids: np.ndarray, cameras: np.ndarray, hfov_deg: float, side: int,
               aspect: float = 1.0) -> np.ndarray:
    """(P, side_h, side) ids the memory's cloud shows each camera (``cameras``: (P, 3) x, y, z and (P,) yaw as
    a (P, 4) array), the nearest point per pixel; -2 where no point falls."""
    h = max(1, round(side * aspect))
    f = (side / 2.0) / np.tan(np.radians(hfov_deg) / 2.0)
    out = np.full((len(cameras), h * side), -2, np.int32)
    for p, (x, y, z, yaw) in enumerate(cameras):
        T = world_to_camera(camera_pose(np.array([x, y, z]), quat_from_yaw(float(yaw))))
        cam = points @ T[:3, :3].T + T[:3, 3]
        d = -cam[:, 2]
        front = d > 0.1
        d, cam, pid = d[front], cam[front], ids[front]
        u = np.floor(f * cam[:, 0] / d + side / 2.0).astype(np.int64)
        v = np.floor(-f * cam[:, 1] / d + h / 2.0).astype(np.int64)
        ok = (u >= 0) & (u < side) & (v >= 0) & (v < h)
        pix, d, pid = v[ok] * side + u[ok], d[ok], pid[ok]
        order = np.lexsort((d, pix))  # by pixel, nearest first
        pix, pid = pix[order], pid[order]
        first = np.ones(len(pix), bool)
        first[1:] = pix[1:] != pix[:-1]
        out[p, pix[first]] = pid[first]
    return out.reshape(len(cameras), h, side)


def voxel_downsample(points: np.ndarray, ids: np.ndarray, voxel: float) -> tuple[np.ndarray, np.ndarray]:
    """One point (the first) per ``voxel``-sided cube."""
    keys = np.floor(points / voxel).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    first.sort()
    return points[first], ids[first]


def _goal_at(goal_ids: np.ndarray, side: int) -> np.ndarray:
    """The goal's ids at ``side`` columns (nearest pixel)."""
    H, W = goal_ids.shape
    h = max(1, round(side * H / W))
    rows = ((np.arange(h) + 0.5) * H / h).astype(int)
    cols = ((np.arange(side) + 0.5) * W / side).astype(int)
    return goal_ids[np.ix_(rows, cols)]


def match_score(shown: np.ndarray, target: np.ndarray) -> np.ndarray:
    """How well each rendered id image (P, h, w) matches ``target`` (h, w): the intersection over union of their
    object pixels with equal ids (walls and floors look alike from many places); for a goal image showing no
    object, the share of all pixels with equal ids."""
    obj = target >= 0
    if not obj.any():
        return (shown == target).mean(axis=(1, 2))
    same = ((shown == target) & obj).sum(axis=(1, 2))
    return same / (obj.sum() + ((shown >= 0) & ~obj).sum(axis=(1, 2)))


@dataclass
class CameraEstimate:
    position: np.ndarray  # (3,) camera position (world)
    yaw: float
    score: float  # match_score of the chosen pose (oracle) or the retrieved keyframe's cosine (real models)
    keyframes: list[tuple[int, float]]  # retrieved keyframes and their similarity, best first


def estimate_camera(memory: Memory, goal_ids: np.ndarray, hfov_deg: float,
                    config: ImageGoalConfig = ImageGoalConfig()) -> CameraEstimate:
    """Where a level camera of ``hfov_deg`` saw ``goal_ids`` (H, W instance ids, -1 structure), from ``memory``
    (module docstring). The camera's height is the retrieved keyframe's."""
    cloud = memory_cloud(memory, config.stride)
    goal_hist = _histogram(goal_ids[::4, ::4])
    sims = np.array([similarity(goal_hist, h) for h in cloud.histograms])
    top = [int(k) for k in np.argsort(-sims, kind="stable")[: config.top_k]]
    y = float(cloud.camera_y[top[0]])
    aspect = goal_ids.shape[0] / goal_ids.shape[1]
    starts = [(cloud.positions[k, 0], cloud.positions[k, 2], cloud.yaws[k]) for k in top]
    best = (float(cloud.positions[top[0], 0]), float(cloud.positions[top[0], 2]), float(cloud.yaws[top[0]]), -1.0)
    for half, step, yaw_half, yaw_step, side, voxel in config.stages:
        target = _goal_at(goal_ids, side)
        pts, pid = cloud.voxels(voxel)
        near = np.zeros(len(pts), bool)
        for x0, z0, _ in starts:
            near |= np.hypot(pts[:, 0] - x0, pts[:, 2] - z0) < config.radius
        pts, pid = pts[near], pid[near]
        n = int(round(half / step))
        offsets = np.arange(-n, n + 1) * step
        m = int(round(min(yaw_half, 180.0 - yaw_step / 2) / yaw_step))
        turns = np.radians(np.arange(-m, m + 1) * yaw_step) if yaw_half < 180 else \
            np.radians(np.arange(0.0, 360.0, yaw_step))
        cams = np.array([(x0 + dx, y, z0 + dz, yaw0 + t) for x0, z0, yaw0 in starts
                         for dx in offsets for dz in offsets for t in turns])
        scores = np.empty(len(cams))
        for i in range(0, len(cams), 256):
            shown = render_ids(pts, pid, cams[i:i + 256], hfov_deg, side, aspect)
            scores[i:i + 256] = match_score(shown, target)
        j = int(np.argmax(scores))
        best = (float(cams[j, 0]), float(cams[j, 2]), float(cams[j, 3]), float(scores[j]))
        starts = [best[:3]]
    x, z, yaw, score = best
    return CameraEstimate(np.array([x, y, z]), float(np.arctan2(np.sin(yaw), np.cos(yaw))), score,
                          [(k, round(float(sims[k]), 4)) for k in top])


def retrieved_camera(memory: Memory, query_vector: np.ndarray) -> CameraEstimate:
    """The camera position of the keyframe the memory's embedding index retrieves first for ``query_vector``."""
    assert memory.index is not None
    found = memory.index.search(query_vector, 1, None)
    k, cosine = found[0]
    pose = memory.store.pose(k)
    fwd = -pose[:3, 2]
    return CameraEstimate(pose[:3, 3].copy(), float(np.arctan2(-fwd[0], -fwd[2])), float(cosine), [(k, float(cosine))])
