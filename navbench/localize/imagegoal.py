"""Where an ImageNav goal image was taken, from the keyframe memory: no map, only stored posed RGB-D keyframes.

ImageNav's goal is a camera position (success: STOP within 0.2 m of where the goal image was taken), so the
localiser's object candidates do not answer it. Under oracle perception (instance ids, :func:`estimate_camera`):

1. **Memory cloud**: the keyframes' depth, back-projected (every ``stride``-th pixel) with each pixel's instance
   id and colour, is a labelled, coloured point cloud of the house, kept once per memory.
2. **Labels**: a goal pixel showing an object is labelled by its id; one showing structure (walls, floors: id -1)
   by its colour among the goal image's few structure colours (flat-shaded walls and floors tell rooms apart).
   A cloud point takes its id, or the goal colour its own is nearest (none if farther than ``colour_tolerance``).
3. **Free floor**: a candidate camera stands where the cloud shows floor and no obstacle within ``clearance``
   (points between ``obstacle`` heights above the floor): never in a wall or in furniture.
4. **Panoramic renders**: a candidate camera position (level, at the keyframes' camera height) sees the cloud as
   a cylindrical image (columns: heading, rows: tangent of elevation), the nearest point per cell, then each
   cell takes a neighbour's point where that is clearly nearer (the sparse cloud's far points do not show through
   near surfaces). Every heading is one shift of its columns, so one render scores all yaws: the weighted share of
   the goal image's cells (resampled onto the cylinder) whose label the render shows (:func:`score_headings`).
5. **Search**: every free position on a coarse grid round the keyframes most like the goal image (histogram
   intersection of instance-id pixel counts, ``top_k``), or round all keyframes when the goal shows no object;
   then finer grids, finer clouds and finer headings round the best ``keep`` poses of each stage.
6. **Live views** (:func:`refine_camera`): an agent standing near the estimate searches again round it over its
   own views (dense, and taken from about where the goal camera stood) joined to the memory's cloud, with finer
   grids and panoramas (``refine_stages``).

With real embedding models the memory holds no instance ids: the estimate is the camera position of the keyframe
the FAISS index retrieves for the goal image (:func:`retrieved_camera`), which is as near as the pre-scan came.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from navbench.localize.geometry import backproject, voxel_firsts
from navbench.memory.prescan import Memory


@dataclass(frozen=True)
class ImageGoalConfig:
    stride: int = 4  # keyframe pixels back-projected into the memory's cloud (every stride-th row and column)
    top_k: int = 8  # retrieved keyframes the coarse grid covers
    reach: float = 2.5  # the coarse grid's half-width (m) round each retrieved keyframe
    radius: float = 9.0  # cloud points farther than this (xz) from every candidate are left out
    colour_tolerance: float = 40.0  # largest RGB channel difference of a structure point from a goal colour
    object_weight: float = 3.0  # a goal object cell's weight in a score, a structure cell's being 1
    clearance: float = 0.15  # m from the nearest obstacle point a candidate camera keeps
    obstacle: tuple[float, float] = (0.15, 1.0)  # heights above the floor (m) whose points are obstacles
    cell: float = 0.05  # free-floor grid cell (m)
    fill: int = 2  # passes of nearer-neighbour filling of each render
    # (grid step m, half-width m round the kept poses or 0 for the coarse grid, cloud voxel m, cylinder columns
    # (headings), cylinder rows, poses kept for the next stage) of each search stage
    stages: tuple[tuple[float, float, float, int, int, int], ...] = (
        (0.25, 0.0, 0.2, 96, 24, 4), (0.1, 0.3, 0.1, 180, 40, 2), (0.05, 0.2, 0.03, 360, 64, 1))
    # the stages of a search round one pose over an agent's live views (refine_camera), the first turning within
    # refine_turn_deg of the pose's yaw
    refine_stages: tuple[tuple[float, float, float, int, int, int], ...] = (
        (0.1, 0.6, 0.05, 180, 40, 2), (0.05, 0.15, 0.02, 360, 64, 1), (0.025, 0.075, 0.01, 720, 128, 1))
    refine_turn_deg: float = 30.0


@dataclass
class MemoryCloud:
    """The memory's keyframes as one labelled, coloured point cloud, and each keyframe's id pixel counts."""
    points: np.ndarray  # (N, 3) world
    ids: np.ndarray  # (N,) instance id, -1 structure
    colours: np.ndarray  # (N, 3) uint8
    histograms: list[dict[int, float]]  # per keyframe: id -> share of its object pixels
    camera_y: np.ndarray  # (K,) keyframe camera heights (world y)
    positions: np.ndarray  # (K, 3) keyframe camera positions
    yaws: np.ndarray  # (K,)
    camera_height: float  # the keyframes' camera height above the floor
    _voxels: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)
    _free: dict[tuple, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)

    def voxels(self, voxel: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The cloud with one point per ``voxel``-sided cube (kept once made): points, ids, colours."""
        if voxel not in self._voxels:
            kept = voxel_firsts(self.points, voxel)
            self._voxels[voxel] = self.points[kept], self.ids[kept], self.colours[kept]
        return self._voxels[voxel]

    def free(self, floor: float, config: ImageGoalConfig) -> tuple[np.ndarray, np.ndarray]:
        """Free floor at height ``floor`` (:func:`free_floor`, kept once made): the grid, its xz origin."""
        key = (round(floor, 2), config.cell, config.clearance, config.obstacle)
        if key not in self._free:
            self._free[key] = free_floor(self.points, floor, config)
        return self._free[key]


