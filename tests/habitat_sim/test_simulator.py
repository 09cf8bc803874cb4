"""navbench.habitat_sim.Simulator with habitat-sim's semantics: observations rendered by navbench's renderer at
each sensor's own camera and pose, actions filtered by the path finder, seeded starts, the greedy follower.

Needs numpy-quaternion (habitat-sim's rotation type): installed with the ``habitat`` extra."""

import math

import numpy as np
import pytest

pytest.importorskip("quaternion", reason="numpy-quaternion (the habitat extra) is not installed")

import navbench.habitat_sim as hs  # noqa: E402
from navbench.habitat_sim import errors  # noqa: E402
from navbench.habitat_sim import magnum as mn  # noqa: E402
from navbench.habitat_sim.utils.common import quat_from_angle_axis, quat_to_coeffs  # noqa: E402


def _spec(uuid, kind, resolution=(64, 96), hfov=90.0, position=(0.0, 1.25, 0.0)):
    s = hs.CameraSensorSpec()
    s.uuid, s.sensor_type, s.resolution, s.hfov, s.position = uuid, kind, list(resolution), hfov, list(position)
    return s


def _config(scene_path, specs, seed=0, sliding=True):
    sim_cfg = hs.SimulatorConfiguration()
    sim_cfg.scene_id, sim_cfg.random_seed, sim_cfg.allow_sliding = str(scene_path), seed, sliding
    agent = hs.AgentConfiguration()
    agent.sensor_specifications = specs
    agent.action_space = {0: hs.ActionSpec("stop"),
                          1: hs.ActionSpec("move_forward", hs.ActuationSpec(amount=0.25)),
                          2: hs.ActionSpec("turn_left", hs.ActuationSpec(amount=10.0)),
                          3: hs.ActionSpec("turn_right", hs.ActuationSpec(amount=10.0))}
    return hs.Configuration(sim_cfg, [agent])


@pytest.fixture(scope="module")
def sim(scene_path):
    specs = [_spec("rgb", hs.SensorType.COLOR, (48, 64), 79.0), _spec("depth", hs.SensorType.DEPTH),
             _spec("semantic", hs.SensorType.SEMANTIC)]
    with hs.Simulator(_config(scene_path, specs, seed=4)) as s:
        yield s


def _place(sim, position, yaw):
    state = sim.get_agent(0).get_state()
    state.position, state.rotation = np.asarray(position, np.float32), quat_from_angle_axis(yaw, [0, 1, 0])
    sim.get_agent(0).set_state(state)


def test_observations_have_habitat_sims_types_and_each_sensors_size(sim):
    obs = sim.get_sensor_observations()
    assert obs["rgb"].shape == (48, 64, 4) and obs["rgb"].dtype == np.uint8 and (obs["rgb"][..., 3] == 255).all()
    assert obs["depth"].shape == (64, 96) and obs["depth"].dtype == np.float32
    assert obs["semantic"].shape == (64, 96) and obs["semantic"].dtype == np.uint32
    assert sim.sensors is sim._sensors or sim.sensors == sim._sensors
    assert set(sim.sensors) == {"rgb", "depth", "semantic"}


def test_depth_and_ids_equal_navbenchs_render_at_the_sensor_pose(sim):
    from navbench.render.camera import CameraConfig
    from navbench.render.renderer import Renderer
    from navbench.scene.pose import quat_from_yaw

    p = np.asarray(sim.pathfinder.get_random_navigable_point(), np.float64)
    _place(sim, p, 1.0)
    obs = sim.get_sensor_observations()
    pos, rot = sim.sensors["depth"].world_pose()  # float32 scene-graph arithmetic, as habitat-sim's
    assert np.allclose(pos, p + [0.0, 1.25, 0.0], atol=1e-6)
    assert np.allclose(rot, quat_from_yaw(1.0), atol=1e-6) or np.allclose(rot, -quat_from_yaw(1.0), atol=1e-6)
    with Renderer(sim._nb_asset, CameraConfig(width=96, height=64, hfov_deg=90.0, znear=0.01, zfar=1000.0)) as r:
        ref = r.render(pos, rot, rgb=False, depth=True, ids=True)
    assert np.array_equal(obs["depth"], ref.depth)
    assert np.array_equal(obs["semantic"], np.maximum(ref.ids, 0).astype(np.uint32))  # 0: structure, background


