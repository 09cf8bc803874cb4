"""The real habitat-lab on navbench's habitat_sim, through habitat-lab's public API: a PointNav config pointed at
navbench's bundled split and scenes. Skipped unless the ``habitat`` extra and ``compat/habitat-sim`` are installed
(``pip install -e ".[habitat]" -e compat/habitat-sim``)."""

import importlib

import numpy as np
import pytest

habitat_sim = pytest.importorskip("habitat_sim", reason="navbench-habitat-sim (compat/habitat-sim) not installed")
if not hasattr(habitat_sim, "__navbench__"):
    pytest.skip("habitat_sim here is not navbench's", allow_module_level=True)
habitat = pytest.importorskip("habitat", reason="habitat-lab (the habitat extra) not installed")

from navbench._version import __version__ as navbench_version  # noqa: E402
from navbench.paths import EPISODES_DIR, SCENES_DIR  # noqa: E402

SPLIT = EPISODES_DIR / "pointnav" / "val" / "val.json.gz"


def _pointnav_config(*extra: str):
    from habitat.config.default import get_config

    # habitat-lab's own benchmark config, unchanged but for where its episodes and scenes are
    return get_config("benchmark/nav/pointnav/pointnav_habitat_test.yaml",
                      overrides=[f"habitat.dataset.data_path={SPLIT}", f"habitat.dataset.scenes_dir={SCENES_DIR}",
                                 "habitat.dataset.split=val", "habitat.environment.iterator_options.shuffle=False",
                                 *extra])


def test_import_surface_names_navbench():
    assert habitat_sim.__version__ == f"0.3.3+navbench.{navbench_version}"
    assert habitat_sim.__navbench__ == navbench_version
    # a feature habitat-lab probes with try/import is real or raises ImportError, never a placeholder
    with pytest.raises(ImportError):
        from habitat_sim.utils import profiling_utils  # noqa: F401
    from habitat_sim.utils.common import d3_40_colors_rgb
    assert d3_40_colors_rgb.shape == (40, 3)
    import magnum as mn
    assert mn.Vector3(0, 0.9, 0).y == pytest.approx(0.9)
    importlib.import_module("habitat.sims.habitat_simulator.habitat_simulator")


def test_habitat_baselines_imports():
    try:
        importlib.import_module("torchvision")
    except Exception as exc:  # PyPI's CUDA build beside torch+cpu raises RuntimeError at import
        pytest.skip(f"torchvision does not import here ({type(exc).__name__}): habitat_baselines needs it")
    importlib.import_module("habitat_baselines.run")


@pytest.fixture(scope="module")
def lab_env():
    with habitat.Env(config=_pointnav_config()) as env:
        yield env


def test_reset_geodesic_equals_navbench_d0(lab_env):
    from navbench.env.base import NavEnv
    from navbench.env.config import EnvConfig

    # navbench's own env with habitat-lab's agent body (radius 0.1, height 1.5, climb 0.2)
    ours = NavEnv(task="pointnav", dataset=SPLIT,
                  config=EnvConfig(agent_radius=0.1, agent_height=1.5, max_climb=0.2, rgb=False, depth=False))
    first_per_scene = {}
    for e in lab_env.episodes:
        first_per_scene.setdefault(e.scene_id, e)
    assert len(first_per_scene) >= 2
    try:
        for ep in [*first_per_scene.values(), next(iter(first_per_scene.values()))]:  # each scene, then back
            lab_env.current_episode = ep
            obs = lab_env.reset()
            lab_d0 = lab_env.get_metrics()["distance_to_goal"]
            _, info = ours.reset(options={"episode": ep.episode_id})
            assert lab_d0 == pytest.approx(info["geodesic_distance"], abs=1e-9), ep.episode_id
            assert obs["rgb"].shape == (256, 256, 3) and obs["depth"].shape == (256, 256, 1)
            state = lab_env.sim.get_agent_state()
            assert np.allclose(state.position, ep.start_position, atol=1e-5)
    finally:
        ours.close()


def test_shortest_path_follower_reaches_the_goal(lab_env):
    from habitat.tasks.nav.shortest_path_follower import ShortestPathFollower

    follower = ShortestPathFollower(lab_env.sim, goal_radius=0.2, return_one_hot=False)
    for _ in range(2):
        lab_env.reset()
        goal = lab_env.current_episode.goals[0].position
        while not lab_env.episode_over:
            lab_env.step(follower.get_next_action(goal))
        metrics = lab_env.get_metrics()
        assert metrics["success"] == 1.0, (lab_env.current_episode.episode_id, metrics)
        assert metrics["spl"] > 0.9


