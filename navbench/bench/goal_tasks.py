"""``navbench bench``'s goal-image tasks: ImageNav, InstanceImageNav and GOAT-Bench beside PointNav, on the
bench's scene with its RGB-D 224x224 config.

ImageNav reads the same PointNav episodes the other figures use (its goal image is the RGB sensor at the goal
point). The InstanceImageNav and GOAT-Bench files are written in the layouts their readers take
(:mod:`navbench.episodes.instance_imagenav`, :mod:`navbench.episodes.goat`): goals at sampled navigable
points, each with view points around it and one goal camera, 512 x 512 at 79° hfov, 1.25 m above the goal
point, pitched 15° down. Every GOAT episode opens with an image subtask, so its steps carry a goal image.

Per task (``T`` = ``pointnav``, ``imagenav``, ``instance_imagenav``, ``goat``):

* ``T_steps_per_s``: env.step of random moves, the four envs stepped in turns (short slices, so a change
  in machine load falls on all of them alike); PointNav's is the baseline the others compare with.
* ``T_goal_obs_us``: what the goal observations cost a step, timed inside those steps (median, so the
  renders at an episode's or image subtask's start, reported below, are left out): a per-episode goal
  image is copied out of the env, GOAT's text and image are looked up for the active subtask.
* ``T_reset_ms``: env.reset to another episode in the same scene (median), the goal image included.
* ``goat_measures_ms_at_5000``: GOAT's measures read on the last step of a 5000-step episode (GOAT-Bench's step
  limit; median): they are kept up to date step by step, so this is the same at every step, as the other
  tasks' measures are.
* ``T_goal_image_ms``: rendering one goal image (median): once per episode for ImageNav and InstanceImageNav
  (with the env's RGB camera, and with a renderer of the file's camera made for it), once per image subtask
  for GOAT.
"""

from __future__ import annotations

import gzip
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from navbench.env.base import NavEnv
from navbench.env.config import EnvConfig
from navbench.env.make import task_env
from navbench.episodes.types import EpisodeDataset
from navbench.render.goal_images import GoalImageCache
from navbench.scene.navigability import NavGrid
from navbench.scene.pose import quat_from_yaw

TASKS = ("pointnav", "imagenav", "instance_imagenav", "goat")
GOAL_IMAGE = {"hfov": 79.0, "image_dimensions": [512, 512], "height": 1.25, "pitch_deg": -15.0}
# GOAT subtasks of every episode: (type, goal index, image index); an image subtask first and one more later
GOAT_TASKS = (("image", 0, 0), ("object", 1, None), ("description", 2, None), ("image", 3, 0), ("object", 0, None))


