"""Save and load PointNav policy checkpoints in habitat-baselines' layout.

On disk a checkpoint is ``torch.save({"state_dict": {...}, "config": {...}})``: the layout
habitat-baselines (0.3) writes and VLFM's ``load_pointnav_policy`` reads, with keys relative to the
policy (``net.…``, ``action_distribution.…``, ``critic.…``). The loader also accepts keys prefixed
``actor_critic.`` (older habitat-baselines trainers save the PPO agent, whose state_dict nests the
policy under that name) and a bare state_dict.

We write fp16 tensors (a 17 MB file instead of 34 MB) and load them back as fp32.

Loading uses ``torch.load(weights_only=True)``, which never runs code from the file. habitat's
checkpoints pickle their config as OmegaConf objects, which weights_only refuses; for those the
loader retries with every global the file names replaced by an inert placeholder class (the real
one is never imported or called; torch still refuses modules such as os/subprocess outright), keeps
the tensors, and drops the config. Our own checkpoints store a plain dict config.
"""

from __future__ import annotations

import json
import os
import pickle
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from navbench.paths import ROOT
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig
from navbench.safeio import write_private

HABITAT_PREFIX = "actor_critic."
_NORMALIZER = "net.visual_encoder.running_mean_and_var."


class CheckpointError(ValueError):
    """A checkpoint file is missing, unreadable or does not fit the policy; the message names the file."""


@dataclass
class CheckpointData:
    state_dict: dict[str, torch.Tensor]  # keys relative to the policy, tensors as stored
    config: dict[str, Any] | None  # None when the file's config could not be read safely


def _json_scalar(value: object) -> object:
    """Paths become strings and numpy scalars Python numbers; anything else is refused."""
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} value {value!r} is not JSON-like")


TRAIN_STATE_FORMAT = "navbench-train-state/1"


def _encode(obj: Any, tensors: dict[str, torch.Tensor]) -> Any:
    """``obj`` as JSON, its tensors moved to ``tensors`` (and named there); dict keys and tuples kept."""
    if isinstance(obj, torch.Tensor):
        name = str(len(tensors))
        tensors[name] = obj.detach().cpu()
        return {"tensor": name}
    if isinstance(obj, Mapping):
        return {"dict": [[_encode(k, tensors), _encode(v, tensors)] for k, v in obj.items()]}
    if isinstance(obj, tuple):
        return {"tuple": [_encode(v, tensors) for v in obj]}
    if isinstance(obj, list):
        return [_encode(v, tensors) for v in obj]
    if obj is None or isinstance(obj, (bool, int, float, str)):
        return obj
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot store a {type(obj).__name__} in a training state")


def _decode(obj: Any, tensors: Mapping[str, torch.Tensor]) -> Any:
    if isinstance(obj, list):
        return [_decode(v, tensors) for v in obj]
    if isinstance(obj, dict):
        (kind, value), = obj.items()
        if kind == "tensor":
            return tensors[value]
        if kind == "tuple":
            return tuple(_decode(v, tensors) for v in value)
        if kind == "dict":
            return {_decode(k, tensors): _decode(v, tensors) for k, v in value}
        raise ValueError(f"unknown entry {kind!r}")
    return obj


def save_train_state(path: Path, state: dict[str, Any]) -> None:
    """Write a resumable training state (weights, optimizer, counters) in a format that cannot run code
    when read: ``torch.save`` of tensors only, plus the rest as a JSON string. A run killed mid-write
    leaves the previous state whole (a fresh temporary file, never a symlink, is renamed over ``path``)."""
    tensors: dict[str, torch.Tensor] = {}
    meta = json.dumps(_encode(state, tensors))
    write_private(Path(path), lambda fh: torch.save({"format": TRAIN_STATE_FORMAT, "state": meta,
                                                      "tensors": tensors}, fh), fsync=False)


