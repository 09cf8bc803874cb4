"""habitat-baselines' PPO / DD-PPO trainer and evaluator on navbench's habitat_sim, through its entry points
(``execute_exp``, and ``python -m habitat_baselines.run``, under ``torchrun`` for two DD-PPO workers) with the example
configs in ``configs/habitat_baselines/`` and the bundled splits. Skipped unless the ``habitat`` extra and
``compat/habitat-sim`` are installed and torchvision imports."""

import gzip
import json
import logging
import math
import os
import pickle
import re
import socket
import subprocess
import sys
from pathlib import Path

import pytest

habitat_sim = pytest.importorskip("habitat_sim", reason="navbench-habitat-sim (compat/habitat-sim) not installed")
if not hasattr(habitat_sim, "__navbench__"):
    pytest.skip("habitat_sim here is not navbench's", allow_module_level=True)
pytest.importorskip("habitat", reason="habitat-lab (the habitat extra) not installed")
try:
    import torchvision  # noqa: F401
except Exception as exc:  # PyPI's CUDA build beside torch+cpu raises RuntimeError at import
    pytest.skip(f"torchvision does not import here ({type(exc).__name__}): habitat_baselines needs it",
                allow_module_level=True)
pytest.importorskip("habitat_baselines", reason="habitat-baselines (the habitat extra) not installed")

