"""Gymnasium's vector API over the navbench envs: ``make_vec`` in "sync" and "async" modes, with
Gymnasium's next-step autoreset and each sub-env on its own seeded episodes.

The async case runs in a subprocess with a timeout, so a hang fails the test instead of CI. Its parent
first renders with an env of its own: worker processes forked after a GL context exists are the case
that used to hang.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

SCRIPT = textwrap.dedent("""
    import json, sys
    import gymnasium as gym, numpy as np
    import navbench
    from navbench.env.config import EnvConfig
    mode = sys.argv[1]
    cfg = EnvConfig(width=64, height=64)
    if mode == "async":  # a GL context in the parent before the workers fork
        solo = gym.make("navbench/ObjectNav-v0", config=cfg)
        solo.reset(seed=0)
        solo.step(2)
    envs = gym.make_vec("navbench/ObjectNav-v0", num_envs=2, vectorization_mode=mode, config=cfg)
    first = list(map(str, envs.reset(seed=3)[1]["episode_id"]))
    again = list(map(str, envs.reset(seed=3)[1]["episode_id"]))
    obs, _, terminated, _, info = envs.step(np.array([0, 2]))  # env 0 calls STOP: its episode ends
    ended = list(map(bool, terminated))
    obs, _, terminated, _, info = envs.step(np.array([2, 2]))  # env 0 autoresets into its next episode
    after = list(map(str, info["episode_id"]))
    steps = list(map(int, info["num_steps"]))
    shape = list(obs["rgb"].shape)
    envs.close()
    print(json.dumps({"first": first, "again": again, "ended": ended, "after": after, "steps": steps,
                      "shape": shape}))
""")


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_make_vec(mode):
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, mode], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=240)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the script and its env workers
        proc.communicate()
        pytest.fail(f"make_vec(vectorization_mode={mode!r}) hung")
    assert proc.returncode == 0, stderr[-2000:]
    out = json.loads(stdout.strip().splitlines()[-1])
    assert out["first"] == out["again"], "reset(seed=) must pick the same episodes"
    assert out["first"][0] != out["first"][1], "each sub-env draws its own episodes"
    assert out["ended"] == [True, False]
    assert out["steps"] == [0, 2], "env 0 restarted (step 0 of its next episode), env 1 kept going"
    assert out["after"][1] == out["first"][1]
    assert out["shape"] == [2, 64, 64, 3]