_CLOUDS: OrderedDict[tuple[str, int], MemoryCloud] = OrderedDict()
_CLOUD_SCENES = 4  # clouds kept per process (a house's is ~1.6M points): the most recently used


def memory_cloud(memory: Memory, stride: int = 4) -> MemoryCloud:
    """The labelled cloud of ``memory`` (built once per process and memory while it is among the last used)."""
    key = (str(memory.directory), stride)
    if key in _CLOUDS:
        _CLOUDS.move_to_end(key)
        return _CLOUDS[key]
    store = memory.store
    pts, ids, cols, hists = [], [], [], []
    for k in range(len(store)):
        depth, kid = store.depth(k), store.instance_ids(k)
        mask = np.zeros(depth.shape, bool)
        mask[stride // 2::stride, stride // 2::stride] = True
        valid = mask & (depth > 0.1) & (depth < 20.0)
        pts.append(backproject(depth, valid, store.K(k), store.pose(k)))
        ids.append(kid[valid])
        cols.append(store.rgb(k)[valid])
        hists.append(_histogram(kid[mask]))
    poses = store.poses()
    fwd = -poses[:, :3, 2]  # the camera looks along -z
    cloud = MemoryCloud(np.concatenate(pts), np.concatenate(ids).astype(np.int32), np.concatenate(cols), hists,
                        poses[:, 1, 3].copy(), poses[:, :3, 3].copy(), np.arctan2(-fwd[:, 0], -fwd[:, 2]),
                        float(memory.config.camera_height))
    _CLOUDS[key] = cloud
    while len(_CLOUDS) > _CLOUD_SCENES:
        _CLOUDS.popitem(last=False)
    return cloud


def _histogram(ids: np.ndarray) -> dict[int, float]:
    values, counts = np.unique(ids[ids >= 0], return_counts=True)
    total = counts.sum()
    return {int(v): float(c) / total for v, c in zip(values, counts)} if total else {}


def similarity(a: dict[int, float], b: dict[int, float]) -> float:
    """Histogram intersection of two instance-id pixel shares (1: the same objects in the same proportions)."""
    return sum(min(p, b[i]) for i, p in a.items() if i in b)


def _dilate(grid: np.ndarray, n: int) -> np.ndarray:
    out = grid.copy()
    for dr in range(-n, n + 1):
        for dc in range(-n, n + 1):
            if dr * dr + dc * dc <= n * n:
                out |= np.roll(np.roll(grid, dr, 0), dc, 1)
    return out


def free_floor(points: np.ndarray, floor: float, config: ImageGoalConfig = ImageGoalConfig()
               ) -> tuple[np.ndarray, np.ndarray]:
    """A (rows, cols) grid of ``config.cell`` cells over xz (and its origin): True where the cloud shows floor
    at height ``floor`` (gaps of a cell closed) and no obstacle point lies within ``config.clearance``."""
    c = config.cell
    y = points[:, 1] - floor
    lo = points[:, [0, 2]].min(axis=0) - 4 * c
    rows, cols = (np.ceil((points[:, [0, 2]].max(axis=0) - lo) / c).astype(int) + 4)
    cells = np.floor((points[:, [0, 2]] - lo) / c).astype(np.int64)

    def grid(mask):
        g = np.zeros((rows, cols), bool)
        g[cells[mask, 0], cells[mask, 1]] = True
        return g
    seen = _dilate(grid(np.abs(y) < 0.05), 1)
    blocked = _dilate(grid((y > config.obstacle[0]) & (y < config.obstacle[1])), int(round(config.clearance / c)))
    return seen & ~blocked, lo


def _palette(rgb: np.ndarray, tolerance: float, most: int = 32) -> np.ndarray:
    """The few colours of ``rgb`` (n, 3): each, most frequent first, unless within ``tolerance`` of one kept."""
    values, counts = np.unique(rgb.reshape(-1, 3), axis=0, return_counts=True)
    kept: list[np.ndarray] = []
    for j in np.argsort(-counts, kind="stable"):
        v = values[j].astype(np.int32)
        if all(np.abs(v - k).max() > tolerance for k in kept):
            kept.append(v)
            if len(kept) == most:
                break
    return np.array(kept, np.int32).reshape(-1, 3)


def _nearest_colour(colours: np.ndarray, palette: np.ndarray, tolerance: float) -> np.ndarray:
    """Each colour's palette index (nearest by largest channel difference), -1 where none is within tolerance."""
    if not len(palette):
        return np.full(len(colours), -1, np.int64)
    d = np.abs(colours[:, None, :].astype(np.int32) - palette[None]).max(axis=2)
    j = np.argmin(d, axis=1)
    return np.where(d[np.arange(len(j)), j] <= tolerance, j, -1)


_EMPTY = -(1 << 30)  # a render's label where no point falls
_OTHER = -(1 << 29)  # a structure point of no goal colour


def point_labels(ids: np.ndarray, colours: np.ndarray, palette: np.ndarray, tolerance: float) -> np.ndarray:
    """A point's label: its id for an object; -2 - its goal colour's index for structure (_OTHER for none)."""
    j = _nearest_colour(colours, palette, tolerance)
    return np.where(ids >= 0, ids, np.where(j >= 0, -2 - j, _OTHER)).astype(np.int64)


@dataclass(frozen=True)
class GoalCylinder:
    """The goal image resampled onto a camera's cylinder: ``labels`` and ``weights`` (rows, K) of the K columns
    ``offsets`` (headings relative to the camera's, in columns) the image covers; weight 0 outside it."""
    labels: np.ndarray
    weights: np.ndarray
    offsets: np.ndarray
    tan_half: float  # the rows span tangents of elevation [-tan_half, tan_half]


def goal_cylinder(goal_labels: np.ndarray, hfov_deg: float, columns: int, rows: int,
                  object_weight: float) -> GoalCylinder:
    """Resample (H, W) goal labels (objects >= 0) onto a cylinder of ``columns`` headings and ``rows``."""
    H, W = goal_labels.shape
    f = (W / 2.0) / np.tan(np.radians(hfov_deg) / 2.0)
    tan_half = (H / 2.0) / f
    step = 2 * np.pi / columns
    m = int(np.ceil(np.radians(hfov_deg) / 2 / step))
    offsets = np.arange(-m, m)
    delta = (offsets + 0.5) * step  # heading of each column's centre left of the camera's
    t = tan_half - (np.arange(rows) + 0.5) * (2 * tan_half / rows)  # each row's tangent of elevation
    u = np.floor(f * np.tan(-delta) + W / 2.0)
    v = np.floor(H / 2.0 - f * t[:, None] / np.cos(delta)[None, :])
    inside = (np.abs(delta) < np.pi / 2)[None, :] & (u >= 0)[None, :] & (u < W)[None, :] & (v >= 0) & (v < H)
    uu = np.broadcast_to(np.clip(u, 0, W - 1), v.shape).astype(np.int64)
    vv = np.clip(v, 0, H - 1).astype(np.int64)
    labels = goal_labels[vv, uu].astype(np.int64)
    weights = np.where(inside, np.where(labels >= 0, object_weight, 1.0), 0.0)
    keep = inside.any(axis=0)
    return GoalCylinder(labels[:, keep], weights[:, keep], offsets[keep], float(tan_half))


def render_cylinders(points: np.ndarray, labels: np.ndarray, positions: np.ndarray, columns: int, rows: int,
                     tan_half: float, fill: int = 2) -> np.ndarray:
    """(P, rows, columns) labels the cloud shows a level cylindrical camera at each of ``positions`` (P, 3):
    column c spans headings [c, c + 1) * 2 pi / columns (yaw convention: 0 looks along -z, turning left adds),
    rows span tangents of elevation from +tan_half down to -tan_half; the nearest point per cell, then ``fill``
    passes in which a cell takes its nearest neighbour's point where that is under 0.8 of its distance."""
    P = len(positions)
    p32 = points.astype(np.float32)
    n = len(points)
    cells = rows * columns
    codes = np.full(P * cells, np.iinfo(np.int64).max, np.int64)
    for i, (x, y, z) in enumerate(positions.astype(np.float32)):
        dx, dy, dz = p32[:, 0] - x, p32[:, 1] - y, p32[:, 2] - z
        r = np.sqrt(dx * dx + dz * dz)
        heading = np.arctan2(-dx, -dz)
        col = np.floor(heading * np.float32(columns / (2 * np.pi))).astype(np.int64) % columns
        row = np.floor((np.float32(tan_half) - dy / np.maximum(r, np.float32(1e-6)))
                       * np.float32(rows / (2 * tan_half))).astype(np.int64)
        ok = (r > 0.05) & (row >= 0) & (row < rows)
        code = (np.round(r[ok] * 1000).astype(np.int64) << 32) | np.nonzero(ok)[0]
        np.minimum.at(codes, i * cells + row[ok] * columns + col[ok], code)
    codes = codes.reshape(P, rows, columns)
    big = np.iinfo(np.int64).max
    for _ in range(fill):
        near = codes.copy()
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                if dr or dc:
                    shifted = np.roll(codes, dc, axis=2)  # headings wrap round
                    if dr:
                        shifted = np.roll(shifted, dr, axis=1)
                        edge = 0 if dr > 0 else rows - 1
                        shifted[:, edge, :] = big
                    near = np.minimum(near, shifted)
        take = (near >> 32) * 5 < (codes >> 32) * 4  # nearer than 0.8 of the cell's (or the cell empty)
        codes = np.where(take, near, codes)
    empty = codes == big
    out = labels[np.where(empty, 0, codes & 0xFFFFFFFF) % max(n, 1)] if n else np.zeros(codes.shape, np.int64)
    return np.where(empty, _EMPTY, out)


def score_headings(rendered: np.ndarray, goal: GoalCylinder, headings: np.ndarray | None = None) -> np.ndarray:
    """(P, H) score of each rendered cylinder (P, rows, columns) at each of ``headings`` (columns; None: all):
    the goal camera's yaw is heading * 2 pi / columns, the centre of its image between the goal's offsets -1 and
    0. A score is the weighted share of the goal's cells whose label the render shows."""
    P, rows, columns = rendered.shape
    base = np.arange(columns) if headings is None else np.asarray(headings)
    score = np.zeros((P, len(base)))
    for k, off in enumerate(goal.offsets):
        w = goal.weights[:, k]
        if not w.any():
            continue
        same = rendered[:, :, (base + off) % columns] == goal.labels[:, k][None, :, None]
        score += np.einsum("prc,r->pc", same, w)
    return score / goal.weights.sum()


@dataclass
class CameraEstimate:
    position: np.ndarray  # (3,) camera position (world)
    yaw: float
    score: float  # score_headings of the chosen pose (oracle) or the retrieved keyframe's cosine (real models)
    keyframes: list[tuple[int, float]]  # retrieved keyframes and their similarity, best first
    # other places the image may have been taken (position, yaw, coarse score), best first
    alternatives: list[tuple[np.ndarray, float, float]] = field(default_factory=list)
    goal: GoalLabels | None = None  # the goal image as searched for (oracle perception)


def _grid(centres: np.ndarray, half: float, step: float) -> np.ndarray:
    """xz points on a ``step`` lattice (aligned to the world origin) within ``half`` of any of ``centres``."""
    lo = np.floor((centres.min(axis=0) - half) / step).astype(int)
    hi = np.ceil((centres.max(axis=0) + half) / step).astype(int)
    gx, gz = np.meshgrid(np.arange(lo[0], hi[0] + 1) * step, np.arange(lo[1], hi[1] + 1) * step, indexing="ij")
    xz = np.stack([gx.ravel(), gz.ravel()], axis=1)
    near = np.zeros(len(xz), bool)
    for c in centres:
        near |= np.abs(xz - c).max(axis=1) <= half + 1e-9
    return xz[near]


def _on_free(xz: np.ndarray, free: np.ndarray, origin: np.ndarray, cell: float) -> np.ndarray:
    ij = np.floor((xz - origin) / cell).astype(int)
    inside = (ij >= 0).all(axis=1) & (ij[:, 0] < free.shape[0]) & (ij[:, 1] < free.shape[1])
    ok = np.zeros(len(xz), bool)
    ok[inside] = free[ij[inside, 0], ij[inside, 1]]
    return ok


def _in_view(points: np.ndarray, poses: list[tuple[float, float, float, float]], half: float,
             half_angle: float) -> np.ndarray:
    """Points some camera within ``half`` (m, each axis) of one of ``poses`` (score, x, z, yaw) could see within
    ``half_angle`` of its yaw: a shift of d metres turns a point r away by at most asin(d / r)."""
    d = half * np.sqrt(2) + 1e-6
    seen = np.zeros(len(points), bool)
    for _, x, z, yaw in poses:
        dx, dz = points[:, 0] - x, points[:, 2] - z
        r = np.hypot(dx, dz)
        turn = np.abs(np.angle(np.exp(1j * (np.arctan2(-dx, -dz) - yaw))))
        seen |= (r <= d) | (turn <= half_angle + np.arcsin(np.minimum(1.0, d / np.maximum(r, d))))
    return seen


@dataclass(frozen=True)
class GoalLabels:
    """A goal image read for the search: each pixel's label (object id, or -2 - its structure colour's index in
    ``palette``) and the image's horizontal field of view."""
    labels: np.ndarray  # (H, W)
    palette: np.ndarray  # (n, 3) the goal image's structure colours
    hfov_deg: float


def goal_labels(goal_ids: np.ndarray, hfov_deg: float, goal_rgb: np.ndarray | None = None,
                config: ImageGoalConfig = ImageGoalConfig()) -> GoalLabels:
    """Label ``goal_ids`` (H, W instance ids, -1 structure), structure by its colour in ``goal_rgb`` (None:
    structure unlabelled)."""
    if goal_rgb is not None:
        palette = _palette(goal_rgb[::4, ::4][goal_ids[::4, ::4] < 0], config.colour_tolerance)
        goal_struct = -2 - _nearest_colour(goal_rgb.reshape(-1, 3), palette, 1e9).reshape(goal_ids.shape)
    else:
        palette = np.zeros((0, 3), np.int32)
        goal_struct = np.full(goal_ids.shape, _OTHER)
    return GoalLabels(np.where(goal_ids >= 0, goal_ids, goal_struct), palette, float(hfov_deg))


Pose = tuple[float, float, float, float]  # (score, x, z, yaw)


def _search(xz: np.ndarray, y: float, cloud: tuple[np.ndarray, np.ndarray, np.ndarray], goal: GoalLabels,
            stage: tuple[float, float, float, int, int, int], kept: list[Pose], turn: float | None,
            config: ImageGoalConfig) -> list[Pose]:
    """One search stage: score the level cameras at ``xz`` (height ``y``) over ``cloud`` (points, ids, colours:
    already voxelised for the stage); ``turn`` None: every heading, else only headings within ``turn`` of a
    ``kept`` pose whose position is within the stage's half-width. The best poses, each over a metre from those
    kept before it, at most the stage's ``keep``."""
    step, half, _, columns, rows, keep = stage
    pts, pid, pcol = cloud
    near = (np.abs(pts[:, 1] - y) < 3.0)
    lo, hi = xz.min(axis=0) - config.radius, xz.max(axis=0) + config.radius
    near &= (pts[:, 0] > lo[0]) & (pts[:, 0] < hi[0]) & (pts[:, 2] > lo[1]) & (pts[:, 2] < hi[1])
    heads = np.arange(columns)
    if turn is not None:
        angles = heads * 2 * np.pi / columns
        heads = heads[np.any([np.abs(np.angle(np.exp(1j * (angles - yaw)))) <= turn for *_, yaw in kept], axis=0)]
        near &= _in_view(pts, kept, half, np.radians(goal.hfov_deg) / 2 + turn + 2 * np.pi / columns)
    pts_n = pts[near]
    labels = point_labels(pid[near], pcol[near], goal.palette, config.colour_tolerance)
    cyl = goal_cylinder(goal.labels, goal.hfov_deg, columns, rows, config.object_weight)
    scores = np.empty((len(xz), len(heads)))
    cams = np.column_stack([xz[:, 0], np.full(len(xz), y), xz[:, 1]])
    for i in range(0, len(xz), 32):
        scores[i:i + 32] = score_headings(
            render_cylinders(pts_n, labels, cams[i:i + 32], columns, rows, cyl.tan_half, config.fill), cyl, heads)
    if turn is not None:  # each position turns only round the kept pose it is near
        allowed = np.zeros_like(scores, bool)
        for _, x, z, yaw in kept:
            close = np.abs(xz - [x, z]).max(axis=1) <= half + 1e-9
            facing = np.abs(np.angle(np.exp(1j * (heads * 2 * np.pi / columns - yaw)))) <= turn
            allowed |= close[:, None] & facing[None, :]
        scores = np.where(allowed, scores, -1.0)
    best_heading = np.argmax(scores, axis=1)
    best = scores[np.arange(len(xz)), best_heading]
    out: list[Pose] = []
    for j in np.argsort(-best, kind="stable"):  # the best poses, each over a metre from those kept
        x, z = float(xz[j, 0]), float(xz[j, 1])
        if all(np.hypot(x - kx, z - kz) > 1.0 for _, kx, kz, _ in out):
            out.append((float(best[j]), x, z, float(heads[best_heading[j]] * 2 * np.pi / columns)))
            if len(out) == keep:
                break
    return out


def _refine(kept: list[Pose], y: float, voxels: Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray]],
            goal: GoalLabels, stages: Sequence[tuple[float, float, float, int, int, int]], turn: float,
            free: tuple[np.ndarray, np.ndarray] | None, config: ImageGoalConfig) -> list[Pose]:
    """Finer grids, clouds (``voxels(size)``) and headings round ``kept``, the first turning within ``turn``."""
    for step, half, voxel, columns, rows, keep in stages:
        xz = _grid(np.array([[x, z] for _, x, z, _ in kept]), half, step)
        if free is not None:
            on = _on_free(xz, free[0], free[1], config.cell)
            xz = xz[on] if on.any() else np.array([[x, z] for _, x, z, _ in kept])
        kept = _search(xz, y, voxels(voxel), goal, (step, half, voxel, columns, rows, keep), kept, turn, config)
        turn = 2 * (2 * np.pi / columns)
    return kept


