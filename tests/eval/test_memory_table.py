"""The memory/efficiency table reads storage, build time and latency from memory-agent records."""

import json

import pytest

from navbench.eval.memory_table import memory_row, memory_table


def _run(tmp_path, name, all_frames, logs):
    d = tmp_path / name
    d.mkdir()
    (d / "config.json").write_text(json.dumps({"agent_options": {"all_frames": all_frames, "keyframe_res": "160x120"}}))
    (d / "summary.json").write_text(json.dumps({"agent": name, "split": "val_unseen", "num_episodes": len(logs),
                                                "success": 0.5, "spl": 0.25, "soft_spl": 0.5,
                                                "distance_to_goal": 1.0}))
    with open(d / "episodes.jsonl", "w") as f:
        for scene, log in logs:
            f.write(json.dumps({"episode_id": str(len(log)), "scene_id": scene, "log": log}) + "\n")
    return d


def test_per_scene_means_and_latency(tmp_path):
    a = {"memory_keyframes": 100, "memory_frames": 400, "memory_bytes": 2e6, "memory_build_s": 2.0, "query_ms": 10}
    b = {"memory_keyframes": 300, "memory_frames": 800, "memory_bytes": 4e6, "memory_build_s": 4.0, "query_ms": 30}
    d = _run(tmp_path, "memory", False, [("s1", a), ("s1", {**a, "query_ms": 20}), ("s2", b)])
    row = memory_row(d)
    assert row["stored frames / scene"] == 200  # scene means, not episode means
    assert row["storage MB / scene"] == pytest.approx(3.0)
    assert row["build s / scene"] == pytest.approx(3.0)
    assert row["query ms"] == pytest.approx(20.0)
    assert row["frames"] == "keyframes" and row["resolution"] == "160x120"
    assert row["SR"] == 50.0 and row["SPL"] == 25.0
    assert "| memory " in memory_table([d])


def test_a_run_without_memory_logs_is_refused(tmp_path):
    d = _run(tmp_path, "oracle", False, [("s1", {})])
    with pytest.raises(ValueError, match="not a memory-agent run"):
        memory_row(d)


def test_first_n_scores_runs_with_different_limits_on_the_same_episodes(tmp_path):
    from navbench.episodes.io import load_dataset
    from navbench.paths import split_file

    path = split_file("objectnav", "val_unseen")
    eps = load_dataset(path).episodes[:3]
    d = tmp_path / "memory"
    d.mkdir()
    (d / "config.json").write_text(json.dumps({"task": "objectnav", "split": "val_unseen", "episodes": str(path),
                                               "agent": "memory", "agent_options": {}}))
    (d / "summary.json").write_text(json.dumps({"agent": "memory", "split": "val_unseen", "num_episodes": 3,
                                                "success": 2 / 3, "spl": 0.5, "soft_spl": 2 / 3,
                                                "distance_to_goal": 1 / 3}))
    log = {"memory_keyframes": 1, "memory_frames": 2, "memory_bytes": 1e6, "memory_build_s": 1.0, "query_ms": 5}
    with open(d / "episodes.jsonl", "w") as f:
        for e, ok in zip(eps, (1.0, 0.0, 1.0)):
            f.write(json.dumps({"episode_id": e.episode_id, "scene_id": e.scene_id, "success": ok, "spl": ok / 2,
                                "soft_spl": ok, "distance_to_goal": 1 - ok, "log": log}) + "\n")
    assert memory_row(d)["SR"] == pytest.approx(200 / 3)
    first2 = memory_row(d, first=2)
    assert first2["SR"] == 50.0 and first2["SPL"] == 25.0 and first2["episodes"] == 2
    with pytest.raises(ValueError, match="of the first 5 episodes"):
        memory_row(d, first=5)
