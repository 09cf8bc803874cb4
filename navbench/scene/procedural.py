"""Seeded procedural multi-room houses: floor plan, walls with doorways, furniture, GLB + semantic JSON.

``generate_house(seed)`` builds one house as a :class:`trimesh.Scene` plus its semantic annotation (the
schema of :mod:`navbench.scene.asset`, plus ``scene_id``, ``seed``, room ``type`` and ``doors``):

1. **Floor plan.** A rectangle of roughly ``n_rooms x 12-22 m^2`` is cut into 3-8 rectangular rooms,
   either by binary space partitioning or as a corridor (the hallway) with rooms sliced off both sides.
   The plan lives on a 5 cm integer grid so adjacency tests are exact.
2. **Doors.** Rooms sharing a wall long enough for a doorway are graph neighbours; a random spanning
   tree of that graph (hallway edges first) gets a doorway on each edge, so every room is reachable,
   and each remaining edge gets an extra doorway with probability ``extra_door_prob``.
3. **Structure.** Walls are closed 0.1 m boxes on the room boundaries (with lintels above doorways), a
   floor slab per room with its own colour (node ``floor_<room>``), and a ceiling (node ``ceiling``).
4. **Furniture.** Each room type has a recipe of categories (anchors first, then random extras, some
   with companions: chairs around a table, a chair at a desk, nightstands beside a bed, a TV on its
   stand). A candidate pose is accepted only if its AABB stays inside the room, clears every other
   object by a margin, stays out of the keep-out zone in front of each doorway, and the room's free
   floor - eroded by the agent radius - stays one connected region. Objects get named colours,
   distinct per category where possible.

Everything is drawn from one ``numpy`` generator seeded with ``seed`` and no set/dict iteration order
or float formatting depends on anything else, so the same seed gives byte-identical GLB and JSON.

    navbench generate scenes            # the bundled houses (envs/houses), seed 0
    navbench generate policy-train      # + envs/houses_policy_train and its train_large episodes
    navbench generate policy-select     # + envs/houses_policy_select and its select episodes
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import trimesh
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree

from navbench.scene.asset import ObjectAnnotation, RoomAnnotation
from navbench.scene.categories import CATEGORIES, COLOURS, WALL_MOUNT_HEIGHT, Category, paint

PLAN_UNIT = 0.05  # metres per floor-plan grid unit

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


class HouseConfigError(ValueError):
    """A :class:`HouseConfig` value is out of range; the message names it."""


@dataclass(frozen=True)
class HouseConfig:
    min_rooms: int = 3
    max_rooms: int = 8
    max_extent: float = 20.0  # the house fits in max_extent x max_extent metres
    room_area: tuple[float, float] = (12.0, 22.0)  # m^2 of footprint per room, sampled per house
    min_room_size: float = 2.4  # smallest room side (wall centre to wall centre)
    hallway_prob: float = 0.5  # chance of a corridor layout when there are >= 5 rooms
    wall_thickness: float = 0.1
    wall_height: float = 2.6
    door_height: float = 2.1
    door_width: tuple[float, float] = (0.9, 1.2)
    extra_door_prob: float = 0.25
    door_clearance: float = 0.7  # free corridor depth in front of each doorway, both sides
    objects_per_room: tuple[int, int] = (3, 8)
    object_margin: float = 0.05  # minimum horizontal gap between object AABBs
    agent_radius: float = 0.18
    agent_height: float = 0.88
    grid: float = 0.05  # free-space raster cell used for the connectivity check
    furnish: bool = True

    def __post_init__(self) -> None:
        if not 1 <= self.min_rooms <= self.max_rooms:
            raise HouseConfigError(
                f"room count range ({self.min_rooms}, {self.max_rooms}) must satisfy 1 <= min <= max")
        if self.min_room_size < 2.0 or self.max_extent < self.min_room_size:
            raise HouseConfigError(
                f"min_room_size {self.min_room_size} must be >= 2.0 and <= max_extent {self.max_extent}")
        if not 0.0 < self.room_area[0] <= self.room_area[1]:
            raise HouseConfigError(f"room_area {self.room_area} must be an increasing positive range")
        if not 2 * self.agent_radius < self.door_width[0] <= self.door_width[1]:
            raise HouseConfigError(f"door_width {self.door_width} must be increasing and wider than the agent")
        if not self.door_height < self.wall_height:
            raise HouseConfigError(f"door_height {self.door_height} must be below wall_height {self.wall_height}")
        if not 0 <= self.objects_per_room[0] <= self.objects_per_room[1]:
            raise HouseConfigError(f"objects_per_room {self.objects_per_room} must be an increasing range >= 0")


# --------------------------------------------------------------------------------------------------
# room recipes


@dataclass(frozen=True)
class Companion:
    """Objects placed relative to an anchor: ``around`` a table, in ``front`` of / ``beside`` / ``on`` it."""

    category: str
    relation: Literal["around", "front", "beside", "on"]
    count: tuple[int, int]  # (min, max); the anchor is dropped if fewer than min fit
    gap: float = 0.08


@dataclass(frozen=True)
class Item:
    category: str
    chance: float = 1.0  # 1.0 = anchor: always attempted, before the shuffled extras
    companions: tuple[Companion, ...] = ()
    central: bool = False  # free-standing anywhere (a table group, a rug) rather than mostly by a wall


RECIPES: dict[str, tuple[Item, ...]] = {
    "kitchen": (
        Item("counter", 1.0, (Companion("microwave", "on", (0, 1)),)),
        Item("refrigerator"),
        Item("oven", 0.8),
        Item("sink", 0.6),
        Item("table", 0.6, (Companion("chair", "around", (2, 4)),), central=True),
        Item("stool", 0.4),
        Item("plant", 0.5),
        Item("trash_can", 0.5),
        Item("cabinet", 0.4),
        Item("clock", 0.4),
        Item("towel", 0.3),
        Item("picture", 0.3),
    ),
    "living_room": (
        Item("sofa", 1.0, (Companion("coffee_table", "front", (0, 1), gap=0.4),)),
        Item("tv_stand", 0.8, (Companion("tv_monitor", "on", (1, 1)),)),
        Item("armchair", 0.6),
        Item("plant", 0.7),
        Item("lamp", 0.5),
        Item("bookshelf", 0.5),
        Item("rug", 0.4, central=True),
        Item("picture", 0.6),
        Item("clock", 0.3),
        Item("cabinet", 0.3),
    ),
    "bedroom": (
        Item("bed", 1.0, (Companion("nightstand", "beside", (0, 2), gap=0.06),)),
        Item("wardrobe", 0.7),
        Item("table_lamp", 0.6),
        Item("dresser", 0.4),
        Item("desk", 0.3, (Companion("chair", "front", (1, 1)),)),
        Item("mirror", 0.4),
        Item("picture", 0.5),
        Item("plant", 0.4),
        Item("rug", 0.3, central=True),
        Item("laundry_basket", 0.3),
        Item("armchair", 0.2),
        Item("bookshelf", 0.2),
    ),
    "bathroom": (
        Item("toilet"),
        Item("sink"),
        Item("bathtub", 0.5),
        Item("shower", 0.5),
        Item("towel", 0.8),
        Item("mirror", 0.7),
        Item("cabinet", 0.3),
        Item("trash_can", 0.4),
        Item("laundry_basket", 0.3),
        Item("washer", 0.2),
        Item("plant", 0.2),
        Item("picture", 0.2),
    ),
    "dining_room": (
        Item("table", 1.0, (Companion("chair", "around", (2, 6)),), central=True),
        Item("cabinet", 0.6),
        Item("plant", 0.6),
        Item("picture", 0.6),
        Item("lamp", 0.4),
        Item("clock", 0.4),
        Item("rug", 0.3, central=True),
    ),
    "office": (
        Item("desk", 1.0, (Companion("chair", "front", (1, 1)), Companion("tv_monitor", "on", (0, 1)))),
        Item("bookshelf", 0.8),
        Item("cabinet", 0.5),
        Item("plant", 0.6),
        Item("armchair", 0.3),
        Item("lamp", 0.4),
        Item("picture", 0.5),
        Item("clock", 0.4),
        Item("trash_can", 0.4),
        Item("sofa", 0.2),
    ),
    "hallway": (
        Item("shoe_rack", 0.7),
        Item("coat_rack", 0.5),
        Item("plant", 0.6),
        Item("picture", 0.8),
        Item("mirror", 0.6),
        Item("clock", 0.5),
        Item("cabinet", 0.4),
        Item("dresser", 0.2),
        Item("rug", 0.3, central=True),
    ),
    "laundry": (
        Item("washer"),
        Item("dryer", 0.8),
        Item("sink", 0.5),
        Item("cabinet", 0.6),
        Item("laundry_basket", 0.8),
        Item("towel", 0.4),
        Item("trash_can", 0.3),
        Item("plant", 0.3),
        Item("picture", 0.3),
    ),
}

# Larger rooms go to types with a larger preference (plus noise), bathrooms to the smallest.
_SIZE_PREFERENCE = {"living_room": 5.0, "dining_room": 4.0, "bedroom": 3.0, "kitchen": 3.0, "office": 2.0,
                    "laundry": 0.8, "bathroom": 0.5, "hallway": 0.0}
_BASE_TYPES = ("living_room", "kitchen", "bathroom", "bedroom")
_EXTRA_TYPES = ("bedroom", "dining_room", "office", "bathroom", "laundry", "bedroom", "office")

# --------------------------------------------------------------------------------------------------
# floor plan (integer grid units)

Rect = tuple[int, int, int, int]  # x0, z0, x1, z1 in PLAN_UNITs


@dataclass(frozen=True)
class _Room:
    name: str
    type: str
    rect: tuple[float, float, float, float]  # wall centre lines, metres
    interior: tuple[float, float, float, float]  # inner wall faces, metres


@dataclass(frozen=True)
class _Door:
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


def _adjacency(rects: list[Rect]) -> list[_Door]:
    """Every shared wall between two rooms, as a full-length 'door' candidate (lo, hi = the overlap)."""
    shared: list[_Door] = []
    for i in range(len(rects)):
        for j in range(i + 1, len(rects)):
            a, b = rects[i], rects[j]
            for c in {a[0], a[2]} & {b[0], b[2]}:  # a vertical line x = c bounds both
                lo, hi = max(a[1], b[1]), min(a[3], b[3])
                if hi > lo and (c == a[2]) != (c == b[2]):
                    shared.append(_Door((i, j), "z", c, lo, hi))
            for c in {a[1], a[3]} & {b[1], b[3]}:
                lo, hi = max(a[0], b[0]), min(a[2], b[2])
                if hi > lo and (c == a[3]) != (c == b[3]):
                    shared.append(_Door((i, j), "x", c, lo, hi))
    return sorted(shared, key=lambda e: (e.rooms, e.axis, e.coord))


def _plan(rng: np.random.Generator, cfg: HouseConfig) -> tuple[list[Rect], int | None, list[_Door]]:
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
            doors.append(_Door(e.rooms, e.axis, e.coord, s, s + w))
        return rects, hallway, doors
    raise HouseConfigError(f"no floor plan with {n} rooms fits the config (room_area {cfg.room_area}, "
                           f"min_room_size {cfg.min_room_size}, max_extent {cfg.max_extent})")


def _room_types(rng: np.random.Generator, rects: list[Rect], hallway: int | None) -> list[str]:
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


# --------------------------------------------------------------------------------------------------
# structure meshes


def _coloured_box(lo, hi, rgb) -> trimesh.Trimesh:
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


def _walls(rects: list[Rect], doors: list[_Door], cfg: HouseConfig, rgb) -> trimesh.Trimesh:
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
            return _coloured_box((a, y0, c - t / 2), (b, y1, c + t / 2), rgb)
        return _coloured_box((c - t / 2, y0, a), (c + t / 2, y1, b), rgb)

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


def _trim(rects: list[Rect], doors: list[_Door], cfg: HouseConfig, rgb) -> trimesh.Trimesh:
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
                boxes.append(_coloured_box((a, y0, c - t / 2 - proud), (b, y1, c + t / 2 + proud), rgb))
            else:
                boxes.append(_coloured_box((c - t / 2 - proud, y0, a), (c + t / 2 + proud, y1, b), rgb))
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
                        boxes.append(_coloured_box((start, 0.0, z_lo), (lo, skirt_h, z_hi), rgb))
                    else:
                        boxes.append(_coloured_box((z_lo, 0.0, start), (z_hi, skirt_h, lo), rgb))
                start = hi
    return trimesh.util.concatenate(boxes)


# --------------------------------------------------------------------------------------------------
# furnishing

_ROTATIONS = [  # quarter turns about +y; turn k maps the object's front (+z) to _FRONTS[k]
    np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1]]),
    np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]),
    np.array([[-1.0, 0, 0], [0, 1, 0], [0, 0, -1]]),
    np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]]),
]
_FRONTS = [np.array([0.0, 1.0]), np.array([1.0, 0.0]), np.array([0.0, -1.0]), np.array([-1.0, 0.0])]  # (x, z)


@dataclass(eq=False)  # identity semantics: placed objects are removed from lists by identity
class _Placed:
    category: str
    mesh: trimesh.Trimesh  # object-local, unpainted (shared between identical chairs)
    yaw: int
    pos: np.ndarray  # world position of the local origin (base centre)
    room: int
    support: "_Placed | None" = None
    colour: str = ""
    lo: np.ndarray = field(init=False)
    hi: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        half = self.mesh.extents / 2.0
        hx, hz = (half[2], half[0]) if self.yaw % 2 else (half[0], half[2])
        self.lo = self.pos + np.array([-hx, 0.0, -hz])
        self.hi = self.pos + np.array([hx, 2 * half[1], hz])

    @property
    def width(self) -> float:  # along the object's own x (across its front)
        return float(self.mesh.extents[0])

    @property
    def depth(self) -> float:
        return float(self.mesh.extents[2])

    def world_mesh(self) -> trimesh.Trimesh:
        painted = paint(self.mesh, COLOURS[self.colour])
        vertices = painted.vertices @ _ROTATIONS[self.yaw].T + self.pos
        return trimesh.Trimesh(vertices, painted.faces, vertex_colors=painted.visual.vertex_colors, process=False)


class _Furnisher:
    """Places objects in one room, keeping doorways clear and the free floor connected."""

    def __init__(self, rng: np.random.Generator, cfg: HouseConfig, index: int, room: _Room,
                 keepouts: list[tuple[float, float, float, float]]):
        self.rng, self.cfg, self.index, self.room = rng, cfg, index, room
        self.keepouts = keepouts
        self.items: list[_Placed] = []
        x0, z0, x1, z1 = room.interior
        g, r = cfg.grid, cfg.agent_radius
        self.xs = x0 + (np.arange(int((x1 - x0) / g)) + 0.5) * g
        self.zs = z0 + (np.arange(int((z1 - z0) / g)) + 0.5) * g
        # Cells where the agent's centre can be, ignoring furniture: r away from every wall face.
        in_x = (self.xs >= x0 + r) & (self.xs <= x1 - r)
        in_z = (self.zs >= z0 + r) & (self.zs <= z1 - r)
        self.free = in_x[:, None] & in_z[None, :]

    # ---- checks

    def _fits(self, p: _Placed) -> bool:
        x0, z0, x1, z1 = self.room.interior
        eps = 1e-9
        if p.lo[0] < x0 - eps or p.lo[2] < z0 - eps or p.hi[0] > x1 + eps or p.hi[2] > z1 + eps:
            return False
        if p.hi[1] > self.cfg.wall_height - 0.05:
            return False
        for kx0, kz0, kx1, kz1 in self.keepouts:
            if p.lo[0] < kx1 and kx0 < p.hi[0] and p.lo[2] < kz1 and kz0 < p.hi[2]:
                return False
        m = self.cfg.object_margin
        for q in self.items:
            if q is p.support:
                continue
            if (p.lo[0] < q.hi[0] + m and q.lo[0] < p.hi[0] + m and p.lo[2] < q.hi[2] + m and q.lo[2] < p.hi[2] + m
                    and p.lo[1] < q.hi[1] and q.lo[1] < p.hi[1]):
                return False
        return True

    def _is_obstacle(self, p: _Placed) -> bool:
        # Flat rugs are walkable; wall-mounted things above the agent's head do not block it.
        return p.hi[1] > 0.05 and p.lo[1] < self.cfg.agent_height

    def _connected(self, extra: _Placed) -> bool:
        if not self._is_obstacle(extra):
            return True
        free = self.free.copy()
        r = self.cfg.agent_radius
        for p in [*self.items, extra]:
            if self._is_obstacle(p):
                mx = (self.xs > p.lo[0] - r) & (self.xs < p.hi[0] + r)
                mz = (self.zs > p.lo[2] - r) & (self.zs < p.hi[2] + r)
                free &= ~(mx[:, None] & mz[None, :])
        _, n = ndimage.label(free)
        return n == 1

    def _try(self, p: _Placed) -> bool:
        if self._fits(p) and self._connected(p):
            self.items.append(p)
            return True
        return False

    # ---- candidate poses

    def _against_wall(self, cat: str, mesh: trimesh.Trimesh, gap: float, y: float = 0.0) -> _Placed | None:
        x0, z0, x1, z1 = self.room.interior
        side = int(self.rng.integers(4))  # == yaw: 0 wall at z0, 1 at x0, 2 at z1, 3 at x1
        w, d = float(mesh.extents[0]), float(mesh.extents[2])
        a, b = (x0, x1) if side % 2 == 0 else (z0, z1)
        if b - a < w:
            return None
        t = float(self.rng.uniform(a + w / 2, b - w / 2))
        depth_pos = {0: z0 + gap + d / 2, 1: x0 + gap + d / 2, 2: z1 - gap - d / 2, 3: x1 - gap - d / 2}[side]
        x, z = (t, depth_pos) if side % 2 == 0 else (depth_pos, t)
        return _Placed(cat, mesh, side, np.array([x, y, z]), self.index)

    def _free_pose(self, cat: str, mesh: trimesh.Trimesh) -> _Placed | None:
        x0, z0, x1, z1 = self.room.interior
        yaw = int(self.rng.integers(4))
        ext = mesh.extents
        hx, hz = (ext[2] / 2, ext[0] / 2) if yaw % 2 else (ext[0] / 2, ext[2] / 2)
        if x1 - x0 < 2 * hx or z1 - z0 < 2 * hz:
            return None
        pos = np.array([self.rng.uniform(x0 + hx, x1 - hx), 0.0, self.rng.uniform(z0 + hz, z1 - hz)])
        return _Placed(cat, mesh, yaw, pos, self.index)

    def _candidate(self, cat: Category, mesh: trimesh.Trimesh, central: bool) -> _Placed | None:
        if cat.placement == "wall":
            return self._against_wall(cat.name, mesh, gap=0.02)
        if cat.placement == "wall_mounted":
            h = float(mesh.extents[1])
            centre = self.rng.uniform(*WALL_MOUNT_HEIGHT)
            centre = min(centre, self.cfg.wall_height - 0.1 - h / 2)
            return self._against_wall(cat.name, mesh, gap=0.005, y=centre - h / 2)
        if not central and self.rng.random() < 0.6:  # free-standing things mostly by a wall
            return self._against_wall(cat.name, mesh, gap=0.05)
        return self._free_pose(cat.name, mesh)

    def _on(self, cat: str, mesh: trimesh.Trimesh, support: _Placed) -> _Placed | None:
        """On top of ``support``, facing the same way, fully inside its footprint."""
        front = _FRONTS[support.yaw]
        side = np.array([front[1], -front[0]])
        slack_w, slack_d = support.width - mesh.extents[0], support.depth - mesh.extents[2]
        if slack_w < 0 or slack_d < 0:
            return None
        centre = (support.lo + support.hi) / 2
        u = self.rng.uniform(-slack_w / 2, slack_w / 2)
        v = self.rng.uniform(-slack_d / 2, slack_d / 2)
        xz = centre[[0, 2]] + u * side + v * front
        return _Placed(cat, mesh, support.yaw, np.array([xz[0], support.hi[1], xz[1]]), self.index, support=support)

    def _companions(self, anchor: _Placed, comp: Companion, n: int) -> list[_Placed]:
        cat = CATEGORIES[comp.category]
        placed: list[_Placed] = []
        if n <= 0:
            return placed
        mesh = cat.build(self.rng)  # one shape per group: a set of matching chairs
        centre = (anchor.lo + anchor.hi) / 2
        front = _FRONTS[anchor.yaw]
        side = np.array([front[1], -front[0]])
        poses: list[tuple[np.ndarray, int]] = []  # (xz centre, yaw)
        if comp.relation == "around":
            # Seats along the two long sides first, then the ends; each chair faces the table.
            ext = anchor.hi - anchor.lo
            long_x = ext[0] >= ext[2]
            length = ext[0] if long_x else ext[2]
            per_side = 2 if length >= 2 * (mesh.extents[0] + 0.15) else 1
            offsets = [0.0] if per_side == 1 or n <= 2 else [-length / 4, length / 4]
            slots = [(long_x, s, off) for off in offsets for s in (1.0, -1.0)]
            slots += [(not long_x, 1.0, 0.0), (not long_x, -1.0, 0.0)]
            for across_z, s, off in slots:  # across_z: the chair sits beyond a z edge of the table
                dist = (ext[2] if across_z else ext[0]) / 2 + comp.gap + mesh.extents[2] / 2
                if across_z:
                    xz = centre[[0, 2]] + np.array([off, s * dist])
                    yaw = 2 if s > 0 else 0
                else:
                    xz = centre[[0, 2]] + np.array([s * dist, off])
                    yaw = 3 if s > 0 else 1
                poses.append((xz, yaw))
        elif comp.relation == "front":
            dist = anchor.depth / 2 + comp.gap + mesh.extents[2] / 2
            poses.append((centre[[0, 2]] + dist * front, (anchor.yaw + 2) % 4))
        elif comp.relation == "beside":
            back = centre[[0, 2]] - front * anchor.depth / 2
            for s in self.rng.permutation([1.0, -1.0]):
                lateral = anchor.width / 2 + comp.gap + mesh.extents[0] / 2
                poses.append((back + front * (mesh.extents[2] / 2) + s * lateral * side, anchor.yaw))
        for xz, yaw in poses:
            if len(placed) >= n:
                break
            p = _Placed(cat.name, mesh, yaw, np.array([xz[0], 0.0, xz[1]]), self.index)
            if self._try(p):
                placed.append(p)
        if comp.relation == "on":
            for _ in range(8 * n):
                if len(placed) >= n:
                    break
                p = self._on(cat.name, mesh, anchor)
                if p is not None and self._try(p):
                    placed.append(p)
        return placed

    # ---- recipes

    def place(self, item: Item, budget: int, attempts: int = 30) -> int:
        """Place ``item`` (and its companions) within ``budget`` objects; returns how many were placed."""
        cat = CATEGORIES[item.category]
        if budget <= 0:
            return 0
        if cat.placement == "on_surface":
            supports = [p for p in self.items if p.category in cat.supports]
            for support in [supports[i] for i in self.rng.permutation(len(supports))]:
                mesh = cat.build(self.rng)
                for _ in range(6):
                    p = self._on(cat.name, mesh, support)
                    if p is not None and self._try(p):
                        return 1
            return 0
        mesh = cat.build(self.rng)
        for _ in range(attempts):
            anchor = self._candidate(cat, mesh, item.central)
            if anchor is None or not self._try(anchor):
                continue
            group = [anchor]
            ok = True
            for comp in item.companions:
                lo, hi = comp.count
                want = min(int(self.rng.integers(lo, hi + 1)), budget - len(group))
                got = self._companions(anchor, comp, want) if want >= lo else []
                group += got
                if len(got) < lo:
                    ok = False
                    break
            if ok:
                return len(group)
            for p in group:
                self.items.remove(p)
        return 0


def _furnish(rng: np.random.Generator, cfg: HouseConfig, rooms: list[_Room], doors: list[_Door]) -> list[_Placed]:
    t = cfg.wall_thickness
    furnishers = []
    for i, room in enumerate(rooms):
        keepouts = []
        for d in doors:
            if i not in d.rooms:
                continue
            c, lo, hi = d.coord * PLAN_UNIT, d.lo * PLAN_UNIT - 0.15, d.hi * PLAN_UNIT + 0.15
            reach = t / 2 + cfg.door_clearance
            if d.axis == "z":  # wall at x = c; this room lies on one side of it
                a, b = (c, c + reach) if room.rect[0] >= c - 1e-9 else (c - reach, c)
                keepouts.append((a, lo, b, hi))
            else:
                a, b = (c, c + reach) if room.rect[1] >= c - 1e-9 else (c - reach, c)
                keepouts.append((lo, a, hi, b))
        furnishers.append(_Furnisher(rng, cfg, i, room, keepouts))

    lo_n, hi_n = cfg.objects_per_room
    for f in furnishers:
        x0, z0, x1, z1 = f.room.interior
        target = int(np.clip(round((x1 - x0) * (z1 - z0) / 2.8) + int(rng.integers(-1, 2)), lo_n, hi_n))
        recipe = RECIPES[f.room.type]
        anchors = [it for it in recipe if it.chance >= 1.0]
        extras = [it for it in recipe if it.chance < 1.0]
        for it in anchors:
            f.place(it, hi_n - len(f.items))
        for k in rng.permutation(len(extras)):
            if len(f.items) >= target:
                break
            if rng.random() < extras[k].chance:
                f.place(extras[k], min(target, hi_n) - len(f.items))
        # Small rooms: top up with wall decorations and plants, which fit almost anywhere.
        fillers = [Item(c.name) for c in CATEGORIES.values()
                   if f.room.type in c.rooms and (c.placement == "wall_mounted" or c.name == "plant")]
        for _ in range(12):
            if len(f.items) >= lo_n or not fillers:
                break
            f.place(fillers[int(rng.integers(len(fillers)))], hi_n - len(f.items))

    # Every house should hold some repeated category (several plants, a set of chairs, ...).
    counts: dict[str, int] = {}
    for f in furnishers:
        for p in f.items:
            counts[p.category] = counts.get(p.category, 0) + 1
    if counts and max(counts.values()) < 2:
        for name in ("plant", "picture"):
            hosts = [f for f in furnishers if len(f.items) < hi_n and f.room.type in CATEGORIES[name].rooms]
            placed = sum(f.place(Item(name), hi_n - len(f.items)) for f in hosts[: 2])
            if placed + counts.get(name, 0) >= 2:
                break
    return [p for f in furnishers for p in f.items]


def _colour_distance(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a, float) - np.asarray(b, float)))


def _assign_colours(rng: np.random.Generator, items: list[_Placed], floor_rgb: list, wall_rgb) -> None:
    """Give each instance a named colour: least used for its category, then overall, readable on its background."""
    names = list(COLOURS)
    per_cat: dict[tuple[str, str], int] = {}
    overall = dict.fromkeys(names, 0)
    for p in items:
        cat = CATEGORIES[p.category]
        background = [wall_rgb] if cat.placement == "wall_mounted" else [floor_rgb[p.room]]
        if p.support is not None:
            background = [COLOURS[p.support.colour]]
        ok = [n for n in names if all(_colour_distance(COLOURS[n], bg) > 60 for bg in background)] or names
        noise = rng.random(len(ok))
        best = min(range(len(ok)), key=lambda k: (per_cat.get((p.category, ok[k]), 0), overall[ok[k]], noise[k]))
        p.colour = ok[best]
        per_cat[(p.category, p.colour)] = per_cat.get((p.category, p.colour), 0) + 1
        overall[p.colour] += 1


# --------------------------------------------------------------------------------------------------
# public API


def generate_house(seed: int, config: HouseConfig = HouseConfig()) -> tuple[trimesh.Scene, dict]:
    """Build house ``seed``: a scene (nodes ``floor_<room>``, ``walls``, ``ceiling``, ``obj_<id>``) + semantics."""
    cfg = config
    rng = np.random.default_rng(seed)
    rects_u, hallway, doors = _plan(rng, cfg)
    types = _room_types(rng, rects_u, hallway)
    t, h = cfg.wall_thickness, cfg.wall_height

    rooms: list[_Room] = []
    seen: dict[str, int] = {}
    for (x0, z0, x1, z1), rtype in zip(rects_u, types):
        seen[rtype] = seen.get(rtype, 0) + 1
        name = rtype if seen[rtype] == 1 else f"{rtype}_{seen[rtype]}"
        rect = (x0 * PLAN_UNIT, z0 * PLAN_UNIT, x1 * PLAN_UNIT, z1 * PLAN_UNIT)
        interior = (rect[0] + t / 2, rect[1] + t / 2, rect[2] - t / 2, rect[3] - t / 2)
        rooms.append(_Room(name, rtype, rect, interior))

    wall_rgb = WALL_COLOURS[int(rng.integers(len(WALL_COLOURS)))]
    palette = rng.permutation(len(FLOOR_COLOURS))
    floor_rgb = [FLOOR_COLOURS[int(palette[i % len(palette)])] for i in range(len(rooms))]

    scene = trimesh.Scene()
    for room, rgb in zip(rooms, floor_rgb):
        x0, z0, x1, z1 = room.rect
        floor = _coloured_box((x0, -0.1, z0), (x1, 0.0, z1), rgb)
        scene.add_geometry(floor, node_name=f"floor_{room.name}", geom_name=f"floor_{room.name}")
    trim_rgb = tuple(int(0.82 * c) for c in wall_rgb)
    walls = trimesh.util.concatenate([_walls(rects_u, doors, cfg, wall_rgb), _trim(rects_u, doors, cfg, trim_rgb)])
    scene.add_geometry(walls, node_name="walls", geom_name="walls")
    ceiling = trimesh.util.concatenate(
        [_coloured_box((r.rect[0], h, r.rect[1]), (r.rect[2], h + 0.1, r.rect[3]), CEILING_COLOUR) for r in rooms])
    scene.add_geometry(ceiling, node_name="ceiling", geom_name="ceiling")

    items = _furnish(rng, cfg, rooms, doors) if cfg.furnish else []
    _assign_colours(rng, items, floor_rgb, wall_rgb)
    objects = []
    for obj_id, p in enumerate(items, start=1):
        mesh = p.world_mesh()
        scene.add_geometry(mesh, node_name=f"obj_{obj_id}", geom_name=f"obj_{obj_id}")
        lo, hi = mesh.bounds
        objects.append(ObjectAnnotation(
            id=obj_id, category=p.category, room=rooms[p.room].name, colour=p.colour,
            colour_rgb=COLOURS[p.colour], aabb_min=tuple(float(v) for v in lo), aabb_max=tuple(float(v) for v in hi),
        ).to_json())

    room_json = []
    for r in rooms:
        x0, z0, x1, z1 = r.interior
        ann = RoomAnnotation(r.name, (round(x0, 5), 0.0, round(z0, 5)), (round(x1, 5), h, round(z1, 5)))
        room_json.append({**ann.to_json(), "type": r.type})
    door_json = [
        {
            "rooms": [rooms[d.rooms[0]].name, rooms[d.rooms[1]].name],
            "center": [round(d.coord * PLAN_UNIT, 5), 0.0, round((d.lo + d.hi) / 2 * PLAN_UNIT, 5)] if d.axis == "z"
            else [round((d.lo + d.hi) / 2 * PLAN_UNIT, 5), 0.0, round(d.coord * PLAN_UNIT, 5)],
            "width": round((d.hi - d.lo) * PLAN_UNIT, 5),
            "height": cfg.door_height,
            "wall_axis": d.axis,
        }
        for d in doors
    ]
    semantic = {"scene_id": f"house_seed{seed}", "seed": int(seed), "rooms": room_json, "objects": objects,
                "doors": door_json}
    return scene, semantic


def write_house(scene: trimesh.Scene, semantic: dict, out_dir: str | Path, name: str) -> Path:
    """Write ``{out_dir}/{name}.glb`` and ``{name}.semantic.json`` (scene_id set to ``name``); returns the GLB path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    glb = out_dir / f"{name}.glb"
    glb.write_bytes(scene.export(file_type="glb"))
    sem = {"scene_id": name, **{k: v for k, v in semantic.items() if k != "scene_id"}}
    (out_dir / f"{name}.semantic.json").write_text(json.dumps(sem, indent=1) + "\n")
    return glb


