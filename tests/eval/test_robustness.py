"""The runner's robustness: failed episodes recorded (not fatal), dying workers retried, shards and merge,
the run directory's lock, refusals and repairs, progress."""

import dataclasses
import errno
import io
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from navbench.agents.oracle import OracleAgent
from navbench.cli import main
from navbench.episodes.io import load_dataset
from navbench.eval import rundir
from navbench.eval.merge import merge
from navbench.eval.run_progress import Progress
from navbench.eval.runner import Execution, RunConfig, RunError, comparable, read_records, run, shard_of
from navbench.paths import SCENES_DIR


def _cfg(path, **kw):
    base = dict(task="pointnav", split=None, agent="oracle", episodes=str(path), scene_dir=str(SCENES_DIR),
                success_distance=0.2)
    base.update(kw)
    return RunConfig(**base)


def _ids(path):
    return [e.episode_id for e in load_dataset(path).episodes]


# Agents for the tests: built in worker processes from the run's config, so what they do to which
# episode comes in agent_options ({"mode": ..., "episode": ..., "dir": ...}).
class Misbehaving(OracleAgent):
    def __init__(self, cfg):
        super().__init__(cfg.scene_dir, cfg.success_distance)
        self.opts = cfg.agent_options
        self.episode_id = None

    def reset(self, episode):
        self.episode_id = episode.episode_id
        if self.opts.get("modes", {}).get(self.episode_id) in ("die_once", "die"):  # count the attempts
            marks = Path(self.opts["dir"])
            self.attempt = len(list(marks.glob(f"{self.episode_id}.*")))
            (marks / f"{self.episode_id}.{self.attempt}").touch()
        super().reset(episode)

    def act(self, obs):
        o = self.opts
        mode = o.get("modes", {}).get(self.episode_id)
        if mode == "raise":
            raise ValueError("the agent is confused\nsecond line")
        if mode == "seven":
            return 7
        if mode == "hang":
            time.sleep(60)
        if mode == "slow":
            time.sleep(1.0)
        if mode == "die" or (mode == "die_once" and self.attempt == 0):
            os.kill(os.getpid(), signal.SIGKILL)
        return super().act(obs)


def _misbehaving(cfg):
    return Misbehaving(cfg)


# ------------------------------------------------------------------------------------- crash isolation
def test_sigkilled_worker_mid_episode_is_retried_and_the_run_finishes(pointnav_file, tmp_path):
    ids = _ids(pointnav_file)
    opts = {"modes": {ids[2]: "die_once"}, "dir": str(tmp_path)}
    summary = run(_cfg(pointnav_file, agent_options=opts), _misbehaving, tmp_path / "run",
                  execution=Execution(workers=2))
    recs = read_records(tmp_path / "run" / "episodes.jsonl")
    assert len(list(tmp_path.glob(f"{ids[2]}.*"))) == 2  # killed once, then run again on a fresh worker
    assert sorted(r["episode_id"] for r in recs) == sorted(ids)  # exact count, no duplicates
    assert not any(r.get("failed") for r in recs) and summary["success"] == 1.0 and summary["num_failed"] == 0


@pytest.mark.slow
def test_a_worker_that_keeps_dying_fails_its_episode_after_the_retries(pointnav_file, tmp_path, capsys):
    ids = _ids(pointnav_file)
    opts = {"modes": {ids[1]: "die"}, "dir": str(tmp_path)}
    summary = run(_cfg(pointnav_file, agent_options=opts), _misbehaving, tmp_path / "run",
                  execution=Execution(workers=2, retries=1))
    recs = {r["episode_id"]: r for r in read_records(tmp_path / "run" / "episodes.jsonl")}
    assert len(recs) == 6 and len(list(tmp_path.glob(f"{ids[1]}.*"))) == 2  # first try + 1 retry
    bad = recs[ids[1]]
    assert bad["failed"] and bad["failure_reason"] == "worker died (signal 9)"
    assert bad["success"] == bad["spl"] == bad["soft_spl"] == 0.0 and bad["num_steps"] == 0
    assert bad["distance_to_goal"] == pytest.approx(bad["geodesic_distance"]) and bad["geodesic_distance"] > 0
    assert summary["num_failed"] == 1 and summary["success"] == pytest.approx(5 / 6)
    assert summary["failed_episodes"] == [{"scene_id": bad["scene_id"], "episode_id": ids[1],
                                           "failure_reason": "worker died (signal 9)"}]