def _camera_rotation(yaw: float, pitch_deg: float) -> list[float]:
    """[x, y, z, w] of a camera turned by ``yaw`` about +y, then pitched about its own x axis."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(math.radians(pitch_deg) / 2), math.sin(math.radians(pitch_deg) / 2)
    return [cy * sp, sy * cp, -sy * sp, cy * cp]


def _goal(grid: NavGrid, rng: np.random.Generator, k: int) -> dict:
    """One goal instance as both files write it: a navigable point, view points around it, one goal camera."""
    p = grid.sample_navigable_point(rng)
    ring = [p + 0.5 * np.array([math.cos(a), 0.0, math.sin(a)]) for a in np.linspace(0, 2 * math.pi, 8, endpoint=False)]
    facing = [quat_from_yaw(math.atan2(q[0] - p[0], q[2] - p[2])) for q in ring]
    view_points = [{"agent_state": {"position": [float(v) for v in q], "rotation": [float(v) for v in r]}, "iou": 0.5}
                   for q, r in zip([p, *ring], [quat_from_yaw(0.0), *facing]) if grid.is_navigable(q)]
    camera = {"position": [float(p[0]), float(p[1] + GOAL_IMAGE["height"]), float(p[2])],
              "rotation": _camera_rotation(float(rng.uniform(0, 2 * math.pi)), GOAL_IMAGE["pitch_deg"]),
              "hfov": GOAL_IMAGE["hfov"], "image_dimensions": GOAL_IMAGE["image_dimensions"],
              "frame_coverage": 0.3, "object_coverage": 0.9}
    return {"position": [float(v) for v in p], "object_id": k, "object_name": f"goal{k}_{k}",
            "object_category": f"goal{k}", "view_points": view_points, "image_goals": [camera]}


def _start(grid: NavGrid, rng: np.random.Generator) -> dict:
    return {"start_position": [float(v) for v in grid.sample_navigable_point(rng)],
            "start_rotation": [float(v) for v in quat_from_yaw(float(rng.uniform(0, 2 * math.pi)))], "info": {}}


def _write(path: Path, doc: dict) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(gzip.compress(json.dumps(doc).encode()))
    return path


def write_goal_task_files(scene: Path, grid: NavGrid, out: Path, episodes: int = 8, seed: int = 0) -> dict[str, Path]:
    """An InstanceImageNav split (``val/val.json.gz`` and ``val/content/{scene}.json.gz``) and a GOAT-Bench
    file (``val/val.json.gz``) of ``episodes`` episodes on ``scene`` (``scene_id``: its file name; read them
    with ``scene_dir=scene.parent``). Returns ``{"instance_imagenav": path, "goat": path}``."""
    rng = np.random.default_rng(seed)
    scene_id = scene.name
    goals = [_goal(grid, rng, k) for k in range(4)]
    stem = scene_id.removesuffix(".glb")
    iin_goals = {f"{stem}_{g['object_id']}": {**g, "object_surface_area": 1.0} for g in goals}
    iin_episodes = [{"episode_id": str(i), "scene_id": scene_id, **_start(grid, rng), "goals": [],
                     "object_category": goals[i % len(goals)]["object_category"],
                     "goal_object_id": str(goals[i % len(goals)]["object_id"]), "goal_image_id": 0}
                    for i in range(episodes)]
    iin = _write(out / "instance_imagenav" / "val" / "val.json.gz", {"episodes": []})
    _write(iin.parent / "content" / f"{stem}.json.gz", {"goals": iin_goals, "episodes": iin_episodes})
    goat_goals = {f"{scene_id}_{g['object_category']}": [{**g, "children_object_categories": [],
                                                           "lang_desc": f"the goal numbered {g['object_id']}"}]
                  for g in goals}
    tasks = [[goals[k]["object_category"], kind, goals[k]["object_id"], *([] if i is None else [i])]
             for kind, k, i in GOAT_TASKS]
    goat_episodes = [{"episode_id": str(i), "scene_id": scene_id, **_start(grid, rng), "goals": [], "tasks": tasks}
                     for i in range(episodes)]
    goat = _write(out / "goat" / "val" / "val.json.gz", {"episodes": goat_episodes, "goals": goat_goals})
    return {"instance_imagenav": iin, "goat": goat}


def _median_ms(fn, repeats: int) -> float:
    times = []
    for i in range(repeats):
        t0 = time.perf_counter()
        fn(i)
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e3)


def reset_ms(env: NavEnv, repeats: int) -> float:
    """env.reset to the next episode of the same scene (median of ``repeats``), its goal image included."""
    n = len(env.dataset.episodes)
    return _median_ms(lambda i: env.reset(options={"episode": (i + 1) % n}), repeats)


def goal_image_ms(env: NavEnv, repeats: int) -> float | None:
    """One goal image's render time (median of ``repeats``), as the env renders it; None for PointNav."""
    n = len(env.dataset.episodes)
    if env.task == "goat":
        cameras = [c for ep in env.dataset.episodes for c in ep.image_goals if c is not None]  # type: ignore[attr-defined]
        cache = GoalImageCache(env.config.gl_platform)
        return _median_ms(lambda i: cache.get(i, env.asset, cameras[i % len(cameras)]), repeats)
    images = [s for s in env.goal_sensors if s.per_episode and len(s.space(env.dataset, env.config).shape) == 3]
    if not images:
        return None
    times = []
    for i in range(repeats):
        env.reset(options={"episode": i % n})
        t0 = time.perf_counter()
        images[0].observe(env)
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e3)


