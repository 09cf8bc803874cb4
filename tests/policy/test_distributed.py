"""Distributed training on loopback: gloo ranks on 127.0.0.1, tiny nets and episodes.

- two ranks' averaged gradients are one process's on the union of their batches (DAgger's loss, a PPO update);
- a run cut after some updates and resumed ends with the weights of the uncut run (DAgger and PPO);
- a rank killed under ``torchrun --max-restarts 1`` comes back and the run continues from its resume state.
"""

import csv
import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from navbench.policy import distributed as ddp
from navbench.policy.checkpoint import read_train_state, save_checkpoint
from navbench.policy.config import PPOConfig, TrainConfig
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig

TINY = PolicyNetConfig(input_size=(64, 64), hidden_size=16, num_layers=1, base_planes=8, ngroups=4)
ROOT = Path(__file__).resolve().parents[2]


def _tiny_policy() -> PointNavResNetPolicy:
    torch.manual_seed(0)
    policy = PointNavResNetPolicy(TINY)
    policy.net.visual_encoder.requires_grad_(False)
    return policy


def _dagger_batch(n: int = 4, T: int = 5) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(1)
    dim = _tiny_policy().net.encode_depth(torch.zeros(1, 64, 64, 1)).shape[-1]
    weight = torch.rand(T, n, generator=g) * 3  # the ranks' halves weigh differently
    weight[-2:, 0] = 0  # padding
    return {"feat": torch.randn(T, n, dim, generator=g).half(), "goal": torch.randn(T, n, 2, generator=g),
            "prev": torch.randint(0, 4, (T, n), generator=g), "mask": torch.rand(T, n, generator=g) > 0.2,
            "label": torch.randint(0, 4, (T, n), generator=g), "weight": weight}


def _ppo_data(n: int = 4, T: int = 6) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(2)
    policy = _tiny_policy()
    dim = policy.net.encode_depth(torch.zeros(1, 64, 64, 1)).shape[-1]
    return {"feat": torch.randn(T, n, dim, generator=g), "goal": torch.randn(T, n, 2, generator=g),
            "prev": torch.randint(0, 4, (T, n), generator=g), "mask": torch.rand(T, n, generator=g) > 0.2,
            "action": torch.randint(0, 4, (T, n), generator=g), "logp": -torch.rand(T, n, generator=g) - 1,
            "value": torch.randn(T, n, generator=g), "adv": torch.randn(T, n, generator=g) * 2 + 0.5,
            "ret": torch.randn(T, n, generator=g), "hidden0": torch.randn(n, *policy.initial_hidden(1).shape[1:],
                                                                         generator=g) * 0.1}


