"""Perception for the ObjectNav agents: the memory agent's localiser and the frontier agent's detector.

Both use the same backend stack (:data:`navbench.localize.benchmark.PERCEPTION`: ``oracle`` over the
renderer's instance ids, or the real SigLIP2 + Qwen2.5-VL + SAM 3 models from local directories), so
the two agents are compared with identical perception. The query is the episode's goal text exactly
as the split names it (a synonym or an unseen category name), never a hidden category id. Outside the
bundled houses (annotated in navbench's own vocabulary), oracle perception is told which instances
that text names from the episode's own goals (:func:`~navbench.localize.backends.oracle.teach`), so an
open-vocabulary name is grounded as the dataset grounds it; real models ignore this.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from navbench.env.base import resolve_scene_path
from navbench.env.config import EnvConfig
from navbench.env.sensors import depth_metres
from navbench.episodes.types import Episode
from navbench.localize.backends.oracle import noise_profile, teach
from navbench.localize.benchmark import PERCEPTION, ModelDirs
from navbench.localize.describe import parse
from navbench.localize.fusion import GoalCandidate
from navbench.localize.geometry import GeometryConfig, backproject, keep_view
from navbench.localize.pipeline import Localizer, LocalizerConfig, Perception, Query, modality, query_prompt
from navbench.localize.route import KeyframeRoutes
from navbench.memory.prescan import Memory, PrescanConfig, load_or_build_memory
from navbench.paths import SCENES_DIR
from navbench.render.camera import CameraConfig, camera_pose, intrinsics
from navbench.scene.asset import load_scene, semantic_path
from navbench.scene.cache import layers_for, scene_digest
from navbench.scene.layers import LayeredNav
from navbench.scene.navigability import NavGridConfig
from navbench.scene.pose import quat_from_yaw


@dataclass(frozen=True)
class PerceptionConfig:
    perception: str = "oracle"
    noise: str = "none"
    fusion: bool = True
    rerank: bool = True
    prescan: PrescanConfig = PrescanConfig()
    memory_root: str | None = None  # default: the user cache (~/.cache/navbench/memory)
    models: ModelDirs = field(default_factory=ModelDirs)


# The perception stacks and memories of the scenes a process used last, shared by the agents of its env
# slots (models and keyframes are loaded once per process, not once per slot).
_SHARED: OrderedDict[tuple, Any] = OrderedDict()
_SHARED_SCENES = 4


def _shared(key: tuple, build: Callable[[], Any]) -> Any:
    if key in _SHARED:
        _SHARED.move_to_end(key)
        return _SHARED[key]
    value = _SHARED[key] = build()
    while len(_SHARED) > 3 * _SHARED_SCENES:  # a stack, a memory and (for goal images) the scene per scene
        _SHARED.popitem(last=False)
    return value


def _stack(scene_path: Path, cfg: PerceptionConfig) -> Perception:
    if cfg.perception not in PERCEPTION:
        raise ValueError(f"unknown perception {cfg.perception!r} (choose from {', '.join(PERCEPTION)})")
    return _shared(("stack", scene_path, cfg), lambda: PERCEPTION[cfg.perception](
        load_scene(scene_path), noise_profile(cfg.noise), cfg.models))


def _scene(scene_path: Path) -> Any:
    return _shared(("scene", scene_path), lambda: load_scene(scene_path))


def scene_memory(scene_path: Path, cfg: PerceptionConfig) -> Memory:
    """Build (or reuse from the cache) the keyframe memory of a scene for this perception config."""
    return load_or_build_memory(scene_path, cfg.memory_root, cfg.prescan, _stack(scene_path, cfg).encoder)


def _memory(scene_path: Path, cfg: PerceptionConfig) -> Memory:
    return _shared(("memory", scene_path, cfg), lambda: scene_memory(scene_path, cfg))


def is_bundled(scene_path: str | Path, scene_id: str) -> bool:
    """Whether ``scene_path`` (the mesh episode ``scene_id`` names) is one of navbench's bundled houses: a
    file under :data:`~navbench.paths.SCENES_DIR`, or a copy of the one ``scene_id`` names there (the
    same mesh and annotation bytes), as a Ray actor runs on. Where the file lies must not decide it: the
    grounding it selects changes the candidates, so a copy would localise differently from the original."""
    scene_path = Path(scene_path)
    if SCENES_DIR.resolve() in scene_path.resolve().parents:
        return True
    if Path(scene_id).is_absolute():
        return False
    twin = SCENES_DIR / scene_id
    if not twin.is_file() or scene_digest(twin) != scene_digest(scene_path):
        return False
    mine, theirs = semantic_path(scene_path), semantic_path(twin)
    if mine.is_file() != theirs.is_file():
        return False
    return not mine.is_file() or mine.read_bytes() == theirs.read_bytes()


def _teach_goals(stack: Perception, episode: Episode, scene_path: Path, name: str | None = None,
                 positions: Sequence[Sequence[float]] | None = None) -> None:
    """The episode's goals say which instances its goal name (``name``: the localiser's prompt; by default the
    episode's category) means, except in the bundled houses (see :func:`is_bundled`), which are annotated in
    navbench's own vocabulary: there that vocabulary grounds every name it knows."""
    name = episode.object_category if name is None else name
    if not name:
        return
    if not is_bundled(scene_path, episode.scene_id) or parse(name) is None:
        teach(stack, name, [g.position for g in episode.goals] if positions is None else positions)


