"""The map-free localiser: from a query to ranked 3D goal candidates, over a keyframe memory.

Steps (defaults from the reference configuration, all in :class:`LocalizerConfig`):

1. Retrieve the top-K keyframes by embedding similarity (0.9 cosine de-duplication). Text queries
   (object, language) use the text embedding; image queries the sum of the query image's embedding
   and its caption's (``image_retrieval``).
2. Re-rank them with the VLM (keep "yes" views by visibility; none -> the single best). Image queries
   are turned into a text prompt by a captioner first (the oracle's names the object in the centre).
3. Segment the target in each kept view, drop views whose median masked depth exceeds 4 m, and
   backproject the mask (depth 0.1-20 m).
4. Group the view clouds into instances in rank order (:func:`~navbench.localize.grouping.group_views`).
5. Fuse each instance (:mod:`~navbench.localize.fusion`): the other retrieved views and up to 5
   neighbour keyframes (within 3 m of the instance, seeing it in the central 80 % of the image) are
   segmented and confirmed by 3D overlap; HDBSCAN keeps the largest cluster; the prediction is the
   bounding-box centre.

``fusion=False`` is the single-view ablation: each instance is predicted from its best-ranked view
alone (bounding-box centre of that view's cloud), no neighbours, no HDBSCAN.

Backends are the protocols of :mod:`navbench.localize.backends.base`; each may declare
``modality = "instance_ids"`` (the oracle) to receive the keyframe's id image instead of RGB.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Literal, Protocol

import numpy as np

from navbench.localize.backends.base import Encoder, Reranker, Segmenter
from navbench.localize.fusion import FusionConfig, GoalCandidate, fuse, neighbour_keyframes
from navbench.localize.geometry import GeometryConfig, backproject, keep_view
from navbench.localize.grouping import GroupingConfig, ViewCloud, group_views
from navbench.localize.vlm import ScoredView, rerank
from navbench.memory.index import l2_normalize
from navbench.memory.prescan import Memory

QueryType = Literal["object", "image", "language"]
QUERY_TYPES: tuple[str, ...] = ("object", "image", "language")


class LocalizeError(ValueError):
    """A malformed query or an unusable memory/backend combination; the message names the value."""


@dataclass(frozen=True)
class Query:
    type: QueryType
    text: str | None = None  # object: a category name or synonym; language: a description
    image: np.ndarray | None = None  # image: H x W x 3 uint8 RGB of the target
    image_ids: np.ndarray | None = None  # image: the renderer's instance ids of that view (oracle only)

    def __post_init__(self) -> None:
        if self.type not in QUERY_TYPES:
            raise LocalizeError(f"query type must be one of {QUERY_TYPES}, got {self.type!r}")
        if self.type == "image":
            if self.image is None and self.image_ids is None:
                raise LocalizeError("an image query needs an image (or, for the oracle, its instance ids)")
        elif not self.text or not self.text.strip():
            raise LocalizeError(f"a {self.type} query needs a non-empty text, got {self.text!r}")


class Captioner(Protocol):
    def describe(self, image: np.ndarray) -> str:
        """A short description of the object in the centre of ``image``."""
        ...


class DepthNoise(Protocol):
    def perturb(self, depth: np.ndarray, query: str) -> np.ndarray: ...


@dataclass
class Perception:
    """One set of perception backends (what a perception name in the benchmark stands for)."""

    encoder: Encoder
    reranker: Reranker
    segmenter: Segmenter
    captioner: Captioner | None = None  # needed for image queries
    depth_noise: DepthNoise | None = None  # simulated depth error (oracle noise profiles)


@dataclass(frozen=True)
class LocalizerConfig:
    top_k: int = 10  # retrieved keyframes
    dedup: float | None = 0.9  # cosine above which a retrieved view duplicates a better one
    rerank: bool = True  # VLM re-ranking (False: keep retrieval order, every view)
    fusion: bool = True  # multi-view fusion + HDBSCAN (False: single-view ablation)
    min_points: int = 10  # a segmented view with fewer backprojected points is dropped
    # Image queries retrieve with the goal image's embedding, its caption's, or both summed: the
    # whole-image embedding also matches the goal's surroundings, so alone it misses small objects on
    # busy walls that the caption finds.
    image_retrieval: Literal["image", "caption", "both"] = "both"
    geometry: GeometryConfig = field(default_factory=GeometryConfig)
    grouping: GroupingConfig = field(default_factory=GroupingConfig)
    fusion_config: FusionConfig = field(default_factory=FusionConfig)


def modality(backend: object) -> str:
    """Which keyframe image a backend consumes: ``"rgb"`` unless it declares otherwise."""
    return getattr(backend, "modality", "rgb")


def query_image(query: Query, backend: object) -> np.ndarray:
    """The query's image as ``backend`` reads it: its instance ids for an ``instance_ids`` backend, else RGB."""
    image = query.image_ids if modality(backend) == "instance_ids" else query.image
    if image is None:
        raise LocalizeError(f"{type(backend).__name__} needs the query's "
                            f"{'instance ids' if modality(backend) == 'instance_ids' else 'RGB image'}")
    return image


