"""GOAT-style multimodal localisation split: object, image and language queries on the val scenes.

Per scene, three kinds of subtask (GOAT-Bench's modalities):

* ``object``: a category name present in the scene; every instance of it is a valid answer.
* ``image``: a 224 x 224 render of one target instance from a random navigable pose 1-3 m away,
  facing it, where the instance is clearly visible (>= ``min_image_fraction`` of the image) and is the
  object in the image centre (:func:`~navbench.localize.backends.oracle.centre_instance`); the pose is
  checked not to coincide with any pose of the pre-scan trajectory (so the query view is not in the
  memory). The RGB PNG and a 16-bit PNG of (instance id + 1) are saved under ``images/``.
* ``language``: "the {colour} {category} in the {room} next to the {object}", built from the
  annotations by :func:`~navbench.localize.describe.describe_with_room` and accepted only if it
  grounds to the target alone (otherwise the target is skipped).

Targets must be *observable*: a view like the image query's exists (objects hidden from every
navigable pose at camera height are never asked for, as GOAT only asks for objects with view points).

File: ``episodes/goat/{split}/{split}.json.gz`` = ``{"info": {...}, "subtasks": [...]}``, each subtask
``{id, scene_id (relative to envs/), type, query, image, image_ids, target_ids, gt_positions}`` with
``gt_positions`` the AABB centres of all valid answers.
"""

from __future__ import annotations

import gzip
import json
import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from navbench.episodes.generate import SPLIT_VERSION
from navbench.localize.backends.oracle import centre_instance
from navbench.localize.describe import describe_with_room
from navbench.localize.pipeline import Query
from navbench.memory.prescan import PrescanConfig, plan_trajectory
from navbench.paths import EPISODES_DIR, SCENES_DIR
from navbench.render.camera import CameraConfig
from navbench.render.renderer import Renderer
from navbench.scene.annotations import ObjectAnnotation
from navbench.scene.asset import SceneAsset
from navbench.scene.cache import load_scene_and_navgrid
from navbench.scene.navigability import NavGrid
from navbench.scene.pose import quat_from_yaw, wrap_angle, yaw_from_quat, yaw_towards

GOAT_DIR = EPISODES_DIR / "goat"
VAL_SCENES: tuple[str, ...] = tuple(f"houses/val/house_{i:03d}.glb" for i in range(8, 12))


class GoatSplitError(ValueError):
    """A GOAT split file is missing or malformed; the message names the file."""


@dataclass(frozen=True)
class GoatConfig:
    per_type: int = 20  # subtasks per query type per scene (fewer if the scene has fewer targets)
    min_distance: float = 1.0  # image-query camera distance to the object centre (xz), metres
    max_distance: float = 3.0
    min_image_fraction: float = 0.02  # the target covers at least this share of the query image
    pose_tries: int = 60  # random poses tried per object
    memory_pose_clearance: float = 0.1  # metres and ...
    memory_yaw_clearance_deg: float = 10.0  # ... degrees from every pre-scan pose
    width: int = 224
    height: int = 224
    hfov_deg: float = 79.0
    camera_height: float = 0.88


