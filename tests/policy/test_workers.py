"""Rollout workers: pinned processes that keep their envs between calls, for DAgger and PPO collection."""

import os
import signal
from functools import partial
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig, prepare_depth
from navbench.policy.ppo import PPOConfig, Rollout
from navbench.policy.rollout import Collection, make_envs, worker_shares
from navbench.policy.train import Collector, TrainConfig, build_learner
from navbench.policy.workers import WorkerError, WorkerPool


def test_pool_answers_in_worker_order_and_reports_a_workers_error_with_its_traceback():
    with WorkerPool(dict, [({"k": 1},), ({"k": 2},), ({"k": 3},)]) as pool:
        assert len(pool) == 3
        assert pool.call("get", [("k",)] * 3) == [1, 2, 3]
        pool.call("update", [({"k": 10 * i},) for i in range(3)])  # state stays in each worker between calls
        assert pool.call("get", [("k",)] * 3) == [0, 10, 20]
        with pytest.raises(KeyError, match="gone") as err:  # the worker's own exception, re-raised here
            pool.call("pop", [("k",), ("gone",), ("k",)])
        assert "raised in rollout worker 1" in err.value.__notes__[0]
        assert pool.call("get", [("k", "none")] * 3) == ["none", 10, "none"]  # the pool still answers
        with pytest.raises(ValueError, match="2 argument tuples for 3 workers"):
            pool.call("get", [("k",)] * 2)


def test_a_worker_that_cannot_build_its_object_fails_the_pool_with_its_error():
    with pytest.raises(ValueError, match=r"invalid literal for int\(\)") as err:
        WorkerPool(int, [("3",), ("three",)])
    assert "raised in rollout worker 1" in err.value.__notes__[0]


def test_a_worker_that_dies_fails_the_pool_by_name():
    with WorkerPool(partial(SimpleNamespace, run=os._exit), [(), ()]) as pool:
        with pytest.raises(WorkerError, match="rollout worker 0: exited with code 3"):
            pool.call("run", [(3,), (4,)])


def test_workers_outlive_a_sigterm_to_the_process_group_and_close_still_ends_them():
    # scancel or `kill -- -PGID` signals every process: the trainer saves after its update, so its workers
    # must still answer then; close() ends them all the same
    pool = WorkerPool(dict, [({"k": 1},), ({"k": 2},)])
    procs = list(pool._procs)
    try:
        for p in procs:
            os.kill(p.pid, signal.SIGTERM)
            os.kill(p.pid, signal.SIGUSR1)
        assert pool.call("get", [("k",)] * 2) == [1, 2]
    finally:
        pool.close()
    assert not any(p.is_alive() for p in procs)


def test_a_collection_whose_worker_was_killed_still_closes():
    source = Collection(pool=WorkerPool(dict, [({},), ({},)]))
    procs = list(source.pool._procs)
    os.kill(procs[0].pid, signal.SIGKILL)
    procs[0].join(timeout=10)
    source.close()
    assert not any(p.is_alive() for p in procs)


def test_worker_shares_split_the_envs_evenly_in_order():
    assert worker_shares(8, 1) == [(0, 8)]
    assert worker_shares(8, 2) == [(0, 4), (4, 4)]
    assert worker_shares(5, 2) == [(0, 3), (3, 2)]
    for bad in (0, 9):
        with pytest.raises(ValueError, match="workers must be between 1 and num_envs"):
            worker_shares(8, bad)


def _key(seg):
    return seg["label"].tobytes(), np.round(seg["goal"], 4).tobytes()


def test_expert_rollouts_split_over_two_workers_are_those_of_one_process():
    # beta = 1 and no random actions: every action is the expert's, so an env's episodes depend only on its
    # seed, and two workers with one env each must hand over exactly the episodes one process collects.
    cfg = TrainConfig(num_envs=2, random_action_prob=0.0, max_episode_steps=100, workers=2)
    torch.manual_seed(0)
    policy = build_learner(cfg).eval()
    local_source = Collection(Collector(make_envs(2, "train", seed=0), cfg, np.random.default_rng(0), policy))
    try:
        local, _ = local_source.collect(policy, 240, 1.0)
    finally:
        local_source.close()
    pooled_source = Collection.in_workers(Collector, cfg, 0, [[0, 0], [0, 1]])
    try:
        pooled, successes = pooled_source.collect(policy, 240, 1.0)
    finally:
        pooled_source.close()
    assert len(local) >= 2 and successes == [1.0] * len(pooled)
    by_key = {_key(s): s for s in local}
    assert sorted(by_key) == sorted(_key(s) for s in pooled)
    for seg in pooled:  # the worker encoded the same frames with the trainer's weights (batch 1 against 2)
        np.testing.assert_allclose(seg["feat"].astype(np.float32), by_key[_key(seg)]["feat"].astype(np.float32),
                                   rtol=2e-3, atol=2e-3)


def test_pooled_ppo_rollout_lays_the_workers_envs_side_by_side_with_the_trainers_weights():
    cfg = PPOConfig(train_split="train", num_envs=2, rollout_steps=6, workers=2)
    torch.manual_seed(1)
    policy = PointNavResNetPolicy(PolicyNetConfig()).eval()
    source = Collection.in_workers(Rollout, cfg, 7, [[0, 0], [0, 1]])
    try:
        data, _ = source.collect(policy)
        again, _ = source.collect(policy)  # the second call sends no encoder weights
    finally:
        source.close()
    feat_dim = int(np.prod(policy.net.visual_encoder.output_shape))
    assert data["action"].shape == (6, 2) and data["feat"].shape == (6, 2, feat_dim)
    assert data["hidden0"].shape == (2, *policy.initial_hidden(1).shape[1:]) and not data["hidden0"].any()
    assert again["hidden0"].any()  # the recurrent state carried over between calls
    # env i of the run, as make_envs seeds it, after the rollout's own first reset
    envs = make_envs(2, "train", 7)
    obs = [env.reset()[0] for env in envs]
    goal = np.stack([o["pointgoal_with_gps_compass"] for o in obs])
    np.testing.assert_allclose(data["goal"][0].numpy(), goal, rtol=1e-6)
    with torch.inference_mode():
        _, value, _ = policy(prepare_depth(np.stack([o["depth"] for o in obs]), policy.cfg.input_size),
                             torch.as_tensor(goal), torch.zeros(2, dtype=torch.long),
                             torch.zeros(2, dtype=torch.bool), policy.initial_hidden(2))
    np.testing.assert_allclose(data["value"][0].numpy(), value.numpy(), rtol=1e-4, atol=1e-5)
    for env in envs:
        env.close()
