"""``navbench bench``: simulator, geodesic and policy speed on a bundled scene.

    navbench bench            # human-readable
    navbench bench --json     # one JSON object (keys below), for scripts and the README table

Keys: ``rgbd_steps_per_s``, ``depth_steps_per_s``, ``rgbd_ids_steps_per_s`` (one process, env.step
with 224x224 sensors), ``rgbd_steps_per_s_2proc`` (total of two processes, one llvmpipe thread each),
``geodesic_cached_us`` (a geodesic query whose goal set's field is cached), ``geodesic_field_ms``
(building the field for a new goal set), ``scene_load_s`` (mesh load + navigability build, no cache),
``geodesic_field_ms_20x20m`` (the same on a 20 x 20 m floor with walls, 400 x 400 cells),
``peak_rss_mb``, and with the policy ``policy_steps_per_s_b1`` / ``policy_frames_per_s_b8``. With the
goal-image tasks (:mod:`navbench.bench.goal_tasks`): ``{pointnav,imagenav,instance_imagenav,goat}_steps_per_s``
(the four stepped in turns), ``..._goal_obs_us`` (the goal observations' cost per step), ``..._reset_ms`` and
``{imagenav,instance_imagenav,goat}_goal_image_ms`` (one goal image, made once per episode or image subtask),
``goat_measures_ms_at_5000`` (GOAT's measures late in a long episode: constant, kept up to date step by step). ``cpu``
names the processor (model, family, widest vector extension) and, with the policy, ``native_bf16``
says whether it has AVX512-BF16 or AMX: the figures depend strongly on the vector extensions, so a
number means little without the CPU it was measured on.
"""

from __future__ import annotations

import dataclasses
import os
import resource
import time
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from navbench.bench.goal_tasks import goal_task_figures, random_steps
from navbench.env.config import EnvConfig
from navbench.env.pointnav import PointNavEnv
from navbench.episodes.types import Episode, EpisodeDataset, NavigationGoal
from navbench.paths import SCENES_DIR
from navbench.scene.asset import load_scene
from navbench.scene.cache import load_scene_and_navgrid
from navbench.scene.navigability import NavGrid, NavGridConfig
from navbench.scene.pose import quat_from_yaw


def cpu_description(cpuinfo: str | None = None) -> str:
    """'<model name>, family <n>, <AVX-512|AVX2|...>' from /proc/cpuinfo (or the given text); 'unknown' elsewhere."""
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text()
        except OSError:
            return "unknown"
    fields: dict[str, str] = {}
    for line in cpuinfo.splitlines():
        key, sep, value = line.partition(":")
        if sep and key.strip() not in fields:  # the first processor's entry; the others repeat it
            fields[key.strip()] = value.strip()
    flags = set(fields.get("flags", "").split())
    widest = (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("avx", "AVX"), ("sse4_2", "SSE4.2"))
    vector = next((name for flag, name in widest if flag in flags), "no AVX")
    if "avx512_bf16" in flags or "amx_bf16" in flags:
        vector += " with BF16"
    model = fields.get("model name", "unknown")
    return f"{model}, family {fields['cpu family']}, {vector}" if "cpu family" in fields else f"{model}, {vector}"


@dataclass(frozen=True)
class BenchConfig:
    scene: str | None = None  # default: the first bundled val scene
    seconds: float = 3.0
    policy: bool = True
    tasks: bool = True  # the goal-image tasks' figures (navbench.bench.goal_tasks)
    device: str = "cpu"  # where the policy figures are measured (resolved: "cpu" or "cuda:N")


def default_scene() -> Path:
    scenes = sorted((SCENES_DIR / "houses" / "val").glob("*.glb"))
    if not scenes:
        raise FileNotFoundError(f"{SCENES_DIR / 'houses' / 'val'}: no bundled scenes")
    return scenes[0]


def _bench_dataset(scene: Path, grid: NavGrid, n: int = 20) -> EpisodeDataset:
    rng = np.random.default_rng(0)
    eps = []
    for i in range(n):
        s, g = grid.sample_navigable_point(rng), grid.sample_navigable_point(rng)
        eps.append(Episode(str(i), str(scene.resolve()), [float(v) for v in s],
                           [float(v) for v in quat_from_yaw(float(rng.uniform(0, 6.28)))],
                           goals=[NavigationGoal([float(v) for v in g])]))
    return EpisodeDataset(episodes=eps)


