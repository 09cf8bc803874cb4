"""The ``navbench`` command: a thin layer over the library.

    navbench run --split val_unseen [--task objectnav] [--agent oracle] [--limit N] [--out DIR] [--resume]
    navbench table RUN_DIR... [--format markdown|csv|latex]
    navbench generate scenes|episodes [--seed 0]
    navbench train pointnav [--out policies/pointnav_navbench.pth] [--resume]
    navbench bench [--json]

Bad input (missing scene, corrupt JSON, unknown category, bad checkpoint...) prints one line naming
the file and the problem and exits with code 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from navbench.env.config import SUCCESS_DISTANCE
from navbench.paths import EPISODES_DIR, SCENES_DIR, split_file

POINTNAV_SPLITS = ("train", "val")
OBJECTNAV_SPLITS = ("train", "val_seen", "val_seen_synonyms", "val_unseen")
OVON_SPLITS = ("train", "val_seen", "val_seen_synonyms", "val_unseen")  # navbench's ObjectNav splits


# ------------------------------------------------------------------------------------ agent choices
# Top-level functions (not lambdas) so worker processes can unpickle them.
def make_oracle(cfg):
    from navbench.agents.oracle import OracleAgent
    return OracleAgent(cfg.scene_dir, cfg.success_distance, cfg.env_config(()))


def make_random(cfg):
    from navbench.agents.random_agent import RandomAgent
    return RandomAgent(cfg.success_distance, seed=cfg.seed)


def make_pointnav(cfg):
    from navbench.agents.pointnav import PointNavAgent
    return PointNavAgent(cfg.agent_options.get("checkpoint"))


AGENTS = {"oracle": make_oracle, "random": make_random, "pointnav": make_pointnav}


# ------------------------------------------------------------------------------------------ commands
def cmd_run(args) -> int:
    from navbench.eval.runner import RunConfig, run
    from navbench.eval.table import summary_markdown

    if args.agent not in AGENTS:
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
    cfg = RunConfig(
        task=task, split=split, agent=args.agent, episodes=str(episodes),
        scene_dir=str(args.scene_dir or SCENES_DIR),
        success_distance=args.success_distance if args.success_distance is not None else default_sd,
        seed=args.seed, limit=args.limit, workers=args.workers,
        agent_options={k: v for k, v in (("checkpoint", args.checkpoint),) if v is not None},
    )
    out = Path(args.out or Path("runs") / f"{args.agent}_{task}_{split or episodes.stem}")

    def progress(rec, n, total):
        if args.quiet:
            return
        status = "skipped" if rec.get("skipped") else f"success={rec['success']:.0f} spl={rec['spl']:.3f}"
        print(f"[{n}/{total}] {rec['scene_id']} ep {rec['episode_id']}: {status}", file=sys.stderr, flush=True)

    summary = run(cfg, AGENTS[args.agent], out, resume=args.resume, progress=progress)
    print(summary_markdown(summary))
    print(f"\nwrote {out}/episodes.jsonl, summary.json, config.json")
    return 0


def cmd_table(args) -> int:
    from navbench.eval.table import render, runs_frame
    print(render(runs_frame(args.run_dirs, wide=not args.long), args.format))
    return 0


def cmd_generate(args) -> int:
    if args.what == "scenes":
        from navbench.scene.procedural import generate_dataset
        generate_dataset(Path(args.out or SCENES_DIR / "houses"), seed=args.seed)
    else:
        from navbench.episodes.generate import generate_bundled_splits
        generate_bundled_splits(Path(args.out or EPISODES_DIR), SCENES_DIR, seed=args.seed)
    return 0


def cmd_train(args) -> int:
    from navbench.policy.train import main_args
    return main_args(args)


def cmd_bench(args) -> int:
    from navbench.bench import BenchConfig, format_report, run_bench
    result = run_bench(BenchConfig(scene=args.scene, seconds=args.seconds, policy=not args.no_policy))
    print(json.dumps(result) if args.json else format_report(result))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="navbench", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="evaluate an agent on a split and print SR/SPL")
    r.add_argument("--split", help="bundled split (default val_unseen)")
    r.add_argument("--task", choices=("pointnav", "objectnav"))
    r.add_argument("--agent", default="oracle", help=f"one of: {', '.join(AGENTS)}")
    r.add_argument("--episodes", help="a Habitat-format episode file (.json/.json.gz) instead of a bundled split")
    r.add_argument("--scene-dir", help="where episode scene_id paths are resolved (default: bundled envs/)")
    r.add_argument("--limit", type=int, help="first N episodes only")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--out", help="run directory (default runs/AGENT_TASK_SPLIT)")
    r.add_argument("--resume", action="store_true", help="skip episodes already in OUT/episodes.jsonl")
    r.add_argument("--success-distance", type=float)
    r.add_argument("--checkpoint", help="PointNav policy checkpoint in habitat's layout (default: the shipped one)")
    r.add_argument("--workers", type=int, default=2, help="parallel episode workers (default 2)")
    r.add_argument("-q", "--quiet", action="store_true")
    r.set_defaults(func=cmd_run)

    t = sub.add_parser("table", help="render run summaries side by side")
    t.add_argument("run_dirs", nargs="+")
    t.add_argument("--format", default="markdown", choices=("markdown", "csv", "latex"))
    t.add_argument("--long", action="store_true", help="one row per run instead of agent x split")
    t.set_defaults(func=cmd_table)

    g = sub.add_parser("generate", help="regenerate the bundled scenes or episodes")
    g.add_argument("what", choices=("scenes", "episodes"))
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--out")
    g.set_defaults(func=cmd_generate)

    tr = sub.add_parser("train", help="train the PointNav policy (DAgger imitation of the geodesic oracle)")
    tr.add_argument("what", choices=("pointnav",))
    tr.add_argument("--out", default="policies/pointnav_navbench.pth")
    tr.add_argument("--state-dir", default="runs/train_pointnav", help="resumable training state")
    tr.add_argument("--resume", action="store_true")
    tr.add_argument("--iterations", type=int)
    tr.add_argument("--frames-per-iteration", type=int)
    tr.add_argument("--num-envs", type=int)
    tr.add_argument("--val-episodes", type=int)
    tr.add_argument("--epochs-per-iteration", type=float)
    tr.add_argument("--seed", type=int)
    tr.set_defaults(func=cmd_train)

    b = sub.add_parser("bench", help="simulator, geodesic and policy speed")
    b.add_argument("--json", action="store_true")
    b.add_argument("--scene", help="scene file (default: first bundled val scene)")
    b.add_argument("--seconds", type=float, default=3.0, help="time per measurement")
    b.add_argument("--no-policy", action="store_true", help="skip the policy inference figures")
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
