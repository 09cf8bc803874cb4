"""Intervals and paired comparisons: reproduced from records, checked against independent implementations,
and the committed val_unseen runs compared as the README describes."""

import hashlib
import json
import math
import random

import numpy as np
import pytest

from navbench.cli import main
from navbench.episodes.io import load_dataset
from navbench.eval.provenance import run_protocol, sha256
from navbench.eval.rundir import read_records
from navbench.eval.runner import select_episodes
from navbench.eval.stats import (
    CI_METHOD,
    N_RESAMPLES,
    SEED,
    StatsError,
    add_intervals,
    compare_records,
    intervals,
    resample_means,
)
from navbench.metrics import aggregate
from navbench.paths import RESULTS_DIR, split_file

VAL_UNSEEN = RESULTS_DIR / "runs" / "objectnav" / "val_unseen"
METRICS = ("success", "spl", "soft_spl", "distance_to_goal")


def _records(name):
    return read_records(VAL_UNSEEN / name / "episodes.jsonl")


def loop_bootstrap(records, metric, draw_scenes, draw_uniforms, n=N_RESAMPLES):
    """The two-stage bootstrap written out as plain loops: scenes drawn with replacement, then for each
    drawn scene as many episodes as it has, episode floor(u * n_s); the mean over all drawn episodes.
    ``draw_scenes(k)`` and ``draw_uniforms(m)`` supply the random numbers."""
    by_scene = {}
    for r in sorted(records, key=lambda r: (r["scene_id"], r["episode_id"])):
        if not r.get("skipped"):
            by_scene.setdefault(r["scene_id"], []).append(float(r[metric]))
    scenes = [by_scene[s] for s in sorted(by_scene)]
    means = []
    for _ in range(n):
        drawn = draw_scenes(len(scenes)) if len(scenes) > 1 else [0]
        sizes = [len(scenes[j]) for j in drawn]
        u = draw_uniforms(sum(sizes))
        total, i = 0.0, 0
        for j, size in zip(drawn, sizes):
            for _ in range(size):
                total += scenes[j][int(math.floor(u[i] * size))]
                i += 1
        means.append(total / i)
    means.sort()

    def pct(q):  # numpy's default (linear) percentile
        pos = q / 100 * (len(means) - 1)
        lo = int(math.floor(pos))
        return means[lo] + (means[min(lo + 1, len(means) - 1)] - means[lo]) * (pos - lo)
    return [pct(2.5), pct(97.5)]


def test_intervals_match_a_loop_implementation_with_the_documented_draws():
    recs = _records("frontier")
    rng = np.random.default_rng(SEED)
    want = loop_bootstrap(recs, "spl", lambda k: [int(x) for x in rng.integers(0, k, size=k)],
                          lambda m: [float(x) for x in rng.random(m)])
    got = intervals(recs)["spl"]
    assert got == pytest.approx(want, abs=1e-12)
    assert got[0] < aggregate(recs)["spl"] < got[1]


def test_intervals_agree_with_the_same_bootstrap_on_another_generator():
    # Python's Mersenne twister instead of numpy's PCG64: the same bootstrap, other draws; percentile
    # intervals from 2,000 resamples agree to Monte Carlo error (a few tenths of a point here).
    recs = _records("frontier")
    py = random.Random(12345)
    other = loop_bootstrap(recs, "success", lambda k: [py.randrange(k) for _ in range(k)],
                           lambda m: [py.random() for _ in range(m)])
    ours = intervals(recs)["success"]
    assert ours == pytest.approx(other, abs=0.015)
    # and it is wider than the binomial interval that treats the 160 episodes as independent
    p, n = aggregate(recs)["success"], len(recs)
    assert ours[1] - ours[0] > 2 * 1.96 * math.sqrt(p * (1 - p) / n)