@dataclass(frozen=True)
class GoatSubtask:
    id: str
    scene_id: str  # relative to envs/
    type: str  # "object" | "image" | "language"
    query: str | None  # category name or description; None for image queries
    image: str | None  # PNG path relative to the split directory
    image_ids: str | None  # 16-bit PNG of instance id + 1, relative to the split directory
    target_ids: tuple[int, ...]
    gt_positions: np.ndarray  # (M, 3) centres of every valid answer

    def to_json(self) -> dict:
        return {"id": self.id, "scene_id": self.scene_id, "type": self.type, "query": self.query,
                "image": self.image, "image_ids": self.image_ids, "target_ids": list(self.target_ids),
                "gt_positions": [[round(float(v), 4) for v in p] for p in self.gt_positions]}

    @classmethod
    def from_json(cls, d: dict) -> GoatSubtask:
        """Raises ValueError/TypeError/KeyError on a subtask that could not be asked or scored."""
        kind = d["type"]
        if kind not in ("object", "image", "language"):
            raise ValueError(f"subtask {d.get('id')!r}: type must be object, image or language, got {kind!r}")
        fields = ("image", "image_ids") if kind == "image" else ("query",)
        if not all(isinstance(d.get(f), str) for f in fields):
            raise ValueError(f"subtask {d.get('id')!r}: a {kind} query needs string {' and '.join(fields)}")
        gt = np.asarray(d["gt_positions"], dtype=np.float64).reshape(-1, 3)
        if len(gt) == 0 or not np.isfinite(gt).all():
            raise ValueError(f"subtask {d.get('id')!r}: gt_positions must be finite xyz points")
        if isinstance(d["target_ids"], (str, dict)):
            raise TypeError(f"subtask {d.get('id')!r}: target_ids must be a list of ints")
        return cls(str(d["id"]), str(d["scene_id"]), kind, d.get("query"), d.get("image"),
                   d.get("image_ids"), tuple(int(i) for i in d["target_ids"]), gt)

    def to_query(self, split_dir: str | Path) -> Query:
        """The localiser's :class:`Query`, loading the image files relative to ``split_dir``."""
        if self.type != "image":
            return Query(self.type, text=self.query)
        split_dir = Path(split_dir)
        rgb = cv2.imread(str(split_dir / self.image), cv2.IMREAD_COLOR)
        ids = cv2.imread(str(split_dir / self.image_ids), cv2.IMREAD_UNCHANGED)
        if rgb is None or ids is None:
            raise GoatSplitError(f"subtask {self.id}: missing image {split_dir / self.image} or its ids")
        return Query("image", image=cv2.cvtColor(rgb, cv2.COLOR_BGR2RGB), image_ids=ids.astype(np.int32) - 1)


def split_path(split: str = "goat_val", root: str | Path | None = None) -> Path:
    root = GOAT_DIR if root is None else Path(root)
    return root / split / f"{split}.json.gz"


def load_goat_split(split: str | Path = "goat_val", root: str | Path | None = None) -> list[GoatSubtask]:
    """Subtasks of a split, by name (under ``episodes/goat``) or by file path."""
    path = Path(split) if str(split).endswith(".json.gz") else split_path(str(split), root)
    try:
        with gzip.open(path, "rt") as f:
            doc = json.load(f)
        return [GoatSubtask.from_json(d) for d in doc["subtasks"]]
    except FileNotFoundError:
        raise GoatSplitError(f"{path}: GOAT split not found (run generate_goat_split)") from None
    except (OSError, EOFError, zlib.error, KeyError, TypeError, ValueError, AttributeError, IndexError) as e:
        raise GoatSplitError(f"{path}: malformed GOAT split ({type(e).__name__}: {e})") from None
    except RecursionError:
        raise GoatSplitError(f"{path}: malformed GOAT split (JSON nested too deeply)") from None


# ------------------------------------------------------------------------------------------ generation


class _ViewFinder:
    """Random clear views of single objects, away from the pre-scan trajectory."""

    def __init__(self, asset: SceneAsset, grid: NavGrid, config: GoatConfig) -> None:
        self.asset, self.grid, self.config = asset, grid, config
        cam = CameraConfig(config.width, config.height, config.hfov_deg)
        self.renderer = Renderer(asset, cam)
        traj = plan_trajectory(asset, grid, PrescanConfig(width=config.width, height=config.height,
                                                          hfov_deg=config.hfov_deg,
                                                          camera_height=config.camera_height))
        self._traj_xz = traj.positions[:, [0, 2]]
        self._traj_yaw = np.array([yaw_from_quat(q) for q in traj.rotations])
        sizes = np.bincount(grid.islands.ravel())
        sizes[0] = 0
        self._main_island = int(np.argmax(sizes))

    def _in_memory(self, xz: np.ndarray, yaw: float) -> bool:
        near = np.hypot(*(self._traj_xz - xz).T) < self.config.memory_pose_clearance
        dyaw = np.abs([wrap_angle(float(y - yaw)) for y in self._traj_yaw[near]])
        return bool((np.degrees(dyaw) < self.config.memory_yaw_clearance_deg).any())

    def find(self, obj: ObjectAnnotation, rng: np.random.Generator):
        """(camera position, rotation, rgb, ids) of a clear view of ``obj``, or None."""
        cfg = self.config
        centre = obj.center
        for _ in range(cfg.pose_tries):
            d = rng.uniform(cfg.min_distance, cfg.max_distance)
            theta = rng.uniform(0, 2 * math.pi)
            p = np.array([centre[0] + d * math.sin(theta), self.grid.floor_height, centre[2] + d * math.cos(theta)])
            if not self.grid.is_navigable(p) or self.grid.island_id(p) != self._main_island:
                continue
            yaw = yaw_towards(p, centre)
            if self._in_memory(p[[0, 2]], yaw):
                continue
            cam = p + np.array([0.0, cfg.camera_height, 0.0])
            rot = quat_from_yaw(yaw)
            out = self.renderer.render(cam, rot, rgb=True, depth=False, ids=True)
            if (out.ids == obj.id).mean() >= cfg.min_image_fraction and centre_instance(out.ids) == obj.id:
                return cam, rot, out.rgb, out.ids
        return None

    def close(self) -> None:
        self.renderer.close()


