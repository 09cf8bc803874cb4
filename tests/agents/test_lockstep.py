"""Lockstep batching of single-episode agents: one policy forward pass per step, records unchanged."""

import numpy as np
import pytest

from navbench.agents.lockstep import LockstepAgent
from navbench.agents.registry import make_frontier, make_memory, prebuild_memories
from navbench.episodes.io import load_dataset
from navbench.eval.runner import RunConfig, comparable, read_records, run, select_episodes
from navbench.paths import POLICIES_DIR, SCENES_DIR
from navbench.policy.checkpoint import load_checkpoint
from navbench.policy.net import InferenceConfig, PointNavAgentPolicy

CHECKPOINT = POLICIES_DIR / "pointnav_navbench.pth"
needs_checkpoint = pytest.mark.skipif(not CHECKPOINT.is_file(), reason="no shipped PointNav checkpoint")


@pytest.fixture(scope="module")
def network():
    return load_checkpoint(CHECKPOINT)


def _frames(rng, n):
    return rng.random((n, 224, 224, 1)).astype(np.float32), rng.random((n, 2)).astype(np.float32) * [3, 1]


@needs_checkpoint
@pytest.mark.parametrize("decoding", ["argmax", "least-tried"])
def test_stepping_some_rows_leaves_the_others_untouched(network, decoding):
    """rows=[0, 2] steps envs 0 and 2 exactly as a full batch would and does not touch env 1's state."""
    rng = np.random.default_rng(0)
    cfg = InferenceConfig(decoding=decoding)
    full, part = PointNavAgentPolicy(network, 3, cfg), PointNavAgentPolicy(network, 3, cfg)
    for p in (full, part):
        for i in range(3):
            p.reset(i, seed=[1, i])
    for _ in range(4):
        depth, goal = _frames(rng, 3)
        a = full.act(depth, goal)
        before = part.hidden[1].clone(), int(part.prev_actions[1]), bool(part.masks[1])
        b = part.act(depth[[0, 2]], goal[[0, 2]], rows=[0, 2])
        assert (part.hidden[1] == before[0]).all() and int(part.prev_actions[1]) == before[1]
        assert bool(part.masks[1]) == before[2]
        assert list(b) == [a[0], a[2]]
        np.testing.assert_allclose(part.hidden[[0, 2]], full.hidden[[0, 2]], atol=1e-5)
        full.hidden[1] = part.hidden[1]  # keep env 1 in step so the next full batch sees the same state
        full.prev_actions[1], full.masks[1] = part.prev_actions[1], part.masks[1]


class _Asker:
    """Asks its policy ``asks`` times a step (0: answers alone), raises at step ``raise_at``."""
    sensors = ("depth",)

    def __init__(self, policy, asks, raise_at=None):
        self.policy, self.asks, self.raise_at, self.steps = policy, asks, raise_at, 0

    def reset(self, episode):
        self.policy.reset(seed=[0])
        self.steps = 0

    def act(self, obs):
        self.steps += 1
        if self.steps == self.raise_at:
            raise RuntimeError("agent broke")
        action = 3
        for _ in range(self.asks):
            action = int(self.policy.act(obs["depth"][None], np.array([[2.0, 0.5]], np.float32))[0])
        return action


class _CountingPolicy:
    """Records each batched call's rows; answers 1 for every row."""

    def __init__(self, n):
        self.num_envs, self.calls = n, []

    def reset(self, i=None, seed=None):
        pass

    def reset_hidden(self, i=None):
        pass

    def act(self, depth, goal, rows=None):
        assert depth.shape[0] == len(rows) == goal.shape[0]
        self.calls.append(list(rows))
        return np.ones(len(rows), np.int64)


def test_one_forward_pass_per_round_of_asks_and_per_slot_failures():
    policy = _CountingPolicy(4)
    plan = {0: (1, None), 1: (0, None), 2: (2, None), 3: (1, 2)}
    agent = LockstepAgent(policy, lambda sp: _Asker(sp, *plan[sp.i]))
    for i in range(4):
        agent.reset_env(i, None)
    obs = {"depth": np.zeros((224, 224, 1), np.float32)}
    out = agent.act_batch([obs, obs, obs, obs])
    assert out == [1, 3, 1, 1]
    # slots 0, 2, 3 asked together, then slot 2 asked again alone
    assert policy.calls == [[0, 2, 3], [2]]
    policy.calls.clear()
    out = agent.act_batch([obs, None, obs, obs])  # slot 1 idle; slot 3's agent raises this step
    assert out[0] == 1 and out[1] is None and out[2] == 1
    assert isinstance(out[3], RuntimeError) and str(out[3]) == "agent broke"
    assert policy.calls == [[0, 2], [2]]
    assert agent.slot(2).steps == 2


@needs_checkpoint
@pytest.mark.parametrize("agent,make", [("memory", make_memory),
                                        pytest.param("frontier", make_frontier, marks=pytest.mark.slow)])
def test_lockstep_records_equal_one_at_a_time(objectnav_file, tmp_path, agent, make):
    """The memory and frontier agents, 3 slots in lockstep over 6 episodes (slot refills included): every
    record, decision log and trace equals the one-episode-at-a-time run's."""
    records = {}
    for n in (1, 3):
        cfg = RunConfig(task="objectnav", split=None, agent=agent, episodes=str(objectnav_file),
                        scene_dir=str(SCENES_DIR), success_distance=0.25, envs_per_worker=n,
                        env={"max_steps": 80}, agent_options={"memory_root": str(tmp_path / "memory")})
        prebuild_memories(cfg, select_episodes(load_dataset(objectnav_file), None))
        run(cfg, make, tmp_path / f"n{n}")
        records[n] = comparable(read_records(tmp_path / f"n{n}" / "episodes.jsonl"))
    assert len(records[3]) == 6 and records[1] == records[3]
    assert all(r.get("log") and r.get("trace") for r in records[3])