def goal_query(episode: Episode, subtask: int = 0, asset: Callable[[], Any] | None = None,
               platform: str = "auto") -> tuple[Query, list[list[float]] | None]:
    """The localiser's :class:`Query` for the goal an agent is given, and the positions of the instances it
    names (for :func:`_teach_goals`; None: the episode's goals). ObjectNav: the category text. InstanceImageNav:
    the goal image (``instance_imagegoal``). GOAT-Bench's ``subtask``: its category (object), its description
    text (description) or its goal image (image). A goal image is rendered in the scene ``asset()`` gives, at
    the file's camera, with its instance ids, which only oracle perception reads (as it reads the keyframes')."""
    from navbench.episodes.goat import MAX_DESCRIPTION_WORDS, GoatEpisode
    from navbench.episodes.instance_imagenav import InstanceImageEpisode
    from navbench.render.goal_images import render_image_goal_ids

    if isinstance(episode, GoatEpisode):
        task = episode.tasks[subtask]
        kept = [k for k, t in enumerate(episode.tasks)  # the subtasks the reader kept goals for
                if t.type != "description" or len((episode.descriptions[k] or "").split(" ")) <= MAX_DESCRIPTION_WORDS]
        goals = episode.subtask_goals[kept.index(subtask)] if subtask in kept else []
        positions = [list(g.position) for g in goals]
        if task.type == "object":
            return Query("object", text=task.category), positions
        if task.type == "description":
            return Query("language", text=episode.descriptions[subtask]), positions
        camera = episode.image_goals[subtask]
    elif isinstance(episode, InstanceImageEpisode):
        camera, positions = episode.image_goal, None
    else:
        return Query("object", text=episode.object_category), None
    if asset is None:
        raise ValueError(f"episode {episode.episode_id}: an image goal needs its scene to render the image in")
    rgb, ids = render_image_goal_ids(asset(), camera, platform)
    return Query("image", image=rgb, image_ids=ids), positions


