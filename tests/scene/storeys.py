"""Two-storey houses for the layered-navigability tests: a 10 x 6 m ground floor and an upper floor 2.8 m up,
joined by a flight of stairs (0.175 m risers), a ramp, or nothing."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import trimesh

UPPER = 2.8  # upper floor height (top of its 0.1 m slab)
X0, X1 = 3.0, 7.5  # the flight climbs +x from its first riser at X0 to the upper floor's edge at X1
Z0, Z1 = 2.0, 3.2  # the flight's width (1.2 m); the upper floor is open above it (the stairwell)
RISE, TREAD, STEPS = 0.175, 0.3, 15  # 15 treads + the last riser up to the upper floor: 16 x 0.175 = 2.8


def box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    b = trimesh.creation.box(hi - lo)
    b.apply_translation((lo + hi) / 2)
    return b


def house(join: str | None, slab: float = 0.1) -> trimesh.Trimesh:
    """10 x 6 m ground floor at y = 0 and upper floor at y = 2.8 (slabs ``slab`` thick) with a stairwell over
    x in [3, 7.5], z in [2, 3.2]; ``join`` = "stairs", "ramp" or None (nothing between the storeys)."""
    return trimesh.util.concatenate(_house_parts(join, slab))


def _house_parts(join: str | None, slab: float = 0.1) -> list[trimesh.Trimesh]:
    """:func:`house`'s boxes: the ground slab, the upper slab's four boxes round the stairwell, then the join."""
    lo = UPPER - slab
    parts = [box((0, -slab, 0), (10, 0, 6)),
             box((0, lo, 0), (10, UPPER, Z0)), box((0, lo, Z1), (10, UPPER, 6)),
             box((0, lo, Z0), (X0, UPPER, Z1)), box((X1, lo, Z0), (10, UPPER, Z1))]
    if join == "stairs":
        parts += [box((X0 + TREAD * k, 0, Z0), (X0 + TREAD * (k + 1), RISE * (k + 1), Z1)) for k in range(STEPS)]
    elif join == "ramp":
        pts = [(x, y, z) for z in (Z0, Z1) for x, y in ((X0, 0.0), (X1, 0.0), (X1, UPPER))]
        parts.append(trimesh.convex.convex_hull(np.array(pts)))
    return parts


# Objects for the annotated house: (id, category, aabb min, aabb max); one chair on each storey, the upper one
# right above the lower one's neighbourhood (x, z the same), and a bed upstairs beyond the flight.
OBJECTS = [(1, "chair", (1.2, 0.0, 4.6), (1.7, 0.5, 5.1)),
           (2, "chair", (1.2, UPPER, 4.6), (1.7, UPPER + 0.5, 5.1)),
           (3, "bed", (8.2, UPPER, 4.0), (9.6, UPPER + 0.6, 5.8))]


def write_house(directory: Path, join: str | None, name: str | None = None) -> Path:
    """The house with :data:`OBJECTS` as ``{name}.glb`` (objects under ``obj_{id}`` nodes) and its
    ``.semantic.json`` sidecar; returns the GLB's path."""
    name = name or (join or "none")
    scene = trimesh.Scene()
    scene.add_geometry(house(join), node_name="structure", geom_name="structure")
    objects = []
    for i, cat, lo, hi in OBJECTS:
        scene.add_geometry(box(lo, hi), node_name=f"obj_{i}", geom_name=f"obj_{i}")
        objects.append({"id": i, "category": cat, "room": "hall", "colour": "grey", "colour_rgb": [128, 128, 128],
                        "aabb": {"min": list(lo), "max": list(hi)}})
    path = Path(directory) / f"{name}.glb"
    scene.export(path)
    path.with_name(f"{name}.semantic.json").write_text(json.dumps({"scene_id": name, "rooms": [], "objects": objects}))
    return path


