"""`navbench viz` (maps and videos of a finished run) and `navbench report` (one HTML page for runs).

Parsers only import argparse; the drawing code loads when a command runs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from navbench.safeio import UniqueNames, child, own_dir, unlink_if_symlink


def write_videos(run_dir: Path, which: str, quiet: bool = False, episode: str | None = None) -> list[Path]:
    """OUT/videos/<episode_id>.mp4 for ``which`` = failures | all episodes of a finished run (or one ``episode``);
    the episode id is made a plain file name (:func:`navbench.safeio.safe_name`), so it stays in OUT/videos."""
    from navbench.viz.replay import Replayer, Run
    from navbench.viz.video import select, write_video

    run = Run.load(run_dir)
    recs = [run.record(episode)] if episode is not None else select(run.records, which)
    untraced = [r for r in recs if not r.get("trace")]
    if untraced:  # e.g. records kept by --resume from a run that predates pose recording
        print(f"{run_dir}: no video for {len(untraced)} episodes recorded without a trace", file=sys.stderr)
        recs = [r for r in recs if r.get("trace")]
    rp = Replayer(run)
    out, names = [], UniqueNames()
    try:
        for k, r in enumerate(recs, 1):
            path = unlink_if_symlink(child(own_dir(Path(run_dir) / "videos"), names(r["episode_id"], ".mp4")))
            n = write_video(rp, r, path)
            out.append(path)
            if not quiet:
                print(f"[{k}/{len(recs)}] {path} ({n} frames)", file=sys.stderr, flush=True)
    finally:
        rp.close()
    return out


def shades_explored(agent: str, flag: bool | None) -> bool:
    """Whether ``navbench viz`` shades what the depth camera saw: ``--[no-]explored`` if given, else
    whether the run's agent explores (its registry spec says so; a plug-in agent does not)."""
    if flag is not None:
        return flag
    from navbench.agents.registry import AGENTS
    spec = AGENTS.get(agent)
    return spec is not None and spec.explores


def cmd_viz(args) -> int:
    import cv2

    from navbench.viz.maps import episode_map
    from navbench.viz.replay import Replayer, Run

    run = Run.load(args.run)
    if args.episode is None and not args.failures:
        raise ValueError("say which episodes: --episode ID or --failures")
    recs = [run.record(e) for e in args.episode] if args.episode else run.failures()
    recs = [r for r in recs if not r.get("skipped")]
    untraced = [str(r["episode_id"]) for r in recs if not r.get("trace")]
    if untraced:
        raise ValueError(f"{args.run}: the run predates pose recording (no trace in episode "
                         f"{', '.join(untraced[:3])}{'...' if len(untraced) > 3 else ''}); rerun it to draw it")
    out = Path(args.out) if args.out else own_dir(Path(args.run) / "viz")
    out.mkdir(parents=True, exist_ok=True)
    rp = Replayer(run)
    names = UniqueNames()
    shade = shades_explored(run.cfg.agent, args.explored)
    try:
        for r in recs:
            explored = None
            if shade:
                from navbench.viz.video import explored_mask
                explored = explored_mask(rp, r)
            # replays the actions, checking every recorded pose
            img = episode_map(rp, r, max_side=args.size, explored=explored)
            name = names(r["episode_id"])  # an episode id from a file is a name, never a path
            png = unlink_if_symlink(child(out, name + ".png"))
            cv2.imwrite(str(png), img[..., ::-1])
            line = f"{png}: {r.get('num_steps', 0)} steps replayed, path matches the record"
            if args.video:
                from navbench.viz.video import write_video
                mp4 = unlink_if_symlink(child(own_dir(Path(args.run) / "videos"), name + ".mp4"))
                line += f"; {mp4} ({write_video(rp, r, mp4)} frames)"
            print(line)
    finally:
        rp.close()
    if not recs:
        print(f"{args.run}: no failed episodes")
    return 0


def cmd_report(args) -> int:
    from navbench.viz.report import write_report
    path = write_report([Path(r) for r in args.runs], Path(args.out), thumbs=args.thumb_size,
                        max_episodes=args.max_episodes, embed_videos=args.embed_videos)
    print(f"wrote {path}")
    return 0


def add_parsers(sub) -> None:
    v = sub.add_parser("viz", help="top-down maps (and videos) of a finished run's episodes, replayed from "
                                   "its records")
    v.add_argument("run", help="run directory (with episodes.jsonl and config.json)")
    v.add_argument("--episode", action="append", help="episode id (repeatable)")
    v.add_argument("--failures", action="store_true", help="every failed episode")
    v.add_argument("--video", action="store_true", help="also write RUN/videos/EPISODE.mp4")
    v.add_argument("--explored", action=argparse.BooleanOptionalAction, default=None,
                   help="shade the cells the depth camera saw (default: on for an agent that explores)")
    v.add_argument("--size", type=int, default=640, help="longest side of the map in pixels (default 640)")
    v.add_argument("-o", "--out", help="where the PNGs go (default RUN/viz)")
    v.set_defaults(func=cmd_viz)

    rp = sub.add_parser("report", help="one self-contained HTML page: SR/SPL, per category, failures, gallery")
    rp.add_argument("runs", nargs="+", help="run directories")
    rp.add_argument("-o", "--out", default="report.html")
    rp.add_argument("--thumb-size", type=int, default=220, help="map thumbnail size in pixels (default 220)")
    rp.add_argument("--max-episodes", type=int, help="gallery: at most N episodes per run (failures first)")
    rp.add_argument("--embed-videos", action="store_true",
                    help="inline the runs' videos (RUN/videos/*.mp4) in the page instead of linking them")
    rp.set_defaults(func=cmd_report)
