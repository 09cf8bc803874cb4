"""Episode videos: RGB | depth | top-down map side by side, one frame per step at 10 fps, then a closing frame.

Frame layout (``FRAME_SIZE`` = 768 x 288 pixels, width x height): a 32-pixel header (step, distance to
goal, the agent's current decision) over three 256 x 256 panels; a red border marks a step that
collided. A video of an episode of N steps has N + 1 frames: one after each step, then the outcome.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np

from navbench.scene.pose import heading_vector
from navbench.viz.replay import Replayer, goal_object_ids, outcome, title
from navbench.viz.topdown import TopDown, annotate, draw_episode

PANEL = 256
HEADER = 32
FRAME_SIZE = (3 * PANEL, PANEL + HEADER)  # (width, height)
FPS = 10


def _imageio():
    try:
        import imageio.v2 as imageio
        import imageio_ffmpeg  # noqa: F401  (the MP4 writer's ffmpeg binary)
    except ImportError:
        raise ImportError("videos need imageio and imageio-ffmpeg: pip install 'navbench[viz]'") from None
    return imageio


def _fit(img: np.ndarray, side: int = PANEL) -> np.ndarray:
    """``img`` scaled to fit a ``side`` square, centred on white."""
    h, w = img.shape[:2]
    s = side / max(h, w)
    small = cv2.resize(img, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)
    out = np.full((side, side, 3), 255, np.uint8)
    y, x = (side - small.shape[0]) // 2, (side - small.shape[1]) // 2
    out[y:y + small.shape[0], x:x + small.shape[1]] = small
    return out


def _depth_rgb(depth: np.ndarray) -> np.ndarray:
    d = np.clip(depth[..., 0], 0, 1)
    return cv2.applyColorMap((255 * (1 - d)).astype(np.uint8), cv2.COLORMAP_INFERNO)[..., ::-1]


def _text(img, s: str, org, scale=0.45, colour=(0, 0, 0)) -> None:
    cv2.putText(img, s, org, cv2.FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv2.LINE_AA)


def _decision_at(decisions: list, step: int) -> list | None:
    cur = None
    for d in decisions:
        if d[0] <= step:
            cur = d
    return cur


def mark_explored(explored: np.ndarray, grid, depth_m: np.ndarray, pose: tuple[float, float, float],
                  hfov_deg: float, max_depth: float) -> None:
    """Mark the grid cells the depth image saw (along each ray up to its hit, or the sensor range)."""
    h, w = depth_m.shape
    f = (w / 2) / np.tan(np.radians(hfov_deg) / 2)
    u = np.arange(0, w, 4)
    d = depth_m[h // 2 - h // 4:h // 2 + h // 4:4][:, u].min(axis=0)  # nearest hit of the middle rows
    d = np.where((d <= 0) | (d >= max_depth), max_depth, d)
    x, z, yaw = pose
    fwd, right = heading_vector(yaw), np.array([np.cos(yaw), 0.0, -np.sin(yaw)])
    t = np.linspace(0.05, 1.0, 24)[:, None]
    side = ((u - w / 2) / f)[None] * d[None] * t
    ahead = d[None] * t
    wx = x + fwd[0] * ahead + right[0] * side
    wz = z + fwd[2] * ahead + right[2] * side
    i = np.floor((wz - grid.origin[1]) / grid.cell_size + 0.5).astype(int).ravel()
    j = np.floor((wx - grid.origin[0]) / grid.cell_size + 0.5).astype(int).ravel()
    ok = (i >= 0) & (i < explored.shape[0]) & (j >= 0) & (j < explored.shape[1])
    explored[i[ok], j[ok]] = True


def explored_mask(rp: Replayer, r: dict[str, Any]) -> np.ndarray:
    """Grid cells the agent's depth camera saw during the episode (replayed with depth rendering)."""
    env = rp.env(("depth",))
    explored = None
    for (obs, _, _), pose in zip(rp.steps(r, ("depth",)), r["trace"]["poses"]):
        cfg, grid = env.config, env.navgrid  # the episode's scene once the replay has reset the env
        if explored is None:
            explored = np.zeros(grid.shape, bool)
        d = obs["depth"][..., 0]
        d = d * (cfg.max_depth - cfg.min_depth) + cfg.min_depth if cfg.normalize_depth else d
        mark_explored(explored, grid, d, tuple(pose), cfg.hfov_deg, cfg.max_depth)
    return explored