# Furniture of the furnished houses: (id, category, storey, box lo, box hi), lo's y above the storey's floor.
# A chair on each storey; the rest on one storey only.
FURNITURE = [
    (1, "chair", 0, (0.6, 0.0, 4.6), (1.2, 0.9, 5.2)),
    (2, "sofa", 0, (8.2, 0.0, 4.8), (9.8, 0.8, 5.7)),
    (3, "table", 0, (4.0, 0.0, 4.5), (5.2, 0.75, 5.5)),
    (4, "chair", 1, (8.8, 0.0, 0.4), (9.4, 0.9, 1.0)),
    (5, "bed", 1, (0.3, 0.0, 4.2), (2.2, 0.6, 5.8)),
    (6, "plant", 1, (5.0, 0.0, 4.8), (5.6, 1.2, 5.4)),
]
COLOURS = {"chair": (200, 40, 40), "sofa": (40, 160, 60), "table": (150, 100, 40), "bed": (40, 60, 200),
           "plant": (30, 200, 120)}


def furnished(join: str | None, directory, slab: float = 0.1, rooms_from_slab: bool = False) -> Path:
    """:func:`house` with :data:`FURNITURE` as annotated objects (``obj_{id}`` nodes) and a room per storey,
    written to ``directory/{join}.glb`` with its ``.semantic.json``; returns the glb's path. With
    ``rooms_from_slab`` each room's box starts at the underside of its floor slab, as a box built from a room's
    faces does (MP3D regions, HM3D rooms), not at the floor's top."""
    directory = Path(directory)
    name = join or "none"
    structure = house(join, slab)
    structure.visual.vertex_colors = (170, 170, 170, 255)
    scene = trimesh.Scene()
    scene.add_geometry(structure, node_name="structure", geom_name="structure")
    objects = []
    for oid, cat, storey, lo, hi in FURNITURE:
        lift = np.array([0.0, UPPER * storey, 0.0])
        lo, hi = np.asarray(lo) + lift, np.asarray(hi) + lift
        b = box(lo, hi)
        b.visual.vertex_colors = (*COLOURS[cat], 255)
        scene.add_geometry(b, node_name=f"obj_{oid}", geom_name=f"obj_{oid}")
        objects.append({"id": oid, "category": cat, "room": ("ground", "upper")[storey], "colour": "",
                        "colour_rgb": list(COLOURS[cat]), "aabb": {"min": lo.tolist(), "max": hi.tolist()}})
    below = slab if rooms_from_slab else 0.0
    rooms = [{"name": "ground", "aabb": {"min": [0.0, -below, 0.0], "max": [10.0, UPPER - slab, 6.0]}},
             {"name": "upper", "aabb": {"min": [0.0, UPPER - below, 0.0], "max": [10.0, UPPER + 2.7, 6.0]}}]
    path = directory / f"{name}.glb"
    scene.export(path)
    (directory / f"{name}.semantic.json").write_text(json.dumps({"scene_id": name, "rooms": rooms,
                                                                "objects": objects}))
    return path


MP3D_CATEGORIES = {"floor": 2, "chair": 3, "table": 5, "sofa": 10, "bed": 11, "plant": 14}  # mpcat40 indices


