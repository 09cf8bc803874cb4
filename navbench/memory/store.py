"""The on-disk keyframe bank: posed RGB-D views, the only scene representation the localiser keeps.

Layout of a store directory::

    keyframes.json        poses, intrinsics, metadata, build statistics (written last)
    rgb/000000.jpg        RGB (JPEG, or PNG with ``rgb_format="png"``)
    depth/000000.png      depth, 16-bit PNG in millimetres, 0 = no measurement
    instance/000000.png   optional 16-bit PNG of (instance id + 1); 0 = structure/background (id -1)

Poses are the *camera's* (not the agent's): position [x, y, z] and rotation [x, y, z, w] in Habitat's
frame (y up, the camera looks along its local -z, +x right, +y up), plus the camera-to-world 4x4.

Pixel convention (the renderer's, :func:`navbench.render.camera.intrinsics`): pixel (u, v) has its
centre at the integer coordinates (u, v), so a W-pixel-wide image spans [-0.5, W - 0.5] and the
principal point of a centred camera is ((W - 1) / 2, (H - 1) / 2). Resizing by (sx, sy) maps a
continuous coordinate x to sx * (x + 0.5) - 0.5, so fx scales by sx and cx becomes
sx * (cx + 0.5) - 0.5 (likewise for y), which is what :meth:`Intrinsics.resized` does. RGB is
area-resized; depth and instance ids use centre-aligned nearest
neighbour (``INTER_NEAREST_EXACT``) so no depth is ever interpolated across an edge.
"""

from __future__ import annotations

import json
import math
import shutil
import time
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from navbench.memory.keyframes import KeyframeSelector
from navbench.render.camera import camera_pose

STORE_VERSION = 1
STORE_FILE = "keyframes.json"
_DEPTH_SCALE = 1000.0  # PNG units per metre (millimetres)
_MAX_DEPTH_MM = np.iinfo(np.uint16).max
_SUBDIRS = ("rgb", "depth", "instance")


class StoreError(ValueError):
    """A keyframe store or one of its files is missing, malformed or inconsistent; names the path."""


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels for a ``width`` x ``height`` image (pixel-centre convention above)."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    @classmethod
    def from_hfov(cls, width: int, height: int, hfov_deg: float) -> Intrinsics:
        """Square pixels, centred principal point, horizontal field of view ``hfov_deg`` (Habitat's HFOV)."""
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        return cls(fx=f, fy=f, cx=(width - 1) / 2.0, cy=(height - 1) / 2.0, width=int(width), height=int(height))

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def resized(self, width: int, height: int) -> Intrinsics:
        sx, sy = width / self.width, height / self.height
        return Intrinsics(self.fx * sx, self.fy * sy, sx * (self.cx + 0.5) - 0.5, sy * (self.cy + 0.5) - 0.5,
                          int(width), int(height))

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict) -> Intrinsics:
        return cls(float(d["fx"]), float(d["fy"]), float(d["cx"]), float(d["cy"]), int(d["width"]), int(d["height"]))


@dataclass
class Frame:
    """One rendered view handed to :meth:`KeyframeStore.write` (camera pose, not agent pose)."""

    rgb: np.ndarray  # H x W x 3 uint8, RGB order
    depth: np.ndarray  # H x W float, metres along the optical axis; 0 = no hit
    position: np.ndarray  # camera position [x, y, z]
    rotation: np.ndarray  # camera rotation [x, y, z, w]
    intrinsics: Intrinsics
    instance_ids: np.ndarray | None = None  # H x W int, -1 = structure/background


@dataclass(frozen=True)
class StoreConfig:
    width: int | None = None  # target resolution (e.g. 160 x 120); None keeps the frames' own
    height: int | None = None
    rgb_format: str = "jpg"  # "jpg" or "png"
    jpeg_quality: int = 90
    keyframes: bool = True  # False stores every frame
    keyframe_translation: float = 0.25
    keyframe_rotation_deg: float = 15.0
    keep_instance_ids: bool = False  # the oracle perception backends need the renderer's instance ids

    def __post_init__(self) -> None:
        if self.rgb_format not in ("jpg", "png"):
            raise ValueError(f"rgb_format must be 'jpg' or 'png', got {self.rgb_format!r}")
        if (self.width is None) != (self.height is None):
            raise ValueError(f"give both width and height or neither, got {self.width}x{self.height}")
        if self.width is not None and (self.width <= 0 or self.height <= 0):
            raise ValueError(f"target resolution must be positive, got {self.width}x{self.height}")