def test_one_scene_resamples_episodes_only():
    recs = [{"scene_id": "a", "episode_id": str(i), **{m: float(i % 3 == 0) for m in METRICS}} for i in range(30)]
    rng = np.random.default_rng(SEED)
    idx_means = [np.mean([recs_sorted["success"] for recs_sorted in
                          [sorted(recs, key=lambda r: r["episode_id"])[int(u * 30)] for u in rng.random(30)]])
                 for _ in range(N_RESAMPLES)]
    assert intervals(recs)["success"] == pytest.approx(list(np.percentile(idx_means, [2.5, 97.5])), abs=1e-12)


def test_summary_intervals_reproduce_exactly_from_the_records_in_any_order():
    recs = _records("memory")
    a, b = aggregate(recs, by="object_category"), aggregate(recs[::-1], by="object_category")
    add_intervals(a, recs, "object_category")
    add_intervals(b, list(reversed(recs)), "object_category")
    assert a == b and a["ci_method"] == CI_METHOD
    assert set(a["ci95"]) == set(METRICS) and all(lo <= a[m] <= hi for m, (lo, hi) in a["ci95"].items())
    lamp = a["by_object_category"]["lamp"]
    assert lamp["ci95"] == intervals([r for r in recs if r["object_category"] == "lamp"])


def test_skipped_episodes_are_left_out_and_no_records_give_no_interval():
    recs = _records("frontier")[:20]
    skipped = dict(recs[0], skipped=True, spl=123.0)
    assert intervals(recs[1:] + [skipped]) == intervals(recs[1:])
    assert intervals([]) is None


def test_a_run_against_itself_is_zero_and_a_shifted_run_is_detected():
    recs = _records("memory")
    same = compare_records(recs, recs)
    assert all(m["diff"] == 0 and m["ci95"] == [0, 0] and m["p_better"] == 0.5 for m in same["metrics"].values())
    better = [dict(r, spl=r["spl"] + 0.05) for r in recs]
    res = compare_records(recs, better)["metrics"]["spl"]
    assert res["diff"] == pytest.approx(0.05) and res["ci95"] == pytest.approx([0.05, 0.05])
    assert res["p_better"] == 1.0


def test_paired_interval_matches_a_loop_bootstrap_of_the_differences():
    base, other = _records("frontier"), _records("memory")
    o = {(r["scene_id"], r["episode_id"]): r for r in other}
    diffs = [dict(b, spl=o[(b["scene_id"], b["episode_id"])]["spl"] - b["spl"]) for b in base]
    rng = np.random.default_rng(SEED)
    want = loop_bootstrap(diffs, "spl", lambda k: [int(x) for x in rng.integers(0, k, size=k)],
                          lambda m: [float(x) for x in rng.random(m)])
    res = compare_records(base, other)
    assert res["metrics"]["spl"]["ci95"] == pytest.approx(want, abs=1e-12)
    boot = resample_means(np.array([d["spl"] for d in sorted(diffs, key=lambda r: (r["scene_id"], r["episode_id"]))]),
                          sorted(d["scene_id"] for d in diffs))
    assert res["metrics"]["spl"]["mde"] == pytest.approx(2.8 * boot[:, 0].std(ddof=1))


