"""Replay a finished run's episodes from their records: the env is stepped with the recorded actions (no
agent), which reproduces the poses, collisions and observations of the run exactly, and is checked
against the recorded poses at every step.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from navbench.episodes.io import load_dataset
from navbench.episodes.types import Episode, ObjectGoal
from navbench.eval.config import RunConfig
from navbench.eval.failures import failure_kind
from navbench.eval.runner import read_records
from navbench.eval.worker import make_env
from navbench.viz.topdown import EpisodeDrawing, TopDown, shortest_path


class ReplayError(ValueError):
    """A run or episode cannot be replayed; the message says why in one line."""


@dataclass
class Run:
    """A finished run directory: its config and records."""

    path: Path
    cfg: RunConfig
    records: list[dict[str, Any]]

    @classmethod
    def load(cls, path: str | Path) -> "Run":
        path = Path(path)
        records = read_records(path / "episodes.jsonl")
        if not records:
            raise ReplayError(f"{path}: no episode records (episodes.jsonl missing or empty)")
        cfg_file = path / "config.json"
        if not cfg_file.is_file():
            raise ReplayError(f"{path}: no config.json")
        raw = json.loads(cfg_file.read_text())
        names = {f.name for f in dataclasses.fields(RunConfig)}
        return cls(path, RunConfig(**{k: v for k, v in raw.items() if k in names}), records)

    @property
    def label(self) -> str:
        return self.cfg.label or self.cfg.agent

    def record(self, episode_id: str) -> dict[str, Any]:
        hits = [r for r in self.records if str(r["episode_id"]) == str(episode_id)]
        if not hits:
            raise ReplayError(f"{self.path}: no episode {episode_id!r} in episodes.jsonl")
        return hits[0]

    def failures(self) -> list[dict[str, Any]]:
        return [r for r in self.records if not r.get("skipped") and not r.get("success")]


def outcome(r: dict[str, Any]) -> str:
    """'success', 'skipped' or the failure kind (wrong instance, stopped early, stuck, timeout)."""
    if r.get("skipped"):
        return "skipped"
    if r.get("failed"):
        return "crashed"
    return "success" if r.get("success") else (failure_kind(r) or "failure")


class Replayer:
    """Envs for one run (one per sensor set), reused across its episodes."""

    def __init__(self, run: Run):
        self.run = run
        self._dataset = None
        self._envs: dict[tuple[str, ...], Any] = {}

    def episode(self, r: dict[str, Any]) -> Episode:
        if self._dataset is None:
            self._dataset = load_dataset(self.run.cfg.episodes)
        for e in self._dataset.episodes:
            if e.episode_id == str(r["episode_id"]) and e.scene_id == r["scene_id"]:
                return e
        raise ReplayError(f"{self.run.cfg.episodes}: episode {r['episode_id']} of {r['scene_id']} not found")

    def env(self, sensors: tuple[str, ...] = ()):
        if sensors not in self._envs:
            self._envs[sensors] = make_env(self.run.cfg, self._dataset or load_dataset(self.run.cfg.episodes),
                                           sensors)
        return self._envs[sensors]

    def steps(self, r: dict[str, Any], sensors: tuple[str, ...] = ()) -> Iterator[tuple[dict, dict, bool]]:
        """(observation, info, collided) after reset and after each recorded action; raises ReplayError
        if the replayed pose leaves the recorded one."""
        trace = r.get("trace")
        if not trace:
            raise ReplayError(f"{self.run.path}: episode {r['episode_id']} has no trace (the run predates pose "
                              f"recording); rerun it to draw it")
        env = self.env(sensors)
        obs, info = env.reset(options={"episode": self.episode(r)})
        poses = trace["poses"]
        self._check(env, poses[0], r, 0)
        yield obs, info, False
        for k, a in enumerate(trace["actions"], start=1):
            before = info["collisions"]
            obs, _, _, _, info = env.step(int(a))
            self._check(env, poses[k], r, k)
            yield obs, info, info["collisions"] > before

    def _check(self, env, pose: list[float], r: dict[str, Any], k: int) -> None:
        p = env.agent_position
        now = [round(float(p[0]), 3), round(float(p[2]), 3), round(float(env.agent_yaw), 3)]
        if now != list(pose):
            raise ReplayError(f"episode {r['episode_id']}: replay leaves the recorded path at step {k} "
                              f"({now} != {pose})")

    def drawing(self, r: dict[str, Any]) -> tuple[EpisodeDrawing, Episode]:
        """The episode's overlay: the replayed path and collisions when the record has a trace, else the
        start, goals and shortest path only."""
        ep = self.episode(r)
        env = self.env()
        env.reset(options={"episode": ep})
        field = env.navgrid.distance_field(env.goal_points)
        start = env.agent_position
        d = EpisodeDrawing(goal_points=np.asarray(env.goal_points), shortest=shortest_path(field, start),
                           candidates=(r.get("log") or {}).get("candidates", []),
                           decisions=(r.get("trace") or {}).get("decisions", []),
                           stopped=bool(r.get("stop_called")))
        if r.get("trace"):
            collided = [c for _, _, c in self.steps(r)][1:]
            d.poses = np.asarray(r["trace"]["poses"], float)
            d.collisions = np.asarray(collided, bool)
        else:
            d.poses = np.array([[start[0], start[2], env.agent_yaw]])
        return d, ep

    def view(self, max_side: int = 640) -> TopDown:
        return TopDown.fit(self.env().navgrid, max_side=max_side)

    def reachable(self) -> np.ndarray:
        """Navigable cells on the current episode's start island."""
        env = self.env()
        g = env.navgrid
        isl = g.island_id(env.agent_position)
        return g.islands == isl if isl > 0 else g.navigable

    def close(self) -> None:
        for env in self._envs.values():
            env.close()
        self._envs.clear()


def goal_object_ids(ep: Episode) -> set[int]:
    return {g.object_id for g in ep.goals if isinstance(g, ObjectGoal)}


def title(r: dict[str, Any]) -> str:
    what = r.get("object_category") or "point goal"
    d = r.get("distance_to_goal")
    dist = f", {d:.2f} m to goal" if isinstance(d, (int, float)) and math.isfinite(d) else ""
    return (f"ep {r['episode_id']} ({r['scene_id']}): {what} - {outcome(r)}, {r.get('num_steps', 0)} steps"
            f"{dist}, SPL {r.get('spl') or 0:.2f}")
