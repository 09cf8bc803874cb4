"""The optimistic map on several storeys: unseen walls are free, a depth frame covers its own storey only, and
with everything seen the map's geodesics are the true layered ones."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from navbench.scene.layers import LayeredNav
from navbench.scene.optimistic import LayeredSeen

sys.path.insert(0, str(Path(__file__).parent))
from storeys import UPPER, box, house

# Either side of the wall, 1.6 m apart, on cell centres (the lattice's origin is half a cell before x = z = 0).
START, GOAL = np.array([0.975, 0.0, 0.975]), np.array([2.575, 0.0, 0.975])


@pytest.fixture(scope="module")
def walled() -> LayeredNav:
    # The stairs house with a 2 m ground-floor wall at x = 1.95 from z = 0 to 4.5 (its foot sunk into the floor
    # slab: no face coincides with the floor's): the way round it is past z = 4.5.
    return LayeredNav.from_mesh(trimesh.util.concatenate([house("stairs"), box((1.9, -0.05, 0), (2.0, 2.0, 4.5))]))


def test_an_unseen_wall_is_free_and_a_seen_map_is_the_true_one(walled):
    s = walled.span_of(START)
    opt = LayeredSeen(walled, 79.0, 0.5, 5.0)
    assert opt.field(GOAL).distance_on(s, START) == pytest.approx(1.6, abs=1e-9)  # straight through the wall
    true = walled.distance_field(GOAL).distance(START)
    assert true > 2 * 3.5  # round the wall's end, 3.5 m away on either side
    opt.seen[:] = True  # everything seen: the navigable spans and their steps, nothing else
    seen = opt.field(GOAL)
    assert seen.distance_on(s, START) == pytest.approx(true, abs=1e-9)
    np.testing.assert_allclose(seen.values[opt.node_of_span], walled.distances(GOAL), rtol=0, atol=1e-9)


def test_a_frame_covers_the_agents_storey_only(walled):
    opt = LayeredSeen(walled, 79.0, 0.5, 5.0)
    far = np.ones((32, 32, 1), np.float32)  # nothing within max_depth
    new = opt.update(far, START, -math.pi / 2, surface_y=0.0)  # facing +x
    assert len(new) and np.all(opt.height[new] <= walled.config.agent_height)
    ahead = opt.node_of_span[walled.span_of((4.0, 0.0, 1.0))]
    above = opt.node_of_span[walled.span_of((4.0, UPPER, 1.0))]
    behind = opt.node_of_span[walled.span_of((0.5, 0.0, 1.0))]
    assert opt.seen[ahead] and not opt.seen[above] and not opt.seen[behind]
    # The wall's cells (virtual floor nodes) in view are seen now: the way round is past the field of view's edge
    # on the wall (0.975 m ahead, tan(39.5 deg) x 0.975 m to either side), no longer straight through.
    wall = np.flatnonzero((np.abs(opt.x - 1.925) < 0.01) & (np.abs(opt.z - 0.975) < 0.01) & (opt.height == 0.0))
    assert len(wall) == 1 and not opt.navigable[wall[0]] and opt.seen[wall[0]]
    assert 1.6 + 0.5 < opt.field(GOAL).distance_on(walled.span_of(START), START) < 2 * 3.5
