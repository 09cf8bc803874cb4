"""Tiny DAgger and PPO runs reproduce fixed weights and log rows, in one process and over two workers.

The expected hashes were computed before DAgger and PPO collection moved to navbench.policy.rollout; a change
that alters what training computes (random streams, env seeding, the order of steps) changes them. A deliberate
change of behaviour updates them, saying so.
"""

import csv
import hashlib
import json
from pathlib import Path

import pytest
import torch

from navbench.policy.checkpoint import save_checkpoint
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig

EXPECTED = {
    # (trainer, workers): (sha256 of the final fp32 state_dict, sha256 of the log rows without timings)
    ("dagger", 1): ("68ef0f4f6605d28b", "8d970f7f3e311ee1"),
    ("dagger", 2): ("918238a8bc7215a5", "c2685c44d0491740"),
    ("ppo", 1): ("662085ebd16d92c5", "13c52f50c25b2c36"),
    ("ppo", 2): ("7f0f4e4bee95cd26", "e81945c1abb34c2d"),
}


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def _state_hash(state: dict[str, torch.Tensor]) -> str:
    return _sha(b"".join(k.encode() + state[k].detach().contiguous().numpy().tobytes() for k in sorted(state)))


def _rows_hash(path: Path) -> str:
    with open(path, newline="") as f:
        rows = [{k: v for k, v in r.items() if not k.endswith("_s") and not k.startswith(("val_", "select_"))}
                for r in csv.DictReader(f)]
    return _sha(json.dumps(rows, sort_keys=True).encode())


def fingerprint(trainer: str, workers: int, tmp: Path) -> tuple[str, str]:
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
        weights = torch.load(state / "train_state.pt", weights_only=False)["policy"]
    else:
        from navbench.policy.ppo import PPOConfig, train_ppo

        cfg = PPOConfig(train_split="train", num_envs=2, rollout_steps=6, updates=2, critic_warmup=1, save_every=1,
                        bc_weight=0.1, tight_starts=0.3, seed=5, workers=workers, threads=1)
        train_ppo(cfg, out, init, state_dir=state, log_every=lambda _: None)
        weights = torch.load(state / "ppo_state.pt", weights_only=False)["policy"]
    return _state_hash(weights), _rows_hash(out.with_suffix(".log.csv"))


@pytest.mark.parametrize(("trainer", "workers"), [("dagger", 1), ("dagger", 2), ("ppo", 1), ("ppo", 2)])
def test_tiny_runs_reproduce_their_fingerprints(tmp_path, trainer, workers):
    assert fingerprint(trainer, workers, tmp_path) == EXPECTED[trainer, workers]


if __name__ == "__main__":  # print the fingerprints of this tree: python tests/policy/test_fingerprint.py
    import tempfile

    for key in [("dagger", 1), ("dagger", 2), ("ppo", 1), ("ppo", 2)]:
        with tempfile.TemporaryDirectory() as tmp:
            print(f"    {key!r}: {fingerprint(*key, Path(tmp))!r},", flush=True)
