"""Fuzz the InstanceImageNav and GOAT-Bench navigation readers: every mutation of a small file in the
published schema loads into usable episodes or fails as one line naming the file."""

from __future__ import annotations

import gzip
import json
import math
from pathlib import Path

import numpy as np
from fuzzlib import USER_ERRORS, check_user_error, mutations
from hypothesis import given

from navbench.episodes.goat import load_goat
from navbench.episodes.instance_imagenav import load_instance_imagenav

VP = [{"agent_state": {"position": [0.5, 0.0, 1.0], "rotation": [0, 0, 0, 1]}, "iou": 0.5}]
IMG = [{"position": [1.0, 1.2, 2.0], "rotation": [0, 0, 0, 1], "hfov": 65, "image_dimensions": [512, 512],
        "frame_coverage": 0.3, "object_coverage": 0.8}]
EP = {"episode_id": "3", "scene_id": "hm3d/val/00800-TEEsavR23oF/TEEsavR23oF.basis.glb",
      "start_position": [0.0, 0.0, 0.0], "start_rotation": [0, 0, 0, 1], "info": {"geodesic_distance": 1.0},
      "goals": []}
IIN = {"goals": {"TEEsavR23oF_10": {"position": [1.0, 0.5, 1.0], "object_id": 10, "object_name": "tv_10",
                                    "object_category": "tv_monitor", "view_points": VP, "image_goals": IMG}},
       "episodes": [dict(EP, object_category="tv_monitor", goal_object_id="10", goal_image_id=0)]}
GOAT = {"goals": {"TEEsavR23oF.basis.glb_tv": [
            {"object_category": "tv", "object_id": "tv_10", "position": [1.0, 0.5, 1.0], "view_points": VP,
             "children_object_categories": [], "lang_desc": "the tv on the wall", "image_goals": IMG}]},
        "episodes": [dict(EP, tasks=[["tv", "object", None], ["tv", "description", "tv_10"],
                                     ["tv", "image", "tv_10", 0]])]}


def _write(dir: Path, doc) -> Path:
    (dir / "content").mkdir(parents=True, exist_ok=True)
    (dir / "val.json.gz").write_bytes(gzip.compress(b'{"episodes": []}', mtime=0))
    (dir / "content" / "TEEsavR23oF.json.gz").write_bytes(gzip.compress(json.dumps(doc).encode(), mtime=0))
    return dir / "val.json.gz"


def _read(reader, path: Path):
    """The reader's dataset, or None after checking it failed as one line naming the content file."""
    try:
        return reader(path)
    except USER_ERRORS as exc:
        check_user_error(exc, path.parent / "content" / "TEEsavR23oF.json.gz")
        return None


def _finite(a) -> bool:
    return bool(np.isfinite(np.asarray(a, np.float64)).all())


@given(doc=mutations(IIN))
def test_instance_imagenav_mutations(doc, fuzz_dir):
    path = _write(fuzz_dir / "iin", doc)
    ds = _read(load_instance_imagenav, path)
    for ep in ds.episodes if ds else []:
        g = ep.image_goal
        assert g.height > 0 and g.width > 0 and 0 < g.hfov_deg < 180 and _finite(g.position + g.rotation)
        pts = ep.goal_positions()
        assert pts.shape[1] == 3 and len(pts) >= 1 and _finite(pts)


@given(doc=mutations(GOAT))
def test_goat_mutations(doc, fuzz_dir):
    path = _write(fuzz_dir / "goat_nav", doc)
    ds = _read(load_goat, path)
    for ep in ds.episodes if ds else []:
        assert 1 <= ep.num_goals <= len(ep.tasks) and len(ep.descriptions) == len(ep.image_goals) == len(ep.tasks)
        for k in range(ep.num_goals):
            pts = ep.subtask_goal_positions(k)
            assert len(pts) >= 1 and _finite(pts)
        assert all(math.isfinite(v) for v in ep.start_position)
