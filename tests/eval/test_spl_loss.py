import json

import pytest

from navbench.eval.spl_loss import episode_measures, main, reversals, revisits, run_summary


def test_reversals_count_turns_that_undo_the_turn_before():
    assert reversals("1232311") == 3
    assert reversals("2222") == 0


def test_revisits_count_forward_steps_back_onto_an_earlier_position():
    # east 2 steps, turn around twice, back west 2 steps: the second step west ends where the agent started
    poses = [[0, 0, 0], [0.25, 0, 0], [0.5, 0, 0], [0.5, 0, 1], [0.5, 0, 2], [0.25, 0, 2], [0.0, 0, 2]]
    assert revisits("112211", poses) == 2  # both steps back end on positions held 4+ steps before
    assert revisits("112211", [[0.25 * i, 0, 0] for i in range(7)]) == 0


def _record(i, success, spl, stop, path=5.0):
    return {"episode_id": str(i), "scene_id": "s", "split": "val", "task": "pointnav", "agent": "a",
            "success": success, "spl": spl, "stop_called": stop, "geodesic_distance": 4.0, "path_length": path,
            "num_steps": 3, "collisions": i % 2, "distance_to_goal": 0.1, "trace": {"actions": "120"}}


def test_the_shortfall_splits_into_failures_and_path(tmp_path):
    recs = [_record(0, 1.0, 0.8, True), _record(1, 0.0, 0.0, True), _record(2, 0.0, 0.0, False),
            _record(3, 1.0, 1.0, True, path=4.0)]
    (tmp_path / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    s = run_summary(tmp_path)
    assert s["SPL"] == pytest.approx(45.0)
    assert s["lost: early stop"] == 25.0 and s["lost: timeout"] == 25.0 and s["lost: path"] == pytest.approx(5.0)
    assert s["SPL"] + s["lost: early stop"] + s["lost: timeout"] + s["lost: path"] == pytest.approx(100.0)
    assert s["path ratio median"] == pytest.approx((5 / 4 + 1) / 2)
    assert s["path lost, successes that collided"] == 0.0  # episode 0 (no collision) lost the 5 points
    assert episode_measures(recs[2])["outcome"] == "timeout"


def test_a_missing_run_is_one_line_and_exit_2(tmp_path, capsys):
    assert main([str(tmp_path / "nope")]) == 2
    assert capsys.readouterr().err.count("\n") == 1