def test_objectnav_reset_geodesic_equals_navbench_d0_and_look_actions_run():
    from habitat.config.default import get_config

    from navbench.env.base import NavEnv
    from navbench.env.config import EnvConfig

    split = EPISODES_DIR / "objectnav" / "val_seen" / "val_seen.json.gz"
    cfg = get_config("benchmark/nav/objectnav/objectnav_hm3d.yaml",
                     overrides=[f"habitat.dataset.data_path={split}", f"habitat.dataset.scenes_dir={SCENES_DIR}",
                                "habitat.dataset.split=val_seen", "habitat.environment.iterator_options.shuffle=False"])
    # habitat-lab's HM3D ObjectNav body is navbench's default one (radius 0.18, height 0.88)
    ours = NavEnv(task="objectnav", dataset=split, config=EnvConfig(rgb=False, depth=False))
    with habitat.Env(config=cfg) as env:
        try:
            for _ in range(3):
                env.reset()
                ep = env.current_episode
                _, info = ours.reset(options={"episode": ep.episode_id})
                assert env.get_metrics()["distance_to_goal"] == pytest.approx(info["geodesic_distance"], abs=1e-9)
            before = env.sim.get_observations_at()["depth"]
            obs = env.step("look_up")
            assert not np.array_equal(obs["depth"], before)  # the tilt acts on the sensor nodes
        finally:
            ours.close()


def _bundled(config: str, task: str, split: str):
    from habitat.config.default import get_config

    data = EPISODES_DIR / task / split / f"{split}.json.gz"
    return data, get_config(config, overrides=[
        f"habitat.dataset.data_path={data}", f"habitat.dataset.scenes_dir={SCENES_DIR}",
        f"habitat.dataset.split={split}", "habitat.environment.iterator_options.shuffle=False"])


def test_imagenav_with_top_down_map_runs():
    _, cfg = _bundled("benchmark/nav/imagenav/imagenav_test.yaml", "imagenav", "val")
    with habitat.Env(config=cfg) as env:
        obs = env.reset()
        assert obs["imagegoal"].shape == (256, 256, 3) and obs["imagegoal"].any()
        env.step(1)
        tdm = env.get_metrics()["top_down_map"]
        assert tdm["map"].ndim == 2 and tdm["map"].any()  # drawn from get_topdown_view


def test_instance_imagenav_goal_image_is_navbenchs():
    from navbench.env.base import NavEnv

    data, cfg = _bundled("benchmark/nav/instance_imagenav/instance_imagenav_hm3d_v2.yaml", "instance_imagenav",
                         "val")
    from navbench.env.config import EnvConfig

    # habitat-lab's HM3D InstanceImageNav body: radius 0.17 m, height 1.41 m
    ours = NavEnv(task="instance_imagenav", dataset=data, config=EnvConfig(agent_radius=0.17, agent_height=1.41))
    with habitat.Env(config=cfg) as env:
        try:
            for _ in range(2):
                obs = env.reset()
                theirs, info = ours.reset(options={"episode": env.current_episode.episode_id})
                assert env.get_metrics()["distance_to_goal"] == pytest.approx(info["geodesic_distance"], abs=1e-9)
                a, b = obs["instance_imagegoal"], theirs["instance_imagegoal"]
                assert a.shape == b.shape
                # the goal camera goes through float32 scene-graph arithmetic: a few edge pixels may differ
                assert (a == b).all(axis=2).mean() > 0.98
            assert "instance_imagegoal_sensor" not in env.sim.sensors  # the temporary goal camera is removed
        finally:
            ours.close()


def _gym_env(config):
    from habitat.gym import make_gym_from_config

    return make_gym_from_config(config)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["forkserver", "spawn"])
def test_vector_env_workers_import_navbench_habitat_sim(method):
    from habitat.core.vector_env import VectorEnv

    cfg = _pointnav_config()
    envs = VectorEnv(make_env_fn=_gym_env, env_fn_args=[(cfg,), (cfg,)], multiprocessing_start_method=method)
    try:
        obs = envs.reset()
        steps = envs.step([1, 2])
        assert [o["rgb"].shape for o in obs] == [(256, 256, 3)] * 2
        assert all(s[0]["depth"].shape == (256, 256, 1) for s in steps)
    finally:
        envs.close()


def test_r2r_instruction_and_reset_geodesic_are_navbenchs():
    from habitat.tasks.nav.shortest_path_follower import ShortestPathFollower

    from navbench.env.base import NavEnv
    from navbench.env.config import EnvConfig

    data, cfg = _bundled("benchmark/nav/vln_r2r.yaml", "r2r_ce", "val")
    # vln_r2r.yaml keeps habitat-lab's default body: radius 0.1 m, height 1.5 m, climb 0.2 m
    ours = NavEnv(task="r2r_ce", dataset=data,
                  config=EnvConfig(agent_radius=0.1, agent_height=1.5, max_climb=0.2, rgb=False, depth=False))
    with habitat.Env(config=cfg) as env:
        try:
            obs = env.reset()
            ep = env.current_episode
            theirs, info = ours.reset(options={"episode": ep.episode_id})
            assert obs["instruction"]["text"] == ep.instruction.instruction_text == theirs["instruction"]["text"]
            assert env.get_metrics()["distance_to_goal"] == pytest.approx(info["geodesic_distance"], abs=1e-9)
            # habitat-lab's VLN success: STOP within success_distance (0.2 m in vln_r2r.yaml)
            follower = ShortestPathFollower(env.sim, goal_radius=0.15, return_one_hot=False)
            while not env.episode_over:
                env.step(follower.get_next_action(ep.goals[0].position))
            metrics = env.get_metrics()
            assert metrics["success"] == 1.0 and metrics["spl"] > 0.8, metrics
        finally:
            ours.close()
