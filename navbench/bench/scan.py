"""``navbench bench --scan DIR``: scan-scale speed figures, measured on the scan fixture.

    navbench bench --scan /tmp/navbench-scan          # makes the fixture there first if missing
    navbench bench --scan /tmp/navbench-scan --json

The fixture (:mod:`navbench.bench.scan_fixture`) is a bundled house made scan-like: two storeys,
about 800k triangles, a 4096² texture atlas. :func:`run_scan_bench` lists the keys.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import trimesh

from navbench.bench.scan_fixture import SCENE_DIR_NAME, SCENE_NAME, SPLIT, make_scan_fixture
from navbench.bench.speed import cpu_description, env_steps_per_s, labelled_figures


def agent_walk(grid, n: int, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """Camera poses of a random agent walk (0.25 m steps, 30 deg turns) at 0.88 m: how an episode moves."""
    from navbench.scene.pose import heading_vector, quat_from_yaw

    rng = np.random.default_rng(seed)
    pos, yaw, out = grid.sample_navigable_point(rng), float(rng.uniform(0, 2 * np.pi)), []
    while len(out) < n:
        a = int(rng.integers(1, 4))
        if a == 1:
            pos, _ = grid.try_step(pos, pos + 0.25 * heading_vector(yaw))
        else:
            yaw += math.radians(30.0) * (1 if a == 2 else -1)
        out.append((pos + np.array([0.0, 0.88, 0.0]), quat_from_yaw(yaw)))
    return out


def _plain_pyrender(glb: Path, poses, repeats: int) -> float:
    """Frames/s of the plain pyrender path of ``benchmarks/render_anchor.py`` (the scene merged into one node,
    FLAT RGB-D, one OffscreenRenderer, shader-cache fix), on the same poses."""
    import pyrender

    import navbench.render.pyrender_fixes  # noqa: F401  (binds OSMesa and applies the shader-cache fix)
    from navbench.render.camera import CameraConfig, camera_pose

    loaded = trimesh.load(str(glb), force="scene", process=False)
    merged = trimesh.util.concatenate([g for g in loaded.geometry.values()])
    scene = pyrender.Scene(bg_color=[0, 0, 0, 0], ambient_light=[0.6, 0.6, 0.6])
    scene.add(pyrender.Mesh.from_trimesh(merged, smooth=False))
    cam = CameraConfig()
    node = scene.add(pyrender.PerspectiveCamera(yfov=cam.yfov, znear=cam.znear, zfar=cam.zfar), pose=np.eye(4))
    r = pyrender.OffscreenRenderer(cam.width, cam.height)
    mats = [camera_pose(p, q) for p, q in poses]
    for m in mats[:10]:
        scene.set_pose(node, m)
        r.render(scene, pyrender.RenderFlags.FLAT)
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for m in mats:
            scene.set_pose(node, m)
            r.render(scene, pyrender.RenderFlags.FLAT)
        rates.append(len(mats) / (time.perf_counter() - t0))
    r.delete()
    return float(np.median(rates))


def _navbench_render(asset, poses, repeats: int) -> float:
    from navbench.render.renderer import Renderer

    rates = []
    with Renderer(asset) as r:
        for p, q in poses:  # first pass: warm-up, and the visibility sets of the cells the walk enters
            r.render(p, q)
        for _ in range(repeats):
            t0 = time.perf_counter()
            for p, q in poses:
                r.render(p, q)
            rates.append(len(poses) / (time.perf_counter() - t0))
    return float(np.median(rates))


def run_scan_bench(root: str | Path, seconds: float = 3.0, faces: int = 800_000,
                   texture_size: int = 4096) -> dict:
    """The scan-scale figures on the fixture under ``root`` (made there first if missing).

    Keys: ``fixture_build_s`` (only when it was made), ``scene_load_grid_s`` (mesh, textures,
    annotations and navigability grid, empty grid cache), ``scene_load_grid_cached_s`` (median of 3),
    ``renderer_init_s``, ``rgbd_steps_per_s`` / ``rgbd_ids_steps_per_s`` (one process, env.step with
    224x224 sensors), ``render_fps`` and ``plain_pyrender_fps`` (the same 300-pose walk, alternated, medians)
    and their ratio ``render_vs_plain``, ``memory_build_s`` (pre-scan memory with the oracle encoder).
    ``*_cpu_s`` give the process CPU time beside two wall times: on a shared machine it shows how
    much of a slow wall time was waiting for a core. ``load_avg_1min`` is read at the start and end.
    """
    import dataclasses
    import os
    import resource
    import tempfile

    from navbench.env.config import EnvConfig
    from navbench.localize.backends.oracle import NoiseProfile
    from navbench.localize.benchmark import PERCEPTION, ModelDirs
    from navbench.memory.prescan import PrescanConfig, build_memory
    from navbench.render.renderer import Renderer
    from navbench.scene.asset import load_scene
    from navbench.scene.cache import load_scene_and_navgrid

    root = Path(root)
    out: dict = {"cpu": cpu_description(), "load_avg_1min": round(os.getloadavg()[0], 2)}
    scene_dir = root / "scene_datasets" / "hm3d" / SPLIT / SCENE_DIR_NAME
    glb = scene_dir / f"{SCENE_NAME}.glb"
    if not glb.is_file():
        t0 = time.perf_counter()
        make_scan_fixture(root, faces=faces, texture_size=texture_size)
        out["fixture_build_s"] = time.perf_counter() - t0
    scene = scene_dir / f"{SCENE_NAME}.basis.glb"
    scene = scene if scene.is_file() else glb
    old_cache = os.environ.get("NAVBENCH_CACHE")
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["NAVBENCH_CACHE"] = tmp
        try:
            t0, c0 = time.perf_counter(), time.process_time()
            asset, grid = load_scene_and_navgrid(scene)
            out["scene_load_grid_s"] = time.perf_counter() - t0
            out["scene_load_grid_cpu_s"] = time.process_time() - c0
            cached = []
            for _ in range(3):
                t0 = time.perf_counter()
                load_scene_and_navgrid(scene)
                cached.append(time.perf_counter() - t0)
            out["scene_load_grid_cached_s"] = float(np.median(cached))
            texture = f"{asset.textures[0].shape[1]}x{asset.textures[0].shape[0]}" if asset.textures else "none"
            out.update(scene=str(scene), scene_triangles=int(len(asset.mesh.faces)), texture=texture,
                       objects=len(asset.objects), grid_shape="x".join(map(str, grid.navigable.shape)))
            t0 = time.perf_counter()
            Renderer(asset).close()
            out["renderer_init_s"] = time.perf_counter() - t0
            rgbd = EnvConfig(rgb=True, depth=True)
            out["rgbd_steps_per_s"] = env_steps_per_s(scene, rgbd, seconds)
            out["rgbd_ids_steps_per_s"] = env_steps_per_s(scene, dataclasses.replace(rgbd, semantic=True), seconds)
            poses = agent_walk(grid, 300)
            ours, plain = [], []
            for _ in range(3):  # alternate the two paths: the machine's load drifts
                ours.append(_navbench_render(asset, poses, 1))
                plain.append(_plain_pyrender(glb, poses, 1))
            out["render_fps"], out["plain_pyrender_fps"] = float(np.median(ours)), float(np.median(plain))
            out["render_vs_plain"] = out["render_fps"] / out["plain_pyrender_fps"]
            encoder = PERCEPTION["oracle"](load_scene(scene), NoiseProfile(), ModelDirs()).encoder
            t0, c0 = time.perf_counter(), time.process_time()
            st = build_memory(scene, Path(tmp) / "memory", PrescanConfig(), encoder)
            out["memory_build_s"] = time.perf_counter() - t0
            out["memory_build_cpu_s"] = time.process_time() - c0  # llvmpipe's threads included
            out["memory_keyframes"] = st.keyframes
        finally:
            if old_cache is None:
                os.environ.pop("NAVBENCH_CACHE", None)
            else:
                os.environ["NAVBENCH_CACHE"] = old_cache
    out["load_avg_1min_end"] = round(os.getloadavg()[0], 2)
    out["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {k: round(v, 3) if isinstance(v, float) else v for k, v in out.items()}


def format_scan_report(r: dict) -> str:
    lines = [f"scan fixture: {r['scene']} ({r['scene_triangles']} triangles, texture {r['texture']}, "
             f"{r['objects']} objects, grid {r['grid_shape']})", f"cpu: {r['cpu']}",
             f"load average (1 min) at start / end: {r['load_avg_1min']} / {r['load_avg_1min_end']}"]
    labels = {
        "fixture_build_s": "fixture build (s)",
        "scene_load_grid_s": "scene load + navigability grid, no cache (s)",
        "scene_load_grid_cpu_s": "  the same, process CPU time (s)",
        "scene_load_grid_cached_s": "scene load + navigability grid, cached (s)",
        "renderer_init_s": "renderer construction (s)",
        "rgbd_steps_per_s": "env steps/s, RGB-D 224x224",
        "rgbd_ids_steps_per_s": "env steps/s, RGB-D + instance ids",
        "render_fps": "RGB-D frames/s, navbench renderer (walk)",
        "plain_pyrender_fps": "RGB-D frames/s, plain pyrender (same walk)",
        "render_vs_plain": "navbench / plain pyrender (x)",
        "memory_build_s": "memory build, oracle encoder (s)",
        "memory_build_cpu_s": "  the same, process CPU time (s)",
        "peak_rss_mb": "peak RSS (MB)",
    }
    return "\n".join(lines + labelled_figures(r, labels, 46))
