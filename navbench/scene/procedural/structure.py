"""Structure meshes of the procedural houses: walls with doorways and lintels, door frames, skirting,
and the colours of floors, walls and ceilings. Walls are closed 0.1 m boxes on the room boundaries."""

from __future__ import annotations

import math

import numpy as np
import trimesh

from navbench.scene.procedural.config import PLAN_UNIT, HouseConfig
from navbench.scene.procedural.plan import Door, Rect

FLOOR_COLOURS: tuple[tuple[int, int, int], ...] = (
    (165, 125, 85),  # oak
    (110, 80, 55),  # walnut
    (200, 170, 125),  # light wood
    (160, 160, 155),  # grey tile
    (215, 215, 208),  # white tile
    (170, 95, 70),  # terracotta
    (90, 95, 100),  # slate
    (95, 120, 90),  # green carpet
    (90, 100, 135),  # blue carpet
    (190, 175, 150),  # beige carpet
)
WALL_COLOURS: tuple[tuple[int, int, int], ...] = (
    (236, 234, 228),
    (226, 231, 236),
    (238, 229, 216),
    (229, 236, 226),
    (240, 234, 234),
)
CEILING_COLOUR = (246, 246, 243)


def coloured_box(lo, hi, rgb) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    box = trimesh.creation.box(extents=hi - lo, transform=trimesh.transformations.translation_matrix((lo + hi) / 2))
    colours = np.tile(np.array([*rgb, 255], np.uint8), (len(box.vertices), 1))
    return trimesh.Trimesh(box.vertices, box.faces, vertex_colors=colours, process=False)


def _merge_intervals(intervals: list[tuple[int, int]]) -> list[tuple[int, int]]:
    merged: list[list[int]] = []
    for lo, hi in sorted(intervals):
        if merged and lo <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    return [(a, b) for a, b in merged]


def wall_mesh(rects: list[Rect], doors: list[Door], cfg: HouseConfig, rgb) -> trimesh.Trimesh:
    """Closed wall boxes along every room boundary, cut at doorways (with a lintel above each)."""
    lines: dict[tuple[str, int], list[tuple[int, int]]] = {}
    for x0, z0, x1, z1 in rects:
        for key, span in ((("x", z0), (x0, x1)), (("x", z1), (x0, x1)), (("z", x0), (z0, z1)), (("z", x1), (z0, z1))):
            lines.setdefault(key, []).append(span)
    t, h = cfg.wall_thickness, cfg.wall_height
    boxes = []

    def box(axis: str, coord: int, a: float, b: float, y0: float, y1: float) -> trimesh.Trimesh:
        c = coord * PLAN_UNIT
        if axis == "x":
            return coloured_box((a, y0, c - t / 2), (b, y1, c + t / 2), rgb)
        return coloured_box((c - t / 2, y0, a), (c + t / 2, y1, b), rgb)

    for (axis, coord) in sorted(lines):
        cuts = sorted((d.lo, d.hi) for d in doors if d.axis == axis and d.coord == coord)
        for lo, hi in _merge_intervals(lines[(axis, coord)]):
            # Solid pieces between doorways; the ends of a wall run overlap the crossing wall by t/2
            # so corners are closed.
            edges = [(lo, True)]
            edges += [e for d in cuts if lo <= d[0] and d[1] <= hi for e in ((d[0], False), (d[1], False))]
            edges.append((hi, True))
            for (a, a_end), (b, b_end) in zip(edges[::2], edges[1::2]):
                if b > a:
                    boxes.append(box(axis, coord, a * PLAN_UNIT - (t / 2 if a_end else 0.0),
                                     b * PLAN_UNIT + (t / 2 if b_end else 0.0), 0.0, h))
        for d_lo, d_hi in cuts:  # lintels
            boxes.append(box(axis, coord, d_lo * PLAN_UNIT, d_hi * PLAN_UNIT, cfg.door_height, h))
    return trimesh.util.concatenate(boxes)


def trim_mesh(rects: list[Rect], doors: list[Door], cfg: HouseConfig, rgb) -> trimesh.Trimesh:
    """Door frames (casings proud of both wall faces) and skirting boards: cheap depth and colour cues."""
    t, fw, proud = cfg.wall_thickness, 0.06, 0.02
    skirt_h, skirt_t = 0.08, 0.012
    boxes = []
    for d in doors:
        c, lo, hi = d.coord * PLAN_UNIT, d.lo * PLAN_UNIT, d.hi * PLAN_UNIT
        pieces = [(lo - fw, lo, 0.0, cfg.door_height + fw), (hi, hi + fw, 0.0, cfg.door_height + fw),
                  (lo - fw, hi + fw, cfg.door_height, cfg.door_height + fw)]
        for a, b, y0, y1 in pieces:
            if d.axis == "x":
                boxes.append(coloured_box((a, y0, c - t / 2 - proud), (b, y1, c + t / 2 + proud), rgb))
            else:
                boxes.append(coloured_box((c - t / 2 - proud, y0, a), (c + t / 2 + proud, y1, b), rgb))
    for i, (x0, z0, x1, z1) in enumerate(rects):
        # (wall axis, wall coord, span along the wall, which way the room lies from the wall)
        for axis, coord, (a, b), inward in (("x", z0, (x0, x1), 1.0), ("x", z1, (x0, x1), -1.0),
                                             ("z", x0, (z0, z1), 1.0), ("z", x1, (z0, z1), -1.0)):
            face = coord * PLAN_UNIT + inward * t / 2
            cuts = sorted((d.lo * PLAN_UNIT - fw, d.hi * PLAN_UNIT + fw) for d in doors
                          if i in d.rooms and d.axis == axis and d.coord == coord)
            start = a * PLAN_UNIT + t / 2
            for lo, hi in [*cuts, (b * PLAN_UNIT - t / 2, math.inf)]:
                if lo > start:
                    z_lo, z_hi = sorted((face, face + inward * skirt_t))
                    if axis == "x":
                        boxes.append(coloured_box((start, 0.0, z_lo), (lo, skirt_h, z_hi), rgb))
                    else:
                        boxes.append(coloured_box((z_lo, 0.0, start), (z_hi, skirt_h, lo), rgb))
                start = hi
    return trimesh.util.concatenate(boxes)