@dataclass(frozen=True)
class StoreStats:
    frames: int  # frames offered to the store
    keyframes: int  # frames kept
    bytes: int  # bytes on disk (images + keyframes.json) when the store was written
    build_seconds: float  # wall time of the write, including producing the frames if they are lazy


@dataclass(frozen=True, eq=False)
class KeyframeRecord:
    id: int
    frame_index: int  # index of this keyframe in the original frame sequence
    position: np.ndarray
    rotation: np.ndarray
    cam_to_world: np.ndarray
    intrinsics: Intrinsics
    rgb_file: str
    depth_file: str
    instance_file: str | None

    def to_json(self) -> dict:
        return {
            "id": self.id,
            "frame_index": self.frame_index,
            "position": [float(v) for v in self.position],
            "rotation": [float(v) for v in self.rotation],
            "cam_to_world": self.cam_to_world.tolist(),
            "intrinsics": self.intrinsics.to_json(),
            "rgb": self.rgb_file,
            "depth": self.depth_file,
            "instance": self.instance_file,
        }

    @classmethod
    def from_json(cls, d: dict) -> KeyframeRecord:
        return cls(
            id=int(d["id"]),
            frame_index=int(d["frame_index"]),
            position=np.asarray(d["position"], dtype=np.float64),
            rotation=np.asarray(d["rotation"], dtype=np.float64),
            cam_to_world=np.asarray(d["cam_to_world"], dtype=np.float64),
            intrinsics=Intrinsics.from_json(d["intrinsics"]),
            rgb_file=str(d["rgb"]),
            depth_file=str(d["depth"]),
            instance_file=None if d.get("instance") is None else str(d["instance"]),
        )


# OpenCV's PNG writer, given no parameters, writes our 16-bit depth several times larger than an
# explicit zlib level 3 does, at the same speed.
_PNG_PARAMS = [cv2.IMWRITE_PNG_COMPRESSION, 3]


def _imwrite(path: Path, image: np.ndarray, params: list[int] | None = None) -> int:
    if params is None and path.suffix == ".png":
        params = _PNG_PARAMS
    if not cv2.imwrite(str(path), image, params or []):
        raise StoreError(f"could not write image {path}")
    return path.stat().st_size


def _imread(path: Path, flags: int) -> np.ndarray:
    image = cv2.imread(str(path), flags)
    if image is None:
        raise StoreError(f"missing or unreadable keyframe image {path}")
    return image


def _check_frame(i: int, frame: Frame) -> tuple[int, int]:
    h, w = frame.depth.shape[:2] if frame.depth.ndim >= 2 else (0, 0)
    if frame.depth.ndim != 2 or frame.rgb.shape != (h, w, 3):
        raise StoreError(f"frame {i}: rgb {frame.rgb.shape} and depth {frame.depth.shape} must be HxWx3 and HxW")
    if (frame.intrinsics.width, frame.intrinsics.height) != (w, h):
        intr = frame.intrinsics
        raise StoreError(f"frame {i}: intrinsics are for {intr.width}x{intr.height}, image is {w}x{h}")
    if frame.instance_ids is not None and frame.instance_ids.shape != (h, w):
        raise StoreError(f"frame {i}: instance ids {frame.instance_ids.shape} do not match the {w}x{h} image")
    return w, h


def read_versioned_json(path: Path, version: int, error: type[ValueError], what: str) -> dict:
    """A JSON document with a ``version`` field, or ``error`` naming the file and what is wrong."""
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise error(f"no {what} at {path.parent} ({path.name} missing)") from None
    except (OSError, json.JSONDecodeError) as e:
        raise error(f"unreadable {what} file {path}: {e}") from None
    if not isinstance(doc, dict) or doc.get("version") != version:
        found = doc.get("version") if isinstance(doc, dict) else None
        raise error(f"{path}: unsupported {what} version {found!r} (expected {version})")
    return doc


