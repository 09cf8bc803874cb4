"""An episode's top-down map as one picture: scene layer, objects, goals, the path and the agent's decisions
(one panel per storey the path touches when the episode crosses storeys)."""

from __future__ import annotations

import dataclasses
from typing import Any

import cv2
import numpy as np

from navbench.viz.replay import Replayer, goal_object_ids, title
from navbench.viz.topdown import EpisodeDrawing, TopDown, annotate, draw_episode, legend


def episode_map(rp: Replayer, r: dict[str, Any], max_side: int = 640, with_legend: bool = True,
                explored: np.ndarray | None = None, view: TopDown | None = None) -> np.ndarray:
    """RGB uint8 map of record ``r`` of ``rp``'s run (with a legend band below unless ``with_legend`` is off)."""
    d, ep = rp.drawing(r)
    storeys = rp.storeys(r) if view is None else None
    if storeys is not None:
        h = max(TopDown.fit(g, max_side=max_side).size[0] for g, _ in storeys)
        panels = [_storey_panel(rp, d, ep, grid, on, max_side, h) for grid, on in storeys]
        sep = np.full((h, 4, 3), 255, np.uint8)
        img = np.concatenate([x for p in panels for x in (p, sep)][:-1], axis=1)
        if not with_legend:
            return img
        return np.concatenate([img, legend(img.shape[1], title(r))], axis=0)
    view = view or rp.view(max_side)
    img = view.scene_layer(reachable=rp.reachable(), explored=explored)
    view.draw_objects(img, rp.env().asset.objects.values(), goal_ids=goal_object_ids(ep))
    draw_episode(img, view, d)
    annotate(img, view)
    if not with_legend:
        return img
    return np.concatenate([img, legend(img.shape[1], title(r))], axis=0)


def _storey_panel(rp: Replayer, d: EpisodeDrawing, ep, grid, on: np.ndarray, max_side: int,
                  height: int) -> np.ndarray:
    """One storey's map: its grid, its objects and goals, and the part of the path that stands on it."""
    view = TopDown.fit(grid, max_side=max_side)
    img = view.scene_layer()
    objects = [o for o in rp.env().asset.objects.values()
               if grid.on_storey((np.asarray(o.aabb_min) + np.asarray(o.aabb_max))[None] / 2)[0]]
    view.draw_objects(img, objects, goal_ids=goal_object_ids(ep))
    part = dataclasses.replace(d, goal_points=d.goal_points[grid.on_storey(d.goal_points)] if len(d.goal_points)
                               else d.goal_points, poses=d.poses[on[:len(d.poses)]],
                               collisions=np.concatenate([[False], d.collisions])[on[:len(d.poses)]][1:],
                               starts=bool(on[0]), ends=bool(on[len(d.poses) - 1]))
    draw_episode(img, view, part)
    annotate(img, view)
    cv2.putText(img, f"floor {grid.floor_height:.2f} m", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1,
                cv2.LINE_AA)
    pad = height - img.shape[0]
    return np.concatenate([img, np.full((pad, img.shape[1], 3), 255, np.uint8)], axis=0) if pad > 0 else img
