"""Object category library for the procedural houses: low-poly furniture built from trimesh primitives.

Every category is a frozen :class:`Category` entry in the :data:`CATEGORIES` dict: a size range, the room
types it may appear in, how it is placed, and a builder. A builder is a plain function
``(rng, size) -> trimesh.Trimesh`` that returns the object in object-local coordinates:

* metres, y up, base at y = 0, centred on x/z, ``size = (width x, height y, depth z)``;
* the object's *front* faces +z, so a "wall" object stands with its back (-z) against a wall;
* vertex colours are grey levels giving each part's shade (255 = the instance colour itself, lower =
  a darker part such as legs or a screen), which :func:`paint` multiplies by the instance colour.
  Shades stay >= ~0.55 so the annotated colour name still describes the whole object.

Shapes are deliberately coarse but recognisable to a depth camera (a chair has legs, a seat and a
back; a bed a headboard; a bathtub is hollow), with cylinders of <= 12 sections to keep houses at a
few thousand triangles.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
import trimesh

Placement = Literal["wall", "floor", "wall_mounted", "on_surface"]
Builder = Callable[[np.random.Generator, np.ndarray], trimesh.Trimesh]

ROOM_TYPES: tuple[str, ...] = (
    "kitchen",
    "living_room",
    "bedroom",
    "bathroom",
    "dining_room",
    "office",
    "hallway",
    "laundry",
)

# Named instance colours: an object's annotated colour is one of these names.
COLOURS: dict[str, tuple[int, int, int]] = {
    "red": (200, 40, 40),
    "blue": (40, 70, 200),
    "green": (50, 150, 60),
    "yellow": (230, 200, 40),
    "white": (240, 240, 236),
    "black": (35, 35, 38),
    "grey": (128, 128, 128),
    "brown": (120, 75, 40),
    "orange": (235, 130, 30),
    "purple": (120, 50, 160),
    "pink": (235, 130, 170),
    "beige": (215, 195, 150),
    "teal": (30, 140, 140),
    "navy": (25, 35, 100),
}

# Wall-mounted objects hang with their vertical centre in this band (metres above the floor).
WALL_MOUNT_HEIGHT: tuple[float, float] = (1.0, 1.8)


@dataclass(frozen=True)
class Category:
    name: str
    size_min: tuple[float, float, float]  # (width x, height y, depth z) in metres
    size_max: tuple[float, float, float]
    rooms: tuple[str, ...]
    placement: Placement
    builder: Builder
    supports: tuple[str, ...] = ()  # for "on_surface": categories whose top it may stand on

    def sample_size(self, rng: np.random.Generator) -> np.ndarray:
        return rng.uniform(self.size_min, self.size_max)

    def build(self, rng: np.random.Generator, size: np.ndarray | None = None) -> trimesh.Trimesh:
        """Build one instance (sampling a size if none is given), recentred to base y=0, centred x/z."""
        mesh = self.builder(rng, self.sample_size(rng) if size is None else np.asarray(size, float))
        lo, hi = mesh.bounds
        mesh.apply_translation([-(lo[0] + hi[0]) / 2.0, -lo[1], -(lo[2] + hi[2]) / 2.0])
        return mesh


def paint(mesh: trimesh.Trimesh, rgb: tuple[int, int, int]) -> trimesh.Trimesh:
    """A copy of a builder's mesh with its grey shades multiplied by ``rgb`` (RGBA uint8 vertex colours)."""
    shade = np.asarray(mesh.visual.vertex_colors, np.float64)[:, :1] / 255.0
    colours = np.empty((len(mesh.vertices), 4), np.uint8)
    colours[:, :3] = np.clip(np.rint(shade * np.asarray(rgb, np.float64)), 0, 255).astype(np.uint8)
    colours[:, 3] = 255
    return trimesh.Trimesh(mesh.vertices.copy(), mesh.faces.copy(), vertex_colors=colours, process=False)


# --------------------------------------------------------------------------------------------------
# primitive helpers (all return a mesh whose vertex colours carry one grey shade)


def _shaded(mesh: trimesh.Trimesh, shade: float) -> trimesh.Trimesh:
    grey = int(round(255 * shade))
    colours = np.tile(np.array([grey, grey, grey, 255], np.uint8), (len(mesh.vertices), 1))
    return trimesh.Trimesh(mesh.vertices, mesh.faces, vertex_colors=colours, process=False)


def _box(x0: float, y0: float, z0: float, x1: float, y1: float, z1: float, shade: float = 1.0) -> trimesh.Trimesh:
    """Axis-aligned box from its min and max corner."""
    transform = trimesh.transformations.translation_matrix([(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2])
    return _shaded(trimesh.creation.box(extents=(x1 - x0, y1 - y0, z1 - z0), transform=transform), shade)


def _cyl(r: float, y0: float, y1: float, x: float = 0.0, z: float = 0.0, sections: int = 10, shade: float = 1.0):
    """Vertical cylinder."""
    return _shaded(trimesh.creation.cylinder(radius=r, segment=[[x, y0, z], [x, y1, z]], sections=sections), shade)


def _disc_z(r: float, z0: float, z1: float, x: float, y: float, sections: int = 12, shade: float = 1.0):
    """Cylinder along z (a round face looking at +z: clock faces, washer doors)."""
    return _shaded(trimesh.creation.cylinder(radius=r, segment=[[x, y, z0], [x, y, z1]], sections=sections), shade)


# revolve() spins a (radius, height) profile around z; this maps that z onto our y.
_Z_TO_Y = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, -1.0, 0, 0], [0, 0, 0, 1.0]])


