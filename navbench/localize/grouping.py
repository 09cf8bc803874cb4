"""Multi-instance grouping: split the per-view clouds of one query into object instances.

Views arrive in rank order (best first, e.g. by VLM visibility). Each view's cloud joins the existing
cluster it overlaps most - at least ``min_overlap`` of its points within ``radius`` of the cluster's
cloud, or its closest point nearer than ``min_distance`` - and otherwise seeds a new cluster. So two
chairs 3 m apart become two candidates, while two views of one chair merge. With the reference
defaults (both distances 0.5 m) the min-distance test alone decides; the overlap test matters when
``min_distance`` is set tighter.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class GroupingConfig:
    radius: float = 0.5  # metres: a point overlaps a cloud if it lies within this distance of it
    min_overlap: float = 0.15  # merge if at least this fraction of the view's points overlap ...
    min_distance: float = 0.5  # ... or if the view's closest point is nearer than this


@dataclass(frozen=True, eq=False)
class ViewCloud:
    """The backprojected mask of one keyframe."""

    keyframe_id: int
    points: np.ndarray  # (N, 3) world coordinates
    score: float = 0.0  # the view's rank score (higher is better), e.g. VLM visibility


@dataclass(eq=False)
class Cluster:
    """One object instance hypothesis: the views whose clouds were merged, seed (best-ranked) first."""

    views: list[ViewCloud]
    points: np.ndarray
    _tree: cKDTree = field(repr=False)

    @property
    def keyframe_ids(self) -> list[int]:
        return [v.keyframe_id for v in self.views]

    @property
    def score(self) -> float:
        return self.views[0].score

    @property
    def tree(self) -> cKDTree:
        return self._tree


def nearest_distances(points: np.ndarray, tree: cKDTree, upper_bound: float) -> np.ndarray:
    """Distance from each point to the tree's cloud; inf beyond ``upper_bound`` (bounded queries are fast)."""
    d, _ = tree.query(np.asarray(points, dtype=np.float64).reshape(-1, 3), k=1, distance_upper_bound=upper_bound)
    return d


def overlap_fraction(points: np.ndarray, tree: cKDTree, radius: float) -> float:
    """Fraction of ``points`` within ``radius`` of the tree's cloud (0 for an empty cloud)."""
    if len(points) == 0:
        return 0.0
    return float(np.mean(nearest_distances(points, tree, radius) <= radius))


def group_views(views: Sequence[ViewCloud], config: GroupingConfig = GroupingConfig()) -> list[Cluster]:
    """Group view clouds (given best first) into clusters, in the order their seeds were ranked.

    Views with empty clouds are skipped. When a view qualifies for several clusters it joins the one
    with the largest overlap fraction (the earliest on a tie).
    """
    bound = max(config.radius, config.min_distance)
    clusters: list[Cluster] = []
    for view in views:
        pts = np.asarray(view.points, dtype=np.float64).reshape(-1, 3)
        if len(pts) == 0:
            continue
        best, best_frac = None, -1.0
        for c in clusters:
            d = nearest_distances(pts, c.tree, bound)
            frac = float(np.mean(d <= config.radius))
            if (frac >= config.min_overlap or float(d.min()) < config.min_distance) and frac > best_frac:
                best, best_frac = c, frac
        if best is None:
            clusters.append(Cluster([view], pts, cKDTree(pts)))
        else:
            best.views.append(view)
            best.points = np.concatenate([best.points, pts])
            best._tree = cKDTree(best.points)
    return clusters
