"""Two-storey houses for the layered-navigability tests: a 10 x 6 m ground floor and an upper floor 2.8 m up,
joined by a flight of stairs (0.175 m risers), a ramp, or nothing."""

from __future__ import annotations

import json
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


def house(join: str | None) -> trimesh.Trimesh:
    """10 x 6 m ground floor at y = 0 and upper floor at y = 2.8 with a stairwell over x in [3, 7.5],
    z in [2, 3.2]; ``join`` = "stairs", "ramp" or None (nothing between the storeys)."""
    parts = [box((0, -0.1, 0), (10, 0, 6)),
             box((0, UPPER - 0.1, 0), (10, UPPER, Z0)), box((0, UPPER - 0.1, Z1), (10, UPPER, 6)),
             box((0, UPPER - 0.1, Z0), (X0, UPPER, Z1)), box((X1, UPPER - 0.1, Z0), (10, UPPER, Z1))]
    if join == "stairs":
        parts += [box((X0 + TREAD * k, 0, Z0), (X0 + TREAD * (k + 1), RISE * (k + 1), Z1)) for k in range(STEPS)]
    elif join == "ramp":
        pts = [(x, y, z) for z in (Z0, Z1) for x, y in ((X0, 0.0), (X1, 0.0), (X1, UPPER))]
        parts.append(trimesh.convex.convex_hull(np.array(pts)))
    return trimesh.util.concatenate(parts)


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


def furnished(join: str | None, directory) -> Path:
    """:func:`house` with :data:`FURNITURE` as annotated objects (``obj_{id}`` nodes) and a room per storey,
    written to ``directory/{join}.glb`` with its ``.semantic.json``; returns the glb's path."""
    directory = Path(directory)
    name = join or "none"
    structure = house(join)
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
    rooms = [{"name": "ground", "aabb": {"min": [0.0, 0.0, 0.0], "max": [10.0, UPPER - 0.1, 6.0]}},
             {"name": "upper", "aabb": {"min": [0.0, UPPER, 0.0], "max": [10.0, UPPER + 2.7, 6.0]}}]
    path = directory / f"{name}.glb"
    scene.export(path)
    (directory / f"{name}.semantic.json").write_text(json.dumps({"scene_id": name, "rooms": rooms,
                                                                "objects": objects}))
    return path


def drive(env, agent, obs) -> dict:
    """Step ``env`` with ``agent`` from ``obs`` until the episode ends; the last step's info."""
    done = False
    while not done:
        obs, _, term, trunc, info = env.step(agent.act(obs))
        done = term or trunc
    return info