def _frustum(r0: float, r1: float, y0: float, y1: float, x: float = 0.0, z: float = 0.0, sections: int = 10,
             shade: float = 1.0) -> trimesh.Trimesh:
    """Truncated cone (radius r0 at y0, r1 at y1): pots, lamp shades, bins."""
    mesh = trimesh.creation.revolve(np.array([[0, 0], [r0, 0], [r1, y1 - y0], [0, y1 - y0]]), sections=sections)
    mesh.apply_transform(_Z_TO_Y)
    mesh.apply_translation([x, y0, z])
    return _shaded(mesh, shade)


def _ellipsoid(cx: float, cy: float, cz: float, rx: float, ry: float, rz: float, shade: float = 1.0):
    mesh = trimesh.creation.icosphere(subdivisions=2)
    mesh.vertices = mesh.vertices * np.array([rx, ry, rz]) + np.array([cx, cy, cz])
    return _shaded(mesh, shade)


def _join(*parts: trimesh.Trimesh) -> trimesh.Trimesh:
    return trimesh.util.concatenate(list(parts))


def _legs(x0: float, z0: float, x1: float, z1: float, y1: float, t: float, shade: float = 0.7) -> list:
    """Four square legs of thickness t inside the rectangle [x0,x1] x [z0,z1], from the floor to y1."""
    return [_box(x, 0, z, x + t, y1, z + t, shade) for x in (x0, x1 - t) for z in (z0, z1 - t)]


# --------------------------------------------------------------------------------------------------
# builders: (rng, size=(w, h, d)) -> mesh, front towards +z


def _chair(rng, size):
    w, h, d = size
    seat = min(0.47, 0.55 * h)
    parts = _legs(-w / 2, -d / 2, w / 2, d / 2, seat - 0.04, 0.04)
    parts.append(_box(-w / 2, seat - 0.04, -d / 2, w / 2, seat, d / 2))
    parts.append(_box(-w / 2, seat, -d / 2, w / 2, h, -d / 2 + 0.05, 0.85))  # backrest
    return _join(*parts)


def _armchair(rng, size):
    w, h, d = size
    arm, back = 0.13, 0.18
    parts = _legs(-w / 2 + 0.03, -d / 2 + 0.03, w / 2 - 0.03, d / 2 - 0.03, 0.1, 0.05, 0.6)
    parts.append(_box(-w / 2, 0.1, -d / 2, w / 2, 0.38, d / 2, 0.85))  # base
    parts.append(_box(-w / 2 + arm, 0.38, -d / 2 + back, w / 2 - arm, 0.46, d / 2))  # cushion
    parts.append(_box(-w / 2, 0.1, -d / 2, w / 2, h, -d / 2 + back, 0.9))  # back
    parts += [_box(x, 0.1, -d / 2, x + arm, 0.62, d / 2, 0.8) for x in (-w / 2, w / 2 - arm)]
    return _join(*parts)


def _sofa(rng, size):
    w, h, d = size
    arm, back = 0.18, 0.22
    n = 3 if w > 1.9 else 2
    inner = w - 2 * arm
    parts = [_box(-w / 2, 0.06, -d / 2, w / 2, 0.36, d / 2, 0.85)]
    parts += _legs(-w / 2 + 0.05, -d / 2 + 0.05, w / 2 - 0.05, d / 2 - 0.05, 0.06, 0.05, 0.55)
    parts.append(_box(-w / 2, 0.06, -d / 2, w / 2, h - 0.12, -d / 2 + back, 0.85))  # back frame
    parts += [_box(x, 0.06, -d / 2, x + arm, 0.6, d / 2, 0.8) for x in (-w / 2, w / 2 - arm)]
    for i in range(n):  # seat and back cushions
        x0 = -w / 2 + arm + i * inner / n + 0.01
        x1 = x0 + inner / n - 0.02
        parts.append(_box(x0, 0.36, -d / 2 + back, x1, 0.46, d / 2 - 0.02))
        parts.append(_box(x0, 0.46, -d / 2 + back, x1, h, -d / 2 + back + 0.14, 0.95))
    return _join(*parts)


def _table(rng, size):
    w, h, d = size
    parts = _legs(-w / 2 + 0.05, -d / 2 + 0.05, w / 2 - 0.05, d / 2 - 0.05, h - 0.04, 0.06)
    parts.append(_box(-w / 2, h - 0.04, -d / 2, w / 2, h, d / 2))
    return _join(*parts)


