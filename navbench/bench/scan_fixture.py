"""A scan-like HM3D fixture made from a bundled house, for the scan-scale speed figures and tests.

:func:`make_scan_fixture` writes, under ``root``, what a user's HM3D v0.2 download and HM3D
ObjectNav-v1 episodes look like::

    scene_datasets/hm3d/hm3d_annotated_basis.scene_dataset_config.json
    scene_datasets/hm3d/val/00999-nbScanHouse/nbScanHouse.glb            (JPEG texture atlas)
    scene_datasets/hm3d/val/00999-nbScanHouse/nbScanHouse.basis.glb      (the atlas as KTX2/ETC1S, optional)
    scene_datasets/hm3d/val/00999-nbScanHouse/nbScanHouse.semantic.glb   (object colours as vertex colours)
    scene_datasets/hm3d/val/00999-nbScanHouse/nbScanHouse.semantic.txt
    objectnav_hm3d_v1/val/val.json.gz + content/nbScanHouse.json.gz

The house is stacked into two storeys, subdivided to about ``faces`` triangles, every vertex moved
by isotropic noise, walls holed above head height, one room's ceiling removed, thin poles added on
the floor, and its colours moved into a texture atlas with per-texel detail a vertex colour cannot
hold. ``benchmarks/scan_fixture.py`` and ``navbench bench --scan`` (:mod:`navbench.bench.scan`) use it.
"""

from __future__ import annotations

import gzip
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from navbench.bench.glb_writer import write_glb
from navbench.paths import SCENES_DIR

SCENE_NAME = "nbScanHouse"
SCENE_DIR_NAME = f"00999-{SCENE_NAME}"
SPLIT = "val"
OBJECTNAV_CATEGORIES = ("chair", "bed", "plant", "toilet", "tv_monitor", "sofa")  # HM3D ObjectNav-v1's six
CONFIG_NAME = "hm3d_annotated_basis.scene_dataset_config.json"
# Raw names the fixture writes for some source categories, to exercise the category table.
RAW_NAMES = {"tv_monitor": "tv", "plant": "potted plant", "armchair": "armchair", "wardrobe": "wardrobe"}


@dataclass(frozen=True)
class ScanFixture:
    root: Path
    scene_datasets: Path
    glb: Path
    basis_glb: Path | None
    episodes: Path
    scene_id: str  # as the episodes name it, relative to scene_datasets/
    faces: int
    texture_size: int


def _storeys(source: Path):
    """The source house and a copy one storey up (object ids offset), as one mesh with per-face labels."""
    from navbench.scene.asset import load_scene

    a = load_scene(source)
    lo, hi = a.mesh.bounds
    lift = float(hi[1] - lo[1]) + 0.05
    offset = 1 + max(a.objects, default=0)
    v = np.concatenate([a.mesh.vertices, a.mesh.vertices + [0.0, lift, 0.0]])
    f = np.concatenate([a.mesh.faces, a.mesh.faces + len(a.mesh.vertices)])
    col = np.asarray(a.mesh.visual.vertex_colors, np.uint8)
    vc = np.concatenate([col, col])
    fid = np.concatenate([a.face_ids, np.where(a.face_ids >= 0, a.face_ids + offset, -1)])
    objects = dict(a.objects)
    for o in a.objects.values():
        objects[o.id + offset] = type(o)(o.id + offset, o.category, o.room, o.colour, o.colour_rgb,
                                         (o.aabb_min[0], o.aabb_min[1] + lift, o.aabb_min[2]),
                                         (o.aabb_max[0], o.aabb_max[1] + lift, o.aabb_max[2]))
    rooms = [(r.name, np.asarray(r.aabb_min), np.asarray(r.aabb_max), 0) for r in a.rooms]
    rooms += [(r.name, np.asarray(r.aabb_min) + [0, lift, 0], np.asarray(r.aabb_max) + [0, lift, 0], 1)
              for r in a.rooms]
    return v, f, vc, fid, objects, rooms, lift


def _subdivide(v, f, target: int):
    """Subdivide to about ``target`` faces; returns (vertices, faces, source face of each face)."""
    area = float(trimesh.triangles.area(v[f]).sum())
    edge = math.sqrt(4.0 * area / target)
    for _ in range(4):
        nv, nf, idx = trimesh.remesh.subdivide_to_size(v, f, edge, max_iter=14, return_index=True)
        if 0.85 * target <= len(nf) <= 1.15 * target:
            break
        edge *= math.sqrt(len(nf) / target)
    return nv, nf, idx


