"""Evaluate an agent from Python, as ``navbench run`` does from the shell:

    import navbench
    summary = navbench.evaluate(MyAgent, task="pointnav", split="val", limit=10)

writes the same run directory (``runs/TASK/SPLIT/LABEL/``: episodes.jsonl, config.json, summary.json)
and returns the summary. See examples/evaluate_agent.py.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Any

from navbench.env.config import SUCCESS_DISTANCE
from navbench.paths import SCENES_DIR, split_file

# `select`: houses of their own for choosing among trained policies, so `val` is looked at once, to report
POINTNAV_SPLITS = ("train", "val", "select")
OBJECTNAV_SPLITS = ("train", "val_seen", "val_seen_synonyms", "val_unseen")
OVON_SPLITS = ("train", "val_seen", "val_seen_synonyms", "val_unseen")  # navbench's ObjectNav splits


def resolve_episodes(task: str | None, split: str | None, episodes: str | Path | None
                     ) -> tuple[str, str | None, Path, float]:
    """(task, split, episode file, default success distance) of a bundled split or a user's file. The
    task defaults to the file's, or for a split to ObjectNav unless the split is PointNav's only; the
    split to the task's validation split (val_unseen without a task)."""
    if episodes:
        episodes = Path(episodes)
        if task is None:
            from navbench.episodes.io import load_dataset
            task = load_dataset(episodes).task
        return task, split, episodes, SUCCESS_DISTANCE[task]
    split = split or ("val" if task == "pointnav" else "val_unseen")
    if task is None:
        task = "pointnav" if split in POINTNAV_SPLITS and split not in OBJECTNAV_SPLITS else "objectnav"
    valid = POINTNAV_SPLITS if task == "pointnav" else OBJECTNAV_SPLITS
    if split not in valid:
        raise ValueError(f"unknown {task} split {split!r}: choose from {', '.join(valid)}")
    sd = SUCCESS_DISTANCE["ovon"] if task == "objectnav" and split in OVON_SPLITS else SUCCESS_DISTANCE[task]
    return task, split, split_file(task, split), sd


def run_dir(task: str, split: str, label: str, root: str | Path = "runs") -> Path:
    """A run's default directory: <root>/<task>/<split>/<label> (split: a user's episode file's stem)."""
    return Path(root) / task / split / label


class _Instance:
    """A factory that hands out one already-built agent (pickled into each worker when workers > 1)."""

    def __init__(self, agent: Any):
        self.agent = agent

    def __call__(self, cfg: Any) -> Any:
        return self.agent


def _spec_of(obj: Any) -> str:
    """``module:QualName``; a script run with ``python -m pkg.mod`` is named by ``pkg.mod``, not ``__main__``."""
    module = obj.__module__
    if module == "__main__":
        import sys
        spec = getattr(sys.modules["__main__"], "__spec__", None)
        module = spec.name if spec is not None and spec.name != "__main__" else module
    return f"{module}:{obj.__qualname__}"