def generate_goat_split(out_dir: str | Path, scene_paths: Sequence[str | Path] | None = None, seed: int = 0,
                        per_type: int = 20, config: GoatConfig | None = None, split: str = "goat_val",
                        scenes_dir: str | Path = SCENES_DIR) -> Path:
    """Write ``{out_dir}/{split}.json.gz`` and ``{out_dir}/images/``; returns the split file.

    ``scene_paths`` default to the four val houses; ``per_type`` subtasks per type per scene.
    """
    config = GoatConfig(per_type=per_type) if config is None else config
    scenes_dir = Path(scenes_dir)
    scene_paths = [scenes_dir / s for s in VAL_SCENES] if scene_paths is None else [Path(s) for s in scene_paths]
    out_dir = Path(out_dir)
    (out_dir / "images").mkdir(parents=True, exist_ok=True)
    subtasks: list[GoatSubtask] = []
    scene_ids: list[str] = []
    for si, scene_path in enumerate(scene_paths):
        rng = np.random.default_rng([seed, si])
        asset, grid = load_scene_and_navgrid(scene_path)
        try:
            scene_id = scene_path.resolve().relative_to(scenes_dir.resolve()).as_posix()
        except ValueError:
            scene_id = scene_path.name
        scene_ids.append(scene_id)
        stem = scene_path.name.split(".")[0]
        finder = _ViewFinder(asset, grid, config)
        try:
            objects = [asset.objects[i] for i in sorted(asset.objects)]
            views = {o.id: finder.find(o, rng) for o in objects}
        finally:
            finder.close()
        observable = [o for o in objects if views[o.id] is not None]

        # Object queries: categories with an observable instance; all instances are answers.
        cats = sorted({o.category for o in observable})
        for n, cat in enumerate(rng.permutation(cats)[:config.per_type]):
            inst = asset.objects_of(str(cat))
            subtasks.append(GoatSubtask(f"{stem}_object_{n:03d}", scene_id, "object", str(cat), None, None,
                                        tuple(o.id for o in inst), np.stack([o.center for o in inst])))

        # Image queries: distinct observable instances.
        order = rng.permutation(len(observable))
        for n, k in enumerate(order[:config.per_type]):
            obj = observable[int(k)]
            _, _, rgb, ids = views[obj.id]
            name = f"{stem}_image_{n:03d}"
            rgb_file, ids_file = f"images/{name}.png", f"images/{name}_ids.png"
            cv2.imwrite(str(out_dir / rgb_file), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
            cv2.imwrite(str(out_dir / ids_file), (ids.astype(np.int64) + 1).astype(np.uint16))
            subtasks.append(GoatSubtask(name, scene_id, "image", None, rgb_file, ids_file, (obj.id,),
                                        obj.center[None]))

        # Language queries: observable instances with an unambiguous description.
        n = 0
        for k in rng.permutation(len(observable)):
            if n >= config.per_type:
                break
            obj = observable[int(k)]
            desc = describe_with_room(obj, asset.objects)
            if desc is None:
                continue
            subtasks.append(GoatSubtask(f"{stem}_language_{n:03d}", scene_id, "language", desc.text(), None, None,
                                        (obj.id,), obj.center[None]))
            n += 1

    path = out_dir / f"{split}.json.gz"
    info = {"split": split, "split_version": SPLIT_VERSION, "seed": seed, "per_type": config.per_type,
            "scenes": scene_ids,
            "counts": {t: sum(s.type == t for s in subtasks) for t in ("object", "image", "language")}}
    text = json.dumps({"info": info, "subtasks": [s.to_json() for s in subtasks]}, indent=1)
    with open(path, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", mtime=0) as f:  # mtime=0: reproducible bytes
        f.write(text.encode())
    return path
