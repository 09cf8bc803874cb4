"""python -m navbench.eval.imagegoal_errors: the xz distance of each logged goal-camera estimate from goals[0]."""

from __future__ import annotations

import json

import numpy as np

from navbench.eval.imagegoal_errors import estimate_errors, main, summary
from navbench.paths import split_file
from navbench.tasks import get_task


def test_errors_are_the_xz_distances_from_the_episodes_goal_points(tmp_path, capsys):
    episodes = get_task("imagenav").read_episodes(split_file("imagenav", "val")).episodes[:2]
    (tmp_path / "config.json").write_text(json.dumps({"task": "imagenav", "split": "val"}))
    records = []
    for e, (dx, dz) in zip(episodes, [(0.3, 0.4), (0.0, 0.0)]):
        g = e.goals[0].position
        records.append({"scene_id": e.scene_id, "episode_id": e.episode_id,
                        "log": {"goal_camera": [g[0] + dx, g[1] + 0.88, g[2] + dz]}})
    (tmp_path / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    assert np.allclose(estimate_errors(tmp_path), [0.5, 0.0])
    assert "50.0% within 0.2 m" in summary(estimate_errors(tmp_path))
    assert main([str(tmp_path)]) == 0 and "2 estimates: median 0.25 m" in capsys.readouterr().out