def test_semantic_ids_index_the_semantic_scene(sim):
    objects = sim.semantic_scene.objects
    assert objects[0].category.name() == "Unknown"
    seen: set[int] = set()
    for k in range(12):
        _place(sim, np.asarray(sim.pathfinder.get_random_navigable_point(), np.float64), k * 0.5)
        ids = np.unique(sim.get_sensor_observations()["semantic"])
        seen.update(int(i) for i in ids[ids > 0])
    assert len(seen) >= 3
    for i in seen:  # the ids the sensor gives index semantic_scene as habitat-lab's ObjectNav goals expect
        assert objects[i].semantic_id == i and objects[i].id.split("_")[-1] == str(i)
        assert objects[i].category.name() == sim._nb_asset.objects[i].category


def test_move_forward_follows_minus_z_and_turns_are_about_y(sim):
    p = np.asarray(sim.pathfinder.get_random_navigable_point(), np.float64)
    for yaw in np.linspace(0.0, 2 * math.pi, 12, endpoint=False):
        _place(sim, p, yaw)
        expected = p + 0.25 * np.array([-math.sin(yaw), 0.0, -math.cos(yaw)])
        filtered = np.asarray(sim.pathfinder.try_step(p, expected), np.float64)
        obs = sim.step(1)
        pos = np.asarray(sim.get_agent(0).get_state().position, np.float64)
        assert np.allclose(pos, filtered, atol=1e-5)
        free = np.allclose(filtered, expected, atol=1e-4)
        assert obs["collided"] == (not free)
    _place(sim, p, 0.0)
    sim.step(2)
    q = sim.get_agent(0).get_state().rotation
    assert np.allclose(quat_to_coeffs(q), quat_to_coeffs(quat_from_angle_axis(math.radians(10.0), [0, 1, 0])),
                       atol=1e-6)
    assert np.allclose(sim.get_agent(0).get_state().position, p, atol=1e-5)


def test_sliding_off_stops_at_the_wall(scene_path):
    with hs.Simulator(_config(scene_path, [], seed=1, sliding=False)) as s:
        for _ in range(60):
            before = np.asarray(s.get_agent(0).get_state().position, np.float32)
            forward = np.asarray(s.get_agent(0).scene_node.rotation.transform_vector(mn.Vector3(0, 0, -1)))
            obs = s.step(1)
            after = np.asarray(s.get_agent(0).get_state().position, np.float64)
            if obs["collided"]:
                stop = np.asarray(s.pathfinder.try_step_no_sliding(before, before + forward * np.float32(0.25)))
                assert np.allclose(after, stop, atol=1e-3)
                assert np.linalg.norm(after - before) < 0.25 - 1e-3
                return
            assert np.linalg.norm(after - before) == pytest.approx(0.25, abs=1e-5)
        pytest.fail("60 steps forward met no wall")


def test_same_seed_same_start_and_reset_returns_to_it(scene_path):
    starts = []
    for _ in range(2):
        with hs.Simulator(_config(scene_path, [], seed=9)) as s:
            first = s.get_agent(0).get_state()
            s.step(1)
            s.step(2)
            s.reset()
            again = s.get_agent(0).get_state()
            assert np.allclose(first.position, again.position) and first.rotation == again.rotation
            starts.append(first.position.tolist())
    assert starts[0] == starts[1]
    with hs.Simulator(_config(scene_path, [], seed=10)) as s:
        assert s.get_agent(0).get_state().position.tolist() != starts[0]


def test_sensor_node_tilt_and_reset_sensors(sim):
    p = np.asarray(sim.pathfinder.get_random_navigable_point(), np.float64)
    _place(sim, p, 0.3)
    level = sim.get_sensor_observations()["depth"]
    node = sim.get_agent(0).sensors["depth"].node
    node.rotation = node.rotation * mn.Quaternion.rotation(mn.Deg(30.0), mn.Vector3.x_axis())  # habitat-lab look_up
    assert not np.array_equal(sim.get_sensor_observations()["depth"], level)
    _place(sim, p, 0.3)  # set_state resets the sensors to their spec poses
    assert np.array_equal(sim.get_sensor_observations()["depth"], level)


