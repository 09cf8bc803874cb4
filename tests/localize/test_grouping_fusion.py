import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from navbench.localize import (
    FusionConfig,
    GroupingConfig,
    ViewCloud,
    confirm_views,
    fuse,
    group_views,
    largest_cluster,
    neighbour_keyframes,
    project,
    world_to_camera,
)
from navbench.memory import Intrinsics
from navbench.render.camera import camera_pose

INTR = Intrinsics.from_hfov(224, 224, 79.0)


def box_surface(rng, centre, size, n):
    """n points on the surface of an axis-aligned box (what a depth camera sees of an object)."""
    pts = rng.uniform(-0.5, 0.5, size=(n, 3))
    face = rng.integers(0, 3, size=n)
    pts[np.arange(n), face] = np.sign(pts[np.arange(n), face]) * 0.5
    return np.asarray(centre) + pts * np.asarray(size)


def partial(points, axis, lo, hi):
    return points[(points[:, axis] >= lo) & (points[:, axis] <= hi)]


def test_two_objects_three_metres_apart_make_two_clusters_in_rank_order():
    rng = np.random.default_rng(0)
    a = box_surface(rng, [0.0, 0.5, 0.0], [0.6, 1.0, 0.6], 3000)
    b = box_surface(rng, [3.0, 0.5, 0.0], [0.6, 1.0, 0.6], 3000)
    views = [
        ViewCloud(7, partial(b, 0, 2.7, 3.1), score=0.9),  # best-ranked view shows object b
        ViewCloud(3, partial(a, 0, -0.3, 0.1), score=0.8),
        ViewCloud(5, partial(a, 0, -0.1, 0.3), score=0.7),
        ViewCloud(9, np.zeros((0, 3)), score=0.65),  # empty mask cloud: skipped
        ViewCloud(8, partial(b, 0, 2.9, 3.3), score=0.6),
        ViewCloud(4, a + rng.normal(scale=0.01, size=a.shape), score=0.5),
    ]
    clusters = group_views(views)
    assert [c.keyframe_ids for c in clusters] == [[7, 8], [3, 5, 4]]
    assert [c.score for c in clusters] == [0.9, 0.8]
    assert len(clusters[1].points) == sum(len(v.points) for v in views if v.keyframe_id in (3, 5, 4))
    # Objects 0.8 m apart (gap 0.2 m between surfaces) merge under the 0.5 m rule ...
    c = box_surface(rng, [0.8, 0.5, 0.0], [0.6, 1.0, 0.6], 1000)
    assert len(group_views([ViewCloud(1, a), ViewCloud(2, c)])) == 1
    # ... but not when the distance rules are tightened below the gap.
    assert len(group_views([ViewCloud(1, a), ViewCloud(2, c)], GroupingConfig(radius=0.1, min_distance=0.1))) == 2


def test_overlap_fraction_rule_alone():
    rng = np.random.default_rng(1)
    seed = rng.uniform(0, 1, size=(2000, 3))
    far = rng.uniform(5, 6, size=(900, 3))
    cfg = GroupingConfig(radius=0.5, min_overlap=0.15, min_distance=0.0)  # only the 15 % rule
    near_10 = np.concatenate([seed[:100], far])  # 100 of 1000 points overlap: 10 %
    near_20 = np.concatenate([seed[:225], far])  # 225 of 1125: 20 %
    assert len(group_views([ViewCloud(0, seed), ViewCloud(1, near_10)], cfg)) == 2
    assert len(group_views([ViewCloud(0, seed), ViewCloud(1, near_20)], cfg)) == 1


def test_hdbscan_removes_far_outliers_and_centre_is_accurate():
    rng = np.random.default_rng(2)
    truth = np.array([2.0, 0.45, -3.0])
    obj = box_surface(rng, truth, [0.5, 0.9, 0.4], 2000)
    # 10 % stray points on one side (e.g. mask bleeding onto the wall behind), 1-4 m away.
    outliers = truth + rng.uniform([1.0, -0.4, -2.0], [4.0, 1.0, 2.0], size=(200, 3))
    cloud = np.concatenate([obj, outliers])
    naive = (cloud.min(0) + cloud.max(0)) / 2
    assert np.linalg.norm(naive - truth) > 0.3  # without outlier removal the box centre is off
    exact = FusionConfig(voxel_size=0.0, max_points=5000)  # the reference: HDBSCAN on (up to 5000) points
    kept = largest_cluster(cloud, exact)
    assert len(kept) >= 0.95 * len(obj)
    assert np.linalg.norm(fuse(ViewCloud(11, cloud), config=exact).centre - truth) < 0.03
    # Default: one centroid per 3 cm voxel first; the outliers still go and the centre stays put.
    kept = largest_cluster(cloud)
    assert len(kept) < len(obj) and np.all(np.abs(kept - truth) <= np.array([0.25, 0.45, 0.2]) + 0.03)
    candidate = fuse(ViewCloud(11, cloud, score=0.7))
    assert np.linalg.norm(candidate.centre - truth) < 0.03
    assert candidate.keyframe_ids == (11,) and candidate.score == 0.7


