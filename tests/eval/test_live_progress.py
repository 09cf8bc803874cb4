"""The run's progress inside long episodes: steps (and GOAT-Bench subtasks closed) of the episodes in flight."""

import io
import time

from navbench.agents.oracle import OracleAgent
from navbench.eval import pool, worker
from navbench.eval.run_progress import Progress
from navbench.eval.runner import Execution, RunConfig, comparable, read_records, run
from navbench.paths import EPISODES_DIR, SCENES_DIR


def test_a_line_for_the_episodes_in_flight_at_a_modest_rate():
    buf = io.StringIO()
    p = Progress(stream=buf, tty=False, live_every=0.0)
    p.live([("houses/val/house_008.glb", "3", 1200, 2, 7), ("s", "4", 10, -1, -1)], 0, 5)
    line = buf.getvalue().splitlines()[-1]
    assert line.startswith("[0/5] running 0:00:0")
    assert "houses/val/house_008.glb ep 3: step 1200, subtasks 2/7 closed; s ep 4: step 10" in line
    assert line.endswith("step 10")  # no subtasks: no subtask count
    slow = Progress(stream=io.StringIO(), tty=False)  # every 30 s, and not before an episode's own line
    slow.live([("s", "1", 5, -1, -1)], 0, 1)
    slow.t0 = slow.last_live = time.monotonic() - 31
    slow.live([("s", "1", 6, -1, -1)], 0, 1)
    slow.live([("s", "1", 7, -1, -1)], 0, 1)
    assert slow.stream.getvalue().splitlines() == ["[0/1] running 0:00:31 | s ep 1: step 6"]
    bar = Progress(stream=io.StringIO(), tty=True)  # on a terminal: the bar's postfix
    bar.last_live -= 2
    bar.live([("s", "1", 9, 0, 5)], 0, 1)
    assert "s ep 1: step 9, subtasks 0/5 closed" in bar.stream.getvalue()


class _Live:
    """A progress that keeps what it hears."""

    def __init__(self):
        self.records, self.in_flight = [], []

    def __call__(self, rec, n, total):
        self.records.append(rec["episode_id"])

    def live(self, in_flight, done, total):
        self.in_flight.append((done, total, list(in_flight)))


def _oracle(cfg):
    return OracleAgent(cfg.scene_dir, cfg.success_distance)


def test_a_goat_run_tells_its_steps_and_subtasks_in_flight_and_records_the_same(tmp_path, monkeypatch):
    monkeypatch.setattr(worker.LiveTracker, "every", 0.0)
    cfg = RunConfig(task="goat", split="val", agent="oracle", episodes=str(EPISODES_DIR / "goat/val/val.json.gz"),
                    scene_dir=str(SCENES_DIR), success_distance=0.25, limit=1)
    heard = _Live()
    run(cfg, _oracle, tmp_path / "live", progress=heard)
    run(cfg, _oracle, tmp_path / "quiet")
    rec = read_records(tmp_path / "live" / "episodes.jsonl")
    assert comparable(rec) == comparable(read_records(tmp_path / "quiet" / "episodes.jsonl"))
    seen = [e for done, total, flight in heard.in_flight for e in flight if (done, total) == (0, 1)]
    assert seen and all(e[:2] == (rec[0]["scene_id"], rec[0]["episode_id"]) for e in seen)
    steps = [e[2] for e in seen]
    closed = [e[3] for e in seen]
    assert steps == sorted(steps) and steps[-1] == rec[0]["num_steps"]
    assert closed == sorted(closed) and closed[0] == 0 and closed[-1] == rec[0]["subtasks_closed"] > 1
    assert {e[4] for e in seen} == {len(rec[0]["subtask_success"])}


class _Slow(OracleAgent):
    def act(self, obs):
        time.sleep(0.01)
        return super().act(obs)


def _slow(cfg):
    return _Slow(cfg.scene_dir, cfg.success_distance)


def test_pool_workers_tell_the_driver_their_episodes_in_flight(pointnav_file, tmp_path, monkeypatch):
    monkeypatch.setattr(pool, "_LIVE_EVERY", 0.05)
    cfg = RunConfig(task="pointnav", split=None, agent="oracle", episodes=str(pointnav_file),
                    scene_dir=str(SCENES_DIR), success_distance=0.2, limit=2)
    heard = _Live()
    run(cfg, _slow, tmp_path / "run", progress=heard, execution=Execution(workers=2))
    recs = {r["episode_id"]: r for r in read_records(tmp_path / "run" / "episodes.jsonl")}
    seen = [e for _, _, flight in heard.in_flight for e in flight]
    assert {e[1] for e in seen} == set(recs)
    assert all(e[3:] == (-1, -1) and 0 <= e[2] <= recs[e[1]]["num_steps"] for e in seen)
    assert max(e[2] for e in seen) > 0