def _coffee_table(rng, size):
    w, h, d = size
    parts = _legs(-w / 2 + 0.03, -d / 2 + 0.03, w / 2 - 0.03, d / 2 - 0.03, h - 0.04, 0.05, 0.75)
    parts.append(_box(-w / 2, h - 0.04, -d / 2, w / 2, h, d / 2))
    parts.append(_box(-w / 2 + 0.08, 0.1, -d / 2 + 0.08, w / 2 - 0.08, 0.13, d / 2 - 0.08, 0.85))  # shelf
    return _join(*parts)


def _desk(rng, size):
    w, h, d = size
    ped = min(0.42, 0.35 * w)
    side = 1.0 if rng.random() < 0.5 else -1.0  # which side holds the drawers
    px0, px1 = sorted((side * (w / 2 - ped), side * w / 2))
    ox0, ox1 = sorted((-side * w / 2, -side * (w / 2 - 0.04)))
    parts = [
        _box(-w / 2, h - 0.035, -d / 2, w / 2, h, d / 2),  # top
        _box(px0, 0, -d / 2 + 0.02, px1, h - 0.035, d / 2 - 0.02, 0.8),  # drawer pedestal
        _box(ox0, 0, -d / 2 + 0.02, ox1, h - 0.035, d / 2 - 0.02, 0.8),  # side panel
        _box(-w / 2 + 0.04, 0.3, -d / 2 + 0.02, w / 2 - 0.04, h - 0.035, -d / 2 + 0.04, 0.75),  # modesty panel
    ]
    for i in range(3):
        y0 = 0.05 + i * (h - 0.1) / 3
        parts.append(_box(px0 + 0.02, y0, d / 2 - 0.02, px1 - 0.02, y0 + (h - 0.1) / 3 - 0.03, d / 2, 0.9))
    return _join(*parts)


def _bed(rng, size):
    w, h, d = size
    parts = [
        _box(-w / 2 + 0.04, 0, -d / 2 + 0.04, w / 2 - 0.04, 0.1, d / 2 - 0.04, 0.6),  # plinth
        _box(-w / 2, 0.1, -d / 2, w / 2, 0.32, d / 2, 0.8),  # frame
        _box(-w / 2 + 0.03, 0.32, -d / 2 + 0.06, w / 2 - 0.03, 0.52, d / 2 - 0.03),  # mattress
        _box(-w / 2, 0, -d / 2, w / 2, h, -d / 2 + 0.07, 0.75),  # headboard
        _box(-w / 2 + 0.01, 0.5, -d / 2 + 0.6, w / 2 - 0.01, 0.56, d / 2 - 0.01, 0.9),  # duvet
    ]
    n = 2 if w > 1.2 else 1
    pw = (w - 0.2) / n
    for i in range(n):  # pillows
        x0 = -w / 2 + 0.1 + i * pw
        parts.append(_box(x0 + 0.03, 0.52, -d / 2 + 0.12, x0 + pw - 0.03, 0.64, -d / 2 + 0.5, 0.95))
    return _join(*parts)


def _drawer_unit(w, h, d, rows, cols, plinth=0.06):
    """Box carcass on a plinth with a grid of slightly proud drawer fronts."""
    parts = [
        _box(-w / 2 + 0.03, 0, -d / 2, w / 2 - 0.03, plinth, d / 2 - 0.04, 0.6),
        _box(-w / 2, plinth, -d / 2, w / 2, h - 0.03, d / 2 - 0.015, 0.85),
        _box(-w / 2 - 0.01, h - 0.03, -d / 2, w / 2 + 0.01, h, d / 2 + 0.01),  # top overhangs slightly
    ]
    fh, fw = (h - plinth - 0.03) / rows, w / cols
    for r in range(rows):
        for c in range(cols):
            x0, y0 = -w / 2 + c * fw, plinth + r * fh
            parts.append(_box(x0 + 0.015, y0 + 0.015, d / 2 - 0.015, x0 + fw - 0.015, y0 + fh - 0.015, d / 2))
    return parts


def _nightstand(rng, size):
    w, h, d = size
    return _join(*_drawer_unit(w, h, d, rows=2, cols=1))


def _dresser(rng, size):
    w, h, d = size
    return _join(*_drawer_unit(w, h, d, rows=3, cols=2 if w > 1.0 else 1))


def _cabinet(rng, size):
    w, h, d = size
    cols = 2 if w > 0.7 else 1
    parts = _drawer_unit(w, h, d, rows=1, cols=cols, plinth=0.08)
    for c in range(cols):  # vertical handles
        x = -w / 2 + (c + 0.5) * w / cols + (0.35 if c == 0 else -0.35) * w / cols
        parts.append(_box(x - 0.01, h * 0.45, d / 2, x + 0.01, h * 0.65, d / 2 + 0.02, 0.6))
    return _join(*parts)