class KeyframeStore:
    """Read access to a keyframe directory; images load lazily, one file per call."""

    def __init__(self, directory: Path, records: list[KeyframeRecord], scene_id: str, config: StoreConfig,
                 metadata: dict[str, Any], stats: StoreStats) -> None:
        self.directory = directory
        self.records = records
        self.scene_id = scene_id
        self.config = config
        self.metadata = metadata
        self.stats = stats

    # ---------------------------------------------------------------- writing
    @classmethod
    def write(cls, directory: str | Path, frames: Iterable[Frame], *, scene_id: str = "",
              config: StoreConfig = StoreConfig(), metadata: dict[str, Any] | None = None,
              overwrite: bool = False, frame_indices: Sequence[int] | None = None,
              total_frames: int | None = None) -> KeyframeStore:
        """Select keyframes from ``frames`` (consumed once, in trajectory order) and write them.

        ``frames`` may be a generator: only the current frame is held in memory.

        A caller that has already selected its keyframes (the pre-scan picks them from the poses alone
        and renders only those) passes ``frame_indices``, their indices in the full trajectory, and
        ``total_frames``, its length: every given frame is then stored, and the records and statistics
        still describe the trajectory.
        """
        if (frame_indices is None) != (total_frames is None):
            raise StoreError("give both frame_indices and total_frames, or neither")
        start = time.perf_counter()
        directory = Path(directory)
        if (directory / STORE_FILE).exists():
            if not overwrite:
                raise StoreError(f"keyframe store already exists at {directory} (pass overwrite=True)")
            for sub in _SUBDIRS:
                shutil.rmtree(directory / sub, ignore_errors=True)
            (directory / STORE_FILE).unlink()
        for sub in _SUBDIRS[:2] + (("instance",) if config.keep_instance_ids else ()):
            (directory / sub).mkdir(parents=True, exist_ok=True)

        selector = KeyframeSelector(config.keyframe_translation, config.keyframe_rotation_deg)
        rgb_params = [cv2.IMWRITE_JPEG_QUALITY, int(config.jpeg_quality)] if config.rgb_format == "jpg" else None
        records: list[KeyframeRecord] = []
        n_bytes = 0
        n_frames = 0
        preselected = None if frame_indices is None else [int(i) for i in frame_indices]
        for j, frame in enumerate(frames):
            n_frames += 1
            if preselected is not None:
                if j >= len(preselected):
                    raise StoreError(f"more frames than the {len(preselected)} frame_indices given for {directory}")
                i = preselected[j]
            else:
                i = j
            w, h = _check_frame(i, frame)
            if preselected is None and config.keyframes and not selector.accept(frame.position, frame.rotation):
                continue
            k = len(records)
            rgb, depth = np.ascontiguousarray(frame.rgb, dtype=np.uint8), np.asarray(frame.depth, dtype=np.float32)
            ids, intr = frame.instance_ids, frame.intrinsics
            if config.width is not None and (config.width, config.height) != (w, h):
                size = (config.width, config.height)
                rgb = cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)
                depth = cv2.resize(depth, size, interpolation=cv2.INTER_NEAREST_EXACT)
                if ids is not None and config.keep_instance_ids:
                    # int32 is not resizable by cv2; ids + 1 fit in uint16 by the storage format anyway.
                    ids = cv2.resize(_ids_to_png(ids, i), size, interpolation=cv2.INTER_NEAREST_EXACT)
                    ids = ids.astype(np.int32) - 1
                intr = intr.resized(*size)
            names = {sub: f"{sub}/{k:06d}.{'png' if sub != 'rgb' else config.rgb_format}" for sub in _SUBDIRS}
            n_bytes += _imwrite(directory / names["rgb"], cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), rgb_params)
            n_bytes += _imwrite(directory / names["depth"], _depth_to_png(depth))
            instance_file = None
            if config.keep_instance_ids:
                if ids is None:
                    raise StoreError(f"frame {i}: keep_instance_ids is set but the frame has no instance ids")
                instance_file = names["instance"]
                n_bytes += _imwrite(directory / instance_file, _ids_to_png(ids, i))
            position = np.asarray(frame.position, dtype=np.float64)
            rotation = np.asarray(frame.rotation, dtype=np.float64)
            records.append(KeyframeRecord(k, i, position, rotation, camera_pose(position, rotation), intr,
                                          names["rgb"], names["depth"], instance_file))
        if not records:
            raise StoreError(f"no frames were given for the keyframe store at {directory}")
        if preselected is not None:
            if len(records) != len(preselected):
                raise StoreError(f"{len(preselected)} frame_indices but {len(records)} frames for {directory}")
            n_frames = int(total_frames)

        doc: dict[str, Any] = {
            "version": STORE_VERSION,
            "scene_id": scene_id,
            "config": asdict(config),
            "metadata": metadata or {},
            "keyframes": [r.to_json() for r in records],
        }
        elapsed = time.perf_counter() - start
        # The byte count includes keyframes.json itself, whose length depends on that count: iterate to
        # the fixed point (two rounds unless the number of digits changes).
        json_bytes = 0
        for _ in range(4):
            stats = StoreStats(n_frames, len(records), n_bytes + json_bytes, elapsed)
            text = json.dumps({**doc, "stats": asdict(stats)}, indent=1)
            if len(text.encode()) == json_bytes:
                break
            json_bytes = len(text.encode())
        (directory / STORE_FILE).write_text(text)
        return cls(directory, records, scene_id, config, doc["metadata"], stats)

    # ---------------------------------------------------------------- reading
    @classmethod
    def open(cls, directory: str | Path) -> KeyframeStore:
        directory = Path(directory)
        path = directory / STORE_FILE
        doc = read_versioned_json(path, STORE_VERSION, StoreError, "keyframe store")
        try:
            records = [KeyframeRecord.from_json(d) for d in doc["keyframes"]]
            config = StoreConfig(**doc["config"])
            stats = StoreStats(**doc["stats"])
        except (KeyError, TypeError, ValueError) as e:
            raise StoreError(f"{path}: malformed keyframe store ({e})") from None
        if [r.id for r in records] != list(range(len(records))):
            raise StoreError(f"{path}: keyframe ids must be 0..{len(records) - 1} in order")
        return cls(directory, records, str(doc.get("scene_id", "")), config, doc.get("metadata", {}), stats)

    def __len__(self) -> int:
        return len(self.records)

    def _record(self, i: int) -> KeyframeRecord:
        if not 0 <= i < len(self.records):
            raise IndexError(f"keyframe {i} out of range for the {len(self.records)} keyframes in {self.directory}")
        return self.records[i]

    def rgb(self, i: int) -> np.ndarray:
        """H x W x 3 uint8 RGB."""
        return cv2.cvtColor(_imread(self.directory / self._record(i).rgb_file, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)

    def depth(self, i: int) -> np.ndarray:
        """H x W float32 metres; 0 where there was no measurement."""
        raw = _imread(self.directory / self._record(i).depth_file, cv2.IMREAD_UNCHANGED)
        if raw.dtype != np.uint16 or raw.ndim != 2:
            path = self.directory / self._record(i).depth_file
            raise StoreError(f"{path}: depth must be a 16-bit single-channel PNG")
        return raw.astype(np.float32) / np.float32(_DEPTH_SCALE)

    def instance_ids(self, i: int) -> np.ndarray:
        """H x W int32 instance ids, -1 for structure/background."""
        record = self._record(i)
        if record.instance_file is None:
            raise StoreError(f"keyframe store {self.directory} was written without instance ids")
        return _imread(self.directory / record.instance_file, cv2.IMREAD_UNCHANGED).astype(np.int32) - 1

    def pose(self, i: int) -> np.ndarray:
        """Camera-to-world 4x4."""
        return self._record(i).cam_to_world.copy()

    def K(self, i: int) -> np.ndarray:
        return self._record(i).intrinsics.K

    def intrinsics(self, i: int) -> Intrinsics:
        return self._record(i).intrinsics

    def poses(self) -> np.ndarray:
        """All camera-to-world matrices, (N, 4, 4)."""
        return np.stack([r.cam_to_world for r in self.records])

    def positions(self) -> np.ndarray:
        """All camera positions, (N, 3)."""
        return np.stack([r.position for r in self.records])

    def disk_bytes(self) -> int:
        """Bytes currently under the store directory (including an index saved beside it)."""
        return sum(p.stat().st_size for p in self.directory.rglob("*") if p.is_file())


def _depth_to_png(depth: np.ndarray) -> np.ndarray:
    mm = np.nan_to_num(depth, nan=0.0, posinf=0.0, neginf=0.0) * _DEPTH_SCALE
    return np.clip(np.rint(mm), 0, _MAX_DEPTH_MM).astype(np.uint16)


def _ids_to_png(ids: np.ndarray, frame_index: int) -> np.ndarray:
    ids = np.asarray(ids)
    if ids.size and (ids.min() < -1 or ids.max() >= _MAX_DEPTH_MM):
        raise StoreError(f"frame {frame_index}: instance ids must lie in [-1, {_MAX_DEPTH_MM - 1}]")
    return (ids.astype(np.int64) + 1).astype(np.uint16)
