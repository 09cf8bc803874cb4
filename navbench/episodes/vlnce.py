"""Read VLN-CE's episode files unchanged: R2R-CE (``R2R_VLNCE_v1-3``, ``R2R_VLNCE_v1-3_preprocessed``),
RxR-CE (``RxR_VLNCE_v0`` guide and follower files), their ``_gt`` files and RxR's text features.

Layouts, as jacobkrantz/VLN-CE reads them (``habitat_extensions/task.py``: ``VLNCEDatasetV1.from_json``,
``RxRVLNCEDatasetV1.from_json``, ``VLNExtendedEpisode``, ``ExtendedInstructionData``):

- ``{split}.json.gz`` (R2R): ``{"episodes": [...], "instruction_vocab": {"word_list": [...], ...}}``. An episode
  has ``episode_id`` and ``trajectory_id`` (ints, read as strings), ``scene_id``, ``start_position``,
  ``start_rotation`` ([x, y, z, w]), ``info``, ``goals`` (one ``{position, radius}``; null or absent in a test
  split), ``reference_path`` (the sparse viewpoints) and ``instruction``: ``{instruction_text,
  instruction_tokens}`` (habitat-lab v0.1.7 ``habitat/tasks/vln/vln.py: InstructionData``), the tokens
  indices into ``word_list``, padded with 0 in the preprocessed files.
- ``{split}_{role}.json.gz`` (RxR, role ``guide`` or ``follower``): the same episodes with string ids and no
  vocabulary; ``instruction`` also has ``instruction_id``, ``language``, ``annotator_id``, ``edit_distance``,
  ``timed_instruction`` and optional ``instruction_tokens``.
- ``{split}_gt.json.gz`` / ``{split}_{role}_gt.json.gz``: ``{episode_id: {"actions": [...], "forward_steps": n,
  "locations": [[x, y, z], ...]}}``; only ``locations`` is scored (``habitat_extensions/measures.py: NDTW``).
  The reference finds it beside the episodes (``TASK.NDTW.GT_PATH``); for RxR it merges the guide and the
  follower gt files into one table (``NDTW.__init__``), and so does :func:`read_vlnce`.
- RxR text features: ``text_features/rxr_{split}/{instruction_id:06}_{lang}_text_features.npz`` with key
  ``features``, zero-padded to (512, 768) float32 (``habitat_extensions/sensors.py: RxRInstructionSensor``;
  path from ``habitat_extensions/config/default.py``).

Every file is read bounded (:mod:`navbench.safeio`); a missing or malformed field is an
:class:`~navbench.episodes.types.EpisodeError` naming the file, the episode and the field.
"""

from __future__ import annotations

import io
import math
import re
import zipfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from navbench.episodes.io import READ_FAILURES, _JsonStream, file_split, load_dataset, read_failure
from navbench.episodes.types import Episode, EpisodeDataset, EpisodeError
from navbench.safeio import open_input, read_input

RXR_ROLES = ("guide", "follower")  # RxRVLNCEDatasetV1.annotation_roles
RXR_LANGUAGES = ("en-US", "en-IN", "hi-IN", "te-IN")  # RxRVLNCEDatasetV1.languages
RXR_FEATURES_SHAPE = (512, 768)  # RxRInstructionSensor's observation
MAX_GT_LOCATIONS = 100_000  # per episode; a real one has at most a few hundred
_LANG = re.compile(r"[a-z]{2,3}")


@dataclass
class VLNCEDataset(EpisodeDataset):
    """A VLN-CE split: its episodes (each with ``extra["instruction"]`` as in the file, ``extra["reference_path"]``
    and ``extra["trajectory_id"]`` when given), plus what the reference reads beside them.

    Attributes:
        flavor: ``"r2r"`` or ``"rxr"``.
        word_list: R2R's ``instruction_vocab.word_list`` (the tokens index it); None for RxR.
        gt_locations: ``episode_id -> locations`` from the ``_gt`` file(s), for the episodes kept; None when
            there is no gt file (nDTW and SDTW are then not scored).
        gt_files: the gt files read.
        split: the split name the file goes by (RxR's text features are filed under it).
        text_features_dir: RxR's ``text_features/`` directory when its features are to be read, else None.
    """
    flavor: str = "r2r"
    word_list: list[str] | None = None
    gt_locations: dict[str, list[list[float]]] | None = None
    gt_files: list[Path] = field(default_factory=list)
    split: str = ""
    text_features_dir: Path | None = None

    @property
    def task(self) -> str:
        return f"{self.flavor}_ce"

    @property
    def has_goals(self) -> bool:
        return bool(self.episodes) and all(e.goals for e in self.episodes)


