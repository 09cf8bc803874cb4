"""The two oracles on PointNav: the geodesic one plans on the true map, the optimistic one on what it saw."""

from navbench.agents.registry import make_optimistic, make_oracle
from navbench.cli import main
from navbench.eval.runner import RunConfig, read_records, run
from navbench.paths import SCENES_DIR


def _run(path, factory, out):
    cfg = RunConfig(task="pointnav", split=None, agent="x", episodes=str(path), scene_dir=str(SCENES_DIR),
                    success_distance=0.2)
    run(cfg, factory, out)
    return {r["episode_id"]: r for r in read_records(out / "episodes.jsonl")}


def test_optimistic_oracle_reaches_every_goal_on_paths_no_shorter_than_the_true_oracles(pointnav_file, tmp_path):
    true_map = _run(pointnav_file, make_oracle, tmp_path / "oracle")
    seen_map = _run(pointnav_file, make_optimistic, tmp_path / "optimistic")
    assert seen_map.keys() == true_map.keys()
    for k, r in seen_map.items():
        assert r["success"] == 1.0 and r["stop_called"]
        # planning on less knowledge can only lengthen the path (one step of slack: both stop inside 0.2 m)
        assert r["path_length"] >= true_map[k]["path_length"] - 0.25


def test_optimistic_oracle_plans_on_what_its_depth_frames_showed(pointnav_file):
    from navbench.env.pointnav import PointNavEnv
    from navbench.episodes.io import load_dataset

    ds = load_dataset(pointnav_file)
    cfg = RunConfig(task="pointnav", split=None, agent="optimistic", episodes=str(pointnav_file),
                    scene_dir=str(SCENES_DIR), success_distance=0.2)
    agent = make_optimistic(cfg)
    env = PointNavEnv(ds, scene_dir=SCENES_DIR, config=cfg.env_config(agent.sensors))
    obs, _ = env.reset(options={"episode": ds.episodes[0]})
    agent.reset(ds.episodes[0])
    assert not agent._follower.mask.seen.any()
    agent.act(obs)
    seen = agent._follower.mask.seen
    assert 0 < seen.sum() < seen.size // 2  # one frame's wedge, not the whole house
    env.close()


def test_optimistic_oracle_refuses_objectnav(tmp_path, capsys):
    assert main(["run", "--split", "val_unseen", "--agent", "optimistic", "--limit", "1", "--out",
                 str(tmp_path / "run")]) == 2
    assert "--task pointnav" in capsys.readouterr().err