def read_train_state(path: Path) -> dict[str, Any]:
    """The state :func:`save_train_state` wrote, read with ``torch.load(weights_only=True)``: a crafted
    file runs no code and fails as one line (:class:`CheckpointError`) naming it."""
    path = Path(path)
    try:
        obj = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # weights_only refusals, truncation, garbage: many types
        raise CheckpointError(f"{path}: not a training state navbench wrote ({_reason(e)}); start over "
                              f"without --resume or remove it") from None
    try:
        if not isinstance(obj, dict) or obj.get("format") != TRAIN_STATE_FORMAT:
            raise ValueError(f"no {TRAIN_STATE_FORMAT!r} format tag")
        tensors = obj["tensors"]
        if not isinstance(tensors, dict) or not all(isinstance(t, torch.Tensor) for t in tensors.values()):
            raise ValueError("its tensors are not a dict of tensors")
        state = _decode(json.loads(obj["state"]), tensors)
        if not isinstance(state, dict):
            raise ValueError("its state is not a dict")
        return state
    except (ValueError, KeyError, TypeError, AttributeError, RecursionError) as e:
        raise CheckpointError(f"{path}: not a training state navbench wrote ({type(e).__name__}: {e}); start "
                              f"over without --resume or remove it"[:400]) from None


def load_train_state(path: Path, policy: torch.nn.Module, opt: torch.optim.Optimizer, counter: str
                     ) -> tuple[int, int, float]:
    """Restore ``policy`` and ``opt`` from a state :func:`save_train_state` wrote; returns (``state[counter]``,
    frames, wall seconds): where the run stopped."""
    st = read_train_state(path)
    try:
        policy.load_state_dict(st["policy"])
        opt.load_state_dict(st["optimizer"])
        return int(st[counter]), int(st["frames"]), float(st["wall_s"])
    except (KeyError, TypeError, ValueError, RuntimeError) as e:
        raise CheckpointError(f"{path}: training state does not fit this run ({type(e).__name__}: "
                              f"{str(e).splitlines()[0] if str(e) else ''})"[:400]) from None


def save_checkpoint(
    path: str | Path, policy: PointNavResNetPolicy, config: Mapping[str, Any], fp16: bool = True
) -> Path:
    """Write ``{"state_dict": ..., "config": dict(config)}``; floating tensors as fp16 when ``fp16``.

    ``config`` must be JSON-like (dicts, lists, str, numbers, bools, None; paths and numpy scalars
    are converted) so that it loads back under ``weights_only=True``.
    """
    path = Path(path)
    try:
        config = json.loads(json.dumps(dict(config), default=_json_scalar))
    except (TypeError, ValueError) as e:
        raise CheckpointError(f"{path}: config must be JSON-like to be loadable safely ({e})") from None
    state = {
        k: (v.detach().half() if fp16 and v.is_floating_point() else v.detach()).cpu().clone()
        for k, v in policy.state_dict().items()
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"state_dict": state, "config": config}, path)
    return path


class _Placeholder:
    """Stands in for any class a checkpoint names but weights_only does not allow (e.g. OmegaConf)."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        pass

    def __setstate__(self, state: object) -> None:
        self.__dict__["_placeholder_state"] = state  # data only: read back by plain_config, never called


def plain_config(obj: Any, depth: int = 0) -> Any:
    """A checkpoint's config as plain data: dicts, lists and scalars as they are, and an OmegaConf node read
    through its placeholder's pickled state (a DictConfig's or ListConfig's ``_content``, a value node's
    ``_val``); anything else None."""
    if depth > 64:
        return None
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    if isinstance(obj, Mapping):
        return {str(k): plain_config(v, depth + 1) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain_config(v, depth + 1) for v in obj]
    state = getattr(obj, "__dict__", {}).get("_placeholder_state") if isinstance(obj, _Placeholder) else None
    if isinstance(state, tuple) and len(state) == 2:  # (dict state, slots state)
        state = state[0]
    if isinstance(state, Mapping):
        if "_content" in state:
            return plain_config(state["_content"], depth + 1)
        if "_val" in state:
            return plain_config(state["_val"], depth + 1)
    return None


def read_checkpoint_config(path: str | Path) -> dict[str, Any]:
    """The configuration a checkpoint holds (``ckpt["config"]``) as plain data, a habitat-baselines
    checkpoint's OmegaConf config included (read with weights_only, its classes as inert placeholders)."""
    given, path = path, checkpoint_path(path)
    if not path.is_file():
        raise CheckpointError(f"{given}: no such checkpoint file")
    obj, _ = _torch_load(path)
    config = plain_config(obj.get("config")) if isinstance(obj, Mapping) else None
    if not isinstance(config, dict):
        raise CheckpointError(f"{path}: holds no readable 'config'")
    return config


