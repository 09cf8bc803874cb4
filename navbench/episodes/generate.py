"""Seeded PointNav / ObjectNav episode generation on navbench scenes, and the bundled splits.

Regenerate everything in ``episodes/`` (deterministic for a seed)::

    navbench generate episodes            # = generate_bundled_splits(seed=0)

Episodes follow Habitat's generators: starts are navigable and on the goal's island; the geodesic
distance to the goal lies in [1, 20] m; episodes whose geodesic/euclidean ratio is below 1.1 are
rejected with probability 0.9 (Habitat keeps a few easy straight-line episodes the same way); start
headings are uniform. ObjectNav goals are every instance of the category in the scene, each with
its dense view points (:mod:`navbench.episodes.viewpoints`), and ``info.geodesic_distance`` is the
distance to the nearest view point.

Multi-storey scenes (``layered=True``) run on the scene's joined walkable surfaces
(:class:`~navbench.scene.layers.LayeredNav`): starts and PointNav goals are drawn uniformly over the
spans standing on any storey's floor that the env accepts as a start there (navigable on that storey's
grid), ``info.geodesic_distance`` is the layered 3-D geodesic (stairs and ramps included, as the env
measures a cross-storey episode) and ``euclidean_distance`` the 3-D straight line (Habitat's), and a
goal the start's surface does not reach has an infinite geodesic, so it is never drawn. ObjectNav view
points lie on their object's storey (:mod:`navbench.episodes.viewpoints`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from navbench.episodes.io import goals_key, save_dataset
from navbench.episodes.split_vocabulary import SYNONYMS, TRAIN_CATEGORIES, UNSEEN_CATEGORIES, categories_table
from navbench.episodes.types import AgentState, Episode, EpisodeDataset, NavigationGoal, ObjectGoal, ViewPoint
from navbench.episodes.viewpoints import ViewPointConfig, ViewPointFinder
from navbench.loop_progress import progress
from navbench.paths import EPISODES_DIR, SCENES_DIR
from navbench.scene.asset import SceneAsset
from navbench.scene.cache import load_scene_and_layers, load_scene_and_navgrid, navgrid_for
from navbench.scene.layers import LayeredNav
from navbench.scene.navigability import NavGrid, NavGridConfig
from navbench.scene.pose import quat_from_yaw, vector_length

# The version of the generated splits, written first in every file and recorded in run directories
# (provenance.json); it changes whenever the same seed draws other episodes (CHANGELOG, "Benchmark versions").
SPLIT_VERSION = 2


@dataclass(frozen=True)
class GeneratorConfig:
    min_geodesic: float = 1.0
    max_geodesic: float = 20.0
    min_ratio: float = 1.1
    low_ratio_reject_prob: float = 0.9
    max_tries: int = 2000  # per episode, before the scene is declared too small for the request


def _rel(scene_path: Path, scene_dir: Path) -> str:
    return scene_path.resolve().relative_to(scene_dir.resolve()).as_posix()


def _random_yaw_quat(rng: np.random.Generator) -> list[float]:
    return [float(v) for v in quat_from_yaw(float(rng.uniform(0, 2 * math.pi)))]


def _accept(rng: np.random.Generator, geo: float, euc: float, cfg: GeneratorConfig) -> bool:
    if not (cfg.min_geodesic <= geo <= cfg.max_geodesic):
        return False
    ratio = geo / max(euc, 1e-6)
    return ratio >= cfg.min_ratio or rng.random() > cfg.low_ratio_reject_prob


class StoreyPoints:
    """Start (and PointNav goal) points of a multi-storey scene: the :class:`LayeredNav` spans on a storey's
    floor that the env accepts as a start, each navigable on its storey's grid (the grid
    :func:`~navbench.scene.cache.navgrid_for` gives the env for a start at that height)."""

    def __init__(self, asset: SceneAsset, nav: LayeredNav):
        self.nav = nav
        spans = nav.storey_spans()
        keep = np.zeros(len(spans), bool)
        for floor in nav.storeys():
            on = np.abs(nav.height[spans] - floor) <= nav.config.max_climb / 2
            if not on.any():
                continue
            grid = navgrid_for(asset, nav.config, floor_hint=float(floor))
            xz = nav.xz(nav.cell[spans[on]])
            ij = grid.world_to_grid(np.column_stack([xz[:, 0], nav.height[spans[on]], xz[:, 1]]))
            inside = (ij >= 0).all(axis=1) & (ij[:, 0] < grid.shape[0]) & (ij[:, 1] < grid.shape[1])
            ok = np.zeros(len(ij), bool)
            ok[inside] = grid.navigable[ij[inside, 0], ij[inside, 1]]
            keep[on] = ok
        self.spans = spans[keep]
        if len(self.spans) == 0:
            raise RuntimeError(f"{asset.path}: no storey has a navigable start")

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        """A uniformly random start span's centre, on its surface."""
        return self.nav.position(int(self.spans[rng.integers(len(self.spans))]))


