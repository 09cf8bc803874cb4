"""Agents written for Habitat's ``habitat.Agent`` run unchanged.

habitat-lab's agent protocol is ``reset()`` without arguments before each episode and
``act(observations)`` returning an action id, an action name (``"move_forward"``, ``"STOP"``...) or a
dict ``{"action": id or name, "action_args": ...}``. navbench calls ``reset(episode)`` and steps the env
with an id (0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT, 3 TURN_RIGHT, and under a configuration with Habitat's
ObjectNav actions 4 LOOK_UP, 5 LOOK_DOWN: Habitat's ids). :func:`adapt` wraps a
plug-in agent so both forms work: ``reset`` gets the episode only if it takes an argument, and ``act``'s
answer becomes the id. :func:`check_agent` refuses, before a run, an agent whose methods cannot be
called that way. habitat-baselines' agents take ``success_distance`` and ``goal_sensor_uuid`` in their
constructor; :func:`run_arguments` fills them from the run config when the options do not give them.
"""

from __future__ import annotations

import inspect
import math
from typing import Any

from navbench.env.config import KNOWN_ACTIONS, EnvConfig
from navbench.tasks import get_task

# by Habitat's ids (navbench.env.config.KNOWN_ACTIONS); names are matched case-insensitively. Which ids a run
# takes is its env's action space (LOOK_UP / LOOK_DOWN only under a configuration that lists them).
ACTIONS = tuple(a.lower() for a in KNOWN_ACTIONS)
RUN_ARGUMENTS = ("success_distance", "goal_sensor_uuid")  # what habitat-baselines passes its agents
# A plug-in whose constructor (or factory) names this parameter gets the run's device ("cpu", "cuda:N")
# unless its options give one.
DEVICE_ARGUMENT = "device"


def allowed() -> str:
    return (f"an action id 0-{len(ACTIONS) - 1}, a name ({', '.join(ACTIONS)}) or "
            f"{{'action': id or name}}")


def action_id(value: Any) -> Any:
    """The id an ``act`` answer names: a name or an ``{"action": ...}`` dict becomes its id; anything else
    is returned as it is (the runner checks ids against the action space). ValueError for a name or dict
    that names no action, showing what was returned and what is allowed."""
    answer = value
    if isinstance(value, dict):
        if "action" not in value:
            raise ValueError(f"act returned {answer!r}: a dict needs an 'action' key; expected {allowed()}")
        value = value["action"]
        if isinstance(value, dict):
            raise ValueError(f"act returned {answer!r}: expected {allowed()}")
    if isinstance(value, str):
        name = value.strip().lower()
        if name not in ACTIONS:
            raise ValueError(f"act returned {answer!r}: {value!r} is not an action; expected {allowed()}")
        return ACTIONS.index(name)
    return value


def _arity(fn: Any, drop_self: bool) -> tuple[int, float, list[str]] | None:
    """(required positional, most positional, required keyword-only names) of ``fn``; None if unknown."""
    try:
        params = list(inspect.signature(fn).parameters.values())
    except (TypeError, ValueError):
        return None
    if drop_self and params and params[0].kind in (params[0].POSITIONAL_ONLY, params[0].POSITIONAL_OR_KEYWORD):
        params = params[1:]
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    required = sum(p.default is p.empty for p in positional)
    most = math.inf if any(p.kind is p.VAR_POSITIONAL for p in params) else len(positional)
    kw_required = [p.name for p in params if p.kind is p.KEYWORD_ONLY and p.default is p.empty]
    return required, most, kw_required


def _method(target: Any, name: str) -> tuple[Any, bool]:
    """``target``'s method ``name`` and whether calling it through the class passes ``self`` first."""
    if inspect.isclass(target):
        static = inspect.getattr_static(target, name, None)
        if isinstance(static, (staticmethod, classmethod)):
            return getattr(target, name), False
        return getattr(target, name, None), True
    return getattr(target, name, None), False


def _signature(fn: Any, drop_self: bool) -> str:
    try:
        params = list(inspect.signature(fn).parameters)
    except (TypeError, ValueError):
        return "(...)"
    return "(" + ", ".join(params[1:] if drop_self else params) + ")"


