"""The benchmark's agents by name: one :class:`AgentSpec` each, read by the CLI, the API, the tables and
both execution backends (no module outside ``navbench.agents`` names a particular agent).

A spec holds the agent's factory, its options dataclass (:mod:`navbench.agents.options`: defaults,
flags and the ``agent_options`` that ``config.json`` records), how many episodes it steps at once by
default, what it prepares before a run and the files it ships to remote workers.

A factory takes the run's :class:`~navbench.eval.config.RunConfig` (duck-typed: ``task``, ``scene_dir``,
``success_distance``, ``seed``, ``envs_per_worker``, ``agent_options``, ``env_config(sensors)``) and
returns a fresh agent. Factories are top-level functions so worker processes can unpickle them.

Adding an agent: write its module under ``navbench/agents/``, a ``make_NAME(cfg)`` factory and an
options dataclass here (or reuse one), and one :class:`AgentSpec` line in :data:`AGENTS`.

    >>> run_label("memory", agent_options("memory", rerank=False))
    'memory-norerank'
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from navbench.agents.options import (  # noqa: F401
    DEFAULT_CHECKPOINT,
    KEYFRAME_RES,
    AgentOptions,
    MemoryOptions,
    PerceptionOptions,
    PointNavOptions,
    PolicyOptions,
    RandomOptions,
    VLNMemoryOptions,
    decoding_of,
)
from navbench.episodes.types import Episode
from navbench.tasks import TASKS, get_task


# ------------------------------------------------------------------------------------------ factories
def make_oracle(cfg):
    from navbench.agents.oracle import OracleAgent
    return OracleAgent(cfg.scene_dir, cfg.success_distance, cfg.env_config(()))


def make_optimistic(cfg):
    from navbench.agents.oracle import OptimisticOracleAgent
    return OptimisticOracleAgent(cfg.scene_dir, cfg.success_distance, cfg.env_config(("depth",)))


def make_vln_random(cfg):
    from navbench.agents.vlnce import VLNRandomAgent
    return VLNRandomAgent(seed=cfg.seed)


def make_vln_forward(cfg):
    from navbench.agents.vlnce import VLNForwardAgent
    return VLNForwardAgent(seed=cfg.seed)


def make_vln_oracle(cfg):
    from navbench.agents.vlnce import ReferencePathOracle
    return ReferencePathOracle(cfg.scene_dir, cfg.env_config(()))


def make_vln_memory(cfg):
    from navbench.agents.vlnce import InstructionMemoryAgent
    # one episode at a time (envs_per_worker 1); without GPS+compass it tracks its pose from actions and depth
    return InstructionMemoryAgent(make_memory(cfg), cfg.env_config(("depth",)),
                                  _options(cfg, VLNMemoryOptions).instruction)


def make_random(cfg):
    from navbench.agents.random_agent import RandomAgent
    return RandomAgent(cfg.success_distance, seed=cfg.seed)


def _options(cfg, cls: type[AgentOptions]) -> Any:
    """The typed options of the run's ``agent_options`` record."""
    return cls.from_record(cfg.agent_options)


def _device(cfg) -> str:
    """The run's resolved device (``"cpu"``, ``"cuda:N"``): where the policy and the real models run."""
    return getattr(cfg, "device", "cpu")


def _inference_config(cfg):
    """How the PointNav policy picks actions, for every agent that drives with it."""
    from navbench.policy.net import InferenceConfig
    o = _options(cfg, PolicyOptions)
    return InferenceConfig(decoding=o.decoding, temperature=o.sampling_temperature)


def make_pointnav(cfg):
    from navbench.agents.pointnav import PointNavAgent
    env = cfg.env_config(("depth",))
    return PointNavAgent(_options(cfg, PolicyOptions).checkpoint, _inference_config(cfg),
                         num_envs=max(1, cfg.envs_per_worker), seed=cfg.seed, device=_device(cfg),
                         step=(env.forward_step, env.turn_angle_deg),
                         depth=(env.min_depth, env.max_depth, env.normalize_depth))


