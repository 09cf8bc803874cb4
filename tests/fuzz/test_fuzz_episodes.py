"""Fuzz the episode readers: PointNav-v1, ObjectNav-v1 (.json, .json.gz, content/ layouts) and GOAT.

Seeds are small files cut from the bundled splits; every mutation must load into a usable dataset or
fail as one line naming the file.
"""

from __future__ import annotations

import gzip
import json
import math
from pathlib import Path

import pytest
from fuzzlib import apply, check_user_error, mutations, paths, read_or_error
from hypothesis import given
from hypothesis import strategies as st

from navbench.episodes.io import goals_key, load_dataset, read_json
from navbench.localize.goat import load_goat_split
from navbench.paths import EPISODES_DIR


def _small_pointnav() -> dict:
    doc = read_json(EPISODES_DIR / "pointnav" / "val" / "val.json.gz")
    return {"episodes": doc["episodes"][:2]}


def _small_objectnav() -> dict:
    doc = read_json(EPISODES_DIR / "objectnav" / "val_seen" / "val_seen.json.gz")
    eps = doc["episodes"][:2]
    keys = {goals_key(e["scene_id"], e["object_category"]) for e in eps}
    gbc = {k: [dict(g, view_points=g["view_points"][:2]) for g in doc["goals_by_category"][k][:2]] for k in keys}
    return {"episodes": eps, "goals_by_category": gbc,
            "category_to_task_category_id": doc["category_to_task_category_id"],
            "category_to_scene_annotation_category_id": doc["category_to_scene_annotation_category_id"]}


def _small_goat() -> dict:
    with gzip.open(EPISODES_DIR / "goat" / "goat_val" / "goat_val.json.gz", "rt") as f:
        doc = json.load(f)
    return {"info": {"split": "goat_val"}, "subtasks": doc["subtasks"][:2]}


SEEDS = {"pointnav": _small_pointnav(), "objectnav": _small_objectnav()}
GOAT = _small_goat()


def _write(path: Path, data: bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(gzip.compress(data, mtime=0) if path.name.endswith(".gz") else data)
    return path


def _dump(doc) -> bytes:
    return json.dumps(doc).encode()


def check_dataset(path: Path) -> None:
    """Loads into episodes with finite poses and goals, or fails as one line naming the file."""
    ds = read_or_error(load_dataset, path)
    if ds is None:
        return
    for ep in ds.episodes:
        assert isinstance(ep.scene_id, str) and isinstance(ep.episode_id, str)
        assert len(ep.start_position) == 3 and len(ep.start_rotation) == 4
        assert all(math.isfinite(v) for v in [*ep.start_position, *ep.start_rotation])
        assert ep.goals, f"episode {ep.episode_id} loaded without goals"
        for g in ep.goals:
            assert len(g.position) == 3 and all(math.isfinite(v) for v in g.position)
            assert g.radius is None or (isinstance(g.radius, float) and math.isfinite(g.radius))
        assert ep.object_category is None or isinstance(ep.object_category, str)
        ep.goal_positions()
    assert all(isinstance(v, int) for v in ds.category_to_task_category_id.values())


# ------------------------------------------------------------------------------ byte-level mutations
@pytest.mark.parametrize("task", sorted(SEEDS))
def test_truncation_at_every_offset_json(task, fuzz_dir):
    data = _dump(SEEDS[task])
    step = max(1, len(data) // 400)  # every offset of the PointNav seed; every few of the larger one
    for cut in range(0, len(data), step):
        check_dataset(_write(fuzz_dir / f"trunc_{task}" / "ep.json", data[:cut]))


@pytest.mark.parametrize("task", sorted(SEEDS))
def test_truncation_at_every_offset_gz(task, fuzz_dir):
    gz = gzip.compress(_dump(SEEDS[task]), mtime=0)
    path = fuzz_dir / f"truncgz_{task}" / "ep.json.gz"
    path.parent.mkdir(parents=True, exist_ok=True)
    for cut in range(len(gz)):
        path.write_bytes(gz[:cut])
        check_dataset(path)


@given(data=st.data())
def test_bytes_flipped_or_non_utf8(data, fuzz_dir):
    task = data.draw(st.sampled_from(sorted(SEEDS)))
    raw = bytearray(_dump(SEEDS[task]))
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(raw) - 1))
        raw[i:i + 1] = data.draw(st.sampled_from([b"\xff", b"\xc3", b"\x00", b"\xed\xa0\x80", b"\"", b"]", b"9"]))
    suffix = data.draw(st.sampled_from(["ep.json", "ep.json.gz"]))
    check_dataset(_write(fuzz_dir / "bytes" / suffix, bytes(raw)))