def _wardrobe(rng, size):
    w, h, d = size
    parts = [
        _box(-w / 2 + 0.03, 0, -d / 2, w / 2 - 0.03, 0.08, d / 2 - 0.04, 0.6),
        _box(-w / 2, 0.08, -d / 2, w / 2, h, d / 2 - 0.02, 0.85),
        _box(-w / 2 - 0.01, h - 0.04, -d / 2, w / 2 + 0.01, h, d / 2 + 0.01, 0.8),  # cornice
    ]
    for x0, x1 in ((-w / 2, 0.0), (0.0, w / 2)):  # two doors with handles near the middle
        parts.append(_box(x0 + 0.01, 0.1, d / 2 - 0.02, x1 - 0.01, h - 0.06, d / 2))
        hx = -0.05 if x1 == 0.0 else 0.05
        parts.append(_box(hx - 0.01, h * 0.45, d / 2, hx + 0.01, h * 0.6, d / 2 + 0.025, 0.6))
    return _join(*parts)


def _bookshelf(rng, size):
    w, h, d = size
    t = 0.025
    n_shelves = max(3, int(h / 0.38))
    parts = [
        _box(-w / 2, 0, -d / 2, -w / 2 + t, h, d / 2, 0.85),
        _box(w / 2 - t, 0, -d / 2, w / 2, h, d / 2, 0.85),
        _box(-w / 2, 0, -d / 2, w / 2, h, -d / 2 + 0.015, 0.75),  # back panel
    ]
    gap = (h - t) / n_shelves
    for i in range(n_shelves + 1):
        y = i * gap
        parts.append(_box(-w / 2 + t, y, -d / 2, w / 2 - t, y + t, d / 2))
        if i == n_shelves:
            break
        x = -w / 2 + t + 0.02
        while x < w / 2 - t - 0.15:  # rows of books of random width/height, shaded individually
            bw = float(rng.uniform(0.12, 0.3))
            bw = min(bw, w / 2 - t - 0.02 - x)
            bh = float(rng.uniform(0.55, 0.85)) * (gap - t)
            parts.append(_box(x, y + t, -d / 2 + 0.03, x + bw, y + t + bh, d / 2 - 0.03, float(rng.uniform(0.6, 0.95))))
            x += bw + float(rng.uniform(0.03, 0.15))
    return _join(*parts)


def _tv_stand(rng, size):
    w, h, d = size
    parts = [_box(-w / 2, 0.08, -d / 2, w / 2, h, d / 2 - 0.01, 0.85)]
    parts += _legs(-w / 2 + 0.04, -d / 2 + 0.04, w / 2 - 0.04, d / 2 - 0.04, 0.08, 0.04, 0.6)
    for i in range(3):
        x0 = -w / 2 + i * w / 3
        parts.append(_box(x0 + 0.015, 0.1, d / 2 - 0.01, x0 + w / 3 - 0.015, h - 0.02, d / 2))
    return _join(*parts)


def _tv_monitor(rng, size):
    w, h, d = size
    bw = min(0.45 * w, 0.45)
    parts = [
        _box(-bw / 2, 0, -d / 2, bw / 2, 0.02, d / 2, 0.7),  # foot
        _box(-0.04, 0.02, -0.02, 0.04, 0.14, 0.02, 0.7),  # neck
        _box(-w / 2, 0.1, -0.03, w / 2, h, 0.03, 0.85),  # panel
        _box(-w / 2 + 0.02, 0.12, 0.03, w / 2 - 0.02, h - 0.02, 0.04, 0.6),  # screen
    ]
    return _join(*parts)


def _refrigerator(rng, size):
    w, h, d = size
    split = 0.62 * h
    parts = [_box(-w / 2, 0, -d / 2, w / 2, h, d / 2 - 0.04, 0.85)]
    parts.append(_box(-w / 2, 0.05, d / 2 - 0.04, w / 2, split - 0.01, d / 2))  # fridge door
    parts.append(_box(-w / 2, split + 0.01, d / 2 - 0.04, w / 2, h - 0.01, d / 2))  # freezer door
    for y0, y1 in ((split - 0.45, split - 0.1), (split + 0.08, split + 0.3)):
        parts.append(_box(w / 2 - 0.08, y0, d / 2, w / 2 - 0.05, y1, d / 2 + 0.04, 0.6))
    return _join(*parts)


def _oven(rng, size):
    w, h, d = size
    parts = [
        _box(-w / 2, 0, -d / 2, w / 2, h - 0.02, d / 2 - 0.02, 0.85),
        _box(-w / 2 + 0.04, 0.1, d / 2 - 0.02, w / 2 - 0.04, h - 0.2, d / 2, 0.65),  # oven window
        _box(-w / 2 + 0.06, h - 0.26, d / 2, w / 2 - 0.06, h - 0.23, d / 2 + 0.03, 0.6),  # door handle
        _box(-w / 2, h - 0.02, -d / 2, w / 2, h, d / 2),  # hob
        _box(-w / 2, h, -d / 2, w / 2, h + 0.12, -d / 2 + 0.05, 0.8),  # back splash / controls
    ]
    for x in (-w / 4, w / 4):
        for z in (-d / 5, d / 5):
            parts.append(_cyl(0.08, h, h + 0.012, x, z, sections=8, shade=0.55))
    return _join(*parts)


