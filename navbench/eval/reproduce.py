"""What a rerun of a recorded run must reproduce, and where.

- On every x86-64 CPU: each episode's outcome (success, stop called, skipped or failed), step count,
  collisions and action sequence, exactly.
- Float metrics (SPL, SoftSPL, distances, path length): exactly on a CPU of the same class as the recording
  machine (:func:`cpu_class`: vendor and the instruction sets numeric libraries dispatch on), within
  :data:`FLOAT_TOLERANCE` on another class. Short-vector lengths are summed in plain Python floats
  (``navbench.scene.pose.vector_length``) so BLAS kernels do not enter the metrics; the tolerance covers
  kernels that may still differ between classes.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from navbench.eval.provenance import PROVENANCE, cpu

FLOAT_TOLERANCE = 1e-6  # absolute: metres for lengths, a fraction for SPL / SoftSPL
EXACT_FIELDS = ("success", "stop_called", "skipped", "failed", "num_steps", "collisions")
FLOAT_FIELDS = ("spl", "soft_spl", "distance_to_goal", "geodesic_distance", "path_length")
# Flags that change which kernels numpy's BLAS, numpy, torch and oneDNN pick.
_CLASS_FLAGS = ("avx2", "fma", "avx512f", "avx512_vnni", "avx512_bf16", "avx512_fp16", "amx_tile")


def cpu_class(info: Mapping[str, Any] | None) -> str:
    """``vendor:flag+flag...`` of a provenance ``cpu`` entry (``""`` when it is missing or unreadable)."""
    model, flags = (info.get("model"), info.get("flags")) if isinstance(info, Mapping) else (None, None)
    if not isinstance(model, str) or not isinstance(flags, str):
        return ""
    have = set(flags.split())
    vendor = "amd" if "AMD" in model.upper() else "intel" if "INTEL" in model.upper() else model
    return f"{vendor}:{'+'.join(f for f in _CLASS_FLAGS if f in have)}"


def recorded_cpu_class(run_dir: str | Path) -> str:
    """The CPU class a run directory's provenance.json names (``""`` if it names none)."""
    try:
        return cpu_class(json.loads((Path(run_dir) / PROVENANCE).read_text()).get("cpu"))
    except (OSError, ValueError, AttributeError):
        return ""


def same_cpu_class(run_dir: str | Path) -> bool:
    """Whether this machine is of the CPU class that recorded ``run_dir`` (float metrics then match exactly)."""
    recorded = recorded_cpu_class(run_dir)
    return bool(recorded) and recorded == cpu_class(cpu())


def record_differences(got: Mapping[str, Any], ref: Mapping[str, Any], exact_floats: bool = True,
                       tolerance: float = FLOAT_TOLERANCE) -> list[str]:
    """``field got vs recorded`` for each way the rerun record ``got`` fails to reproduce ``ref``: a discrete
    field or the action sequence differs, or a float metric differs (at all with ``exact_floats``, else by
    more than ``tolerance``). Empty when it reproduces."""
    out = [f"{k} {got.get(k)!r} vs {ref.get(k)!r}" for k in EXACT_FIELDS if got.get(k) != ref.get(k)]
    acts, ref_acts = (got.get("trace") or {}).get("actions"), (ref.get("trace") or {}).get("actions")
    if acts != ref_acts:
        out.append(f"actions {acts!r} vs {ref_acts!r}")
    for k in FLOAT_FIELDS:
        a, b = got.get(k), ref.get(k)
        if a == b:
            continue
        close = isinstance(a, (int, float)) and isinstance(b, (int, float)) and \
            math.isclose(a, b, rel_tol=0.0, abs_tol=tolerance)
        if exact_floats or not close:
            out.append(f"{k} {a!r} vs {b!r}")
    return out