def furnished_mp3d(directory, slab: float = 0.3, scan: str = "twoStorey") -> Path:
    """The furnished house without a join as Matterport3D ships a scan (z-up frame): ``{scan}/{scan}.glb``, the
    semantic PLY with a per-face ``object_id`` (each storey's slab a ``floor`` object of its region, each piece of
    :data:`FURNITURE` an object) and the ``.house`` file's ``C``/``R``/``O`` records, under ``directory`` with
    ``mp3d.scene_dataset_config.json``. The rooms' boxes come from their faces, so each starts at the underside of
    its slab, ``slab`` below its floor. Returns the mesh's path."""
    parts = _house_parts(None, slab)
    objects = [0, 1, 1, 1, 1]  # .house object index per part: the ground slab, the upper slab's four boxes
    records = [(0, 0, "floor"), (1, 1, "floor")]  # (object index, region, category)
    for oid, cat, storey, lo, hi in FURNITURE:
        lift = np.array([0.0, UPPER * storey, 0.0])
        parts.append(box(np.asarray(lo) + lift, np.asarray(hi) + lift))
        objects.append(oid + 1)
        records.append((oid + 1, storey, cat))
    v = np.concatenate([p.vertices for p in parts])
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
    f = np.concatenate([p.faces + o for p, o in zip(parts, offsets)])
    face_obj = np.concatenate([np.full(len(p.faces), k, np.int32) for p, k in zip(parts, objects)])
    v_mp = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)  # (x, y, z)_habitat = (x, z, -y)_matterport
    d = Path(directory) / scan
    d.mkdir(parents=True, exist_ok=True)
    mesh = trimesh.Trimesh(v_mp, f, process=False)
    mesh.visual.vertex_colors = (170, 170, 170, 255)
    mesh.export(d / f"{scan}.glb")
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v_mp)}\nproperty float x\n"
            f"property float y\nproperty float z\nelement face {len(f)}\nproperty list uchar int vertex_indices\n"
            "property int object_id\nend_header\n").encode()
    rec = np.zeros(len(f), dtype=[("n", "u1"), ("idx", "<i4", (3,)), ("obj", "<i4")])
    rec["n"], rec["idx"], rec["obj"] = 3, f, face_obj
    (d / f"{scan}_semantic.ply").write_bytes(head + v_mp.astype("<f4").tobytes() + rec.tobytes())
    cats = sorted(MP3D_CATEGORIES)
    lines = ["ASCII 1.1", "H twoStorey unknown 0 0 0 0 0 2 2 2 0 1  0 0 0 0 0  0 -6 -0.3 10 0 5.5  0 0 0 0 0"]
    lines += [f"R {r} {r} 0 0 {label} 5 -3 {y} 0 -6 {y - slab} 10 0 {y + 2.7}  2.7 0 0 0 0"
              for r, label, y in ((0, "l", 0.0), (1, "b", UPPER))]
    lines += [f"C {i} {MP3D_CATEGORIES[c]} {c} {MP3D_CATEGORIES[c]} {c} 0 0 0 0 0" for i, c in enumerate(cats)]
    lines += [f"O {o} {r} {cats.index(c)}  0 0 0  1 0 0  0 1 0  0.5 0.5 0.5 0 0 0 0 0 0 0 0" for o, r, c in records]
    (d / f"{scan}.house").write_text("\n".join(lines) + "\n")
    (Path(directory) / "mp3d.scene_dataset_config.json").write_text(json.dumps({
        "stages": {"default_attributes": {"up": [0, 0, 1], "front": [0, 1, 0], "origin": [0, 0, 0],
                                          "semantic_asset": "%%CONFIG_NAME_AS_ASSET_FILENAME%%_semantic.ply"},
                   "paths": {".glb": ["*/*.glb"]}}}))
    return d / f"{scan}.glb"


def drive(env, agent, obs) -> dict:
    """Step ``env`` with ``agent`` from ``obs`` until the episode ends; the last step's info."""
    done = False
    while not done:
        obs, _, term, trunc, info = env.step(agent.act(obs))
        done = term or trunc
    return info


# Buildings composed of touching boxes, as composed scenes and many exported meshes are built: walls stand on
# the slabs, steps on the floor, and nothing is welded, so faces coincide wherever two parts meet.
WALL = 0.1  # wall and railing thickness
BZ0, BZ1 = 1.0, 2.2  # the flight's (or ramp's) width along z; the building is 8 m deep
DEPTH = 8.0


def flight_end(join: str | None, angle_deg: float = 20.0) -> float:
    """x where the flight (or the ramp) of :func:`building` reaches the upper floor."""
    return X0 + (TREAD * STEPS if join != "ramp" else UPPER / math.tan(math.radians(angle_deg)))


def building_length(join: str | None, angle_deg: float = 20.0) -> float:
    return max(12.0, flight_end(join, angle_deg) + 4.0)


