"""The ``navbench`` command: a thin layer over the library.

    navbench run --split val_unseen [--task objectnav] [--agent memory] [--decoding argmax|sample|least-tried]
                 [--limit N] [--out DIR] [--resume | --overwrite] [--shard I/N] [--retries 2]
                 [--step-timeout SECONDS] [--fail-fast] [--backend local|ray [--address auto|HOST:PORT]]
    navbench run --agent package.module:Name|http://HOST:PORT|NAME [--agent-opt KEY=VALUE ...] ...
    navbench agents
    navbench tasks
    navbench serve-agent package.module:Name|NAME [--agent-opt KEY=VALUE ...] [--host 127.0.0.1] --port P
    navbench check-agent http://HOST:PORT [--task TASK] [--steps 200]
    navbench merge RUN_DIR... --out DIR
    navbench table RUN_DIR... [--format markdown|csv|latex] [--by scene|category]
    navbench compare BASE OTHER... [--json] [--metric spl] [--per-scene K]
    navbench protocol RUN_DIR [--format markdown|latex|json]
    navbench generate scenes|episodes|imagenav|instance_imagenav|goat|vlnce|policy-train|policy-select [--seed 0]
    navbench generate benchmark --houses 36 --episodes-per-split 3000 --out DIR [--seed 0]
    navbench generate habitat-test-data DIR [--overwrite] [--seed 0]
    navbench train --config configs/pointnav/2h.toml [--out-dir DIR] [--resume] [--only STAGE] [--out PATH]
    navbench train encoder|dagger|ppo [--FIELD VALUE ...] [--init PATH] [--out PATH] [--resume]
    navbench memory build --scene houses/val/house_008.glb
    navbench localize --split goat_val --perception oracle [--noise default] [--no-fusion] [-k 5]
    navbench bench [--json] [--seconds S] [--no-policy] [--no-tasks] [--scan DIR]

Bad input (missing scene, corrupt JSON, unknown category, bad checkpoint...) prints one line naming
the file and the problem and exits with code 2. `navbench run` exits with code 3 when it finished but
some episodes failed (their agent or env raised, a worker died...): they are listed in summary.json.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from contextlib import nullcontext
from pathlib import Path
from typing import Any

from navbench.agents.options import add_flags, flag_of, given_flags
from navbench.agents.plugins import parse_options, resolve_agent
from navbench.agents.registry import AGENTS, agent_options, default_agent, loads_models, scan_config
from navbench.api import env_config_line, resolve_episodes, run_dir  # noqa: F401  (run_dir: importable from here too)
from navbench.episodes.io import file_split
from navbench.loop_progress import silenced
from navbench.paths import EPISODES_DIR, SCENES_DIR
from navbench.tasks import TASKS, task_names


# ------------------------------------------------------------------------------------------ commands
def cmd_run(args) -> int:
    """``navbench run``: the flags as :func:`navbench.evaluate`'s arguments, then the summary printed."""
    from navbench.api import evaluate
    from navbench.eval.run_progress import Progress
    from navbench.eval.table import summary_markdown

    habitat = None
    if args.habitat_config:
        from navbench.eval.habitat_config import read_habitat_config, run_arguments
        if args.env_config:
            raise ValueError("--habitat-config and --env-config: choose one")
        habitat = read_habitat_config(args.habitat_config)
        args.task, args.episodes, args.scene_dir, args.success_distance = run_arguments(
            habitat, args.task, args.split, args.episodes, args.scene_dir, args.success_distance)
        if habitat.ignored:
            print(habitat.ignored_line(), file=sys.stderr)
    episodes = resolve_episodes(args.task, args.split, args.episodes)  # evaluate() takes it, not again
    task, split = episodes[:2]
    # what a named configuration changes (one for another task: refused), printed once the run is set to start
    changes = env_config_line(args.env_config, task, episodes[3]) if args.env_config else None
    args.agent = args.agent or default_agent(task)
    options = _agent_request(args)
    # real perception models load once per machine: one worker (its envs batched) unless told otherwise
    default_workers = 1 if loads_models(args.agent, options) else 2
    workers = args.workers if args.workers is not None or args.address is not None else default_workers
    where: list[Path] = []

    def starting(out: Path) -> None:
        where.append(out)
        if changes and not args.quiet:
            print(changes, file=sys.stderr)
    # -q: no run progress, and no loop progress either (memory pre-scans, workers)
    with warnings.catch_warnings(), silenced() if args.quiet else nullcontext():
        # failed episodes are reported below, in one line, with exit 3
        warnings.filterwarnings("ignore", r".* episode\(s\) failed", RuntimeWarning)
        summary = evaluate(
            args.agent, task, split, args.episodes, options=options, limit=args.limit, per_scene=args.per_scene,
            shard=args.shard, seed=args.seed, scene_dir=args.scene_dir, success_distance=args.success_distance,
            out=args.out, runs_dir=args.runs_dir, resume=args.resume, overwrite=args.overwrite, workers=workers,
            envs_per_worker=args.envs_per_worker, backend=args.backend, address=args.address, retries=args.retries,
            step_timeout=args.step_timeout, fail_fast=args.fail_fast, env_config=args.env_config,
            progress=None if args.quiet else Progress(),
            video=args.video, on_run_dir=starting, device=args.device, precision=args.precision,
            habitat_config=habitat, gt=args.gt, _episodes=episodes)
    out = where[0]
    print(summary_markdown({**summary, "split": split or file_split(args.episodes)}, out))
    print(f"\nwrote {out}/episodes.jsonl, summary.json, config.json")
    if summary["num_failed"]:
        print(f"navbench: {summary['num_failed']} episode(s) failed (listed in {out}/summary.json), e.g. "
              f"{summary['failed_episodes'][0]['episode_id']}: {summary['failed_episodes'][0]['failure_reason']}",
              file=sys.stderr)
        return 3
    return 0