def scan_config(keyframe_res: str, all_frames: bool):
    """The pre-scan for a ``--keyframe-res`` choice: the agent's 224x224 camera stored as rendered or
    downsampled to 160x120, or a 640x480 phone-like scan camera; ``all_frames`` keeps every frame."""
    from navbench.memory.prescan import PrescanConfig
    scan = {"full": PrescanConfig(), "160x120": PrescanConfig(store_resolution=(160, 120)),
            "640x480": PrescanConfig(width=640, height=480)}[keyframe_res]
    return dataclasses.replace(scan, keyframes=not all_frames)


def _perception_config(cfg):
    """Perception of the memory and frontier agents (the frontier agent's options keep the memory
    agent's ablations at their defaults)."""
    from navbench.agents.perceive import PerceptionConfig
    from navbench.localize.benchmark import model_dirs

    o = _options(cfg, MemoryOptions)
    models = model_dirs(o.models(), _device(cfg), getattr(cfg, "precision", "fp32"))
    return PerceptionConfig(perception=o.perception, noise=o.noise, fusion=o.fusion, rerank=o.rerank,
                            prescan=scan_config(o.keyframe_res, o.all_frames), memory_root=o.memory_root,
                            models=models)


def _step_policy(cfg, num_envs: int = 1):
    from navbench.policy.checkpoint import load_checkpoint
    from navbench.policy.net import PointNavAgentPolicy
    return PointNavAgentPolicy(load_checkpoint(_options(cfg, PolicyOptions).checkpoint or DEFAULT_CHECKPOINT),
                               num_envs=num_envs, config=_inference_config(cfg), device=_device(cfg), frozen=True)


def _driving(cfg, build: Callable[[Any], Any]):
    """``build(policy)``: one agent driving with ``policy``; with ``envs_per_worker`` > 1, that many agents
    stepped in lockstep over one batched policy (:mod:`navbench.agents.lockstep`)."""
    n = max(1, cfg.envs_per_worker)
    if n == 1:
        return build(_step_policy(cfg))
    from navbench.agents.lockstep import LockstepAgent
    return LockstepAgent(_step_policy(cfg, n), build)


def make_memory(cfg):
    from navbench.agents.memory_agent import MemoryAgent, MemoryAgentConfig
    from navbench.agents.perceive import LiveDetector, SceneLocalizer
    o = _options(cfg, MemoryOptions)
    agent_cfg = MemoryAgentConfig(goal_tracking=o.goal_tracking, visibility_stop=o.visibility_stop,
                                  image_look_round=o.look_round)
    pcfg = _perception_config(cfg)
    # Camera and depth range for the agent and its arrival check; what the env renders is the agent's
    # `sensors` (depth, plus the image the detector segments), which the runner reads off the agent.
    env_cfg = cfg.env_config(("depth",))

    def build(policy):
        localizer = SceneLocalizer(cfg.scene_dir, pcfg, env_cfg)
        agent = MemoryAgent(localizer, policy, agent_cfg, env_cfg, verify=LiveDetector(cfg.scene_dir, pcfg, env_cfg),
                            route=localizer.route_lengths, route_path=localizer.route_path,
                            surfaces=localizer.surfaces, seed=cfg.seed)
        if o.look_round and getattr(cfg, "task", None) == "imagenav" and "rgb" not in agent.sensors:
            agent.sensors += ("rgb",)  # its look round on arrival reads the colours of walls and floors
        return agent
    return _driving(cfg, build)


def make_frontier(cfg):
    from navbench.agents.frontier import FrontierAgent, FrontierAgentConfig
    from navbench.agents.perceive import LiveDetector
    env_cfg = cfg.env_config(FrontierAgentConfig().sensors)
    pcfg = _perception_config(cfg)
    return _driving(cfg, lambda policy: FrontierAgent(LiveDetector(cfg.scene_dir, pcfg, env_cfg), policy,
                                                      FrontierAgentConfig(), env_cfg, seed=cfg.seed))


