"""habitat-lab's sensors and the top-down map on navbench's habitat_sim, through habitat-lab's public API: ObjectNav
goals index ``semantic_scene`` as the ``top_down_map`` measure looks them up, and an ORTHOGRAPHIC sensor set from
habitat-lab's config. Skipped unless the ``habitat`` extra and ``compat/habitat-sim`` are installed
(``pip install -e ".[habitat]" -e compat/habitat-sim``)."""

import pytest

habitat_sim = pytest.importorskip("habitat_sim", reason="navbench-habitat-sim (compat/habitat-sim) not installed")
if not hasattr(habitat_sim, "__navbench__"):
    pytest.skip("habitat_sim here is not navbench's", allow_module_level=True)
habitat = pytest.importorskip("habitat", reason="habitat-lab (the habitat extra) not installed")

from navbench.paths import EPISODES_DIR, SCENES_DIR  # noqa: E402

SMALL = [f"habitat.simulator.agents.main_agent.sim_sensors.{s}_sensor.{k}={v}"
         for s in ("rgb", "depth") for k, v in (("width", 64), ("height", 48))]


def _objectnav(*extra: str):
    from habitat.config.default import get_config

    split = EPISODES_DIR / "objectnav" / "val_seen" / "val_seen.json.gz"
    return get_config("benchmark/nav/objectnav/objectnav_hm3d.yaml", overrides=[
        f"habitat.dataset.data_path={split}", f"habitat.dataset.scenes_dir={SCENES_DIR}",
        "habitat.dataset.split=val_seen", "habitat.environment.iterator_options.shuffle=False", *SMALL, *extra])


def test_objectnav_goals_index_the_semantic_scene_as_the_top_down_map_reads_them():
    cfg = _objectnav("+habitat/task/measurements@habitat.task.measurements.top_down_map=top_down_map")
    with habitat.Env(config=cfg) as env:
        for _ in range(3):
            env.reset()
            objects = env.sim.semantic_annotations().objects
            for goal in env.current_episode.goals:  # TopDownMap._draw_goals_aabb's lookup (habitat/tasks/nav/nav.py)
                assert int(objects[goal.object_id].id.split("_")[-1]) == int(goal.object_id)
                assert objects[goal.object_id].category.name() == env.current_episode.object_category
            env.step("move_forward")
            tdm = env.get_metrics()["top_down_map"]
            assert tdm["map"].ndim == 2 and tdm["map"].any()


def test_orthographic_sensor_from_habitat_labs_config():
    sub = "habitat.simulator.agents.main_agent.sim_sensors.{}_sensor.sensor_subtype=ORTHOGRAPHIC"
    with habitat.Env(config=_objectnav(sub.format("rgb"), sub.format("depth"))) as env:
        obs = env.reset()
        specs = {s.uuid: s for s in env.sim.config.agents[0].sensor_specifications}
        assert specs["depth"].sensor_subtype == habitat_sim.SensorSubType.ORTHOGRAPHIC
        assert obs["rgb"].shape == (48, 64, 3) and obs["depth"].shape == (48, 64, 1)
        raw = env.sim.get_sensor_observations()["depth"]  # metres, before habitat-lab's normalization
        assert raw.shape == (48, 64) and raw.max() > 0