# Every built-in agent's option flags (field name -> field), added to `navbench run` by build_parser.
AGENT_FLAGS: dict[str, Any] = {}


def _agent_request(args) -> dict:
    """The agent's options from its flags and ``--agent-opt``: a flag the chosen agent does not read is a
    one-line ValueError naming it (a plug-in or remote agent reads ``--agent-opt`` only)."""
    given = given_flags(args, AGENT_FLAGS)
    spec = AGENTS.get(args.agent)
    reads = [f.name for f in spec.options.user_fields()] if spec is not None else []
    stray = [flag_of(AGENT_FLAGS[name]) for name in given if name not in reads]
    if stray:
        if spec is None:
            why = "a plug-in or remote agent takes --agent-opt KEY=VALUE only"
        else:
            first = next(name for name in given if name not in reads)
            readers = [n for n, s in AGENTS.items() if first in {f.name for f in s.options.user_fields()}]
            why = f"{stray[0]} is read by {', '.join(readers)}"
        raise ValueError(f"{', '.join(stray)}: not read by agent {args.agent!r} ({why})")
    return {**given, **parse_options(args.agent_opt)}


def cmd_merge(args) -> int:
    from navbench.eval.merge import merge
    from navbench.eval.table import summary_markdown

    summary = merge([Path(d) for d in args.run_dirs], Path(args.out), overwrite=args.overwrite)
    print(summary_markdown(summary, args.out))
    print(f"\nwrote {args.out}/episodes.jsonl, summary.json, config.json")
    return 3 if summary["num_failed"] else 0


def _agent_options(args) -> dict:
    """Everything that changes a built-in agent's behaviour, as its run's config.json records it."""
    return agent_options(args.agent, **_agent_request(args))


def cmd_agents(args) -> int:
    from navbench.agents.plugins import available_agents
    rows = available_agents()
    width = max(len(r["name"]) for r in rows)
    for r in rows:  # a built-in: what it is and whether it reads the simulator beyond the sensors
        spec = AGENTS.get(r["name"]) if r["source"] == "built-in" else None
        if spec is not None:
            kind = "built-in, " + ("privileged" if spec.privileged else "non-privileged")
            print(f"{r['name']:<{width}}  {kind:<26}  {spec.help}")
        else:
            print(f"{r['name']:<{width}}  {r['source']:<26}  {r['target']}")
    print("\nalso: --agent package.module:Name (a class or factory) or --agent http://HOST:PORT "
          "(a served agent)")
    return 0


def task_rows() -> list[dict[str, str]]:
    """``navbench tasks``' rows: name, Gymnasium id, success rule, step limit, default split, default agent."""
    rows = []
    for t in TASKS.values():
        to = "the goal point" if t.distance_to == "POINT" else "a goal's view points"
        rule = f"STOP < {t.success_distance:g} m from {to}"
        if t.success_rule_text:
            rule += f"; {t.success_rule_text}"
        rows.append({"task": t.name, "gym id": t.gym_id, "success": rule, "steps": str(t.max_steps),
                     "default split": t.default_split or "none: --episodes", "default agent": t.default_agent})
    return rows


