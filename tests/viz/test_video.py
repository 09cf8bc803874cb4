"""Episode videos: `navbench run --video all` writes playable MP4s and leaves the records as they were."""

import pytest

from navbench.cli import main
from navbench.eval.runner import read_records

NONDETERMINISTIC = ("elapsed_s",)


def _strip(records):
    return [{k: v for k, v in r.items() if k not in NONDETERMINISTIC} for r in records]


@pytest.mark.slow
def test_run_with_videos_writes_mp4s_and_the_same_records(oracle_run, objectnav_file, tmp_path):
    import imageio.v2 as imageio

    from navbench.viz.video import FRAME_SIZE

    out = tmp_path / "with_video"
    assert main(["run", "--episodes", str(objectnav_file), "--agent", "oracle", "--limit", "3", "--workers", "1",
                 "--out", str(out), "-q", "--video", "all"]) == 0
    with_video = read_records(out / "episodes.jsonl")
    assert _strip(with_video) == _strip(read_records(oracle_run / "episodes.jsonl"))
    assert len(with_video) == 3
    for r in with_video:
        frames = imageio.mimread(out / "videos" / f"{r['episode_id']}.mp4", memtest=False)
        assert len(frames) == r["num_steps"] + 1  # a frame per step, then the closing frame
        assert frames[0].shape == (FRAME_SIZE[1], FRAME_SIZE[0], 3)


def test_video_frames_count_size_and_collision_border(oracle_run):
    from navbench.viz.replay import Replayer, Run
    from navbench.viz.video import FRAME_SIZE, episode_frames

    run = Run.load(oracle_run)
    r = min(run.records, key=lambda r: r["num_steps"])
    frames = list(episode_frames(Replayer(run), r))
    assert len(frames) == r["num_steps"] + 1
    assert all(f.shape == (FRAME_SIZE[1], FRAME_SIZE[0], 3) for f in frames)
    # no collision in an oracle episode: no red border
    assert not any((f[0, 0] == (230, 0, 0)).all() for f in frames[:-1]) or r["collisions"] > 0


def test_video_choice_selects_episodes():
    from navbench.viz.video import select
    recs = [{"success": 1.0}, {"success": 0.0}, {"skipped": True}]
    assert select(recs, "none") == [] and select(recs, "all") == recs[:2] and select(recs, "failures") == recs[1:2]