def estimate_camera(memory: Memory, goal_ids: np.ndarray, hfov_deg: float, goal_rgb: np.ndarray | None = None,
                    config: ImageGoalConfig = ImageGoalConfig()) -> CameraEstimate:
    """Where a level camera of ``hfov_deg`` saw ``goal_ids`` (H, W instance ids, -1 structure) and ``goal_rgb``
    (H, W, 3; None: structure unlabelled), from ``memory`` (module docstring). The camera's height is the
    retrieved keyframe's. The coarse stage's other poses (over a metre from the estimate, on its coarse grid) are
    the estimate's ``alternatives``."""
    cloud = memory_cloud(memory, config.stride)
    goal_hist = _histogram(goal_ids[::4, ::4])
    sims = np.array([similarity(goal_hist, h) for h in cloud.histograms])
    order = np.argsort(-sims, kind="stable")
    top = [int(k) for k in order[: config.top_k]] if sims.max() > 0 else []
    y = float(cloud.camera_y[top[0]] if top else np.median(cloud.camera_y))
    same_floor = np.abs(cloud.camera_y - y) < 0.5
    free = cloud.free(y - cloud.camera_height, config)
    goal = goal_labels(goal_ids, hfov_deg, goal_rgb, config)
    first = config.stages[0]
    centres = cloud.positions[top][:, [0, 2]] if top else cloud.positions[same_floor][:, [0, 2]]
    xz = _grid(centres, config.reach if top else 0.5, first[0])
    xz = xz[_on_free(xz, free[0], free[1], config.cell)]
    if not len(xz):  # no free floor round the keyframes: their own positions
        xz = cloud.positions[top or np.nonzero(same_floor)[0]][:, [0, 2]]
    coarse = _search(xz, y, cloud.voxels(first[2]), goal, first, [], None, config)
    turn = 2 * (2 * np.pi / first[3])
    kept = _refine(coarse, y, cloud.voxels, goal, config.stages[1:], turn, free, config)
    score, x, z, yaw = kept[0]
    alternatives = [pose for pose in coarse if np.hypot(pose[1] - x, pose[2] - z) > 1.0]
    return CameraEstimate(np.array([x, y, z]), _wrap(yaw), score, [(k, round(float(sims[k]), 4)) for k in top],
                          [(np.array([ax, y, az]), _wrap(ayaw), ascore) for ascore, ax, az, ayaw in alternatives],
                          goal)


