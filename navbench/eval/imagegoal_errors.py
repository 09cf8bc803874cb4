"""How far a memory agent's ImageNav goal-camera estimates fell from where the goal images were taken.

``python -m navbench.eval.imagegoal_errors RUN_DIR``: reads the run's records (each logs its estimate,
``goal_camera``) and the run's episodes (``goals[0]``, where the image was taken), and prints the xz error's
median, quartiles and the shares within 0.2 m (ImageNav's success distance), 0.5 m and 1 m.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from navbench.eval.rundir import read_records
from navbench.paths import split_file
from navbench.tasks import get_task


def estimate_errors(run_dir: str | Path) -> np.ndarray:
    """The xz distance (m) of each record's ``goal_camera`` from its episode's ``goals[0]``."""
    run_dir = Path(run_dir)
    cfg = json.loads((run_dir / "config.json").read_text())
    path = split_file(cfg["task"], cfg["split"]) if cfg.get("split") else Path(cfg["episodes"])
    episodes = get_task(cfg["task"]).read_episodes(path).episodes
    goals = {(e.scene_id, e.episode_id): e.goals[0].position for e in episodes}
    out = []
    for r in read_records(run_dir / "episodes.jsonl"):
        g, c = goals[(r["scene_id"], r["episode_id"])], r["log"]["goal_camera"]
        out.append(float(np.hypot(c[0] - g[0], c[2] - g[2])))
    return np.asarray(out)


def summary(errors: np.ndarray) -> str:
    q1, med, q3 = np.percentile(errors, [25, 50, 75])
    within = ", ".join(f"{100 * float(np.mean(errors < d)):.1f}% within {d:g} m" for d in (0.2, 0.5, 1.0))
    return f"{len(errors)} estimates: median {med:.2f} m (quartiles {q1:.2f}-{q3:.2f} m); {within}"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python -m navbench.eval.imagegoal_errors RUN_DIR", file=sys.stderr)
        return 2
    print(summary(estimate_errors(argv[0])))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
