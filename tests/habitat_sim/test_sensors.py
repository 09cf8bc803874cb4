"""habitat_sim's camera sensors on navbench: ORTHOGRAPHIC cameras as habitat-sim projects them (the view spans
``1 / ortho_scale`` metres across), for COLOR, DEPTH and SEMANTIC, on a scene of known geometry written here.

Needs numpy-quaternion (habitat-sim's rotation type): installed with the ``habitat`` extra."""

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("quaternion", reason="numpy-quaternion (the habitat extra) is not installed")

import navbench.habitat_sim as hs  # noqa: E402
from navbench.habitat_sim.utils.common import quat_from_angle_axis  # noqa: E402

sys.path.insert(0, str(Path(__file__).parents[1] / "scene"))
import scanfix as F  # noqa: E402

WALL_Z, BOX_Z = -6.0, -2.5  # the wall's and the box's faces towards the camera (the camera at z = 0 looks along -z)
EYE = 1.0  # sensor height above the agent
H, W = 60, 80


@pytest.fixture(scope="module")
def wall_scene(tmp_path_factory) -> Path:
    """A floor, a wall across the whole view at z = -6 and a 1 m box (object 1, a chair) at x, y in [0, 1] x
    [0.5, 1.5], its front at z = -2.5."""
    parts = [F.box((-10, -0.1, -10), (10, 0.0, 10)), F.box((-10, -5, -6.1), (10, 10, WALL_Z)),
             F.box((0.0, 0.5, -3.5), (1.0, 1.5, BOX_Z))]
    verts, faces, part, n = [], [], [], 0
    for k, (v, f) in enumerate(parts):
        verts.append(v)
        faces.append(f + n)
        part.append(np.full(len(f), k))
        n += len(v)
    v, f, part = np.concatenate(verts), np.concatenate(faces), np.concatenate(part)
    colours = np.tile([150, 150, 150, 255], (len(v), 1)).astype(np.uint8)
    colours[16:] = [200, 30, 40, 255]  # the box's vertices
    d = tmp_path_factory.mktemp("wall")
    path = F.write_mesh_glb(d / "wall.glb", v, f, colours,
                            node_names=[("structure", np.flatnonzero(part < 2)), ("obj_1", np.flatnonzero(part == 2))])
    (d / "wall.semantic.json").write_text(
        '{"scene_id": "wall", "rooms": [], "objects": [{"id": 1, "category": "chair", '
        '"aabb": {"min": [0, 0.5, -3.5], "max": [1, 1.5, -2.5]}}]}')
    return path


def _sensors(subtype, ortho_scale=0.1):
    specs = []
    for uuid, kind in (("rgb", hs.SensorType.COLOR), ("depth", hs.SensorType.DEPTH),
                       ("semantic", hs.SensorType.SEMANTIC)):
        s = hs.CameraSensorSpec()
        s.uuid, s.sensor_type, s.sensor_subtype = uuid, kind, subtype
        s.resolution, s.position, s.hfov, s.ortho_scale = [H, W], [0.0, EYE, 0.0], 90.0, ortho_scale
        specs.append(s)
    return specs


def _observe(scene, specs, z=0.0):
    sim_cfg = hs.SimulatorConfiguration()
    sim_cfg.scene_id = str(scene)
    agent = hs.AgentConfiguration()
    agent.sensor_specifications = specs
    with hs.Simulator(hs.Configuration(sim_cfg, [agent])) as sim:
        state = sim.get_agent(0).get_state()
        state.position, state.rotation = np.array([0.0, 0.0, z], np.float32), quat_from_angle_axis(0.0, [0, 1, 0])
        sim.get_agent(0).set_state(state)
        return sim.get_sensor_observations()


def _box_extent(mask):
    """(columns, rows) the box covers."""
    return int(mask.any(axis=0).sum()), int(mask.any(axis=1).sum())