def test_added_sensor_at_a_world_pose_renders_there(sim):
    from navbench.render.camera import CameraConfig
    from navbench.render.renderer import Renderer

    p = np.asarray(sim.pathfinder.get_random_navigable_point(), np.float64)
    _place(sim, p, 2.0)
    spec = _spec("goal_camera", hs.SensorType.COLOR, (40, 50), 60.0)
    sim.add_sensor(spec)
    agent = sim.get_agent(0)
    state = agent.get_state()
    cam_pos = p + np.array([0.3, 1.0, -0.2])
    cam_rot = quat_from_angle_axis(0.7, [0, 1, 0]) * quat_from_angle_axis(-0.2, [1, 0, 0])
    state.sensor_states["goal_camera"] = hs.SixDOFPose(cam_pos, cam_rot)
    agent.set_state(state, infer_sensor_states=False)
    sensor = sim.get_sensor("goal_camera")
    sensor.draw_observation()
    img = sensor.get_observation()
    pos, rot = sensor.world_pose()  # the requested world pose, through float32 scene-graph arithmetic
    assert np.allclose(pos, cam_pos, atol=1e-5)
    assert np.allclose(rot, quat_to_coeffs(cam_rot), atol=1e-5) or np.allclose(rot, -quat_to_coeffs(cam_rot), atol=1e-5)
    with Renderer(sim._nb_asset, CameraConfig(width=50, height=40, hfov_deg=60.0, znear=0.01, zfar=1000.0)) as r:
        ref = r.render(pos, rot, rgb=True, depth=False, ids=False)
    assert img.shape == (40, 50, 4)
    assert np.array_equal(img[..., :3], ref.rgb)
    sim.remove_sensor("goal_camera")
    assert "goal_camera" not in sim.sensors
    assert spec not in agent.agent_config.sensor_specifications


def test_greedy_follower_reaches_the_goal_and_errors_when_unreachable(sim):
    rng_points = [np.asarray(sim.pathfinder.get_random_navigable_point(), np.float64) for _ in range(2)]
    _place(sim, rng_points[0], 0.0)
    goal = rng_points[1]
    follower = sim.make_greedy_follower(0, 0.2, stop_key=0, forward_key=1, left_key=2, right_key=3)
    for _ in range(500):
        action = follower.next_action_along(goal)
        if action == 0:
            break
        sim.step(action)
    else:
        pytest.fail("the follower did not stop within 500 actions")
    path = hs.ShortestPath()
    path.requested_start, path.requested_end = sim.get_agent(0).get_state().position, goal
    sim.pathfinder.find_path(path)
    assert path.geodesic_distance < 0.2
    with pytest.raises(errors.GreedyFollowerError):
        follower.next_action_along(goal + np.array([500.0, 0.0, 0.0]))


def test_out_of_scope_features_are_refused_in_one_line(scene_path):
    eq = hs.EquirectangularSensorSpec()
    eq.uuid = "pano"
    with pytest.raises(NotImplementedError, match="covers navigation"):
        hs.Simulator(_config(scene_path, [eq]))
    cfg = _config(scene_path, [])
    cfg.sim_cfg.enable_physics = True
    with pytest.raises(NotImplementedError, match="no physics"):
        hs.Simulator(cfg)
    with pytest.raises(NotImplementedError, match="covers navigation"):
        hs.physics.ManagedRigidObject()