def test_memory_leads_frontier_in_spl_on_40_val_unseen_episodes(capsys):
    keep = {(e.scene_id, e.episode_id)
            for e in select_episodes(load_dataset(split_file("objectnav", "val_unseen")), None, per_scene=10)}
    def sub(name):
        return [r for r in _records(name) if (r["scene_id"], r["episode_id"]) in keep]
    res = compare_records(sub("frontier"), sub("memory"))
    assert res["episodes"] == 40 and res["scenes"] == 4
    assert res["metrics"]["spl"]["ci95"][0] > 0
    assert main(["compare", str(VAL_UNSEEN / "frontier"), str(VAL_UNSEEN / "memory"), "--per-scene", "10",
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["metrics"] == res["metrics"]


def test_pairing_drops_episodes_one_run_lacks_and_says_which():
    base, other = _records("frontier"), _records("memory")[5:]
    res = compare_records(base, other)
    assert res["episodes"] == 155 and len(res["dropped"]) == 5
    assert {d["reason"] for d in res["dropped"]} == {"only in base"}
    with pytest.raises(StatsError, match="share no"):
        compare_records(base[:3], [])


def test_cli_compare_json_self_and_refusals(copy_run, capsys):
    mem = VAL_UNSEEN / "memory"
    assert main(["compare", str(mem), str(mem), "--json", "--metric", "spl"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["episodes"] == 160 and doc["scenes"] == 4 and list(doc["metrics"]) == ["spl"]
    assert doc["metrics"]["spl"]["diff"] == 0 and doc["metrics"]["spl"]["ci95"] == [0, 0]
    far = copy_run(VAL_UNSEEN / "frontier", "frontier", success_distance=1.0)
    assert main(["compare", str(mem), str(far)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "success_distance 0.25 vs 1.0" in err[0]
    assert main(["compare", str(mem), str(far), "--mix-protocols"]) == 0
    assert "MIXED PROTOCOLS" in capsys.readouterr().out
    seen = RESULTS_DIR / "runs" / "objectnav" / "val_seen" / "memory"
    assert main(["compare", str(mem), str(seen)]) == 2
    err = capsys.readouterr().err  # BASE named first, and its file first
    assert f"{mem} vs {seen}: scored on different episode files (episode file episodes/objectnav/val_unseen/" in err


def test_cli_compare_text_names_the_dropped_episodes(copy_run, capsys):
    short = copy_run(VAL_UNSEEN / "memory", "memory")
    lines = (short / "episodes.jsonl").read_text().splitlines()
    (short / "episodes.jsonl").write_text("\n".join(lines[3:]) + "\n")
    assert main(["compare", str(VAL_UNSEEN / "frontier"), str(short)]) == 0
    out = capsys.readouterr().out
    assert "paired on 157 episodes in 4 scenes; dropped 3: 3 only in base" in out
    assert "SPL %" in out and "P(other better)" in out


def test_a_run_with_provenance_pairs_with_one_written_before_it(copy_run, capsys):
    old = copy_run(VAL_UNSEEN / "frontier", "frontier")
    (old / "provenance.json").unlink(missing_ok=True)
    new = copy_run(VAL_UNSEEN / "memory", "memory")
    proto = {k: v for k, v in run_protocol(old).items() if k != "derived"}
    doc = {"protocol": proto, "files": {"episodes": {"sha256": sha256(split_file("objectnav", "val_unseen"))}}}
    (new / "provenance.json").write_text(json.dumps(doc))
    assert main(["compare", str(old), str(new), "--metric", "spl"]) == 0
    assert "paired on 160 episodes" in capsys.readouterr().out
    (new / "provenance.json").write_text(json.dumps({**doc, "files": {"episodes": {"sha256": "0" * 64}}}))
    assert main(["compare", str(old), str(new)]) == 2
    assert "different episode files" in capsys.readouterr().err


def _tiny_run(d, n, success_distance=0.2, env=None, checkpoint="policies/a.pth", seed=0):
    """A run directory as `navbench run` writes one, of ``n`` PointNav episodes of one file (two scenes)."""
    from navbench.eval.provenance import protocol, protocol_id
    d.mkdir()
    proto = protocol("pointnav", success_distance, env)
    ckpt = {"path": checkpoint, "root": "navbench", "sha256": hashlib.sha256(checkpoint.encode()).hexdigest()}
    (d / "config.json").write_text(json.dumps({
        "task": "pointnav", "split": None, "episodes": "eps.json.gz", "agent": "pointnav", "seed": seed,
        "success_distance": success_distance, "env": env or {}, "agent_options": {"checkpoint": checkpoint,
                                                                                 "decoding": "sample"}}))
    (d / "provenance.json").write_text(json.dumps({
        "protocol": proto, "protocol_id": protocol_id(proto), "navbench": {"version": "0.1.0"},
        "versions": {"torch": "2.13.0+cpu"}, "run_on": {"device": "cpu", "precision": "fp32"},
        "files": {"episodes": {"path": "eps.json.gz", "root": "cwd", "sha256": "ab" * 32}, "checkpoint": ckpt}}))
    rng = np.random.default_rng(len(checkpoint) + n)
    rows = [{"scene_id": f"s{i % 2}", "episode_id": str(i), "success": float(s), "spl": float(s) * 0.8,
             "soft_spl": 0.5, "distance_to_goal": 1.0} for i, s in enumerate(rng.random(n) < 0.6)]
    (d / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return d


def test_compare_names_each_protocol_difference_in_its_refusal_mixed_text_and_json(tmp_path, capsys):
    a = _tiny_run(tmp_path / "a", 50)
    b = _tiny_run(tmp_path / "b", 50, success_distance=0.36, env={"max_steps": 300})
    assert main(["compare", str(a), str(b)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    reasons = ["max_steps 500 vs 300", "success_distance 0.2 vs 0.36"]
    assert len(err) == 1 and all(r in err[0] for r in reasons)
    assert main(["compare", str(a), str(b), "--mix-protocols", "--metric", "spl"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [line for line in out if line.startswith("protocol: ")] == [f"protocol: {r}" for r in reasons]
    assert main(["compare", str(a), str(b), "--mix-protocols", "--json", "--metric", "spl"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [x["line"] for x in doc["differences"]] == reasons and all(x["in_protocol"] for x in doc["differences"])
    assert doc["differences"][0]["base"] == 500 and doc["differences"][0]["other"] == 300
    # nothing else differs, so nothing else is said
    assert len(doc["differences"]) == 2


def test_compare_pairs_a_subset_on_the_common_episodes_and_names_both_checkpoints(tmp_path, capsys):
    a = _tiny_run(tmp_path / "a", 200, checkpoint="policies/pointnav_navbench.pth")
    b = _tiny_run(tmp_path / "b", 1000, checkpoint="policies/pointnav_v2.pth", seed=1)
    assert main(["compare", str(a), str(b), "--metric", "spl"]) == 0
    out = capsys.readouterr().out
    assert "differs: the same episodes file, 200 vs 1000 of its episodes: paired on the 200 both ran" in out
    assert "paired on 200 episodes in 2 scenes; dropped 800: 800 only in other" in out
    line = next(x for x in out.splitlines() if x.startswith("differs: checkpoint "))
    assert "policies/pointnav_navbench.pth (sha256 " in line and " vs policies/pointnav_v2.pth (sha256 " in line
    assert "differs: seed 0 vs 1" in out and "protocol:" not in out
    assert main(["compare", str(a), str(b), "--metric", "spl", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["episodes"] == 200
    fields = {x["field"]: x for x in doc["differences"]}
    assert set(fields) == {"episode_subset", "checkpoint", "seed"}
    assert (fields["episode_subset"]["base"], fields["episode_subset"]["other"]) == (200, 1000)
    # another episode file: refused, naming both files by checksum
    doc = json.loads((b / "provenance.json").read_text())
    doc["files"]["episodes"] = {"path": "other.json.gz", "root": "cwd", "sha256": "cd" * 32}
    (b / "provenance.json").write_text(json.dumps(doc))
    assert main(["compare", str(a), str(b)]) == 2
    err = capsys.readouterr().err
    assert "episode file eps.json.gz (sha256 abababababab) vs other.json.gz (sha256 cdcdcdcdcdcd)" in err


def test_first_per_scene_reads_a_run_s_file_with_its_task_s_reader():
    """An InstanceImageNav split (goals in content/ files, not ObjectNav's goals_by_category) pairs per house."""
    from navbench.eval.stats import first_per_scene
    from navbench.paths import RESULTS_DIR

    keys = first_per_scene(RESULTS_DIR / "runs" / "instance_imagenav" / "val" / "memory", 2)
    assert len(keys) == 8 and len({s for s, _ in keys}) == 4