def rxr_split_and_role(path: str | Path) -> tuple[str, str | None]:
    """``val_unseen_guide.json.gz`` -> ``("val_unseen", "guide")``; a name without a role: ``(name, None)``."""
    split = file_split(path)
    for role in RXR_ROLES:
        if split.endswith("_" + role):
            return split[: -len(role) - 1], role
    return split, None


def gt_paths_beside(path: str | Path) -> list[Path]:
    """Where the reference looks for the gt file(s) of an episode file: ``{split}_gt.json.gz`` beside it, and
    for an RxR ``{split}_{role}.json.gz`` both roles' ``{split}_{role}_gt.json.gz`` (those that exist)."""
    path = Path(path)
    split, role = rxr_split_and_role(path)
    if role is None:
        cands = [path.parent / f"{split}_gt.json.gz"]
    else:
        cands = [path.parent / f"{split}_{r}_gt.json.gz" for r in RXR_ROLES]
    return [c for c in cands if c.is_file()]


def read_vlnce(path: str | Path, select: Callable[..., list[Episode]] | None = None,
               gt: str | Path | Iterable[str | Path] | None = None, languages: Iterable[str] | None = None,
               find_gt: bool = True, cap: int | None = None) -> VLNCEDataset:
    """A VLN-CE episode file read as the reference reads it (module docstring), with its gt locations.

    Args:
        path: ``{split}.json.gz`` (R2R) or ``{split}_{role}.json.gz`` (RxR).
        select: as :func:`navbench.episodes.io.load_dataset` takes it.
        gt: the gt file(s); None: those beside ``path`` (:func:`gt_paths_beside`) when ``find_gt``.
        languages: keep only RxR episodes whose ``instruction.language`` is one of these (the reference's
            ``DATASET.LANGUAGES``); None keeps all.
    Raises:
        EpisodeError: one line naming the file and the field, for anything missing or malformed, and for an
            episode the gt file has no entry for (the reference's NDTW raises KeyError there).
    """
    path = Path(path)
    base = load_dataset(path, select, cap, require_goals=False)
    ds = VLNCEDataset(episodes=[], extra=dict(base.extra))
    vocab = ds.extra.get("instruction_vocab")
    ds.flavor = "rxr" if vocab is None and any(_is_rxr(e) for e in base.episodes) else "r2r"
    ds.split = rxr_split_and_role(path)[0] if ds.flavor == "rxr" else file_split(path)
    if ds.flavor == "r2r":
        ds.word_list = _word_list(vocab, path)
    wanted = None if languages is None else set(languages)
    for ep in base.episodes:
        _check_episode(ep, path, ds.flavor, ds.word_list)
        if wanted is not None and ep.extra["instruction"].get("language") not in wanted:
            continue
        ds.episodes.append(ep)
    if gt is None:
        gt_files = gt_paths_beside(path) if find_gt else []
    else:
        gt_files = [Path(gt)] if isinstance(gt, (str, Path)) else [Path(g) for g in gt]
    if gt_files:
        ids = {e.episode_id for e in ds.episodes}
        table: dict[str, list[list[float]]] = {}
        for f in gt_files:
            table.update(read_gt(f, ids, cap))
        for ep in ds.episodes:
            if ep.episode_id not in table:
                raise EpisodeError(f"{gt_files[0]}: no entry for episode {ep.episode_id} of {path.name}")
        ds.gt_locations, ds.gt_files = table, gt_files
    return ds