def goat_measures_ms(env: NavEnv, steps: int, repeats: int) -> float:
    """GOAT's measures (``info``) read on the last step of a ``steps``-step episode, from the env's first state
    on (GoatProgress updates them as each step is recorded, in constant time; this is the read-out)."""
    from navbench.episodes.goat import GoatProgress

    live = env.goat_progress  # type: ignore[attr-defined]
    progress = GoatProgress(live.episode, steps + 1, live.success_distance)
    first = live.states[0]
    progress.load([first] + [(1, first[1], first[2])] * steps, 0, False)
    return _median_ms(lambda i: progress.metrics(), repeats)


def _timed_goal_observation(env: NavEnv) -> list[float]:
    """Time the env's goal observations from now on: returns the list of their durations, growing as it steps."""
    times: list[float] = []
    inner = env._goal_observation

    def timed() -> dict[str, np.ndarray]:
        t0 = time.perf_counter()
        try:
            return inner()
        finally:
            times.append(time.perf_counter() - t0)
    env._goal_observation = timed  # type: ignore[method-assign]  (NavEnv._observe calls it every step)
    return times


def random_steps(env: NavEnv, rng: np.random.Generator, seconds: float) -> tuple[int, float]:
    """Random moves (never STOP, so it measures steps rather than resets) for ``seconds``: (steps, elapsed).
    An episode that ends is reset."""
    steps, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        _, _, term, trunc, _ = env.step(int(rng.integers(1, 4)))
        steps += 1
        if term or trunc:
            env.reset()
    return steps, time.perf_counter() - t0


def make_task_envs(scene: Path, dataset: EpisodeDataset, config: EnvConfig, out: Path) -> dict[str, NavEnv]:
    """The four envs on ``scene``: PointNav and ImageNav over ``dataset`` (PointNav episodes with absolute
    scene paths), InstanceImageNav and GOAT over the files :func:`write_goal_task_files` writes under ``out``."""
    from navbench.scene.cache import load_scene_and_navgrid

    _, grid = load_scene_and_navgrid(scene)
    files = write_goal_task_files(scene, grid, out)
    envs = {name: task_env(name, dataset, scene_dir="/", config=config) for name in ("pointnav", "imagenav")}
    envs.update({name: task_env(name, files[name], scene_dir=scene.parent, config=config) for name in files})
    return envs


def goal_task_figures(scene: Path, dataset: EpisodeDataset, config: EnvConfig, seconds: float,
                      repeats: int = 8, slices: int = 6) -> dict[str, float]:
    """The module's figures (see its docstring) for the four tasks; ``seconds`` of stepping per task."""
    out: dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="navbench-bench-") as tmp:
        envs = make_task_envs(scene, dataset, config, Path(tmp))
        try:
            for name, env in envs.items():
                env.reset(seed=0, options={"episode": 0})  # the scene loaded, the renderer made
                out[f"{name}_reset_ms"] = reset_ms(env, repeats)
                ms = goal_image_ms(env, repeats)
                if ms is not None:
                    out[f"{name}_goal_image_ms"] = ms
                if name == "goat":
                    out["goat_measures_ms_at_5000"] = goat_measures_ms(env, 5000, 3)
            rngs = {name: np.random.default_rng(k) for k, name in enumerate(envs)}
            for name, env in envs.items():  # warm-up: first frames, shader programs
                for _ in range(20):
                    env.step(int(rngs[name].integers(1, 4)))
            totals = {name: [0, 0.0] for name in envs}
            goal_obs = {name: _timed_goal_observation(env) for name, env in envs.items()}
            for _ in range(slices):
                for name, env in envs.items():
                    steps, elapsed = random_steps(env, rngs[name], seconds / slices)
                    totals[name][0] += steps
                    totals[name][1] += elapsed
            out.update({f"{name}_steps_per_s": steps / elapsed for name, (steps, elapsed) in totals.items()})
            out.update({f"{name}_goal_obs_us": float(np.median(t) * 1e6) for name, t in goal_obs.items()})
        finally:
            for env in envs.values():
                env.close()
    return out
