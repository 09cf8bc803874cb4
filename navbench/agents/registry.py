"""The benchmark's agents by name: factories, their options with defaults, and the run label.

A factory takes the run's :class:`~navbench.eval.runner.RunConfig` (duck-typed: ``task``, ``scene_dir``,
``success_distance``, ``seed``, ``envs_per_worker``, ``agent_options``, ``env_config(sensors)``) and
returns a fresh agent. Factories are top-level functions so worker processes can unpickle them.

``agent_options(agent, ...)`` fills in each agent's defaults and refuses options the agent does not
use; ``run_label(agent, options, seed)`` names a run by what differs from those defaults.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from navbench.episodes.types import Episode

# ------------------------------------------------------------------------------------------- defaults
# Agents that drive with the PointNav policy: they take a checkpoint and a decoding.
POLICY_AGENTS = ("pointnav", "memory", "frontier")
# The decoding each policy agent is run (and reported) with when none is given:
DEFAULT_DECODING = {
    "pointnav": "least-tried",  # the PointNav table's headline figures are the shipped policy's with it
    "memory": "argmax",  # the ObjectNav tables are argmax; least-tried is a listed variant
    "frontier": "argmax",  # as the memory agent, so the two ObjectNav agents compare on one decoding
}
# Episodes a worker steps at once when none is given: the policy agents batch their PointNav forward pass
# over 8 env slots (records do not depend on it); the others run one episode at a time.
DEFAULT_ENVS_PER_WORKER = {agent: 8 for agent in POLICY_AGENTS}
# Perception of the ObjectNav agents (the memory agent's localiser, both agents' live detector).
PERCEPTION_DEFAULTS: dict[str, Any] = {"perception": "oracle", "noise": "none"}
# The memory agent's localisation and stopping ablations (all on = the agent as reported).
MEMORY_DEFAULTS: dict[str, Any] = {"fusion": True, "rerank": True, "keyframe_res": "full", "all_frames": False,
                                   "goal_tracking": True, "visibility_stop": True}
KEYFRAME_RES = ("full", "640x480", "160x120")


# ------------------------------------------------------------------------------------------ factories
def make_oracle(cfg):
    from navbench.agents.oracle import OracleAgent
    return OracleAgent(cfg.scene_dir, cfg.success_distance, cfg.env_config(()))


def make_optimistic(cfg):
    from navbench.agents.oracle import OptimisticOracleAgent
    if cfg.task != "pointnav":
        raise ValueError("agent 'optimistic' plans to a single goal point: use it with --task pointnav")
    return OptimisticOracleAgent(cfg.scene_dir, cfg.success_distance, cfg.env_config(("depth",)))


def make_random(cfg):
    from navbench.agents.random_agent import RandomAgent
    return RandomAgent(cfg.success_distance, seed=cfg.seed)


def decoding_of(options: dict[str, Any]) -> tuple[str, float]:
    """(decoding, temperature) of a run's agent options. ``navbench run`` always records ``decoding``; a
    config written before that option existed says it with ``sample_actions``/``sample_on_revisit``/
    ``least_tried`` flags (none: argmax), read here so its records can be rerun from it."""
    temperature = float(options.get("temperature", 1.0))
    if "decoding" in options:
        return options["decoding"], temperature
    if not options.get("sample_actions"):
        return "argmax", temperature
    if not options.get("sample_on_revisit"):
        return "sample", temperature
    if options.get("least_tried"):
        return "least-tried", temperature
    raise ValueError("agent_options draw on revisits only (sample_on_revisit without least_tried), a decoding "
                     "navbench no longer has: use decoding 'least-tried' or 'sample'")


def _inference_config(cfg):
    """How the PointNav policy picks actions, for every agent that drives with it."""
    from navbench.policy.net import InferenceConfig
    decoding, temperature = decoding_of(cfg.agent_options)
    return InferenceConfig(decoding=decoding, temperature=temperature)


def make_pointnav(cfg):
    from navbench.agents.pointnav import PointNavAgent
    return PointNavAgent(cfg.agent_options.get("checkpoint"), _inference_config(cfg),
                         num_envs=max(1, cfg.envs_per_worker), seed=cfg.seed)


def scan_config(keyframe_res: str, all_frames: bool):
    """The pre-scan for a ``--keyframe-res`` choice: the agent's 224x224 camera stored as rendered or
    downsampled to 160x120, or a 640x480 phone-like scan camera; ``all_frames`` keeps every frame."""
    from navbench.memory.prescan import PrescanConfig
    scan = {"full": PrescanConfig(), "160x120": PrescanConfig(store_resolution=(160, 120)),
            "640x480": PrescanConfig(width=640, height=480)}[keyframe_res]
    return dataclasses.replace(scan, keyframes=not all_frames)


def _perception_config(cfg):
    from navbench.agents.perceive import PerceptionConfig
    from navbench.localize.benchmark import ModelDirs

    o = cfg.agent_options
    scan = scan_config(o.get("keyframe_res", "full"), o.get("all_frames", False))
    models = ModelDirs(**{k: Path(v) for k, v in o.get("models", {}).items()})
    return PerceptionConfig(perception=o.get("perception", "oracle"), noise=o.get("noise", "none"),
                            fusion=o.get("fusion", True), rerank=o.get("rerank", True), prescan=scan,
                            memory_root=o.get("memory_root"), models=models)


def _step_policy(cfg, num_envs: int = 1):
    from navbench.agents.pointnav import DEFAULT_CHECKPOINT
    from navbench.policy.checkpoint import load_checkpoint
    from navbench.policy.net import PointNavAgentPolicy
    return PointNavAgentPolicy(load_checkpoint(cfg.agent_options.get("checkpoint") or DEFAULT_CHECKPOINT),
                               num_envs=num_envs, config=_inference_config(cfg))


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
    o = cfg.agent_options
    agent_cfg = MemoryAgentConfig(goal_tracking=o.get("goal_tracking", True),
                                  visibility_stop=o.get("visibility_stop", True))
    pcfg = _perception_config(cfg)
    # Camera and depth range for the agent and its arrival check; what the env renders is the agent's
    # `sensors` (depth, plus the image the detector segments), which the runner reads off the agent.
    env_cfg = cfg.env_config(("depth",))

    def build(policy):
        localizer = SceneLocalizer(cfg.scene_dir, pcfg)
        return MemoryAgent(localizer, policy, agent_cfg, env_cfg, verify=LiveDetector(cfg.scene_dir, pcfg, env_cfg),
                           route=localizer.route_lengths, route_path=localizer.route_path, seed=cfg.seed)
    return _driving(cfg, build)


def make_frontier(cfg):
    from navbench.agents.frontier import FrontierAgent, FrontierAgentConfig
    from navbench.agents.perceive import LiveDetector
    env_cfg = cfg.env_config(FrontierAgentConfig().sensors)
    pcfg = _perception_config(cfg)
    return _driving(cfg, lambda policy: FrontierAgent(LiveDetector(cfg.scene_dir, pcfg, env_cfg), policy,
                                                      FrontierAgentConfig(), env_cfg, seed=cfg.seed))


AgentFactory = Callable[[Any], Any]
AGENTS: dict[str, AgentFactory] = {"oracle": make_oracle, "optimistic": make_optimistic, "random": make_random,
                                   "pointnav": make_pointnav, "memory": make_memory, "frontier": make_frontier}


def agent_factory(name: str) -> AgentFactory:
    """The factory of agent ``name``; a ValueError naming the choices for an unknown one."""
    if name not in AGENTS:
        raise ValueError(f"unknown agent {name!r}: choose from {', '.join(AGENTS)}")
    return AGENTS[name]


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


# -------------------------------------------------------------------------------------------- options
def agent_options(agent: str, checkpoint: str | None = None, decoding: str | None = None,
                  temperature: float | None = None, models: dict[str, str] | None = None,
                  **choices: Any) -> dict[str, Any]:
    """Everything that changes ``agent``'s behaviour, with its defaults filled in, as a run's
    config.json records it. ``choices`` are the perception and ablation keys of PERCEPTION_DEFAULTS and
    MEMORY_DEFAULTS. Options the agent does not use raise a one-line ValueError (unless at default)."""
    agent_factory(agent)
    opts: dict[str, Any] = {}
    if agent not in POLICY_AGENTS and (checkpoint is not None or decoding is not None or temperature is not None):
        raise ValueError(f"--checkpoint, --decoding and --temperature apply to the agents that drive with the "
                         f"PointNav policy ({', '.join(POLICY_AGENTS)}), not {agent!r}")
    if agent in POLICY_AGENTS:
        from navbench.policy.net import InferenceConfig
        decoding = decoding or DEFAULT_DECODING[agent]
        if temperature is not None and decoding != "sample":
            raise ValueError(f"--temperature applies to decoding 'sample' only, not {decoding!r}")
        inference = InferenceConfig(decoding=decoding, temperature=1.0 if temperature is None else temperature)
        opts.update({"checkpoint": checkpoint} if checkpoint else {}, decoding=inference.decoding)
        if inference.decoding == "sample":
            opts["temperature"] = inference.temperature
    defaults = {**PERCEPTION_DEFAULTS, **MEMORY_DEFAULTS}
    unknown = set(choices) - set(defaults)
    if unknown:
        raise ValueError(f"unknown agent option(s): {', '.join(sorted(unknown))}")
    own = defaults if agent == "memory" else PERCEPTION_DEFAULTS if agent == "frontier" else {}
    for key, value in choices.items():
        if key not in own and value != defaults[key]:
            raise ValueError(f"agent option {key!r} does not apply to agent {agent!r}")
    if choices.get("keyframe_res", "full") not in KEYFRAME_RES:
        raise ValueError(f"unknown keyframe resolution {choices['keyframe_res']!r}: choose from "
                         f"{', '.join(KEYFRAME_RES)}")
    models = {k: v for k, v in (models or {}).items() if v}
    if models and not own:
        raise ValueError(f"model directories apply to the memory and frontier agents, not {agent!r}")
    if own:
        opts.update({k: choices.get(k, v) for k, v in own.items()}, models=models)
    return opts


def _seed_matters(agent: str, options: dict[str, Any]) -> bool:
    """Whether ``agent``'s actions depend on the run's seed: the random agent's always, a policy agent's
    when its policy draws actions."""
    return agent == "random" or (agent in POLICY_AGENTS and decoding_of(options)[0] != "argmax")


def run_label(agent: str, options: dict[str, Any], seed: int = 0) -> str:
    """A run's name: the agent, then what differs from its defaults, in a fixed order: the checkpoint's
    stem, the decoding (``sample_t0.5`` with a temperature), ``seedN``, the perception, the noise
    profile, then ``norerank``, ``nofusion``, ``notrack``, ``novisstop``, the keyframe resolution and
    ``allframes``; e.g. ``pointnav``, ``pointnav-argmax``, ``pointnav-pointnav_2h-seed3``,
    ``memory-norerank``, ``memory-noise_default``."""
    parts = [agent]
    if agent in POLICY_AGENTS:
        from navbench.agents.pointnav import DEFAULT_CHECKPOINT
        checkpoint = options.get("checkpoint")
        if checkpoint and Path(checkpoint).resolve() != DEFAULT_CHECKPOINT.resolve():
            parts.append(Path(checkpoint).stem)
        decoding, temperature = decoding_of(options)
        if decoding != DEFAULT_DECODING[agent] or temperature != 1.0:
            parts.append(f"sample_t{temperature:g}" if temperature != 1.0 else decoding)
    if seed != 0 and _seed_matters(agent, options):
        parts.append(f"seed{seed}")
    o = {**PERCEPTION_DEFAULTS, **MEMORY_DEFAULTS, **options}
    if o["perception"] != "oracle":
        parts.append(o["perception"])
    if o["noise"] != "none":
        parts.append(f"noise_{o['noise']}")
    parts += [tag for tag, on in (("norerank", not o["rerank"]), ("nofusion", not o["fusion"]),
                                  ("notrack", not o["goal_tracking"]), ("novisstop", not o["visibility_stop"]))
              if on]
    if o["keyframe_res"] != "full":
        parts.append(o["keyframe_res"])
    if o["all_frames"]:
        parts.append("allframes")
    return "-".join(parts)
