"""Training throughput: habitat-baselines' DD-PPO trainer on navbench's habitat_sim against ``navbench train ppo``.

Run in the habitat virtualenv (``pip install -e ".[habitat]" -e compat/habitat-sim``), from the checkout root::

    PYOPENGL_PLATFORM=osmesa python benchmarks/habitat_ddppo.py                     # both, 2 envs x 32 steps, 4 updates
    PYOPENGL_PLATFORM=osmesa python benchmarks/habitat_ddppo.py --which habitat --steps 128
    PYOPENGL_PLATFORM=osmesa python benchmarks/habitat_ddppo.py --navbench-python .venv/bin/python  # own venv

Both train a PointNav policy on the bundled ``train_large`` episodes with the same settings: ``--envs`` environments,
rollouts of ``--steps`` steps, 2 PPO epochs of 2 minibatches, habitat's ResNet-18 encoder (32 base planes, 16
groups) on one 224x224 depth image (hfov 79, 0.5-5 m, camera 0.88 m up) with the point goal, a 2-layer 512 LSTM,
the visual encoder frozen (navbench's PPO always freezes it; habitat-baselines' ``train_encoder=False``, or
``--train-encoder`` for its default), and the body and actions of navbench's env (radius 0.18 m, 0.25 m forward,
30 degree turns, no sliding).

- habitat-baselines: ``python -m habitat_baselines.run`` with the config below (written to a temporary directory):
  habitat-lab's ``pointnav_habitat_test`` benchmark config and habitat-baselines' structured defaults, trainer
  ``ddppo`` (one rank: DD-PPO's trainer with world size 1), its VectorEnv with one process per environment.
- navbench: ``python -m navbench train ppo`` from ``policies/pointnav_navbench.pth`` (weights do not change the cost
  of a step), ``--critic-warmup 0`` so every update trains the actor as habitat-baselines' does.

Each run's rate is taken between the end of its first update and the end of its last (start-up and the first
update excluded): environment steps per second (wall) and CPU seconds per step of the whole process tree (trainer
and environment workers, from /proc; less sensitive to other load on a shared machine).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SPLIT = ROOT / "episodes" / "pointnav" / "train_large" / "train_large.json.gz"
SCENES = ROOT / "envs"
INIT = ROOT / "policies" / "pointnav_navbench.pth"

# habitat-baselines ships no yaml in its wheel; this is its DD-PPO PointNav recipe (habitat-lab's
# habitat-baselines/habitat_baselines/config/pointnav/ddppo_pointnav.yaml) at the settings above
CONFIG = """\
# @package _global_
defaults:
  - /benchmark/nav/pointnav: pointnav_habitat_test
  - /habitat_baselines: habitat_baselines_rl_config_base
  - _self_

habitat:
  environment:
    max_episode_steps: 500
  dataset:
    data_path: {split}
    scenes_dir: {scenes}
    split: train_large
  simulator:
    forward_step_size: 0.25
    turn_angle: 30
    habitat_sim_v0:
      allow_sliding: false
    agents:
      main_agent:
        height: 0.88
        radius: 0.18
        sim_sensors:
          depth_sensor:
            width: 224
            height: 224
            hfov: 79
            position: [0.0, 0.88, 0.0]
            min_depth: 0.5
            max_depth: 5.0

habitat_baselines:
  trainer_name: ddppo
  verbose: false
  num_environments: {envs}
  num_updates: {updates}
  total_num_steps: -1.0
  num_checkpoints: 1
  log_interval: 1
  force_torch_single_threaded: true
  tensorboard_dir: {out}/tb
  checkpoint_folder: {out}/checkpoints
  video_dir: {out}/video
  log_file: {out}/train.log
  rl:
    policy:
      main_agent:
        name: PointNavResNetPolicy
    ppo:
      clip_param: 0.2
      ppo_epoch: 2
      num_mini_batch: 2
      value_loss_coef: 0.5
      entropy_coef: 0.01
      lr: 2.5e-4
      eps: 1.0e-5
      max_grad_norm: 0.2
      num_steps: {steps}
      use_gae: true
      gamma: 0.99
      tau: 0.95
      hidden_size: 512
    ddppo:
      sync_frac: 0.6
      distrib_backend: GLOO
      pretrained: false
      pretrained_encoder: false
      train_encoder: {train_encoder}
      reset_critic: true
      backbone: resnet18
      rnn_type: LSTM
      num_recurrent_layers: 2
