"""Floor plans of the procedural houses: rooms on a 5 cm grid, their types, and the doorways between them.

A rectangle of roughly ``n_rooms x 12-22 m^2`` is cut into 3-8 rectangular rooms, either by binary
space partitioning or as a corridor (the hallway) with rooms sliced off both sides. Rooms sharing a
wall long enough for a doorway are graph neighbours; a random spanning tree of that graph (hallway
edges first) gets a doorway on each edge, so every room is reachable, and each remaining edge gets
an extra doorway with probability ``extra_door_prob``. Larger rooms go to types that prefer space.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree

from navbench.scene.procedural.config import PLAN_UNIT, HouseConfig, HouseConfigError

# Larger rooms go to types with a larger preference (plus noise), bathrooms to the smallest.
_SIZE_PREFERENCE = {"living_room": 5.0, "dining_room": 4.0, "bedroom": 3.0, "kitchen": 3.0, "office": 2.0,
                    "laundry": 0.8, "bathroom": 0.5, "hallway": 0.0}
_BASE_TYPES = ("living_room", "kitchen", "bathroom", "bedroom")
_EXTRA_TYPES = ("bedroom", "dining_room", "office", "bathroom", "laundry", "bedroom", "office")

Rect = tuple[int, int, int, int]  # x0, z0, x1, z1 in PLAN_UNITs


@dataclass(frozen=True)
class Room:
    name: str
    type: str
    rect: tuple[float, float, float, float]  # wall centre lines, metres
    interior: tuple[float, float, float, float]  # inner wall faces, metres


@dataclass(frozen=True)
class Door:
    rooms: tuple[int, int]
    axis: Literal["x", "z"]  # direction the wall runs in: "x" -> wall at z = coord; "z" -> wall at x = coord
    coord: int
    lo: int
    hi: int


def _units(metres: float) -> int:
    return int(round(metres / PLAN_UNIT))


def _slices(rng: np.random.Generator, lo: int, hi: int, k: int, mn: int) -> list[tuple[int, int]] | None:
    """Cut [lo, hi] into k consecutive pieces each at least mn long."""
    extra = hi - lo - k * mn
    if extra < 0:
        return None
    widths = mn + np.floor(rng.dirichlet(np.ones(k)) * extra).astype(int)
    widths[-1] += hi - lo - int(widths.sum())
    edges = lo + np.concatenate([[0], np.cumsum(widths)])
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def _split_bsp(rng: np.random.Generator, width: int, depth: int, n: int, mn: int) -> list[Rect] | None:
    rects: list[Rect] = [(0, 0, width, depth)]
    while len(rects) < n:
        sides = [(r[2] - r[0], r[3] - r[1]) for r in rects]
        cands = [i for i, (w, d) in enumerate(sides) if max(w, d) >= 2 * mn]
        if not cands:
            return None
        areas = np.array([sides[i][0] * sides[i][1] for i in cands], float)
        i = cands[int(rng.choice(len(cands), p=areas / areas.sum()))]
        x0, z0, x1, z1 = rects.pop(i)
        w, d = x1 - x0, z1 - z0
        if w < 2 * mn:
            along_x = False
        elif d < 2 * mn:
            along_x = True
        else:  # cut across the long side; near-square rooms either way
            along_x = w > 1.25 * d or (d <= 1.25 * w and rng.random() < 0.5)
        length = w if along_x else d
        cut = int(np.clip(round(rng.uniform(0.35, 0.65) * length), mn, length - mn))
        halves = [(x0, z0, x0 + cut, z1), (x0 + cut, z0, x1, z1)] if along_x else \
            [(x0, z0, x1, z0 + cut), (x0, z0 + cut, x1, z1)]
        rects[i:i] = halves
    return rects


def _split_hallway(rng: np.random.Generator, width: int, depth: int, n: int, mn: int) -> tuple[list[Rect], int] | None:
    """A corridor along x across the whole house, rooms sliced off both sides of it."""
    cw = _units(rng.uniform(1.3, 1.8))
    if depth < 2 * mn + cw:
        return None
    zc = int(rng.integers(mn, depth - cw - mn + 1))
    k = n - 1
    k_a = int(np.clip(round(k * zc / (depth - cw)), 1, k - 1))
    side_a = _slices(rng, 0, width, k_a, mn)
    side_b = _slices(rng, 0, width, k - k_a, mn)
    if side_a is None or side_b is None:
        return None
    rects = [(a, 0, b, zc) for a, b in side_a] + [(0, zc, width, zc + cw)] + [(a, zc + cw, b, depth) for a, b in side_b]
    return rects, len(side_a)


def _adjacency(rects: list[Rect]) -> list[Door]:
    """Every shared wall between two rooms, as a full-length 'door' candidate (lo, hi = the overlap)."""
    shared: list[Door] = []
    for i in range(len(rects)):
        for j in range(i + 1, len(rects)):
            a, b = rects[i], rects[j]
            for c in {a[0], a[2]} & {b[0], b[2]}:  # a vertical line x = c bounds both
                lo, hi = max(a[1], b[1]), min(a[3], b[3])
                if hi > lo and (c == a[2]) != (c == b[2]):
                    shared.append(Door((i, j), "z", c, lo, hi))
            for c in {a[1], a[3]} & {b[1], b[3]}:
                lo, hi = max(a[0], b[0]), min(a[2], b[2])
                if hi > lo and (c == a[3]) != (c == b[3]):
                    shared.append(Door((i, j), "x", c, lo, hi))
    return sorted(shared, key=lambda e: (e.rooms, e.axis, e.coord))


def floor_plan(rng: np.random.Generator, cfg: HouseConfig) -> tuple[list[Rect], int | None, list[Door]]:
    """Room rectangles, the hallway's index (or None) and the doorways, all in plan units."""
    n = int(rng.integers(cfg.min_rooms, cfg.max_rooms + 1))
    mn = _units(cfg.min_room_size)
    margin = _units(cfg.wall_thickness / 2 + 0.15)  # doorway edge to perpendicular wall
    dmin, dmax = _units(cfg.door_width[0]), _units(cfg.door_width[1])
    lim = _units(cfg.max_extent)
    for _ in range(200):
        area = n * rng.uniform(*cfg.room_area)
        aspect = rng.uniform(1.0, 1.5)
        width = min(lim, _units(math.sqrt(area * aspect)))
        depth = max(mn, min(lim, _units(area / (width * PLAN_UNIT))))
        hallway: int | None = None
        if n >= 5 and rng.random() < cfg.hallway_prob:
            out = _split_hallway(rng, width, depth, n, mn)
            rects, hallway = out if out is not None else (None, None)
        else:
            rects = _split_bsp(rng, width, depth, n, mn)
        if rects is None:
            continue
        if rng.random() < 0.5:  # the generators cut along x first; transpose half the houses
            rects = [(z0, x0, z1, x1) for x0, z0, x1, z1 in rects]
            width, depth = depth, width
        ox, oz = -(width // 2), -(depth // 2)  # centre the house on the origin
        rects = [(x0 + ox, z0 + oz, x1 + ox, z1 + oz) for x0, z0, x1, z1 in rects]

        usable = [e for e in _adjacency(rects) if e.hi - e.lo >= dmin + 2 * margin]
        # A random spanning tree (minimum over random weights; corridor edges first) gets doorways,
        # so every room is reachable; each other shared wall gets one with extra_door_prob.
        n_rooms = len(rects)
        weights = np.zeros((n_rooms, n_rooms))
        for e, key in zip(usable, rng.random(len(usable))):
            weights[e.rooms] = 1.0 + key + (0.0 if hallway in e.rooms else 2.0)
        tree = minimum_spanning_tree(csr_matrix(weights)).toarray() > 0
        if connected_components(csr_matrix(tree), directed=False)[0] != 1:
            continue
        extra = rng.random(len(usable)) < cfg.extra_door_prob
        chosen = [e for e, x in zip(usable, extra) if tree[e.rooms] or x]
        doors = []
        for e in sorted(chosen, key=lambda e: (e.rooms, e.axis, e.coord)):
            w = int(rng.integers(dmin, min(dmax, e.hi - e.lo - 2 * margin) + 1))
            s = int(rng.integers(e.lo + margin, e.hi - margin - w + 1))
            doors.append(Door(e.rooms, e.axis, e.coord, s, s + w))
        return rects, hallway, doors
    raise HouseConfigError(f"no floor plan with {n} rooms fits the config (room_area {cfg.room_area}, "
                           f"min_room_size {cfg.min_room_size}, max_extent {cfg.max_extent})")


def room_types(rng: np.random.Generator, rects: list[Rect], hallway: int | None) -> list[str]:
    others = [i for i in range(len(rects)) if i != hallway]
    m = len(others)
    types = list(_BASE_TYPES[:m])
    if m > len(types):
        k = m - len(types)
        types += [str(t) for t in rng.choice(_EXTRA_TYPES, size=k, replace=k > len(_EXTRA_TYPES))]
    pref = np.array([_SIZE_PREFERENCE[t] for t in types]) + rng.uniform(0, 1.5, len(types))
    area = np.array([(rects[i][2] - rects[i][0]) * (rects[i][3] - rects[i][1]) for i in others])
    out = [""] * len(rects)
    rooms_by_size = np.array(others)[np.argsort(-area, kind="stable")]
    types_by_size = np.array(types)[np.argsort(-pref, kind="stable")]
    for room, t in zip(rooms_by_size, types_by_size):
        out[int(room)] = str(t)
    if hallway is not None:
        out[hallway] = "hallway"
    return out
