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
