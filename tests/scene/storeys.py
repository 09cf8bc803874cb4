"""Two-storey houses for the layered-navigability tests: a 10 x 6 m ground floor and an upper floor 2.8 m up,
joined by a flight of stairs (0.175 m risers), a ramp, or nothing."""

from __future__ import annotations

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
