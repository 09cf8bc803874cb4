"""Procedural houses: determinism, floor-plan connectivity, annotation/geometry agreement, category library."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy import ndimage

from navbench.scene.asset import load_scene
from navbench.scene.procedural import HouseConfig, HouseConfigError, generate_dataset, generate_house, write_house
from navbench.scene.procedural.furnish import RECIPES
from navbench.scene.procedural.furniture import CATEGORIES, COLOURS, ROOM_TYPES, WALL_MOUNT_HEIGHT, paint

SEED = 7  # an 8-room corridor house in the default config
CELL = 0.05
AGENT_RADIUS = 0.18
BUNDLED = Path(__file__).resolve().parents[2] / "envs" / "houses"


@pytest.fixture(scope="module")
def house():
    return generate_house(SEED)


@pytest.fixture(scope="module")
def written(house, tmp_path_factory):
    return write_house(*house, tmp_path_factory.mktemp("houses"), "house_x")


def _node_meshes(scene: trimesh.Scene) -> dict[str, trimesh.Trimesh]:
    out = {}
    for node in scene.graph.nodes_geometry:
        transform, geom = scene.graph[node]
        mesh = scene.geometry[geom].copy()
        mesh.apply_transform(transform)
        out[str(node)] = mesh
    return out


def _top_down_heights(mesh: trimesh.Trimesh, lo: np.ndarray, hi: np.ndarray):
    """First surface below 1.5 m along a vertical ray through each raster cell centre.

    Rays start below the lintels (so doorways are open) and above the agent. Returns the hit height
    (-inf = no hit) and whether the ray started inside a solid (it first hit a downward-facing face
    from inside, e.g. a wall box), which counts as blocked.
    """
    xs = np.arange(lo[0], hi[0], CELL) + CELL / 2
    zs = np.arange(lo[2], hi[2], CELL) + CELL / 2
    gx, gz = np.meshgrid(xs, zs, indexing="ij")
    origins = np.stack([gx.ravel(), np.full(gx.size, 1.5), gz.ravel()], axis=1)
    dirs = np.tile([0.0, -1.0, 0.0], (len(origins), 1))
    locs, ray_idx, tri_idx = mesh.ray.intersects_location(origins, dirs, multiple_hits=False)
    heights = np.full(len(origins), -np.inf)
    heights[ray_idx] = locs[:, 1]
    inside = np.zeros(len(origins), bool)
    inside[ray_idx] = mesh.face_normals[tri_idx, 1] < 0
    return heights.reshape(gx.shape), inside.reshape(gx.shape), xs, zs


def _dilate(mask: np.ndarray, radius: float) -> np.ndarray:
    r = int(np.ceil(radius / CELL))
    yy, xx = np.mgrid[-r : r + 1, -r : r + 1]
    return ndimage.binary_dilation(mask, structure=(xx**2 + yy**2) * CELL**2 <= radius**2)


def _cell(xs, zs, x, z):
    return int(np.argmin(np.abs(xs - x))), int(np.argmin(np.abs(zs - z)))


# ---- category library


def test_category_library_has_enough_well_formed_categories():
    assert len(CATEGORIES) >= 22
    for name in ("chair", "table", "sofa", "bed", "toilet", "tv_monitor", "plant", "sink", "refrigerator", "microwave"):
        assert name in CATEGORIES
    rng = np.random.default_rng(0)
    for cat in CATEGORIES.values():
        assert set(cat.rooms) <= set(ROOM_TYPES), cat.name
        assert all(s in CATEGORIES for s in cat.supports), cat.name
        assert (cat.placement == "on_surface") == bool(cat.supports), cat.name
        mesh = cat.build(rng)
        lo, hi = mesh.bounds
        assert abs(lo[1]) < 1e-9 and np.allclose((lo + hi)[[0, 2]], 0.0, atol=1e-9), cat.name
        assert mesh.extents.max() >= 0.3, f"{cat.name} too small to see: {mesh.extents}"
        assert np.all(mesh.extents <= np.asarray(cat.size_max) * 1.3 + 0.25), cat.name
        assert len(mesh.faces) <= 600, f"{cat.name} has {len(mesh.faces)} triangles"


def test_colour_palette_is_named_and_distinct():
    assert len(COLOURS) >= 14
    rgb = np.array(list(COLOURS.values()))
    assert len({tuple(c) for c in rgb}) == len(rgb)
    dist = np.linalg.norm(rgb[:, None, :] - rgb[None, :, :], axis=2) + np.eye(len(rgb)) * 1e9
    assert dist.min() > 40  # no two names for (almost) the same colour


@pytest.mark.parametrize("name", ["chair", "table"])
def test_legged_furniture_has_legs(name):
    # A horizontal ray at knee height through the middle passes between the legs; one at the top hits.
    cat = CATEGORIES[name]
    mesh = cat.build(np.random.default_rng(1), np.asarray(cat.size_max))
    top = mesh.bounds[1][1]
    seat = 0.45 if name == "chair" else top - 0.02
    origins = np.array([[-2.0, 0.2, 0.0], [-2.0, seat - 0.02, 0.0]])
    hits = mesh.ray.intersects_any(origins, np.tile([1.0, 0.0, 0.0], (2, 1)))
    assert hits.tolist() == [False, True]


def test_paint_scales_part_shades_by_instance_colour():
    mesh = CATEGORIES["sofa"].build(np.random.default_rng(0))
    painted = paint(mesh, COLOURS["blue"])
    rgb = np.asarray(painted.visual.vertex_colors)[:, :3].astype(float)
    assert np.asarray(painted.visual.vertex_colors).dtype == np.uint8
    ratio = rgb / np.asarray(COLOURS["blue"], float)
    assert ratio.max() <= 1.0 + 1e-6 and ratio.min() >= 0.5
    assert np.allclose(ratio, ratio[:, :1], atol=0.05)  # a shade of blue, not another hue


def test_recipes_only_use_categories_allowed_in_their_room():
    assert set(RECIPES) == set(ROOM_TYPES)
    for room_type, items in RECIPES.items():
        for item in items:
            assert room_type in CATEGORIES[item.category].rooms, (room_type, item.category)
            for comp in item.companions:
                assert room_type in CATEGORIES[comp.category].rooms, (room_type, comp.category)


def test_bad_config_is_rejected():
    with pytest.raises(HouseConfigError, match="room count"):
        HouseConfig(min_rooms=5, max_rooms=4)
    with pytest.raises(ValueError, match="door_width"):
        HouseConfig(door_width=(0.3, 0.4))


# ---- determinism


def test_same_seed_gives_identical_bytes_and_other_seed_differs(house):
    scene, semantic = house
    again_scene, again_semantic = generate_house(SEED)
    assert scene.export(file_type="glb") == again_scene.export(file_type="glb")
    assert json.dumps(semantic) == json.dumps(again_semantic)
    other_scene, other_semantic = generate_house(SEED + 1)
    assert other_scene.export(file_type="glb") != scene.export(file_type="glb")
    assert json.dumps(other_semantic) != json.dumps(semantic)


def test_bundled_dataset_matches_the_generator():
    glb = BUNDLED / "train" / "house_000.glb"
    if not glb.is_file():
        pytest.skip("bundled dataset not generated")
    scene, semantic = generate_house(0)
    assert glb.read_bytes() == scene.export(file_type="glb"), "envs/houses is stale: rerun generate_dataset"
    stored = json.loads(glb.with_name("house_000.semantic.json").read_text())
    assert stored["objects"] == json.loads(json.dumps(semantic["objects"]))


# ---- floor plan


def test_floor_plans_have_valid_rooms_and_every_room_is_reachable():
    cfg = HouseConfig(furnish=False)
    counts = set()
    for seed in range(6):
        scene, semantic = generate_house(seed, cfg)
        rooms = semantic["rooms"]
        counts.add(len(rooms))
        assert cfg.min_rooms <= len(rooms) <= cfg.max_rooms
        names = [r["name"] for r in rooms]
        assert len(set(names)) == len(names)
        assert all(r["type"] in ROOM_TYPES for r in rooms)
        lo = np.min([r["aabb"]["min"] for r in rooms], axis=0)
        hi = np.max([r["aabb"]["max"] for r in rooms], axis=0)
        assert np.all((hi - lo)[[0, 2]] <= cfg.max_extent)
        for d in semantic["doors"]:
            assert cfg.door_width[0] - 1e-9 <= d["width"] <= cfg.door_width[1] + 1e-9

        # Rasterise the walls alone, grow them by the agent radius, and flood-fill from the first room.
        walls = _node_meshes(scene)["walls"]
        heights, _, xs, zs = _top_down_heights(walls, lo - 1.0, hi + 1.0)
        blocked = _dilate(np.isfinite(heights), AGENT_RADIUS)  # only wall interiors are hit
        labels, _ = ndimage.label(~blocked)
        centres = [_cell(xs, zs, (r["aabb"]["min"][0] + r["aabb"]["max"][0]) / 2,
                         (r["aabb"]["min"][2] + r["aabb"]["max"][2]) / 2) for r in rooms]
        start = labels[centres[0]]
        assert start != 0
        assert all(labels[c] == start for c in centres), f"seed {seed}: a room is cut off"
        assert labels[0, 0] != start, f"seed {seed}: the inside leaks to the outside"
    assert len(counts) >= 2  # the room count varies with the seed


def test_walls_are_closed_boxes(house):
    scene, _ = house
    parts = _node_meshes(scene)["walls"].split(only_watertight=False)
    assert len(parts) > 10
    assert all(p.is_watertight and p.volume > 0 for p in parts)


# ---- furnished house


def test_scene_nodes_and_triangle_budget(house):
    scene, semantic = house
    nodes = set(_node_meshes(scene))
    assert {"walls", "ceiling"} <= nodes
    assert {f"floor_{r['name']}" for r in semantic["rooms"]} <= nodes
    assert {f"obj_{o['id']}" for o in semantic["objects"]} == {n for n in nodes if n.startswith("obj_")}
    triangles = sum(len(g.faces) for g in scene.geometry.values())
    assert 1000 < triangles < 30000


def test_annotations_match_geometry(house):
    scene, semantic = house
    meshes = _node_meshes(scene)
    rooms = {r["name"]: r for r in semantic["rooms"]}
    objects = semantic["objects"]
    assert [o["id"] for o in objects] == list(range(1, len(objects) + 1))
    per_room: dict[str, int] = {}
    per_category: dict[str, int] = {}
    for o in objects:
        mesh = meshes[f"obj_{o['id']}"]
        assert np.allclose(mesh.bounds, [o["aabb"]["min"], o["aabb"]["max"]], atol=1e-4), o
        room = rooms[o["room"]]
        assert np.all(np.asarray(o["aabb"]["min"]) >= np.asarray(room["aabb"]["min"]) - 1e-4), o
        assert np.all(np.asarray(o["aabb"]["max"]) <= np.asarray(room["aabb"]["max"]) + 1e-4), o
        assert o["room"] and room["type"] in CATEGORIES[o["category"]].rooms
        assert tuple(o["colour_rgb"]) == COLOURS[o["colour"]]
        rgb = np.asarray(mesh.visual.vertex_colors)[:, :3].astype(float)
        ratio = rgb / np.maximum(np.asarray(o["colour_rgb"], float), 1.0)
        assert 0.5 <= ratio.min() and ratio.max() <= 1.0 + 1e-6, o  # shades of the annotated colour
        if CATEGORIES[o["category"]].placement == "wall_mounted":
            centre = (o["aabb"]["min"][1] + o["aabb"]["max"][1]) / 2
            assert WALL_MOUNT_HEIGHT[0] - 1e-6 <= centre <= WALL_MOUNT_HEIGHT[1] + 1e-6
        per_room[o["room"]] = per_room.get(o["room"], 0) + 1
        per_category[o["category"]] = per_category.get(o["category"], 0) + 1
    assert set(per_room) == set(rooms)
    assert all(3 <= n <= 8 for n in per_room.values()), per_room
    assert max(per_category.values()) >= 2


def test_objects_do_not_overlap_or_block_doorways(house):
    _, semantic = house
    boxes = [(np.asarray(o["aabb"]["min"]), np.asarray(o["aabb"]["max"]), o) for o in semantic["objects"]]
    for i, (lo_a, hi_a, a) in enumerate(boxes):
        for lo_b, hi_b, b in boxes[i + 1 :]:
            gap = np.maximum(lo_a - hi_b, lo_b - hi_a)
            # Touching in y is allowed (a TV standing on its stand); interpenetration is not.
            assert gap.max() >= -1e-6, (a["id"], b["id"])
    for door in semantic["doors"]:
        c, half = np.asarray(door["center"]), door["width"] / 2
        along, across = (0, 2) if door["wall_axis"] == "x" else (2, 0)
        for lo, hi, o in boxes:
            if lo[1] > door["height"]:
                continue
            in_span = lo[along] < c[along] + half and hi[along] > c[along] - half
            in_corridor = lo[across] < c[across] + 0.05 + 0.6 and hi[across] > c[across] - 0.05 - 0.6
            assert not (in_span and in_corridor), f"object {o['id']} blocks door {door}"


def test_free_floor_is_connected_for_the_agent(house):
    scene, semantic = house
    meshes = _node_meshes(scene)
    mesh = trimesh.util.concatenate([m for name, m in meshes.items() if name != "ceiling"])
    lo = np.min([r["aabb"]["min"] for r in semantic["rooms"]], axis=0) - 0.5
    hi = np.max([r["aabb"]["max"] for r in semantic["rooms"]], axis=0) + 0.5
    heights, inside, xs, zs = _top_down_heights(mesh, lo, hi)
    floor = np.isfinite(heights) & (heights < 0.1) & ~inside
    free = floor & ~_dilate(np.isfinite(heights) & ((heights >= 0.1) | inside), AGENT_RADIUS)
    labels, n = ndimage.label(free)
    sizes = np.bincount(labels.ravel())[1:]
    main = int(np.argmax(sizes)) + 1
    assert sizes[main - 1] >= 0.97 * free.sum()
    for r in semantic["rooms"]:
        ix = (xs > r["aabb"]["min"][0]) & (xs < r["aabb"]["max"][0])
        iz = (zs > r["aabb"]["min"][2]) & (zs < r["aabb"]["max"][2])
        assert (labels[np.ix_(ix, iz)] == main).sum() > 20, f"room {r['name']} unreachable"


def test_written_house_loads_with_matching_face_ids(written, house):
    _, semantic = house
    asset = load_scene(written)
    assert asset.scene_id == "house_x"
    ids = set(np.unique(asset.face_ids).tolist()) - {-1}
    assert ids == {o["id"] for o in semantic["objects"]} == set(asset.objects)
    for obj in asset.objects.values():
        verts = asset.mesh.vertices[asset.mesh.faces[asset.face_ids == obj.id].ravel()]
        assert np.allclose(verts.min(0), obj.aabb_min, atol=1e-4)
        assert np.allclose(verts.max(0), obj.aabb_max, atol=1e-4)
        rgb = asset.mesh.visual.vertex_colors[asset.mesh.faces[asset.face_ids == obj.id].ravel(), :3]
        assert np.all(rgb <= np.asarray(obj.colour_rgb)) and rgb.max() > 0  # vertex colours survive the GLB
    assert len(asset.rooms) == len(semantic["rooms"])
    assert (asset.face_ids == -1).sum() > 0  # structure


def test_generate_dataset_layout(tmp_path):
    paths = generate_dataset(tmp_path, n_train=1, n_val=1, seed=0)
    assert [p.relative_to(tmp_path).as_posix() for p in paths] == ["train/house_000.glb", "val/house_001.glb"]
    assert (tmp_path / "val" / "house_001.semantic.json").is_file()
    assert "house_001" in (tmp_path / "README.md").read_text()
    assert paths[0].read_bytes() == generate_house(0)[0].export(file_type="glb")