def _update(kind: str, world: int, rank: int) -> dict[str, torch.Tensor]:
    """The weights after one plain-SGD update on this rank's share of the batch (all of it when world is 1)."""
    policy = _tiny_policy()
    opt = torch.optim.SGD([p for p in policy.parameters() if p.requires_grad], lr=0.5)
    forward = ddp.training_forward(policy)
    share = slice(rank * 4 // world, (rank + 1) * 4 // world)
    if kind == "dagger":
        from navbench.policy.train import train_step

        batch = {k: v[:, share] for k, v in _dagger_batch().items()}
        train_step(policy, opt, batch, TrainConfig(grad_clip=1e9), forward)
    else:
        from navbench.policy.ppo import ppo_update

        data = {k: (v[share] if k == "hidden0" else v[:, share]) for k, v in _ppo_data().items()}
        cfg = PPOConfig(ppo_epochs=1, num_minibatches=1, max_grad_norm=0.2)
        ppo_update(policy, opt, data, cfg, actor=True, rng=np.random.default_rng(0), forward=forward)
    return {k: v.detach().clone() for k, v in policy.state_dict().items()}


def _rank_main(rank: int, world: int, port: int, out: str) -> None:
    os.environ.update(RANK=str(rank), WORLD_SIZE=str(world), LOCAL_RANK=str(rank), MASTER_ADDR="127.0.0.1",
                      MASTER_PORT=str(port))
    torch.set_num_threads(1)
    info = ddp.init()
    assert info.world_size == world and info.backend == "gloo"
    try:
        torch.save({"dagger": _update("dagger", world, rank), "ppo": _update("ppo", world, rank),
                    "preempt": _preemption(rank)}, f"{out}.{rank}")
    finally:
        ddp.shutdown()


def _preemption(rank: int) -> dict[str, bool]:
    """Rank 0 finishes its rollout at once; rank 1 asks whether to end its own early, at 0 and at 2 of 8 steps."""
    fast = ddp.Preemption(0.5, 0.25, "stage/0")
    never = ddp.Preemption(1.0, 0.25, "stage/0")
    if rank == 0:
        fast.finished()
    ddp.barrier()
    other = ddp.Preemption(0.5, 0.25, "stage/1")
    out = {"before_min_share": fast.should_stop(0, 8), "after_min_share": fast.should_stop(2, 8),
           "fraction_1": never.should_stop(2, 8), "other_rollout": other.should_stop(2, 8)}
    ddp.barrier()
    return out


@pytest.fixture(scope="module")
def loopback(tmp_path_factory) -> list[dict]:
    """Two gloo ranks on 127.0.0.1, each with its results of the DAgger and PPO updates and the preemption rule."""
    return _on_loopback(tmp_path_factory.mktemp("loopback"))


def _on_loopback(tmp_path: Path, world: int = 2) -> list[dict]:
    ctx = multiprocessing.get_context("spawn")
    port = ddp.free_port()
    procs = [ctx.Process(target=_rank_main, args=(r, world, port, str(tmp_path / "rank"))) for r in range(world)]
    for p in procs:
        p.start()
    try:
        for p in procs:
            p.join(timeout=120)
            assert p.exitcode == 0, f"rank exited with {p.exitcode}"
    finally:
        for p in procs:
            if p.is_alive():
                p.kill()
                p.join()
    return [torch.load(f"{tmp_path / 'rank'}.{r}") for r in range(world)]


@pytest.mark.parametrize("kind", ["dagger", "ppo"])
def test_two_gloo_ranks_update_as_one_process_on_the_union_of_their_batches(kind, loopback):
    single = _update(kind, 1, 0)
    before = _tiny_policy().state_dict()
    ranks = [r[kind] for r in loopback]
    moved = [k for k in single if not torch.equal(single[k], before[k])]
    assert moved, "the update moved nothing"
    for k in single:
        assert torch.equal(ranks[0][k], ranks[1][k]), f"{k}: the ranks disagree"
        torch.testing.assert_close(ranks[0][k], single[k], rtol=1e-5, atol=1e-6, msg=f"{k}")
    # one rank's half alone gives another update: the test sees the other rank's gradient
    half = _update_half(kind)
    assert any(not torch.allclose(half[k], single[k], rtol=1e-4, atol=1e-5) for k in moved)


def _update_half(kind: str) -> dict[str, torch.Tensor]:
    return _update(kind, 2, 0)  # world 2 numbering, but no process group: rank 0's half on its own


def test_launch_variables_come_from_torchrun_or_slurm():
    torchrun = {"RANK": "3", "WORLD_SIZE": "8", "LOCAL_RANK": "1", "MASTER_ADDR": "h", "MASTER_PORT": "1"}
    assert ddp.launch_env(torchrun) == torchrun
    slurm = {"SLURM_PROCID": "5", "SLURM_NTASKS": "8", "SLURM_LOCALID": "1", "SLURM_JOB_ID": "12345",
             "SLURM_JOB_NODELIST": "gpu[07-09,12],cpu1"}
    assert ddp.launch_env(slurm) == {"RANK": "5", "WORLD_SIZE": "8", "LOCAL_RANK": "1", "MASTER_ADDR": "gpu07",
                                     "MASTER_PORT": str(ddp.DEFAULT_PORT + 345)}
    assert ddp.launch_env({"SLURM_PROCID": "0", "SLURM_NTASKS": "1"}) == {}  # one task: a plain run
    assert ddp.launch_env({}) == {}
    assert ddp.rank_seeds(7) == 7 and ddp.rank_seeds([7, 1], rank=2) == [7, 1, 7777, 2]


# ------------------------------------------------------------------------------------------ resume
def _run(trainer: str, d: Path, init: Path, n: int, resume: bool = False) -> dict[str, torch.Tensor]:
    torch.set_num_threads(1)
    if trainer == "ppo":
        from navbench.policy.ppo import train_ppo

        cfg = PPOConfig(train_split="train", num_envs=1, rollout_steps=6, updates=n, critic_warmup=1, save_every=1,
                        num_minibatches=1, bc_weight=0.1, tight_starts=0.3, seed=5, threads=1)
        train_ppo(cfg, d / "o.pth", init, resume=resume, state_dir=d / "s", log_every=lambda _: None)
        return read_train_state(d / "s" / "ppo_state.pt")["policy"]
    from navbench.policy.train import train

    cfg = TrainConfig(num_envs=1, iterations=n, frames_per_iteration=16, max_episode_steps=7, batch_episodes=2,
                      monitor_episodes=0, epochs_per_iteration=1.0, seed=3, threads=1, buffer_frames=30,
                      tight_starts=0.3)
    train(cfg, d / "o.pth", resume=resume, state_dir=d / "s", init=init, log_every=lambda _: None)
    return read_train_state(d / "s" / "train_state.pt")["policy"]


@pytest.mark.parametrize("trainer", ["dagger", "ppo"])
def test_a_run_cut_and_resumed_ends_with_the_weights_of_the_uncut_run(trainer, tmp_path):
    torch.manual_seed(1)
    init = save_checkpoint(tmp_path / "init.pth", PointNavResNetPolicy(PolicyNetConfig()), {})
    uncut = _run(trainer, tmp_path / "uncut", init, 3)
    _run(trainer, tmp_path / "cut", init, 1)
    step = "update" if trainer == "ppo" else "iteration"
    log = tmp_path / "cut" / "o.log.csv"
    with open(log, "a") as f:  # a row written after the saved state, by a run killed before its next save
        f.write("2" + "," * (log.read_text().splitlines()[0].count(",")) + "\n")
    resumed = _run(trainer, tmp_path / "cut", init, 3, resume=True)
    assert all(torch.equal(uncut[k], resumed[k]) for k in uncut)
    assert [r[step] for r in csv.DictReader(open(log))] == ["1", "2", "3"]  # each step once, the resumed run's
    if trainer == "dagger":  # the buffer's shards on disk are only those the buffer still holds
        names = sorted(p.name for p in (tmp_path / "cut" / "s" / "buffer").iterdir())
        assert names[-1] == "iteration_000003.pt" and "iteration_000001.pt" not in names


def test_sigterm_saves_the_resume_state_after_the_update_in_progress(tmp_path):
    from navbench.policy.ppo import train_ppo

    torch.manual_seed(1)
    init = save_checkpoint(tmp_path / "init.pth", PointNavResNetPolicy(PolicyNetConfig()), {})
    cfg = PPOConfig(train_split="train", num_envs=1, rollout_steps=3, updates=50, critic_warmup=1, save_every=100,
                    num_minibatches=1, seed=5, threads=1)
    lines: list[str] = []

    def log(line: str) -> None:
        lines.append(line)
        if len(lines) == 3:  # "initialised", then two updates' rows
            os.kill(os.getpid(), signal.SIGTERM)

    before = signal.getsignal(signal.SIGTERM)  # the caller's (a test process may hold one, e.g. Ray's)
    last = train_ppo(cfg, tmp_path / "o.pth", init, state_dir=tmp_path / "s", log_every=log)
    assert last["update"] == 2 and "stopped by signal" in lines[-1]
    assert read_train_state(tmp_path / "s" / "ppo_state.pt")["update"] == 2
    assert signal.getsignal(signal.SIGTERM) is before  # the handler is the caller's again


# ------------------------------------------------------------------------------------------ torchrun
def _children(pid: int) -> list[int]:
    kids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            kids.append(int(stat.parent.name))
    return kids


@pytest.mark.slow  # torchrun restarting a killed rank end to end: make test-slow
def test_a_rank_killed_under_torchrun_comes_back_and_resumes(tmp_path):
    torch.manual_seed(1)
    init = save_checkpoint(tmp_path / "init.pth", PointNavResNetPolicy(PolicyNetConfig()), {})
    state = tmp_path / "s"
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc-per-node", "2",
           "--max-restarts", "1", "--monitor-interval", "0.2", "-m", "navbench", "train", "ppo",
           "--init", str(init), "--out", str(tmp_path / "o.pth"), "--state-dir", str(state), "--train-split", "train",
           "--num-envs", "1", "--rollout-steps", "3", "--updates", "5", "--critic-warmup", "1", "--save-every", "1",
           "--threads", "1", "--preempt-fraction", "1", "--num-minibatches", "1"]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NAVBENCH_PROGRESS": "0", "OMP_NUM_THREADS": "1"}
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                            start_new_session=True)
    seen: set[int] = set()  # every worker torchrun started, to end them whatever happens
    try:
        deadline = time.monotonic() + 120
        while not (state / "ppo_state.rank1.pt").is_file():  # both ranks have saved an update
            seen.update(_children(proc.pid))
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"the run ended before any resume state:\n{proc.communicate(timeout=30)[0][-3000:]}")
            time.sleep(0.1)
        workers = _children(proc.pid)
        assert len(workers) == 2
        seen.update(workers)
        os.kill(max(workers), signal.SIGKILL)  # one of the two ranks dies
        time.sleep(1)
        seen.update(_children(proc.pid))  # the restarted ones
        out, _ = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.terminate()  # torchrun ends its workers on SIGTERM
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        for pid in seen | set(_children(proc.pid)):
            try:  # only if that pid is still one of this run's workers
                if str(state) in Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace"):
                    os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
    assert proc.returncode == 0, out[-3000:]
    assert "world size 2 (gloo)" in out
    assert "resumed at update" in out, out[-3000:]
    assert read_train_state(state / "ppo_state.pt")["update"] == 5


def test_a_recipe_stops_at_the_stage_a_signal_stopped(tmp_path):
    from navbench.policy.recipe import load_recipe, run_recipe

    recipe = load_recipe("full")  # eleven stages: the ten after the stopped one do not run
    ran = []

    def run(trainer, cfg, out, state_dir, init, resume):
        ran.append(Path(out).stem)
        return {"stopped_by_signal": signal.SIGUSR1} if len(ran) == 1 else {}

    run_recipe(recipe, tmp_path, init=tmp_path / "init.pth", run=run)
    assert ran == [recipe.stages[0].name]


def test_a_rank_ends_its_rollout_early_once_enough_ranks_finished_and_it_did_its_minimum_share(loopback):
    answers = loopback[1]["preempt"]
    assert answers == {"before_min_share": False, "after_min_share": True, "fraction_1": False,
                       "other_rollout": False}
