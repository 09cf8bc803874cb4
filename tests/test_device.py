"""``--device`` and ``--precision``: parsed and resolved in one place, refused in one line where the device is
not there, recorded in provenance.json and reported (not refused) by compare. The CUDA paths run only
where torch sees a GPU (benchmarks/gpu_check.py measures them)."""

import json
import shutil

import numpy as np
import pytest
import torch

import navbench
from navbench.cli import main
from navbench.device import DeviceError, check_precision, parse_device, resolve_device, torch_dtype
from navbench.eval.provenance import PROVENANCE, recorded_run_on, run_protocol
from navbench.paths import RESULTS_DIR

CUDA = torch.cuda.is_available()
needs_cuda = pytest.mark.skipif(not CUDA, reason="torch sees no CUDA device")
no_cuda = pytest.mark.skipif(CUDA, reason="checks what a machine without CUDA says")


@pytest.mark.parametrize("text, want", [("auto", "auto"), ("cpu", "cpu"), ("CPU", "cpu"), ("cuda", "cuda"),
                                        (" cuda:3 ", "cuda:3")])
def test_parse_device_accepts_the_four_forms(text, want):
    assert parse_device(text) == want


@pytest.mark.parametrize("text", ["gpu", "cuda:", "cuda:-1", "cuda:x", "mps", "", "cpu:0"])
def test_parse_device_refuses_anything_else_in_one_line(text):
    with pytest.raises(DeviceError, match="choose from auto, cpu, cuda, cuda:N") as exc:
        parse_device(text)
    assert "\n" not in str(exc.value) and isinstance(exc.value, ValueError)


def test_cpu_resolves_without_looking_and_auto_follows_torch():
    assert resolve_device("cpu") == "cpu"
    assert resolve_device("auto") == (f"cuda:{torch.cuda.current_device()}" if CUDA else "cpu")


@no_cuda
@pytest.mark.parametrize("text", ["cuda", "cuda:0", "cuda:7"])
def test_a_cuda_device_that_is_not_there_is_one_line(text):
    with pytest.raises(DeviceError, match=rf"device '{text}' is not available .*use --device cpu or auto") as exc:
        resolve_device(text)
    assert "\n" not in str(exc.value)


@needs_cuda
def test_a_cuda_index_past_the_last_gpu_is_one_line():
    n = torch.cuda.device_count()
    assert resolve_device("cuda") == f"cuda:{torch.cuda.current_device()}"
    with pytest.raises(DeviceError, match=f"torch sees {n} CUDA device"):
        resolve_device(f"cuda:{n}")


def test_precision():
    assert [torch_dtype(p) for p in ("fp32", "bf16", "fp16")] == [torch.float32, torch.bfloat16, torch.float16]
    with pytest.raises(DeviceError, match="choose from fp32, bf16, fp16"):
        check_precision("int8")


@no_cuda
@pytest.mark.parametrize("command", [["run", "--task", "pointnav", "--limit", "1"], ["bench", "--seconds", "0.1"],
                                     ["localize", "--limit", "1"]])
