"""Vision-and-language navigation in continuous environments (VLN-CE): R2R-CE and RxR-CE as jacobkrantz/VLN-CE
defines and scores them (``habitat_extensions/config/vlnce_task.yaml``, ``rxr_vlnce_english_task.yaml``,
``habitat_extensions/measures.py``, ``habitat_extensions/sensors.py``; habitat-lab v0.1.7
``habitat/tasks/vln/vln.py``).

The goal observation is ``instruction``, habitat-lab's ``InstructionSensor`` value: ``text`` (the instruction),
``tokens`` (``instruction_tokens`` as in the file, padding included; a file without tokens gives none),
``trajectory_id``; for RxR also ``language`` and, where the text features exist beside the episodes
(``text_features/rxr_{split}/``), ``features``: ``RxRInstructionSensor``'s (512, 768) float32 array. The goal
point is not observed. Episodes are read by :func:`navbench.episodes.vlnce.read_vlnce` (the ``_gt`` file found
beside them); the measures are :func:`navbench.metrics.vlnce_episode_metrics`'s.
"""

from __future__ import annotations

import string
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces

from navbench.episodes.types import EpisodeDataset
from navbench.metrics import VLNCE_METRIC_KEYS, VLNCE_SUCCESS_DISTANCE
from navbench.tasks.base import NAV_ACTIONS, GoalContext, GoalSensor, Task

if TYPE_CHECKING:
    from navbench.episodes.vlnce import VLNCEDataset

GYM_ID = "navbench/VLNCE-v0"
RXR_ACTIONS = (*NAV_ACTIONS, "LOOK_UP", "LOOK_DOWN")
MAX_TEXT = 20_000  # characters of one instruction (RxR's longest are a few thousand)


def features_dir(dataset: EpisodeDataset) -> Path | None:
    """Where an RxR split's text features are: ``text_features/`` beside the split directories (VLN-CE's
    ``data/datasets/RxR_VLNCE_v0/text_features/rxr_{split}/``), when that directory exists."""
    return getattr(dataset, "text_features_dir", None)


def _charset(dataset: EpisodeDataset) -> str:
    chars = set(string.printable)
    for ep in dataset.episodes:
        chars.update(ep.extra["instruction"]["instruction_text"])
        chars.update(str(ep.extra.get("trajectory_id") or ""))
        chars.update(str(ep.extra["instruction"].get("language") or ""))
    return "".join(sorted(chars))


def _int_tokens(ep) -> list[int]:
    tokens = ep.extra["instruction"].get("instruction_tokens") or []
    return tokens if all(type(t) is int for t in tokens) else []  # RxR's may be word strings: not given as ids


def token_length(dataset: EpisodeDataset) -> int:
    """The tokens' length in the observation: the longest episode's (R2R-CE's files pad them all alike)."""
    return max((len(_int_tokens(ep)) for ep in dataset.episodes), default=0)


def instruction_space(dataset: EpisodeDataset, config: Any) -> spaces.Dict:
    charset = _charset(dataset)
    text = spaces.Text(MAX_TEXT, min_length=0, charset=charset)
    out: dict[str, spaces.Space] = {"text": text, "trajectory_id": spaces.Text(64, min_length=0, charset=charset)}
    n = token_length(dataset)
    words = getattr(dataset, "word_list", None)
    if n:
        hi = len(words) - 1 if words else np.iinfo(np.int64).max
        out["tokens"] = spaces.Box(0, hi, (n,), np.int64)
    if getattr(dataset, "flavor", "r2r") == "rxr":
        out["language"] = spaces.Text(16, min_length=0, charset=charset)
        if features_dir(dataset) is not None:
            big = np.finfo(np.float32).max
            out["features"] = spaces.Box(-big, big, (512, 768), np.float32)
    return spaces.Dict(out)


def instruction(ctx: GoalContext) -> dict[str, Any]:
    """The episode's ``instruction`` observation (module docstring)."""
    ep = ctx.episode
    assert ep is not None  # the env's episode, set by reset()
    ins = ep.extra["instruction"]
    out: dict[str, Any] = {"text": ins["instruction_text"], "trajectory_id": str(ep.extra.get("trajectory_id") or "")}
    n = token_length(ctx.dataset)
    if n:
        tokens = np.zeros(n, np.int64)
        raw = _int_tokens(ep)
        tokens[: len(raw)] = raw
        out["tokens"] = tokens
    if getattr(ctx.dataset, "flavor", "r2r") == "rxr":
        out["language"] = str(ins.get("language") or "")
        fdir = features_dir(ctx.dataset)
        if fdir is not None:
            from navbench.episodes.vlnce import read_text_features, text_features_path
            split = getattr(ctx.dataset, "split", "")
            out["features"] = read_text_features(text_features_path(fdir, split, ins.get("instruction_id"),
                                                                    str(ins.get("language") or "")))
    return out