def _placeholder_globals(path: Path) -> list[tuple[type, str]]:
    names = torch.serialization.get_unsafe_globals_in_checkpoint(str(path))
    return [(type(name.rsplit(".", 1)[-1], (_Placeholder,), {}), name) for name in names]


def _reason(e: BaseException) -> str:
    """The informative line of a torch.load error (its weights_only errors start with boilerplate)."""
    boilerplate = ("Weights only load failed", "(1)", "(2)", "Check the documentation")
    lines = [line.strip() for line in str(e).splitlines() if line.strip()]
    useful = [line.removeprefix("WeightsUnpickler error:").strip() for line in lines
              if not line.startswith(boilerplate)]
    return (useful or lines or [type(e).__name__])[0]


def _torch_load(path: Path) -> tuple[Any, bool]:
    """Load with weights_only=True; returns (object, whether placeholders replaced foreign classes)."""
    try:
        return torch.load(path, map_location="cpu", weights_only=True), False
    except pickle.UnpicklingError as e:
        refused = _reason(e)
        if not zipfile.is_zipfile(path):
            raise CheckpointError(f"{path}: not a PyTorch checkpoint ({refused})") from None
    except Exception as e:  # torch.load raises many types on garbage (RuntimeError, EOFError, IndexError...)
        raise CheckpointError(f"{path}: not a PyTorch checkpoint ({_reason(e)})") from None
    try:
        with torch.serialization.safe_globals(_placeholder_globals(path)):
            return torch.load(path, map_location="cpu", weights_only=True), True
    except Exception as e:
        raise CheckpointError(
            f"{path}: refused by torch.load(weights_only=True) ({refused}) and still unreadable with"
            f" placeholder classes ({_reason(e)})"
        ) from None


def checkpoint_path(path: str | Path) -> Path:
    """``path`` as given, or, when it is relative and not found here, the bundled file it names
    (``policies/pointnav_2h.pth`` from any directory, also with an installed wheel)."""
    path = Path(path)
    if path.is_file() or path.is_absolute() or not (ROOT / path).is_file():
        return path
    return ROOT / path


def read_checkpoint(path: str | Path) -> CheckpointData:
    """Read a checkpoint's state_dict (``actor_critic.`` prefix removed) and config, without a policy."""
    given, path = path, checkpoint_path(path)
    if not path.is_file():
        raise CheckpointError(f"{given}: no such checkpoint file")
    obj, stubbed = _torch_load(path)
    if not isinstance(obj, Mapping):
        raise CheckpointError(f"{path}: holds a {type(obj).__name__}, not a checkpoint dict or state_dict")
    config: dict[str, Any] | None = None
    if isinstance(obj.get("state_dict"), Mapping):
        state = obj["state_dict"]
        raw_config = obj.get("config")
        config = raw_config if isinstance(raw_config, dict) and not stubbed else None
    elif obj and all(isinstance(v, torch.Tensor) for v in obj.values()):
        state = obj
    else:
        keys = ", ".join(map(str, list(obj)[:5]))
        raise CheckpointError(f"{path}: has no 'state_dict' and is not a state_dict (keys: {keys})")
    bad = [k for k, v in state.items() if not isinstance(v, torch.Tensor)]
    if bad:
        raise CheckpointError(f"{path}: state_dict entry {bad[0]!r} is not a tensor")
    state_dict = {(k[len(HABITAT_PREFIX) :] if k.startswith(HABITAT_PREFIX) else k): v for k, v in state.items()}
    return CheckpointData(state_dict=state_dict, config=config)


def _ranked(t: Any, rank: int) -> torch.Tensor | None:
    """``t`` when it is a tensor of at least ``rank`` dimensions, else None."""
    return t if isinstance(t, torch.Tensor) and t.dim() >= rank else None