def _env(scene: Path, config: EnvConfig) -> PointNavEnv:
    _, grid = load_scene_and_navgrid(scene)
    env = PointNavEnv(_bench_dataset(scene, grid), scene_dir="/", config=config)
    env.reset(seed=0)
    return env


def _timed_steps(env: PointNavEnv, rng: np.random.Generator, seconds: float, barrier=None) -> float:
    """Steps/s of random moves (never STOP, so it measures steps rather than resets), after a warm-up
    (shader compile, first-frame allocation); with a barrier, timing starts when all processes are ready."""
    for _ in range(20):
        env.step(int(rng.integers(1, 4)))
    if barrier is not None:
        barrier.wait()
    steps, elapsed = random_steps(env, rng, seconds)
    env.close()
    return steps / elapsed


def env_steps_per_s(scene: Path, config: EnvConfig, seconds: float) -> float:
    return _timed_steps(_env(scene, config), np.random.default_rng(0), seconds)


def _proc_worker(scene: str, config: EnvConfig, seconds: float, barrier, queue) -> None:
    os.environ["LP_NUM_THREADS"] = "1"  # one llvmpipe thread per process: the processes share the cores
    queue.put(_timed_steps(_env(Path(scene), config), np.random.default_rng(os.getpid()), seconds, barrier))


def multiprocess_steps_per_s(scene: Path, config: EnvConfig, seconds: float, procs: int = 2) -> float:
    ctx = get_context("spawn")
    barrier, queue = ctx.Barrier(procs), ctx.Queue()
    ps = [ctx.Process(target=_proc_worker, args=(str(scene), config, seconds, barrier, queue)) for _ in range(procs)]
    for p in ps:
        p.start()
    rates = [queue.get(timeout=120 + seconds) for _ in ps]
    for p in ps:
        p.join()
    return float(sum(rates))


def geodesic_figures(grid: NavGrid, seconds: float) -> dict[str, float]:
    rng = np.random.default_rng(1)
    goal = grid.sample_navigable_point(rng)
    starts = [grid.sample_navigable_point(rng) for _ in range(256)]
    grid.geodesic_distance(starts[0], goal)  # build and cache the field
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < min(seconds, 1.0):
        for s in starts:
            grid.geodesic_distance(s, goal)
        n += len(starts)
    cached_us = (time.perf_counter() - t0) / n * 1e6
    times = []
    for _ in range(10):
        g = grid.sample_navigable_point(rng) + np.array([rng.uniform(-1e-3, 1e-3), 0, 0])  # a new goal set
        t0 = time.perf_counter()
        grid.distance_field(g)
        times.append(time.perf_counter() - t0)
    return {"geodesic_cached_us": cached_us, "geodesic_field_ms": float(np.median(times) * 1e3)}


def field_ms_20x20m(repeats: int = 5) -> float:
    """Field build time on a 20 x 20 m floor (400 x 400 cells) with interior walls: the target's size."""
    import trimesh
    parts = [trimesh.creation.box(extents=(20.0, 0.1, 20.0), transform=trimesh.transformations.translation_matrix(
        (0, -0.05, 0)))]
    for x in (-5.0, 0.0, 5.0):  # three walls with gaps, so the field has to bend around them
        at = trimesh.transformations.translation_matrix((x, 1.25, 3.0 if x == 0.0 else -3.0))
        parts.append(trimesh.creation.box(extents=(0.1, 2.5, 14.0), transform=at))
    grid = NavGrid.from_mesh(trimesh.util.concatenate(parts), NavGridConfig())
    rng = np.random.default_rng(2)
    times = []
    for _ in range(repeats):
        g = grid.sample_navigable_point(rng)
        t0 = time.perf_counter()
        grid.distance_field(g)
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e3)


