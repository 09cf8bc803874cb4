"""Evaluate an agent from Python, as ``navbench run`` does from the shell (the command calls it):

    import navbench
    summary = navbench.evaluate(MyAgent, task="pointnav", split="val", limit=10)

writes the same run directory (``runs/TASK/SPLIT/LABEL/``: episodes.jsonl, config.json, summary.json)
and returns the summary. See examples/evaluate_agent.py.
"""

from __future__ import annotations

import itertools
import re
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from navbench.eval.records import EpisodeRecord, RunSummary
from navbench.paths import SCENES_DIR
from navbench.tasks import TASKS, get_task
from navbench.tasks.base import default_reader

__all__ = ["evaluate", "resolve_episodes", "run_dir"]

VIDEOS = ("none", "failures", "all")

# What a run reads without --task: a user's file tells its own task (PointNav-v1 or ObjectNav-v1); a split
# is this task's, unless only another task bundles a split of that name.
DEFAULT_TASK = "objectnav"


def resolve_episodes(task: str | None, split: str | None, episodes: str | Path | None
                     ) -> tuple[str, str | None, Path, float]:
    """The episodes a run reads, from a bundled split or a user's file.

    Args:
        task: a task of :data:`navbench.tasks.TASKS` or None: the file's task (PointNav, ObjectNav, or as its
            episodes' fields tell, InstanceImageNav or GOAT-Bench), or for
            a split ObjectNav unless only another task bundles a split of that name.
        split: a bundled split, or None: the task's default split (ObjectNav's val_unseen without a task).
        episodes: a user's episode file instead of a bundled split.

    Returns:
        (task, split or None for a user's file, episode file, the default success distance: the task's
        ``success_distance_for`` the split or the file's first episode; for ObjectNav a file in HM3D-OVON's
        format (:func:`navbench.episodes.io.is_ovon`) or drawn by navbench (``navbench generate benchmark``:
        it states a ``split_version``) gets OVON's).

    >>> resolve_episodes("pointnav", None, None)[::3]
    ('pointnav', 0.2)
    """
    if task is not None:
        get_task(task)  # an unknown task is a one-line ValueError naming the known ones
    if episodes:
        episodes = Path(episodes)
        if task is not None:
            check_file_task(task, episodes)

        def first(stream):  # the first episode (and the goals by category) tell the task and the format
            return list(itertools.islice(stream(), 1))
        dataset = None
        if task is None:  # InstanceImageNav and GOAT-Bench by their fields; else Habitat's PointNav-v1 or
            # ObjectNav-v1, read once when that task's reader is the same
            from navbench.episodes.io import file_task
            task = file_task(episodes)
            if task is None:
                dataset = default_reader(episodes, first)
                task = dataset.task
        t = get_task(task)
        if t.success_rule is None:
            return task, split, episodes, t.success_distance
        if dataset is None or t.read_episodes is not default_reader:
            dataset = t.read_episodes(episodes, first)
        return task, split, episodes, t.success_distance_for(None, dataset)
    if task is None:
        others = [t.name for t in TASKS.values() if split in t.splits and split not in TASKS[DEFAULT_TASK].splits]
        task = others[0] if split is not None and others else DEFAULT_TASK
    t = get_task(task)
    if not t.splits:
        raise ValueError(f"task {task} bundles no split: give a file of its episodes with --episodes FILE "
                         f"(and its scenes with --scene-dir DIR)")
    split = split or t.default_split
    if split not in t.splits:
        raise ValueError(f"unknown {task} split {split!r}: choose from {', '.join(t.splits)}")
    return task, split, t.split_file(split), t.success_distance_for(split)


def check_file_task(task: str, path: Path) -> None:
    """A one-line ValueError when ``path`` holds another task's episodes, by its first episode's fields
    (:func:`navbench.episodes.io.file_task`), in a format ``task``'s reader does not take (ImageNav reads
    PointNav-v1 files), naming the task the file belongs to. A file that cannot be read is left to the reader."""
    from navbench.episodes.io import file_task
    found = file_task(path, habitat_v1=True)
    if found is None or found == task or get_task(found).episode_format == get_task(task).episode_format:
        return
    fits = [t.name for t in TASKS.values() if t.episode_format == get_task(found).episode_format]
    article = "an" if get_task(found).display_name[0] in "AEIOR" else "a"
    raise ValueError(f"{path}: looks like {article} {get_task(found).display_name} file "
                     f"({get_task(found).episode_format}), not {get_task(task).display_name}'s: use --task "
                     f"{' or '.join(fits)}")


