"""CI smoke runs of the ObjectNav agents end to end: real env, oracle perception, the shipped policy.

Short (a 60-step cap) so they check the wiring, not the agents' quality: memory built and cached,
candidates localised, decisions logged, records written.
"""

import pytest

from navbench.agents.registry import make_frontier, make_memory, prebuild_memories
from navbench.episodes.io import load_dataset
from navbench.eval.runner import RunConfig, read_records, run, select_episodes
from navbench.paths import POLICIES_DIR, SCENES_DIR

CHECKPOINT = POLICIES_DIR / "pointnav_navbench.pth"


def _cfg(path, agent, memory_root):
    return RunConfig(task="objectnav", split=None, agent=agent, episodes=str(path), scene_dir=str(SCENES_DIR),
                     success_distance=0.25, limit=2, env={"max_steps": 60},
                     agent_options={"memory_root": str(memory_root), "checkpoint": str(CHECKPOINT)})


@pytest.mark.skipif(not CHECKPOINT.is_file(), reason="no shipped PointNav checkpoint")
def test_memory_agent_smoke(objectnav_file, tmp_path):
    cfg = _cfg(objectnav_file, "memory", tmp_path / "memory")
    episodes = select_episodes(load_dataset(objectnav_file), cfg.limit)
    prebuild_memories(cfg, episodes)
    built = list((tmp_path / "memory").iterdir())
    assert len(built) == 1  # one scene, one cached memory
    summary = run(cfg, make_memory, tmp_path / "run")
    recs = read_records(tmp_path / "run" / "episodes.jsonl")
    assert len(recs) == 2 and summary["num_episodes"] == 2
    for r in recs:
        assert r["num_steps"] <= 60
        log = r["log"]
        assert log["candidates"], "the oracle localiser must find the goal category in the memory"
        assert log["memory_keyframes"] > 0 and log["query_ms"] > 0
    # the second run reuses the cached memory instead of rebuilding it
    prebuild_memories(cfg, episodes)
    assert list((tmp_path / "memory").iterdir()) == built


@pytest.mark.skipif(not CHECKPOINT.is_file(), reason="no shipped PointNav checkpoint")
def test_frontier_agent_smoke(objectnav_file, tmp_path):
    cfg = _cfg(objectnav_file, "frontier", tmp_path / "memory")
    cfg.limit = 1
    run(cfg, make_frontier, tmp_path / "run")
    (rec,) = read_records(tmp_path / "run" / "episodes.jsonl")
    assert rec["num_steps"] <= 60 and rec["log"]["events"][0]["step"] >= 1