def run_bench(cfg: BenchConfig = BenchConfig()) -> dict[str, float | str | bool]:
    scene = Path(cfg.scene) if cfg.scene else default_scene()
    t0 = time.perf_counter()
    asset = load_scene(scene)
    grid = NavGrid.from_mesh(asset.mesh, NavGridConfig())
    result: dict[str, float | str | bool] = {"scene": str(scene), "scene_triangles": int(len(asset.mesh.faces)),
                                             "scene_load_s": time.perf_counter() - t0, "cpu": cpu_description()}
    result["grid_shape"] = "x".join(map(str, grid.navigable.shape))
    result.update(geodesic_figures(grid, cfg.seconds))
    result["geodesic_field_ms_20x20m"] = field_ms_20x20m()
    rgbd = EnvConfig(rgb=True, depth=True)
    result["rgbd_steps_per_s"] = env_steps_per_s(scene, rgbd, cfg.seconds)
    result["depth_steps_per_s"] = env_steps_per_s(scene, dataclasses.replace(rgbd, rgb=False), cfg.seconds)
    result["rgbd_ids_steps_per_s"] = env_steps_per_s(scene, dataclasses.replace(rgbd, semantic=True), cfg.seconds)
    result["rgbd_steps_per_s_2proc"] = multiprocess_steps_per_s(scene, rgbd, cfg.seconds)
    result["scaling_2proc"] = result["rgbd_steps_per_s_2proc"] / result["rgbd_steps_per_s"]
    if cfg.tasks:
        result.update(goal_task_figures(scene, _bench_dataset(scene, grid), rgbd, cfg.seconds))
    if cfg.policy:
        from navbench.policy.precision import native_bf16
        from navbench.policy.speed import measure_policy_speed
        result.update(measure_policy_speed(seconds=cfg.seconds, device=cfg.device))
        result["native_bf16"] = native_bf16()
        result["policy_device"] = cfg.device
    result["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {k: round(v, 3) if isinstance(v, float) else v for k, v in result.items()}


TASK_NAMES = {"pointnav": "PointNav", "imagenav": "ImageNav", "instance_imagenav": "InstanceImageNav",
              "goat": "GOAT"}


def format_report(r: dict) -> str:
    lines = [f"scene: {r['scene']} ({r['scene_triangles']} triangles, grid {r['grid_shape']})", f"cpu: {r['cpu']}"]
    if r.get("policy_device", "cpu") != "cpu":
        lines.append(f"policy on: {r['policy_device']}")
    labels = {
        "rgbd_steps_per_s": "env steps/s, RGB-D 224x224",
        "depth_steps_per_s": "env steps/s, depth only",
        "rgbd_ids_steps_per_s": "env steps/s, RGB-D + instance ids",
        "rgbd_steps_per_s_2proc": "env steps/s, RGB-D, 2 processes (total)",
        "scaling_2proc": "2-process scaling (x)",
        **{f"{t}_steps_per_s": f"env steps/s, RGB-D, {name} (in turns)" for t, name in TASK_NAMES.items()},
        **{f"{t}_goal_obs_us": f"goal observations per step, {name} (us)" for t, name in TASK_NAMES.items()},
        **{f"{t}_reset_ms": f"reset, {name} (ms)" for t, name in TASK_NAMES.items()},
        **{f"{t}_goal_image_ms": f"goal image, {name} (ms, once per {per})" for t, name, per in (
            ("imagenav", "ImageNav", "episode"), ("instance_imagenav", "InstanceImageNav", "episode"),
            ("goat", "GOAT", "image subtask"))},
        "goat_measures_ms_at_5000": "GOAT measures per step, at step 5000 (ms)",
        "geodesic_cached_us": "geodesic query, cached field (us)",
        "geodesic_field_ms": "geodesic field for a new goal set (ms)",
        "geodesic_field_ms_20x20m": "geodesic field, 20x20 m floor at 5 cm (ms)",
        "scene_load_s": "scene load + navigability build (s)",
        "policy_steps_per_s_b1": "policy steps/s, batch 1",
        "policy_frames_per_s_b8": "policy frames/s, batch 8",
        "peak_rss_mb": "peak RSS (MB)",
    }
    return "\n".join(lines + labelled_figures(r, labels, 56))


def labelled_figures(r: dict, labels: dict[str, str], width: int) -> list[str]:
    """One line per figure of ``r`` that ``labels`` names, in the labels' order: the label, then the value."""
    return [f"{label:<{width}} {r[k]:>10.2f}" for k, label in labels.items() if k in r]
