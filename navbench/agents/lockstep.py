"""Many single-episode agents stepped in lockstep with one PointNav forward pass per step for all of them.

The memory and frontier agents are written for one episode: each step they decide what to do and, when
they drive, call their injected policy's ``act`` once for one frame. :class:`LockstepAgent` runs
``num_envs`` such agents (one per env slot of a worker) as a :class:`~navbench.agents.base.BatchAgent`:
each agent's ``act`` runs in its own thread, one thread at a time, until it either returns an action or
asks its :class:`SlotPolicy` for one; the asks of a step are then answered by one batched forward pass of
the shared :class:`~navbench.policy.net.PointNavAgentPolicy` over the slots that asked. Every slot's
recurrent state, generator and agent are its own, so an episode's actions do not depend on the other
slots (tests/agents/test_lockstep.py runs the same episodes batched and one at a time).

    navbench run --split val_unseen                      # memory agent, 8 episodes per worker in lockstep
    navbench run --split val_unseen --envs-per-worker 1  # the same records, one episode at a time
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from navbench.episodes.types import Episode
from navbench.policy.net import PointNavAgentPolicy


class SlotPolicy:
    """Slot ``i`` of a shared batched policy, with the one-env interface the agents drive with
    (:class:`~navbench.agents.common.StepPolicy`); ``act`` blocks until the batch's forward pass."""

    def __init__(self, batch: LockstepAgent, i: int) -> None:
        self.batch, self.i = batch, i

    def reset(self, i: int | None = None, seed: int | list[int] | None = None) -> None:
        self.batch.policy.reset(self.i, seed=seed)

    def reset_hidden(self, i: int | None = None) -> None:
        self.batch.policy.reset_hidden(self.i)

    def act(self, depth: np.ndarray, pointgoal: np.ndarray) -> np.ndarray:
        return self.batch._ask(self.i, depth, pointgoal)


class _Slot:
    """One agent's thread and its hand-offs with the stepping thread."""

    def __init__(self, agent: Any, parked: threading.Semaphore) -> None:
        self.agent, self.parked = agent, parked
        self.go = threading.Semaphore(0)
        self.obs: dict[str, np.ndarray] | None = None
        self.result: Any = None  # the action, or the exception the agent raised
        self.ask: tuple[np.ndarray, np.ndarray] | None = None  # (depth, pointgoal) while waiting on the policy
        self.answer: Any = None  # the policy's action (an array) or the exception of its forward pass
        self.thread = threading.Thread(target=self._loop, daemon=True)
        self.thread.start()

    def _loop(self) -> None:
        while True:
            self.go.acquire()
            try:
                self.result = self.agent.act(self.obs)
            except Exception as exc:  # the runner records it as this slot's failed episode
                self.result = exc
            self.obs = None
            self.parked.release()


class LockstepAgent:
    """A :class:`~navbench.agents.base.BatchAgent` of ``policy.num_envs`` agents, slot ``i``'s built by
    ``build(SlotPolicy(self, i))``; ``slot(i)`` is that agent (its episode log and decisions)."""

    def __init__(self, policy: PointNavAgentPolicy, build: Callable[[SlotPolicy], Any]) -> None:
        self.policy, self.num_envs = policy, policy.num_envs
        self._parked = threading.Semaphore(0)
        self._slots = [_Slot(build(SlotPolicy(self, i)), self._parked) for i in range(self.num_envs)]
        self.sensors = tuple(self._slots[0].agent.sensors)

    def slot(self, i: int) -> Any:
        return self._slots[i].agent

    def reset_env(self, i: int, episode: Episode) -> None:
        self._slots[i].agent.reset(episode)

    def act_batch(self, observations: list[dict[str, np.ndarray] | None]) -> list[Any]:
        """One step of every slot with an observation (None: no episode in that slot). Returns per slot its
        action, or the exception its agent raised (the runner fails that slot's episode only)."""
        out: list[Any] = [None] * self.num_envs
        pending = [i for i, o in enumerate(observations) if o is not None]
        for i in pending:
            self._slots[i].obs = observations[i]
            self._resume(i)
        while pending:
            asking = [i for i in pending if self._slots[i].ask is not None]
            for i in pending:
                if self._slots[i].ask is None:
                    out[i] = self._slots[i].result
            if asking:
                self._answer(asking)
                for i in asking:
                    self._slots[i].ask = None
                    self._resume(i)
            pending = asking
        return out

    # ------------------------------------------------------------------------------------ hand-offs
    def _resume(self, i: int) -> None:
        """Let slot ``i``'s thread run until it returns an action or asks the policy (one thread at a time)."""
        self._slots[i].go.release()
        self._parked.acquire()

    def _ask(self, i: int, depth: np.ndarray, pointgoal: np.ndarray) -> np.ndarray:
        """In slot ``i``'s thread: park with the frame and goal, wait for the batch's answer."""
        s = self._slots[i]
        s.ask = (np.asarray(depth)[0], np.asarray(pointgoal)[0])
        self._parked.release()
        s.go.acquire()
        if isinstance(s.answer, Exception):
            raise s.answer
        return s.answer

    def _answer(self, rows: list[int]) -> None:
        """One forward pass for the slots in ``rows`` (each asked for one action)."""
        try:
            actions = self.policy.act(np.stack([self._slots[i].ask[0] for i in rows]),
                                      np.stack([self._slots[i].ask[1] for i in rows]), rows=rows)
            for i, a in zip(rows, actions):
                self._slots[i].answer = np.array([a])
        except Exception as exc:
            for i in rows:
                self._slots[i].answer = exc
