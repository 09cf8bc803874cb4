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
from navbench.eval.config import RunConfig, recorded_paths
from navbench.eval.failures import failure_kind
from navbench.eval.rundir import RunError
from navbench.eval.runner import read_records
from navbench.eval.worker import make_env
from navbench.safeio import read_input
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
    def load(cls, path: str | Path) -> Run:
        """A run directory, its config and records checked (a hand-edited file is one line naming it)."""
        path = Path(path)
        records = read_records(path / "episodes.jsonl")
        if not records:
            raise ReplayError(f"{path}: no episode records (episodes.jsonl missing or empty)")
        for i, r in enumerate(records):
            problem = record_problem(r)
            if problem:
                raise ReplayError(f"{path / 'episodes.jsonl'}: record {i + 1}: {problem}"[:300])
        cfg_file = path / "config.json"
        if not cfg_file.is_file():
            raise ReplayError(f"{path}: no config.json")
        try:
            raw = json.loads(read_input(cfg_file, 16 << 20))
        except (ValueError, OSError, RecursionError) as exc:
            raise ReplayError(f"{cfg_file}: not a run config ({type(exc).__name__})") from None
        names = {f.name for f in dataclasses.fields(RunConfig)}
        bad = [k for k in ("agent", "label", "task", "split", "episodes", "scene_dir")
               if isinstance(raw, dict) and raw.get(k) is not None and not isinstance(raw[k], str)]
        if not isinstance(raw, dict) or bad:
            raise ReplayError(f"{cfg_file}: not a run config ({'a ' + type(raw).__name__ if not bad else bad[0]!r}"
                              f"{' is not a string' if bad else ''})")
        cfg = RunConfig(**{k: v for k, v in raw.items() if k in names})
        try:
            cfg.episodes, cfg.scene_dir = recorded_paths(raw, cfg_file)
        except RunError as exc:
            raise ReplayError(str(exc)) from None
        return cls(path, cfg, records)

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


_NUMBERS = ("spl", "soft_spl", "distance_to_goal", "geodesic_distance", "elapsed_s", "path_length")
_COUNTS = ("num_steps", "collisions")


def record_problem(r: Any) -> str | None:
    """What makes ``r`` unusable as an episode record (a wrong type), or None."""
    if not isinstance(r, dict):
        return f"not an object but {type(r).__name__}"
    eid = r.get("episode_id")
    if isinstance(eid, bool) or not isinstance(eid, (str, int)):
        return f"'episode_id' must be a string, got {eid!r}"
    if not isinstance(r.get("scene_id"), str):
        return f"episode {eid}: 'scene_id' must be a string, got {r.get('scene_id')!r}"
    for k in ("success", *_NUMBERS):
        v = r.get(k)
        if v is not None and (not isinstance(v, (int, float)) or (isinstance(v, bool) and k != "success")):
            return f"episode {eid}: {k!r} must be a number, got {v!r}"
    for k in _COUNTS:
        v = r.get(k)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int)):
            return f"episode {eid}: {k!r} must be an integer, got {v!r}"
    for k in ("object_category", "failure_reason"):
        if r.get(k) is not None and not isinstance(r[k], str):
            return f"episode {eid}: {k!r} must be a string, got {r[k]!r}"
    trace = r.get("trace")
    if trace is not None and (not isinstance(trace, dict) or not isinstance(trace.get("poses", []), list)
                              or not isinstance(trace.get("actions", ""), (str, list))
                              or not isinstance(trace.get("decisions", []), list)):
        return f"episode {eid}: 'trace' must be an object (poses and decisions lists, actions)"
    return None


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

    def dataset(self):
        """The run's episode file, holding only the episodes the run recorded (streamed)."""
        if self._dataset is None:
            wanted = {(str(r["scene_id"]), str(r["episode_id"])) for r in self.run.records}
            self._dataset = load_dataset(self.run.cfg.episodes, lambda stream: [
                e for e in stream() if (e.scene_id, e.episode_id) in wanted])
        return self._dataset

    def episode(self, r: dict[str, Any]) -> Episode:
        self.dataset()
        for e in self._dataset.episodes:
            if e.episode_id == str(r["episode_id"]) and e.scene_id == r["scene_id"]:
                return e
        raise ReplayError(f"{self.run.cfg.episodes}: episode {r['episode_id']} of {r['scene_id']} not found")

    def env(self, sensors: tuple[str, ...] = ()):
        if sensors not in self._envs:
            self._envs[sensors] = make_env(self.run.cfg, self.dataset(), sensors)
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

    def storeys(self, r: dict[str, Any]) -> list[tuple[Any, np.ndarray]] | None:
        """For an episode the env ran over several storeys (a goal on another one), each storey's grid that
        the replayed path touches and which of its poses stand on it (on a flight of steps: the storey
        below); None for an episode on one storey."""
        from navbench.scene.cache import navgrid_for
        from navbench.scene.navigability import NavGrid

        env = self.env()
        env.reset(options={"episode": self.episode(r)})
        if not env.crosses_storeys:
            return None
        ys = [float(self.env().agent_position[1]) for _ in self.steps(r)] if r.get("trace") \
            else [float(env.agent_position[1])]
        config = env.nav_config
        levels = NavGrid._levels(env.asset.mesh, config)
        levels = np.array([env.navgrid.floor_height]) if levels is None else levels
        floors = [float(levels[levels <= y + config.max_climb].max(initial=levels.min())) for y in ys]
        out = []
        for f in sorted(set(floors)):
            grid = navgrid_for(env.asset, config, floor_hint=f)
            out.append((grid, np.array([abs(g - f) < 1e-9 for g in floors])))
        return out

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