# ------------------------------------------------------------------------------------------- PointNav
def _pointnav_episode(episode_id: str, scene_id: str, start: np.ndarray, goal: np.ndarray, geo: float, euc: float,
                      rng: np.random.Generator) -> Episode:
    """The episode of an accepted (start, goal) draw; its heading is the next draw of ``rng``."""
    return Episode(
        episode_id=episode_id, scene_id=scene_id,
        start_position=[float(v) for v in start], start_rotation=_random_yaw_quat(rng),
        goals=[NavigationGoal(position=[float(v) for v in goal], radius=None)],
        info={"geodesic_distance": geo, "euclidean_distance": euc,
              "difficulty": "easy" if geo < 6 else "medium" if geo < 12 else "hard"},
    )


def pointnav_episodes(scene_path: Path, scene_dir: Path, n: int, rng: np.random.Generator,
                      cfg: GeneratorConfig = GeneratorConfig(), id_offset: int = 0,
                      layered: bool = False, grid_config: NavGridConfig = NavGridConfig()) -> list[Episode]:
    """``n`` PointNav episodes in one scene, for an agent of ``grid_config``'s body; ``layered`` for a
    multi-storey scene (module docstring)."""
    if layered:
        return _layered_pointnav_episodes(scene_path, scene_dir, n, rng, cfg, id_offset)
    _, grid = load_scene_and_navgrid(scene_path, grid_config)
    scene_id = _rel(scene_path, scene_dir)
    episodes: list[Episode] = []
    for k in range(n):
        for _ in range(cfg.max_tries):
            goal = grid.sample_navigable_point(rng)
            start = grid.sample_navigable_point(rng)
            geo = grid.geodesic_distance(start, goal)
            euc = vector_length((goal - start)[[0, 2]])
            if math.isfinite(geo) and _accept(rng, geo, euc, cfg):
                break
        else:
            raise RuntimeError(f"{scene_path}: no PointNav episode satisfies {cfg} after {cfg.max_tries} tries")
        episodes.append(_pointnav_episode(str(id_offset + k), scene_id, start, goal, geo, euc, rng))
    return episodes


def _layered_pointnav_episodes(scene_path: Path, scene_dir: Path, n: int, rng: np.random.Generator,
                               cfg: GeneratorConfig, id_offset: int) -> list[Episode]:
    asset, nav = load_scene_and_layers(scene_path)
    points = StoreyPoints(asset, nav)
    scene_id = _rel(scene_path, scene_dir)
    episodes: list[Episode] = []
    for k in range(n):
        for _ in range(cfg.max_tries):
            goal, start = points.sample(rng), points.sample(rng)
            if not nav.connected(start, goal):  # on storeys nothing joins: never drawn (and no field to build)
                continue
            geo = float(nav.distance_field(goal).distance(start))  # what the env measures
            euc = vector_length(goal - start)
            if math.isfinite(geo) and _accept(rng, geo, euc, cfg):
                break
        else:
            raise RuntimeError(f"{scene_path}: no PointNav episode satisfies {cfg} after {cfg.max_tries} tries")
        episodes.append(_pointnav_episode(str(id_offset + k), scene_id, start, goal, geo, euc, rng))
    return episodes


