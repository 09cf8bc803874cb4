"""Mesa's LLVM (behind OSMesa) stays out of the process's global symbols, so triton's own LLVM loads beside it.

Each check runs in a fresh interpreter: the order of imports is the point. The triton checks are slow-marked,
because triton (one ~900 MB wheel) is installed only by ``make test-slow``; without it they skip.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from navbench.paths import POLICIES_DIR
from navbench.render import gl_platform

ROOT = Path(__file__).resolve().parents[2]
osmesa_only = pytest.mark.skipif(gl_platform.bound_platform() != "osmesa", reason="renders on OSMesa only")
needs_triton = pytest.mark.skipif(importlib.util.find_spec("triton") is None,
                                  reason="triton is not installed (make test-slow installs it)")


def _python(code: str, *args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code), *args], capture_output=True, text=True,
                          timeout=timeout, env=env, cwd=ROOT)


# A rendered reset, then whatever the argument names; prints the depth mean before and a step's after.
ENV_THEN = """
    import sys
    import gymnasium as gym
    import navbench
    env = gym.make("navbench/PointNav-v0")
    obs, _ = env.reset(seed=0)
    print(float(obs["depth"].mean()))
    if sys.argv[1] == "triton":
        import triton  # noqa: F401
    elif sys.argv[1] == "optimizer":
        import torch
        p = torch.nn.Parameter(torch.zeros(3))
        opt = torch.optim.Adam([p], lr=0.1)
        (p - 1).pow(2).sum().backward()
        opt.step()
    obs, *_ = env.step(1)
    print(float(obs["depth"].mean()))
"""


@osmesa_only
def test_a_rendered_frame_leaves_no_llvm_symbol_in_the_global_scope():
    r = _python("""
        import ctypes
        import gymnasium as gym
        import navbench
        env = gym.make("navbench/PointNav-v0")
        env.reset(seed=0)
        maps = open("/proc/self/maps").read()
        print("libLLVM" in maps, hasattr(ctypes.CDLL(None), "LLVMContextCreate"))
    """)
    assert r.returncode == 0, r.stderr
    mapped, global_symbol = r.stdout.split()
    if mapped != "True":
        pytest.skip("this Mesa links no shared libLLVM")
    assert global_symbol == "False"  # PyOpenGL alone loads libOSMesa RTLD_GLOBAL and this is True


@pytest.mark.slow
@osmesa_only
@needs_triton
@pytest.mark.parametrize("then", ["triton", "optimizer"])
def test_triton_and_a_torch_optimizer_load_after_an_env_has_rendered(then):
    r = _python(ENV_THEN, then)
    assert r.returncode == 0, f"exit {r.returncode}: {r.stderr[-2000:]}"  # -11 (SIGSEGV) without the isolation
    before, after = map(float, r.stdout.split())
    assert before > 0 and after > 0


@pytest.mark.slow
@osmesa_only
@needs_triton
def test_an_env_renders_after_triton_is_imported():
    r = _python("import triton\n" + textwrap.dedent(ENV_THEN), "none")
    assert r.returncode == 0, r.stderr[-2000:]


@pytest.mark.slow
@osmesa_only
@needs_triton
def test_ppo_training_runs_and_resumes_with_triton_installed(tmp_path):
    checkpoint = POLICIES_DIR / "pointnav_navbench.pth"
    if not checkpoint.is_file():
        pytest.skip("no shipped PointNav checkpoint")
    common = ["--num-envs", "2", "--rollout-steps", "16", "--threads", "1", "--out", str(tmp_path / "run")]
    first = subprocess.run([sys.executable, "-m", "navbench", "train", "ppo", *common, "--updates", "2",
                            "--init", str(checkpoint)], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert first.returncode == 0, first.stderr[-2000:]
    resumed = subprocess.run([sys.executable, "-m", "navbench", "train", "ppo", *common, "--updates", "3", "--resume"],
                             capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert '"update": 3' in resumed.stdout


@pytest.mark.slow
@osmesa_only
@needs_triton
def test_triton_loads_after_pyopengl_bound_osmesa_before_navbench():
    # pyrender first loads libOSMesa RTLD_GLOBAL: navbench then has triton's library bind its own LLVM first
    r = _python("import warnings\nwarnings.simplefilter('error')\nimport pyrender\n" + textwrap.dedent(ENV_THEN),
                "optimizer")
    assert r.returncode == 0, f"exit {r.returncode}: {r.stderr[-2000:]}"
