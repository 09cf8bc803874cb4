"""Where torch work runs (``--device``) and at what precision the real perception models run (``--precision``).

``auto`` is CUDA when torch sees a GPU, else the CPU; ``cuda`` is the current CUDA device; ``cuda:N`` the
N-th. :func:`resolve_device` turns a choice into the device a run uses (``"cpu"`` or ``"cuda:N"``), and a
device that is not there into one ValueError line. torch is imported only when a device is resolved.

    >>> parse_device("CUDA:1"), parse_device("auto")
    ('cuda:1', 'auto')
"""

from __future__ import annotations

import re

__all__ = ["DEVICES", "PRECISIONS", "DeviceError", "check_precision", "device_arg", "device_name", "parse_device",
           "resolve_device", "torch_dtype"]

DEVICES = "auto, cpu, cuda, cuda:N"
PRECISIONS = ("fp32", "bf16", "fp16")
_DEVICE = re.compile(r"^(auto|cpu|cuda(:\d+)?)$")


class DeviceError(ValueError):
    """A device that cannot be parsed or is not on this machine; the message is one line."""


def parse_device(text: str) -> str:
    """``text`` as one of ``auto``, ``cpu``, ``cuda``, ``cuda:N`` (lower case), without looking for it."""
    norm = str(text).strip().lower()
    if not _DEVICE.match(norm):
        raise DeviceError(f"device {text!r}: choose from {DEVICES}")
    return norm


def device_arg(text: str) -> str:
    """An argparse ``type`` for ``--device``: :func:`parse_device`, its error as argparse's (usage, exit 2);
    whether the device is there is checked when the command runs (:func:`resolve_device`)."""
    import argparse
    try:
        return parse_device(text)
    except DeviceError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def resolve_device(text: str = "cpu") -> str:
    """The device a run with ``--device text`` uses: ``"cpu"`` or ``"cuda:N"``. A CUDA device torch does
    not see (no GPU, a CPU build of torch, an index past the last GPU) is a :class:`DeviceError`."""
    choice = parse_device(text)
    if choice == "cpu":
        return "cpu"
    import torch

    available = torch.cuda.is_available()
    if choice == "auto":
        return f"cuda:{torch.cuda.current_device()}" if available else "cpu"
    if not available:
        why = "this torch is a CPU build" if torch.version.cuda is None else "torch sees no CUDA device"
        raise DeviceError(f"device {text!r} is not available ({why}, torch {torch.__version__}); "
                          f"use --device cpu or auto")
    if choice == "cuda":
        return f"cuda:{torch.cuda.current_device()}"
    index, count = int(choice.split(":")[1]), torch.cuda.device_count()
    if index >= count:
        raise DeviceError(f"device {text!r} is not available (torch sees {count} CUDA device(s): cuda:0"
                          + (f"..cuda:{count - 1})" if count > 1 else ")"))
    return choice


def device_name(device: str) -> str:
    """What ``device`` (resolved) is, for provenance: the GPU's name for ``cuda:N``, else ``"cpu"``."""
    if not device.startswith("cuda"):
        return "cpu"
    import torch
    return torch.cuda.get_device_name(torch.device(device))


def check_precision(precision: str) -> str:
    """``precision`` if it is one of :data:`PRECISIONS`, else a one-line :class:`DeviceError`."""
    if precision not in PRECISIONS:
        raise DeviceError(f"precision {precision!r}: choose from {', '.join(PRECISIONS)}")
    return precision


def torch_dtype(precision: str):
    """The torch dtype of ``precision`` (``fp32`` float32, ``bf16`` bfloat16, ``fp16`` float16)."""
    import torch
    return {"fp32": torch.float32, "bf16": torch.bfloat16, "fp16": torch.float16}[check_precision(precision)]