import torch  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
CONFIG_DIR = REPO / "configs" / "habitat_baselines"
POINTNAV_VAL = REPO / "episodes" / "pointnav" / "val" / "val.json.gz"
# two short updates, a checkpoint after each
TWO_UPDATES = ("habitat_baselines.num_updates=2", "habitat_baselines.checkpoint_interval=1",
               "habitat_baselines.rl.ppo.num_steps=16", "habitat_baselines.log_interval=1")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _run(config: str, out: Path, *overrides: str, nproc: int = 0, timeout: int = 900) -> str:
    """Runs habitat_baselines.run from the repository root (the configs' paths are relative to it), its outputs
    under ``out``; ``nproc`` > 0 launches it under torchrun. Returns stdout and stderr together."""
    entry = ["-m", "habitat_baselines.run"]
    launcher = [sys.executable, "-m", "torch.distributed.run", "--standalone", f"--nproc_per_node={nproc}"] \
        if nproc else [sys.executable]
    cmd = [*launcher, *entry, "--config-dir", str(CONFIG_DIR), "--config-name", config,
           f"hydra.run.dir={out}", f"habitat_baselines.checkpoint_folder={out / 'checkpoints'}",
           f"habitat_baselines.tensorboard_dir={out / 'tb'}", f"habitat_baselines.video_dir={out / 'video'}",
           f"habitat_baselines.log_file={out / 'run.log'}", "habitat_baselines.verbose=False", *overrides]
    env = {**os.environ, "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "osmesa"),
           # habitat-baselines' checkpoints hold an omegaconf DictConfig, which torch.load's weights_only refuses
           "TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD": "1", "MAIN_PORT": str(_free_port()), "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=timeout)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output[-4000:]
    return output


def _load(path: Path) -> dict:
    return torch.load(path, map_location="cpu", weights_only=False)


def _eval_metrics(output: str) -> dict[str, float]:
    # habitat-baselines' evaluator logs "Average episode <metric>: <value>" over the evaluated episodes
    return {k: float(v) for k, v in re.findall(r"Average episode (\w+): (-?[\d.]+|nan|inf)", output)}


def _episodes_evaluated(output: str) -> int:
    # the evaluator's progress bar counts finished episodes: "n/total [..."
    done, total = re.findall(r"(\d+)/(\d+) \[", output)[-1]
    assert done == total, output[-2000:]
    return int(done)


def _check_train(out: Path, output: str, frames: int, config: str, preemptible: bool = False) -> Path:
    """Checks a two-update run with a checkpoint after each update (``checkpoint_interval=1``), each update
    collecting ``frames`` steps (at most, where DD-PPO's workers are ``preemptible``: one that falls behind cuts
    its rollout short, habitat-baselines' ``should_end_early``, so the count depends on the machine's load);
    returns the last checkpoint."""
    folder = out / "checkpoints"
    assert sorted(p.name for p in folder.iterdir()) == ["ckpt.0.pth", "ckpt.1.pth", "latest.pth"], output[-2000:]
    steps = [_load(folder / f"ckpt.{i}.pth")["extra_state"]["step"] for i in (0, 1)]
    if preemptible:
        assert 0 < steps[0] <= frames and steps[0] < steps[1] <= steps[0] + frames, steps
    else:
        assert steps == [frames, 2 * frames]
    ckpt = folder / "latest.pth"
    state = _load(ckpt)
    assert state["extra_state"]["step"] == steps[1]
    assert Path(state["config"].habitat.dataset.scenes_dir).name == "envs"
    assert set(state["config"].habitat.simulator.agents.main_agent.sim_sensors) >= {"rgb_sensor", "depth_sensor"}
    weights = state["state_dict"]
    assert any(k.startswith("net.visual_encoder.") for k in weights)
    assert all(torch.isfinite(v).all() for v in weights.values() if v.is_floating_point()), config
    assert "update: 2" in output
    return ckpt


def _check_eval(output: str, episodes: int, metrics: tuple[str, ...]) -> dict[str, float]:
    assert _episodes_evaluated(output) == episodes
    got = _eval_metrics(output)
    for k in ("spl", "success", *metrics):
        assert k in got, (k, got)
    assert 0.0 <= got["spl"] <= 1.0 and 0.0 <= got["success"] <= 1.0
    assert math.isfinite(got["distance_to_goal"]) and got["distance_to_goal"] >= 0.0
    return got


class _Messages(logging.Handler):
    def __init__(self):
        super().__init__()
        self.lines: list[str] = []

    def emit(self, record):
        self.lines.append(record.getMessage())


def _execute(config: str, out: Path, run_type: str, *overrides: str) -> str:
    """Runs habitat-baselines' ``execute_exp`` (what ``python -m habitat_baselines.run`` calls) in this process on
    an example config, its outputs under ``out``; returns what it logged."""
    from habitat import logger
    from habitat_baselines.config.default import get_config
    from habitat_baselines.run import execute_exp

    cfg = get_config(str(CONFIG_DIR / f"{config}.yaml"), [
        f"habitat_baselines.checkpoint_folder={out / 'checkpoints'}", f"habitat_baselines.tensorboard_dir={out / 'tb'}",
        f"habitat_baselines.video_dir={out / 'video'}", f"habitat_baselines.log_file={out / 'run.log'}",
        "habitat_baselines.verbose=False", *overrides])
    handlers = list(logger.handlers)
    messages = _Messages()
    logger.addHandler(messages)
    threads = torch.get_num_threads()
    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setenv("PYOPENGL_PLATFORM", os.environ.get("PYOPENGL_PLATFORM", "osmesa"))
            mp.setenv("TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD", "1")
            mp.setenv("OMP_NUM_THREADS", "1")  # the environment workers'; the trainer's below
            torch.set_num_threads(1)
            execute_exp(cfg, run_type)
    finally:
        torch.set_num_threads(threads)
        for h in set(logger.handlers) - set(handlers):  # the trainer's log file handler too
            logger.removeHandler(h)
            h.close()
    return "\n".join(messages.lines)


@pytest.mark.parametrize(("config", "splits"), [("ppo_pointnav", ["val"]),
                                                ("ddppo_objectnav", ["train", "val_seen"])])
def test_example_configs_point_at_bundled_data(config, splits):
    from habitat_baselines.config.default import get_config

    cfg = get_config(str(CONFIG_DIR / f"{config}.yaml"))
    assert cfg.habitat.dataset.split == splits[0] and cfg.habitat_baselines.eval.split == splits[-1]
    assert not Path(cfg.habitat.dataset.data_path).is_absolute()  # from the repository root, as the header says
    for split in splits:
        path = REPO / cfg.habitat.dataset.data_path.format(split=split)
        with gzip.open(path, "rt") as f:
            scenes = {e["scene_id"] for e in json.load(f)["episodes"]}
        assert scenes and all((REPO / cfg.habitat.dataset.scenes_dir / s).is_file() for s in scenes), path
    # the headers' commands are the ones the tests run
    header = (CONFIG_DIR / f"{config}.yaml").read_text().split("\ndefaults:")[0]
    assert f"--config-dir configs/habitat_baselines --config-name {config}" in header
    assert "habitat_baselines.evaluate=True" in header


@pytest.fixture(scope="module")
def ppo_pointnav(tmp_path_factory):
    out = tmp_path_factory.mktemp("ppo_pointnav")
    # one episode a scene, so that training and the evaluation (which keeps the checkpoint's config) reconfigure
    # the simulator to another house between episodes
    output = _execute("ppo_pointnav", out, "train", f"habitat.dataset.data_path={POINTNAV_VAL}",
                      f"habitat.dataset.scenes_dir={REPO / 'envs'}", "habitat_baselines.num_environments=1",
                      *TWO_UPDATES, "habitat_baselines.rl.ppo.ppo_epoch=1",
                      "habitat.environment.iterator_options.max_scene_repeat_episodes=1")
    return out, output


def test_ppo_pointnav_train_writes_checkpoint(ppo_pointnav):
    out, output = ppo_pointnav
    ckpt = _check_train(out, output, frames=16, config="ppo_pointnav")
    config = _load(ckpt)["config"]
    assert config.habitat.dataset.data_path == str(POINTNAV_VAL)
    assert config.habitat.environment.iterator_options.max_scene_repeat_episodes == 1
    assert "Initialized DD-PPO" not in output
    # torch.load's default (weights_only) refuses the checkpoint: why the runs set TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD
    with pytest.MonkeyPatch.context() as mp:
        mp.delenv("TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD", raising=False)
        with pytest.raises(pickle.UnpicklingError, match="DictConfig"):
            torch.load(ckpt, map_location="cpu")


def test_ppo_pointnav_eval_of_checkpoint(ppo_pointnav, tmp_path, capfd):
    out, _ = ppo_pointnav
    # the evaluator builds its environments from the checkpoint's config and its rollout buffers from this one's:
    # both must have the training run's num_environments
    output = _execute("ppo_pointnav", tmp_path, "eval", "habitat_baselines.evaluate=True",
                      "habitat_baselines.num_environments=1", "habitat_baselines.test_episode_count=3",
                      f"habitat_baselines.eval_ckpt_path_dir={out / 'checkpoints' / 'latest.pth'}")
    assert "Loaded checkpoint trained for 32 steps" in output
    _check_eval(output + capfd.readouterr().err, episodes=3, metrics=("distance_to_goal", "distance_to_goal_reward"))


@pytest.mark.slow
def test_ddppo_pointnav_two_processes_train_and_eval(tmp_path):
    train = tmp_path / "train"
    output = _run("ppo_pointnav", train, "habitat_baselines.trainer_name=ddppo", "habitat_baselines.num_environments=1",
                  *TWO_UPDATES, nproc=2)
    assert "Initialized DD-PPO with 2 workers" in output
    # two workers, one environment each, 16 steps per update
    ckpt = _check_train(train, output, frames=32, config="ppo_pointnav", preemptible=True)
    output = _run("ppo_pointnav", tmp_path / "eval", "habitat_baselines.evaluate=True",
                  "habitat_baselines.num_environments=1", f"habitat_baselines.eval_ckpt_path_dir={ckpt}",
                  "habitat_baselines.test_episode_count=2")
    _check_eval(output, episodes=2, metrics=("distance_to_goal",))


@pytest.mark.slow
def test_ddppo_objectnav_train_and_eval(tmp_path):
    train = tmp_path / "train"
    output = _run("ddppo_objectnav", train, *TWO_UPDATES)
    assert "Initialized DD-PPO with 1 workers" in output
    ckpt = _check_train(train, output, frames=32, config="ddppo_objectnav")
    state = _load(ckpt)
    assert state["config"].habitat.dataset.split == "train"
    # the policy embeds one goal per category of the bundled dataset (ObjectGoalSensor's space)
    with gzip.open(REPO / "episodes" / "objectnav" / "train" / "train.json.gz", "rt") as f:
        categories = json.load(f)["category_to_task_category_id"]
    assert state["state_dict"]["net.obj_categories_embedding.weight"].shape[0] == max(categories.values()) + 1
    output = _run("ddppo_objectnav", tmp_path / "eval", "habitat_baselines.evaluate=True",
                  f"habitat_baselines.eval_ckpt_path_dir={ckpt}", "habitat_baselines.test_episode_count=2")
    got = _check_eval(output, episodes=2, metrics=("distance_to_goal", "soft_spl"))
    assert 0.0 <= got["soft_spl"] <= 1.0