def cmd_tasks(args) -> int:
    rows = task_rows()
    widths = {k: max(len(k), *(len(r[k]) for r in rows)) for k in rows[0]}
    print("  ".join(f"{k:<{w}}" for k, w in widths.items()).rstrip())
    for r in rows:
        print("  ".join(f"{r[k]:<{w}}" for k, w in widths.items()).rstrip())
    print("\nnavbench run --task NAME; gymnasium.make(GYM_ID); docs/tasks.md describes each")
    return 0


def cmd_serve_agent(args) -> int:
    from navbench.agents.remote import AgentServer
    agent = resolve_agent(args.agent, parse_options(args.agent_opt), device=args.device)
    if agent.spec.startswith(("http://", "https://")):
        raise ValueError(f"serve-agent serves a local agent, not {agent.spec!r}")
    server = AgentServer(agent.factory, agent.spec, (args.host, args.port), options=agent.options,
                         scene_dir=args.scene_dir, task=args.task, device=agent.device, precision=args.precision)
    print(f"serving {agent.spec} at {server.url} on {agent.device} (sensors: {', '.join(server.sensors) or 'none'})",
          flush=True)
    try:
        server.serve_forever()
    finally:
        server.server_close()
    return 0


def cmd_check_agent(args) -> int:
    """Each check's line; exit 1 if any check failed (warnings do not), 2 if the server cannot be reached."""
    from navbench.agents.check_remote import check_server
    if args.steps < 1:
        raise ValueError(f"--steps {args.steps}: expected at least 1")
    checks = check_server(args.url, task=args.task, steps=args.steps, timeout=args.timeout)
    failed = [c for c in checks if not c.ok and not c.warning]
    warned = [c for c in checks if not c.ok and c.warning]
    print(f"{args.url}: " + (f"{len(failed)} check(s) failed" if failed else "follows the protocol")
          + (f", {len(warned)} warning(s)" if warned else ""))
    return 1 if failed else 0


def cmd_table(args) -> int:
    from navbench.eval.table import group_frame, render, runs_frame
    if args.by:
        print(render(group_frame(args.run_dirs, args.by, args.first), args.format))
        return 0
    print(render(runs_frame(args.run_dirs, wide=not args.long, first=args.first), args.format))
    return 0


def cmd_export(args) -> int:
    from navbench.eval.export import export_run
    print(export_run(args.run_dir, args.format, args.out, partial=args.partial,
                     note=lambda line: print(line, file=sys.stderr)))
    return 0


def cmd_compare(args) -> int:
    from navbench.eval.stats import compare_runs, format_comparison
    results = compare_runs(args.base, args.others, args.metric, mix_protocols=args.mix_protocols,
                           per_scene=args.per_scene)
    if args.json:
        print(json.dumps(results[0] if len(results) == 1 else results, indent=1))
    else:
        print("\n\n".join(format_comparison(r) for r in results))
    return 0


def cmd_protocol(args) -> int:
    from navbench.eval.methods import protocol_text
    print(protocol_text(args.run_dir, args.format))
    return 0


