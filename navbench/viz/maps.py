"""An episode's top-down map as one picture: scene layer, objects, goals, the path and the agent's decisions."""

from __future__ import annotations

from typing import Any

import numpy as np

from navbench.viz.replay import Replayer, goal_object_ids, title
from navbench.viz.topdown import TopDown, annotate, draw_episode, legend


def episode_map(rp: Replayer, r: dict[str, Any], max_side: int = 640, with_legend: bool = True,
                explored: np.ndarray | None = None, view: TopDown | None = None) -> np.ndarray:
    """RGB uint8 map of record ``r`` of ``rp``'s run (with a legend band below unless ``with_legend`` is off)."""
    d, ep = rp.drawing(r)
    view = view or rp.view(max_side)
    img = view.scene_layer(reachable=rp.reachable(), explored=explored)
    view.draw_objects(img, rp.env().asset.objects.values(), goal_ids=goal_object_ids(ep))
    draw_episode(img, view, d)
    annotate(img, view)
    if not with_legend:
        return img
    return np.concatenate([img, legend(img.shape[1], title(r))], axis=0)
