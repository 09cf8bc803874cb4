"""Real-scan inputs: textures (GLB, OBJ+MTL, Basis), PLY vertex colours, HM3D / MP3D layouts and
annotations, scene_id resolution, multi-floor grids. Every fixture is written here (scanfix.py)."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
import trimesh

sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
import scanfix as F  # noqa: E402

from navbench.render import CameraConfig, Renderer, intrinsics  # noqa: E402
from navbench.scene.asset import SceneError, load_scene  # noqa: E402
from navbench.scene.datasets import resolve_scene  # noqa: E402
from navbench.scene.navigability import NavGrid, NavGridConfig  # noqa: E402

ORIGIN, IDENTITY = np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])


def _quad_pixels(size: int):
    """Quad points (x, y) seen by each pixel of a camera at the origin looking down -z."""
    cam = CameraConfig(width=size, height=size)
    k = intrinsics(cam)
    v, u = np.mgrid[0:size, 0:size]
    depth = -F.QUAD_Z
    return cam, (u - k[0, 2]) / k[0, 0] * depth, -(v - k[1, 2]) / k[1, 1] * depth


def _check_checker(path, size: int, tol: int = 2):
    asset = load_scene(path)
    assert asset.is_textured and len(asset.textures) == 1
    cam, x, y = _quad_pixels(size)
    with Renderer(asset, cam) as r:
        out = r.render(ORIGIN, IDENTITY, rgb=True, depth=True, ids=True)
    colour, edge = F.expected_checker(x, y)
    inside = (np.abs(x) < 0.97) & (np.abs(y) < 0.97)
    far_from_edges = inside & (edge > 3)
    assert far_from_edges.sum() > 0.15 * size * size
    err = np.abs(out.rgb.astype(int) - colour)[far_from_edges]
    assert err.max() <= tol, f"max error {err.max()} levels"
    # Both colours are there: the texture is not averaged into one vertex colour.
    assert (np.abs(out.rgb[far_from_edges].astype(int) - F.CHECK_A).max(1) <= tol).mean() > 0.3
    assert (np.abs(out.rgb[far_from_edges].astype(int) - F.CHECK_B).max(1) <= tol).mean() > 0.3
    np.testing.assert_allclose(out.depth[inside], -F.QUAD_Z, atol=1e-3)  # depth unchanged by texturing
    assert (out.ids == -1).all()
    return out


@pytest.mark.parametrize("size", [224, 480])
def test_textured_glb_renders_checkerboard(tmp_path, size):
    _check_checker(F.write_png_glb(tmp_path / "quad.glb", F.checkerboard()), size)


def test_textured_obj_mtl_renders_checkerboard(tmp_path):
    _check_checker(F.write_obj(tmp_path, F.checkerboard()), 224)


def test_ply_vertex_colours_take_the_vertex_colour_path(tmp_path):
    colours = np.array([[255, 0, 0]] * 4, np.uint8)
    asset = load_scene(F.write_ply(tmp_path / "quad.ply", colours))
    assert not asset.is_textured
    with Renderer(asset) as r:
        out = r.render(ORIGIN, IDENTITY)
    assert tuple(out.rgb[112, 112]) == (255, 0, 0)


def test_basis_texture_decodes_to_the_source_within_codec_error(tmp_path):
    alktx2 = pytest.importorskip("alktx2")
    yy, xx = np.mgrid[0:256, 0:256]
    shade = 30 * np.sin(xx / 9.0)[..., None] + 20 * np.cos(yy / 13.0)[..., None]  # detail inside the squares
    img = np.clip(F.checkerboard().astype(float) + shade, 0, 255).astype(np.uint8)
    rgba = np.dstack([img, np.full(img.shape[:2], 255, np.uint8)])
    ktx2 = alktx2.encode_raw_rgba_to_ktx2(rgba.tobytes(), 256, 256, has_alpha=False, codec="uastc", quality=90)
    asset = load_scene(F.write_glb(tmp_path / "quad.basis.glb", ktx2, "image/ktx2", basisu=True))
    decoded = asset.textures[0][..., :3].astype(int)
    err = np.abs(decoded - img.astype(int))
    assert err.mean() < 3.0 and np.percentile(err, 99) < 16  # UASTC is near-lossless
    _check_checker(F.write_glb(tmp_path / "flat.basis.glb", alktx2.encode_raw_rgba_to_ktx2(
        np.dstack([F.checkerboard(), np.full((256, 256), 255, np.uint8)]).tobytes(), 256, 256, has_alpha=False,
        codec="uastc", quality=90), "image/ktx2", basisu=True), 224, tol=4)


def test_undecodable_basis_texture_names_file_and_extension(tmp_path):
    path = F.write_glb(tmp_path / "bad.basis.glb", b"\xabKTX 20\xbb\r\n\x1a\n" + b"\0" * 40, "image/ktx2",
                       basisu=True)
    with pytest.raises(SceneError, match=r"bad\.basis\.glb.*KHR_texture_basisu"):
        load_scene(path)


def test_missing_basis_transcoder_is_one_line_naming_the_package(tmp_path, monkeypatch):
    path = F.write_glb(tmp_path / "q.basis.glb", b"\xabKTX 20\xbb\r\n\x1a\n", "image/ktx2", basisu=True)
    monkeypatch.setitem(sys.modules, "opengl_basisu", None)
    with pytest.raises(SceneError, match=r"q\.basis\.glb.*KHR_texture_basisu.*opengl-basisu") as exc:
        load_scene(path)
    assert "\n" not in str(exc.value)


def test_broken_textures_raise_instead_of_rendering_grey(tmp_path):
    with pytest.raises(SceneError, match=r"bad\.glb.*cannot be decoded"):
        load_scene(F.write_glb(tmp_path / "bad.glb", b"\x89PNG not really", "image/png"))
    obj = F.write_obj(tmp_path, F.checkerboard())
    (tmp_path / "checker.png").unlink()
    with pytest.raises(SceneError, match=r"quad\.mtl.*checker\.png"):
        load_scene(obj)


# ------------------------------------------------------------------------------------------ HM3D
@pytest.mark.parametrize("textured", [False, True], ids=["vertex-coloured", "semantic-texture"])
def test_hm3d_v02_layout_annotations(tmp_path, textured):
    root = tmp_path / "scene_datasets" / "hm3d"
    mesh = F.write_hm3d_scene(root, textured_semantics=textured)
    asset = load_scene(mesh)
    v, f, part = F.room_scene()
    assert len(asset.mesh.faces) == len(f)
    # Structure (floor, wall) is -1; the armchair is object 3 (category chair), the tv object 4 (tv_monitor).
    expected = np.array([-1, -1, 3, 4])[part]
    np.testing.assert_array_equal(asset.face_ids, expected)
    assert {o.id: o.category for o in asset.objects.values()} == {3: "chair", 4: "tv_monitor"}
    assert asset.objects[3].room == "region_0" and asset.objects[4].room == "region_1"
    np.testing.assert_allclose(asset.objects[3].aabb_min, (0.5, 0.0, -1.5))
    np.testing.assert_allclose(asset.objects[3].aabb_max, (1.0, 0.9, -1.0))
    assert asset.objects[4].colour_rgb == (0xD6, 0x27, 0x28)
    assert {r.name for r in asset.rooms} == {"region_0", "region_1"}


def test_hm3d_semantic_txt_errors_name_the_file_and_line(tmp_path):
    root = tmp_path / "hm3d"
    mesh = F.write_hm3d_scene(root)
    txt = mesh.parent / "abcDEFghiJK.semantic.txt"
    txt.write_text("Some Other Header\n1,FFFFFF,\"wall\",0\n")
    with pytest.raises(SceneError, match="semantic.txt.*HM3D Semantic Annotations"):
        load_scene(mesh)
    txt.write_text("HM3D Semantic Annotations\n1,FFFFFF,\"wall\",0\n2,notahex,\"chair\",0\n")
    with pytest.raises(SceneError, match=r"semantic\.txt:3"):
        load_scene(mesh)


# ------------------------------------------------------------------------------------------ MP3D
def test_mp3d_layout_annotations_and_z_up_frame(tmp_path):
    root = tmp_path / "scene_datasets" / "mp3d"
    mesh = F.write_mp3d_scene(root)
    asset = load_scene(mesh)
    v, f, part = F.room_scene()
    lo, hi = asset.mesh.bounds
    np.testing.assert_allclose(lo, v.min(0), atol=1e-5)  # rotated into Habitat's y-up frame
    np.testing.assert_allclose(hi, v.max(0), atol=1e-5)
    np.testing.assert_array_equal(asset.face_ids, np.array([-1, -1, 1, 2])[part])
    assert asset.objects[1].category == "chair" and asset.objects[2].category == "tv_monitor"
    assert asset.objects[1].room == "living_room" and asset.objects[2].room == "kitchen"
    np.testing.assert_allclose(asset.objects[1].aabb_min, (0.5, 0.0, -1.5), atol=1e-5)
    grid = NavGrid.from_mesh(asset.mesh)
    assert abs(grid.floor_height) < 1e-3


def test_mp3d_bad_house_record_names_file_and_line(tmp_path):
    mesh = F.write_mp3d_scene(tmp_path / "mp3d")
    house = mesh.with_suffix(".house")
    house.write_text(house.read_text().replace("O 1 0 1", "O x 0 1"))
    with pytest.raises(SceneError, match=r"\.house:\d+: malformed O record"):
        load_scene(mesh)


# ------------------------------------------------------------------------------- scene resolution
def test_scene_ids_resolve_like_habitat(tmp_path):
    sd = tmp_path / "data" / "scene_datasets"
    mesh = F.write_hm3d_scene(sd / "hm3d")
    sid = "hm3d/val/00800-abcDEFghiJK/abcDEFghiJK.basis.glb"
    assert resolve_scene(sid, sd) == mesh
    assert resolve_scene("data/scene_datasets/" + sid, sd) == mesh
    assert resolve_scene(sid, tmp_path / "data") == mesh
    assert resolve_scene(sid, sd / "hm3d") == mesh  # --scene-dir at the dataset's own folder
    plain = mesh.with_name("abcDEFghiJK.glb")
    mesh.rename(plain)  # the -glb- download only: .basis.glb episodes still resolve
    assert resolve_scene(sid, sd) == plain
    missing = r"00801-zzz/zzz\.basis\.glb: scene file not found \(also looked for: .*00801-zzz/zzz\.glb"
    with pytest.raises(SceneError, match=missing):
        resolve_scene("hm3d/val/00801-zzz/zzz.basis.glb", sd)


# ---------------------------------------------------------------------------------- multi-floor
def test_floor_of_the_episode_start_on_a_two_storey_scan(tmp_path):
    from navbench.scene.cache import load_scene_and_navgrid

    parts = [trimesh.creation.box(extents=(8, 0.1, 8), transform=trimesh.transformations.translation_matrix(
        (0, -0.05 + 3.0 * k, 0))) for k in range(2)]
    mesh = trimesh.util.concatenate(parts)
    path = tmp_path / "two.glb"
    mesh.export(path)
    _, ground = load_scene_and_navgrid(path, floor_hint=0.02)
    _, upper = load_scene_and_navgrid(path, floor_hint=3.01)
    assert abs(ground.floor_height) < 0.01 and abs(upper.floor_height - 3.0) < 0.01
    assert abs(NavGrid.floor_for(mesh, 2.5)) < 0.01  # the floor below the point, not the one above its head
    assert abs(NavGrid.floor_for(mesh, 2.9) - 3.0) < 0.01  # within a step of the upper floor


def test_a_goal_on_another_storey_never_counts():
    """Two stacked 8 x 8 m storeys (floors at 0 and 2.8 m): a view point 2.8 m below the agent, 1.15 m
    away in xz, is not on the agent's storey; the same category's view point 3 m away upstairs is."""
    parts = [trimesh.creation.box(extents=(8, 0.1, 8), transform=trimesh.transformations.translation_matrix(
        (0, -0.05 + 2.8 * k, 0))) for k in range(2)]
    mesh = trimesh.util.concatenate(parts)
    ground = NavGrid.from_mesh(mesh)
    upper = NavGrid.from_mesh(mesh, NavGridConfig(floor_height=NavGrid.floor_for(mesh, 2.8)))
    assert ground.storey_top == pytest.approx(2.8, abs=0.01) and upper.storey_top == math.inf
    start = [0.0, 2.8, 0.0]
    below, same = [1.15, 0.0, 0.0], [0.0, 2.8, 3.0]
    assert upper.geodesic_distance(start, [below, same]) == pytest.approx(3.0, rel=0.01)
    assert upper.geodesic_distance(start, [below]) == math.inf
    assert ground.geodesic_distance([0.0, 0.0, 0.0], [below, same]) == pytest.approx(1.15, rel=0.01)
    assert list(ground.on_storey([below, same, [0.0, 1.8, 0.0]])) == [True, False, True]  # an object centre counts
    assert list(upper.on_storey([below, same, [0.0, 3.9, 0.0]])) == [False, True, True]


def test_stairs_between_storeys_are_not_navigable():
    """Two 8 x 8 m storeys joined by a flight of 0.17 m steps: each storey's grid stops at the stairs
    (beyond the first step, which is within the 0.2 m climb), so neither grid reaches the other floor."""
    slab = lambda y, cx=0.0, w=8.0: trimesh.creation.box(  # noqa: E731
        extents=(w, 0.1, 8), transform=trimesh.transformations.translation_matrix((cx, y - 0.05, 0)))
    parts = [slab(0.0), slab(3.06, cx=-1.5, w=5.0)]  # the upper floor leaves x > 1 open above the stairs
    for k in range(18):  # steps 0.17 m high, 0.3 m deep, 1.2 m wide, climbing towards -x from x = 3.9
        h = 0.17 * (k + 1)
        parts.append(trimesh.creation.box(extents=(0.3, h, 1.2), transform=trimesh.transformations.translation_matrix(
            (3.75 - 0.3 * k, h / 2, -3.0))))
    mesh = trimesh.util.concatenate(parts)
    ground = NavGrid.from_mesh(mesh)
    upper_y = NavGrid.floor_for(mesh, 3.06)
    assert abs(ground.floor_height) < 0.01 and abs(upper_y - 3.06) < 0.02
    # The second step (0.34 m) and everything above it are not on the ground floor's grid.
    for k in range(1, 18):
        assert not ground.is_navigable([3.75 - 0.3 * k, 0.0, -3.0])
    assert ground.is_navigable([0.0, 0.0, 2.0])


def _uastc(alktx2, rgb: np.ndarray) -> bytes:
    rgba = np.dstack([rgb, np.full(rgb.shape[:2], 255, np.uint8)])
    return alktx2.encode_raw_rgba_to_ktx2(np.ascontiguousarray(rgba).tobytes(), rgb.shape[1], rgb.shape[0],
                                          has_alpha=False, codec="uastc", quality=90)


def test_google_texture_basis_as_habitats_tool_writes_it_renders_the_checker(tmp_path):
    """habitat-sim's create_basis_compressed_glbs.py: magnum's BasisImageConverter stores the image bottom
    row first and sets the Y-flipped flag; gltf2basis.py moves the source into GOOGLE_texture_basis."""
    alktx2 = pytest.importorskip("alktx2")
    basis = F.ktx2_to_basis(_uastc(alktx2, F.checkerboard()[::-1]), y_flipped=True)
    path = F.write_glb(tmp_path / "quad.basis.glb", basis, "image/x-basis", extension="GOOGLE_texture_basis",
                       declare=False)
    _check_checker(path, 224, tol=4)


def test_basis_file_without_the_flip_flag_keeps_its_row_order(tmp_path):
    alktx2 = pytest.importorskip("alktx2")
    basis = F.ktx2_to_basis(_uastc(alktx2, F.checkerboard()), y_flipped=False)
    _check_checker(F.write_glb(tmp_path / "q.basis.glb", basis, "image/x-basis", extension="GOOGLE_texture_basis"),
                   224, tol=4)
    _check_checker(F.write_glb(tmp_path / "k.basis.glb", basis, "image/x-basis", basisu=True), 224, tol=4)


def test_undecodable_google_basis_names_file_and_extension(tmp_path):
    path = F.write_glb(tmp_path / "bad.basis.glb", b"sB" + b"\0" * 90, "image/x-basis",
                       extension="GOOGLE_texture_basis", declare=False)
    with pytest.raises(SceneError, match=r"bad\.basis\.glb: image 0: cannot decode GOOGLE_texture_basis"):
        load_scene(path)


def test_texture_only_in_an_unreadable_extension_is_refused_not_rendered_white(tmp_path):
    path = F.write_glb(tmp_path / "dds.glb", b"DDS " + b"\0" * 124, "image/vnd-ms.dds", extension="MSFT_texture_dds")
    with pytest.raises(SceneError, match=r"dds\.glb: texture 0 uses the MSFT_texture_dds extension"):
        load_scene(path)


def test_cli_exits_2_naming_file_and_extension_for_an_undecodable_basis_scene(tmp_path):
    import subprocess

    path = F.write_glb(tmp_path / "bad.basis.glb", b"sB" + b"\0" * 90, "image/x-basis",
                       extension="GOOGLE_texture_basis")
    proc = subprocess.run([sys.executable, "-m", "navbench.cli", "memory", "build", "--scene", str(path), "--out",
                           str(tmp_path / "mem")], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert "bad.basis.glb" in proc.stderr and "GOOGLE_texture_basis" in proc.stderr


@pytest.mark.parametrize("orientation, stored", [("ru", "bottom row first"), ("rd", "top row first")])
def test_ktx2_orientation_is_honoured(tmp_path, orientation, stored):
    alktx2 = pytest.importorskip("alktx2")
    img = F.checkerboard()[::-1] if orientation == "ru" else F.checkerboard()
    ktx2 = F.ktx2_with_orientation(_uastc(alktx2, img), orientation)
    _check_checker(F.write_glb(tmp_path / f"{orientation}.glb", ktx2, "image/ktx2", basisu=True), 224, tol=4)