def test_subsampling_is_bounded_and_seeded():
    rng = np.random.default_rng(3)
    cloud = box_surface(rng, [0, 0, 0], [1, 1, 1], 12000)
    cfg = FusionConfig(max_points=3000, voxel_size=0.0)
    a, b = largest_cluster(cloud, cfg), largest_cluster(cloud, cfg)
    assert len(a) <= 3000 and np.array_equal(a, b)
    assert not np.array_equal(a, largest_cluster(cloud, FusionConfig(max_points=3000, seed=1, voxel_size=0.0)))
    assert len(largest_cluster(cloud[:10])) == 10  # too few points to cluster: kept as they are


def test_fusion_keeps_only_confirming_views():
    rng = np.random.default_rng(4)
    obj = box_surface(rng, [1.0, 0.5, 1.0], [0.5, 0.8, 0.5], 3000)
    other = box_surface(rng, [4.0, 0.5, 1.0], [0.5, 0.8, 0.5], 1000)
    seed = ViewCloud(0, partial(obj, 0, 0.75, 1.0), score=0.9)
    confirming = ViewCloud(1, partial(obj, 0, 0.85, 1.25))  # overlaps the seed half-way
    mostly_elsewhere = ViewCloud(2, np.concatenate([partial(obj, 0, 0.9, 1.0)[:50], other]))  # < 30 % overlap
    assert [v.keyframe_id for v in confirm_views(seed.points, [confirming, mostly_elsewhere])] == [1]
    cand = fuse(seed, [confirming, mostly_elsewhere, seed])  # the seed itself is not counted twice
    assert cand.keyframe_ids == (0, 1)
    assert np.linalg.norm(cand.centre - [1.0, 0.5, 1.0]) < 0.05
    cluster = group_views([seed, confirming])[0]
    assert fuse(cluster, [confirming]).keyframe_ids == (0, 1)
    with pytest.raises(ValueError, match="empty cloud"):
        fuse(ViewCloud(5, np.zeros((0, 3))))


def look_at_pose(position, target, offset_deg=0.0):
    """Camera at ``position`` turned (yaw only) so its -z axis points at ``target`` in xz, then turned
    ``offset_deg`` further left (so the target moves right in the image)."""
    d = np.asarray(target, float) - np.asarray(position, float)
    yaw = np.arctan2(-d[0], -d[2]) + np.radians(offset_deg)
    return camera_pose(position, Rotation.from_euler("y", yaw).as_quat())


def test_neighbour_keyframes():
    target = np.array([0.0, 0.88, 0.0])
    poses = [
        look_at_pose([2.0, 0.88, 0.0], target),  # 0: 2 m, facing it
        look_at_pose([0.0, 0.88, 1.0], target),  # 1: 1 m, facing it
        look_at_pose([0.0, 0.88, 3.5], target),  # 2: too far
        look_at_pose([-1.5, 0.88, 0.0], [-3.0, 0.88, 0.0]),  # 3: close but facing away
        look_at_pose([1.0, 0.88, -1.0], [1.0 + 2.0, 0.88, -1.0 + 0.1]),  # 4: target far off to the side
        look_at_pose([2.5, 0.88, 0.5], target, offset_deg=35.0),  # 5: target near the image's right edge
    ]
    uv, _, in_view = project(target[None], INTR.K, world_to_camera(poses[5]), 224, 224)
    assert in_view[0] and 201.6 < uv[0, 0] < 224  # in the image, outside the central 80 %
    assert neighbour_keyframes(target, poses, INTR) == [1, 0]
    assert neighbour_keyframes(target, poses, INTR, config=FusionConfig(central_fraction=1.0)) == [1, 0, 5]
    assert neighbour_keyframes(target, poses, [INTR] * 6, keyframe_ids=[10, 11, 12, 13, 14, 15], exclude=[11]) == [10]
    many = [look_at_pose([np.cos(a) * r, 0.88, np.sin(a) * r], target)
            for a, r in zip(np.linspace(0, 6, 9), np.linspace(0.5, 2.9, 9))]
    assert neighbour_keyframes(target, many, INTR) == [0, 1, 2, 3, 4]


def test_largest_cluster_does_not_depend_on_how_sklearn_orders_equal_edges(monkeypatch):
    # Points on a regular grid (as voxel centroids of a flat surface are): many spanning-tree edges of equal
    # weight, whose order numpy's unstable argsort leaves to the vector width it dispatches to. Reversing
    # equal edges in sklearn's own sort must not change what is kept.
    from sklearn.cluster._hdbscan import hdbscan as sk

    rng = np.random.default_rng(2)
    n = rng.integers(8, 16)
    grid = np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 2) * 0.03
    grid = grid[rng.random(len(grid)) < 0.7]
    plane = np.c_[grid, np.zeros(len(grid))]
    shifted = plane[: rng.integers(20, 60)] + [rng.uniform(0.1, 0.6), 0, 0.03 * rng.integers(0, 3)]
    points = np.concatenate([plane, shifted])
    config = FusionConfig(voxel_size=0.0)
    expected = largest_cluster(points, config)

    class TiesReversed:
        def __getattr__(self, name):
            return getattr(np, name)

        @staticmethod
        def argsort(a, *args, **kwargs):
            return np.lexsort((-np.arange(len(a)), np.asarray(a)))  # by value, equal values last-first

    monkeypatch.setattr(sk, "np", TiesReversed())
    np.testing.assert_array_equal(largest_cluster(points, config), expected)
