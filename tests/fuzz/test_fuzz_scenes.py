"""Fuzz the scene readers: meshes (GLB/OBJ/PLY) through load_scene and the navigation grid, and the
``{stem}.semantic.json`` annotations beside them.

A scene must load into a finite mesh with a navigable floor, or fail as one line naming the file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from fuzzlib import USER_ERRORS, check_user_error, mutations, read_or_error
from hypothesis import given
from hypothesis import strategies as st

from navbench.paths import SCENES_DIR
from navbench.scene.asset import load_scene, semantic_path
from navbench.scene.cache import load_scene_and_navgrid

FORMATS = ("glb", "obj", "ply")
SEMANTIC = json.loads((SCENES_DIR / "houses" / "val" / "house_008.semantic.json").read_text())
SMALL_SEMANTIC = {"scene_id": "room", "rooms": SEMANTIC["rooms"][:2], "objects": SEMANTIC["objects"][:2]}


def room(size: float = 4.0, height: float = 2.6, offset: float = 0.0) -> trimesh.Scene:
    """A floor and a ceiling ``height`` above it, plus one object node ``obj_1``."""
    floor = trimesh.creation.box((size, 0.1, size))
    floor.apply_translation((offset, -0.05, offset))
    ceiling = trimesh.creation.box((size, 0.1, size))
    ceiling.apply_translation((offset, height + 0.05, offset))
    chair = trimesh.creation.box((0.5, 0.8, 0.5))
    chair.apply_translation((offset + 1.0, 0.4, offset + 1.0))
    scene = trimesh.Scene()
    scene.add_geometry(floor, node_name="floor", geom_name="floor")
    scene.add_geometry(ceiling, node_name="ceiling", geom_name="ceiling")
    scene.add_geometry(chair, node_name="obj_1", geom_name="obj_1")
    return scene


def export(scene_or_mesh, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    data = scene_or_mesh.export(file_type=path.suffix[1:])
    path.write_bytes(data.encode() if isinstance(data, str) else data)
    return path


def check_scene(path: Path) -> None:
    """Loads (with its navigation grid) into finite geometry, or fails as one line naming the file."""
    out = read_or_error(load_scene_and_navgrid, path, use_cache=False)
    if out is None:
        return
    asset, grid = out
    assert np.isfinite(asset.mesh.vertices).all()
    assert len(asset.face_ids) == len(asset.mesh.faces)
    assert grid.navigable.any() and np.isfinite(grid.floor_height)


# ------------------------------------------------------------------------------ meshes
coords = st.floats(allow_nan=True, allow_infinity=True, width=32) | st.sampled_from([0.0, 1e-9, 1e9, -1e9, 3e38])


@given(fmt=st.sampled_from(FORMATS), data=st.data())
def test_random_triangles(fmt, data, fuzz_dir):
    """Arbitrary (possibly degenerate, non-finite, huge) triangles, alone or added to a room."""
    n = data.draw(st.integers(1, 6))
    verts = np.array(data.draw(st.lists(st.tuples(coords, coords, coords), min_size=3, max_size=3 * n)), np.float64)
    faces = np.array(data.draw(st.lists(st.tuples(*[st.integers(0, len(verts) - 1)] * 3), min_size=1, max_size=n)))
    junk = trimesh.Trimesh(verts, faces, process=False)
    scene = room() if data.draw(st.booleans()) else trimesh.Scene()
    scene.add_geometry(junk, node_name="junk", geom_name="junk")
    check_scene(export(scene, fuzz_dir / "tri" / f"scene.{fmt}"))


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("case", ["room", "no_floor", "ceiling_10m", "huge_coordinates", "huge_extent", "flat",
                                  "degenerate_only"])
def test_shapes(fmt, case, fuzz_dir):
    if case == "room":
        scene = room()
    elif case == "no_floor":
        scene = trimesh.Scene(trimesh.creation.box((0.5, 2.0, 0.5)))  # a pillar: nowhere to stand
    elif case == "ceiling_10m":
        scene = room(height=10.0)
    elif case == "huge_coordinates":
        scene = room(offset=1e7)
    elif case == "huge_extent":
        scene = room(size=1e6)
    elif case == "flat":
        scene = trimesh.Scene(trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 0, 1]], [[0, 1, 2]], process=False))
    else:
        scene = trimesh.Scene(trimesh.Trimesh([[0, 0, 0], [0, 0, 0], [1, 1, 1]], [[0, 1, 2], [0, 0, 0]],
                                              process=False))
    check_scene(export(scene, fuzz_dir / case / f"scene.{fmt}"))


@pytest.mark.parametrize("fmt", FORMATS)
def test_truncated_and_garbage_files(fmt, fuzz_dir):
    data = room().export(file_type=fmt)
    data = data if isinstance(data, bytes) else data.encode()
    path = fuzz_dir / "trunc" / f"scene.{fmt}"
    path.parent.mkdir(parents=True, exist_ok=True)
    for cut in sorted({0, 1, 4, 12, 20, len(data) // 3, len(data) // 2, len(data) - 1}):
        path.write_bytes(data[:cut])
        check_scene(path)
    for junk in (b"\x00" * 64, b"\xff\xfe garbage", b"glTF" + b"\x00" * 40, b"ply\nformat ascii 1.0\n"):
        path.write_bytes(junk)
        check_scene(path)


def test_directory_and_missing(fuzz_dir):
    (fuzz_dir / "adir.glb").mkdir(exist_ok=True)
    check_scene(fuzz_dir / "adir.glb")
    check_scene(fuzz_dir / "missing.glb")


# ------------------------------------------------------------------------------ semantic annotations
@pytest.fixture(scope="module")
def room_glb(tmp_path_factory) -> Path:
    return export(room(), tmp_path_factory.mktemp("sem") / "room.glb")


def _check_semantic(glb: Path, text: bytes) -> None:
    sem = semantic_path(glb)
    sem.write_bytes(text)
    try:
        asset = load_scene(glb)
    except USER_ERRORS as exc:
        check_user_error(exc, sem)  # the annotation file, not the mesh, is named
        return
    assert isinstance(asset.scene_id, str)
    for oid, o in asset.objects.items():
        assert isinstance(oid, int) and isinstance(o.category, str)
        assert len(o.aabb_min) == 3 and np.isfinite(o.aabb_min).all() and np.isfinite(o.aabb_max).all()
        assert len(o.colour_rgb) == 3
    for r in asset.rooms:
        assert len(r.aabb_min) == 3 and np.isfinite(r.aabb_min).all() and np.isfinite(r.aabb_max).all()


@given(doc=mutations(SMALL_SEMANTIC))
def test_semantic_mutations(doc, room_glb):
    _check_semantic(room_glb, json.dumps(doc).encode())


def test_semantic_truncation_and_bytes(room_glb):
    data = json.dumps(SMALL_SEMANTIC).encode()
    for cut in range(0, len(data), max(1, len(data) // 300)):
        _check_semantic(room_glb, data[:cut])
    for junk in (b"\xff\xfe\x00", b"[" * 100_000 + b"]" * 100_000, b"null", b"[]", b'"x"'):
        _check_semantic(room_glb, junk)
