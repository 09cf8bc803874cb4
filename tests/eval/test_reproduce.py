"""What a rerun must reproduce (navbench.eval.reproduce), and that the BLAS kernel a CPU picks does not enter it."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from navbench.eval.provenance import cpu
from navbench.eval.reproduce import FLOAT_TOLERANCE, cpu_class, record_differences, recorded_cpu_class, same_cpu_class
from navbench.eval.runner import read_records
from navbench.paths import RESULTS_DIR

ORACLE = RESULTS_DIR / "runs" / "objectnav" / "val_unseen" / "oracle"
# The first two episodes of that run, in one process (the CLI's worker pool would add seconds of start-up).
RUN_ORACLE = """import json, sys
from navbench.agents.registry import AGENTS
from navbench.eval.runner import RunConfig, run
from navbench.paths import RESULTS_DIR, SCENES_DIR, split_file
cfg = json.loads((RESULTS_DIR / "runs/objectnav/val_unseen/oracle/config.json").read_text())
cfg = RunConfig(**{k: v for k, v in cfg.items() if k in RunConfig.__dataclass_fields__})
cfg.episodes, cfg.scene_dir, cfg.limit = str(split_file("objectnav", "val_unseen")), str(SCENES_DIR), 2
run(cfg, AGENTS["oracle"], sys.argv[1])
"""


def _record(**kw):
    base = {"success": 1.0, "stop_called": True, "num_steps": 3, "collisions": 0, "spl": 0.5, "soft_spl": 0.5,
            "distance_to_goal": 0.1, "geodesic_distance": 2.0, "path_length": 4.0, "trace": {"actions": "110"}}
    return {**base, **kw}


def test_discrete_fields_and_actions_must_match_exactly_floats_to_the_class_rule():
    ref = _record()
    assert record_differences(_record(), ref) == []
    assert record_differences(_record(num_steps=4), ref, exact_floats=False) == ["num_steps 4 vs 3"]
    assert record_differences(_record(trace={"actions": "120"}), ref, exact_floats=False)[0].startswith("actions")
    assert record_differences(_record(success=0.0, spl=0.0), ref, exact_floats=False)[0].startswith("success")
    near = _record(spl=0.5 + FLOAT_TOLERANCE / 2, path_length=4.0 + 1e-12)
    assert record_differences(near, ref, exact_floats=False) == []
    assert [d.split()[0] for d in record_differences(near, ref, exact_floats=True)] == ["spl", "path_length"]
    assert record_differences(_record(spl=0.5 + 2 * FLOAT_TOLERANCE), ref, exact_floats=False)[0].startswith("spl")
    assert record_differences(_record(geodesic_distance=None), ref, exact_floats=False)  # None is not a number


def test_cpu_class_names_vendor_and_the_dispatching_instruction_sets():
    amd = {"model": "AMD EPYC 9R14", "flags": "avx avx2 fma avx512f avx512_bf16 sse4_2"}
    intel = {"model": "Intel(R) Xeon(R) Platinum", "flags": "avx2 fma avx512f avx512_vnni"}
    assert cpu_class(amd) == "amd:avx2+fma+avx512f+avx512_bf16"
    assert cpu_class(intel) == "intel:avx2+fma+avx512f+avx512_vnni"
    assert cpu_class(None) == "" and cpu_class({"model": 3}) == ""
    assert recorded_cpu_class(ORACLE).startswith("amd:") and cpu_class(cpu())


@pytest.mark.slow
def test_records_do_not_depend_on_the_blas_kernel(tmp_path):
    """OpenBLAS picks its kernels by CPU (its AVX-512 one fuses multiply-adds in ddot, its Zen/Haswell one does
    not); OPENBLAS_CORETYPE forces one. The oracle's second val_unseen episode came out 2e-6 apart in SPL
    between the two while numpy's norm measured its steps and its start yaw; it must not depend on them."""
    flags = cpu().get("flags", "").split()
    kernels = ("Haswell", "SkylakeX") if "avx512f" in flags else ("Prescott", "Haswell")
    ref = {r["episode_id"]: r for r in read_records(ORACLE / "episodes.jsonl")}
    runs = {}
    for kernel in kernels:
        out = tmp_path / kernel
        subprocess.run([sys.executable, "-c", RUN_ORACLE, str(out)], check=True,
                       env={**os.environ, "OPENBLAS_CORETYPE": kernel})
        runs[kernel] = read_records(out / "episodes.jsonl")
        assert len(runs[kernel]) == 2
    for a, b in zip(*runs.values()):
        assert record_differences(a, b, exact_floats=True) == [], a["episode_id"]
        assert record_differences(a, ref[a["episode_id"]], exact_floats=same_cpu_class(ORACLE)) == [], a["episode_id"]