def _check_failed(r, reason):
    assert r["failed"] and r["success"] == 0.0 and r["spl"] == 0.0 and r["soft_spl"] == 0.0
    assert r["num_steps"] == 0 and r["distance_to_goal"] == pytest.approx(r["geodesic_distance"])
    assert r["failure_reason"] == reason or (reason.endswith("*") and r["failure_reason"].startswith(reason[:-1]))


def test_an_agent_that_raises_or_returns_7_fails_its_episodes_not_the_run(pointnav_file, tmp_path):
    ids = _ids(pointnav_file)
    modes = {ids[0]: "raise", ids[1]: "seven"}
    summary = run(_cfg(pointnav_file, agent_options={"modes": modes}), _misbehaving, tmp_path / "run")
    recs = {r["episode_id"]: r for r in read_records(tmp_path / "run" / "episodes.jsonl")}
    assert len(recs) == 6 and summary["complete"] and summary["num_failed"] == 2
    _check_failed(recs[ids[0]], "ValueError: the agent is confused")
    _check_failed(recs[ids[1]], "invalid action 7 (expected 0-3)")
    assert all(recs[i]["success"] == 1.0 and "failed" not in recs[i] for i in ids[2:])
    assert summary["success"] == pytest.approx(4 / 6) and summary["spl"] < 4 / 6


def test_a_step_slower_than_the_limit_fails_its_episode(pointnav_file, tmp_path):
    from navbench.eval.worker import Clock, make_env, run_episode
    ds = load_dataset(pointnav_file)
    cfg = _cfg(pointnav_file, agent_options={"modes": {ds.episodes[0].episode_id: "slow"}})
    rec = run_episode(make_env(cfg, ds, ()), Misbehaving(cfg), ds.episodes[0], cfg, Clock(0.5))
    _check_failed(rec, "step took 1.*")
    assert rec["failure_reason"].endswith(" s (limit 0.5 s)")


@pytest.mark.slow
def test_a_hung_agent_call_is_killed_and_fails_its_episode(pointnav_file, tmp_path):
    ids = _ids(pointnav_file)
    modes = {ids[0]: "raise", ids[1]: "seven", ids[3]: "hang"}
    summary = run(_cfg(pointnav_file, agent_options={"modes": modes}), _misbehaving,
                  tmp_path / "run", execution=Execution(workers=2, step_timeout=0.5))
    recs = {r["episode_id"]: r for r in read_records(tmp_path / "run" / "episodes.jsonl")}
    assert len(recs) == 6 and summary["complete"] and summary["num_failed"] == 3
    _check_failed(recs[ids[0]], "ValueError: the agent is confused")
    _check_failed(recs[ids[1]], "invalid action 7 (expected 0-3)")
    _check_failed(recs[ids[3]], "step took *")
    assert recs[ids[3]]["failure_reason"].endswith(" s (limit 0.5 s)")
    assert all(recs[ids[i]]["success"] == 1.0 for i in (2, 4, 5))