# ------------------------------------------------------------------------------------------ ObjectNav
class SceneGoals:
    """Per-scene ObjectNav goals: each category's instances with view points, computed once."""

    def __init__(self, scene_path: Path, scene_dir: Path, vp_config: ViewPointConfig = ViewPointConfig(),
                 layered: bool = False):
        self.layered = layered
        self.grid: NavGrid | LayeredNav
        if layered:  # a multi-storey scene (module docstring)
            self.asset, self.grid = load_scene_and_layers(scene_path)
            self._starts = StoreyPoints(self.asset, self.grid)
        else:
            self.asset, self.grid = load_scene_and_navgrid(scene_path)
        self.scene_id = _rel(scene_path, scene_dir)
        self._finder = ViewPointFinder(self.asset, self.grid, vp_config)
        self._cache: dict[str, list[ObjectGoal]] = {}

    def goals(self, category: str) -> list[ObjectGoal]:
        if category not in self._cache:
            out = []
            for obj in sorted(self.asset.objects_of(category), key=lambda o: o.id):
                pos, rot, frac = self._finder.find(obj)
                if len(pos) == 0:
                    continue  # never visible from the navigable area: not a valid goal
                out.append(ObjectGoal(
                    position=[float(v) for v in obj.center], object_id=obj.id, object_category=category,
                    object_name=f"{category}_{obj.id}", room_id=obj.room, room_name=obj.room,
                    view_points=[ViewPoint(AgentState([float(v) for v in p], [float(v) for v in q]), float(f))
                                 for p, q, f in zip(pos, rot, frac)],
                ))
            self._cache[category] = out
        return self._cache[category]

    def available(self, categories: tuple[str, ...]) -> list[str]:
        """Categories with at least one reachable goal instance on the main island."""
        return [c for c in categories if self.goals(c)]

    def sample_start(self, rng: np.random.Generator) -> np.ndarray:
        if self.layered:
            return self._starts.sample(rng)
        assert isinstance(self.grid, NavGrid)
        return self.grid.sample_navigable_point(rng)

    def draw_start(self, points: np.ndarray, rng: np.random.Generator, cfg: GeneratorConfig = GeneratorConfig(),
                   what: str = "episode") -> tuple[np.ndarray, float, float]:
        """(start, geodesic, euclidean) of a start the generator accepts for goals at ``points`` (view points):
        drawn until its geodesic to the nearest lies in range (:func:`_accept`); RuntimeError naming ``what``
        after ``cfg.max_tries``."""
        field = self.grid.distance_field(points)
        for _ in range(cfg.max_tries):
            start = self.sample_start(rng)
            geo = float(field.distance(start))
            euc = self.euclidean(start, points)
            if math.isfinite(geo) and _accept(rng, geo, euc, cfg):
                return start, geo, euc
        raise RuntimeError(f"{self.scene_id}: no {what} after {cfg.max_tries} tries")

    def euclidean(self, start: np.ndarray, points: np.ndarray) -> float:
        """Straight distance to the nearest of ``points``: in xz on one storey, in 3-D on several."""
        d = points - start if self.layered else (points - start)[:, [0, 2]]
        return float(np.min(np.linalg.norm(d, axis=1)))


def objectnav_episodes(sg: SceneGoals, categories: list[str], n: int, rng: np.random.Generator,
                       names: dict[str, str] | None = None, cfg: GeneratorConfig = GeneratorConfig(),
                       id_offset: int = 0) -> tuple[list[Episode], dict[str, list[ObjectGoal]]]:
    """``n`` episodes cycling over ``categories``; ``names`` renames categories (synonym splits)."""
    names = names or {}
    episodes: list[Episode] = []
    table: dict[str, list[ObjectGoal]] = {}
    order = list(categories)
    rng.shuffle(order)
    for k in range(n):
        cat = order[k % len(order)]
        name = names.get(cat, cat)
        goals = sg.goals(cat)
        vps = np.concatenate([g.view_point_positions() for g in goals])
        start, geo, euc = sg.draw_start(vps, rng, cfg, f"ObjectNav episode for '{cat}'")
        key = goals_key(sg.scene_id, name)
        if key not in table:
            table[key] = [ObjectGoal(position=g.position, object_id=g.object_id, object_category=name,
                                     object_name=g.object_name, room_id=g.room_id, room_name=g.room_name,
                                     view_points=g.view_points) for g in goals]
        closest = min(goals, key=lambda g: sg.grid.geodesic_distance(start, g.view_point_positions()))
        episodes.append(Episode(
            episode_id=str(id_offset + k), scene_id=sg.scene_id,
            start_position=[float(v) for v in start], start_rotation=_random_yaw_quat(rng),
            info={"geodesic_distance": geo, "euclidean_distance": euc, "closest_goal_object_id": closest.object_id},
            object_category=name,
        ))
    return episodes, table