def house_stats(scene: trimesh.Scene, semantic: dict) -> dict:
    """Rooms, objects and triangles of a generated house (for the dataset README)."""
    return {
        "rooms": len(semantic["rooms"]),
        "objects": len(semantic["objects"]),
        "categories": len({o["category"] for o in semantic["objects"]}),
        "triangles": int(sum(len(g.faces) for g in scene.geometry.values())),
    }


def generate_dataset(out_dir: str | Path, n_train: int = 8, n_val: int = 4, seed: int = 0) -> list[Path]:
    """Write houses ``house_000 ...`` into ``out_dir/train`` and ``out_dir/val`` plus ``out_dir/README.md``.

    House ``i`` uses seed ``seed * 1000 + i``, so the default call reproduces the bundled dataset and
    other seeds give disjoint houses (``POLICY_TRAIN_HOUSES`` below uses seed 1).
    """
    if n_train < 0 or n_val < 0 or n_train + n_val > 1000:
        raise ValueError(f"dataset sizes n_train={n_train}, n_val={n_val} must be >= 0 and total <= 1000")
    out_dir = Path(out_dir)
    paths, rows = [], []
    for i in range(n_train + n_val):
        split = "train" if i < n_train else "val"
        scene, semantic = generate_house(seed * 1000 + i)
        name = f"house_{i:03d}"
        path = write_house(scene, semantic, out_dir / split, name)
        paths.append(path)
        rows.append((split, name, house_stats(scene, semantic), path.stat().st_size))
    (out_dir / "README.md").write_text(_readme(rows, seed, out_dir.name, n_train, n_val))
    return paths