def test_failures_exit_3_and_fail_fast_stops_with_exit_2(pointnav_file, tmp_path, monkeypatch, capsys):
    from navbench.agents import registry
    ids = _ids(pointnav_file)
    monkeypatch.setitem(registry.AGENTS, "oracle", dataclasses.replace(registry.AGENTS["oracle"], factory=lambda cfg: (
        Misbehaving(type("C", (), {"scene_dir": cfg.scene_dir, "success_distance": cfg.success_distance,
                                   "agent_options": {"modes": {ids[2]: "raise"}}})))))
    argv = ["run", "--episodes", str(pointnav_file), "--agent", "oracle", "--workers", "1", "-q"]
    assert main(argv + ["--out", str(tmp_path / "a")]) == 3
    assert "1 episode(s) failed" in capsys.readouterr().err
    assert main(argv + ["--out", str(tmp_path / "b"), "--fail-fast"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"episode {ids[2]} " in err[0] and "ValueError: the agent is confused" in err[0]
    kept = read_records(tmp_path / "b" / "episodes.jsonl")
    assert len(kept) == 2 and not any(r.get("failed") for r in kept)  # those before it, not the failure
    # --resume reruns a failed episode (here it fails again: still one record for it)
    assert main(argv + ["--out", str(tmp_path / "a"), "--resume"]) == 3
    recs = read_records(tmp_path / "a" / "episodes.jsonl")
    assert len(recs) == 6 and len({r["episode_id"] for r in recs}) == 6


class _BatchOfOracles:
    """A batched agent made of oracles; returns 7 for one episode's slot."""
    sensors = ()

    def __init__(self, cfg, bad):
        self.num_envs = cfg.envs_per_worker
        self.agents = [OracleAgent(cfg.scene_dir, cfg.success_distance) for _ in range(self.num_envs)]
        self.bad, self.ids = bad, [None] * self.num_envs

    def reset_env(self, i, episode):
        self.ids[i] = episode.episode_id
        self.agents[i].reset(episode)

    def act_batch(self, observations):
        return [None if o is None else 7 if self.ids[i] == self.bad else a.act(o)
                for i, (a, o) in enumerate(zip(self.agents, observations))]


def test_batched_invalid_action_fails_only_its_slot(pointnav_file, tmp_path):
    bad = _ids(pointnav_file)[4]
    run(_cfg(pointnav_file, envs_per_worker=3), lambda cfg: _BatchOfOracles(cfg, bad), tmp_path / "run")
    recs = {r["episode_id"]: r for r in read_records(tmp_path / "run" / "episodes.jsonl")}
    assert len(recs) == 6 and recs[bad]["failure_reason"] == "invalid action 7 (expected 0-3)"
    assert all(r["success"] == 1.0 for i, r in recs.items() if i != bad)


def test_a_batched_worker_refills_free_slots_until_the_driver_has_nothing_left(pointnav_file):
    """``EpisodeWorker.run(keys, more=)``: once ``keys`` are used up, each free slot asks ``more()`` for the
    next keys, until it returns none; it is not asked again after that."""
    from navbench.eval.worker import EpisodeWorker

    keys = [(e.scene_id, e.episode_id) for e in load_dataset(pointnav_file).episodes]
    handed, calls, records = [[k] for k in keys[2:]], [], []

    def more():
        calls.append(len(handed))
        return handed.pop(0) if handed else []

    with EpisodeWorker(_cfg(pointnav_file, envs_per_worker=3), lambda cfg: _BatchOfOracles(cfg, None)) as worker:
        worker.run(keys[:2], records.append, more=more)
    assert sorted(r["episode_id"] for r in records) == sorted(k[1] for k in keys)
    assert all(r["success"] == 1.0 for r in records)
    assert calls == [4, 3, 2, 1, 0]  # the third slot's first ask, the refills, then one empty answer


class _LogBreaks(OracleAgent):
    """An oracle whose decision log cannot be fetched (a remote agent's server gone after the last step)."""

    def episode_log(self):
        raise ConnectionError("log broke")


class _BatchLogBreaks(_BatchOfOracles):
    def slot(self, i):
        return _LogBreaks(self.agents[i].scene_dir, self.agents[i].success_distance) if i == 1 else self.agents[i]


@pytest.mark.parametrize("envs", [1, 3])
def test_an_episode_whose_log_fails_is_a_failed_record_not_a_lost_run(pointnav_file, tmp_path, envs):
    """A failure after the last step (fetching the agent's episode log) fails that episode only."""
    if envs == 1:
        factory = lambda cfg: _LogBreaks(cfg.scene_dir, cfg.success_distance)  # noqa: E731
    else:
        factory = lambda cfg: _BatchLogBreaks(cfg, None)  # noqa: E731
    run(_cfg(pointnav_file, envs_per_worker=envs), factory, tmp_path / "run")
    recs = read_records(tmp_path / "run" / "episodes.jsonl")
    failed = [r for r in recs if r.get("failed")]
    assert len(recs) == 6 and len({r["episode_id"] for r in recs}) == 6
    assert failed and all(r["failure_reason"] == "ConnectionError: log broke" for r in failed)
    assert len(failed) == 6 if envs == 1 else 0 < len(failed) < 6  # batched: slot 1's episodes only


# ---------------------------------------------------------------------------------------- shards
def test_shards_are_disjoint_blocks_covering_every_episode_once():
    for n_eps in (0, 1, 5, 12, 13):
        eps = list(range(n_eps))
        for n in (1, 2, 3, 7):
            parts = [shard_of(eps, f"{i}/{n}") for i in range(1, n + 1)]
            assert sum(parts, []) == eps
            assert max(map(len, parts)) - min(map(len, parts)) <= 1
    with pytest.raises(RunError, match="I/N"):
        shard_of([1], "x")
    with pytest.raises(RunError, match="between 1 and N"):
        shard_of([1], "4/3")


def test_shards_merged_equal_the_unsharded_run(pointnav_file, tmp_path, capsys):
    full = run(_cfg(pointnav_file), _misbehaving, tmp_path / "full")
    dirs = [tmp_path / f"s{i}" for i in (1, 2, 3)]
    for i, d in enumerate(dirs, 1):
        run(_cfg(pointnav_file, shard=f"{i}/3"), _misbehaving, d)
        assert json.loads((d / "config.json").read_text())["shard"] == f"{i}/3"
    assert main(["merge", *map(str, dirs), "--out", str(tmp_path / "merged")]) == 0
    assert comparable(read_records(tmp_path / "merged" / "episodes.jsonl")) == \
        comparable(read_records(tmp_path / "full" / "episodes.jsonl"))
    assert json.loads((tmp_path / "merged" / "summary.json").read_text()) == full
    assert json.loads((tmp_path / "merged" / "config.json").read_text()) == \
        json.loads((tmp_path / "full" / "config.json").read_text())
    capsys.readouterr()

    run(_cfg(pointnav_file, shard="1/3", seed=5), _misbehaving, tmp_path / "other_seed")
    dup = tmp_path / "dup"
    dup.mkdir()
    for f in ("config.json", "episodes.jsonl", "provenance.json"):
        (dup / f).write_text((dirs[0] / f).read_text().replace('"1/3"', '"2/3"'))
    for argv, needle in [
        ([dirs[0], dirs[1]], "are in none of the runs"),
        ([dirs[0], dirs[1], dirs[2], dirs[0]], "given twice"),
        ([dirs[0], dup, dirs[2]], "is also in"),
        ([tmp_path / "other_seed", dirs[1], dirs[2]], "differs from"),
        ([dirs[0], dirs[1], dirs[2], tmp_path / "nowhere"], "missing (not a run directory)"),
    ]:
        assert main(["merge", *map(str, argv), "--out", str(tmp_path / "m2")]) == 2, needle
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0], (needle, err)
    assert not (tmp_path / "m2" / "episodes.jsonl").exists()
    with pytest.raises(RunError, match="already holds a run"):
        merge(dirs, tmp_path / "merged")


# -------------------------------------------------------------------------------------- run directory
def _records_bytes(out):
    return (out / "episodes.jsonl").read_bytes()


def test_a_run_directory_is_never_replaced_silently(pointnav_file, tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["run", "--episodes", str(pointnav_file), "--agent", "oracle", "--workers", "1", "-q", "--out", str(out)]
    assert main(argv + ["--limit", "3"]) == 0
    before = _records_bytes(out)
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "already holds a run (3 records)" in err[0] and "--resume" in err[0]
    assert _records_bytes(out) == before
    assert main(argv + ["--overwrite", "--limit", "1"]) == 0
    assert len(read_records(out / "episodes.jsonl")) == 1


def test_a_second_run_on_a_locked_directory_refuses_naming_the_holder(pointnav_file, tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / ".lock").write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname()}))
    with pytest.raises(RunError, match=f"another run is using this directory \\(PID {os.getpid()} "):
        run(_cfg(pointnav_file, limit=1), _misbehaving, out)
    assert not (out / "episodes.jsonl").exists()


