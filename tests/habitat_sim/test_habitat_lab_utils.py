"""habitat-lab's gym wrapper, top-down map and video utilities on navbench's habitat_sim, through habitat-lab's
public API on the bundled PointNav split. Skipped unless the ``habitat`` extra and ``compat/habitat-sim`` are
installed."""

import numpy as np
import pytest

habitat_sim = pytest.importorskip("habitat_sim", reason="navbench-habitat-sim (compat/habitat-sim) not installed")
if not hasattr(habitat_sim, "__navbench__"):
    pytest.skip("habitat_sim here is not navbench's", allow_module_level=True)
habitat = pytest.importorskip("habitat", reason="habitat-lab (the habitat extra) not installed")

from navbench.paths import EPISODES_DIR, SCENES_DIR  # noqa: E402

SPLIT = EPISODES_DIR / "pointnav" / "val" / "val.json.gz"


def _config():
    from habitat.config.default import get_config

    return get_config("benchmark/nav/pointnav/pointnav_habitat_test.yaml", overrides=[
        f"habitat.dataset.data_path={SPLIT}", f"habitat.dataset.scenes_dir={SCENES_DIR}", "habitat.dataset.split=val",
        "habitat.environment.iterator_options.shuffle=False",
        "+habitat/task/measurements@habitat.task.measurements.top_down_map=top_down_map",
        "+habitat/task/measurements@habitat.task.measurements.collisions=collisions"])


def test_gym_wrapper_renders_frames_with_the_top_down_map_into_a_video(tmp_path):
    from habitat.gym import make_gym_from_config
    from habitat.utils.visualizations.utils import images_to_video

    env = make_gym_from_config(_config())
    try:
        obs = env.reset()
        assert env.observation_space.contains(obs)
        frames = [env.render(mode="rgb_array")]
        for action in (1, 2, 1, 3, 1):  # forward, left, forward, right, forward
            obs, reward, done, info = env.step(action)
            assert env.observation_space.contains(obs) and np.isfinite(reward) and not done
            frames.append(env.render(mode="rgb_array"))
        tdm = info["top_down_map"]
        assert tdm["map"].ndim == 2 and (tdm["map"] > 0).any()
        h, w = tdm["map"].shape
        y, x = tdm["agent_map_coord"][0]
        assert 0 <= y < h and 0 <= x < w  # the agent is drawn inside the map
    finally:
        env.close()
    # the depth and rgb views side by side, then the top-down map fitted to their height
    assert all(f.shape == frames[0].shape and f.dtype == np.uint8 for f in frames)
    assert frames[0].shape[0] == 256 and frames[0].shape[1] > 2 * 256
    images_to_video(frames, str(tmp_path), "episode", fps=4, verbose=False)
    video = tmp_path / "episode.mp4"
    assert video.stat().st_size > 1000
    import imageio.v2 as imageio

    with imageio.get_reader(str(video)) as reader:
        assert sum(1 for _ in reader) == len(frames)