# The PointNav policy's extra training houses (envs/houses_policy_train): disjoint from the bundled
# houses (seed 1, not 0), never used by any evaluation split: the eight bundled train houses are too
# few for an imitation-learned policy to generalise to unseen houses.
POLICY_TRAIN_HOUSES = {"dir": "houses_policy_train", "n_train": 40, "seed": 1}
# Houses for choosing among trained PointNav policies (checkpoints, seeds, decoding) without looking at
# the reported val split: disjoint from the bundled houses and the training houses (seed 2), in `val/`
# because no policy trains on them.
POLICY_SELECT_HOUSES = {"dir": "houses_policy_select", "n_val": 8, "seed": 2}


def _readme(rows: list, seed: int, name: str = "houses", n_train: int = 8, n_val: int = 4) -> str:
    t, v = POLICY_TRAIN_HOUSES, POLICY_SELECT_HOUSES
    known = {  # the bundled datasets: their title and the command that writes them
        ("houses", 8, 4, 0): ("Procedural houses (bundled default scenes)", "scenes"),
        (t["dir"], t["n_train"], 0, t["seed"]): (
            "Procedural houses for training the PointNav policy only (never evaluated on)", "policy-train"),
        (v["dir"], 0, v["n_val"], v["seed"]): (
            "Procedural houses for choosing among PointNav policies (never trained on, not reported)", "policy-select"),
    }
    title, cmd = known.get((name, n_train, n_val, seed), ("Procedural houses", None))
    command = f"`navbench generate {cmd}`, i.e. " if cmd else ""
    lines = [
        f"# {title}",
        "",
        "Multi-room houses generated by `navbench.scene.procedural` from trimesh primitives - no external",
        f"assets. Regenerate (byte-identical) with {command}",
        f"`navbench.scene.procedural.generate_dataset(Path(\"envs/{name}\"), n_train={n_train}, n_val={n_val}, "
        f"seed={seed})`;",
        f"house `i` uses seed `{seed} * 1000 + i`. This file is written by the same call.",
        "",
        "Each house is `{split}/house_NNN.glb` plus `house_NNN.semantic.json`:",
        "",
        "- Habitat conventions: metres, y up, floor top at y = 0, walls 0.1 m thick and 2.6 m high, ceiling",
        "  slab from 2.6 m, doorways 0.9-1.2 m wide and 2.1 m high (no door leaves).",
        "- 3-8 rectangular rooms (kitchen, living_room, bedroom, bathroom, dining_room, office, hallway,",
        "  laundry) on a plan within 20 x 20 m. Doorways on a spanning tree of adjacent rooms (plus a few",
        "  extra) connect every room; furniture keeps a 0.7 m corridor clear in front of each doorway and",
        "  never splits a room's free floor for an agent of radius 0.18 m.",
        "- GLB nodes: `floor_<room>` (one colour per room), `walls` (closed wall boxes, lintels, door frames",
        "  proud of the wall faces by 2 cm, skirting boards 8 cm high), `ceiling` - all structure, instance",
        "  id -1 - and `obj_<id>`, one node per object. RGBA vertex colours, no textures.",
        "- JSON: `scene_id`, `seed`, `rooms` (`name`, `type`, interior `aabb`), `objects` (`id`, `category`,",
        "  `room`, `colour` name, `colour_rgb`, world `aabb`) and `doors` (`rooms`, `center`, `width`, `height`,",
        "  `wall_axis`); load with `navbench.scene.asset.load_scene`.",
        f"- {len(CATEGORIES)} object categories (`navbench.scene.categories.CATEGORIES`): "
        + ", ".join(sorted(CATEGORIES)) + ".",
        f"- {len(COLOURS)} named object colours: " + ", ".join(COLOURS) + ".",
        "",
        "| split | scene | rooms | objects | categories | triangles | GLB KiB |",
        "|---|---|---|---|---|---|---|",
    ]
    for split, name, s, size in rows:
        lines.append(f"| {split} | {name} | {s['rooms']} | {s['objects']} | {s['categories']} | {s['triangles']} "
                     f"| {size // 1024} |")
    return "\n".join(lines) + "\n"