def read_r2r(path: str | Path, select=None, gt: str | Path | None = None) -> VLNCEDataset:
    """An R2R-CE ``{split}.json.gz`` with its ``{split}_gt.json.gz`` beside it when there is one (or ``gt``)."""
    from navbench.episodes.vlnce import read_vlnce
    return read_vlnce(path, select, gt=gt)


def read_rxr(path: str | Path, select=None, gt: str | Path | None = None) -> VLNCEDataset:
    """An RxR-CE ``{split}_{role}.json.gz`` (every language; the challenge scores all three), with both roles'
    gt files beside it (or ``gt``) and the text features when ``../text_features/`` exists."""
    from navbench.episodes.vlnce import read_vlnce
    ds = read_vlnce(path, select, gt=gt)
    fdir = Path(path).parent.parent / "text_features"
    ds.text_features_dir = fdir if fdir.is_dir() else None
    return ds


def episode_files(path: str | Path, gt: str | Path | None = None) -> list[Path]:
    """The episode file (and any ``content/`` files) and the gt file(s) scored against: ``gt``, else those
    beside it (:func:`navbench.episodes.vlnce.gt_paths_beside`)."""
    from navbench.episodes.instance_imagenav import split_files
    from navbench.episodes.vlnce import gt_paths_beside
    return [*split_files(Path(path)), *([Path(gt)] if gt is not None else gt_paths_beside(path))]


_COMMON: dict[str, Any] = dict(
    gym_id=GYM_ID,
    goal_sensors=(GoalSensor("instruction", instruction_space, instruction, per_episode=True),),
    measures=VLNCE_METRIC_KEYS,
    distance_to="POINT",
    success_distance=VLNCE_SUCCESS_DISTANCE,
    max_steps=500,
    env_class="navbench.env.vlnce:VLNCEEnv",
    episode_files=episode_files,
    default_agent="vln_memory",
    # the VLN-CE README's table: TL, NE, OS, SR, SPL; nDTW and SDTW as the RxR-Habitat leaderboard lists them
    columns=(("TL", "path_length", 1), ("NE", "distance_to_goal", 1), ("OS", "oracle_success", 100),
             ("SR", "success", 100), ("SPL", "spl", 100), ("nDTW", "ndtw", 100), ("SDTW", "sdtw", 100)),
)

# {instruction}: which instructions, for each task's rules
_RULES = ("The agent is given {instruction} describing a route, and no goal position. An episode succeeds when the "
          "agent calls STOP within {{sd}} m geodesic distance of the goal point at the route's end, and ends after at "
          "most {{max_steps}} actions. SPL weighs success by the shortest path's length over the longer of it and the "
          "length walked; oracle success counts an episode that came within {{sd}} m of the end at any step; nDTW "
          "scores how closely the path walked follows the instruction's reference path (dynamic time warping, "
          "normalised as VLN-CE does), and SDTW is nDTW counted on successful episodes only.")

R2R_TASK = Task(
    name="r2r_ce",
    display_name="R2R-CE",
    rules=_RULES.format(instruction="a Room-to-Room instruction in English"),
    title="follow a Room-to-Room instruction in continuous space (VLN-CE R2R-CE; scored within 3.0 m)",
    reference="jacobkrantz/VLN-CE habitat_extensions/config/vlnce_task.yaml, habitat_extensions/measures.py",
    episode_format="VLN-CE-v1",
    read_episodes=read_r2r,
    actions=NAV_ACTIONS,
    splits=("val",),  # navbench generate vlnce: R2R-style routes through the bundled val houses
    default_split="val",
    env_config="r2r-ce",
    **_COMMON,
)

RXR_TASK = Task(
    name="rxr_ce",
    display_name="RxR-CE",
    rules=_RULES.format(instruction="a Room-across-Room instruction (English, Hindi or Telugu)"),
    title="follow a Room-across-Room instruction in continuous space (VLN-CE RxR-CE; scored within 3.0 m)",
    reference="jacobkrantz/VLN-CE habitat_extensions/config/rxr_vlnce_english_task.yaml, "
              "habitat_extensions/measures.py",
    episode_format="RxR-VLN-CE-v1",
    read_episodes=read_rxr,
    actions=RXR_ACTIONS,
    splits=(),  # RxR-CE's files are the user's (--episodes)
    env_config="rxr-ce",
    **_COMMON,
)
