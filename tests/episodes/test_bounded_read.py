"""Episode files from the internet: read streamed, with a cap on their decompressed size. A decompression bomb
is one line and exit 2 with memory bounded; --limit, --per-scene and --shard hold only what they select.
The bombs are built streaming (a few MB on disk) and the cap lowered, so the tests stay small."""

import gzip
import json
import os
import subprocess
import sys
import textwrap
import zlib

import pytest

from navbench.episodes.io import episode_keys, load_dataset
from navbench.episodes.types import EpisodeError
from navbench.eval.config import select_episodes, selector
from navbench.eval.runner import run_dataset

EPISODE = {"scene_id": "houses/val/house_008.glb", "start_position": [0.5, 0.0, 0.5],
           "start_rotation": [0, 0, 0, 1], "info": {"geodesic_distance": 2.0},
           "goals": [{"position": [1.5, 0.0, 1.5], "radius": None}]}


def _bomb(path, prefix: bytes, filler: bytes, total: int, suffix: bytes = b"") -> None:
    """A gzip file expanding to ``prefix + filler * n + suffix`` (``total`` bytes of filler), written streaming."""
    c = zlib.compressobj(9, zlib.DEFLATED, 31)
    chunk = filler * max(1, (1 << 20) // len(filler))
    with open(path, "wb") as f:
        f.write(c.compress(prefix))
        for _ in range(0, total, len(chunk)):
            f.write(c.compress(chunk))
        f.write(c.compress(suffix) + c.flush())


def _many(path, n: int, scenes: int = 1) -> None:
    with gzip.open(path, "wt", compresslevel=1) as f:
        f.write('{"episodes": [')
        for i in range(n):
            ep = dict(EPISODE, episode_id=str(i), scene_id=f"houses/val/house_{i % scenes:03d}.glb")
            f.write(("," if i else "") + json.dumps(ep))
        f.write('], "trailing": 1}')


@pytest.mark.parametrize("shape", ["whitespace", "string", "episodes", "zeros", "nested-string"])
def test_a_bomb_is_one_line_naming_the_file(shape, tmp_path, monkeypatch):
    monkeypatch.setenv("NAVBENCH_MAX_INPUT_BYTES", "16M")
    path = tmp_path / "bomb.json.gz"
    ep = json.dumps(dict(EPISODE, episode_id="x")).encode()
    prefix, filler, suffix = {
        "whitespace": (b'{"episodes": [', b" ", b"]}"),
        "string": (b'{"episodes": [], "pad": "', b"A", b'"}'),
        "episodes": (b'{"episodes": [' + ep, b"," + ep, b"]}"),
        "zeros": (b"", b"\0", b""),
        "nested-string": (b'{"episodes": [{"episode_id": "', b"\xe2\x82\xac", b'"}]}'),
    }[shape]
    _bomb(path, prefix, filler, 64 << 20, suffix)
    assert path.stat().st_size < 1 << 20
    with pytest.raises(EpisodeError) as exc:
        load_dataset(path)
    assert str(path) in str(exc.value).splitlines()[0]


def test_one_value_larger_than_its_cap_is_refused_early(tmp_path):
    path = tmp_path / "big.json.gz"
    _bomb(path, b'{"episodes": [], "pad": "', b"A", 80 << 20, b'"}')
    with pytest.raises(EpisodeError, match="single JSON value"):
        load_dataset(path)


def test_the_cap_is_a_documented_default_and_can_be_raised(tmp_path, monkeypatch):
    from navbench import safeio
    assert safeio.max_input_bytes() == 1 << 30
    path = tmp_path / "ok.json.gz"
    _bomb(path, b'{"episodes": [' + json.dumps(dict(EPISODE, episode_id="0")).encode(), b" ", 3 << 20, b"]}")
    monkeypatch.setenv("NAVBENCH_MAX_INPUT_BYTES", "2M")
    with pytest.raises(EpisodeError, match="larger than 2 MiB"):
        load_dataset(path)
    monkeypatch.setenv("NAVBENCH_MAX_INPUT_BYTES", "8M")
    assert len(load_dataset(path).episodes) == 1
    monkeypatch.setenv("NAVBENCH_MAX_INPUT_BYTES", "lots")
    with pytest.raises(ValueError, match="NAVBENCH_MAX_INPUT_BYTES"):
        load_dataset(path)


def test_plain_json_over_the_cap_is_refused_before_reading(tmp_path, monkeypatch):
    monkeypatch.setenv("NAVBENCH_MAX_INPUT_BYTES", "1K")
    path = tmp_path / "e.json"
    path.write_text(json.dumps({"episodes": [dict(EPISODE, episode_id=str(i)) for i in range(20)]}))
    with pytest.raises(EpisodeError, match="on disk"):
        load_dataset(path)


def test_streamed_selection_equals_the_selection_of_the_whole_file(tmp_path):
    path = tmp_path / "many.json.gz"
    _many(path, 103, scenes=7)
    whole = load_dataset(path)
    assert whole.extra == {"trailing": 1}
    for limit, per_scene, shard in [(None, None, None), (5, None, None), (None, 3, None), (40, 2, "2/3"),
                                    (None, None, "3/3"), (0, None, None), (None, None, "1/200")]:
        streamed = load_dataset(path, selector(limit, per_scene, shard))
        expected = select_episodes(whole, limit, per_scene, shard)
        assert [e.episode_id for e in streamed.episodes] == [e.episode_id for e in expected]
        assert streamed.extra == {"trailing": 1}
        ds = run_dataset(path, limit, per_scene, shard)
        assert [e.episode_id for e in ds.episodes] == [e.episode_id for e in expected]
    assert episode_keys(path) == {(e.scene_id, e.episode_id) for e in whole.episodes}


def test_objectnav_goals_after_the_episodes_still_reach_a_limited_selection(tmp_path):
    doc = {"episodes": [{"episode_id": str(i), "scene_id": "s/a.glb", "start_position": [0, 0, 0],
                         "start_rotation": [0, 0, 0, 1], "goals": [], "object_category": "chair"} for i in range(5)],
           "goals_by_category": {"a.glb_chair": [{"position": [1, 0, 1], "object_id": 3, "view_points": []}]},
           "category_to_task_category_id": {"chair": 0}}
    path = tmp_path / "on.json"
    path.write_text(json.dumps(doc))
    ds = load_dataset(path, selector(2))
    assert len(ds.episodes) == 2 and ds.episodes[1].goals[0].object_id == 3
    assert ds.category_to_task_category_id == {"chair": 0}


# A child's peak memory in MB: VmHWM belongs to the new process image, whereas ru_maxrss survives exec on
# Linux (a child of a large pytest process would report the parent's peak).
PEAK = ("def peak_mb():\n"
        "    for line in open('/proc/self/status'):\n"
        "        if line.startswith('VmHWM:'):\n"
        "            return int(line.split()[1]) // 1024\n")
PROBE = PEAK + textwrap.dedent("""
    import sys, time
    from navbench.eval.runner import run_dataset
    t0 = time.monotonic()
    ds = run_dataset(sys.argv[1], int(sys.argv[2]))
    print(len(ds.episodes), peak_mb(), time.monotonic() - t0)
""")


def test_a_limit_on_a_big_file_holds_only_what_it_selects(tmp_path):
    path = tmp_path / "big.json.gz"
    _many(path, 100_000)
    base = subprocess.run([sys.executable, "-c", PEAK + "import navbench.eval.runner\nprint(peak_mb())"],
                          capture_output=True, text=True, check=True, env=dict(os.environ))
    out = subprocess.run([sys.executable, "-c", PROBE, str(path), "2"], capture_output=True, text=True, check=True)
    n, rss, _ = out.stdout.split()
    assert int(n) == 2
    assert int(rss) - int(base.stdout) < 60, f"{rss} MB after reading 2 of 100000 episodes"


def test_a_bomb_through_the_cli_is_exit_2_with_memory_bounded(tmp_path):
    path = tmp_path / "bomb.json.gz"
    _bomb(path, b'{"episodes": [', b" ", 96 << 20, b"]}")
    env = dict(os.environ, NAVBENCH_MAX_INPUT_BYTES="64M")
    code = (PEAK + "import sys\nfrom navbench.cli import main\nrc = main(sys.argv[1:])\n"
            "print(peak_mb())\nsys.exit(rc)")
    out = subprocess.run([sys.executable, "-c", code, "run", "--episodes", str(path), "--limit", "2", "--out",
                          str(tmp_path / "run"), "-q"], capture_output=True, text=True, env=env)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and "larger than 64 MiB" in lines[0]
    assert int(out.stdout) < 600, f"{out.stdout} MB"  # imports (torch) included; the bomb adds little
    assert set(p.name for p in tmp_path.iterdir()) <= {"bomb.json.gz", "run"}  # nothing outside OUT


@pytest.mark.parametrize("chunk", [5, 61])
def test_reading_in_tiny_chunks_gives_the_same_dataset(chunk, objectnav_file, monkeypatch):
    """Every value split across chunk boundaries (strings, numbers, keys, view points)."""
    from navbench.episodes import io

    whole = load_dataset(objectnav_file)
    monkeypatch.setattr(io, "_CHUNK", chunk)
    for limit in (None, 2):
        streamed = load_dataset(objectnav_file, selector(limit))
        assert streamed.goals_by_category == whole.goals_by_category
        assert streamed.episodes == whole.episodes[:limit]
        assert streamed.extra == whole.extra


def test_tiny_chunks_with_escapes_and_unicode(tmp_path, monkeypatch):
    from navbench.episodes import io
    eps = [dict(EPISODE, episode_id=f'é\\"{i}\u2603\U0001F600', info={"n": 1.5e-7, "s": "a\\\\b\\n"}) for i in range(5)]
    path = tmp_path / "u.json"
    path.write_text(json.dumps({"episodes": eps, "x": [1, {"y": "}]"}]}, ensure_ascii=False), encoding="utf-8")
    whole = load_dataset(path)
    monkeypatch.setattr(io, "_CHUNK", 1)
    assert load_dataset(path).episodes == whole.episodes and load_dataset(path).extra == {"x": [1, {"y": "}]"}]}
    first = load_dataset(path, selector(2)).episodes
    assert [e.episode_id for e in first] == [e.episode_id for e in whole.episodes[:2]]