@pytest.mark.parametrize("depth", [10, 1000, 100_000])
def test_deep_nesting(depth, fuzz_dir):
    for text in ("[" * depth + "]" * depth, '{"episodes": ' + "[" * depth + "]" * depth + "}"):
        check_dataset(_write(fuzz_dir / "deep" / "ep.json", text.encode()))


# ------------------------------------------------------------------------------ structural mutations
@given(data=st.data())
def test_structural_mutations(data, fuzz_dir):
    task = data.draw(st.sampled_from(sorted(SEEDS)))
    doc = data.draw(mutations(SEEDS[task]))
    suffix = data.draw(st.sampled_from(["ep.json", "ep.json.gz"]))
    check_dataset(_write(fuzz_dir / "struct" / suffix, _dump(doc)))


@pytest.mark.parametrize("task", sorted(SEEDS))
def test_every_key_dropped_and_swapped(task, fuzz_dir):
    """Systematically: each path of the seed deleted, and set to each JSON type."""
    seed = SEEDS[task]
    for p in paths(seed, limit=120):
        for op, value in (("drop", None), ("swap", None), ("swap", "x"), ("swap", 1e308 * 10), ("swap", []),
                          ("swap", {}), ("swap", True), ("nest", None)):
            check_dataset(_write(fuzz_dir / "every" / "ep.json", _dump(apply(seed, p, op, value))))


@given(data=st.data())
def test_content_layout(data, fuzz_dir, tmp_path_factory):
    """A split file with empty ``episodes`` and its episodes in ``content/{scene}.json(.gz)``."""
    task = data.draw(st.sampled_from(sorted(SEEDS)))
    root = tmp_path_factory.mktemp("content")
    seed = SEEDS[task]
    split = {k: v for k, v in seed.items() if k != "episodes"}
    split["episodes"] = []
    scene = {"episodes": seed["episodes"]}
    if data.draw(st.booleans()):
        scene = data.draw(mutations(scene))
    else:
        split = data.draw(mutations(split))
    (root / "content").mkdir()
    _write(root / "content" / data.draw(st.sampled_from(["house_008.json", "house_008.json.gz"])), _dump(scene))
    split_path = _write(root / "split.json.gz", _dump(split))
    try:
        ds = load_dataset(split_path)
    except (ValueError, FileNotFoundError, ImportError) as exc:
        first = str(exc).splitlines()[0]
        assert str(root) in first, first  # names the split file or the content file
        check_user_error(exc, root)
        return
    check_dataset(split_path)
    assert ds.episodes or not scene.get("episodes")


# ------------------------------------------------------------------------------ GOAT split
def _check_goat(path: Path) -> None:
    subtasks = read_or_error(load_goat_split, path)
    for s in subtasks or []:
        assert s.type in ("object", "image", "language"), s.type
        assert s.gt_positions.shape[1] == 3 and len(s.gt_positions) >= 1
        assert all(math.isfinite(v) for v in s.gt_positions.ravel())
        assert s.type == "image" or isinstance(s.query, str)


@given(doc=mutations(GOAT))
def test_goat_mutations(doc, fuzz_dir):
    _check_goat(_write(fuzz_dir / "goat" / "g.json.gz", _dump(doc)))


def test_goat_truncation(fuzz_dir):
    gz = gzip.compress(_dump(GOAT), mtime=0)
    path = fuzz_dir / "goat_trunc" / "g.json.gz"
    path.parent.mkdir(parents=True, exist_ok=True)
    for cut in range(len(gz)):
        path.write_bytes(gz[:cut])
        _check_goat(path)