def _is_rxr(ep: Episode) -> bool:
    ins = ep.extra.get("instruction")
    return isinstance(ins, dict) and ("instruction_id" in ins or "language" in ins)


def _word_list(vocab: Any, path: Path) -> list[str]:
    if not isinstance(vocab, dict):
        raise EpisodeError(f"{path}: instruction_vocab: missing or not an object (R2R files carry the vocabulary)")
    words = vocab.get("word_list")
    if not isinstance(words, list) or not all(isinstance(w, str) for w in words):
        raise EpisodeError(f"{path}: instruction_vocab.word_list: missing or not a list of strings")
    return words


def _fail(path: Path, ep: Episode, what: str) -> EpisodeError:
    return EpisodeError(f"{path}: episode {ep.episode_id}: {what}"[:400])


def _check_episode(ep: Episode, path: Path, flavor: str, word_list: list[str] | None) -> None:
    """Validate (and normalise in place) the VLN fields of one episode."""
    if flavor == "r2r" and "trajectory_id" not in ep.extra:
        raise _fail(path, ep, "trajectory_id: missing")
    tid = ep.extra.get("trajectory_id")
    if tid is not None:
        if isinstance(tid, bool) or not isinstance(tid, (int, str)):
            raise _fail(path, ep, f"trajectory_id: must be an integer or a string, got {tid!r}")
        ep.extra["trajectory_id"] = str(tid)  # VLNCEDatasetV1.from_json casts it
    if len(ep.goals) > 1:
        raise _fail(path, ep, f"goals: VLN-CE episodes have one goal, got {len(ep.goals)}")
    ref = ep.extra.get("reference_path")
    if ref is not None:
        if not isinstance(ref, list) or not all(_is_vec3(p) for p in ref):
            raise _fail(path, ep, "reference_path: must be a list of [x, y, z] positions")
    ins = ep.extra.get("instruction")
    if not isinstance(ins, dict):
        raise _fail(path, ep, "instruction: missing or not an object")
    if not isinstance(ins.get("instruction_text"), str):
        raise _fail(path, ep, "instruction.instruction_text: missing or not a string")
    tokens = ins.get("instruction_tokens")
    if flavor == "r2r":
        if tokens is not None:
            if not isinstance(tokens, list) or not all(type(t) is int for t in tokens):
                raise _fail(path, ep, "instruction.instruction_tokens: must be a list of integers")
            n = len(word_list or ())
            if any(t < 0 or t >= n for t in tokens):
                raise _fail(path, ep, f"instruction.instruction_tokens: an index outside the vocabulary of {n} words")
    else:
        if tokens is not None and (not isinstance(tokens, list)
                                   or not all(isinstance(t, (str, int)) and not isinstance(t, bool) for t in tokens)):
            raise _fail(path, ep, "instruction.instruction_tokens: must be a list of tokens")
        iid = ins.get("instruction_id")
        if iid is not None and not (isinstance(iid, int) and not isinstance(iid, bool)
                                    or isinstance(iid, str) and iid.isdigit() and len(iid) <= 12):
            raise _fail(path, ep, f"instruction.instruction_id: must be an integer, got {iid!r}")
        lang = ins.get("language")
        if lang is not None and not isinstance(lang, str):
            raise _fail(path, ep, "instruction.language: must be a string")


def _is_vec3(p: Any) -> bool:
    return (isinstance(p, list) and len(p) == 3
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in p))