def run_dir(task: str, split: str, label: str, root: str | Path = "runs") -> Path:
    """A run's default directory: <root>/<task>/<split>/<label> (split: a user's episode file's stem).

    >>> str(run_dir("pointnav", "val", "pointnav-argmax"))
    'runs/pointnav/val/pointnav-argmax'
    """
    return Path(root) / task / split / label


def evaluate(agent: Any = None, task: str | None = None, split: str | None = None,
             episodes: str | Path | None = None, *, options: dict[str, Any] | None = None,
             limit: int | None = None, per_scene: int | None = None, shard: str | None = None, seed: int = 0,
             scene_dir: str | Path | None = None, success_distance: float | None = None, label: str | None = None,
             out: str | Path | None = None, runs_dir: str | Path = "runs", resume: bool = False,
             overwrite: bool = False, workers: int | None = None, envs_per_worker: int | None = None,
             backend: str = "local", address: str | None = None, retries: int = 2,
             step_timeout: float | None = None, fail_fast: bool = False, env_config: Any = None,
             progress: Callable[[EpisodeRecord, int, int], None] | None = None, video: str = "none",
             on_run_dir: Callable[[Path], None] | None = None, device: str = "cpu", precision: str = "fp32",
             habitat_config: Any = None,
             gt: str | Path | None = None,
             _episodes: tuple[str, str | None, Path, float] | None = None) -> RunSummary:
    """Run ``agent`` over a bundled ``split`` (or an ``episodes`` file) and return the summary; what
    ``navbench run`` does, flag for flag.

    A module-level class or function is recorded in config.json by its import path, so the CLI can
    rerun or ``--resume`` the run; an instance or a function defined in ``__main__`` runs but cannot be
    rerun from config.json alone. An option, or an execution setting, that cannot apply to the agent is
    a one-line ValueError, as is bad input; a failed episode is recorded (``num_failed``) and the run
    goes on unless ``fail_fast``.

    Args:
        agent: an agent spec as ``--agent`` takes it (a built-in or entry-point name,
            ``"package.module:Name"``, ``"http://HOST:PORT"``), a class (built as ``Class(**options)``), a
            factory function (``f(run_config, **options)``) or an agent instance (used as is; pickled into
            each worker when ``workers > 1``). None: the task's default agent (``Task.default_agent``:
            memory for ObjectNav, pointnav for PointNav).
        task: a task of :data:`navbench.tasks.TASKS` (``navbench tasks`` lists them; default: the episode
            file's, else from the split).
        split: a bundled split (default: the task's validation split).
        episodes: a Habitat-format episode file instead of a bundled split.
        options: the agent's options (a built-in's by field name, e.g. ``{"decoding": "sample"}``).
        limit: the first ``limit`` episodes only (file order).
        per_scene: the first ``per_scene`` episodes of each scene only (before ``limit``).
        shard: ``"I/N"``: the I-th of N contiguous blocks of the selected episodes.
        seed: the run's seed: the same seed gives the same records.
        scene_dir: where episodes' ``scene_id`` paths are resolved (default: the bundled scenes).
        success_distance: default: the task's (the split's for OVON-style splits).
        label: the run's name in tables (default: the agent and what differs from its defaults).
        out: the run directory (default ``runs_dir/TASK/SPLIT/LABEL[/shardIofN]``).
        runs_dir: root of the default run directory.
        resume: continue the run in ``out`` (finished episodes kept, failed ones rerun).
        overwrite: replace the run in ``out``.
        workers: parallel episode workers (default 1; with ``backend="ray"`` and no ``address``, the CPUs
            of the local Ray instance); not with ``address`` (the cluster's CPUs are the workers).
        envs_per_worker: episodes a worker steps at once, for an agent with ``act_batch`` (default: the
            built-in's, else the agent's ``num_envs``, else 1); records do not depend on it.
        backend: ``"local"`` (worker processes) or ``"ray"``.
        address: the Ray cluster to join (``backend="ray"`` only; default: start a local instance).
        retries: times an episode whose worker died is retried before it is recorded as failed.
        step_timeout: seconds an agent call may take before its episode fails.
        fail_fast: raise at the first failed episode instead of recording it.
        env_config: the conditions: a named configuration (``"habitat-challenge-pointnav-2021"``, see
            ``navbench.env.config.env_config_names()``), a TOML file of EnvConfig fields, or an
            :class:`~navbench.env.config.EnvConfig` (default: navbench's). Its success distance applies
            unless ``success_distance`` is given; the label gets its name (docs/realistic.md).
        progress: called as ``progress(record, done, total)`` after each episode.
        video: ``"failures"`` or ``"all"``: also write ``out/videos/EPISODE.mp4`` for those episodes.
        on_run_dir: called with the run directory once it is known, before any episode runs.
        device: where the agent's torch work runs: ``"cpu"`` (default), ``"cuda"``, ``"cuda:N"`` or
            ``"auto"`` (CUDA when torch sees a GPU); a device that is not there is a one-line ValueError.
            Records on CUDA agree with the CPU's up to the last bits (docs/gpu.md).
        precision: ``"fp32"`` (default), ``"bf16"`` or ``"fp16"``: the real perception models' weights.
        habitat_config: a Habitat configuration (a resolved habitat-lab yaml, or a habitat-baselines checkpoint
            holding one; or what :func:`navbench.eval.habitat_config.read_habitat_config` read from it) that
            sets the task, the env, the success distance and, where its files exist, the episodes and scenes;
            the other arguments override it. Not with ``env_config``.
        gt: a VLN-CE task's gt paths file (``{split}_gt.json.gz``), when it is not beside the episode file.

    Returns:
        The summary, as ``summary.json`` holds it.
    """
    from navbench.agents.plugins import resolve_agent
    from navbench.agents.registry import default_agent
    from navbench.device import check_precision
    from navbench.episodes.io import file_split
    from navbench.eval.config import Execution, RunConfig, parse_shard
    from navbench.eval.runner import run, run_dataset

    if resume and overwrite:
        raise ValueError("--resume and --overwrite: choose one")
    if address is not None and workers is not None:
        raise ValueError("--workers does not apply with --address: the Ray cluster's CPUs are the workers")
    execution = Execution(workers=workers or 1, backend=backend, address=address, retries=retries,
                          step_timeout=step_timeout, fail_fast=fail_fast)
    if video not in VIDEOS:
        raise ValueError(f"--video {video!r}: choose from {', '.join(VIDEOS)}")
    check_precision(precision)
    habitat = None
    if habitat_config is not None:
        from navbench.eval.habitat_config import HabitatSettings, read_habitat_config, run_arguments
        if env_config is not None:
            raise ValueError("--habitat-config and --env-config: choose one")
        habitat = habitat_config if isinstance(habitat_config, HabitatSettings) else \
            read_habitat_config(habitat_config)
        if _episodes is None:
            task, episodes, scene_dir, success_distance = run_arguments(habitat, task, split, episodes, scene_dir,
                                                                        success_distance)
    # `navbench run` resolved the episodes already (for the task's default agent): a user's file is read once
    task, split, episodes_path, default_sd = _episodes or resolve_episodes(task, split, episodes)
    env, env_name = _env_config(env_config, task) if habitat is None else \
        (habitat.env, "habitat-" + re.sub(r"[^\w.=+-]+", "_", habitat.path.name.split(".")[0])[:60])
    if env is None:
        env = _task_env(task)
    resolved = resolve_agent(default_agent(task) if agent is None else agent, options, seed,
                             envs_per_worker=envs_per_worker, device=device, task=task, env=env)
    if success_distance is None and env is not None:
        success_distance = env.success_distance
    cfg = RunConfig(task=task, split=split, agent=resolved.spec, episodes=str(episodes_path),
                    scene_dir=str(scene_dir or SCENES_DIR),
                    success_distance=success_distance if success_distance is not None else default_sd,
                    seed=seed, limit=limit, per_scene=per_scene, envs_per_worker=resolved.envs_per_worker,
                    agent_options=resolved.options, shard=shard, device=resolved.device, precision=precision,
                    env={} if env is None else env.overrides(), env_config_name=env_name,
                    habitat_config=None if habitat is None else habitat.record(),
                    gt=None if gt is None else str(gt))
    cfg.label = label or (resolved.label + (f"-{env_name}" if env_name else ""))
    parsed_shard = parse_shard(shard)
    if out is None:
        out = run_dir(task, split or file_split(episodes_path), cfg.label, runs_dir)
        if parsed_shard:
            out = out / f"shard{parsed_shard[0]}of{parsed_shard[1]}"
    out = Path(out)
    if on_run_dir is not None:
        on_run_dir(out)
    if backend == "ray":  # before the agent prepares: a missing extra is a one-line error
        from navbench.eval.ray_backend import require_ray
        require_ray()
    if resolved.prepare is not None:
        selected = run_dataset(episodes_path, cfg.limit, cfg.per_scene, cfg.shard, cfg.task, cfg.gt)
        resolved.prepare(cfg, selected.episodes)
    summary = run(cfg, resolved.factory, out, resume=resume, progress=progress, overwrite=overwrite,
                  execution=execution)
    if video != "none":  # drawn from the finished records, so the run itself is the same without
        from navbench.viz.cli import write_videos
        write_videos(out, video, quiet=progress is None)
    warn_failed(summary, out)
    return summary