def prebuild_memories(cfg, episodes: Iterable[Episode]) -> None:
    """Build the memory agent's memories of the scenes of ``episodes`` once, in this process, before
    workers start: two workers must never build the same cache directory at the same time."""
    from navbench.agents.perceive import scene_memory
    from navbench.env.base import resolve_scene_path

    pcfg = _perception_config(cfg)
    for scene_id in dict.fromkeys(e.scene_id for e in episodes):
        m = scene_memory(resolve_scene_path(scene_id, Path(cfg.scene_dir)), pcfg)
        st = m.stats
        print(f"memory {scene_id}: {st.keyframes}/{st.frames} keyframes, {st.bytes / 1e6:.2f} MB, "
              f"built in {st.build_seconds:.2f} s" + ("" if m.built_now else " (cached)"), file=sys.stderr)


def _checkpoint_file(cfg) -> dict[str, Path]:
    """The policy checkpoint a policy agent reads, as the option that names it."""
    return {"checkpoint": Path(_options(cfg, PolicyOptions).checkpoint or DEFAULT_CHECKPOINT)}


def _memory_files(cfg, scene_path: Path) -> list[tuple[str, Path]]:
    """The memory agent's keyframe memory of a scene as the driver has it (built now if missing), as
    (path under the memory root, file)."""
    from navbench.agents.perceive import scene_memory

    directory = scene_memory(scene_path, _perception_config(cfg)).directory
    return [(str(Path(directory.name) / f.relative_to(directory)), f)
            for f in sorted(directory.rglob("*")) if f.is_file()]


# ---------------------------------------------------------------------------------------------- specs
@dataclass(frozen=True)
class AgentSpec:
    """Everything the harness knows of one built-in agent.

    Calling a spec builds the agent: ``spec(cfg)`` is ``spec.factory(cfg)``.
    """
    name: str
    factory: Callable[[Any], Any]
    options: type[AgentOptions] = AgentOptions
    help: str = ""
    # Episodes a worker steps at once when not told (one batched policy forward pass for all of them;
    # records do not depend on it); 1: the agent steps one episode at a time and cannot batch.
    envs_per_worker: int = 1
    # Run in the driver before any worker starts, with the run's config and selected episodes.
    prepare: Callable[[Any, list[Episode]], None] | None = None
    # Files a remote worker needs: run-wide, as option -> file (the worker's option then names its copy) ...
    run_files: Callable[[Any], dict[str, Path]] | None = None
    # ... and per scene, as (path under a directory, file), the directory named by option ``scene_option``.
    scene_files: Callable[[Any, Path], list[tuple[str, Path]]] | None = None
    scene_option: str | None = None
    # Explores the house for its goal: `navbench viz` shades the cells its depth camera saw unless told not to.
    explores: bool = False
    # Works without GPS+compass (EnvConfig.gps_compass false: Habitat's PointNav challenges).
    gps_free: bool = False
    # Reads the simulator beyond the configuration's sensors (the scene's geodesics or navigability, goals in world
    # coordinates, its true pose through `agent_pose`, as habitat-lab's ShortestPathFollower reads
    # sim.get_agent_state()): a ceiling, never a task's default; it runs under every configuration of its task.
    privileged: bool = False
    # Back-projects depth with a level camera, so cannot run with a pitched one (EnvConfig.camera_pitch_deg).
    level_camera: bool = False
    # The goal observations it navigates to (a task must give one of them); empty: any task's (it plans from
    # the episode's goals, as the oracle does).
    goals: tuple[str, ...] = ()

    def __call__(self, cfg: Any) -> Any:
        return self.factory(cfg)

    @property
    def drives_policy(self) -> bool:
        """Whether the agent drives with the PointNav policy (takes a checkpoint and a decoding)."""
        return issubclass(self.options, PolicyOptions)

    @property
    def batches(self) -> bool:
        return self.envs_per_worker > 1


_POLICY_FILES = dict(run_files=_checkpoint_file, envs_per_worker=8)
_POINT_GOALS = ("pointgoal_with_gps_compass", "pointgoal")
_OBJECT_GOALS = ("objectgoal",)
# the memory agent localises an image or a description as it does a category (navbench.agents.perceive.goal_query),
# and an ImageNav goal image's camera (SceneLocalizer.image_goal)
_MEMORY_GOALS = (*_OBJECT_GOALS, "imagegoal", "instance_imagegoal", "current_subtask", "subtask_category",
                 "subtask_description", "subtask_image")
