"""Furnishing the procedural houses: room recipes, placement rules and instance colours.

Each room type has a recipe of categories (anchors first, then random extras, some with companions:
chairs around a table, a chair at a desk, nightstands beside a bed, a TV on its stand). A candidate
pose is accepted only if its AABB stays inside the room, clears every other object by a margin,
stays out of the keep-out zone in front of each doorway, and the room's free floor - eroded by the
agent radius - stays one connected region. Objects get named colours, distinct per category where
possible. The objects themselves come from :mod:`navbench.scene.procedural.furniture`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import trimesh
from scipy import ndimage

from navbench.scene.pose import vector_length
from navbench.scene.procedural.config import PLAN_UNIT, HouseConfig
from navbench.scene.procedural.furniture import CATEGORIES, COLOURS, WALL_MOUNT_HEIGHT, Category, paint
from navbench.scene.procedural.plan import Door, Room


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
    support: _Placed | None = None
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

    def __init__(self, rng: np.random.Generator, cfg: HouseConfig, index: int, room: Room,
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


def furnish(rng: np.random.Generator, cfg: HouseConfig, rooms: list[Room], doors: list[Door]) -> list[_Placed]:
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
    return vector_length(np.asarray(a, float) - np.asarray(b, float))


def assign_colours(rng: np.random.Generator, items: list[_Placed], floor_rgb: list, wall_rgb) -> None:
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