class SceneLocalizer:
    """``episode -> goal candidates`` over the episode scene's cached keyframe memory."""

    def __init__(self, scene_dir: str | Path, cfg: PerceptionConfig = PerceptionConfig(),
                 camera: EnvConfig | None = None):
        self.scene_dir, self.cfg = Path(scene_dir), cfg
        self.camera = camera  # the episode's RGB sensor: ImageNav's goal image is taken with it
        self._path: Path | None = None
        self.last: dict[str, Any] = {}
        self.prompt = ""

    def __call__(self, episode: Episode, subtask: int = 0) -> list[GoalCandidate]:
        """Candidates for the episode's goal (:func:`goal_query`; a GOAT-Bench episode's ``subtask``), from the
        scene's memory, built once and kept for every episode and subtask in the scene."""
        path = resolve_scene_path(episode.scene_id, self.scene_dir)
        if path != self._path:
            stack = _stack(path, self.cfg)
            self.memory = _memory(path, self.cfg)
            self._localizer = Localizer.from_perception(
                self.memory, stack, LocalizerConfig(rerank=self.cfg.rerank, fusion=self.cfg.fusion))
            self.routes = KeyframeRoutes(self.memory.store, self.memory.config.camera_height)
            self._path = path
        query, positions = goal_query(episode, subtask, lambda: _scene(path))
        self.prompt = self._localizer.prompt(query)  # what the detector then checks targets for
        _teach_goals(_stack(path, self.cfg), episode, path, self.prompt, positions)
        t0 = time.perf_counter()
        candidates = self._localizer.localize(query)
        st = self.memory.stats
        self.last = {"query_ms": round(1000 * (time.perf_counter() - t0), 2), "memory_keyframes": st.keyframes,
                     "memory_frames": st.frames, "memory_bytes": st.bytes,
                     "memory_build_s": round(st.build_seconds, 3)}
        return candidates

    def image_goal(self, episode: Episode) -> Any:
        """Where an ImageNav episode's goal image was taken (a :class:`~navbench.localize.imagegoal.CameraEstimate`),
        from the scene's memory: the image is rendered as ``imagegoal`` is (the episode's RGB sensor at
        ``goals[0]``, facing :func:`~navbench.tasks.imagenav.goal_yaw`); oracle perception reads its instance ids
        and colours and searches the memory's labelled cloud for the pose, real models retrieve the keyframe nearest
        the image's embedding."""
        from navbench.episodes.instance_imagenav import ImageGoal
        from navbench.localize.imagegoal import estimate_camera, retrieved_camera
        from navbench.render.goal_images import render_image_goal_ids
        from navbench.tasks.imagenav import goal_rotation

        c = self.camera or EnvConfig()
        path = resolve_scene_path(episode.scene_id, self.scene_dir)
        stack, memory = _stack(path, self.cfg), _memory(path, self.cfg)
        self.memory, self._path = memory, None  # the next object query rebuilds its localiser
        eye = np.asarray(episode.goals[0].position, np.float64) + [0.0, c.agent_height, 0.0]
        goal = ImageGoal(tuple(eye), tuple(goal_rotation(episode.episode_id)), c.hfov_deg, c.height, c.width)
        rgb, ids = render_image_goal_ids(_scene(path), goal)
        t0 = time.perf_counter()
        if modality(stack.encoder) == "instance_ids":
            estimate = estimate_camera(memory, ids, c.hfov_deg, rgb)
        else:
            estimate = retrieved_camera(memory, stack.encoder.encode_images([rgb])[0])
        self.last = {"query_ms": round(1000 * (time.perf_counter() - t0), 2),
                     "memory_keyframes": memory.stats.keyframes}
        return estimate

    def refine_image_goal(self, estimate: Any, points: np.ndarray, ids: np.ndarray, colours: np.ndarray,
                          position: np.ndarray, yaw: float) -> Any:
        """The goal camera of ``estimate`` (from :meth:`image_goal`, oracle perception) searched for again round
        ``position`` (camera height) and ``yaw`` over the agent's live views there (``points`` with their instance
        ``ids`` and ``colours``) joined to the memory's cloud, on the floor the memory shows free
        (:func:`~navbench.localize.imagegoal.refine_camera`)."""
        from navbench.localize.imagegoal import ImageGoalConfig, memory_cloud, refine_camera

        config = ImageGoalConfig()
        cloud = memory_cloud(self.memory, config.stride)
        mp, mi, mc = cloud.voxels(config.stages[-1][2])
        near = np.hypot(mp[:, 0] - position[0], mp[:, 2] - position[2]) < config.radius
        free = cloud.free(float(position[1]) - cloud.camera_height, config)
        return refine_camera(np.concatenate([points, mp[near]]), np.concatenate([ids, mi[near]]),
                             np.concatenate([colours, mc[near]]), estimate.goal, position, yaw, free, config)

    def surfaces(self, config: NavGridConfig) -> LayeredNav | None:
        """The joined walkable surfaces (storeys, stairs, ramps) of the scene last localised in when its
        memory's keyframes stand on more than one storey (their camera heights differ by more than a step);
        None for a memory of one storey, where the agent moves and routes on one floor."""
        if not len(self.memory.store) or float(np.ptp(self.memory.store.positions()[:, 1])) <= config.max_climb:
            return None
        path = self._path
        return _shared(("surfaces", path, config), lambda: layers_for(load_scene(path), config))

    def route_lengths(self, position: np.ndarray, candidates: Sequence[GoalCandidate]) -> np.ndarray:
        """Route lengths (m) from ``position`` to ``candidates`` over the memory of the scene last
        localised in (:class:`~navbench.localize.route.KeyframeRoutes`); ``inf`` where there is none."""
        return self.routes.lengths(position, candidates)

    def route_path(self, position: np.ndarray, candidate: GoalCandidate) -> np.ndarray:
        """The keyframe positions (K, 3) along the shortest route from ``position`` to ``candidate`` over
        the same memory (:meth:`~navbench.localize.route.KeyframeRoutes.path`); (0, 3) where there is none."""
        return self.routes.path(position, candidate)