# ------------------------------------------------------------------------------------- bundled splits
@dataclass(frozen=True)
class SplitPlan:
    pointnav_train_per_scene: int = 100
    pointnav_val_per_scene: int = 50
    objectnav_train_per_scene: int = 60
    objectnav_val_per_scene: int = 40
    imagenav_val_per_scene: int = 100  # 400 episodes over the 4 val houses: SR within about +-5 points


def scene_files(scene_dir: Path, split: str, dataset: str = "houses") -> list[Path]:
    files = sorted((scene_dir / dataset / split).glob("*.glb"))
    if not files:
        command = {"houses": "scenes", "houses_policy_select": "policy-select"}.get(dataset, "policy-train")
        raise FileNotFoundError(f"{scene_dir / dataset / split}: no scenes (run `navbench generate {command}`)")
    return files


def write_pointnav_split(out_dir: Path, split: str, scene_paths: list[Path], scene_dir: Path, per_scene: int,
                         rng: np.random.Generator, log=print, task: str = "pointnav") -> int:
    """``per_scene`` PointNav-v1 episodes in each scene, in order, to ``out_dir/{task}/{split}/{split}.json.gz``
    (ImageNav's splits are PointNav-v1 files too)."""
    eps: list[Episode] = []
    for path in scene_paths:
        eps += pointnav_episodes(path, scene_dir, per_scene, rng, id_offset=len(eps))
    ds = EpisodeDataset(episodes=eps, extra={"split_version": SPLIT_VERSION})
    save_dataset(ds, out_dir / task / split / f"{split}.json.gz")
    log(f"{task}/{split}: {len(eps)} episodes")
    return len(eps)


def write_imagenav_split(out_dir: Path = EPISODES_DIR, scene_dir: Path = SCENES_DIR, seed: int = 0,
                         per_scene: int = SplitPlan().imagenav_val_per_scene, log=print) -> int:
    """ImageNav ``val``: PointNav-v1 episodes in the val houses (Habitat's ImageNav reads PointNav's files), from
    a generator stream of its own, so the other splits are unchanged by it."""
    return write_pointnav_split(out_dir, "val", scene_files(scene_dir, "val"), scene_dir, per_scene,
                                np.random.default_rng([seed, 2, 0]), log, task="imagenav")


def objectnav_split(scenes: list[tuple[SceneGoals, int]], categories, synonyms: bool, rng: np.random.Generator,
                    split: str, desc: str) -> EpisodeDataset:
    """One ObjectNav split: ``n`` episodes for each ``(scene goals, n)`` over the ``categories`` each scene
    has a reachable instance of (goal names drawn from their synonyms when ``synonyms``); category ids in
    name order."""
    ds = EpisodeDataset(extra={"split_version": SPLIT_VERSION})
    for sg, n in progress(scenes, desc=desc):
        avail = sg.available(categories)
        if not avail:
            raise RuntimeError(f"{sg.scene_id}: none of the {split} categories has a reachable instance")
        names = {c: SYNONYMS[c][int(rng.integers(len(SYNONYMS[c])))] for c in avail} if synonyms else None
        eps, table = objectnav_episodes(sg, avail, n, rng, names=names, id_offset=len(ds.episodes))
        ds.episodes += eps
        ds.goals_by_category.update(table)
    used = sorted({e.object_category for e in ds.episodes})
    ds.category_to_task_category_id = {c: i for i, c in enumerate(used)}
    ds.category_to_scene_annotation_category_id = {c: i for i, c in enumerate(used)}
    return ds


