"""Multi-view fusion: turn one candidate cluster (plus nearby confirming views) into a goal estimate.

1. :func:`neighbour_keyframes` picks extra views likely to see the target: keyframes within
   ``neighbour_radius`` of it whose projection of the target centre lands in the central
   ``central_fraction`` of the image, nearest first, at most ``max_neighbours``.
2. The caller segments those views and backprojects them; :func:`confirm_views` keeps a view when at
   least ``min_overlap`` of its points lie within ``overlap_radius`` of the seed cloud (the reference
   gives no separate fusion distance, so the grouping radius, 0.5 m, is the default).
3. :func:`fuse` concatenates the seed cloud with the confirmed clouds, runs HDBSCAN on a seeded
   subsample of at most ``max_points`` points and keeps the largest cluster unless it holds fewer than
   ``min_cluster_fraction`` of them (then nothing is dropped); the prediction is the bounding-box
   centre of what is kept. The fused cloud is that subsample, which is ample for the navigation
   agent's visibility test (it projects at most 2000 points).

Before subsampling, the cloud is reduced to one centroid per ``voxel_size`` voxel: sklearn's HDBSCAN
builds its spanning tree with Prim's algorithm over all point pairs (O(n^2)), and the views of one
object repeat the same surface, so voxels keep the shape while cutting the points several-fold. ``voxel_size=0``
restores the plain reference behaviour.

The clusters are the same on every CPU: sklearn orders the spanning tree's edges by weight with numpy's
default (unstable) argsort, whose order among equal weights - common, since a mutual-reachability
distance is often a point's core distance - depends on the vector width numpy dispatches to (AVX-512
or AVX2), and that order decides which points a cluster keeps. :func:`largest_cluster` has sklearn sort
those edges stably, so equal weights keep the spanning tree's own order.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree
from sklearn.cluster import HDBSCAN
from sklearn.cluster._hdbscan import hdbscan as _sklearn_hdbscan

from navbench.localize.geometry import PIXEL_CENTRE, project, voxel_downsample, world_to_camera
from navbench.localize.grouping import Cluster, ViewCloud, overlap_fraction
from navbench.memory.store import Intrinsics


@dataclass(frozen=True)
class FusionConfig:
    neighbour_radius: float = 3.0  # metres from the target centre to a neighbour keyframe's camera
    central_fraction: float = 0.8  # the target must project inside this central part of the image
    max_neighbours: int = 5
    overlap_radius: float = 0.5  # metres: a point confirms if it lies this close to the seed cloud
    min_overlap: float = 0.30  # fraction of a view's points that must confirm
    min_cluster_size: int = 20  # HDBSCAN
    min_samples: int = 5  # HDBSCAN
    # Subsample before HDBSCAN. The reference allows up to 5000; sklearn's HDBSCAN is O(n^2) (see the
    # module docstring), and 2000 points still outline an object, so the default is the cheaper bound.
    max_points: int = 2000
    min_cluster_fraction: float = 0.05  # keep the largest cluster only if it holds at least this fraction
    seed: int = 0  # subsampling RNG
    voxel_size: float = 0.03  # metres; one point per voxel before HDBSCAN (0 = off), see module docstring


@dataclass(frozen=True, eq=False)
class GoalCandidate:
    centre: np.ndarray  # (3,) bounding-box centre of the fused cloud, world coordinates
    points: np.ndarray  # (N, 3) fused (and HDBSCAN-filtered) cloud
    keyframe_ids: tuple[int, ...]  # supporting views: the cluster's, then the confirming neighbours
    score: float  # the seed view's rank score
    # (K, 3) camera positions of the supporting views (keyframe_ids order): where the pre-scan saw the
    # target from, i.e. places with a line of sight to it (the navigation agent's detour goals)
    view_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


def neighbour_keyframes(target: np.ndarray, cam_to_world: np.ndarray, intrinsics: Intrinsics | Sequence[Intrinsics],
                        keyframe_ids: Sequence[int] | None = None, exclude: Iterable[int] = (),
                        config: FusionConfig = FusionConfig()) -> list[int]:
    """Keyframes (ids, nearest first) that should see ``target``: see the module docstring.

    ``cam_to_world`` is (M, 4, 4); ``intrinsics`` one for all keyframes or one per keyframe;
    ``keyframe_ids`` names the rows (default 0..M-1); ids in ``exclude`` are skipped. Occlusion is not
    tested here: an occluded neighbour fails the overlap confirmation later.
    """
    poses = np.asarray(cam_to_world, dtype=np.float64).reshape(-1, 4, 4)
    ids = list(range(len(poses))) if keyframe_ids is None else [int(i) for i in keyframe_ids]
    if len(ids) != len(poses):
        raise ValueError(f"{len(poses)} poses but {len(ids)} keyframe ids")
    per_view = [intrinsics] * len(poses) if isinstance(intrinsics, Intrinsics) else list(intrinsics)
    if len(per_view) != len(poses):
        raise ValueError(f"{len(poses)} poses but {len(per_view)} intrinsics")
    target = np.asarray(target, dtype=np.float64).reshape(3)
    skip = set(int(i) for i in exclude)
    margin = (1.0 - config.central_fraction) / 2.0
    dist = np.linalg.norm(poses[:, :3, 3] - target, axis=1)
    found: list[int] = []
    for row in np.argsort(dist, kind="stable"):
        if dist[row] > config.neighbour_radius or len(found) >= config.max_neighbours:
            break
        if ids[row] in skip:
            continue
        intr = per_view[row]
        uv, _, in_view = project(target[None], intr.K, world_to_camera(poses[row]), intr.width, intr.height)
        # Fraction across the image: the image spans [c - 0.5, size + c - 0.5] for pixel-centre offset c.
        u, v = (uv[0] + 0.5 - PIXEL_CENTRE) / (intr.width, intr.height)
        if in_view[0] and margin <= u <= 1.0 - margin and margin <= v <= 1.0 - margin:
            found.append(ids[row])
    return found


def confirm_views(seed_points: np.ndarray, views: Sequence[ViewCloud], config: FusionConfig = FusionConfig()
                  ) -> list[ViewCloud]:
    """The views (in the given order) whose clouds overlap the seed cloud enough to confirm it."""
    seed_points = np.asarray(seed_points, dtype=np.float64).reshape(-1, 3)
    if len(seed_points) == 0:
        return []
    tree = cKDTree(seed_points)
    return [v for v in views if overlap_fraction(np.asarray(v.points).reshape(-1, 3), tree, config.overlap_radius)
            >= config.min_overlap]


@contextmanager
def stable_edge_order() -> Iterator[None]:
    """Within the block, sklearn's HDBSCAN sorts spanning-tree edges stably (see the module docstring)."""
    original = _sklearn_hdbscan._process_mst

    def process_mst(mst: np.ndarray) -> np.ndarray:
        return _sklearn_hdbscan.make_single_linkage(mst[np.argsort(mst["distance"], kind="stable")])

    _sklearn_hdbscan._process_mst = process_mst
    try:
        yield
    finally:
        _sklearn_hdbscan._process_mst = original