def check_agent(spec: str, target: Any) -> None:
    """Refuse, in one line naming the agent, a class or instance whose ``reset`` cannot be called with
    no argument or with the episode, or whose ``act`` cannot be called with the observations. A batched
    agent (``act_batch``) and a factory function (its agent is known only once built) pass."""
    if inspect.isfunction(target) or callable(getattr(target, "act_batch", None)):
        return
    act, drop = _method(target, "act")
    if not callable(act):
        raise ValueError(f"agent {spec!r} has no act(observations) method (nor act_batch)")
    shape = _arity(act, drop)
    if shape is not None and (shape[2] or not shape[0] <= 1 <= shape[1]):
        raise ValueError(f"agent {spec!r}: act{_signature(act, drop)} cannot be called as act(observations)")
    reset, drop = _method(target, "reset")
    if not callable(reset):
        raise ValueError(f"agent {spec!r} has no reset() or reset(episode) method")
    shape = _arity(reset, drop)
    if shape is not None and (shape[2] or shape[0] > 1):
        raise ValueError(f"agent {spec!r}: reset{_signature(reset, drop)} cannot be called as reset() "
                         f"or reset(episode)")


def run_arguments(target: Any, cfg: Any, options: dict[str, Any]) -> dict[str, Any]:
    """habitat-baselines' constructor arguments ``target`` requires and ``options`` lacks, from the run
    config: ``success_distance`` (the run's) and ``goal_sensor_uuid`` (the task's goal observation); and
    ``device`` (the run's) when ``target`` takes one."""
    shape = _parameters(target)
    wanted = [n for n in RUN_ARGUMENTS if shape.get(n, False) and n not in options]
    out: dict[str, Any] = {}
    if DEVICE_ARGUMENT in shape and DEVICE_ARGUMENT not in options:  # the run's --device, required or not
        out[DEVICE_ARGUMENT] = str(getattr(cfg, "device", "cpu"))
    for name in wanted:
        if name == "success_distance" and getattr(cfg, "success_distance", None) is not None:
            out[name] = float(cfg.success_distance)
        elif name == "goal_sensor_uuid":
            # the task's first goal sensor under the run's conditions (without GPS+compass, PointNav's is
            # Habitat's static `pointgoal`)
            out[name] = get_task(getattr(cfg, "task", "pointnav")).goal_sensor_uuid(_env_of(cfg))
    return out


def _env_of(cfg: Any) -> EnvConfig:
    """The run's EnvConfig (a RunConfig's, or one from a duck-typed config's ``env`` overrides)."""
    if callable(getattr(cfg, "env_config", None)):
        return cfg.env_config(())
    env = getattr(cfg, "env", None)
    try:
        return EnvConfig(**env) if isinstance(env, dict) else EnvConfig()
    except (TypeError, ValueError):
        return EnvConfig()


def _parameters(target: Any) -> dict[str, bool]:
    """Each named parameter of a class's constructor or a factory (after its run config): required?"""
    try:
        params = list(inspect.signature(target).parameters.values())
    except (TypeError, ValueError):
        return {}
    if not inspect.isclass(target) and params:
        params = params[1:]
    return {p.name: p.default is p.empty for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}


class HabitatAgent:
    """An agent speaking Habitat's protocol, seen through navbench's: ``reset(episode)`` calls the agent's
    ``reset()`` or ``reset(episode)``, ``act`` returns the id of what the agent's ``act`` returned. Every
    other attribute (``sensors``, ``episode_log``...) is the agent's."""

    def __init__(self, agent: Any):
        self.agent = agent
        shape = _arity(agent.reset, False)
        self._reset_takes_episode = shape is None or shape[1] >= 1

    def reset(self, episode: Any) -> None:
        if self._reset_takes_episode:
            self.agent.reset(episode)
        else:
            self.agent.reset()

    def act(self, observations: Any) -> Any:
        return action_id(self.agent.act(observations))

    def __getattr__(self, name: str) -> Any:
        if name == "agent":  # not set yet (unpickling): no recursion through __getattr__
            raise AttributeError(name)
        return getattr(self.agent, name)


def adapt(agent: Any) -> Any:
    """``agent`` wrapped in :class:`HabitatAgent` when it steps one episode at a time (``act``); a batched
    agent, or one already wrapped, is returned as it is."""
    if isinstance(agent, HabitatAgent) or callable(getattr(agent, "act_batch", None)) \
            or not callable(getattr(agent, "act", None)) or not callable(getattr(agent, "reset", None)):
        return agent
    return HabitatAgent(agent)
