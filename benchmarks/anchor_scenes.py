"""The render anchor's two scenes and 300 camera poses, built deterministically (seed 0).

``scene_simple.glb`` (1.2k triangles) and ``scene_dense.glb`` (205k): an 8 x 8 m footprint of three
rooms (y up, metres) with doorways and 20 vertex-coloured objects, boxes and cylinders (the dense
scene subdivides them). The poses walk one collision-free circle (radius 1.0 m, centre x = 1.4,
z = 5.7, at least 0.25 m from every object and wall footprint), heading along the tangent plus a
+-0.7 rad head turn, camera at 0.88 m; :func:`mats` gives them as 4x4 camera-to-world matrices in
the OpenGL/Habitat camera frame. ``benchmarks/render_anchor.py`` renders them with navbench and
with the plain pyrender path (``benchmarks/anchor_pyrender.py``).

    python benchmarks/anchor_scenes.py /tmp/sbs        # writes scene_simple.glb and scene_dense.glb
"""

from __future__ import annotations

import colorsys
import sys
from pathlib import Path

import numpy as np
import trimesh

SCENES = ("simple", "dense")
N = 300  # poses
CAMERA_HEIGHT = 0.88


def _coloured(mesh: trimesh.Trimesh, rgb) -> trimesh.Trimesh:
    c = np.array(list(rgb) + [255], dtype=np.uint8)
    mesh.visual = trimesh.visual.ColorVisuals(mesh, vertex_colors=np.tile(c, (len(mesh.vertices), 1)))
    return mesh


def _box(extents, centre) -> trimesh.Trimesh:
    m = trimesh.creation.box(extents=extents)
    m.apply_translation(centre)
    return m


def build(dense: bool = False, seed: int = 0, n_obj: int = 20) -> trimesh.Scene:
    """The three-room scene; ``dense`` subdivides the objects (205k triangles instead of 1.2k)."""
    rng = np.random.default_rng(seed)
    h, t = 2.5, 0.1  # wall height, thickness
    parts = {}
    parts["floor"] = _coloured(_box((8, 0.05, 8), (4, -0.025, 4)), (150, 150, 150))
    parts["ceiling"] = _coloured(_box((8, 0.05, 8), (4, h + 0.025, 4)), (230, 230, 230))
    walls = [_box((8, h, t), (4, h / 2, 0)), _box((8, h, t), (4, h / 2, 8)),  # outer walls
             _box((t, h, 8), (0, h / 2, 4)), _box((t, h, 8), (8, h / 2, 4))]
    for x0, x1 in [(0, 1.5), (2.5, 5.5), (6.5, 8)]:  # interior wall z = 4, doorways x in [1.5, 2.5], [5.5, 6.5]
        walls.append(_box((x1 - x0, h, t), ((x0 + x1) / 2, h / 2, 4)))
    for z0, z1 in [(4, 5.5), (6.5, 8)]:  # interior wall x = 4 for z in [4, 8], doorway z in [5.5, 6.5]
        walls.append(_box((t, h, z1 - z0), (4, h / 2, (z0 + z1) / 2)))
    parts["walls"] = _coloured(trimesh.util.concatenate(walls), (200, 180, 160))
    for i in range(n_obj):
        rgb = tuple(int(255 * v) for v in colorsys.hsv_to_rgb(i / n_obj, 0.8, 0.9))
        x, z = rng.uniform(0.6, 7.4, size=2)
        if i % 2 == 0:
            sx, sz = rng.uniform(0.4, 1.4, 2)
            sy = rng.uniform(0.4, 1.2)
            m = trimesh.creation.box(extents=(sx, sy, sz))
            if dense:  # 12 * 4**5 = 12288 triangles
                for _ in range(5):
                    m = m.subdivide()
        else:
            r = rng.uniform(0.15, 0.45)
            sy = rng.uniform(0.4, 1.2)
            m = trimesh.creation.cylinder(radius=r, height=sy, sections=(128 if dense else 24))
            m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
            if dense:  # 512 * 4**2 = 8192 triangles
                for _ in range(2):
                    m = m.subdivide()
        m.apply_translation((x, sy / 2 - m.bounds[0][1] - sy / 2, z))
        parts[f"obj{i:02d}"] = _coloured(m, rgb)
    scene = trimesh.Scene()
    for name, m in parts.items():
        scene.add_geometry(m, node_name=name, geom_name=name)
    return scene


def mats() -> np.ndarray:
    """(N, 4, 4) camera-to-world matrices of the walk (OpenGL camera frame, as Habitat's sensors)."""
    th = 2 * np.pi * np.arange(N) / N
    x, z = 1.4 + np.cos(th), 5.7 + np.sin(th)
    dx, dz = -np.sin(th), np.cos(th)  # walking direction (counter-clockwise)
    yaw = np.arctan2(-dx, -dz) + 0.7 * np.sin(3 * th)  # the camera looks along -z: R_y(yaw)(0, 0, -1)
    p = np.tile(np.eye(4), (N, 1, 1))
    c, s = np.cos(yaw), np.sin(yaw)
    p[:, 0, 0] = c
    p[:, 0, 2] = s
    p[:, 2, 0] = -s
    p[:, 2, 2] = c
    p[:, 0, 3] = x
    p[:, 1, 3] = CAMERA_HEIGHT
    p[:, 2, 3] = z
    return p


def scene_path(out_dir: str | Path, scene: str) -> Path:
    return Path(out_dir) / f"scene_{scene}.glb"


def write_scenes(out_dir: str | Path, scenes=SCENES) -> list[Path]:
    """Write the scenes not yet in ``out_dir``; returns the paths of all of them."""
    paths = []
    for scene in scenes:
        path = scene_path(out_dir, scene)
        if not path.is_file():
            path.parent.mkdir(parents=True, exist_ok=True)
            build(dense=scene == "dense").export(str(path))
        paths.append(path)
    return paths


if __name__ == "__main__":
    out = sys.argv[1] if len(sys.argv) > 1 else "."
    for p in write_scenes(out):
        loaded = trimesh.load(str(p), force="scene")
        print(p, "triangles:", sum(len(g.faces) for g in loaded.geometry.values()), "nodes:", len(loaded.geometry))