def read_gt(path: str | Path, episode_ids: set[str] | None = None,
            cap: int | None = None) -> dict[str, list[list[float]]]:
    """``episode_id -> locations`` from a ``_gt`` file, streamed: only the entries of ``episode_ids`` (all when
    None) are kept. Each kept entry must have ``locations``, a non-empty list of [x, y, z]."""
    path = Path(path)
    if not path.is_file():
        raise EpisodeError(f"{path}: file not found")
    out: dict[str, list[list[float]]] = {}
    try:
        with open_input(path, cap) as fh:
            stream = _JsonStream(fh)
            if stream.peek() != "{":
                raise EpisodeError(f"{path}: not a VLN-CE gt file (expected an object keyed by episode_id)")
            for key, value in stream.items():
                if episode_ids is not None and key not in episode_ids:
                    continue
                locs = value.get("locations") if isinstance(value, dict) else None
                if locs is None:
                    raise EpisodeError(f"{path}: episode {key[:40]}: locations: missing")
                if not isinstance(locs, list) or not locs or len(locs) > MAX_GT_LOCATIONS \
                        or not all(_is_vec3(p) for p in locs):
                    raise EpisodeError(f"{path}: episode {key[:40]}: locations: must be a non-empty list of [x, y, z]")
                out[key] = [[float(x) for x in p] for p in locs]
            if stream.peek():
                raise EpisodeError(f"{path}: extra data after the gt object")
    except EpisodeError:
        raise
    except READ_FAILURES as exc:
        raise read_failure(path, exc) from None
    except (RecursionError, ValueError) as exc:
        raise EpisodeError(f"{path}: malformed gt file ({type(exc).__name__})") from None
    return out


def instruction_observation(ep: Episode) -> dict[str, Any]:
    """habitat-lab v0.1.7's ``InstructionSensor`` value: ``{"text", "tokens", "trajectory_id"}`` (tokens as in
    the file, padding included; None when the file has none)."""
    ins = ep.extra["instruction"]
    return {"text": ins["instruction_text"], "tokens": ins.get("instruction_tokens"),
            "trajectory_id": ep.extra.get("trajectory_id")}


def text_features_path(features_dir: str | Path, split: str, instruction_id: Any, language: str) -> Path:
    """``{features_dir}/rxr_{split}/{id:06}_{lang}_text_features.npz`` (VLN-CE's default ``features_path``), from
    validated parts only: an integer id, a language whose prefix is 2-3 lowercase letters, a plain split name."""
    if isinstance(instruction_id, bool) or not str(instruction_id).isdigit():
        raise ValueError(f"instruction_id must be an integer, got {instruction_id!r}"[:200])
    lang = str(language).split("-")[0]
    if not _LANG.fullmatch(lang):
        raise ValueError(f"language must look like 'en-US', got {language!r}"[:200])
    if not re.fullmatch(r"[A-Za-z0-9_]{1,64}", split):
        raise ValueError(f"split must be a plain name, got {split!r}"[:200])
    return Path(features_dir) / f"rxr_{split}" / f"{int(instruction_id):06}_{lang}_text_features.npz"


def read_text_features(path: str | Path) -> np.ndarray:
    """An RxR text-features ``.npz`` zero-padded to (512, 768) float32, as ``RxRInstructionSensor`` returns it;
    EpisodeError for a missing, oversized or malformed file."""
    path = Path(path)
    limit = RXR_FEATURES_SHAPE[0] * RXR_FEATURES_SHAPE[1] * 8 + 4096  # float64 at most, plus the .npy header
    try:
        data = read_input(path, cap=limit * 2, gunzip=False)
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            info = zf.getinfo("features.npy")
            if info.file_size > limit:
                raise EpisodeError(f"{path}: features: larger than {RXR_FEATURES_SHAPE}")
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            feats = np.asarray(npz["features"])
    except EpisodeError:
        raise
    except FileNotFoundError:
        raise EpisodeError(f"{path}: file not found") from None
    except KeyError:
        raise EpisodeError(f"{path}: features: missing") from None
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise EpisodeError(f"{path}: not a text-features .npz ({type(exc).__name__})") from None
    if feats.ndim != 2 or feats.shape[0] > RXR_FEATURES_SHAPE[0] or feats.shape[1] > RXR_FEATURES_SHAPE[1] \
            or not np.issubdtype(feats.dtype, np.number):
        raise EpisodeError(f"{path}: features: must be numbers of shape at most {RXR_FEATURES_SHAPE}, "
                           f"got {feats.dtype} {feats.shape}")
    out = np.zeros(RXR_FEATURES_SHAPE, np.float32)
    out[: feats.shape[0], : feats.shape[1]] = feats
    return out