def _microwave(rng, size):
    w, h, d = size
    return _join(
        _box(-w / 2, 0, -d / 2, w / 2, h, d / 2 - 0.01, 0.85),
        _box(-w / 2 + 0.03, 0.03, d / 2 - 0.01, w / 2 - 0.15, h - 0.03, d / 2, 0.6),  # door window
        _box(w / 2 - 0.12, 0.04, d / 2 - 0.01, w / 2 - 0.03, h - 0.04, d / 2),  # control panel
    )


def _counter(rng, size):
    w, h, d = size
    n = max(1, int(round(w / 0.6)))
    parts = [
        _box(-w / 2 + 0.02, 0, -d / 2, w / 2 - 0.02, 0.1, d / 2 - 0.08, 0.6),  # plinth
        _box(-w / 2, 0.1, -d / 2, w / 2, h - 0.04, d / 2 - 0.04, 0.85),  # carcass
        _box(-w / 2, h - 0.04, -d / 2, w / 2, h, d / 2),  # worktop
    ]
    for i in range(n):
        x0 = -w / 2 + i * w / n
        parts.append(_box(x0 + 0.01, 0.12, d / 2 - 0.04, x0 + w / n - 0.01, h - 0.2, d / 2 - 0.02, 0.95))
        parts.append(_box(x0 + 0.01, h - 0.18, d / 2 - 0.04, x0 + w / n - 0.01, h - 0.06, d / 2 - 0.02, 0.95))
    return _join(*parts)


def _sink(rng, size):
    w, h, d = size
    t, top = 0.04, h - 0.14
    parts = [
        _box(-w / 2 + 0.02, 0, -d / 2, w / 2 - 0.02, top, d / 2 - 0.02, 0.8),  # vanity cabinet
        _box(-w / 2, top, -d / 2, w / 2, top + 0.03, d / 2),  # basin floor
        _box(-w / 2, top, -d / 2, w / 2, h, -d / 2 + 0.1),  # back rim (holds the tap)
        _box(-w / 2, top, d / 2 - t, w / 2, h, d / 2),  # front rim
        _box(-w / 2, top, -d / 2, -w / 2 + t, h, d / 2),
        _box(w / 2 - t, top, -d / 2, w / 2, h, d / 2),
        _cyl(0.02, h, h + 0.22, 0, -d / 2 + 0.05, sections=6, shade=0.6),  # tap
        _box(-0.015, h + 0.18, -d / 2 + 0.05, 0.015, h + 0.22, -d / 2 + 0.2, 0.6),  # spout
    ]
    return _join(*parts)


def _toilet(rng, size):
    w, h, d = size
    tank_d = 0.18
    bowl_r = w / 2
    bz = -d / 2 + tank_d + (d - tank_d) / 2  # bowl centre
    bowl = _cyl(bowl_r, 0.3, 0.4, 0, 0, sections=12, shade=0.95)
    bowl.vertices[:, 2] = bowl.vertices[:, 2] * ((d - tank_d) / 2) / bowl_r + bz  # ellipse in z
    seat = _cyl(bowl_r, 0.4, 0.43, 0, 0, sections=12)
    seat.vertices[:, 2] = seat.vertices[:, 2] * ((d - tank_d) / 2) / bowl_r + bz
    parts = [
        _frustum(0.13, 0.17, 0.0, 0.3, 0, bz, sections=10, shade=0.9),  # pedestal
        bowl,
        seat,
        _box(-w / 2, 0.38, -d / 2, w / 2, h, -d / 2 + tank_d, 0.9),  # cistern
        _box(-w / 2 - 0.01, h - 0.03, -d / 2, w / 2 + 0.01, h, -d / 2 + tank_d + 0.01),  # cistern lid
    ]
    return _join(*parts)


def _bathtub(rng, size):
    w, h, d = size
    t = 0.07
    # The inner floor sits at 0.2 m so the tub reads as an obstacle in a top-down height map.
    parts = [
        _box(-w / 2, 0, -d / 2, w / 2, 0.2, d / 2, 0.85),
        _box(-w / 2, 0.2, -d / 2, w / 2, h, -d / 2 + t),
        _box(-w / 2, 0.2, d / 2 - t, w / 2, h, d / 2),
        _box(-w / 2, 0.2, -d / 2 + t, -w / 2 + t, h, d / 2 - t),
        _box(w / 2 - t, 0.2, -d / 2 + t, w / 2, h, d / 2 - t),
        _cyl(0.02, h, h + 0.15, -w / 2 + 0.12, -d / 2 + 0.04, sections=6, shade=0.6),  # tap
    ]
    return _join(*parts)


def _shower(rng, size):
    w, h, d = size
    parts = [
        _box(-w / 2, 0, -d / 2, w / 2, 0.14, d / 2, 0.9),  # tray
        _box(w / 2 - 0.02, 0.14, -d / 2, w / 2, h, d / 2, 0.8),  # side screen
        _box(-w / 2, 0.14, d / 2 - 0.02, 0.1 * w, h, d / 2, 0.8),  # front screen (half open)
        _box(-w / 2, 0.14, -d / 2, -w / 2 + 0.02, h, d / 2, 0.8),  # other side
        _cyl(0.015, 0.9, h - 0.1, 0, -d / 2 + 0.04, sections=6, shade=0.6),  # riser
        _cyl(0.08, h - 0.14, h - 0.1, 0, -d / 2 + 0.14, sections=8, shade=0.6),  # head
    ]
    return _join(*parts)