def cmd_generate(args) -> int:
    if args.dir and args.what != "habitat-test-data":
        raise ValueError(f"generate {args.what}: a DIR argument is for habitat-test-data (use --out)")
    if args.what == "habitat-test-data":  # stand-ins at the paths habitat-lab's own tests read
        from navbench.episodes.habitat_test_data import write_habitat_test_data
        out = args.dir or args.out
        if not out:
            raise ValueError("generate habitat-test-data needs DIR")
        write_habitat_test_data(Path(out), seed=args.seed, overwrite=args.overwrite)
        print(f"run habitat-lab's tests with {out} as the working directory")
    elif args.what == "benchmark":
        from navbench.episodes.benchmark import generate_benchmark
        if not args.out:
            raise ValueError("generate benchmark needs --out DIR")
        m = generate_benchmark(Path(args.out), houses=args.houses, episodes_per_split=args.episodes_per_split,
                               seed=args.seed)
        print("run a split with: " + m["run"].replace("DIR", args.out))
    elif args.what == "scenes":
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
    elif args.what == "imagenav":  # ImageNav's val only (`episodes` writes it with every other split)
        from navbench.episodes.generate import write_imagenav_split
        write_imagenav_split(Path(args.out or EPISODES_DIR), SCENES_DIR, seed=args.seed)
    elif args.what == "vlnce":
        from navbench.episodes.vlnce_generate import generate_vlnce_split
        generate_vlnce_split(Path(args.out or EPISODES_DIR), SCENES_DIR, seed=args.seed)
    elif args.what == "instance_imagenav":  # InstanceImageNav's val only (`episodes` writes it too)
        from navbench.localize.nav_splits import write_instance_imagenav_split
        write_instance_imagenav_split(Path(args.out or EPISODES_DIR), SCENES_DIR, seed=args.seed)
    elif args.what == "goat":  # GOAT-Bench's val only (`episodes` writes it too)
        from navbench.localize.nav_splits import write_goat_split
        write_goat_split(Path(args.out or EPISODES_DIR), SCENES_DIR, seed=args.seed)
    else:
        from navbench.episodes.generate import generate_bundled_splits
        from navbench.localize.nav_splits import write_goat_split, write_instance_imagenav_split
        out = Path(args.out or EPISODES_DIR)
        generate_bundled_splits(out, SCENES_DIR, seed=args.seed)
        write_instance_imagenav_split(out, SCENES_DIR, seed=args.seed)
        write_goat_split(out, SCENES_DIR, seed=args.seed)
    return 0


def cmd_memory(args) -> int:
    from navbench.localize.backends.oracle import NoiseProfile
    from navbench.localize.benchmark import PERCEPTION, ModelDirs
    from navbench.memory.prescan import build_memory
    from navbench.scene.asset import load_scene

    if args.perception not in PERCEPTION:
        raise ValueError(f"unknown perception {args.perception!r}: choose from {', '.join(PERCEPTION)}")
    scene = Path(args.scene)
    if not scene.is_file():
        scene = SCENES_DIR / args.scene
    scan = scan_config(args.keyframe_res, args.all_frames)
    encoder = PERCEPTION[args.perception](load_scene(scene), NoiseProfile(), ModelDirs(
        siglip2=Path(args.siglip2) if args.siglip2 else None, **_run_on(args))).encoder
    out = Path(args.out or Path("runs") / "memory" / scene.name.split(".")[0])
    st = build_memory(scene, out, scan, encoder)
    print(f"{scene}: {st.frames} frames, {st.keyframes} keyframes, {st.bytes / 1e6:.2f} MB on disk, "
          f"built in {st.build_seconds:.2f} s -> {out}")
    return 0


def _run_on(args) -> dict[str, str]:
    """``--device`` (resolved: a device that is not there is one line) and ``--precision`` of the real models."""
    from navbench.device import resolve_device
    return {"device": resolve_device(args.device), "precision": args.precision}


def cmd_localize(args) -> int:
    from navbench.localize.benchmark import model_dirs, run_localize
    models = model_dirs({"siglip2": args.siglip2, "qwen_vl": args.qwen_vl, "sam3": args.sam3}, **_run_on(args))
    on_query = None
    if args.viz:  # pictures per query, under OUT/viz
        from navbench.viz.localize import QueryViews
        if not args.out:
            raise ValueError("--viz needs --out (the views go to OUT/viz)")
        on_query = QueryViews(Path(args.out) / "viz")
    s = run_localize(split=args.split, perception=args.perception, noise=args.noise, fusion=not args.no_fusion,
                     rerank=args.rerank != "none", k=args.k, out=args.out, limit=args.limit, models=models,
                     on_query=on_query, episodes=args.episodes, scene_dir=args.scene_dir)
    rows = " | ".join(f"{t} {100 * v:.1f}" for t, v in s["sr_by_type"].items())
    print(f"SR@{s['k']} ({s['perception']}, noise={s['noise']}, fusion={s['fusion']}, rerank={s['rerank']}): "
          f"{100 * s['sr']:.1f} avg | {rows}")
    print(f"memory: build {s['build_s']:.1f} s total, {s['storage_bytes'] / 1e6:.2f} MB; "
          f"query {s['query_ms']:.1f} ms mean")
    return 0