class LiveDetector:
    """``detect(observations, (position, yaw)) -> (N, 3)`` world points of the goal in the current frame,
    segmented with the perception stack's segmenter and backprojected with the depth sensor."""

    def __init__(self, scene_dir: str | Path, cfg: PerceptionConfig = PerceptionConfig(),
                 env_config: EnvConfig = EnvConfig()):
        self.scene_dir, self.cfg, self.env_config = Path(scene_dir), cfg, env_config
        self.K = intrinsics(CameraConfig(width=env_config.width, height=env_config.height,
                                         hfov_deg=env_config.hfov_deg))
        self._path: Path | None = None
        self.query = ""

    @property
    def sensors(self) -> tuple[str, ...]:
        """The image the segmenter reads: the renderer's instance ids for the oracle, else RGB."""
        return ("semantic",) if self.cfg.perception == "oracle" else ("rgb",)

    def reset(self, episode: Episode, query: str | None = None, subtask: int = 0) -> None:
        """Detect the episode's goal: its category, an InstanceImageNav episode's goal image or a GOAT-Bench
        episode's ``subtask`` (its category, description or image; an image as its caption, as the localiser
        prompts with it), or ``query`` (the localiser's prompt, taught by :class:`SceneLocalizer`)."""
        from navbench.episodes.goat import GoatEpisode
        from navbench.episodes.instance_imagenav import InstanceImageEpisode

        path = resolve_scene_path(episode.scene_id, self.scene_dir)
        stack = _stack(path, self.cfg)
        if path != self._path:
            self.segmenter = stack.segmenter
            self._path = path
        if query is None and isinstance(episode, (InstanceImageEpisode, GoatEpisode)):
            goal, positions = goal_query(episode, subtask, lambda: _scene(path))
            query = query_prompt(goal, stack.captioner)
            _teach_goals(stack, episode, path, query, positions)
        elif query is None:
            _teach_goals(stack, episode, path)
        self.query = (episode.object_category or "") if query is None else query

    def __call__(self, observations: dict[str, np.ndarray], pose: tuple[np.ndarray, float]) -> np.ndarray:
        c = self.env_config
        image = observations["semantic"][..., 0] if modality(self.segmenter) == "instance_ids" else observations["rgb"]
        mask, _ = self.segmenter.segment(image, self.query)
        if mask is None or not mask.any():
            return np.zeros((0, 3))
        raw = observations["depth"][..., 0]
        depth = depth_metres(observations["depth"], c.min_depth, c.max_depth, c.normalize_depth)
        depth = np.where(raw > 0, depth, 0.0)  # 0 = nothing measured (too near or nothing hit)
        if not keep_view(depth, mask, GeometryConfig()):
            return np.zeros((0, 3))
        position, yaw = pose
        cam = camera_pose(position + np.array([0.0, c.agent_height, 0.0]), quat_from_yaw(yaw))
        return backproject(depth, mask, self.K, cam, min_depth=c.min_depth, max_depth=c.max_depth)