def _washer(rng, size, door_y: float = 0.42):
    w, h, d = size
    return _join(
        _box(-w / 2, 0, -d / 2, w / 2, h, d / 2 - 0.03, 0.9),
        _disc_z(min(w, h) * 0.3, d / 2 - 0.03, d / 2, 0, door_y, sections=12, shade=0.65),
        _disc_z(min(w, h) * 0.22, d / 2, d / 2 + 0.01, 0, door_y, sections=12, shade=0.8),
        _box(-w / 2, h - 0.12, d / 2 - 0.03, w / 2, h, d / 2, 0.8),  # control panel
        _cyl(0.025, h - 0.09, h - 0.03, w / 4, d / 2 - 0.03, sections=6, shade=0.6),  # knob
    )


def _dryer(rng, size):
    w, h, d = size
    mesh = _washer(rng, size, door_y=0.5)
    vent = _box(-w / 2 + 0.05, h, -d / 2 + 0.05, w / 2 - 0.05, h + 0.02, -d / 2 + 0.15, 0.7)
    return _join(mesh, vent)


def _plant(rng, size):
    w, h, d = size
    r = 0.28 * min(w, d)
    pot_h = min(0.38, 0.3 * h)
    parts = [_frustum(0.75 * r, r, 0, pot_h, sections=12, shade=0.7), _cyl(0.02, pot_h, pot_h + 0.12, sections=6)]
    style = int(rng.integers(3))
    fh = h - pot_h - 0.05
    if style == 0:  # bushy ball
        parts.append(_ellipsoid(0, pot_h + 0.05 + fh / 2, 0, w / 2, fh / 2, d / 2))
    elif style == 1:  # conifer
        parts.append(_frustum(w / 2, 0.02, pot_h + 0.05, h, sections=12))
    else:  # two stacked clumps
        parts.append(_ellipsoid(0, pot_h + 0.05 + fh * 0.3, 0, w / 2, fh * 0.3, d / 2, 0.9))
        parts.append(_ellipsoid(0.05 * w, pot_h + 0.05 + fh * 0.75, 0, w * 0.35, fh * 0.25, d * 0.35))
    return _join(*parts)


def _lamp(rng, size):
    w, h, d = size
    sh = min(0.35, 0.2 * h)
    return _join(
        _cyl(0.13, 0, 0.03, sections=10, shade=0.7),
        _cyl(0.015, 0.03, h - sh + 0.05, sections=6, shade=0.7),
        _frustum(w / 2, 0.6 * w / 2, h - sh, h, sections=10),
    )


def _table_lamp(rng, size):
    w, h, d = size
    sh = 0.4 * h
    return _join(
        _frustum(0.6 * w / 2, 0.3 * w / 2, 0, 0.45 * (h - sh), sections=10, shade=0.75),
        _cyl(0.015, 0.45 * (h - sh), h - sh + 0.03, sections=6, shade=0.7),
        _frustum(w / 2, 0.6 * w / 2, h - sh, h, sections=10),
    )


def _rug(rng, size):
    w, h, d = size
    return _join(
        _box(-w / 2, 0, -d / 2, w / 2, h - 0.004, d / 2, 0.8),
        _box(-w / 2 + 0.1, h - 0.004, -d / 2 + 0.1, w / 2 - 0.1, h, d / 2 - 0.1),
    )


def _picture(rng, size):
    w, h, d = size
    return _join(
        _box(-w / 2, 0, -d / 2, w / 2, h, d / 2 - 0.01, 0.65),  # frame
        _box(-w / 2 + 0.05, 0.05, d / 2 - 0.01, w / 2 - 0.05, h - 0.05, d / 2),  # canvas
    )


def _mirror(rng, size):
    w, h, d = size
    return _join(
        _box(-w / 2, 0, -d / 2, w / 2, h, d / 2 - 0.01, 0.7),
        _box(-w / 2 + 0.04, 0.04, d / 2 - 0.01, w / 2 - 0.04, h - 0.04, d / 2),
    )


def _clock(rng, size):
    w, h, d = size
    r = min(w, h) / 2
    return _join(
        _disc_z(r, -d / 2, d / 2 - 0.01, 0, r, sections=12, shade=0.8),
        _disc_z(0.85 * r, d / 2 - 0.01, d / 2, 0, r, sections=12),
        _box(-0.01, r, d / 2, 0.01, r + 0.7 * r, d / 2 + 0.005, 0.55),  # hands
        _box(-0.01, r - 0.01, d / 2, 0.5 * r, r + 0.01, d / 2 + 0.005, 0.55),
    )