def generate_bundled_splits(out_dir: Path = EPISODES_DIR, scene_dir: Path = SCENES_DIR, seed: int = 0,
                            plan: SplitPlan = SplitPlan(), log=print) -> dict[str, int]:
    """Write every bundled split; returns {"task/split": number of episodes}."""
    counts: dict[str, int] = {}
    for split, per_scene in (("train", plan.pointnav_train_per_scene), ("val", plan.pointnav_val_per_scene)):
        rng = np.random.default_rng([seed, 0, 0 if split == "train" else 1])
        counts[f"pointnav/{split}"] = write_pointnav_split(out_dir, split, scene_files(scene_dir, split), scene_dir,
                                                           per_scene, rng, log)

    scene_goals = {s: [SceneGoals(p, scene_dir) for p in scene_files(scene_dir, s)] for s in ("train", "val")}
    plans = {
        "train": ("train", TRAIN_CATEGORIES, False, plan.objectnav_train_per_scene),
        "val_seen": ("val", TRAIN_CATEGORIES, False, plan.objectnav_val_per_scene),
        "val_seen_synonyms": ("val", TRAIN_CATEGORIES, True, plan.objectnav_val_per_scene),
        "val_unseen": ("val", UNSEEN_CATEGORIES, False, plan.objectnav_val_per_scene),
    }
    for i, (split, (scenes, cats, synonyms, per_scene)) in enumerate(plans.items()):
        rng = np.random.default_rng([seed, 1, i])
        ds = objectnav_split([(sg, per_scene) for sg in scene_goals[scenes]], cats, synonyms, rng, split,
                             f"objectnav/{split}: scenes")
        save_dataset(ds, out_dir / "objectnav" / split / f"{split}.json.gz")
        counts[f"objectnav/{split}"] = len(ds.episodes)
        log(f"objectnav/{split}: {len(ds.episodes)} episodes over {len(ds.category_to_task_category_id)} categories")
    (out_dir / "objectnav" / "categories.json").write_text(json.dumps(categories_table(), indent=1) + "\n")
    counts["imagenav/val"] = write_imagenav_split(out_dir, scene_dir, seed, plan.imagenav_val_per_scene, log)
    return counts


def generate_policy_train_split(out_dir: Path = EPISODES_DIR, scene_dir: Path = SCENES_DIR, seed: int = 0,
                                per_scene: int = 100, log=print) -> int:
    """PointNav ``train_large``: the bundled train houses plus the policy's extra training houses
    (``envs/houses_policy_train``, :data:`navbench.scene.procedural.POLICY_TRAIN_HOUSES`), ``per_scene``
    episodes each. Its own generator stream, so the bundled splits are unchanged by it."""
    from navbench.scene.procedural import POLICY_TRAIN_HOUSES

    scenes = scene_files(scene_dir, "train") + scene_files(scene_dir, "train", POLICY_TRAIN_HOUSES["dir"])
    return write_pointnav_split(out_dir, "train_large", scenes, scene_dir, per_scene,
                                np.random.default_rng([seed, 0, 2]), log)


def generate_policy_select_split(out_dir: Path = EPISODES_DIR, scene_dir: Path = SCENES_DIR, seed: int = 0,
                                 per_scene: int = 25, log=print) -> int:
    """PointNav ``select``: ``per_scene`` episodes in each house of ``envs/houses_policy_select``
    (:data:`navbench.scene.procedural.POLICY_SELECT_HOUSES`), for choosing among trained policies
    without looking at ``val``. Its own generator stream, like ``train_large``."""
    from navbench.scene.procedural import POLICY_SELECT_HOUSES

    return write_pointnav_split(out_dir, "select", scene_files(scene_dir, "val", POLICY_SELECT_HOUSES["dir"]),
                                scene_dir, per_scene, np.random.default_rng([seed, 0, 3]), log)
