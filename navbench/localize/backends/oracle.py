"""Oracle perception: the localiser's backends computed from the renderer's instance ids.

They implement the same protocols as the real models, over the keyframes' *instance-id images*
(``modality = "instance_ids"``: the pipeline hands them the stored id image where a real backend gets
RGB), so retrieval, re-ranking, grouping and fusion all run their real code paths:

* :class:`OracleEncoder`: image embedding = L2-normalised visible-pixel fractions over a fixed
  vocabulary: one slot per category of :data:`~navbench.localize.describe.VOCABULARY`, one per
  (category, colour) pair, and a structure/background slot (weight 0.1, so a view of bare walls is
  not a zero vector, yet walls and floor do not make every pair of views look alike). Text embedding
  = one-hot of the category the text names (synonyms resolved; for a description, its head noun),
  plus its (category, colour) slot when the text names a colour - an ideal SigLIP sees colours.
  FAISS inner product then ranks views by visible pixels of the queried category (and colour). The
  colour slots also keep the 0.9 cosine de-duplication meaningful: with category slots alone, views
  of two different chairs would count as near-identical.
* :class:`OracleReranker`: "yes" when the instances the query grounds to cover at least
  ``min_fraction`` of the view; visibility grows with that fraction.
* :class:`OracleSegmenter`: the exact mask of the largest visible grounded instance (for a category,
  the largest instance of it, as SAM's top mask would be; for a unique description, that instance).
* :class:`OracleCaptioner`: for image queries, describes the instance in the centre of the query's id
  image with :func:`~navbench.localize.describe.describe_unique`, which the others then ground.

Grounding is :func:`navbench.localize.describe.ground`: category, colour, room and "next to" words
matched against the annotations - perfect grounding, not a lookup of the generated answer. A goal
name outside that vocabulary (an open-vocabulary HM3D-OVON name such as "tv", a GOAT-Bench
description) is grounded from the task's own goals instead: :func:`teach` gives every backend of a
stack the instances the episode's goals name (by goal position, see :func:`instances_at`), and those
take precedence over the fixed vocabulary for that query. Categories of a scan that the vocabulary
lacks get encoder slots of their own after the fixed ones (the encoder's ``name`` then says so, so a
memory built without them is not reused).

:class:`NoiseProfile` degrades the oracle like real perception: masks dilated/eroded (bleeding onto
the background, or shrunk), multiplicative depth noise, views without the target reported as a
confident detection of another object (``wrong_view_prob``, with the segmenter then returning that
object's mask), and missed detections. Every random draw is seeded from the profile's seed, the
query text and the CRC of the image, so it is deterministic per (query, keyframe) and independent of
call order.
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from navbench.localize.backends.base import BackendError
from navbench.localize.describe import VOCABULARY, describe_unique, ground, parse
from navbench.memory.index import l2_normalize
from navbench.scene.annotations import ObjectAnnotation
from navbench.scene.procedural.furniture import COLOURS

ORACLE_NAME = "oracle-v2"
COLOUR_NAMES: tuple[str, ...] = tuple(COLOURS)
STRUCTURE_WEIGHT = 0.1  # of the structure/background slot, see the module docstring
N_SLOTS = len(VOCABULARY) * (1 + len(COLOUR_NAMES)) + 1
STRUCTURE_SLOT = N_SLOTS - 1


def category_slot(category: str) -> int:
    return VOCABULARY.index(category)


def colour_slot(category: str, colour: str) -> int:
    return len(VOCABULARY) + VOCABULARY.index(category) * len(COLOUR_NAMES) + COLOUR_NAMES.index(colour)


@dataclass(frozen=True)
class NoiseProfile:
    mask_dilate_px: int = 0  # grow masks by this many pixels (bleeding onto the background)
    mask_erode_px: int = 0  # shrink masks (applied after dilation)
    depth_noise_std: float = 0.0  # per-pixel multiplicative depth noise, relative (0.05 = 5 %)
    wrong_view_prob: float = 0.0  # a view without the target is reported as a confident detection
    miss_prob: float = 0.0  # a detection is missed (no mask)
    seed: int = 0

    def __post_init__(self) -> None:
        if self.mask_dilate_px < 0 or self.mask_erode_px < 0 or self.depth_noise_std < 0:
            raise ValueError(f"noise magnitudes must be >= 0, got {self}")
        if not (0.0 <= self.wrong_view_prob <= 1.0 and 0.0 <= self.miss_prob <= 1.0):
            raise ValueError(f"noise probabilities must lie in [0, 1], got {self}")

    @property
    def is_noiseless(self) -> bool:
        return self == NoiseProfile(seed=self.seed)


NOISE_PROFILES: dict[str, NoiseProfile] = {
    "none": NoiseProfile(),
    "default": NoiseProfile(mask_dilate_px=3, depth_noise_std=0.05, wrong_view_prob=0.2, miss_prob=0.1),
    "heavy": NoiseProfile(mask_dilate_px=6, depth_noise_std=0.10, wrong_view_prob=0.4, miss_prob=0.25),
}


def noise_profile(name: str) -> NoiseProfile:
    if name not in NOISE_PROFILES:
        raise ValueError(f"unknown noise profile {name!r} (choose from {', '.join(NOISE_PROFILES)})")
    return NOISE_PROFILES[name]


def _rng(profile: NoiseProfile, purpose: str, query: str, image: np.ndarray) -> np.random.Generator:
    """A generator determined by (seed, purpose, query, image content) only."""
    image = np.ascontiguousarray(image)
    return np.random.default_rng([profile.seed, zlib.crc32(purpose.encode()), zlib.crc32(query.encode()),
                                  zlib.crc32(image.tobytes()), image.shape[0], image.shape[1]])


def _check_ids(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image)
    if image.ndim != 2 or not np.issubdtype(image.dtype, np.integer):
        raise BackendError(f"oracle backends take HxW integer instance-id images, got shape {image.shape} "
                           f"dtype {image.dtype}")
    return image


def centre_instance(ids: np.ndarray, window: float = 0.2) -> int | None:
    """The object in the centre of an id image: the id covering most of the central ``window`` of the
    image, else the object pixel nearest the centre; None if the image shows no object."""
    ids = _check_ids(ids)
    h, w = ids.shape
    dh, dw = max(1, round(h * window / 2)), max(1, round(w * window / 2))
    centre = ids[h // 2 - dh:h // 2 + dh, w // 2 - dw:w // 2 + dw]
    obj = centre[centre >= 0]
    if obj.size:
        values, counts = np.unique(obj, return_counts=True)
        return int(values[np.argmax(counts)])
    rows, cols = np.nonzero(ids >= 0)
    if rows.size == 0:
        return None
    k = int(np.argmin((rows - (h - 1) / 2) ** 2 + (cols - (w - 1) / 2) ** 2))
    return int(ids[rows[k], cols[k]])


def instances_at(objects: Mapping[int, ObjectAnnotation], positions: Sequence[Sequence[float]],
                 margin: float = 0.25) -> tuple[int, ...]:
    """Ids of the annotated instances that goal ``positions`` name: for each position (an object's
    AABB centre, as Habitat's ObjectNav/OVON/GOAT generators write goals), the instance whose AABB,
    grown by ``margin`` metres, contains it, nearest centre first; positions inside none name nothing."""
    out: list[int] = []
    for p in positions:
        p = np.asarray(p, dtype=np.float64).reshape(3)
        best, best_d = None, np.inf
        for o in objects.values():
            if np.all(p >= np.asarray(o.aabb_min) - margin) and np.all(p <= np.asarray(o.aabb_max) + margin):
                d = float(np.linalg.norm(o.center - p))
                if d < best_d:
                    best, best_d = o.id, d
        if best is not None and best not in out:
            out.append(best)
    return tuple(sorted(out))


def teach(perception, query: str, positions: Sequence[Sequence[float]]) -> tuple[int, ...]:
    """Tell each oracle backend of ``perception`` (a :class:`~navbench.localize.pipeline.Perception`)
    which instances ``query`` names: those at the goal ``positions``. Real backends are left alone.
    Returns the instance ids (empty when no goal lies on an annotated instance)."""
    ids: tuple[int, ...] = ()
    for backend in (perception.encoder, perception.reranker, perception.segmenter):
        if hasattr(backend, "teach"):
            ids = instances_at(backend.objects, positions)
            if ids:
                backend.teach(query, ids)
    return ids


class _Grounding:
    """Query text -> instance ids, cached (queries repeat across the views of one localisation);
    targets taught by :func:`teach` come first."""

    def __init__(self, objects: Mapping[int, ObjectAnnotation]) -> None:
        self.objects = dict(objects)
        self.taught: dict[str, np.ndarray] = {}
        self._ground = lru_cache(maxsize=1024)(lambda q: np.asarray(ground(q, self.objects), dtype=np.int64))

    def teach(self, query: str, ids: Sequence[int]) -> None:
        self.taught[query] = np.asarray(sorted(ids), dtype=np.int64)

    def targets(self, query: str) -> np.ndarray:
        taught = self.taught.get(query)
        return taught if taught is not None else self._ground(query)


class OracleEncoder:
    """:class:`~navbench.localize.backends.base.Encoder` over instance-id images (see module docstring)."""

    name = ORACLE_NAME
    modality = "instance_ids"

    def __init__(self, objects: Mapping[int, ObjectAnnotation]) -> None:
        self.objects = dict(objects)
        max_id = max([o.id for o in objects.values()], default=0)
        # Categories outside the vocabulary (a scan's own names) get slots after the fixed ones.
        self.extra_categories = sorted({o.category for o in objects.values() if o.category not in VOCABULARY})
        self._extra = {c: N_SLOTS + k for k, c in enumerate(self.extra_categories)}
        # Lookup tables: id + 1 -> category slot and -> (category, colour) slot (index 0 is id -1).
        self._cat = np.full(max_id + 2, STRUCTURE_SLOT, dtype=np.int64)
        self._cc = np.full(max_id + 2, STRUCTURE_SLOT, dtype=np.int64)
        for o in objects.values():
            if o.category in VOCABULARY:
                self._cat[o.id + 1] = category_slot(o.category)
                if o.colour in COLOUR_NAMES:
                    self._cc[o.id + 1] = colour_slot(o.category, o.colour)
            else:
                self._cat[o.id + 1] = self._cc[o.id + 1] = self._extra[o.category]
        self.dim = N_SLOTS + len(self.extra_categories)
        if self.extra_categories:
            names = zlib.crc32("\n".join(self.extra_categories).encode())
            self.name = f"{ORACLE_NAME}+{len(self.extra_categories)}-{names:08x}"
        self._taught: dict[str, list[int]] = {}

    def teach(self, query: str, ids: Sequence[int]) -> None:
        """Embed ``query`` as the categories of instances ``ids`` (see :func:`teach`)."""
        self._taught[query] = [int(self._cat[i + 1]) for i in ids if 0 <= i + 1 < len(self._cat)]

    def _slot_of_name(self, text: str) -> int | None:
        name = " ".join(text.lower().replace("_", " ").split())
        for c, slot in self._extra.items():
            if c.replace("_", " ") == name:
                return slot
        return None

    def encode_images(self, images: Sequence[np.ndarray]) -> np.ndarray:
        if len(images) == 0:
            raise BackendError("nothing to encode: the input list is empty")
        out = np.zeros((len(images), self.dim), dtype=np.float32)
        for row, ids in enumerate(images):
            ids = _check_ids(ids).ravel().astype(np.int64) + 1
            ids[(ids < 0) | (ids >= len(self._cat))] = 0
            counts = np.bincount(self._cat[ids], minlength=self.dim)
            counts += np.bincount(self._cc[ids], minlength=self.dim)
            counts[STRUCTURE_SLOT] = (self._cat[ids] == STRUCTURE_SLOT).sum()  # counted once, not twice
            v = counts / max(ids.size, 1)
            v[STRUCTURE_SLOT] *= STRUCTURE_WEIGHT
            out[row] = v
        return l2_normalize(out, "oracle image embedding")

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        if len(texts) == 0:
            raise BackendError("nothing to encode: the input list is empty")
        out = np.zeros((len(texts), self.dim), dtype=np.float32)
        for row, text in enumerate(texts):
            desc = parse(text)
            if desc is None:
                slots = self._taught.get(text) or [s for s in [self._slot_of_name(text)] if s is not None]
                if not slots:
                    raise BackendError(f"oracle encoder: query {text!r} names no known object category "
                                       f"and no taught goal instance")
                out[row, sorted(set(slots))] = 1.0
                continue
            out[row, category_slot(desc.category)] = 1.0
            if desc.colour is not None:
                out[row, colour_slot(desc.category, desc.colour)] = 1.0
        return l2_normalize(out, "oracle text embedding")


class OracleReranker:
    """:class:`~navbench.localize.backends.base.Reranker` from visible pixels of the grounded instances."""

    modality = "instance_ids"

    def __init__(self, objects: Mapping[int, ObjectAnnotation], noise: NoiseProfile = NoiseProfile(),
                 min_fraction: float = 0.002, full_fraction: float = 0.2) -> None:
        self._grounding = _Grounding(objects)
        self.objects = self._grounding.objects
        self.teach = self._grounding.teach
        self.noise = noise
        self.min_fraction = min_fraction  # "yes" from this share of the image (~100 px at 224 x 224)
        self.full_fraction = full_fraction  # visibility 1.0 from this share

    def score(self, image: np.ndarray, query: str) -> tuple[bool, float]:
        ids = _check_ids(image)
        fraction = float(np.isin(ids, self._grounding.targets(query)).mean())
        if fraction >= self.min_fraction:
            return True, min(1.0, fraction / self.full_fraction)
        if _hallucinates(self.noise, query, ids, self._grounding.targets(query)):
            return True, 1.0  # a confident wrong detection ranks first
        return False, min(1.0, fraction / self.full_fraction)


def _hallucinates(noise: NoiseProfile, query: str, ids: np.ndarray, targets: np.ndarray) -> bool:
    """Whether this (query, view) is one where perception mistakes another object for the target."""
    if noise.wrong_view_prob <= 0.0 or not ((ids >= 0) & ~np.isin(ids, targets)).any():
        return False
    return bool(_rng(noise, "wrong", query, ids).random() < noise.wrong_view_prob)


def _largest(ids: np.ndarray, candidates: np.ndarray) -> int | None:
    sel = ids[np.isin(ids, candidates)] if candidates is not None else ids[ids >= 0]
    if sel.size == 0:
        return None
    values, counts = np.unique(sel, return_counts=True)
    return int(values[np.argmax(counts)])


class OracleSegmenter:
    """:class:`~navbench.localize.backends.base.Segmenter`: exact masks from instance ids, plus noise."""

    modality = "instance_ids"

    def __init__(self, objects: Mapping[int, ObjectAnnotation], noise: NoiseProfile = NoiseProfile(),
                 min_fraction: float = 0.002) -> None:
        self._grounding = _Grounding(objects)
        self.objects = self._grounding.objects
        self.teach = self._grounding.teach
        self.noise = noise
        self.min_fraction = min_fraction

    def segment(self, image: np.ndarray, query: str) -> tuple[np.ndarray | None, float]:
        ids = _check_ids(image)
        targets = self._grounding.targets(query)
        instance = _largest(ids, targets)
        if instance is not None and (ids == instance).mean() < self.min_fraction:
            instance = None
        score = 1.0
        if instance is None:
            if not _hallucinates(self.noise, query, ids, targets):
                return None, 0.0
            instance = _largest(ids, None if targets.size == 0 else
                                np.setdiff1d(np.unique(ids[ids >= 0]), targets))
            if instance is None:
                return None, 0.0
        if self.noise.miss_prob > 0 and _rng(self.noise, "miss", query, ids).random() < self.noise.miss_prob:
            return None, 0.0
        mask = ids == instance
        mask = _morph(mask, self.noise.mask_dilate_px, cv2.dilate)
        mask = _morph(mask, self.noise.mask_erode_px, cv2.erode)
        return (mask if mask.any() else None), score


def _morph(mask: np.ndarray, radius: int, op) -> np.ndarray:
    if radius <= 0:
        return mask
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    return op(mask.astype(np.uint8), kernel).astype(bool)


class OracleCaptioner:
    """Image query -> text: a unique description of the instance in the centre of the query id image."""

    modality = "instance_ids"

    def __init__(self, objects: Mapping[int, ObjectAnnotation]) -> None:
        self.objects = dict(objects)

    def describe(self, image: np.ndarray) -> str:
        instance = centre_instance(image)
        if instance is None or instance not in self.objects:
            raise BackendError("oracle captioner: the query image shows no annotated object in its centre")
        obj = self.objects[instance]
        desc = describe_unique(obj, self.objects)
        # No unique description: the most specific one, which a real captioner would also give.
        return desc.text() if desc is not None else f"the {obj.colour} {obj.category.replace('_', ' ')}"


class OracleDepthNoise:
    """Multiplicative per-pixel depth noise, deterministic per (query, depth image)."""

    def __init__(self, noise: NoiseProfile) -> None:
        self.noise = noise

    def perturb(self, depth: np.ndarray, query: str) -> np.ndarray:
        if self.noise.depth_noise_std <= 0:
            return depth
        rng = _rng(self.noise, "depth", query, depth)
        noisy = depth * (1.0 + self.noise.depth_noise_std * rng.standard_normal(depth.shape)).astype(np.float32)
        return np.where(depth > 0, noisy, 0.0).astype(np.float32)