def test_cli_refuses_cuda_without_it_in_one_line_exit_2(command, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([*command, "--device", "cuda"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("navbench: error: device 'cuda' is not available") and "\n" not in err
    assert not (tmp_path / "runs").exists()  # refused before a run directory is made


def test_cli_refuses_a_malformed_device_with_usage_exit_2(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--device", "gpu0"])
    assert exc.value.code == 2
    assert "--device: device 'gpu0': choose from auto, cpu, cuda, cuda:N" in capsys.readouterr().err


@no_cuda
def test_evaluate_refuses_cuda_without_it(tmp_path):
    with pytest.raises(ValueError, match="device 'cuda:0' is not available"):
        navbench.evaluate("oracle", task="pointnav", limit=1, runs_dir=tmp_path, device="cuda:0")
    with pytest.raises(ValueError, match="precision 'fp8'"):
        navbench.evaluate("oracle", task="pointnav", limit=1, runs_dir=tmp_path, precision="fp8")


def test_auto_here_runs_where_torch_says_and_provenance_records_where(tmp_path):
    out = tmp_path / "run"
    navbench.evaluate("oracle", task="pointnav", limit=1, out=out, device="auto")
    run_on = json.loads((out / PROVENANCE).read_text())["run_on"]
    device = resolve_device("auto")
    assert run_on["device"] == device and run_on["precision"] == "fp32"
    assert run_on["gl_platform"] in ("osmesa", "egl") and run_on["device_name"]
    config = json.loads((out / "config.json").read_text())
    # the CPU and fp32 are config.json's defaults, left out so that earlier runs read the same
    assert ("device" in config) == (device != "cpu") and "precision" not in config


def test_a_plugin_that_takes_a_device_gets_the_runs():
    from types import SimpleNamespace

    from navbench.agents.plugins import build

    class Agent:
        def __init__(self, device="cuda:5"):
            self.device = device

        def reset(self):
            pass

        def act(self, observations):
            return 0

    assert build(Agent, SimpleNamespace(device="cpu", task="pointnav"), {}).agent.device == "cpu"
    assert build(Agent, SimpleNamespace(device="cpu"), {"device": "cuda:1"}).agent.device == "cuda:1"


def test_compare_reports_devices_without_refusing(tmp_path, capsys):
    runs = RESULTS_DIR / "runs" / "objectnav" / "val_unseen"
    base, other = tmp_path / "memory", tmp_path / "memory_gpu"
    shutil.copytree(runs / "memory", base)
    shutil.copytree(runs / "memory", other)
    proto = run_protocol(base)
    (other / PROVENANCE).write_text(json.dumps({"protocol": proto, "run_on": {
        "device": "cuda:0", "device_name": "a GPU", "precision": "bf16", "gl_platform": "egl"}}))
    assert recorded_run_on(base) == {"device": "cpu", "precision": "fp32"}
    assert main(["compare", str(base), str(other), "--metric", "spl"]) == 0
    out = capsys.readouterr().out
    assert "run on cpu fp32 vs cuda:0 bf16: the same protocol" in out
    assert main(["compare", str(base), str(other), "--metric", "spl", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["run_on"]["other"] == {"device": "cuda:0", "precision": "bf16"} and "other_protocol_id" not in res


# --------------------------------------------------------------------------------------------- CUDA
@needs_cuda
def test_policy_on_cuda_acts_as_on_the_cpu():
    from navbench.agents.registry import DEFAULT_CHECKPOINT
    from navbench.policy.checkpoint import load_checkpoint
    from navbench.policy.net import InferenceConfig, PointNavAgentPolicy

    rng = np.random.default_rng(0)
    depth = rng.random((8, 224, 224, 1), dtype=np.float32)
    goal = np.stack([rng.uniform(0.5, 5, 8), rng.uniform(-3, 3, 8)], 1).astype(np.float32)
    got = {}
    for device in ("cpu", "cuda"):
        policy = PointNavAgentPolicy(load_checkpoint(DEFAULT_CHECKPOINT), 8, InferenceConfig(decoding="argmax"),
                                     device=device)
        got[device] = [policy.act(depth, goal) for _ in range(3)]
    agree = np.mean([np.mean(a == b) for a, b in zip(got["cpu"], got["cuda"])])
    assert agree >= 0.9, agree  # argmax flips only where two logits lie within float rounding


# ------------------------------------------------------------------------------------- gpu_check.py
GPU_CHECK = RESULTS_DIR.parent / "benchmarks" / "gpu_check.py"


def _gpu_check(*args, timeout=600):
    import os
    import subprocess
    import sys
    env = {**os.environ, "PYTHONPATH": str(RESULTS_DIR.parent)}
    return subprocess.run([sys.executable, str(GPU_CHECK), *args], capture_output=True, text=True, env=env,
                          timeout=timeout)


@no_cuda
def test_gpu_check_without_cuda_is_one_line_and_exit_0():
    res = _gpu_check()
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines() == [f"gpu_check: skipped, torch {torch.__version__} sees no CUDA device"]


@pytest.mark.slow
def test_gpu_check_runs_every_check_with_the_cpu_on_both_sides():
    # every code path of the script, on the CPU: each comparison must then be exact
    res = _gpu_check("--device", "cpu", "--episodes", "2", "--seconds", "0.2")
    assert res.returncode == 0, res.stdout + res.stderr
    table = [line for line in res.stdout.splitlines() if line.startswith("| ")]
    assert "| policy logits, max abs diff vs CPU | 0.00e+00 |" in res.stdout and "FAIL" not in res.stdout
    assert any("PointNav val, 2 episodes" in line and "2 of 2" in line for line in table)
    assert any(line.startswith("| policy frames/s on cpu, batch 64 |") for line in table)
    assert res.stdout.rstrip().endswith("0 check(s) failed")
