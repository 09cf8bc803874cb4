"""LayeredNav on scenes composed of touching boxes (walls standing on slabs, under slabs, steps on floors): the
floor under a wall is no surface, a wall thinner than a cell still blocks, a slab's underside is no floor, and
a ramp's slope does not chain the floors it joins into one storey."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from navbench.scene.layers import LayeredNav
from navbench.scene.navigability import NavGrid, NavGridConfig

sys.path.insert(0, str(Path(__file__).parent))
from storeys import UPPER, box, building

R = NavGridConfig().agent_radius


def room(wall: float, under_slab: bool) -> trimesh.Trimesh:
    """A 6 x 4 m room, a wall ``wall`` m thick across it at x = 3 with a 1 m door at z in [3, 4], standing on
    the floor and (``under_slab``) touching a slab over the room: faces meet wherever parts do."""
    parts = [box((0, -0.1, 0), (6, 0, 4)), box((3, 0, 0), (3 + wall, 2.7, 3))]
    if under_slab:
        parts.append(box((0, 2.7, 0), (6, 2.8, 4)))
    return trimesh.util.concatenate(parts)


@pytest.mark.parametrize(("wall", "under_slab"), [(0.1, True), (0.1, False), (0.02, True)])
def test_a_wall_on_the_floor_blocks_and_the_path_goes_round_by_the_door(wall, under_slab):
    nav = LayeredNav.from_mesh(room(wall, under_slab))
    a, b = (1.5, 0.0, 1.0), (4.5, 0.0, 1.0)
    # by hand: round the wall's end at z = 3, keeping the radius from the cells the wall touches (Recast's
    # voxels: 5 cm cells with edges on multiples of 5 cm here, a face on an edge touching the cells on both sides)
    cs = NavGridConfig().cell_size
    x0, x1, z1 = 3.0 - cs, (math.floor((3.0 + wall) / cs + 1e-9) + 1) * cs, 3.0 + cs
    path = [a, (x0, 0.0, z1 + R), (x1, 0.0, z1 + R), b]
    by_hand = sum(math.dist(p, q) for p, q in zip(path, path[1:]))
    assert nav.geodesic_distance(a, b) == pytest.approx(by_hand, rel=0.02)
    for x in np.arange(2.9, 3.15 + wall, 0.05):  # no navigable span in or beside the wall
        assert nav.span_of((x, 0.0, 1.0), max_dist=0.0) < 0, x


def test_a_slab_underside_is_no_floor():
    nav = LayeredNav.from_mesh(room(0.1, True))
    # spans: the floor and the slab's top (nothing at the underside's 2.7 m)
    assert set(np.round(nav.height, 3)) <= {0.0, 2.8}


@pytest.mark.parametrize("angle", [10.0, 20.0, 30.0])
def test_a_ramp_separates_the_storeys_it_joins(angle):
    mesh = building("ramp", angle)
    levels = NavGrid._levels(mesh, NavGridConfig())
    assert np.any(np.abs(levels) < 0.01) and np.any(np.abs(levels - UPPER) < 0.01), levels
    assert NavGrid.floor_for(mesh, 0.0) == pytest.approx(0.0, abs=0.01)
    assert NavGrid.floor_for(mesh, UPPER) == pytest.approx(UPPER, abs=0.01)
    nav = LayeredNav.from_mesh(mesh)
    np.testing.assert_allclose(nav.storeys(), [0.0, UPPER], atol=0.01)