AGENTS: dict[str, AgentSpec] = {s.name: s for s in (
    AgentSpec("oracle", make_oracle, help="follows the geodesic shortest path on the scene's map (a ceiling)",
              privileged=True),
    AgentSpec("optimistic", make_optimistic, help="plans to the goal's world position on the true map of the "
              "cells its depth has seen (PointNav; a learner's ceiling)", level_camera=True, goals=_POINT_GOALS,
              privileged=True),
    AgentSpec("random", make_random, RandomOptions, help="Habitat's random agent", gps_free=True),
    AgentSpec("pointnav", make_pointnav, PointNavOptions, help="the PointNav policy (without GPS+compass it "
              "dead-reckons from its own actions)", gps_free=True, goals=_POINT_GOALS, **_POLICY_FILES),
    AgentSpec("memory", make_memory, MemoryOptions, help="keyframe memory of a pre-scan, localisation, then the "
              "PointNav policy (perception: ground-truth instance ids unless --perception names models)",
              prepare=prebuild_memories, scene_files=_memory_files, scene_option="memory_root", level_camera=True,
              goals=_MEMORY_GOALS, **_POLICY_FILES),
    AgentSpec("frontier", make_frontier, PerceptionOptions, help="frontier exploration with a live detector "
              "(perception: ground-truth instance ids unless --perception names models)",
              explores=True, level_camera=True, goals=(*_OBJECT_GOALS, "instance_imagegoal", "current_subtask"),
              **_POLICY_FILES),
    AgentSpec("vln_random", make_vln_random, RandomOptions, help="VLN-CE's RandomAgent: actions drawn from the "
              "R2R training set's oracle distribution", gps_free=True),
    AgentSpec("vln_forward", make_vln_forward, RandomOptions, help="VLN-CE's HandcraftedAgent: a random heading, "
              "37 steps forward, STOP", gps_free=True),
    AgentSpec("vln_oracle", make_vln_oracle, help="follows a VLN episode's reference path on the scene's map "
              "(a ceiling)", privileged=True),
    AgentSpec("vln_memory", make_vln_memory, VLNMemoryOptions, help="localises a VLN instruction's last landmark, "
              "in the room the route enters, in the keyframe memory, then the PointNav policy (pose from actions and "
              "depth without GPS+compass)", prepare=prebuild_memories, scene_files=_memory_files,
              scene_option="memory_root", level_camera=True, run_files=_checkpoint_file, gps_free=True,
              goals=("instruction",)),
)}
# The decoding each policy agent is run (and reported) with when none is given.
DEFAULT_DECODING = {n: s.options().decoding for n, s in AGENTS.items() if s.drives_policy}
DEFAULT_TASK_AGENT = {name: t.default_agent for name, t in TASKS.items()}  # `navbench run` without --agent


def is_privileged(agent: str | None) -> bool:
    """Whether ``agent`` is a built-in privileged agent (:attr:`AgentSpec.privileged`): only those are given the
    simulator's pose (``agent_pose``); a plug-in or a served agent never is."""
    spec = AGENTS.get(agent) if isinstance(agent, str) else None
    return spec is not None and spec.privileged


def check_conditions(agent: str | None, task: str, env: Any) -> None:
    """A one-line ValueError when built-in ``agent`` cannot run under ``env`` (an EnvConfig): a non-privileged
    agent that knows its pose from GPS+compass under a configuration without them (a privileged one reads the
    simulator's pose), or one that back-projects depth with a level camera under a pitched one. Plug-ins and
    remote agents are not checked."""
    spec = AGENTS.get(agent) if agent is not None else None
    if spec is None:
        return
    if not env.gps_compass and not spec.gps_free and not spec.privileged:
        given = {s.uuid for s in TASKS[task].sensors(env)} if task in TASKS else set()
        free = [n for n, s in AGENTS.items() if s.gps_free and (not s.goals or set(s.goals) & given or not given)]
        raise ValueError(f"agent {agent!r} knows its pose from GPS+compass, which this configuration does not "
                         f"give (gps_compass = false); run it under one that does, or use --agent "
                         f"{' or '.join(free)}")
    if env.camera_pitch_deg != 0.0 and spec.level_camera:
        raise ValueError(f"agent {agent!r} maps depth with a level camera: it cannot run with camera_pitch_deg "
                         f"{env.camera_pitch_deg:g}")