def test_orthographic_depth_is_the_distance_and_the_view_spans_one_over_ortho_scale(wall_scene):
    obs = _observe(wall_scene, _sensors(hs.SensorSubType.ORTHOGRAPHIC, 0.1))
    depth, ids, rgb = obs["depth"], obs["semantic"], obs["rgb"]
    assert depth.shape == (H, W) and depth.dtype == np.float32 and ids.dtype == np.uint32 and rgb.shape == (H, W, 4)
    box = ids == 1
    assert set(np.unique(ids)) == {0, 1}  # the box is object 1, the wall structure (0)
    # every pixel sees the wall or the box along parallel rays: depth is the distance, the same for all pixels
    np.testing.assert_allclose(depth[~box], -WALL_Z, atol=1e-3)
    np.testing.assert_allclose(depth[box], -BOX_Z, atol=1e-3)
    # 10 m across (80 px: 8 per metre) and 7.5 m down: the 1 m box covers 8 x 8 pixels, right of the centre,
    # its top 3.25 m (26 rows) below the view's top edge at EYE + 3.75 m
    assert _box_extent(box) == (8, 8)
    cols, rows = np.flatnonzero(box.any(axis=0)), np.flatnonzero(box.any(axis=1))
    assert (cols[0], rows[0]) == (W // 2, 26)
    assert np.array_equal((rgb[..., 0] == 200) & (rgb[..., 1] == 30), box)  # COLOR sees the same box

    # twice the scale: half the extent, the box twice as many pixels each way
    doubled = _observe(wall_scene, _sensors(hs.SensorSubType.ORTHOGRAPHIC, 0.2))["semantic"] == 1
    assert _box_extent(doubled) == (16, 16)
    # parallel projection: a step back changes the depth, not the box's size in the image
    back = _observe(wall_scene, _sensors(hs.SensorSubType.ORTHOGRAPHIC, 0.1), z=1.0)
    assert np.array_equal(back["semantic"] == 1, box)
    np.testing.assert_allclose(back["depth"][box], 1.0 - BOX_Z, atol=1e-3)


def test_pinhole_is_unchanged_beside_orthographic(wall_scene):
    obs = _observe(wall_scene, _sensors(hs.SensorSubType.PINHOLE))
    box = obs["semantic"] == 1
    # hfov 90: x / z in [0, 0.4] at 2.5 m is 0.4 of the half-width (40 px): 16 columns, shrinking with distance
    assert _box_extent(box)[0] == 16
    assert _box_extent(_observe(wall_scene, _sensors(hs.SensorSubType.PINHOLE), z=1.0)["semantic"] == 1)[0] < 16
    np.testing.assert_allclose(obs["depth"][box], -BOX_Z, atol=1e-3)  # z-depth of a fronto-parallel face


def test_bad_ortho_scale_is_refused_in_one_line(wall_scene):
    with pytest.raises(ValueError, match="sensor 'rgb': ortho_scale must be greater than 0"):
        _observe(wall_scene, _sensors(hs.SensorSubType.ORTHOGRAPHIC, 0.0))


def test_orthographic_depth_is_linearized_alike_on_both_draw_paths(wall_scene):
    from navbench.render.camera import CameraConfig
    from navbench.render.renderer import Renderer
    from navbench.scene.asset import load_scene

    camera = CameraConfig(width=W, height=H, znear=0.01, zfar=1000.0, ortho_scale=0.1)
    pose = (np.array([0.0, EYE, 0.0]), np.array([0.0, 0.0, 0.0, 1.0]))
    with Renderer(load_scene(wall_scene), camera) as r:
        direct = r.render(*pose, rgb=False, depth=True, ids=True)
        r._direct = None  # pyrender's own path (EGL's), which linearizes every depth buffer as a perspective one
        pyr = r.render(*pose, rgb=False, depth=True, ids=True)
    assert np.array_equal(direct.ids, pyr.ids)
    np.testing.assert_allclose(pyr.depth, direct.depth, atol=1e-3)
    np.testing.assert_allclose(pyr.depth[pyr.ids < 0], -WALL_Z, atol=1e-3)


def test_constrained_look_stops_at_the_constraint_as_habitat_sim():
    from navbench.habitat_sim import magnum as mn
    from navbench.habitat_sim.agent import controls
    from navbench.habitat_sim.scene import SceneNode

    def pitch(node):  # degrees above level of the node's front
        front = np.asarray(node.rotation.transform_vector(mn.Vector3(0.0, 0.0, -1.0)), np.float64)
        return np.degrees(np.arctan2(front[1], -front[2]))

    node = SceneNode()
    up = hs.ActuationSpec(amount=20.0, constraint=30.0)
    controls.look_up(node, up)
    assert pitch(node) == pytest.approx(20.0, abs=1e-4)
    controls.look_up(node, up)  # cut short at the constraint (habitat-sim's default_controls._rotate_local)
    assert pitch(node) == pytest.approx(30.0, abs=1e-4)
    controls.look_down(node, hs.ActuationSpec(amount=75.0, constraint=30.0))
    assert pitch(node) == pytest.approx(-30.0, abs=1e-4)
    controls.look_down(node, hs.ActuationSpec(amount=10.0))  # no constraint: no limit
    assert pitch(node) == pytest.approx(-40.0, abs=1e-4)
    node.rotate_y_local(mn.Deg(10.0))
    with pytest.raises(RuntimeError, match="singular look action"):
        controls.look_up(node, up)