def _env_config(env_config: Any, task: str) -> tuple[Any, str | None]:
    """(EnvConfig or None, the name config.json records) for ``evaluate``'s ``env_config``; a configuration made
    for other tasks than ``task`` is a one-line ValueError."""
    from navbench.env.config import EnvConfig, env_config_name, env_config_names, env_config_path, env_config_tasks
    if env_config is None:
        return None, None
    if isinstance(env_config, EnvConfig):
        return env_config, None
    if isinstance(env_config, (str, Path)):
        made_for = env_config_tasks(env_config)
        if made_for and task not in made_for:
            fits = [n for n in env_config_names() if not env_config_tasks(n) or task in env_config_tasks(n)]
            raise ValueError(f"{env_config_path(env_config)}: a configuration for {', '.join(made_for)}, not "
                             f"{task}: choose one for {task} ({', '.join(fits)})")
        return EnvConfig.load(env_config), env_config_name(env_config)
    raise ValueError(f"env_config: expected a name, a TOML file or an EnvConfig, got {env_config!r}"[:200])


def env_config_line(env_config: str | Path, task: str, success_distance: float) -> str:
    """One line saying what a named configuration (or TOML file) changes from ``task``'s own conditions, whose
    success distance is ``success_distance`` (the split's or file's); a ValueError when it is made for another
    task."""
    from navbench.env.config import EnvConfig, config_changes
    env, name = _env_config(env_config, task)
    changes = config_changes(env, _task_env(task) or EnvConfig(), task, success_distance)
    if not changes:
        return f"--env-config {name}: {task}'s own conditions, unchanged"
    return f"--env-config {name} changes {task}'s defaults: " + "; ".join(changes)


def _task_env(task: str) -> Any:
    """None (navbench's EnvConfig); for a task with a named configuration of its own (``Task.env_config``),
    that; for a task whose step limit is not EnvConfig's, EnvConfig with it (the run's config.json records
    either as ``env`` overrides)."""
    from navbench.env.config import EnvConfig
    t = get_task(task)
    if t.env_config is not None:
        return EnvConfig.load(t.env_config)
    return None if t.max_steps == EnvConfig().max_steps else EnvConfig(max_steps=t.max_steps)


def warn_failed(summary: RunSummary, out: Path) -> None:
    """A RuntimeWarning when episodes failed (their agent raised, returned an invalid action...), naming
    the first reason: a summary of failures is otherwise easy to read as a weak agent's scores."""
    failed = summary.get("failed_episodes") or []
    if failed:
        first = failed[0]
        warnings.warn(f"{summary.get('num_failed')} of {summary.get('num_episodes')} episode(s) failed (listed in "
                      f"{out}/summary.json); first, episode {first['episode_id']}: {first['failure_reason']}",
                      RuntimeWarning, stacklevel=3)  # the caller of navbench.evaluate