def test_a_stale_lock_from_a_killed_run_is_taken_over(pointnav_file, tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    out = tmp_path / "run"
    out.mkdir()
    (out / ".lock").write_text(json.dumps({"pid": dead.pid, "host": socket.gethostname()}))
    notes = []
    run(_cfg(pointnav_file, limit=2), _misbehaving, out, note=notes.append)
    assert len(read_records(out / "episodes.jsonl")) == 2
    assert any("stale lock" in n and str(dead.pid) in n for n in notes)
    assert not (out / ".lock").exists()  # released at the end


def test_resume_repairs_a_truncated_line_and_a_duplicate(pointnav_file, tmp_path):
    out = tmp_path / "run"
    run(_cfg(pointnav_file, limit=3), _misbehaving, out)
    lines = (out / "episodes.jsonl").read_text().splitlines(keepends=True)
    (out / "episodes.jsonl").write_text(lines[0] + lines[1] + lines[0] + lines[2][:25])
    notes = []
    run(_cfg(pointnav_file), _misbehaving, out, resume=True, note=notes.append)
    text = (out / "episodes.jsonl").read_text()
    recs = read_records(out / "episodes.jsonl")
    assert len(recs) == 6 and len({r["episode_id"] for r in recs}) == 6 and text.endswith("\n")
    assert text.startswith(lines[0] + lines[1])  # kept records unchanged, the duplicate gone
    assert any("truncated last line" in n for n in notes)
    assert any("1 duplicated record(s) kept once" in n for n in notes)


def test_resuming_a_finished_batched_run_runs_nothing_and_keeps_its_records(pointnav_file, tmp_path):
    """Nothing left to run (no episodes, so no tasks to size) with several slots per worker is not an error."""
    from navbench.agents.registry import make_pointnav
    cfg = _cfg(pointnav_file, agent="pointnav", envs_per_worker=3, env={"max_steps": 20})
    run(cfg, make_pointnav, tmp_path / "run", execution=Execution(workers=2))
    before = (tmp_path / "run" / "episodes.jsonl").read_text()
    summary = run(cfg, make_pointnav, tmp_path / "run", resume=True, execution=Execution(workers=2))
    assert summary["num_episodes"] == 6 and (tmp_path / "run" / "episodes.jsonl").read_text() == before


def test_resume_refuses_a_record_of_an_episode_not_in_the_dataset(pointnav_file, tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["run", "--episodes", str(pointnav_file), "--agent", "oracle", "--workers", "1", "-q", "--out", str(out)]
    assert main(argv + ["--limit", "2"]) == 0
    rec = read_records(out / "episodes.jsonl")[0]
    with open(out / "episodes.jsonl", "a") as fh:
        fh.write(json.dumps(dict(rec, episode_id="ghost")) + "\n")
    before = _records_bytes(out)
    assert main(argv + ["--resume"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "episode 'ghost'" in err[0] and "not in" in err[0]
    assert _records_bytes(out) == before


def test_resume_refuses_a_hand_edited_or_corrupt_config(pointnav_file, tmp_path):
    out = tmp_path / "run"
    run(_cfg(pointnav_file, limit=2), _misbehaving, out)
    cfg = json.loads((out / "config.json").read_text())
    (out / "config.json").write_text(json.dumps(dict(cfg, seed=9)))
    with pytest.raises(RunError, match="differs in seed"):
        run(_cfg(pointnav_file), _misbehaving, out, resume=True)
    (out / "config.json").write_text("{not json")
    with pytest.raises(RunError, match="corrupt JSON"):
        run(_cfg(pointnav_file), _misbehaving, out, resume=True)
    (out / "config.json").unlink()
    with pytest.raises(RunError, match="config.json: missing"):
        run(_cfg(pointnav_file), _misbehaving, out, resume=True)
    assert len(read_records(out / "episodes.jsonl")) == 2


def test_read_only_output_directory_is_one_line(pointnav_file, tmp_path, monkeypatch, capsys):
    def refuse(path, text):
        raise PermissionError(errno.EACCES, "Permission denied", str(path))

    monkeypatch.setattr(rundir, "_create_exclusive", refuse)  # root ignores a chmod'ed directory
    assert main(["run", "--episodes", str(pointnav_file), "--agent", "oracle", "--workers", "1", "-q",
                 "--out", str(tmp_path / "ro")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(tmp_path / "ro") in err[0] and "Permission denied" in err[0]


def test_a_full_disk_leaves_no_partial_record(pointnav_file, tmp_path, monkeypatch, capsys):
    calls = []

    def write(fd, data):
        calls.append(1)
        if len(calls) == 3:  # the third record: half of it reaches the disk, then ENOSPC
            os.write(fd, data[:len(data) // 2])
            raise OSError(errno.ENOSPC, "No space left on device")
        return os.write(fd, data)

    monkeypatch.setattr(rundir, "_write", write)
    out = tmp_path / "run"
    argv = ["run", "--episodes", str(pointnav_file), "--agent", "oracle", "--workers", "1", "-q", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "disk full" in err[0] and "episodes.jsonl" in err[0]
    text = (out / "episodes.jsonl").read_text()
    assert text.count("\n") == 2 and all(json.loads(line) for line in text.splitlines())
    monkeypatch.undo()
    assert main(argv + ["--resume"]) == 0
    recs = read_records(out / "episodes.jsonl")
    assert len(recs) == 6 and len({r["episode_id"] for r in recs}) == 6


# ------------------------------------------------------------------------------------------ progress
def test_progress_lines_off_a_terminal_and_quiet(pointnav_file, tmp_path, capsys):
    buf = io.StringIO()
    p = Progress(stream=buf, tty=False)
    base = {"scene_id": "s", "episode_id": "1", "success": 1.0, "spl": 0.5}
    p(base, 4, 6)  # a resumed run: 3 were done before
    p(dict(base, episode_id="2", failed=True, failure_reason="ValueError: x", success=0.0, spl=0.0), 5, 6)
    lines = buf.getvalue().splitlines()
    assert lines[0].startswith("[4/6] ") and "ep/s, ETA " in lines[0] and "0 failed" in lines[0]
    assert "1 failed" in lines[1] and "FAILED: ValueError: x" in lines[1]
    assert main(["run", "--episodes", str(pointnav_file), "--agent", "oracle", "--workers", "1", "--limit", "2",
                 "-q", "--out", str(tmp_path / "q")]) == 0
    assert capsys.readouterr().err == ""


# ------------------------------------------------------------------------------------- determinism
DETERMINISM_RUN = """
import sys
from navbench.agents.registry import make_pointnav
from navbench.eval.runner import Execution, RunConfig, run
if __name__ == "__main__":  # not in the spawned workers
    workers, envs, out = int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
    cfg = RunConfig(task="pointnav", split=None, agent="pointnav", episodes=sys.argv[1], scene_dir=sys.argv[2],
                    success_distance=0.2, envs_per_worker=envs, env={"max_steps": 40},
                    agent_options={"decoding": "least-tried"})
    run(cfg, make_pointnav, out, resume=len(sys.argv) > 6, execution=Execution(workers=workers))
"""


def _sorted_lines(out):
    """episodes.jsonl's lines without the wall-clock field (elapsed_s, the only timing field of these
    records), sorted: what must be byte-identical however the run was split up or interrupted."""
    lines = []
    for line in (out / "episodes.jsonl").read_text().splitlines():
        r = json.loads(line)
        r.pop("elapsed_s")
        lines.append(json.dumps(r))
    return sorted(lines)


@pytest.fixture(scope="module")
def twelve_pointnav(tmp_path_factory, scene_path):
    from navbench.episodes.generate import GeneratorConfig, pointnav_episodes
    from navbench.episodes.io import save_dataset
    from navbench.episodes.types import EpisodeDataset
    eps = pointnav_episodes(scene_path, SCENES_DIR, 12, np.random.default_rng(11),
                            GeneratorConfig(min_geodesic=1.0, max_geodesic=6.0))
    return save_dataset(EpisodeDataset(episodes=eps), tmp_path_factory.mktemp("pn12") / "twelve.json.gz")


@pytest.mark.slow
def test_records_do_not_depend_on_workers_batching_or_a_kill_and_resume(twelve_pointnav, tmp_path):
    """12 PointNav episodes with least-tried decoding (it draws actions): 1 and 2 workers, one episode at
    a time and batched, and a run SIGKILLed at a random point then resumed give the same records."""
    import random
    script = tmp_path / "run.py"
    script.write_text(DETERMINISM_RUN)
    base = [sys.executable, str(script), str(twelve_pointnav), str(SCENES_DIR)]
    results = {}
    for workers, envs in ((1, 1), (1, 4), (2, 1), (2, 4)):
        out = tmp_path / f"w{workers}e{envs}"
        subprocess.run(base + [str(workers), str(envs), str(out)], check=True)
        results[workers, envs] = _sorted_lines(out)
    assert len(results[1, 1]) == 12 and len(set(results[1, 1])) == 12
    for key, lines in results.items():
        assert lines == results[1, 1], key

    kill_at = random.randint(1, 9)
    out = tmp_path / "killed"
    proc = subprocess.Popen(base + ["2", "4", str(out)])
    deadline = time.time() + 300
    while time.time() < deadline and proc.poll() is None and len(read_records(out / "episodes.jsonl")) < kill_at:
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    done = len(read_records(out / "episodes.jsonl"))
    assert kill_at <= done < 12, f"killed after {done} records (aimed at {kill_at}): must be mid-run"
    subprocess.run(base + ["1", "1", str(out), "--resume"], check=True)
    assert _sorted_lines(out) == results[1, 1], f"killed after {done} records"


def test_records_do_not_depend_on_workers_batching_or_a_resume_after_a_cut(twelve_pointnav, tmp_path):
    """The CI-sized determinism guard: in-process and 2 batched workers give the same sorted records,
    and a run cut after a random number of records (the last one half written) resumes to them too."""
    import random
    import shutil

    from navbench.agents.registry import make_pointnav

    def go(out, workers, envs, resume=False):
        cfg = RunConfig(task="pointnav", split=None, agent="pointnav", episodes=str(twelve_pointnav),
                        scene_dir=str(SCENES_DIR), success_distance=0.2, envs_per_worker=envs,
                        env={"max_steps": 40}, agent_options={"decoding": "least-tried"})
        run(cfg, make_pointnav, out, resume=resume, note=lambda *_: None, execution=Execution(workers=workers))
        return _sorted_lines(out)

    serial = go(tmp_path / "serial", 1, 1)
    assert len(serial) == 12 and go(tmp_path / "batched", 2, 4) == serial
    lines = (tmp_path / "batched" / "episodes.jsonl").read_text().splitlines(keepends=True)
    k = random.Random(os.getpid()).randint(1, 10)
    cut = tmp_path / "cut"
    shutil.copytree(tmp_path / "batched", cut)
    (cut / "summary.json").unlink()
    (cut / "episodes.jsonl").write_text("".join(lines[:k]) + lines[k][: len(lines[k]) // 2])
    assert go(cut, 1, 4, resume=True) == serial, f"cut after {k} records"