def test_noise_models_are_navbenchs_seeded_by_the_simulator(scene_path):
    from navbench.env.noise import gaussian_rgb, redwood_depth

    def noisy(spec, seed):
        with hs.Simulator(_config(scene_path, [spec], seed=seed)) as s:
            return s.get_sensor_observations()[spec.uuid], s

    clean_depth, s0 = noisy(_spec("d", hs.SensorType.DEPTH), 3)
    spec = _spec("d", hs.SensorType.DEPTH)
    spec.noise_model, spec.noise_model_kwargs = "RedwoodDepthNoiseModel", {"noise_multiplier": 0.5}
    depth, _ = noisy(spec, 3)
    assert np.array_equal(depth, redwood_depth(clean_depth, 0.5, np.random.default_rng([3, 1])))
    assert np.array_equal(noisy(spec, 3)[0], depth) and not np.array_equal(noisy(spec, 4)[0], depth)

    clean_rgb, _ = noisy(_spec("c", hs.SensorType.COLOR), 3)
    spec = _spec("c", hs.SensorType.COLOR)
    spec.noise_model, spec.noise_model_kwargs = "GaussianNoiseModel", {"intensity_constant": 0.1}
    rgb, _ = noisy(spec, 3)
    # habitat-sim 0.3.3 noises the whole RGBA buffer, alpha included
    assert np.array_equal(rgb, gaussian_rgb(clean_rgb, 0.1, np.random.default_rng([3, 1])))
    spec.noise_model, spec.noise_model_kwargs = "SaltAndPepperNoiseModel", {"amount": 0.2}
    changed = noisy(spec, 3)[0] != clean_rgb
    assert changed[..., 2].any() and not changed[..., 3].any()  # upstream's index quirk: never the last channel
    spec.noise_model, spec.noise_model_kwargs = "SpeckleNoiseModel", {"intensity_constant": 0.1, "mean": 0, "sigma": 1}
    assert not np.array_equal(noisy(spec, 3)[0], clean_rgb)

    for model, kwargs, kind, message in [("FancyNoise", {}, hs.SensorType.COLOR, "not supported"),
                                         ("RedwoodDepthNoiseModel", {}, hs.SensorType.COLOR, "applies to DEPTH"),
                                         ("GaussianNoiseModel", {"sigma2": 1}, hs.SensorType.COLOR, "takes")]:
        bad = _spec("x", kind)
        bad.noise_model, bad.noise_model_kwargs = model, kwargs
        with pytest.raises((NotImplementedError, ValueError), match=message):
            hs.Simulator(_config(scene_path, [bad]))


def test_sensors_sharing_a_frame_each_get_their_own_array(scene_path):
    from navbench.render.camera import CameraConfig
    from navbench.render.renderer import Renderer

    specs = [_spec(u, k) for u, k in (("rgb_a", hs.SensorType.COLOR), ("rgb_b", hs.SensorType.COLOR),
                                      ("depth_a", hs.SensorType.DEPTH), ("depth_b", hs.SensorType.DEPTH))]
    with hs.Simulator(_config(scene_path, specs, seed=2)) as s:
        obs = s.get_sensor_observations()
        pos, rot = s.sensors["rgb_a"].world_pose()
        with Renderer(s._nb_asset, CameraConfig(width=96, height=64, hfov_deg=90.0, znear=0.01, zfar=1000.0)) as r:
            ref = r.render(pos, rot, rgb=True, depth=True)
    for a, b in (("rgb_a", "rgb_b"), ("depth_a", "depth_b")):
        assert np.array_equal(obs[a], obs[b]) and not np.shares_memory(obs[a], obs[b])
    assert np.array_equal(obs["rgb_a"][..., :3], ref.rgb) and (obs["rgb_a"][..., 3] == 255).all()
    assert obs["rgb_a"].flags.c_contiguous and np.array_equal(obs["depth_a"], ref.depth)


def test_scene_node_translation_and_rotation_are_values_as_magnums():
    from navbench.habitat_sim.scene import SceneNode

    node = SceneNode()
    node.translation = [1.0, 2.0, 3.0]
    node.rotation = mn.Quaternion.rotation(mn.Deg(90), mn.Vector3.y_axis())
    t, r = node.translation, node.rotation
    t.x = 5.0  # changing a value read off the node leaves the node alone (magnum returns copies)
    r.scalar = 0.0
    assert node.translation.x == 1.0
    assert node.rotation.scalar == pytest.approx(math.sqrt(0.5))
    node.translate([0.0, 0.0, 1.0])
    assert list(node.translation) == [1.0, 2.0, 4.0] and t.z == 3.0