def query_prompt(query: Query, captioner: Captioner | None) -> str:
    """The text the re-ranker and segmenter look for: a text query's own, an image query's caption."""
    if query.type != "image":
        return query.text.strip()
    if captioner is None:
        raise LocalizeError("image queries need a captioner to prompt the re-ranker and segmenter")
    return captioner.describe(query_image(query, captioner))


@dataclass
class LocalizationTrace:
    """What one call did, for logs and tests."""

    prompt: str = ""
    retrieved: list[tuple[int, float]] = field(default_factory=list)
    kept: list[int] = field(default_factory=list)  # after re-ranking, best first
    segmented: list[int] = field(default_factory=list)  # views with a usable cloud
    neighbours: list[int] = field(default_factory=list)  # extra keyframes looked at by fusion
    seconds: float = 0.0


class Localizer:
    """Answers queries against one scene's memory (see the module docstring)."""

    def __init__(self, memory: Memory, encoder: Encoder, reranker: Reranker, segmenter: Segmenter,
                 config: LocalizerConfig = LocalizerConfig(), captioner: Captioner | None = None,
                 depth_noise: DepthNoise | None = None) -> None:
        if memory.index is None:
            raise LocalizeError(f"memory at {memory.directory} has no embedding index (built without an encoder)")
        enc_name = getattr(encoder, "name", None)
        if enc_name is not None and memory.index.model and enc_name != memory.index.model:
            raise LocalizeError(f"memory at {memory.directory} was indexed with {memory.index.model!r}, "
                                f"the query encoder is {enc_name!r}")
        self.memory = memory
        self.encoder = encoder
        self.reranker = reranker
        self.segmenter = segmenter
        self.captioner = captioner
        self.depth_noise = depth_noise
        self.config = config
        store = memory.store
        self._poses = store.poses()
        self._intrinsics = [store.intrinsics(i) for i in range(len(store))]
        self.last_trace = LocalizationTrace()

    @classmethod
    def from_perception(cls, memory: Memory, perception: Perception,
                        config: LocalizerConfig = LocalizerConfig()) -> Localizer:
        return cls(memory, perception.encoder, perception.reranker, perception.segmenter, config,
                   perception.captioner, perception.depth_noise)

    # ------------------------------------------------------------------ steps

    def _image(self, keyframe_id: int, backend: object) -> np.ndarray:
        return self.memory.images(keyframe_id, modality(backend))

    def _query_image(self, query: Query, backend: object) -> np.ndarray:
        return query_image(query, backend)

    def prompt(self, query: Query) -> str:
        return query_prompt(query, self.captioner)

    def query_vector(self, query: Query, prompt: str | None = None) -> np.ndarray:
        """Retrieval vector: the text embedding for text queries; for image queries the image's
        embedding, its caption's (``prompt``) text embedding, or their normalised sum
        (``config.image_retrieval``)."""
        if query.type != "image":
            return self.encoder.encode_text([query.text.strip()])[0]
        mode = self.config.image_retrieval
        vectors = []
        if mode in ("image", "both"):
            vectors.append(self.encoder.encode_images([self._query_image(query, self.encoder)])[0])
        if mode in ("caption", "both"):
            vectors.append(self.encoder.encode_text([self.prompt(query) if prompt is None else prompt])[0])
        return l2_normalize(np.sum(vectors, axis=0))[0]

    def _cloud(self, keyframe_id: int, prompt: str, score: float) -> ViewCloud | None:
        mask, _ = self.segmenter.segment(self._image(keyframe_id, self.segmenter), prompt)
        if mask is None or not mask.any():
            return None
        depth = self.memory.store.depth(keyframe_id)
        if self.depth_noise is not None:
            depth = self.depth_noise.perturb(depth, prompt)
        geo = self.config.geometry
        if not keep_view(depth, mask, geo):
            return None
        points = backproject(depth, mask, self.memory.store.K(keyframe_id), self._poses[keyframe_id],
                             geo.min_depth, geo.max_depth)
        if len(points) < self.config.min_points:
            return None
        return ViewCloud(keyframe_id, points, score)

    # ------------------------------------------------------------------ the pipeline

    def localize(self, query: Query) -> list[GoalCandidate]:
        """Goal candidates, best first (one per object instance found)."""
        start = time.perf_counter()
        cfg = self.config
        trace = LocalizationTrace(prompt=self.prompt(query))
        prompt = trace.prompt
        trace.retrieved = self.memory.index.search(self.query_vector(query, prompt), cfg.top_k, cfg.dedup)

        if cfg.rerank:
            scored = []
            for kf, cosine in trace.retrieved:
                yes, visibility = self.reranker.score(self._image(kf, self.reranker), prompt)
                scored.append(ScoredView(kf, cosine, yes, visibility))
            ranked = [(v.keyframe_id, v.visibility) for v in rerank(scored)]
        else:
            ranked = list(trace.retrieved)
        trace.kept = [kf for kf, _ in ranked]

        clouds: dict[int, ViewCloud | None] = {}
        views = []
        for kf, score in ranked:
            clouds[kf] = cloud = self._cloud(kf, prompt, score)
            if cloud is not None:
                views.append(cloud)
        trace.segmented = [v.keyframe_id for v in views]
        clusters = group_views(views, cfg.grouping)

        candidates = []
        for cluster in clusters:
            if not cfg.fusion:
                seed = cluster.views[0]
                centre = (seed.points.min(axis=0) + seed.points.max(axis=0)) / 2.0
                candidates.append(GoalCandidate(centre, seed.points, tuple(cluster.keyframe_ids), seed.score))
                continue
            # Neighbours are looked up around a robust centre of the instance (the median, which
            # bleeding masks do not drag far), then segmented like the retrieved views.
            target = np.median(cluster.points, axis=0)
            in_cluster = set(cluster.keyframe_ids)
            nbrs = neighbour_keyframes(target, self._poses, self._intrinsics, exclude=in_cluster,
                                       config=cfg.fusion_config)
            others = {v.keyframe_id: v for v in views if v.keyframe_id not in in_cluster}
            for kf in nbrs:
                if kf not in clouds:
                    clouds[kf] = self._cloud(kf, prompt, 0.0)
                    trace.neighbours.append(kf)
                if clouds[kf] is not None:
                    others.setdefault(kf, clouds[kf])
            candidates.append(fuse(cluster, list(others.values()), cfg.fusion_config))
        candidates = [replace(c, view_positions=self._poses[list(c.keyframe_ids), :3, 3].copy())
                      for c in candidates]
        trace.seconds = time.perf_counter() - start
        self.last_trace = trace
        return candidates