def _towel(rng, size):
    w, h, d = size
    return _join(
        _box(-w / 2 - 0.05, h - 0.04, -d / 2, w / 2 + 0.05, h, -d / 2 + 0.04, 0.6),  # rail
        _box(-w / 2, 0.25 * h, -d / 2 + 0.01, w / 2, h - 0.02, d / 2 - 0.02, 0.9),  # back fold
        _box(-w / 2, 0, d / 2 - 0.03, w / 2, h - 0.02, d / 2),  # front fold, longer
    )


def _trash_can(rng, size):
    w, h, d = size
    r = min(w, d) / 2
    return _join(
        _frustum(0.85 * r, r, 0, h - 0.04, sections=10, shade=0.9),
        _cyl(r + 0.01, h - 0.04, h, sections=10),
    )


def _laundry_basket(rng, size):
    w, h, d = size
    t = 0.025
    return _join(
        _box(-w / 2, 0, -d / 2, w / 2, h - 0.08, d / 2, 0.9),  # full of laundry
        _box(-w / 2, h - 0.08, -d / 2, w / 2, h, -d / 2 + t),
        _box(-w / 2, h - 0.08, d / 2 - t, w / 2, h, d / 2),
        _box(-w / 2, h - 0.08, -d / 2 + t, -w / 2 + t, h, d / 2 - t),
        _box(w / 2 - t, h - 0.08, -d / 2 + t, w / 2, h, d / 2 - t),
    )


def _shoe_rack(rng, size):
    w, h, d = size
    t = 0.02
    n = max(2, int(h / 0.22))
    parts = [_box(-w / 2, 0, -d / 2, -w / 2 + t, h, d / 2, 0.85), _box(w / 2 - t, 0, -d / 2, w / 2, h, d / 2, 0.85)]
    for i in range(n):
        y = 0.04 + i * (h - 0.04) / n
        parts.append(_box(-w / 2 + t, y, -d / 2, w / 2 - t, y + t, d / 2))
        x = -w / 2 + t + 0.03
        while x + 0.1 < w / 2 - t:  # shoes
            parts.append(_box(x, y + t, -d / 2 + 0.03, x + 0.09, y + t + 0.08, d / 2 - 0.02, 0.7))
            x += 0.09 + float(rng.uniform(0.03, 0.12))
    parts.append(_box(-w / 2, h - t, -d / 2, w / 2, h, d / 2))
    return _join(*parts)


def _coat_rack(rng, size):
    w, h, d = size
    parts = [
        _box(-w / 2, 0, -0.03, w / 2, 0.04, 0.03, 0.7),
        _box(-0.03, 0, -d / 2, 0.03, 0.04, d / 2, 0.7),
        _cyl(0.02, 0.04, h, sections=6, shade=0.8),
        _ellipsoid(0.0, h - 0.45, 0.12 * d, 0.2 * w, 0.35, 0.15 * d, 1.0),  # a coat hanging on it
    ]
    for sx, sz in ((1, 0), (-1, 0), (0, 1), (0, -1)):  # hooks
        parts.append(_box(min(0, sx * 0.15) - 0.01, h - 0.12, min(0, sz * 0.15) - 0.01,
                          max(0, sx * 0.15) + 0.01, h - 0.1, max(0, sz * 0.15) + 0.01, 0.7))
    return _join(*parts)


def _stool(rng, size):
    w, h, d = size
    r = min(w, d) / 2
    a = 0.62 * r
    parts = [_box(x - 0.02, 0, z - 0.02, x + 0.02, h - 0.04, z + 0.02, 0.7) for x in (-a, a) for z in (-a, a)]
    parts.append(_box(-a, 0.25 * h, -0.015, a, 0.25 * h + 0.03, 0.015, 0.7))  # foot rest
    parts.append(_cyl(r, h - 0.04, h, sections=10))
    return _join(*parts)


# --------------------------------------------------------------------------------------------------

_EVERYWHERE = ROOM_TYPES
_LIVING = ("living_room", "bedroom", "office", "dining_room")

