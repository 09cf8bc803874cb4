"""Tiny DAgger and PPO runs reproduce fixed weights and log rows, in one process and over two workers.

A change that alters what training computes (random streams, env seeding, the order of steps) changes the
hashes; a deliberate change of behaviour updates them, saying so. The floats of training depend on the CPU:
oneDNN's convolutions and torch's kernels follow the instruction set, and CPUs of one instruction set from two
vendors also differ in the last bits. So the hashes are recorded per CPU class (vendor and the instruction set
torch dispatches to); on a class with none recorded the exact check is skipped, and what holds on every CPU is
still checked: a run is deterministic on its machine, its schedule is the configured one, its weights are
finite and trained. ``python tests/policy/test_fingerprint.py`` prints this machine's class and hashes.
"""

import csv
import hashlib
import json
from pathlib import Path

import pytest
import torch

from navbench.policy.checkpoint import read_train_state, save_checkpoint
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig

RUNS = [("dagger", 1), ("dagger", 2), ("ppo", 1), ("ppo", 2)]
EXPECTED = {
    # CPU class: {(trainer, workers): (sha256 of the final fp32 state_dict, sha256 of the log rows without timings)}
    "AuthenticAMD AVX512": {  # AMD EPYC with AVX-512 and BF16
        ("dagger", 1): ("650dbc17f84d050b", "b22ae1791dd311e8"),
        ("dagger", 2): ("a79bb0996794338e", "b3ead920e37878c7"),
        ("ppo", 1): ("4826ef7a0eecfdbd", "104e547ac313ca86"),
        ("ppo", 2): ("301e0cdd08e1039e", "2f6801aad2698fff"),
    },
}
# Log columns fixed by the configuration alone, the same on every CPU.
SCHEDULE = {
    "dagger": (("iteration", "frames", "beta", "lr", "updates", "buffer_frames"),
               [("1", "50", "1.0", "0.0005", "2", "50"), ("2", "100", "0.7", "0.0005", "2", "100")]),
    "ppo": (("update", "frames"), [("1", "12"), ("2", "24")]),
}


def cpu_class() -> str:
    """'<vendor> <torch's CPU capability>', e.g. 'AuthenticAMD AVX2' (set ``ATEN_CPU_CAPABILITY=avx2`` and
    ``DNNL_MAX_CPU_ISA=AVX2`` together to compute as an AVX2 CPU of the same vendor would)."""
    vendor = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("vendor_id"):
                vendor = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{vendor} {torch.backends.cpu.get_cpu_capability()}"


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def _state_hash(state: dict[str, torch.Tensor]) -> str:
    return _sha(b"".join(k.encode() + state[k].detach().contiguous().numpy().tobytes() for k in sorted(state)))


def _rows_hash(path: Path) -> str:
    with open(path, newline="") as f:
        rows = [{k: v for k, v in r.items() if not k.endswith("_s") and not k.startswith(("val_", "select_"))}
                for r in csv.DictReader(f)]
    return _sha(json.dumps(rows, sort_keys=True).encode())


def fingerprint(trainer: str, workers: int, tmp: Path, details: dict | None = None) -> tuple[str, str]:
    """The run's (weights hash, log rows hash); ``details`` (if given) receives the weights, the initial
    weights and the log rows."""
    # The run's own thread count from the start: a process's first convolutions at another count differ from
    # the later ones in the last bits.
    torch.set_num_threads(1)
    torch.manual_seed(123)
    init = save_checkpoint(tmp / "init.pth", PointNavResNetPolicy(PolicyNetConfig()), {})
    out, state = tmp / f"{trainer}.pth", tmp / "state"
    if trainer == "dagger":
        from navbench.policy.train import TrainConfig, train

        fields = TrainConfig.__dataclass_fields__  # the names before the refactor, so both trees run this
        kw = {"batch_chunks" if "batch_chunks" in fields else "batch_episodes": 2,
              "val_episodes" if "val_episodes" in fields else "monitor_episodes": 0}
        cfg = TrainConfig(num_envs=2, iterations=2, frames_per_iteration=60, max_episode_steps=25,
                          epochs_per_iteration=2.0, seed=3, workers=workers, threads=1, **kw)
        train(cfg, out, state_dir=state, init=init, log_every=lambda _: None)
        weights = read_train_state(state / "train_state.pt")["policy"]
    else:
        from navbench.policy.ppo import PPOConfig, train_ppo

        cfg = PPOConfig(train_split="train", num_envs=2, rollout_steps=6, updates=2, critic_warmup=1, save_every=1,
                        bc_weight=0.1, tight_starts=0.3, seed=5, workers=workers, threads=1)
        train_ppo(cfg, out, init, state_dir=state, log_every=lambda _: None)
        weights = read_train_state(state / "ppo_state.pt")["policy"]
    if details is not None:
        with open(out.with_suffix(".log.csv"), newline="") as f:
            details.update(weights=weights, init=torch.load(init, weights_only=False), rows=list(csv.DictReader(f)))
    return _state_hash(weights), _rows_hash(out.with_suffix(".log.csv"))


@pytest.mark.parametrize(("trainer", "workers"), RUNS)
def test_tiny_runs_reproduce_their_fingerprints(tmp_path, trainer, workers):
    expected = EXPECTED.get(cpu_class())
    if expected is None:
        pytest.skip(f"no fingerprints recorded for CPU class {cpu_class()!r} (the properties below still hold)")
    assert fingerprint(trainer, workers, tmp_path) == expected[trainer, workers]


@pytest.mark.parametrize(("trainer", "workers"), [("dagger", 2), ("ppo", 2)])
def test_tiny_runs_are_deterministic_and_train_on_every_cpu(tmp_path, trainer, workers):
    details: dict = {}
    first = fingerprint(trainer, workers, tmp_path / "a", details)
    assert fingerprint(trainer, workers, tmp_path / "b") == first
    columns, schedule = SCHEDULE[trainer]
    assert [tuple(r[c] for c in columns) for r in details["rows"]] == schedule
    weights, init = details["weights"], details["init"]
    init = init.get("state_dict", init)
    assert all(torch.isfinite(v).all() for v in weights.values() if v.is_floating_point())
    assert any(not torch.equal(weights[k], init[k].to(weights[k].dtype)) for k in weights if k in init)


if __name__ == "__main__":  # print the fingerprints of this tree: python tests/policy/test_fingerprint.py
    import tempfile

    print(f"    {cpu_class()!r}: {{")
    for key in RUNS:
        with tempfile.TemporaryDirectory() as tmp:
            print(f"        {key!r}: {fingerprint(*key, Path(tmp))!r},", flush=True)
    print("    },")
