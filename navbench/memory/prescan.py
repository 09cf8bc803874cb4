"""Pre-scan: walk through a scene like a person filming their home, and keep posed RGB-D keyframes.

The coverage trajectory visits every room (annotated room AABBs): for each room, the navigable point
nearest the room's centre (inside the room, on the main navigable island) is a *viewpoint*; the
viewpoints are ordered by a greedy nearest-neighbour tour over geodesic distances, the camera is
driven between them with :class:`~navbench.scene.follower.GreedyFollower` and
:meth:`NavGrid.try_step` (the agent's own discrete motion model, no sliding) and looks around with
``look_around_turns`` turns at each. Rooms on every storey are visited
(:class:`~navbench.scene.layers.LayeredNav`): each storey's rooms in a tour of their own, the walk between
storeys driven over the joined surfaces where stairs or a ramp join them, a cut to the storey (as a video
cuts between takes) where nothing does, the camera always ``camera_height`` above the surface under it.
Like a hand-held video, every action is recorded as ``frames_per_action`` frames (the motion
interpolated), which is what keyframe selection thins.

Keyframes depend on the poses alone, so the whole trajectory is planned first, keyframes are selected,
and only keyframes are rendered. The memory directory holds the :class:`KeyframeStore`, the
:class:`EmbeddingIndex` (made with the chosen encoder) and ``memory.json`` (written last): the scene
file's sha1, the config and the encoder name, so :func:`load_or_build_memory` can tell a reusable
memory from a stale one.

This module sits below :mod:`navbench.localize`: it takes any encoder object with the small
:class:`KeyframeEncoder` shape (the localiser's backends have it), never imports one.

    navbench memory build --scene houses/val/house_008.glb [--perception oracle] [--out DIR]
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import shutil
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from navbench.loop_progress import progress
from navbench.memory.index import EmbeddingIndex
from navbench.memory.keyframes import select_keyframes
from navbench.memory.store import Frame, Intrinsics, KeyframeStore, StoreConfig, read_versioned_json
from navbench.paths import cache_dir
from navbench.scene import NAVIGABILITY_VERSION
from navbench.scene.asset import SceneAsset, SceneError
from navbench.scene.cache import layers_for, load_scene_and_navgrid, navgrid_for, scene_digest
from navbench.scene.follower import MOVE_FORWARD, STOP, TURN_LEFT, GreedyFollower
from navbench.scene.layers import LayeredNav, LayerView
from navbench.scene.navigability import NavGrid
from navbench.scene.pose import heading_vector, quat_from_yaw

MEMORY_FILE = "memory.json"
MEMORY_VERSION = 2
MODALITIES = ("rgb", "instance_ids")


class PrescanError(ValueError):
    """Bad pre-scan input, or a memory directory that is missing or malformed; names the value or path."""


class KeyframeEncoder(Protocol):
    """What the pre-scan needs from an encoder (structural: the localiser's encoders satisfy it)."""

    name: str  # identifies the embedding space; part of the memory's cache key
    modality: str  # "rgb" or "instance_ids": which keyframe image encode_images() takes

    def encode_images(self, images: Sequence[np.ndarray]) -> np.ndarray: ...


@dataclass(frozen=True)
class PrescanConfig:
    width: int = 224  # rendered camera (the agent's by default; e.g. 640 x 480 for a phone-like scan)
    height: int = 224
    hfov_deg: float = 79.0
    camera_height: float = 0.88  # metres above the floor
    keyframe_translation: float = 0.25
    keyframe_rotation_deg: float = 15.0
    store_resolution: tuple[int, int] | None = None  # (width, height) stored, e.g. (160, 120); None = rendered
    keyframes: bool = True  # False stores every frame
    keep_instance_ids: bool = True  # the oracle perception backends need them
    rgb_format: str = "jpg"
    forward_step: float = 0.25  # the agent's motion model
    turn_deg: float = 30.0
    look_around_turns: int = 12  # 12 x 30 deg: a full turn at every viewpoint
    frames_per_action: int = 3  # a hand-held video records the motion between the agent's poses
    room_margin: float = 0.3  # viewpoints keep this far inside the room's AABB (xz)
    # Rooms longer than this along x or z get several viewpoints (one per part of a grid of parts at
    # most this long): from the centre of a 7 m room the far corners lie beyond the localiser's 4 m
    # view filter, while those of a 5 m part lie within it (3.5 m) from the part's centre.
    viewpoint_spacing: float = 5.0
    success_distance: float = 0.25  # a viewpoint counts as reached this close (geodesic)
    max_leg_actions: int = 400  # give up on a viewpoint after this many actions

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0 or not 0 < self.hfov_deg < 180:
            raise PrescanError(f"bad prescan camera {self.width}x{self.height} hfov {self.hfov_deg}")
        if self.store_resolution is not None:
            w, h = self.store_resolution
            if w <= 0 or h <= 0:
                raise PrescanError(f"store_resolution must be positive, got {self.store_resolution}")
            object.__setattr__(self, "store_resolution", (int(w), int(h)))
        if self.frames_per_action < 1 or self.look_around_turns < 0:
            raise PrescanError(f"frames_per_action must be >= 1 and look_around_turns >= 0, got "
                               f"{self.frames_per_action} and {self.look_around_turns}")

    @property
    def camera(self) -> CameraConfig:  # noqa: F821 - see build_memory for the lazy import
        from navbench.render.camera import CameraConfig

        return CameraConfig(self.width, self.height, self.hfov_deg)

    def store_config(self) -> StoreConfig:
        w, h = self.store_resolution if self.store_resolution is not None else (None, None)
        return StoreConfig(width=w, height=h, rgb_format=self.rgb_format, keyframes=self.keyframes,
                           keyframe_translation=self.keyframe_translation,
                           keyframe_rotation_deg=self.keyframe_rotation_deg,
                           keep_instance_ids=self.keep_instance_ids)

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["store_resolution"] = None if self.store_resolution is None else list(self.store_resolution)
        return d


@dataclass(frozen=True)
class MemoryStats:
    frames: int  # frames of the scan trajectory
    keyframes: int  # frames kept (and rendered)
    bytes: int  # bytes on disk: keyframes, index, memory.json
    build_seconds: float  # planning + rendering + writing + encoding
    rooms_visited: tuple[str, ...] = ()
    rooms_missed: tuple[str, ...] = ()  # rooms with no reachable viewpoint

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["rooms_visited"], d["rooms_missed"] = list(self.rooms_visited), list(self.rooms_missed)
        return d

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> MemoryStats:
        return cls(int(d["frames"]), int(d["keyframes"]), int(d["bytes"]), float(d["build_seconds"]),
                   tuple(d.get("rooms_visited", ())), tuple(d.get("rooms_missed", ())))


@dataclass
class Trajectory:
    """Camera poses of a scan (position [x, y, z], rotation [x, y, z, w]) and what it visited."""

    positions: np.ndarray  # (N, 3) camera positions
    rotations: np.ndarray  # (N, 4)
    viewpoints: list[tuple[str, np.ndarray]] = field(default_factory=list)  # reached (room, agent position), tour order
    rooms_missed: list[str] = field(default_factory=list)  # rooms where no viewpoint was reached

    def __len__(self) -> int:
        return len(self.positions)

    def poses(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return list(zip(self.positions, self.rotations))


# ------------------------------------------------------------------------------------------ planning


def _room_parts(lo: np.ndarray, hi: np.ndarray, spacing: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Split a room's xz AABB into an n x m grid of parts no longer than ``spacing`` (if possible)."""
    nx = max(1, math.ceil((hi[0] - lo[0]) / spacing)) if spacing > 0 else 1
    nz = max(1, math.ceil((hi[2] - lo[2]) / spacing)) if spacing > 0 else 1
    xs, zs = np.linspace(lo[0], hi[0], nx + 1), np.linspace(lo[2], hi[2], nz + 1)
    return [(np.array([xs[i], lo[1], zs[j]]), np.array([xs[i + 1], hi[1], zs[j + 1]]))
            for i in range(nx) for j in range(nz)]


def room_viewpoints(asset: SceneAsset, grid: NavGrid, margin: float = 0.3, spacing: float = 0.0
                    ) -> tuple[list[tuple[str, np.ndarray]], list[str]]:
    """Per room (per part of a room, see ``PrescanConfig.viewpoint_spacing``), the navigable point
    nearest its centre inside the room's AABB shrunk by ``margin`` and inside the part, on the largest
    navigable island; rooms without any are returned as missed."""
    sizes = np.bincount(grid.islands.ravel())
    sizes[0] = 0
    main = grid.islands == int(np.argmax(sizes))
    rows, cols = np.nonzero(main)
    cells = grid.grid_to_world(np.stack([rows, cols], axis=1))
    found, missed = [], []
    for room in asset.rooms:
        lo, hi = np.asarray(room.aabb_min), np.asarray(room.aabb_max)
        if not lo[1] - 0.5 <= grid.floor_height <= hi[1]:
            missed.append(room.name)  # a room of another storey: its xz box would revisit this one's rooms
            continue
        in_room = ((cells[:, 0] >= lo[0] + margin) & (cells[:, 0] <= hi[0] - margin)
                   & (cells[:, 2] >= lo[2] + margin) & (cells[:, 2] <= hi[2] - margin))
        n_found = 0
        for plo, phi in _room_parts(lo, hi, spacing):
            inside = (in_room & (cells[:, 0] >= plo[0]) & (cells[:, 0] <= phi[0])
                      & (cells[:, 2] >= plo[2]) & (cells[:, 2] <= phi[2]))
            if not inside.any():
                continue
            centre = (plo + phi) / 2.0
            cand = cells[inside]
            best = cand[int(np.argmin(np.hypot(cand[:, 0] - centre[0], cand[:, 2] - centre[2])))]
            # Start a fifth of a cell off the cell centre: from a centre, 0.25 m steps at 30-degree
            # multiples land exactly on half-cell boundaries, where NavGrid's cell lookup and the
            # geodesic field's disagree by a float ulp (the follower then sees an infinite distance).
            found.append((room.name, best + np.array([0.2, 0.0, 0.2]) * grid.cell_size))
            n_found += 1
        if n_found == 0:
            missed.append(room.name)
    return found, missed


def tour_order(grid: NavGrid, points: Sequence[np.ndarray], start: int = 0) -> list[int]:
    """Greedy nearest-neighbour tour over geodesic distances, from ``points[start]``."""
    order, left = [start], set(range(len(points))) - {start}
    while left:
        field = grid.distance_field(points[order[-1]])
        nxt = min(left, key=lambda j: (field.distance(points[j]), j))
        order.append(nxt)
        left.remove(nxt)
    return order


def _other_storeys(asset: SceneAsset, grid: NavGrid, config: PrescanConfig, first: np.ndarray,
                   ) -> tuple[LayeredNav, list[tuple[NavGrid, list[tuple[str, np.ndarray]], bool]]] | None:
    """The viewpoints of the rooms on other storeys than ``grid``'s, grouped by storey with each storey's grid
    and whether the joined walkable surfaces (stairs, ramps) connect it to ``first``; None when no room lies
    on another storey (the surfaces are not built then)."""
    others = [r for r in asset.rooms if not r.aabb_min[1] - 0.5 <= grid.floor_height <= r.aabb_max[1]]
    if not others:
        return None
    nav = layers_for(asset, grid.config)
    s = nav.span_of(first)
    base = dataclasses.replace(grid.config, floor_height=None)  # a storey's grid pins its floor: free it
    groups: dict[float, tuple[NavGrid, list[tuple[str, np.ndarray]], bool]] = {}
    for room in others:
        floor = NavGrid.floor_within(asset.mesh, float(room.aabb_min[1]), float(room.aabb_max[1]), base)
        if floor is None:
            continue  # no walkable level inside the room's height range
        try:
            g = navgrid_for(asset, base, floor_hint=floor)
        except SceneError:
            continue  # no walkable floor with headroom at that height
        if abs(g.floor_height - grid.floor_height) <= grid.config.max_climb or g.floor_height in groups:
            continue
        found, _ = room_viewpoints(asset, g, config.room_margin, config.viewpoint_spacing)
        found = [(r, p) for r, p in found if nav.span_of(p) >= 0]
        joined = [(r, p) for r, p in found if s >= 0 and nav.component[nav.span_of(p)] == nav.component[s]]
        if found:
            groups[g.floor_height] = (g, joined or found, bool(joined))
    return nav, list(groups.values())


def _scan_plan(asset: SceneAsset, grid: NavGrid, config: PrescanConfig
               ) -> tuple[list[tuple[str, np.ndarray]], list[NavGrid | LayerView | None]]:
    """The viewpoints in tour order and what each leg to one is driven on: its storey's grid, or, for the
    first viewpoint of another storey, the joined surfaces over the stairs or ramp between them, or None
    where nothing joins that storey to the walk so far (the scan cuts to it, as a video cuts between takes).
    The start storey's rooms come first; the joined storeys follow, nearest (along the surfaces) first, then
    the storeys nothing joins, bottom-up."""
    viewpoints, missed = room_viewpoints(asset, grid, config.room_margin, config.viewpoint_spacing)
    if not viewpoints:
        raise PrescanError(f"{asset.path}: no room has a navigable viewpoint")
    order = tour_order(grid, [p for _, p in viewpoints])
    viewpoints = [viewpoints[i] for i in order]
    legs: list[NavGrid | LayerView | None] = [grid] * len(viewpoints)
    found = _other_storeys(asset, grid, config, viewpoints[0][1]) if missed else None
    if found is None:
        return viewpoints, legs
    nav, groups = found
    joined = [(g, pts) for g, pts, j in groups if j]
    while joined:
        field = nav.distance_field(viewpoints[-1][1])
        near = [min(range(len(pts)), key=lambda j: (field.distance(pts[j][1]), j)) for _, pts in joined]
        k = min(range(len(joined)), key=lambda i: (field.distance(joined[i][1][near[i]][1]), i))
        g, pts = joined.pop(k)
        order = tour_order(g, [p for _, p in pts], start=near[k])
        viewpoints += [pts[i] for i in order]
        legs += [LayerView(nav, viewpoints[-len(order) - 1][1])] + [g] * (len(order) - 1)
    for g, pts, _ in sorted((x for x in groups if not x[2]), key=lambda x: x[0].floor_height):
        order = tour_order(g, [p for _, p in pts])
        viewpoints += [pts[i] for i in order]
        legs += [None] + [g] * (len(order) - 1)
    return viewpoints, legs


def plan_trajectory(asset: SceneAsset, grid: NavGrid, config: PrescanConfig = PrescanConfig()) -> Trajectory:
    """The scan's camera poses (see the module docstring); deterministic for a scene and config."""
    viewpoints, legs = _scan_plan(asset, grid, config)
    lift = np.array([0.0, config.camera_height, 0.0])
    turn = math.radians(config.turn_deg)
    n = config.frames_per_action
    positions: list[np.ndarray] = []
    yaws: list[float] = []

    pos = viewpoints[0][1].copy()
    yaw = 0.0
    positions.append(pos.copy())
    yaws.append(yaw)

    def emit(p0: np.ndarray, p1: np.ndarray, y0: float, y1: float) -> None:
        for k in range(1, n + 1):
            t = k / n
            positions.append(p0 + t * (p1 - p0))
            yaws.append(y0 + t * (y1 - y0))

    visited = []
    for vi, (room, goal) in enumerate(viewpoints):
        if vi > 0 and legs[vi] is None:  # a storey nothing joins: the scan cuts to its first viewpoint
            pos = goal.copy()
            positions.append(pos.copy())
            yaws.append(yaw)
        elif vi > 0:
            motion = legs[vi]
            follower = GreedyFollower(motion, goal, config.success_distance, config.forward_step, config.turn_deg)
            for _ in range(config.max_leg_actions):
                if isinstance(motion, LayerView):
                    motion.track(pos)
                action = follower.next_action(pos, quat_from_yaw(yaw))
                if action == STOP:
                    break
                if action == MOVE_FORWARD:
                    new, _ = motion.try_step(pos, pos + config.forward_step * heading_vector(yaw))
                    emit(pos, new, yaw, yaw)
                    pos = new
                else:
                    new_yaw = yaw + (turn if action == TURN_LEFT else -turn)
                    emit(pos, pos, yaw, new_yaw)
                    yaw = new_yaw
            if isinstance(motion, LayerView):
                motion.track(pos)
            if follower.distance(pos) >= config.success_distance:
                continue  # could not get there (the room counts as missed unless another viewpoint works)
        visited.append((room, pos.copy()))
        for _ in range(config.look_around_turns):
            emit(pos, pos, yaw, yaw + turn)
            yaw += turn
    yaw_arr = np.asarray(yaws)
    rotations = np.stack([quat_from_yaw(float(math.remainder(y, 2 * math.pi))) for y in yaw_arr])
    reached = {r for r, _ in visited}
    missed = [r.name for r in asset.rooms if r.name not in reached]
    return Trajectory(np.asarray(positions) + lift, rotations, visited, missed)


# ------------------------------------------------------------------------------------------ memory


@dataclass
class Memory:
    """A built memory: keyframes, their embedding index, and the record of how they were made."""

    directory: Path
    store: KeyframeStore
    index: EmbeddingIndex | None  # None when built without an encoder
    info: dict[str, Any]
    built_now: bool = False  # set by load_or_build_memory: built by this call rather than reused

    @property
    def stats(self) -> MemoryStats:
        return MemoryStats.from_json(self.info["stats"])

    @property
    def config(self) -> PrescanConfig:
        return config_from_json(self.info["config"])

    @classmethod
    def open(cls, directory: str | Path) -> Memory:
        directory = Path(directory)
        info = read_versioned_json(directory / MEMORY_FILE, MEMORY_VERSION, PrescanError, "memory")
        index = None if info.get("encoder") is None else EmbeddingIndex.load(directory)
        return cls(directory, KeyframeStore.open(directory), index, info)

    def images(self, keyframe_id: int, modality: str) -> np.ndarray:
        """The keyframe image an encoder/backend of ``modality`` consumes."""
        if modality == "rgb":
            return self.store.rgb(keyframe_id)
        if modality == "instance_ids":
            return self.store.instance_ids(keyframe_id)
        raise PrescanError(f"unknown image modality {modality!r} (expected one of {MODALITIES})")


def config_from_json(d: dict[str, Any]) -> PrescanConfig:
    d = dict(d)
    if d.get("store_resolution") is not None:
        d["store_resolution"] = tuple(d["store_resolution"])
    return PrescanConfig(**d)


def encoder_modality(encoder: KeyframeEncoder) -> str:
    # An encoder without a ``modality`` attribute (any plain Encoder) reads RGB.
    modality = getattr(encoder, "modality", "rgb")
    if modality not in MODALITIES:
        raise PrescanError(f"encoder {encoder!r} has unknown modality {modality!r}")
    return modality


def encoder_name(encoder: KeyframeEncoder) -> str:
    return str(getattr(encoder, "name", type(encoder).__name__))


def encoder_placement(encoder: KeyframeEncoder | None) -> str | None:
    """Where and at what precision an encoder computes its embeddings, when that is not the CPU in float32
    (the GPU's model, not its index: two cards of one model give the same numbers, e.g. ``NVIDIA H200
    bfloat16``); None on the CPU in float32 and for an encoder without a torch device (the oracle's)."""
    device = getattr(encoder, "device", None)
    dtype = getattr(encoder, "dtype", None)
    dev = "cpu" if device is None else str(device)
    dt = "float32" if dtype is None else str(dtype).removeprefix("torch.")
    if dev == "cpu" and dt == "float32":
        return None
    if dev.startswith("cuda"):
        from navbench.device import device_name
        dev = device_name(dev)
    return f"{dev} {dt}"


def _frames(renderer, traj: Trajectory, keep: Sequence[int], intr: Intrinsics, ids: bool):
    for i in keep:
        out = renderer.render(traj.positions[i], traj.rotations[i], rgb=True, depth=True, ids=ids)
        yield Frame(out.rgb, out.depth, traj.positions[i], traj.rotations[i], intr, out.ids)


def build_memory(scene_path: str | Path, out_dir: str | Path, config: PrescanConfig = PrescanConfig(),
                 encoder: KeyframeEncoder | None = None, batch_size: int = 32) -> MemoryStats:
    """Scan ``scene_path`` and write a memory to ``out_dir`` (replacing what is there).

    Without an ``encoder`` no index is written (the directory is then a bare keyframe store and
    ``memory.json`` records ``encoder: null``).
    """
    # Imported here, not at module level: the renderer binds PyOpenGL's platform and loads pyrender on
    # import, which code that only reads memories (the localiser) should not pay for.
    from navbench.render.renderer import Renderer

    start = time.perf_counter()
    scene_path, out_dir = Path(scene_path), Path(out_dir)
    digest = scene_digest(scene_path)
    asset, grid = load_scene_and_navgrid(scene_path)
    traj = plan_trajectory(asset, grid, config)
    poses = traj.poses()
    keep = (select_keyframes(poses, config.keyframe_translation, config.keyframe_rotation_deg)
            if config.keyframes else list(range(len(poses))))

    if out_dir.exists():
        shutil.rmtree(out_dir)
    out_dir.mkdir(parents=True)
    cam = config.camera
    intr = Intrinsics.from_hfov(cam.width, cam.height, cam.hfov_deg)
    with Renderer(asset, cam) as renderer:
        frames = progress(_frames(renderer, traj, keep, intr, config.keep_instance_ids), len(keep),
                          f"memory {scene_path.name.split('.')[0]}: keyframes")
        store = KeyframeStore.write(out_dir, frames,
                                    scene_id=asset.scene_id, config=config.store_config(),
                                    metadata={"scene_path": str(scene_path), "scene_digest": digest},
                                    frame_indices=keep, total_frames=len(poses))
    name = None
    if encoder is not None:
        modality = encoder_modality(encoder)
        name = encoder_name(encoder)
        chunks = []
        for s in range(0, len(store), batch_size):
            ids = range(s, min(s + batch_size, len(store)))
            chunks.append(encoder.encode_images([
                store.rgb(i) if modality == "rgb" else store.instance_ids(i) for i in ids]))
        EmbeddingIndex(np.concatenate(chunks), list(range(len(store))), model=name).save(out_dir)

    missed = tuple(traj.rooms_missed)
    visited = tuple(dict.fromkeys(r for r, _ in traj.viewpoints))
    info: dict[str, Any] = {
        "version": MEMORY_VERSION,
        "scene_path": str(scene_path),
        "scene_id": asset.scene_id,
        "scene_digest": digest,
        "config": config.to_json(),
        "encoder": name,
        **({"placement": placement} if (placement := encoder_placement(encoder)) is not None else {}),
        "viewpoints": [{"room": r, "position": [round(float(v), 4) for v in p]} for r, p in traj.viewpoints],
    }
    # Bytes include memory.json itself; its length depends on the count, so settle the fixed point.
    other = sum(p.stat().st_size for p in out_dir.rglob("*") if p.is_file())
    json_bytes = 0
    # The build time is read once: a time that changed between the passes could change the text's
    # length on the last one and leave the recorded byte count wrong.
    seconds = time.perf_counter() - start
    for _ in range(4):
        stats = MemoryStats(len(poses), len(store), other + json_bytes, seconds, visited, missed)
        text = json.dumps({**info, "stats": stats.to_json()}, indent=1)
        if len(text.encode()) == json_bytes:
            break
        json_bytes = len(text.encode())
    (out_dir / MEMORY_FILE).write_text(text)
    return stats


# Which storeys the scan covers and how it reaches them; a change that moves any scan pose bumps it.
# 2: every storey with rooms, the ones nothing joins by a cut. 3: a storey's floor found within its rooms' height range.
SCAN_VERSION = 3


def memory_key(digest: str, config: PrescanConfig, encoder_name_: str | None, placement: str | None = None) -> str:
    # the navigability rules and the scan's plan place the scan poses, so a memory built under others is not
    # reused; a GPU's or another precision's embeddings differ in rounding from the CPU's float32 ones, so each
    # placement has its own (a CPU float32 memory keeps the key it always had)
    blob = json.dumps({"digest": digest, "config": config.to_json(), "encoder": encoder_name_,
                       "navigability": NAVIGABILITY_VERSION, "scan": SCAN_VERSION,
                       **({"placement": placement} if placement is not None else {})}, sort_keys=True)
    return hashlib.sha1(blob.encode()).hexdigest()[:12]


def load_or_build_memory(scene_path: str | Path, cache_root: str | Path | None = None,
                         config: PrescanConfig = PrescanConfig(), encoder: KeyframeEncoder | None = None
                         ) -> Memory:
    """The memory of ``scene_path`` for ``config`` and ``encoder``: reused from ``cache_root`` (default
    ``cache_dir("memory")``) when its ``memory.json`` matches the scene's sha1, the config, the
    encoder name and where it ran (:func:`encoder_placement`), otherwise (re)built there;
    ``memory.built_now`` tells which.

    The directory is ``{cache_root}/{scene stem}-{key}``, the key hashing config, encoder and placement, so
    memories of different configs coexist; a changed scene file (same path, new sha1) is rebuilt in
    place.
    """
    scene_path = Path(scene_path)
    root = cache_dir("memory") if cache_root is None else Path(cache_root)
    name = None if encoder is None else encoder_name(encoder)
    placement = encoder_placement(encoder)
    cfg_key = memory_key("", config, name, placement)
    directory = root / f"{scene_path.name.split('.')[0]}-{cfg_key}"
    digest = scene_digest(scene_path)
    if (directory / MEMORY_FILE).is_file():
        try:
            memory = Memory.open(directory)
            if (memory.info.get("scene_digest") == digest and memory.info.get("encoder") == name
                    and memory.info.get("placement") == placement and memory.info.get("config") == config.to_json()):
                return memory
        except ValueError:
            pass  # stale or partial: rebuilt below
    build_memory(scene_path, directory, config, encoder)
    memory = Memory.open(directory)
    memory.built_now = True
    return memory
