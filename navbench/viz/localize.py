"""Localisation views: one PNG per query showing why the localiser predicted what it did.

Top row: the re-ranked keyframes (best first) with their retrieval cosine and re-rank position, the
segmenter's mask in red. Bottom: the scene's top-down map with each candidate's fused 3D points (one colour
per rank), the top-K predicted centres (numbered), the ground truth (green stars) and the success
radius around it. Scores and masks are recomputed for the picture with the run's own backends.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np

from navbench.viz.topdown import TopDown, annotate, time_colours

TILE = 160
SHOWN = 5  # keyframes in the top row


def _tile(img: np.ndarray, mask: np.ndarray | None, lines: list[str]) -> np.ndarray:
    """A keyframe scaled to TILE wide, its mask shaded and outlined in magenta, captions below."""
    img = np.ascontiguousarray(img[..., :3]).astype(np.uint8)
    h, w = img.shape[:2]
    size = (TILE, round(h * TILE / w))
    small = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
    if mask is not None and mask.any():
        m = cv2.resize(mask.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST)
        small[m > 0] = (0.6 * small[m > 0] + 0.4 * np.array([255, 0, 255])).astype(np.uint8)
        contours, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(small, contours, -1, (255, 0, 255), 2)
    t = np.full((small.shape[0] + 30, TILE, 3), 255, np.uint8)
    t[:small.shape[0]] = small
    for k, line in enumerate(lines):
        cv2.putText(t, line, (3, small.shape[0] + 12 + 12 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.36, (0, 0, 0), 1,
                    cv2.LINE_AA)
    return t


def query_view(localizer, query, candidates, record: dict[str, Any], grid) -> np.ndarray:
    """The picture of one query (RGB uint8). ``record`` is the benchmark's prediction record."""
    trace = localizer.last_trace
    prompt = trace.prompt
    cosine = dict(trace.retrieved)
    tiles = []
    for rank, kf in enumerate(trace.kept[:SHOWN]):
        img = localizer.memory.store.rgb(kf)
        mask = None
        try:
            mask, _ = localizer.segmenter.segment(localizer._image(kf, localizer.segmenter), prompt)
        except Exception:  # a backend that needs what the store lacks: the picture goes without the mask
            mask = None
        rr = ""
        if getattr(getattr(localizer, "config", None), "rerank", False):
            _, vis = localizer.reranker.score(localizer._image(kf, localizer.reranker), prompt)
            rr = f"  rerank {vis:.2f}"
        tiles.append(_tile(img, mask, [f"#{rank + 1} kf {kf} cos {cosine.get(kf, 0):.2f}{rr}",
                                       "segmented" if kf in trace.segmented else "no usable mask"]))
    height = max([t.shape[0] for t in tiles], default=TILE)
    tiles = [np.pad(t, ((0, height - t.shape[0]), (0, 0), (0, 0)), constant_values=255) for t in tiles]
    while len(tiles) < SHOWN:
        tiles.append(np.full((height, TILE, 3), 255, np.uint8))
    top = np.concatenate(tiles, axis=1)

    view = TopDown.fit(grid, max_side=top.shape[1] - 20)
    m = view.scene_layer()
    cols = time_colours(max(len(candidates), 2))[::-1]
    for k, c in enumerate(candidates):
        pts = np.asarray(c.points)[::max(1, len(c.points) // 400)]
        col = tuple(int(v) for v in (cols[k] if k < len(cols) else (120, 120, 120)))
        for u, v in np.round(view.to_px(pts[:, 0], pts[:, 2])).astype(int):
            cv2.circle(m, (int(u), int(v)), 1, col, -1)
    ppm = view.scale / grid.cell_size
    for g in record["gt_positions"]:
        u, v = view.px(g[0], g[2])
        cv2.circle(m, (u, v), int(round(1.5 * ppm)), (0, 150, 0), 1, cv2.LINE_AA)
        cv2.drawMarker(m, (u, v), (0, 150, 0), cv2.MARKER_STAR, 14, 2)
    for k, c in enumerate(record["top_k"]):
        u, v = view.px(c[0], c[2])
        cv2.drawMarker(m, (u, v), (220, 30, 30), cv2.MARKER_TILTED_CROSS, 12, 2)
        cv2.putText(m, str(k + 1), (u + 6, v - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (220, 30, 30), 1, cv2.LINE_AA)
    annotate(m, view)
    bottom = np.full((m.shape[0] + 10, top.shape[1], 3), 255, np.uint8)
    bottom[5:5 + m.shape[0], 10:10 + m.shape[1]] = m
    head = np.full((44, top.shape[1], 3), 255, np.uint8)
    ok = "SUCCESS" if record["success"] else "MISS"
    q = record["query"] if isinstance(record["query"], str) else "(image query)"
    cv2.putText(head, f"{record['id']} [{record['type']}] {ok}: {q}"[:110], (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                (0, 120, 0) if record["success"] else (200, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(head, f"prompt: {prompt}"[:110] + "  | red x: top-K centres, green star: ground truth (1.5 m circle)",
                (6, 36), cv2.FONT_HERSHEY_SIMPLEX, 0.36, (60, 60, 60), 1, cv2.LINE_AA)
    return np.concatenate([head, top, bottom], axis=0)


class QueryViews:
    """The ``on_query`` hook of :func:`navbench.localize.benchmark.run_localize`: writes OUT/viz/<id>.png."""

    def __init__(self, out: str | Path):
        self.out = Path(out)
        self.out.mkdir(parents=True, exist_ok=True)
        self._grids: dict[str, Any] = {}

    def __call__(self, localizer, query, candidates, record: dict[str, Any], scene_path: Path) -> None:
        key = str(scene_path)
        if key not in self._grids:
            from navbench.env.config import EnvConfig
            from navbench.scene.cache import load_scene_and_navgrid
            self._grids[key] = load_scene_and_navgrid(scene_path, EnvConfig().nav_grid_config())[1]
        img = query_view(localizer, query, candidates, record, self._grids[key])
        name = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in str(record["id"]))
        cv2.imwrite(str(self.out / f"{name}.png"), img[..., ::-1])