def _wrap(yaw: float) -> float:
    return float(np.arctan2(np.sin(yaw), np.cos(yaw)))


def refine_camera(points: np.ndarray, ids: np.ndarray, colours: np.ndarray, goal: GoalLabels, position: np.ndarray,
                  yaw: float, free: tuple[np.ndarray, np.ndarray] | None = None,
                  config: ImageGoalConfig = ImageGoalConfig()) -> CameraEstimate:
    """The goal camera searched for again round ``position`` (its height kept) and ``yaw`` over a cloud of
    ``points`` with their ``ids`` and ``colours`` (the live views of an agent that stands near it, with the
    memory's): ``config.refine_stages``, the first turning within ``config.refine_turn`` of ``yaw``, positions
    on ``free`` floor (a grid and its origin; None: anywhere). Its score is how well the cloud shows the goal
    image from there."""
    cache: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def voxels(size: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if size not in cache:
            kept = voxel_firsts(points, size)
            cache[size] = points[kept], ids[kept], colours[kept]
        return cache[size]
    start: list[Pose] = [(0.0, float(position[0]), float(position[2]), float(yaw))]
    score, x, z, a = _refine(start, float(position[1]), voxels, goal, config.refine_stages,
                             np.radians(config.refine_turn_deg), free, config)[0]
    return CameraEstimate(np.array([x, float(position[1]), z]), _wrap(a), score, [], [], goal)


def retrieved_camera(memory: Memory, query_vector: np.ndarray) -> CameraEstimate:
    """The camera position of the keyframe the memory's embedding index retrieves first for ``query_vector``."""
    assert memory.index is not None
    found = memory.index.search(query_vector, 1, None)
    k, cosine = found[0]
    pose = memory.store.pose(k)
    fwd = -pose[:3, 2]
    return CameraEstimate(pose[:3, 3].copy(), float(np.arctan2(-fwd[0], -fwd[2])), float(cosine), [(k, float(cosine))])