def building(join: str | None, angle_deg: float = 20.0, walled: bool = True) -> trimesh.Trimesh:
    """A two-storey building of touching boxes, ``building_length`` x 8 m: exterior walls on both slabs, a
    walled (or, with ``walled=False``, open) flight of ``STEPS`` steps or a ``angle_deg`` ramp along +x over
    z in [1.0, 2.2] from x = 3 up to the upper floor (``join`` "stairs", "ramp" or None: no join, a stairwell
    only), a ground-floor partition with a 1 m door at x = 1.5 m past the flight, and a 1 m railing round the
    stairwell upstairs (open at the flight's top)."""
    length, x1 = building_length(join, angle_deg), flight_end(join, angle_deg)
    top = UPPER - 0.1  # walls of the ground floor end under the upper slab
    parts = [box((0, -0.1, 0), (length, 0, DEPTH)),  # ground slab
             # the upper slab round the stairwell x in [X0, x1], z in [BZ0, BZ1]
             box((0, top, 0), (length, UPPER, BZ0)), box((0, top, BZ1), (length, UPPER, DEPTH)),
             box((0, top, BZ0), (X0, UPPER, BZ1)), box((x1, top, BZ0), (length, UPPER, BZ1))]
    for y0, y1 in ((0.0, top), (UPPER, UPPER + 2.6)):  # exterior walls of each storey, standing on its slab
        parts += [box((0, y0, 0), (WALL, y1, DEPTH)), box((length - WALL, y0, 0), (length, y1, DEPTH)),
                  box((WALL, y0, 0), (length - WALL, y1, WALL)),
                  box((WALL, y0, DEPTH - WALL), (length - WALL, y1, DEPTH))]
    xp = x1 + 1.5  # the partition, with a door at z in [5.5, 6.5]
    parts += [box((xp, 0, WALL), (xp + WALL, top, 5.5)), box((xp, 0, 6.5), (xp + WALL, top, DEPTH - WALL))]
    if walled:  # the flight's side walls from floor to slab
        parts += [box((X0, 0, BZ0 - WALL), (x1, top, BZ0)), box((X0, 0, BZ1), (x1, top, BZ1 + WALL))]
    # the railing upstairs on the stairwell's sides and its low end
    parts += [box((X0 - WALL, UPPER, BZ0 - WALL), (x1, UPPER + 1.0, BZ0)),
              box((X0 - WALL, UPPER, BZ1), (x1, UPPER + 1.0, BZ1 + WALL)),
              box((X0 - WALL, UPPER, BZ0), (X0, UPPER + 1.0, BZ1))]
    if join == "stairs":
        parts += [box((X0 + TREAD * k, 0, BZ0), (X0 + TREAD * (k + 1), RISE * (k + 1), BZ1)) for k in range(STEPS)]
    elif join == "ramp":
        pts = [(x, y, z) for z in (BZ0, BZ1) for x, y in ((X0, 0.0), (x1, 0.0), (x1, UPPER))]
        parts.append(trimesh.convex.convex_hull(np.array(pts)))
    return trimesh.util.concatenate(parts)


# Cross-storey (start, goal) pairs in :func:`building`: from each ground-floor room (before and past the partition,
# the corridor beside the flight) to the upper floor, and down again.
def building_pairs(join: str | None, angle_deg: float = 20.0) -> list[tuple[list[float], list[float]]]:
    length, x1 = building_length(join, angle_deg), flight_end(join, angle_deg)
    far = length - 1.0
    return [([1.0, 0.0, 4.0], [far, UPPER, 4.5]), ([1.0, 0.0, 6.5], [far, UPPER, 6.5]),
            ([far, 0.0, 4.0], [1.0, UPPER, 6.5]), ([(X0 + x1) / 2, 0.0, 0.5], [(X0 + x1) / 2, UPPER, 4.0]),
            ([far, UPPER, 0.6], [1.0, 0.0, 4.0]), ([1.0, UPPER, 0.6], [far, 0.0, 6.0])]


# The composed buildings measured against Detour (benchmarks/detour_agreement.py --storeys): (join, ramp angle, walled).
BUILDINGS = [("stairs", 20.0, True), ("stairs", 20.0, False), ("ramp", 10.0, True), ("ramp", 20.0, True),
             ("ramp", 30.0, True)]


def building_name(join: str | None, angle_deg: float, walled: bool) -> str:
    kind = f"ramp{angle_deg:g}" if join == "ramp" else (join or "none")
    return f"building-{kind}-{'walled' if walled else 'open'}"