def cmd_bench(args) -> int:
    from navbench.bench.speed import BenchConfig, format_report, run_bench
    if args.scan:
        from navbench.bench.scan import format_scan_report, run_scan_bench
        result = run_scan_bench(args.scan, seconds=args.seconds)
        print(json.dumps(result) if args.json else format_scan_report(result))
        return 0
    from navbench.device import resolve_device
    result = run_bench(BenchConfig(scene=args.scene, seconds=args.seconds, policy=not args.no_policy,
                                   tasks=not args.no_tasks, device=resolve_device(args.device)))
    print(json.dumps(result) if args.json else format_report(result))
    return 0


class _Parser(argparse.ArgumentParser):
    """argparse with usage errors as the house's one line and exit code 2 (subcommands inherit it)."""

    def error(self, message: str):
        self.exit(2, f"navbench: error: {self.prog}: {message.splitlines()[0]} (see {self.prog} --help)\n")


def _int_at_least(lo: int):
    """An argparse type: an integer >= ``lo``."""
    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            n = lo - 1
        if n < lo:
            raise argparse.ArgumentTypeError(f"expected an integer >= {lo}, got {text!r}")
        return n
    return parse


_count = _int_at_least(1)  # episode counts, workers, k
_seed = _int_at_least(0)


def _positive(text: str) -> float:
    """A finite number > 0 (distances, temperatures, seconds)."""
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}") from None
    if not math.isfinite(x) or x <= 0:
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return x