def evaluate(agent: Any, task: str | None = None, split: str | None = None, episodes: str | Path | None = None,
             *, options: dict[str, Any] | None = None, workers: int = 1, envs_per_worker: int | None = None,
             limit: int | None = None, per_scene: int | None = None, seed: int = 0, out: str | Path | None = None,
             runs_dir: str | Path = "runs", resume: bool = False, scene_dir: str | Path | None = None,
             success_distance: float | None = None, label: str | None = None,
             progress: Callable[[dict[str, Any], int, int], None] | None = None, overwrite: bool = False,
             retries: int = 2, step_timeout: float | None = None, fail_fast: bool = False) -> dict[str, Any]:
    """Run ``agent`` over a bundled ``split`` (or an ``episodes`` file) and return the summary.

    ``agent`` is an agent spec as ``--agent`` takes it (a built-in or entry-point name,
    ``"package.module:Name"``, ``"http://HOST:PORT"``), a class (built as ``Class(**options)``), a
    factory function (``f(run_config, **options)``), or an agent instance (used as is; pickled into
    each worker when ``workers > 1``). A module-level class or function is recorded in config.json by
    its import path, so the CLI can rerun or ``--resume`` the run; an instance or a function defined
    in ``__main__`` runs but cannot be rerun from config.json alone. Agents with ``act_batch`` step
    ``envs_per_worker`` episodes at once (default: the agent's ``num_envs``, else 1; 8 for the pointnav,
    memory and frontier agents). ``resume``, ``overwrite``, ``retries``, ``step_timeout`` and ``fail_fast`` are
    ``navbench run``'s options of the same names.
    """
    from navbench.agents.plugins import ResolvedAgent, can_batch, check_options, plugin_label, resolve_agent
    from navbench.eval.runner import RunConfig, run, select_episodes

    options = dict(options or {})
    if isinstance(agent, str):
        resolved = resolve_agent(agent, options, seed)
    elif inspect.isclass(agent) or inspect.isfunction(agent):
        spec = _spec_of(agent)
        check_options(spec, agent, options)
        if not spec.startswith("__main__:") and "<locals>" not in agent.__qualname__:
            from navbench.agents.plugins import PluginFactory
            factory: Any = PluginFactory(spec, options)  # workers re-import it by name
        else:
            factory = _Bound(agent, options)
        resolved = ResolvedAgent(spec, factory, options, plugin_label(spec, options, seed), batches=can_batch(agent))
    elif callable(getattr(agent, "act", None)) or callable(getattr(agent, "act_batch", None)):
        if options:
            raise ValueError("options apply to an agent class or factory, not to an agent instance")
        spec = _spec_of(type(agent))
        resolved = ResolvedAgent(spec, _Instance(agent), {}, plugin_label(spec, {}, seed),
                                 batches=callable(getattr(agent, "act_batch", None)))
        envs_per_worker = envs_per_worker or getattr(agent, "num_envs", None)
    else:
        raise ValueError(f"agent {agent!r}: expected an agent spec string, class, factory or instance "
                         f"(with act or act_batch)")
    if envs_per_worker is not None and envs_per_worker > 1 and resolved.batches is False:
        raise ValueError(f"--envs-per-worker applies to agents that step episodes in batches (act_batch), "
                         f"not {resolved.spec!r}, which steps one at a time")
    if envs_per_worker is None:
        n = getattr(agent, "num_envs", 1)
        envs_per_worker = resolved.envs_per_worker if resolved.builtin else (n if isinstance(n, int) and n > 0 else 1)

    task, split, episodes_path, default_sd = resolve_episodes(task, split, episodes)
    cfg = RunConfig(task=task, split=split, agent=resolved.spec, episodes=str(episodes_path),
                    scene_dir=str(scene_dir or SCENES_DIR),
                    success_distance=success_distance if success_distance is not None else default_sd,
                    seed=seed, limit=limit, per_scene=per_scene, workers=workers,
                    envs_per_worker=envs_per_worker, agent_options=resolved.options)
    cfg.label = label or resolved.label
    out = Path(out) if out is not None else run_dir(task, split or episodes_path.name.split(".")[0], cfg.label,
                                                    runs_dir)
    if resolved.prepare is not None:
        from navbench.eval.runner import run_dataset
        resolved.prepare(cfg, select_episodes(run_dataset(episodes_path), cfg.limit, cfg.per_scene))
    return run(cfg, resolved.factory, out, resume=resume, progress=progress, overwrite=overwrite,
               retries=retries, step_timeout=step_timeout, fail_fast=fail_fast)


class _Bound:
    """A class or factory with its options, for one defined where workers cannot import it by name."""

    def __init__(self, target: Any, options: dict[str, Any]):
        self.target, self.options = target, options

    def __call__(self, cfg: Any) -> Any:
        from navbench.agents.plugins import build
        return build(self.target, cfg, self.options)
