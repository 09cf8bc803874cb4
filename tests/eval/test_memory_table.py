"""The memory/efficiency table reads storage, build time and latency from memory-agent records."""

import json

import pytest

from navbench.eval.memory_table import memory_row, memory_table


def _run(tmp_path, name, all_frames, logs):
    d = tmp_path / name
    d.mkdir()
    (d / "config.json").write_text(json.dumps({"agent_options": {"all_frames": all_frames, "keyframe_res": "160x120"}}))
    (d / "summary.json").write_text(json.dumps({"agent": name, "split": "val_unseen", "num_episodes": len(logs),
                                                "success": 0.5, "spl": 0.25}))
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