CATEGORIES: dict[str, Category] = {
    c.name: c
    for c in (
        Category("chair", (0.42, 0.8, 0.44), (0.5, 1.0, 0.52),
                 ("kitchen", "dining_room", "office", "bedroom", "living_room"), "floor", _chair),
        Category("armchair", (0.7, 0.75, 0.7), (0.9, 0.95, 0.9), ("living_room", "bedroom", "office"), "floor",
                 _armchair),
        Category("sofa", (1.5, 0.8, 0.82), (2.2, 0.95, 0.95), ("living_room", "office"), "wall", _sofa),
        Category("table", (1.0, 0.72, 0.75), (1.6, 0.78, 0.95), ("kitchen", "dining_room"), "floor", _table),
        Category("coffee_table", (0.8, 0.38, 0.5), (1.2, 0.46, 0.7), ("living_room",), "floor", _coffee_table),
        Category("desk", (1.0, 0.72, 0.55), (1.5, 0.77, 0.7), ("office", "bedroom"), "wall", _desk),
        Category("bed", (1.0, 0.9, 1.95), (1.8, 1.2, 2.15), ("bedroom",), "wall", _bed),
        Category("nightstand", (0.4, 0.45, 0.35), (0.55, 0.6, 0.45), ("bedroom",), "wall", _nightstand),
        Category("dresser", (0.8, 0.75, 0.42), (1.4, 1.0, 0.52), ("bedroom", "hallway"), "wall", _dresser),
        Category("wardrobe", (0.9, 1.9, 0.55), (1.6, 2.2, 0.65), ("bedroom", "hallway"), "wall", _wardrobe),
        Category("cabinet", (0.6, 0.8, 0.35), (1.2, 1.2, 0.5),
                 ("kitchen", "dining_room", "bathroom", "office", "hallway", "laundry", "living_room"), "wall",
                 _cabinet),
        Category("bookshelf", (0.7, 1.5, 0.28), (1.2, 2.0, 0.38), ("living_room", "office", "bedroom"), "wall",
                 _bookshelf),
        Category("tv_stand", (1.1, 0.4, 0.38), (1.8, 0.55, 0.48), ("living_room", "bedroom"), "wall", _tv_stand),
        Category("tv_monitor", (0.7, 0.45, 0.2), (1.3, 0.85, 0.26), ("living_room", "bedroom", "office"),
                 "on_surface", _tv_monitor, supports=("tv_stand", "desk", "dresser", "cabinet")),
        Category("refrigerator", (0.6, 1.7, 0.6), (0.8, 1.95, 0.7), ("kitchen",), "wall", _refrigerator),
        Category("oven", (0.6, 0.85, 0.58), (0.75, 0.92, 0.65), ("kitchen",), "wall", _oven),
        Category("microwave", (0.45, 0.28, 0.32), (0.6, 0.35, 0.4), ("kitchen",), "on_surface", _microwave,
                 supports=("counter", "cabinet")),
        Category("counter", (1.2, 0.88, 0.58), (2.4, 0.92, 0.65), ("kitchen",), "wall", _counter),
        Category("sink", (0.5, 0.8, 0.4), (0.8, 0.9, 0.55), ("kitchen", "bathroom", "laundry"), "wall", _sink),
        Category("toilet", (0.38, 0.75, 0.62), (0.45, 0.85, 0.72), ("bathroom",), "wall", _toilet),
        Category("bathtub", (1.5, 0.5, 0.7), (1.8, 0.6, 0.8), ("bathroom",), "wall", _bathtub),
        Category("shower", (0.8, 1.9, 0.8), (1.0, 2.1, 1.0), ("bathroom",), "wall", _shower),
        Category("washer", (0.58, 0.82, 0.55), (0.62, 0.88, 0.62), ("laundry", "bathroom"), "wall", _washer),
        Category("dryer", (0.58, 0.82, 0.55), (0.62, 0.88, 0.62), ("laundry",), "wall", _dryer),
        Category("plant", (0.35, 0.5, 0.35), (0.7, 1.5, 0.7), _EVERYWHERE, "floor", _plant),
        Category("lamp", (0.35, 1.4, 0.35), (0.5, 1.75, 0.5), _LIVING, "floor", _lamp),
        Category("table_lamp", (0.25, 0.4, 0.25), (0.35, 0.6, 0.35), ("bedroom", "living_room", "office"),
                 "on_surface", _table_lamp, supports=("nightstand", "desk", "dresser", "cabinet")),
        Category("rug", (1.2, 0.015, 0.8), (2.4, 0.015, 1.7),
                 ("living_room", "bedroom", "dining_room", "hallway", "office"), "floor", _rug),
        Category("picture", (0.4, 0.3, 0.03), (1.0, 0.8, 0.04), _EVERYWHERE, "wall_mounted", _picture),
        Category("mirror", (0.4, 0.6, 0.03), (0.8, 0.9, 0.04), ("bathroom", "bedroom", "hallway"), "wall_mounted",
                 _mirror),
        Category("clock", (0.3, 0.3, 0.05), (0.45, 0.45, 0.06),
                 ("kitchen", "living_room", "dining_room", "office", "hallway"), "wall_mounted", _clock),
        Category("towel", (0.35, 0.5, 0.07), (0.6, 0.8, 0.09), ("bathroom", "laundry", "kitchen"), "wall_mounted",
                 _towel),
        Category("trash_can", (0.3, 0.35, 0.3), (0.4, 0.6, 0.4), ("kitchen", "bathroom", "office", "laundry"), "floor",
                 _trash_can),
        Category("laundry_basket", (0.4, 0.45, 0.35), (0.55, 0.6, 0.45), ("laundry", "bathroom", "bedroom"),
                 "floor", _laundry_basket),
        Category("shoe_rack", (0.6, 0.4, 0.28), (1.0, 0.9, 0.35), ("hallway",), "wall", _shoe_rack),
        Category("coat_rack", (0.45, 1.6, 0.45), (0.55, 1.85, 0.55), ("hallway",), "floor", _coat_rack),
        Category("stool", (0.32, 0.45, 0.32), (0.4, 0.75, 0.4), ("kitchen",), "floor", _stool),
    )
}