def episode_frames(rp: Replayer, r: dict[str, Any], explored_out: list | None = None):
    """Yield the episode's video frames (RGB uint8, ``FRAME_SIZE``) by replaying it with rendering."""
    d, ep = rp.drawing(r)
    env = rp.env(("rgb", "depth"))
    env.reset(options={"episode": ep})  # load the episode's scene before reading its grid
    view = TopDown.fit(env.navgrid, max_side=2 * PANEL)
    grid = env.navgrid
    explored = np.zeros(grid.shape, bool)
    objects = list(env.asset.objects.values())
    goal_ids = goal_object_ids(ep)
    reachable = None
    cfg = env.config
    decisions = d.decisions
    last = None
    for k, (obs, info, collided) in enumerate(rp.steps(r, ("rgb", "depth"))):
        if reachable is None:
            isl = grid.island_id(env.agent_position)
            reachable = grid.islands == isl if isl > 0 else grid.navigable
        depth_m = obs["depth"][..., 0] * (cfg.max_depth - cfg.min_depth) + cfg.min_depth \
            if cfg.normalize_depth else obs["depth"][..., 0]
        mark_explored(explored, grid, depth_m, tuple(d.poses[k]), cfg.hfov_deg, cfg.max_depth)
        if k == 0:  # the start has no frame of its own: each frame shows the state after a step
            continue
        dec = _decision_at(decisions, k)
        goal = (dec[-2], dec[-1]) if dec is not None and dec[-1] is not None else None
        m = view.scene_layer(reachable=reachable, explored=explored)
        view.draw_objects(m, objects, goal_ids=goal_ids)
        draw_episode(m, view, d, upto=k, current_goal=goal)
        annotate(m, view)
        frame = np.full((FRAME_SIZE[1], FRAME_SIZE[0], 3), 255, np.uint8)
        frame[HEADER:, :PANEL] = _fit(obs["rgb"])
        frame[HEADER:, PANEL:2 * PANEL] = _fit(_depth_rgb(obs["depth"]))
        frame[HEADER:, 2 * PANEL:] = _fit(m)
        what = f" | {dec[1]}" + (f" #{dec[2]}" if len(dec) == 5 else "") if dec is not None else ""
        _text(frame, f"step {k}/{r['num_steps']}  d={info['distance_to_goal']:.2f} m{what}", (8, 21))
        if collided:
            cv2.rectangle(frame, (0, 0), (FRAME_SIZE[0] - 1, FRAME_SIZE[1] - 1), (230, 0, 0), 6)
        last = frame
        yield frame
    if explored_out is not None:
        explored_out.append(explored)
    end = (last * 0.35 + 255 * 0.65).astype(np.uint8)
    ok = r.get("success")
    _text(end, "SUCCESS" if ok else f"FAILURE: {outcome(r)}", (20, 120), 1.1, (0, 140, 0) if ok else (200, 0, 0))
    _text(end, title(r), (20, 160), 0.45)
    yield end


def write_video(rp: Replayer, r: dict[str, Any], path: Path) -> int:
    """Write the episode's MP4 (H.264, 10 fps) to ``path``; returns the number of frames."""
    imageio = _imageio()
    path.parent.mkdir(parents=True, exist_ok=True)
    n = 0
    with imageio.get_writer(path, fps=FPS, codec="libx264", quality=6, macro_block_size=16,
                            ffmpeg_log_level="error") as w:
        for frame in episode_frames(rp, r):
            w.append_data(frame)
            n += 1
    return n


def select(records: list[dict[str, Any]], which: str) -> list[dict[str, Any]]:
    """Records to draw for ``which`` = none | failures | all (skipped episodes never)."""
    if which == "none":
        return []
    recs = [r for r in records if not r.get("skipped") and not r.get("failed")]
    return recs if which == "all" else [r for r in recs if not r.get("success")]