def check_task(agent: str | None, task: str, env: Any) -> None:
    """A one-line ValueError when built-in ``agent`` navigates to none of the goals ``task`` gives under ``env``
    (an EnvConfig). Plug-ins and remote agents are not checked."""
    spec = AGENTS.get(agent) if agent is not None else None
    if spec is None or not spec.goals or task not in TASKS:
        return
    given = [s.uuid for s in TASKS[task].sensors(env)]
    if not set(spec.goals) & set(given):
        fits = [t.name for t in TASKS.values() if set(spec.goals) & {s.uuid for s in t.goal_sensors}]
        able = [name for name, s in AGENTS.items() if set(s.goals) & set(given)] or [TASKS[task].default_agent]
        raise ValueError(f"agent {agent!r} reads its goal from {' or '.join(spec.goals)}; task {task!r} gives "
                         f"{', '.join(given) or 'none'}: run it with --task {' or '.join(fits)}, or choose "
                         f"another agent ({task}'s: {', '.join(dict.fromkeys([TASKS[task].default_agent, *able]))})")


def agent_spec(name: str) -> AgentSpec:
    """The spec of built-in agent ``name``; a ValueError naming the choices for an unknown one."""
    if name not in AGENTS:
        raise ValueError(f"unknown agent {name!r}: choose from {', '.join(AGENTS)}")
    return AGENTS[name]


agent_factory = agent_spec  # a spec is its agent's factory


def default_agent(task: str) -> str:
    """The benchmark's own strongest non-privileged method for ``task`` (its ``Task.default_agent``): the policy
    for PointNav, ``vln_memory`` for VLN-CE, the memory agent for the other tasks."""
    return get_task(task).default_agent


def loads_models(agent: str, options: dict[str, Any]) -> bool:
    """Whether ``agent`` with these options loads the real perception models (not the oracle): a run then
    keeps to one worker per machine by default, so each model is loaded once."""
    spec = AGENTS.get(agent)
    return spec is not None and issubclass(spec.options, PerceptionOptions) \
        and options.get("perception") not in (None, "oracle")


def agent_options(agent: str, **options: Any) -> dict[str, Any]:
    """Everything that changes ``agent``'s behaviour, with its defaults filled in, as a run's config.json
    records it. ``None`` means not given; an option the agent does not read, or a bad value, is a
    one-line ValueError.

    Args:
        agent: a built-in agent's name.
        **options: its options by field name (``models`` may be given as a dict of model directories).

    Returns:
        The ``agent_options`` record.

    >>> agent_options("pointnav")
    {'decoding': 'least-tried'}
    """
    spec = agent_spec(agent)
    given = {k: v for k, v in options.items() if v is not None}
    return spec.options.from_user(given, agent).to_record()


def run_label(agent: str, options: dict[str, Any], seed: int = 0) -> str:
    """A run's name: the agent, then what differs from its defaults, in a fixed order: the checkpoint's
    stem, the decoding (``sample_t0.5`` with a temperature), ``seedN`` (when the agent draws), the
    perception, the noise profile, then ``norerank``, ``nofusion``, ``notrack``, ``novisstop``, the
    keyframe resolution, ``allframes`` and ``nolookround``; e.g. ``pointnav``, ``pointnav-argmax``,
    ``pointnav-pointnav_2h-seed3``, ``memory-norerank``, ``memory-noise_default``.

    Args:
        agent: a built-in agent's name.
        options: its ``agent_options`` record.
        seed: the run's seed.

    Returns:
        The label, which is also the run directory's default name.
    """
    return "-".join([agent, *agent_spec(agent).options.from_record(options).label_parts(agent, seed)])
