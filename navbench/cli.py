"""The ``navbench`` command: a thin layer over the library.

    navbench run --split val_unseen [--task objectnav] [--agent oracle] [--limit N] [--out DIR] [--resume]
    navbench table RUN_DIR... [--format markdown|csv|latex]
    navbench generate scenes|episodes|policy-train|policy-select [--seed 0]
    navbench train encoder|pointnav|ppo [--out PATH] [--resume]
    navbench memory build --scene houses/val/house_008.glb
    navbench localize --split goat_val --perception oracle [--noise default] [--no-fusion] [-k 5]
    navbench bench [--json] [--scan DIR]

Bad input (missing scene, corrupt JSON, unknown category, bad checkpoint...) prints one line naming
the file and the problem and exits with code 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from navbench.env.config import SUCCESS_DISTANCE
from navbench.paths import EPISODES_DIR, SCENES_DIR, split_file

# `select`: houses of their own for choosing among trained policies, so `val` is looked at once, to report
POINTNAV_SPLITS = ("train", "val", "select")
OBJECTNAV_SPLITS = ("train", "val_seen", "val_seen_synonyms", "val_unseen")
OVON_SPLITS = ("train", "val_seen", "val_seen_synonyms", "val_unseen")  # navbench's ObjectNav splits


# ------------------------------------------------------------------------------------ agent choices
# Top-level functions (not lambdas) so worker processes can unpickle them.
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


def _inference_config(cfg):
    """How the PointNav policy picks actions (argmax unless --sample-actions), for every agent that drives with it."""
    from navbench.policy.net import InferenceConfig
    o = cfg.agent_options
    return InferenceConfig(sample=o.get("sample_actions", False), temperature=o.get("temperature", 1.0),
                           sample_on_revisit=o.get("sample_on_revisit", False), least_tried=o.get("least_tried", False))


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


def _step_policy(cfg):
    from navbench.agents.pointnav import DEFAULT_CHECKPOINT
    from navbench.policy.checkpoint import load_checkpoint
    from navbench.policy.net import PointNavAgentPolicy
    return PointNavAgentPolicy(load_checkpoint(cfg.agent_options.get("checkpoint") or DEFAULT_CHECKPOINT),
                               config=_inference_config(cfg))


def make_memory(cfg):
    from navbench.agents.memory_agent import MemoryAgent, MemoryAgentConfig
    from navbench.agents.perceive import LiveDetector, SceneLocalizer
    o = cfg.agent_options
    agent_cfg = MemoryAgentConfig(goal_tracking=o.get("goal_tracking", True),
                                  visibility_stop=o.get("visibility_stop", True),
                                  recovery_turns=MemoryAgentConfig.recovery_turns if o.get("recovery", True) else 0,
                                  goal_standoff=MemoryAgentConfig.goal_standoff if o.get("standoff", True) else 0.0,
                                  view_detour=o.get("detour", True),
                                  recovery_probes=MemoryAgentConfig.recovery_probes if o.get("probe", True) else 0,
                                  route_guidance=o.get("guidance", True))
    pcfg = _perception_config(cfg)
    # Camera and depth range for the agent and its arrival check; what the env renders is the agent's
    # `sensors` (depth, plus the image the detector segments), which the runner reads off the agent.
    env_cfg = cfg.env_config(("depth",))
    verify = LiveDetector(cfg.scene_dir, pcfg, env_cfg) if o.get("verify", True) else None
    localizer = SceneLocalizer(cfg.scene_dir, pcfg)
    route = localizer.route_lengths if o.get("route", True) else None
    return MemoryAgent(localizer, _step_policy(cfg), agent_cfg, env_cfg, verify=verify, route=route,
                       route_path=localizer.route_path, seed=cfg.seed)


def make_frontier(cfg):
    from navbench.agents.frontier import FrontierAgent, FrontierAgentConfig
    from navbench.agents.perceive import LiveDetector
    env_cfg = cfg.env_config(FrontierAgentConfig().sensors)
    return FrontierAgent(LiveDetector(cfg.scene_dir, _perception_config(cfg), env_cfg), _step_policy(cfg),
                         FrontierAgentConfig(), env_cfg, seed=cfg.seed)


AGENTS = {"oracle": make_oracle, "optimistic": make_optimistic, "random": make_random, "pointnav": make_pointnav,
          "memory": make_memory, "frontier": make_frontier}


def prebuild_memories(cfg) -> None:
    """Build the memory agent's per-scene memories once, in this process, before workers start: two
    workers must never build the same cache directory at the same time."""
    from navbench.agents.perceive import scene_memory
    from navbench.env.base import resolve_scene_path
    from navbench.episodes.io import load_dataset
    from navbench.eval.runner import select_episodes

    pcfg = _perception_config(cfg)
    scenes = dict.fromkeys(e.scene_id for e in select_episodes(load_dataset(cfg.episodes), cfg.limit, cfg.per_scene))
    for scene_id in scenes:
        m = scene_memory(resolve_scene_path(scene_id, Path(cfg.scene_dir)), pcfg)
        st = m.stats
        print(f"memory {scene_id}: {st.keyframes}/{st.frames} keyframes, {st.bytes / 1e6:.2f} MB, "
              f"built in {st.build_seconds:.2f} s" + ("" if m.built_now else " (cached)"), file=sys.stderr)


# ------------------------------------------------------------------------------------------ commands
def cmd_run(args) -> int:
    from navbench.eval.runner import RunConfig, run
    from navbench.eval.table import summary_markdown

    if args.agent is not None and args.agent not in AGENTS:
        raise ValueError(f"unknown agent {args.agent!r}: choose from {', '.join(AGENTS)}")
    task = args.task
    if args.episodes:
        episodes = Path(args.episodes)
        split = args.split
        if task is None:
            from navbench.episodes.io import load_dataset
            task = load_dataset(episodes).task
        default_sd = SUCCESS_DISTANCE[task]
    else:
        split = args.split or "val_unseen"
        if task is None:
            # ObjectNav unless the split exists only for PointNav ("val")
            task = "pointnav" if split in POINTNAV_SPLITS and split not in OBJECTNAV_SPLITS else "objectnav"
        valid = POINTNAV_SPLITS if task == "pointnav" else OBJECTNAV_SPLITS
        if split not in valid:
            raise ValueError(f"unknown {task} split {split!r}: choose from {', '.join(valid)}")
        episodes = split_file(task, split)
        default_sd = SUCCESS_DISTANCE["ovon"] if task == "objectnav" and split in OVON_SPLITS \
            else SUCCESS_DISTANCE[task]
    # The benchmark's own methods by default: the memory agent for ObjectNav, the policy for PointNav.
    args.agent = args.agent or ("memory" if task == "objectnav" else "pointnav")
    cfg = RunConfig(
        task=task, split=split, agent=args.agent, episodes=str(episodes),
        scene_dir=str(args.scene_dir or SCENES_DIR),
        success_distance=args.success_distance if args.success_distance is not None else default_sd,
        seed=args.seed, limit=args.limit, per_scene=args.per_scene, workers=args.workers,
        # batched policy inference: default 8 episodes per worker for the pointnav agent
        envs_per_worker=args.envs_per_worker or (8 if args.agent == "pointnav" else 1),
        agent_options=_agent_options(args),
    )
    cfg.label = _label(args, cfg)
    out = Path(args.out or Path("runs") / f"{cfg.label}_{task}_{split or episodes.stem}")

    def progress(rec, n, total):
        if args.quiet:
            return
        status = "skipped" if rec.get("skipped") else f"success={rec['success']:.0f} spl={rec['spl']:.3f}"
        print(f"[{n}/{total}] {rec['scene_id']} ep {rec['episode_id']}: {status}", file=sys.stderr, flush=True)

    if args.agent == "memory":
        prebuild_memories(cfg)
    summary = run(cfg, AGENTS[args.agent], out, resume=args.resume, progress=progress)
    print(summary_markdown(summary))
    print(f"\nwrote {out}/episodes.jsonl, summary.json, config.json")
    return 0


def _agent_options(args) -> dict:
    """Everything that changes an agent's behaviour, recorded in the run's config.json."""
    opts = {"checkpoint": args.checkpoint}
    if args.sample_actions:  # recorded only when on: argmax runs keep their config
        if args.agent not in ("pointnav", "memory", "frontier"):
            raise ValueError(f"--sample-actions applies to the agents that drive with the PointNav policy "
                             f"(pointnav, memory, frontier), not {args.agent!r}")
        opts["sample_actions"] = True
    if args.temperature is not None:
        if not args.sample_actions:
            raise ValueError("--temperature sets how --sample-actions draws: give both")
        if not args.temperature > 0:
            raise ValueError(f"--temperature must be > 0, got {args.temperature}")
        opts["temperature"] = args.temperature
    if args.sample_on_revisit:
        if not args.sample_actions:
            raise ValueError("--sample-on-revisit sets when --sample-actions draws: give both")
        opts["sample_on_revisit"] = True
    if args.least_tried:
        if not args.sample_on_revisit:
            raise ValueError("--least-tried sets what --sample-on-revisit draws from: give both")
        opts["least_tried"] = True
    if args.agent in ("memory", "frontier"):
        opts.update(perception=args.perception, noise=args.noise, fusion=not args.no_fusion,
                    rerank=args.rerank != "none", keyframe_res=args.keyframe_res, all_frames=args.all_frames,
                    goal_tracking=not args.no_tracking, visibility_stop=not args.no_visibility_stop,
                    verify=not args.no_verify, recovery=not args.no_recovery, standoff=not args.no_standoff,
                    detour=not args.no_detour, route=not args.no_route, probe=not args.no_probe,
                    guidance=not args.no_guidance,
                    models={k: v for k, v in (("siglip2", args.siglip2), ("qwen_vl", args.qwen_vl),
                                              ("sam3", args.sam3)) if v})
    return {k: v for k, v in opts.items() if v is not None}


def _label(args, cfg) -> str:
    """Table row name: the agent plus any ablation that changes it (e.g. memory-norerank-noise_default)."""
    o = cfg.agent_options
    parts = [args.agent]
    if args.agent in ("memory", "frontier"):
        parts += [tag for tag, on in (("norerank", not o["rerank"]), ("nofusion", not o["fusion"]),
                                      ("notrack", not o["goal_tracking"]), ("novisstop", not o["visibility_stop"]),
                                      ("noverify", not o.get("verify", True)),
                                      ("norecover", not o.get("recovery", True)),
                                      ("nostandoff", not o.get("standoff", True)),
                                      ("nodetour", not o.get("detour", True)), ("noroute", not o.get("route", True)),
                                      ("noprobe", not o.get("probe", True)),
                                      ("noguidance", not o.get("guidance", True)),
                                      ("allframes", o["all_frames"]))
                  if on]
        if o["noise"] != "none":
            parts.append(f"noise_{o['noise']}")
        if o["keyframe_res"] != "full":
            parts.append(o["keyframe_res"])
        if o["perception"] != "oracle":
            parts.append(o["perception"])
    if o.get("sample_actions"):
        parts.append("sampled" if o.get("temperature", 1.0) == 1.0 else f"sampled_t{o['temperature']:g}")
        if o.get("sample_on_revisit"):
            parts.append("revisit")
        if o.get("least_tried"):
            parts.append("leasttried")
    return "-".join(parts)


def cmd_table(args) -> int:
    from navbench.eval.table import render, runs_frame
    print(render(runs_frame(args.run_dirs, wide=not args.long, first=args.first), args.format))
    return 0


def cmd_generate(args) -> int:
    if args.what == "scenes":
        from navbench.scene.procedural import generate_dataset
        generate_dataset(Path(args.out or SCENES_DIR / "houses"), seed=args.seed)
    elif args.what == "policy-train":  # the PointNav policy's extra houses and its train_large episodes
        from navbench.episodes.generate import generate_policy_train_split
        from navbench.scene.procedural import POLICY_TRAIN_HOUSES, generate_dataset
        h = POLICY_TRAIN_HOUSES
        generate_dataset(SCENES_DIR / h["dir"], n_train=h["n_train"], n_val=0, seed=h["seed"])
        generate_policy_train_split(Path(args.out or EPISODES_DIR), SCENES_DIR, seed=args.seed)
    elif args.what == "policy-select":  # houses and episodes for choosing among policies, never val
        from navbench.episodes.generate import generate_policy_select_split
        from navbench.scene.procedural import POLICY_SELECT_HOUSES, generate_dataset
        h = POLICY_SELECT_HOUSES
        generate_dataset(SCENES_DIR / h["dir"], n_train=0, n_val=h["n_val"], seed=h["seed"])
        generate_policy_select_split(Path(args.out or EPISODES_DIR), SCENES_DIR, seed=args.seed)
    else:
        from navbench.episodes.generate import generate_bundled_splits
        generate_bundled_splits(Path(args.out or EPISODES_DIR), SCENES_DIR, seed=args.seed)
    return 0


def cmd_train(args) -> int:
    from navbench.policy.precision import emulated_bf16_warning
    # ppo's --bf16 reaches only the encoder pass of a --train-encoder update (PPOConfig.bf16): without it
    # nothing runs in bf16, and warning that it would be slow would be wrong.
    bf16_flags = ("act_bf16",) if args.what == "ppo" and args.freeze_visual is not False else ("bf16", "act_bf16")
    warning = emulated_bf16_warning([f"--{n.replace('_', '-')}" for n in bf16_flags if getattr(args, n)])
    if warning:
        print(warning, file=sys.stderr)
    if args.what == "encoder":
        from navbench.policy.pretrain import main_args
        args.out = args.out or "runs/pointnav/encoder.pth"
        args.state_dir = args.state_dir or "runs/pointnav/encoder_state"
    elif args.what == "ppo":
        from navbench.policy.ppo import main_args
        args.out = args.out or "runs/pointnav/policy_ppo.pth"
        args.state_dir = args.state_dir or "runs/pointnav/ppo_state"
    else:
        from navbench.policy.train import main_args
        args.out = args.out or "policies/pointnav_navbench.pth"
        args.state_dir = args.state_dir or "runs/train_pointnav"
    return main_args(args)


def cmd_memory(args) -> int:
    from navbench.localize.backends.oracle import NoiseProfile
    from navbench.localize.benchmark import PERCEPTION, ModelDirs
    from navbench.memory.prescan import build_memory
    from navbench.scene.asset import load_scene

    scene = Path(args.scene)
    if not scene.is_file():
        scene = SCENES_DIR / args.scene
    scan = scan_config(args.keyframe_res, args.all_frames)
    encoder = PERCEPTION[args.perception](load_scene(scene), NoiseProfile(), ModelDirs(
        siglip2=Path(args.siglip2) if args.siglip2 else None)).encoder
    out = Path(args.out or Path("runs") / "memory" / scene.name.split(".")[0])
    st = build_memory(scene, out, scan, encoder)
    print(f"{scene}: {st.frames} frames, {st.keyframes} keyframes, {st.bytes / 1e6:.2f} MB on disk, "
          f"built in {st.build_seconds:.2f} s -> {out}")
    return 0


def cmd_localize(args) -> int:
    from navbench.localize.benchmark import ModelDirs, run_localize
    models = ModelDirs(**{k: Path(v) for k, v in (("siglip2", args.siglip2), ("qwen_vl", args.qwen_vl),
                                                  ("sam3", args.sam3)) if v})
    s = run_localize(split=args.split, perception=args.perception, noise=args.noise, fusion=not args.no_fusion,
                     rerank=args.rerank != "none", k=args.k, out=args.out, limit=args.limit, models=models)
    rows = " | ".join(f"{t} {100 * v:.1f}" for t, v in s["sr_by_type"].items())
    print(f"SR@{s['k']} ({s['perception']}, noise={s['noise']}, fusion={s['fusion']}, rerank={s['rerank']}): "
          f"{100 * s['sr']:.1f} avg | {rows}")
    print(f"memory: build {s['build_s']:.1f} s total, {s['storage_bytes'] / 1e6:.2f} MB; "
          f"query {s['query_ms']:.1f} ms mean")
    return 0


def cmd_bench(args) -> int:
    from navbench.bench import BenchConfig, format_report, run_bench
    if args.scan:
        from navbench.bench_scan import format_scan_report, run_scan_bench
        result = run_scan_bench(args.scan, seconds=args.seconds)
        print(json.dumps(result) if args.json else format_scan_report(result))
        return 0
    result = run_bench(BenchConfig(scene=args.scene, seconds=args.seconds, policy=not args.no_policy))
    print(json.dumps(result) if args.json else format_report(result))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="navbench", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="evaluate an agent on a split and print SR/SPL")
    r.add_argument("--split", help="bundled split (default val_unseen)")
    r.add_argument("--task", choices=("pointnav", "objectnav"))
    r.add_argument("--agent", help=f"one of: {', '.join(AGENTS)} (default: memory for ObjectNav, "
                                   "pointnav for PointNav)")
    r.add_argument("--episodes", help="a Habitat-format episode file (.json/.json.gz) instead of a bundled split")
    r.add_argument("--scene-dir", help="where episode scene_id paths are resolved (default: bundled envs/)")
    r.add_argument("--limit", type=int, help="first N episodes only")
    r.add_argument("--per-scene", type=int, help="first K episodes of each scene only (before --limit)")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--out", help="run directory (default runs/AGENT_TASK_SPLIT)")
    r.add_argument("--resume", action="store_true", help="skip episodes already in OUT/episodes.jsonl")
    r.add_argument("--success-distance", type=float)
    r.add_argument("--checkpoint", help="PointNav policy checkpoint in habitat's layout (default: the shipped one)")
    r.add_argument("--sample-actions", action="store_true",
                   help="pointnav, memory and frontier agents: sample the PointNav policy's actions "
                        "(habitat-baselines' evaluation; seeded by --seed and the episode) instead of the argmax")
    r.add_argument("--temperature", type=float,
                   help="with --sample-actions: draw from softmax(logits / T) (default 1, the policy's own "
                        "distribution; lower is closer to the argmax)")
    r.add_argument("--sample-on-revisit", action="store_true",
                   help="with --sample-actions: take the argmax, and draw only at a pose the episode has "
                        "already been in (a refused step, a back-and-forth turn, a loop)")
    r.add_argument("--least-tried", action="store_true",
                   help="with --sample-on-revisit: draw only among the movements taken least often at that "
                        "pose (STOP keeps its probability)")
    m = r.add_argument_group("memory / frontier agents (perception and ablations)")
    m.add_argument("--perception", default="oracle", help="oracle | siglip2+qwen2.5-vl+sam3")
    m.add_argument("--noise", default="none", help="oracle noise profile: none | default | heavy")
    m.add_argument("--rerank", default="vlm", choices=("vlm", "none"), help="'none': skip VLM re-ranking")
    m.add_argument("--no-fusion", action="store_true", help="single-view backprojection (no multi-view fusion)")
    m.add_argument("--no-tracking", action="store_true", help="no dynamic goal tracking")
    m.add_argument("--no-visibility-stop", action="store_true", help="STOP on distance alone")
    m.add_argument("--no-verify", action="store_true", help="memory agent: no re-detection of the target before STOP")
    m.add_argument("--no-recovery", action="store_true",
                   help="memory agent: no recovery manoeuvre when stuck with no candidate left")
    m.add_argument("--no-standoff", action="store_true",
                   help="memory agent: the policy drives to the target point itself, not to a point short of it")
    m.add_argument("--no-detour", action="store_true",
                   help="memory agent: no detour to a keyframe's view of a target hidden behind a wall")
    m.add_argument("--no-route", action="store_true",
                   help="memory agent: order candidates by straight-line distance, not by route over the "
                        "keyframe poses")
    m.add_argument("--no-probe", action="store_true",
                   help="memory agent: a recovery whose first step is refused does not turn on to try other headings")
    m.add_argument("--no-guidance", action="store_true",
                   help="memory agent: stuck on a target, do not follow the memory's keyframe route to it")
    m.add_argument("--all-frames", action="store_true", help="store every pre-scan frame, not keyframes")
    m.add_argument("--keyframe-res", default="full", choices=("full", "640x480", "160x120"))
    m.add_argument("--siglip2", help="local SigLIP2 model directory")
    m.add_argument("--qwen-vl", help="local Qwen2.5-VL model directory")
    m.add_argument("--sam3", help="local SAM 3 model directory")
    r.add_argument("--envs-per-worker", type=int, help="episodes a worker steps at once with one batched "
                   "policy forward pass (pointnav agent; default 8)")
    r.add_argument("--workers", type=int, default=2, help="parallel episode workers (default 2)")
    r.add_argument("-q", "--quiet", action="store_true")
    r.set_defaults(func=cmd_run)

    t = sub.add_parser("table", help="render run summaries side by side")
    t.add_argument("run_dirs", nargs="+")
    t.add_argument("--format", default="markdown", choices=("markdown", "csv", "latex"))
    t.add_argument("--long", action="store_true", help="one row per run instead of agent x split")
    t.add_argument("--first", type=int, help="score every run on the first N episodes of its split only")
    t.set_defaults(func=cmd_table)

    g = sub.add_parser("generate", help="regenerate the bundled scenes or episodes, or the PointNav policy's "
                                        "extra training houses and episodes (policy-train) or its houses and "
                                        "episodes for choosing among policies (policy-select)")
    g.add_argument("what", choices=("scenes", "episodes", "policy-train", "policy-select"))
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--out")
    g.set_defaults(func=cmd_generate)

    tr = sub.add_parser("train", help="pre-train the PointNav depth encoder (encoder), train the policy "
                                      "by DAgger imitation of a shortest-path expert (pointnav) or fine-tune "
                                      "it with PPO on the PointNav reward (ppo)")
    tr.add_argument("what", choices=("encoder", "pointnav", "ppo"))
    tr.add_argument("--out", help="checkpoint (default runs/pointnav/encoder.pth | policies/pointnav_navbench.pth | "
                                  "runs/pointnav/policy_ppo.pth)")
    tr.add_argument("--state-dir", help="resumable training state (default runs/pointnav/encoder_state | "
                                        "runs/train_pointnav | runs/pointnav/ppo_state)")
    tr.add_argument("--resume", action="store_true")
    tr.add_argument("--iterations", type=int)
    tr.add_argument("--frames-per-iteration", type=int)
    tr.add_argument("--num-envs", type=int)
    tr.add_argument("--workers", type=int, help="pointnav/ppo: rollout processes sharing the envs (default 1: in "
                                                "this process; 2 collects ~1.4x faster on 2 cores)")
    tr.add_argument("--val-episodes", type=int)
    tr.add_argument("--epochs-per-iteration", type=float)
    tr.add_argument("--train-encoder", dest="freeze_visual", action="store_false", default=None,
                    help="train the visual encoder too (pointnav: truncated chunks + free-space auxiliary loss; "
                         "ppo: re-encoded depth, bf16 autocast)")
    tr.add_argument("--truncated", dest="full_episodes", action="store_false", default=None,
                    help="train on chunks of --chunk-len steps instead of whole episodes")
    tr.add_argument("--no-prev-action", dest="prev_action", action="store_false", default=None,
                    help="zero and freeze the previous-action embedding (against copycat policies)")
    tr.add_argument("--expert-margin", type=float, help="extra clearance (m) the geodesic expert keeps")
    tr.add_argument("--expert-success-distance", type=float,
                    help="where the expert says STOP (default 0.2 m; ppo --bc-weight: 0.1 m)")
    tr.add_argument("--expert", choices=("optimistic", "geodesic"), help="label source (default geodesic)")
    tr.add_argument("--beta0", type=float, help="oracle share of executed actions in the first iteration")
    tr.add_argument("--beta-min", type=float, help="floor of the oracle share (default 0.1; 0 = pure learner rollouts)")
    tr.add_argument("--random-action-prob", type=float,
                    help="share of random non-STOP actions in rollouts (default 0.08)")
    tr.add_argument("--max-episode-steps", type=int)
    tr.add_argument("--buffer-frames", type=int, help="aggregated DAgger buffer cap in frames, oldest episodes "
                                                      "dropped first (default 250000)")
    tr.add_argument("--train-split", help="PointNav split to roll out in (default train; train_large adds the "
                                          "40 houses of `navbench generate policy-train`)")
    tr.add_argument("--chunk-len", type=int)
    tr.add_argument("--batch-chunks", type=int)
    tr.add_argument("--lr", type=float)
    tr.add_argument("--lr-schedule", choices=("constant", "cosine"),
                    help="learning rate over the iterations (ppo: the updates after the critic warm-up): "
                         "constant (default) or cosine from --lr to --lr-min")
    tr.add_argument("--lr-min", type=float, help="the cosine schedule's last rate (default 1e-5; ppo: 0)")
    tr.add_argument("--collision-weight", type=float, help="loss weight of steps after a blocked FORWARD (default 1)")
    tr.add_argument("--endgame-weight", type=float, help="loss weight of steps within 0.75 m of the goal (default 1)")
    tr.add_argument("--turnaround-weight", type=float,
                    help="loss weight of steps where the expert still has 3 or more turns to make (default 1)")
    tr.add_argument("--init", help="start from this checkpoint's weights (e.g. to continue the shipped policy)")
    tr.add_argument("--seed", type=int)
    tr.add_argument("--updates", type=int, help="encoder: gradient updates; ppo: PPO updates (rollouts)")
    tr.add_argument("--rollout-steps", type=int, help="ppo: steps per env and update (default 128)")
    tr.add_argument("--critic-warmup", type=int, help="ppo: first updates that train only the value head (default 30)")
    tr.add_argument("--entropy-coef", type=float, help="ppo: entropy bonus (default 1e-3)")
    tr.add_argument("--waste-weight", type=float,
                    help="ppo: penalty per metre walked beyond the progress made (default 0: habitat's reward)")
    tr.add_argument("--success-spl", action="store_true", default=None,
                    help="ppo: scale the success bonus by the episode's SPL (default: a flat 2.5)")
    tr.add_argument("--collision-penalty", type=float,
                    help="ppo: reward penalty per refused MOVE_FORWARD (default 0: habitat's reward)")
    tr.add_argument("--encoder-lr-scale", type=float,
                    help="ppo --train-encoder: the encoder's rate as a fraction of the actor's (default 0.1)")
    tr.add_argument("--bc-weight", type=float,
                    help="ppo: weight of a cross-entropy term to the geodesic expert's actions (default 0: off)")
    tr.add_argument("--replay-failures", type=float,
                    help="ppo: probability that a finished episode is followed by a replay of an earlier failed one "
                         "(default 0: off)")
    tr.add_argument("--tight-starts", type=float,
                    help="pointnav/ppo: probability that a rollout episode starts from a random cell beside an "
                         "obstacle (within 0.1 m of the navigable edge) instead of its own start (default 0: off)")
    tr.add_argument("--bf16", action=argparse.BooleanOptionalAction, default=None,
                    help="bfloat16 autocast in the updates (encoder and pointnav: default off; ppo: only the encoder's "
                         "pass with --train-encoder, default on where the CPU has AVX512-BF16 or AMX, else off)")
    tr.add_argument("--act-bf16", action="store_true", default=None,
                    help="pointnav/ppo: bfloat16 autocast for the acting policy's encoder in rollouts (default off)")
    tr.add_argument("--frames-per-scene", type=int, help="encoder: rendered frames per train house")
    tr.add_argument("--batch-size", type=int, help="encoder: frames per update")
    tr.set_defaults(func=cmd_train)

    mem = sub.add_parser("memory", help="build a scene's keyframe memory (pre-scan, keyframes, index)")
    mem.add_argument("what", choices=("build",))
    mem.add_argument("--scene", required=True, help="scene file, or a path under envs/ (e.g. houses/val/house_008.glb)")
    mem.add_argument("--out")
    mem.add_argument("--perception", default="oracle", help="encoder of the index: oracle | siglip2+qwen2.5-vl+sam3")
    mem.add_argument("--keyframe-res", default="full", choices=("full", "640x480", "160x120"))
    mem.add_argument("--all-frames", action="store_true")
    mem.add_argument("--siglip2", help="local SigLIP2 model directory")
    mem.set_defaults(func=cmd_memory)

    lo = sub.add_parser("localize", help="GOAT-style localisation benchmark (SR@K)")
    lo.add_argument("--split", default="goat_val")
    lo.add_argument("--perception", default="oracle")
    lo.add_argument("--noise", default="none")
    lo.add_argument("--no-fusion", action="store_true")
    lo.add_argument("--rerank", default="vlm", choices=("vlm", "none"))
    lo.add_argument("-k", type=int, default=5)
    lo.add_argument("--limit", type=int)
    lo.add_argument("--out")
    lo.add_argument("--siglip2")
    lo.add_argument("--qwen-vl")
    lo.add_argument("--sam3")
    lo.set_defaults(func=cmd_localize)

    b = sub.add_parser("bench", help="simulator, geodesic and policy speed")
    b.add_argument("--json", action="store_true")
    b.add_argument("--scene", help="scene file (default: first bundled val scene)")
    b.add_argument("--seconds", type=float, default=3.0, help="time per measurement")
    b.add_argument("--no-policy", action="store_true", help="skip the policy inference figures")
    b.add_argument("--scan", metavar="DIR", help="scan-scale figures on the HM3D-layout scan fixture in DIR "
                                                "(made there first if missing; benchmarks/scan_fixture.py)")
    b.set_defaults(func=cmd_bench)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("navbench: interrupted; finished episodes are saved (rerun with --resume)", file=sys.stderr)
        return 130
    except (ValueError, FileNotFoundError, ImportError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"navbench: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