"""


def tree_cpu(pid: int) -> float:
    """CPU seconds (user + system) of ``pid`` and its live descendants, from /proc."""
    tick = os.sysconf("SC_CLK_TCK")
    parent, cpu = {}, {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            stat = Path(f"/proc/{d}/stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()  # after "pid (comm) "
        parent[int(d)] = int(fields[1])
        cpu[int(d)] = (int(fields[11]) + int(fields[12])) / tick
    total, todo = 0.0, [pid]
    while todo:
        p = todo.pop()
        total += cpu.get(p, 0.0)
        todo += [c for c, pp in parent.items() if pp == p]
    return total


def run(cmd: list[str], env: dict, frames_of, log: Path) -> list[tuple[int, float, float]]:
    """Run ``cmd``; at each output line ``frames_of`` maps to a frame count, record (frames, wall, tree CPU)."""
    marks = []
    with open(log, "w") as f:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, cwd=ROOT)
        assert proc.stdout is not None
        for line in proc.stdout:
            f.write(line)
            frames = frames_of(line)
            if frames is not None:
                marks.append((frames, time.perf_counter(), tree_cpu(proc.pid)))
        if proc.wait() != 0:
            raise SystemExit(f"{cmd[:4]} failed (exit {proc.returncode}); its output is in {log}")
    return marks


def rate(marks: list[tuple[int, float, float]]) -> tuple[float, float, int]:
    """(steps/s, CPU ms per step, steps) between the first and the last mark."""
    if len(marks) < 2:
        raise SystemExit("fewer than two updates logged: raise --updates")
    (f0, w0, c0), (f1, w1, c1) = marks[0], marks[-1]
    return (f1 - f0) / (w1 - w0), 1e3 * (c1 - c0) / (f1 - f0), f1 - f0


def habitat_run(args, out: Path, env: dict):
    cfg_dir = out / "config"
    cfg_dir.mkdir()
    (cfg_dir / "ddppo_bench.yaml").write_text(CONFIG.format(
        split=SPLIT, scenes=SCENES, envs=args.envs, updates=args.updates, steps=args.steps, out=out,
        train_encoder=str(args.train_encoder).lower()))
    cmd = [sys.executable, "-u", "-m", "habitat_baselines.run", f"--config-path={cfg_dir}",
           "--config-name=ddppo_bench", f"hydra.run.dir={out}/hydra",
           "~habitat.simulator.agents.main_agent.sim_sensors.rgb_sensor"]
    pattern = re.compile(r"Num updates: \d+\s+Num frames (\d+)")  # habitat_baselines/rl/ppo/ppo_trainer.py
    return cmd, run(cmd, env, lambda line: int(m.group(1)) if (m := pattern.search(line)) else None,
                    out / "habitat_baselines.log")


def navbench_run(args, out: Path, env: dict):
    cmd = [args.navbench_python, "-u", "-m", "navbench", "train", "ppo", "--init", str(INIT),
           "--out", str(out / "ppo.pth"), "--state-dir", str(out / "state"), "--num-envs", str(args.envs),
           "--rollout-steps", str(args.steps), "--updates", str(args.updates), "--critic-warmup", "0",
           "--save-every", str(args.updates)]
    # log rows are "update=N frames=F ..." (navbench.policy.csv_log.log_row)
    pattern = re.compile(r"\bframes[=:]\s*(\d+)")
    return cmd, run(cmd, env, lambda line: int(m.group(1)) if (m := pattern.search(line)) else None,
                    out / "navbench.log")


def torch_version(python: str) -> str:
    return subprocess.run([python, "-c", "import torch; print(torch.__version__)"], capture_output=True, text=True,
                          check=True).stdout.strip()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--which", choices=("both", "habitat", "navbench"), default="both")
    p.add_argument("--envs", type=int, default=2, help="environments (habitat-baselines: one process each)")
    p.add_argument("--steps", type=int, default=32, help="rollout steps per environment and update")
    p.add_argument("--updates", type=int, default=4)
    p.add_argument("--train-encoder", action="store_true", help="habitat-baselines also trains its visual encoder")
    p.add_argument("--navbench-python", default=sys.executable, help="the interpreter of navbench's run")
    p.add_argument("--keep", type=Path, default=None, help="keep the runs' logs and outputs in this directory")
    args = p.parse_args(argv)
    if args.envs < 1 or args.steps < 1 or args.updates < 2:
        p.error("--envs and --steps must be positive, --updates at least 2")
    env = {**os.environ, "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "osmesa"), "PYTHONUNBUFFERED": "1",
           "PYTHONPATH": os.pathsep.join([str(ROOT), str(ROOT / "compat" / "habitat-sim"),
                                          os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    with tempfile.TemporaryDirectory() as tmp:
        base = args.keep or Path(tmp)
        results = {}
        for which, fn, python in (("habitat-baselines ddppo", habitat_run, sys.executable),
                                  ("navbench train ppo", navbench_run, args.navbench_python)):
            if args.which not in ("both", which.split()[0].split("-")[0]):
                continue
            out = base / which.split()[0]
            out.mkdir(parents=True, exist_ok=True)
            t = time.perf_counter()
            _, marks = fn(args, out, env)
            results[which] = (*rate(marks), time.perf_counter() - t, torch_version(python))
    print(f"PointNav PPO training, {args.envs} envs x {args.steps} steps, {args.updates} updates, depth 224x224, "
          f"encoder {'trained' if args.train_encoder else 'frozen'}, {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.1f} at the end")
    for which, (sps, cpu, n, wall, tv) in results.items():
        print(f"  {which:24s} {sps:6.1f} steps/s, CPU {cpu:6.2f} ms/step (over {n} steps after the first update; "
              f"run {wall:.0f} s; torch {tv})")
    if len(results) == 2:
        (h, hc, *_), (nb, nc, *_) = results.values()
        print(f"  navbench / habitat-baselines: steps/s {nb / h:.2f}x, CPU per step {hc / nc:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