def largest_cluster(points: np.ndarray, config: FusionConfig = FusionConfig()) -> np.ndarray:
    """HDBSCAN outlier removal over a seeded subsample: the largest cluster, or the whole subsample when
    clustering finds nothing that holds at least ``min_cluster_fraction`` of it."""
    points = voxel_downsample(points, config.voxel_size)
    if len(points) > config.max_points:
        rng = np.random.default_rng(config.seed)
        points = points[np.sort(rng.choice(len(points), config.max_points, replace=False))]
    if len(points) < max(config.min_cluster_size, config.min_samples + 1):
        return points
    hdbscan = HDBSCAN(min_cluster_size=config.min_cluster_size, min_samples=config.min_samples, copy=True)
    with stable_edge_order():
        labels = hdbscan.fit_predict(points)
    if not (labels >= 0).any():
        return points
    counts = np.bincount(labels[labels >= 0])
    biggest = int(np.argmax(counts))
    if counts[biggest] < config.min_cluster_fraction * len(points):
        return points
    return points[labels == biggest]


def fuse(seed: Cluster | ViewCloud, others: Sequence[ViewCloud] = (), config: FusionConfig = FusionConfig()
         ) -> GoalCandidate:
    """Fuse a candidate (a grouping cluster or a single view) with the ``others`` that confirm it."""
    seed_views = seed.views if isinstance(seed, Cluster) else [seed]
    seed_points = np.asarray(seed.points, dtype=np.float64).reshape(-1, 3)
    if len(seed_points) == 0:
        raise ValueError(f"candidate seeded by keyframe {seed_views[0].keyframe_id} has an empty cloud")
    seed_ids = {v.keyframe_id for v in seed_views}
    confirmed = confirm_views(seed_points, [v for v in others if v.keyframe_id not in seed_ids], config)
    cloud = np.concatenate([seed_points] + [np.asarray(v.points, dtype=np.float64).reshape(-1, 3) for v in confirmed])
    kept = largest_cluster(cloud, config)
    centre = (kept.min(axis=0) + kept.max(axis=0)) / 2.0
    ids = tuple(v.keyframe_id for v in seed_views) + tuple(v.keyframe_id for v in confirmed)
    return GoalCandidate(centre=centre, points=kept, keyframe_ids=ids, score=float(seed_views[0].score))
