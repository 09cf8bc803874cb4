"""Agents from outside the package (an import path, an installed entry point, a remote server), and the
one place any agent is resolved: :func:`resolve_agent` turns a spec, class, factory or instance into the
:class:`ResolvedAgent` a run builds, with the device it runs on.

An agent spec is one of
- a built-in name (``oracle``, ``pointnav``, ...: :data:`navbench.agents.registry.AGENTS`);
- a name registered by an installed package in the ``navbench.agents`` entry-point group;
- an import path ``package.module:Name``;
- ``http://HOST:PORT``: an agent served over HTTP (:mod:`navbench.agents.remote`).

What an entry point or import path names is either a class, built as ``Name(**options)``, or a
function, called as ``f(run_config, **options)`` (the run config as the built-in factories get it).
:class:`PluginFactory` holds only the spec and options, so spawned workers re-import the module
(which must be importable there: installed, or on ``sys.path``/``PYTHONPATH``).
"""

from __future__ import annotations

import importlib
import inspect
import json
import os
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any

from navbench.agents import habitat_compat

ENTRY_POINT_GROUP = "navbench.agents"
_IMPORT_PATH = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_][\w.]*$")


def is_remote(spec: str) -> bool:
    return spec.startswith(("http://", "https://"))


def is_import_path(spec: str) -> bool:
    return bool(_IMPORT_PATH.match(spec))


def entry_points() -> dict[str, metadata.EntryPoint]:
    """The installed ``navbench.agents`` entry points by name."""
    return {ep.name: ep for ep in metadata.entry_points(group=ENTRY_POINT_GROUP)}