def infer_net_config(state_dict: Mapping[str, torch.Tensor]) -> PolicyNetConfig:
    """The architecture a state_dict was saved from, as far as the shapes tell.

    Hidden size, LSTM depth, base planes, action count and whether the running normaliser exists
    are read off the tensors; group count follows habitat's base_planes // 2 and the input size
    stays 224x224 (a checkpoint for another size then fails on ``net.visual_fc.1.weight``).
    """
    defaults = PolicyNetConfig()
    # a tensor of the wrong rank tells nothing: the default stands and the shape check names the tensor
    critic = _ranked(state_dict.get("critic.fc.weight"), 2)
    actor = _ranked(state_dict.get("action_distribution.linear.weight"), 2)
    conv1 = _ranked(state_dict.get("net.visual_encoder.backbone.conv1.0.weight"), 1)
    layers = sum(1 for k in state_dict if k.startswith("net.state_encoder.rnn.weight_ih_l"))
    base = int(conv1.shape[0]) if conv1 is not None else defaults.base_planes
    return PolicyNetConfig(
        hidden_size=int(critic.shape[1]) if critic is not None else defaults.hidden_size,
        num_layers=layers or defaults.num_layers,
        base_planes=base,
        ngroups=max(base // 2, 1),
        num_actions=int(actor.shape[0]) if actor is not None else defaults.num_actions,
        normalize_visual_inputs=any(k.startswith(_NORMALIZER) for k in state_dict),
    )


def _names(keys: list[str], limit: int = 3) -> str:
    more = f" (+{len(keys) - limit} more)" if len(keys) > limit else ""
    return ", ".join(keys[:limit]) + more


def load_checkpoint(path: str | Path, policy: PointNavResNetPolicy | None = None) -> PointNavResNetPolicy:
    """Load weights into ``policy`` (built from the checkpoint's shapes when None); returns it in eval mode.

    fp16 tensors are converted to the policy's dtype. Any missing or unexpected key, or a shape
    mismatch, a float/integer dtype mismatch or a non-finite weight, raises :class:`CheckpointError` naming
    the file and the first offending tensors; nothing is copied into ``policy`` in that case.
    """
    path = Path(path)
    data = read_checkpoint(path)
    built_here = policy is None
    if policy is None:
        # On the meta device: skips the random (orthogonal, QR-based: seconds on 2 cores) init that
        # the checkpoint's tensors replace anyway; they are assigned as the parameters below.
        with torch.device("meta"):
            policy = PointNavResNetPolicy(infer_net_config(data.state_dict))
    own = policy.state_dict()
    missing = [k for k in own if k not in data.state_dict]
    unexpected = [k for k in data.state_dict if k not in own]
    if missing:
        raise CheckpointError(f"{path}: missing {len(missing)} tensor(s): {_names(missing)}")
    if unexpected:
        raise CheckpointError(f"{path}: {len(unexpected)} unexpected tensor(s): {_names(unexpected)}")
    mismatched = [
        f"{k} {tuple(v.shape)} vs policy {tuple(own[k].shape)}"
        for k, v in data.state_dict.items()
        if tuple(v.shape) != tuple(own[k].shape)
    ]
    if mismatched:
        raise CheckpointError(f"{path}: shape mismatch: {_names(mismatched, 2)}")
    wrong = [f"{k} {v.dtype} vs policy {own[k].dtype}" for k, v in data.state_dict.items()
             if v.is_floating_point() != own[k].is_floating_point() or v.is_complex()]
    if wrong:
        raise CheckpointError(f"{path}: dtype mismatch: {_names(wrong, 2)}")
    bad = [k for k, v in data.state_dict.items() if v.is_floating_point() and not torch.isfinite(v).all()]
    if bad:
        raise CheckpointError(f"{path}: non-finite values in {_names(bad)}")
    converted = {k: v.to(own[k].dtype) for k, v in data.state_dict.items()}
    try:
        policy.load_state_dict(converted, strict=True, assign=built_here)
    except RuntimeError as exc:  # anything the checks above missed, still one line naming the file
        raise CheckpointError(f"{path}: does not fit the policy ({str(exc).splitlines()[-1].strip()})") from None
    return policy.eval()
