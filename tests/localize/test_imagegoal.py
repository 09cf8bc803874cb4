"""The ImageNav camera estimate's parts: the z-buffered render of a labelled cloud and the id-histogram retrieval."""

from __future__ import annotations

import numpy as np

from navbench.localize.imagegoal import _histogram, render_ids, similarity, voxel_downsample


def _wall(z: float, instance: int, n: int = 60) -> tuple[np.ndarray, np.ndarray]:
    xs, ys = np.meshgrid(np.linspace(-3, 3, n), np.linspace(-2, 4, n))
    pts = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)], axis=1)
    return pts, np.full(len(pts), instance, np.int32)


def test_render_ids_shows_the_nearest_surface_in_front():
    near, far = _wall(-2.0, 7), _wall(-4.0, 9)
    behind = _wall(+2.0, 5)  # behind a camera at the origin facing -z (yaw 0)
    pts = np.concatenate([far[0], near[0], behind[0]])
    ids = np.concatenate([far[1], near[1], behind[1]])
    shown = render_ids(pts, ids, np.array([[0.0, 1.0, 0.0, 0.0]]), 60.0, 12)[0]
    assert (shown == 7).mean() > 0.9 and not (shown == 9).any() and not (shown == 5).any()
    turned = render_ids(pts, ids, np.array([[0.0, 1.0, 0.0, np.pi]]), 60.0, 12)[0]  # facing +z: the other wall
    assert (turned == 5).mean() > 0.9 and not (turned == 7).any()


def test_similarity_is_the_histogram_intersection():
    a = _histogram(np.array([1, 1, 2, -1]))
    assert a == {1: 2 / 3, 2: 1 / 3}
    assert similarity(a, a) == 1.0
    assert abs(similarity(a, {2: 1.0}) - 1 / 3) < 1e-12
    assert similarity(a, {3: 1.0}) == 0.0


def test_voxel_downsample_keeps_one_point_per_cube():
    pts = np.array([[0.01, 0.0, 0.0], [0.02, 0.0, 0.0], [0.3, 0.0, 0.0]])
    kept, ids = voxel_downsample(pts, np.array([1, 2, 3]), 0.1)
    assert len(kept) == 2 and ids.tolist() == [1, 3]


def test_match_score_counts_object_pixels_not_walls():
    from navbench.localize.imagegoal import match_score
    target = np.array([[-1, -1], [3, 3]])
    walls_only = np.array([[[-1, -1], [-1, -1]]])  # every wall pixel agrees, the object is missed
    object_seen = np.array([[[4, -1], [3, 3]]])  # the object, and one more object where the goal sees a wall
    assert match_score(walls_only, target)[0] == 0.0
    assert match_score(object_seen, target)[0] == 2 / 3
    assert match_score(walls_only, np.full((2, 2), -1))[0] == 1.0  # a goal image without objects: all pixels