def import_object(path: str) -> Any:
    """The object ``package.module:Name`` names. The working directory is tried after ``sys.path``, as a
    user's ``myagent.py`` beside them should import; a ValueError says what is missing."""
    module_name, _, attr = path.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        cwd = os.getcwd()
        top = module_name.split(".")[0]
        if exc.name != top or cwd in sys.path or "" in sys.path:
            raise ValueError(f"agent {path!r}: cannot import {module_name!r}: {exc}") from None
        sys.path.append(cwd)  # appended, so it never shadows an installed module; spawned workers inherit it
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError:
            raise ValueError(f"agent {path!r}: no module {module_name!r} on sys.path or in {cwd} "
                             f"(install it or add its folder to PYTHONPATH)") from None
    obj: Any = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ValueError(f"agent {path!r}: module {module_name!r} has no {attr!r}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise ValueError(f"agent {path!r}: {attr!r} is neither a class nor a factory function")
    return obj


def load_target(spec: str) -> Any:
    """The class or factory an entry point name or import path names."""
    eps = entry_points()
    if spec in eps:
        try:
            return eps[spec].load()
        except Exception as exc:  # a broken plug-in names itself and its package
            raise ValueError(f"agent {spec!r} (entry point {eps[spec].value}): {type(exc).__name__}: {exc}") from None
    if is_import_path(spec):
        return import_object(spec)
    raise ValueError(f"unknown agent {spec!r}")


def check_options(spec: str, target: Any, options: dict[str, Any]) -> None:
    """Refuse options ``target`` does not take, in one line naming the agent and what it takes, and an
    agent whose ``reset``/``act`` cannot be called (:func:`habitat_compat.check_agent`)."""
    habitat_compat.check_agent(spec, target)
    try:
        sig = inspect.signature(target)
    except (TypeError, ValueError):  # builtins/extension types: let the call itself complain
        return
    params = list(sig.parameters.values())
    if not inspect.isclass(target) and params:
        params = params[1:]  # a factory's first parameter is the run config
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return
    takes = [p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    unknown = sorted(set(options) - set(takes))
    if unknown:
        raise ValueError(f"agent {spec!r} takes no option {', '.join(map(repr, unknown))} "
                         f"(it takes: {', '.join(takes) or 'none'})")
    from_run = (*habitat_compat.RUN_ARGUMENTS, habitat_compat.DEVICE_ARGUMENT)  # filled in from the run config
    missing = [p.name for p in params if p.default is p.empty and p.kind is not p.VAR_POSITIONAL
               and p.name not in options and p.name not in from_run]
    if missing:
        raise ValueError(f"agent {spec!r} needs option(s) {', '.join(missing)} (--agent-opt NAME=VALUE)")


def build(target: Any, cfg: Any, options: dict[str, Any]) -> Any:
    """An agent from a plug-in class (``Name(**options)``) or factory (``f(cfg, **options)``), speaking
    navbench's protocol whether it was written for navbench's or Habitat's (:mod:`habitat_compat`)."""
    options = {**habitat_compat.run_arguments(target, cfg, options), **options}
    agent = target(**options) if inspect.isclass(target) else target(cfg, **options)
    return habitat_compat.adapt(agent)


@dataclass
class PluginFactory:
    """A picklable agent factory for a plug-in or remote spec: workers resolve the spec themselves."""
    spec: str
    options: dict[str, Any] = field(default_factory=dict)

    def __call__(self, cfg: Any) -> Any:
        if is_remote(self.spec):
            from navbench.agents.remote import RemoteAgent
            return RemoteAgent(self.spec, cfg, **self.options)
        return build(load_target(self.spec), cfg, self.options)


# -------------------------------------------------------------------------------------------- options
def parse_option(text: str) -> tuple[str, Any]:
    """``key=value`` with the value read as a JSON literal (``3`` int, ``0.5`` float, ``true`` bool,
    ``null``, ``[1, 2]``), else kept as a string (``ckpt=runs/a.pt``)."""
    key, sep, raw = text.partition("=")
    key = key.strip()
    if not sep or not key.isidentifier():
        raise ValueError(f"--agent-opt {text!r}: expected NAME=VALUE with NAME a Python identifier")
    try:
        return key, json.loads(raw)
    except json.JSONDecodeError:
        return key, raw


def parse_options(texts: list[str] | None) -> dict[str, Any]:
    return dict(parse_option(t) for t in texts or [])


def plugin_label(spec: str, options: dict[str, Any], seed: int = 0) -> str:
    """A plug-in run's name: the agent's last name (``MyAgent`` of ``pkg.mod:MyAgent``, the entry point's
    name, ``remote-HOST_PORT``), then ``key_value`` per option in sorted order, then ``seedN`` when the
    seed is not 0 (a plug-in's use of it is unknown). Only characters safe in a directory name remain."""
    if is_remote(spec):
        name = "remote-" + spec.split("://", 1)[1].rstrip("/").replace(":", "_")
    else:
        name = spec.rsplit(":", 1)[-1].rsplit(".", 1)[-1]
    parts = [name] + [f"{k}_{json.dumps(v) if not isinstance(v, str) else v}" for k, v in sorted(options.items())]
    if seed:
        parts.append(f"seed{seed}")
    return re.sub(r"[^\w.=+-]+", "_", "-".join(parts)).strip("_")[:120]


# -------------------------------------------------------------------------------------------- listing
def available_agents() -> list[dict[str, str]]:
    """Every agent ``--agent`` takes by name, with where it comes from: built in, or the distribution
    and object of an entry point (a name taken by a built-in is listed, marked as shadowed)."""
    from navbench.agents.registry import AGENTS
    rows = [{"name": n, "source": "built-in", "target": f"{s.factory.__module__}:{s.factory.__name__}"}
            for n, s in AGENTS.items()]
    for name, ep in sorted(entry_points().items()):
        dist = getattr(ep, "dist", None)
        where = f"{dist.name} {dist.version}" if dist is not None else "entry point"
        rows.append({"name": name, "source": where + (" (shadowed by the built-in)" if name in AGENTS else ""),
                     "target": ep.value})
    return rows


# -------------------------------------------------------------------------------------------- resolve
def can_batch(target: Any) -> bool | None:
    """Whether what builds an agent builds one that steps episodes in batches (``act_batch``): a class
    says so, a factory function does not until it is called (None)."""
    if inspect.isclass(target):
        return callable(getattr(target, "act_batch", None))
    return None


@dataclass
class ResolvedAgent:
    """What a run needs of an agent, however it was given: a picklable factory, the options config.json
    records (a built-in's with its defaults filled in), the run's label, the device it runs on, and what
    the harness knows of it up front.

    ``envs_per_worker`` is the episodes a worker steps at once; ``batches`` whether the agent can step
    several (None: unknown until it is built); ``prepare(cfg, episodes)`` runs in the driver before the
    workers start; ``device`` is the resolved ``--device`` (``"cpu"`` or ``"cuda:N"``), which the run's
    config hands to the built-in factories and to a plug-in that takes a ``device`` argument."""
    spec: str
    factory: Any
    options: dict[str, Any]
    label: str
    builtin: bool = False
    envs_per_worker: int = 1
    batches: bool | None = None
    prepare: Callable[[Any, list[Any]], None] | None = None
    device: str = "cpu"


def spec_of(obj: Any) -> str:
    """``module:QualName``; a script run with ``python -m pkg.mod`` is named by ``pkg.mod``, not ``__main__``."""
    module = obj.__module__
    if module == "__main__":
        spec = getattr(sys.modules["__main__"], "__spec__", None)
        module = spec.name if spec is not None and spec.name != "__main__" else module
    return f"{module}:{obj.__qualname__}"


class Instance:
    """A factory that hands out one already-built agent (pickled into each worker when workers > 1)."""

    def __init__(self, agent: Any):
        self.agent = agent

    def __call__(self, cfg: Any) -> Any:
        return habitat_compat.adapt(self.agent)


class Bound:
    """A class or factory with its options, for one defined where workers cannot import it by name."""

    def __init__(self, target: Any, options: dict[str, Any]):
        self.target, self.options = target, options

    def __call__(self, cfg: Any) -> Any:
        return build(self.target, cfg, self.options)


def resolve_agent(agent: Any, options: dict[str, Any] | None = None, seed: int = 0, *,
                  envs_per_worker: int | None = None, device: str = "cpu", task: str | None = None,
                  env: Any = None) -> ResolvedAgent:
    """Whatever names an agent, with its options, checked up front (one-line ValueError naming the agent).

    Args:
        agent: a spec string (a built-in or entry-point name, ``package.module:Name``,
            ``http://HOST:PORT``), a class (built as ``Class(**options)``), a factory function
            (``f(run_config, **options)``) or an agent instance with ``act`` or ``act_batch`` (navbench's
            protocol or Habitat's; used as is).
        options: the agent's options (a built-in's by field name; a plug-in's as its keywords).
        seed: the run's seed (it names the run when the agent's actions depend on it).
        envs_per_worker: episodes a worker steps at once (None: the built-in's default, else the
            class's or instance's ``num_envs``, else 1); more than 1 for an agent that cannot batch is refused.
        device: ``auto``, ``cpu``, ``cuda`` or ``cuda:N`` (:func:`navbench.device.resolve_device`).
        task, env: the run's task and EnvConfig, when it is not navbench's default: a built-in agent that cannot
            work under it (:func:`navbench.agents.registry.check_conditions`) is refused.

    Returns:
        The resolved agent.
    """
    from navbench.device import resolve_device

    options = dict(options or {})
    if isinstance(agent, str):
        resolved = _resolve_spec(agent, options, seed)
    elif inspect.isclass(agent) or inspect.isfunction(agent):
        spec = spec_of(agent)
        check_options(spec, agent, options)
        importable = not spec.startswith("__main__:") and "<locals>" not in agent.__qualname__
        factory: Any = PluginFactory(spec, options) if importable else Bound(agent, options)  # workers import it
        resolved = ResolvedAgent(spec, factory, options, plugin_label(spec, options, seed), batches=can_batch(agent),
                                 envs_per_worker=_num_envs(agent))
    elif callable(getattr(agent, "act", None)) or callable(getattr(agent, "act_batch", None)):
        if options:
            raise ValueError("options apply to an agent class or factory, not to an agent instance")
        spec = spec_of(type(agent))
        habitat_compat.check_agent(spec, agent)
        resolved = ResolvedAgent(spec, Instance(agent), {}, plugin_label(spec, {}, seed),
                                 envs_per_worker=_num_envs(agent),
                                 batches=callable(getattr(agent, "act_batch", None)))
    else:
        raise ValueError(f"agent {agent!r}: expected an agent spec string, class, factory or instance "
                         f"(with act or act_batch)")
    if envs_per_worker is not None:
        if envs_per_worker > 1 and resolved.batches is False:
            raise ValueError(f"--envs-per-worker applies to agents that step episodes in batches (act_batch), "
                             f"not {resolved.spec!r}, which steps one at a time")
        resolved.envs_per_worker = envs_per_worker
    resolved.device = resolve_device(device)
    if resolved.builtin:
        from navbench.agents.registry import check_conditions, check_task
        from navbench.env.config import EnvConfig
        if env is not None:
            check_conditions(resolved.spec, task or "", env)
        check_task(resolved.spec, task or "", env if env is not None else EnvConfig())
    return resolved


def _num_envs(agent: Any) -> int:
    """The episodes an agent class or instance says it steps at once (``num_envs``), else 1."""
    n = getattr(agent, "num_envs", 1)
    return n if isinstance(n, int) and not isinstance(n, bool) and n > 0 else 1


def _resolve_spec(spec: str, options: dict[str, Any], seed: int) -> ResolvedAgent:
    from navbench.agents import registry
    if spec in registry.AGENTS:
        s = registry.AGENTS[spec]
        opts = registry.agent_options(spec, **options)
        return ResolvedAgent(spec, s.factory, opts, registry.run_label(spec, opts, seed), True,
                             envs_per_worker=s.envs_per_worker, batches=s.batches, prepare=s.prepare)
    batches: bool | None
    if is_remote(spec):
        from navbench.agents.remote import RemoteAgent, probe
        check_options(spec, RemoteAgent, {"url": None, "cfg": None, **options})
        probe(spec, timeout=min(float(options.get("timeout", 5.0)), 5.0))
        batches = can_batch(RemoteAgent)
    elif spec in entry_points() or is_import_path(spec):
        target = load_target(spec)
        check_options(spec, target, options)
        batches = can_batch(target)
    else:
        raise ValueError(f"unknown agent {spec!r}: choose from {', '.join(registry.AGENTS)}, an installed "
                         f"plug-in (`navbench agents` lists them), package.module:Name or http://HOST:PORT")
    return ResolvedAgent(spec, PluginFactory(spec, options), options, plugin_label(spec, options, seed),
                         batches=batches)