def add_device_flags(p: argparse.ArgumentParser, precision: bool = False) -> None:
    """``--device`` (and ``--precision``, for commands that load the real perception models)."""
    from navbench.device import DEVICES, PRECISIONS, device_arg
    p.add_argument("--device", type=device_arg, default="cpu", metavar="DEVICE",
                   help=f"where torch work runs: {DEVICES} (default cpu; auto: CUDA when torch sees a GPU)")
    if precision:
        p.add_argument("--precision", default="fp32", choices=PRECISIONS,
                       help="weights of the real perception models (default fp32)")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="navbench", description=__doc__.split("\n\n")[0])
    from navbench._version import __version__
    p.add_argument("--version", action="version", version=f"navbench {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="evaluate an agent on a split and print SR/SPL")
    r.add_argument("--split", help="bundled split (default: the task's; val_unseen without --task)")
    r.add_argument("--task", choices=task_names(), help="default: the episode file's, else from the split "
                                                       "(`navbench tasks` lists them)")
    r.add_argument("--agent", help=f"one of: {', '.join(AGENTS)} (default: the task's: "
                                   f"{', '.join(f'{t.default_agent} for {t.name}' for t in TASKS.values())}), "
                                   "an installed plug-in's "
                                   "name (`navbench agents`), "
                                   "package.module:Name (a class or a factory f(run_config, **opts)), or "
                                   "http://HOST:PORT (an agent served by `navbench serve-agent`)")
    r.add_argument("--agent-opt", action="append", metavar="KEY=VALUE",
                   help="an option for the agent, repeatable; VALUE is read as a JSON literal (3, 0.5, true, "
                        "null, [1,2]) or else kept as a string. A plug-in class gets them as constructor "
                        "keywords; a remote agent takes timeout=SECONDS (per request, default 30)")
    r.add_argument("--episodes", help="a Habitat-format episode file (.json/.json.gz) instead of a bundled split")
    r.add_argument("--gt", help="VLN-CE: the gt paths file, when it is not beside the episodes as {split}_gt.json.gz")
    r.add_argument("--scene-dir", help="where episode scene_id paths are resolved (default: bundled envs/)")
    r.add_argument("--limit", type=_count, help="first N episodes only")
    r.add_argument("--per-scene", type=_count, help="first K episodes of each scene only (before --limit)")
    r.add_argument("--seed", type=_seed, default=0)
    r.add_argument("--out", help="run directory (default runs/TASK/SPLIT/LABEL: the agent, then what differs "
                                 "from its defaults, e.g. runs/pointnav/val/pointnav-argmax)")
    r.add_argument("--runs-dir", default="runs", help="root of the default run directory (default runs; the "
                                                      "reference runs use results/runs)")
    r.add_argument("--resume", action="store_true", help="continue the run in OUT: keep its finished episodes "
                                                        "(each once), rerun its failed ones")
    r.add_argument("--overwrite", action="store_true", help="replace the run already in OUT (without --resume or "
                                                           "--overwrite a directory holding a run is refused)")
    r.add_argument("--shard", metavar="I/N", help="run shard I (1-based) of N: the I-th of N contiguous blocks of "
                                                  "the selected episodes in file order; join with `navbench merge`")
    r.add_argument("--retries", type=int, default=2, help="times an episode whose worker process died is retried "
                                                          "on a fresh worker before it is recorded as failed "
                                                          "(default 2)")
    r.add_argument("--step-timeout", type=float, metavar="SECONDS",
                   help="record an episode as failed when one agent call takes longer (default: no limit; with "
                        "workers a call that never returns is killed)")
    r.add_argument("--fail-fast", action="store_true", help="stop at the first failed episode (exit 2) instead of "
                                                           "recording it and going on")
    r.add_argument("--success-distance", type=_positive)
    r.add_argument("--habitat-config", metavar="FILE", help="a resolved habitat-lab configuration (yaml) or a "
                   "habitat-baselines checkpoint holding one: task, limits, actions, agent, sensors, noise and, "
                   "where they exist, the dataset's files; a key navbench cannot honour is refused "
                   "(docs/habitat_configs.md)")
    r.add_argument("--env-config", metavar="NAME|FILE",
                   help="the conditions: a named configuration (habitat-challenge-pointnav-2020, "
                        "habitat-challenge-pointnav-2021, habitat-challenge-objectnav-2021, habitat-objectnav-hm3d, "
                        "navbench, ...: "
                        "configs/env/) or a TOML file of EnvConfig fields (sensors, noise; docs/realistic.md)")
    flags = r.add_argument_group("agent options (in brackets: the agents that read each; another agent's flag "
                                 "is an error)")
    AGENT_FLAGS.update(add_flags(flags, {name: spec.options for name, spec in AGENTS.items()}))
    batching = ", ".join(f"{n} {s.envs_per_worker}" for n, s in AGENTS.items() if s.batches)
    r.add_argument("--envs-per-worker", type=_count, help="episodes a worker steps at once with one batched "
                   f"policy forward pass (agents that batch; default {batching}; records do not depend on it)")
    r.add_argument("--workers", type=_count, help="parallel episode workers (default 2; with --backend ray and no "
                                                  "--address, the local Ray instance's CPUs; not with --address)")
    r.add_argument("--backend", default="local", choices=("local", "ray"),
                   help="where episodes run: local worker processes, or one Ray actor per CPU of a Ray cluster "
                        "(pip install navbench[ray]; records are the same, so --resume works across backends)")
    r.add_argument("--address", metavar="auto|HOST:PORT", help="with --backend ray: the cluster to join (default: "
                                                               "start a local Ray instance)")
    r.add_argument("--video", default="none", choices=("none", "failures", "all"),
                   help="write OUT/videos/EPISODE.mp4 (RGB | depth | map, 10 fps) for failed or all episodes")
    add_device_flags(r, precision=True)
    r.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    r.set_defaults(func=cmd_run)

    mg = sub.add_parser("merge", help="join shard runs (run --shard I/N) into one run directory")
    mg.add_argument("run_dirs", nargs="+")
    mg.add_argument("--out", required=True, help="the merged run's directory")
    mg.add_argument("--overwrite", action="store_true", help="replace a run already in --out")
    mg.set_defaults(func=cmd_merge)

    from navbench.viz.cli import add_parsers as add_viz_parsers
    add_viz_parsers(sub)

    t = sub.add_parser("table", help="render run summaries side by side",
                       description="One row per run (or per agent, a column per split) in each task's own "
                       "measures, each with its 95% interval. Runs under different protocols are shown side by "
                       "side: a protocol column, one column per protocol field that differs and a note say so "
                       "(navbench compare refuses to pair them).")
    t.add_argument("run_dirs", nargs="+")
    t.add_argument("--format", default="markdown", choices=("markdown", "csv", "latex"))
    t.add_argument("--long", action="store_true", help="one row per run instead of agent x split")
    t.add_argument("--first", type=_count, help="score every run on the first N episodes of its split only")
    t.add_argument("--by", choices=("scene", "category"), help="one row per run and scene or object category")
    t.set_defaults(func=cmd_table)

    ex = sub.add_parser("export", help="write a VLN-CE run's leaderboard file (R2R-CE JSON, RxR-CE JSON Lines)")
    ex.add_argument("run_dir")
    ex.add_argument("--format", required=True, choices=("r2r-ce", "rxr-ce"))
    ex.add_argument("-o", "--out", help="the file to write (default: RUN/predictions.json or .jsonl)")
    ex.add_argument("--partial", action="store_true", help="write it although the run covers only part of its "
                                                          "episode file (a leaderboard scores the whole split)")
    ex.set_defaults(func=cmd_export)

    c = sub.add_parser("compare", help="paired comparison of runs on the episodes they share, with intervals",
                       description="Pairs OTHER with BASE on the episodes both scored and, per measure of their task "
                       "(by default its headline measures: VLN-CE's TL, NE, OS, SR, SPL, nDTW, SDTW; GOAT-Bench's "
                       "partial and composite success, composite SPL and success by goal type), prints "
                       "both means, the difference OTHER - BASE, its 95% interval (two-stage bootstrap: scenes, "
                       "then episodes within each drawn scene; 2,000 resamples, seed 0), P(other better) (the "
                       "share of resamples whose difference favours OTHER, ties half; lower is better for distance "
                       "to goal, neither for path length) and the smallest difference this episode set could "
                       "detect: 2.8 x the bootstrap standard error of the difference (80% power, two-sided alpha "
                       "0.05). It names what differs, each with both values, BASE's first: protocol fields, split "
                       "(every file it is read from) or subset, agent and each of its settings, checkpoint, seed, "
                       "navbench version, torch build, device. Runs under "
                       "different protocols or on different splits are refused.")
    c.add_argument("base")
    c.add_argument("others", nargs="+", metavar="other")
    c.add_argument("--json", action="store_true", help="one JSON object (a list for several OTHER runs)")
    c.add_argument("--metric", action="append", help="only this measure of the runs' task (repeatable; default: "
                                                     "the task's headline measures; a wrong name lists the task's)")
    c.add_argument("--per-scene", type=_count, metavar="K", help="only the first K episodes of each scene of "
                                                                 "the episode file (as run --per-scene K)")
    c.add_argument("--mix-protocols", action="store_true", help="compare runs under different protocols anyway "
                                                                "(the output says so)")
    c.set_defaults(func=cmd_compare)

    pr = sub.add_parser("protocol", help="a run's protocol as a paragraph for a paper's methods section",
                        description="Writes the task, the episodes (file, count, sha256), the success rule, the "
                        "step limit, the actions, the agent and its sensors, the noise, the navigability rules, "
                        "navbench's version and the protocol id of RUN_DIR, from its provenance.json and "
                        "config.json.")
    pr.add_argument("run_dir")
    pr.add_argument("--format", default="markdown", choices=("markdown", "latex", "json"))
    pr.set_defaults(func=cmd_protocol)

    g = sub.add_parser("generate", help="regenerate the bundled scenes or episodes, or the PointNav policy's "
                                        "extra training houses and episodes (policy-train) or its houses and "
                                        "episodes for choosing among policies (policy-select); or a larger "
                                        "ObjectNav benchmark with houses of its own and checksums (benchmark "
                                        "--out DIR); or one val split: ImageNav's (imagenav), InstanceImageNav's "
                                        "(instance_imagenav), GOAT-Bench's (goat), the R2R-CE-style one (vlnce); "
                                        "or stand-ins for habitat-lab's test data (habitat-test-data DIR)")
    g.add_argument("what", choices=("scenes", "episodes", "imagenav", "instance_imagenav", "goat", "policy-train",
                                    "policy-select", "benchmark", "vlnce", "habitat-test-data"))
    g.add_argument("dir", nargs="?", help="habitat-test-data: the directory to write habitat-lab's test data "
                                          "stand-ins in (navbench/episodes/habitat_test_data.py)")
    g.add_argument("--seed", type=_seed, default=0)
    g.add_argument("--out")
    g.add_argument("--overwrite", action="store_true", help="habitat-test-data: write into a non-empty DIR")
    g.add_argument("--houses", type=_count, default=36, help="benchmark: houses of its own (default 36)")
    g.add_argument("--episodes-per-split", type=_count, default=3000,
                   help="benchmark: episodes in each of val_seen, val_seen_synonyms, val_unseen (default 3000)")
    g.set_defaults(func=cmd_generate)

    from navbench.policy.recipe import add_train_parser
    add_train_parser(sub)

    mem = sub.add_parser("memory", help="build a scene's keyframe memory (pre-scan, keyframes, index)")
    mem.add_argument("what", choices=("build",))
    mem.add_argument("--scene", required=True, help="scene file, or a path under envs/ (e.g. houses/val/house_008.glb)")
    mem.add_argument("--out")
    mem.add_argument("--perception", default="oracle", help="encoder of the index: oracle | siglip2+qwen2.5-vl+sam3")
    mem.add_argument("--keyframe-res", default="full", choices=("full", "640x480", "160x120"))
    mem.add_argument("--all-frames", action="store_true")
    mem.add_argument("--siglip2", help="local SigLIP2 model directory")
    add_device_flags(mem, precision=True)
    mem.set_defaults(func=cmd_memory)

    lo = sub.add_parser("localize", help="GOAT-style localisation benchmark (SR@K)")
    lo.add_argument("--split", default="goat_val")
    lo.add_argument("--episodes", help="a GOAT-Bench episode file (.json or .json.gz) instead of --split")
    lo.add_argument("--scene-dir", help="where --episodes' scene_ids resolve (a Habitat scene_datasets/ root)")
    lo.add_argument("--perception", default="oracle")
    lo.add_argument("--noise", default="none")
    lo.add_argument("--no-fusion", action="store_true")
    lo.add_argument("--rerank", default="vlm", choices=("vlm", "none"))
    lo.add_argument("-k", type=_count, default=5)
    lo.add_argument("--limit", type=_count)
    lo.add_argument("--out")
    lo.add_argument("--viz", action="store_true", help="save a picture per query in OUT/viz: the re-ranked keyframes "
                    "with scores and masks, the fused points, top-K centres and ground truth on the top-down map")
    lo.add_argument("--siglip2")
    lo.add_argument("--qwen-vl", help="local Qwen2.5-VL directory, or http://HOST:PORT/v1[#MODEL]: an "
                                      "OpenAI-compatible server (vLLM...) all workers share")
    lo.add_argument("--sam3")
    add_device_flags(lo, precision=True)
    lo.set_defaults(func=cmd_localize)

    a = sub.add_parser("agents", help="list the agents --agent takes by name and where each comes from")
    a.set_defaults(func=cmd_agents)

    ts = sub.add_parser("tasks", help="list the tasks --task takes: Gymnasium id, success rule, step limit, "
                                      "default split")
    ts.set_defaults(func=cmd_tasks)

    sa = sub.add_parser("serve-agent", help="serve a local agent over HTTP for `run --agent http://HOST:PORT` "
                                            "(protocol: docs/remote_agent.md)")
    sa.add_argument("agent", help="a built-in or plug-in name, or package.module:Name")
    sa.add_argument("--agent-opt", action="append", metavar="KEY=VALUE", help="as for `run`, repeatable")
    sa.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine "
                                                        "only)")
    sa.add_argument("--port", type=int, default=8765, help="default 8765; 0 picks a free port")
    sa.add_argument("--task", default="pointnav", choices=task_names(),
                    help="task of the agent built at start to answer /info (each client's run says its own)")
    sa.add_argument("--scene-dir", help="where this machine keeps the scenes, if not where the client does")
    add_device_flags(sa, precision=True)  # where the served agents run: this machine's, whatever the client's
    sa.set_defaults(func=cmd_serve_agent)

    ca = sub.add_parser("check-agent", help="exercise a remote agent server against the protocol "
                                            "(docs/remote_agent.md); exit 1 if it breaks it")
    ca.add_argument("url", help="http://HOST:PORT")
    ca.add_argument("--task", default="pointnav", choices=task_names(),
                    help="the env whose observations are sent")
    ca.add_argument("--steps", type=int, default=200, help="/act round trips timed (default 200)")
    ca.add_argument("--timeout", type=_positive, default=10.0, help="seconds per request (default 10)")
    ca.set_defaults(func=cmd_check_agent)

    b = sub.add_parser("bench", help="simulator, geodesic and policy speed")
    b.add_argument("--json", action="store_true")
    b.add_argument("--scene", help="scene file (default: first bundled val scene)")
    b.add_argument("--seconds", type=_positive, default=3.0, help="time per measurement")
    b.add_argument("--no-policy", action="store_true", help="skip the policy inference figures")
    b.add_argument("--no-tasks", action="store_true", help="skip the goal-image tasks' figures (ImageNav, "
                                                          "InstanceImageNav, GOAT beside PointNav)")
    add_device_flags(b)
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