def _atlas(v, f, face_colour, face_chart_key, size: int, rng):
    """Per-corner UVs (OpenGL convention) and an RGB atlas: one planar chart per key, shelf-packed."""
    keys, chart = np.unique(face_chart_key, return_inverse=True)
    axis = (keys // 2) % 3  # key = ((label * 3 + axis) * 2 + sign); charts are projected along their axis
    tri = v[f]  # (F, 3, 3)
    planes = {0: (2, 1), 1: (0, 2), 2: (0, 1)}
    puv = np.zeros((len(f), 3, 2))
    for a, (i, j) in planes.items():
        sel = axis[chart] == a
        puv[sel] = tri[sel][:, :, [i, j]]
    lo = np.full((len(keys), 2), np.inf)
    hi = np.full((len(keys), 2), -np.inf)
    np.minimum.at(lo, chart, puv.min(axis=1))
    np.maximum.at(hi, chart, puv.max(axis=1))
    ext = np.maximum(hi - lo, 1e-3)
    pad = 2
    scale = math.sqrt(0.55 * size * size / float((ext[:, 0] * ext[:, 1]).sum()))
    while True:  # shelf packing, tallest first; shrink until everything fits
        wh = np.ceil(ext * scale).astype(int) + 2 * pad
        order = np.argsort(-wh[:, 1])
        origin = np.zeros((len(keys), 2), int)
        x = y = shelf = 0
        ok = True
        for k in order:
            w, h = wh[k]
            if w > size:
                ok = False
                break
            if x + w > size:
                x, y, shelf = 0, y + shelf, 0
            if y + h > size:
                ok = False
                break
            origin[k] = (x, y)
            x, shelf = x + w, max(shelf, h)
        if ok:
            break
        scale *= 0.92
    img = np.zeros((size, size, 3), np.float32)
    # Per-texel detail (a vertex colour cannot hold it): fine grain and a darker grid every 0.25 m.
    grain = rng.normal(0.0, 10.0, (size, size)).astype(np.float32)
    for k in range(len(keys)):
        x0, y0 = origin[k]
        w, h = wh[k]
        rows = (np.arange(h) - pad) / scale
        cols = (np.arange(w) - pad) / scale
        grid = ((np.abs(((rows[:, None] + 0.125) % 0.25) - 0.125) < 0.012) |
                (np.abs(((cols[None, :] + 0.125) % 0.25) - 0.125) < 0.012))
        base = face_colour[np.flatnonzero(chart == k)[0]].astype(np.float32)
        img[y0:y0 + h, x0:x0 + w] = base * np.where(grid, 0.8, 1.0)[..., None]
    img += grain[..., None]
    atlas = np.clip(img + 0.5, 0, 255).astype(np.uint8)
    # Atlas pixel (column, row from the top) -> OpenGL uv (v up).
    px = (puv - lo[chart][:, None, :]) * scale + origin[chart][:, None, :] + pad
    uv = np.stack([px[..., 0] / size, 1.0 - px[..., 1] / size], axis=-1)
    return uv, atlas, chart


def make_scan_fixture(root: str | Path, faces: int = 800_000, texture_size: int = 4096, seed: int = 0,
                      basis: bool = True, episodes: int = 12, source: Path | None = None) -> ScanFixture:
    """Write the scan-like HM3D fixture under ``root`` (see the module docstring); returns its paths."""
    from PIL import Image

    from navbench.scene.navigability import NavGrid

    root = Path(root)
    rng = np.random.default_rng(seed)
    source = source or SCENES_DIR / "houses" / "val" / "house_008.glb"
    v, f, vc, fid, objects, rooms, lift = _storeys(source)
    face_col = vc[f[:, 0], :3]

    # Thin clutter: poles (1.5 cm radius, 1 m tall) on open floor of the ground storey.
    grid = NavGrid.from_mesh(trimesh.Trimesh(v, f, process=False))
    open_floor = np.argwhere(grid.navigable & (grid.navigable_clearance() > 0.8))
    extra_v, extra_f, extra_c = [], [], []
    n0 = len(v)
    for cell in open_floor[rng.choice(len(open_floor), size=min(12, len(open_floor)), replace=False)]:
        p = grid.grid_to_world(cell)
        pole = trimesh.creation.cylinder(radius=0.015, height=1.0, sections=8)
        pole.apply_translation([p[0], grid.floor_height + 0.5, p[2]])
        extra_f.append(pole.faces + n0 + sum(len(e) for e in extra_v))
        extra_v.append(pole.vertices)
        extra_c.append(np.tile([90, 90, 95], (len(pole.faces), 1)))
    if extra_v:
        v = np.concatenate([v] + extra_v)
        f = np.concatenate([f] + extra_f)
        face_col = np.concatenate([face_col] + extra_c)
        fid = np.concatenate([fid, np.full(sum(len(e) for e in extra_f), -1, np.int32)])

    v, f, src = _subdivide(v, f, faces)
    fid, face_col = fid[src], face_col[src]
    # Isotropic noise per position, so coincident vertices move together and no cracks open.
    _, pos_key = np.unique(np.round(v * 1e4).astype(np.int64), axis=0, return_inverse=True)
    v = v + rng.normal(0.0, 0.004, (pos_key.max() + 1, 3))[pos_key.reshape(-1)]

    normals = trimesh.Trimesh(v, f, process=False).face_normals
    centre = v[f].mean(axis=1)
    keep = np.ones(len(f), bool)
    # Holes in walls above head height, where scans lose windows and mirrors.
    wall = (np.abs(normals[:, 1]) < 0.3) & (fid < 0)
    for c in centre[wall][rng.choice(int(wall.sum()), size=40, replace=False)]:
        r = rng.uniform(0.15, 0.35)
        y = c[1] - (lift if c[1] > lift else 0.0)
        if 1.3 <= y <= 2.2:
            keep &= np.linalg.norm(centre - c, axis=1) > r
    # An open ceiling: the top storey's first room has none.
    name, rlo, rhi, _ = next(r for r in rooms if r[3] == 1)
    inside = np.all((centre[:, [0, 2]] >= rlo[[0, 2]]) & (centre[:, [0, 2]] <= rhi[[0, 2]]), axis=1)
    keep &= ~(inside & (normals[:, 1] < -0.7) & (centre[:, 1] > rhi[1] - 0.3) & (fid < 0))
    f, fid, face_col, normals, centre = f[keep], fid[keep], face_col[keep], normals[keep], centre[keep]

    # Regions: the room whose box holds the face centre (storeys stacked in one list).
    region = np.full(len(f), -1, np.int64)
    for k, (_, rlo, rhi, _) in enumerate(rooms):
        inside = np.all((centre >= rlo - 0.05) & (centre <= rhi + 0.05), axis=1) & (region < 0)
        region[inside] = k
    region[region < 0] = 0
    # Semantic labels: objects keep theirs; structure becomes one wall/floor/ceiling object per region.
    kind = np.where(normals[:, 1] > 0.7, 0, np.where(normals[:, 1] < -0.7, 2, 1))
    sem = np.where(fid >= 0, fid, -1).astype(np.int64)
    next_id = 1 + max(objects, default=0)
    struct_keys, struct_inv = np.unique(region[fid < 0] * 3 + kind[fid < 0], return_inverse=True)
    sem[fid < 0] = next_id + struct_inv.reshape(-1)
    names = {}
    for oid, o in objects.items():
        names[oid] = RAW_NAMES.get(o.category, o.category.replace("_", " "))
    for k, key in enumerate(struct_keys):
        names[next_id + k] = ("floor", "wall", "ceiling")[int(key % 3)]
    obj_region = {}
    for oid in np.unique(sem):
        obj_region[int(oid)] = int(np.bincount(region[sem == oid]).argmax())
    palette = rng.permutation(np.arange(1, 1 << 24, 997))[: len(names)]
    colour_of = {oid: int(c) for oid, c in zip(sorted(names), palette)}

    # Texture atlas: one chart per (label, axis, sign).
    ax = np.argmax(np.abs(normals), axis=1)
    sign = (normals[np.arange(len(f)), ax] > 0).astype(np.int64)
    chart_key = ((sem - sem.min()) * 3 + ax) * 2 + sign
    uv_corner, atlas, _ = _atlas(v, f, face_col, chart_key, texture_size, rng)
    # Split vertices along chart seams: one vertex per (position, chart).
    corner_key = f.reshape(-1).astype(np.int64) * (int(chart_key.max()) + 1) + np.repeat(chart_key, 3)
    uniq, first, inv = np.unique(corner_key, return_index=True, return_inverse=True)
    tex_v = v[f.reshape(-1)[first]]
    tex_uv = uv_corner.reshape(-1, 2)[first]
    tex_f = inv.reshape(-1, 3)

    out = root / "scene_datasets" / "hm3d"
    scene_dir = out / SPLIT / SCENE_DIR_NAME
    scene_dir.mkdir(parents=True, exist_ok=True)
    jpeg = io.BytesIO()
    Image.fromarray(atlas).save(jpeg, format="JPEG", quality=92)
    glb = scene_dir / f"{SCENE_NAME}.glb"
    write_glb(glb, tex_v, tex_f, uv=tex_uv, image=jpeg.getvalue())
    basis_glb = None
    if basis:
        import alktx2

        rgba = np.dstack([atlas, np.full(atlas.shape[:2], 255, np.uint8)])
        ktx2 = alktx2.encode_raw_rgba_to_ktx2(rgba.tobytes(), texture_size, texture_size, has_alpha=False,
                                              codec="etc1s", quality=90, effort=2)
        basis_glb = scene_dir / f"{SCENE_NAME}.basis.glb"
        write_glb(basis_glb, tex_v, tex_f, uv=tex_uv, image=ktx2, mime="image/ktx2", basisu=True)

    # semantic.glb: the same triangles, each object's vertices in its colour (split per object).
    skey = f.reshape(-1).astype(np.int64) * (int(sem.max()) + 1) + np.repeat(sem, 3)
    suniq, sfirst, sinv = np.unique(skey, return_index=True, return_inverse=True)
    sem_obj = np.repeat(sem, 3)[sfirst]
    rgb = np.array([colour_of[int(o)] for o in sem_obj], np.int64)
    scol = np.stack([(rgb >> 16) & 255, (rgb >> 8) & 255, rgb & 255, np.full_like(rgb, 255)], 1).astype(np.uint8)
    write_glb(scene_dir / f"{SCENE_NAME}.semantic.glb", v[f.reshape(-1)[sfirst]], sinv.reshape(-1, 3), colours=scol)
    lines = ["HM3D Semantic Annotations"]
    for oid in sorted(names):
        if oid in obj_region:
            lines.append(f'{oid},{colour_of[oid]:06X},"{names[oid]}",{obj_region[oid]}')
    (scene_dir / f"{SCENE_NAME}.semantic.txt").write_text("\n".join(lines) + "\n")
    stage = {"requires_lighting": False,
             "semantic_asset": "%%CONFIG_NAME_AS_ASSET_FILENAME%%.semantic.glb",
             "semantic_descriptor_filename": "%%CONFIG_NAME_AS_ASSET_FILENAME%%.semantic.txt",
             "has_semantic_textures": False}
    (out / CONFIG_NAME).write_text(json.dumps({
        "stages": {"default_attributes": stage, "paths": {".glb": ["*/*/*.basis.glb"]}},
        "scene_instances": {"paths": {".json": []}}}, indent=2))

    mesh_path = basis_glb or glb
    scene_datasets = root / "scene_datasets"
    ep_path = _write_episodes(root, mesh_path, scene_datasets, episodes, rng)
    return ScanFixture(root=root, scene_datasets=scene_datasets, glb=glb, basis_glb=basis_glb, episodes=ep_path,
                       scene_id=mesh_path.relative_to(scene_datasets).as_posix(), faces=len(tex_f),
                       texture_size=texture_size)


def _write_episodes(root: Path, mesh_path: Path, scene_datasets: Path, n: int, rng) -> Path:
    """HM3D ObjectNav-v1 layout: an empty split file and the episodes in ``content/{scene}.json.gz``."""
    from navbench.episodes.generate import GeneratorConfig, SceneGoals, objectnav_episodes
    from navbench.episodes.io import dataset_to_json
    from navbench.episodes.types import EpisodeDataset

    sg = SceneGoals(mesh_path, scene_datasets)
    cats = sg.available(OBJECTNAV_CATEGORIES)
    eps, table = objectnav_episodes(sg, cats, n, rng, cfg=GeneratorConfig(min_geodesic=1.0, max_geodesic=12.0))
    config_ref = f"./data/scene_datasets/hm3d/{CONFIG_NAME}"
    for e in eps:
        e.extra["scene_dataset_config"] = config_ref
        e.extra["additional_obj_config_paths"] = []
    ds = EpisodeDataset(episodes=eps, goals_by_category=table,
                        category_to_task_category_id={c: i for i, c in enumerate(OBJECTNAV_CATEGORIES)},
                        category_to_scene_annotation_category_id={c: i for i, c in enumerate(OBJECTNAV_CATEGORIES)})
    split = root / "objectnav_hm3d_v1" / SPLIT
    (split / "content").mkdir(parents=True, exist_ok=True)
    (split / "content" / f"{SCENE_NAME}.json.gz").write_bytes(
        gzip.compress(json.dumps(dataset_to_json(ds)).encode(), mtime=0))
    path = split / f"{SPLIT}.json.gz"
    path.write_bytes(gzip.compress(json.dumps({"episodes": []}).encode(), mtime=0))
    return path
