"""SR@K scoring, the bundled GOAT-style split, its generator and a small benchmark run."""

import gzip
import json
import shutil

import numpy as np
import pytest

from navbench.localize.backends.oracle import centre_instance
from navbench.localize.benchmark import PERCEPTION, run_localize, sr_by_type, success_at_k
from navbench.localize.describe import ground
from navbench.localize.goat import (
    GOAT_DIR,
    GoatConfig,
    GoatSplitError,
    generate_goat_split,
    load_goat_split,
)
from navbench.paths import SCENES_DIR
from navbench.scene.asset import load_scene

from .conftest import ORACLE_SCENE


def test_success_at_k_on_hand_made_predictions():
    gt = np.array([[0.0, 0.5, 0.0], [10.0, 0.5, 0.0]])
    preds = [[5.0, 0.0, 0.0], [10.0, 3.0, 1.4], [0.0, 0.0, 0.0]]  # 2nd: 1.4 m away in xz, height ignored
    assert not success_at_k(preds, gt, k=1)
    assert success_at_k(preds, gt, k=2)
    assert not success_at_k(preds, gt[:1], k=2)  # only the first object counts now
    assert success_at_k(preds, gt[:1], k=3)
    assert not success_at_k(preds, gt, k=2, radius=1.3)
    assert success_at_k([[1.5, 0.0, 0.0]], gt, k=1)  # the 1.5 m boundary counts as success
    assert not success_at_k([], gt, k=5) and not success_at_k(preds, np.zeros((0, 3)), k=5)


def test_sr_is_the_mean_over_query_types_not_over_subtasks():
    records = ([{"type": "object", "success": True}] * 9 + [{"type": "object", "success": False}]
               + [{"type": "image", "success": False}] * 2 + [{"type": "language", "success": True}])
    sr, by_type = sr_by_type(records)
    assert by_type == {"object": 0.9, "image": 0.0, "language": 1.0}
    assert sr == pytest.approx((0.9 + 0.0 + 1.0) / 3)
    assert sr_by_type([]) == (0.0, {})


def test_bundled_goat_split_is_complete_and_consistent():
    subtasks = load_goat_split("goat_val")
    for t in ("object", "image", "language"):
        assert sum(s.type == t for s in subtasks) >= 60
    assert len({s.id for s in subtasks}) == len(subtasks)
    assets = {sid: load_scene(SCENES_DIR / sid) for sid in {s.scene_id for s in subtasks}}
    assert sorted(assets) == [f"houses/val/house_{i:03d}.glb" for i in range(8, 12)]
    for s in subtasks:
        asset = assets[s.scene_id]
        centres = np.stack([asset.objects[i].center for i in s.target_ids])
        assert np.allclose(s.gt_positions, centres, atol=1e-3)
        if s.type == "object":  # every instance of the category is a valid answer
            assert sorted(s.target_ids) == sorted(o.id for o in asset.objects_of(s.query))
        elif s.type == "language":  # unambiguous: the description grounds to the target alone
            assert ground(s.query, asset.objects) == list(s.target_ids)
        else:
            q = s.to_query(GOAT_DIR / "goat_val")
            assert q.image.shape == (224, 224, 3) and q.image_ids.shape == (224, 224)
            assert centre_instance(q.image_ids) == s.target_ids[0]
            assert (q.image_ids == s.target_ids[0]).mean() >= 0.02


def test_generator_writes_a_loadable_split(tmp_path):
    path = generate_goat_split(tmp_path / "mini", [ORACLE_SCENE], seed=3, per_type=2,
                               config=GoatConfig(per_type=2, pose_tries=30), split="mini")
    subtasks = load_goat_split(path)
    assert [s.type for s in subtasks].count("object") == 2 and len(subtasks) == 6
    assert all(s.scene_id == "houses/val/house_011.glb" for s in subtasks)
    for s in subtasks:
        if s.type == "image":
            assert (tmp_path / "mini" / s.image).is_file() and (tmp_path / "mini" / s.image_ids).is_file()
    # Reproducible: the same seed writes the same bytes.
    again = generate_goat_split(tmp_path / "mini2", [ORACLE_SCENE], seed=3, config=GoatConfig(per_type=2,
                                                                                            pose_tries=30),
                                split="mini")
    assert gzip.decompress(path.read_bytes()) == gzip.decompress(again.read_bytes())
    with pytest.raises(GoatSplitError, match="not found"):
        load_goat_split("nope", root=tmp_path)


def test_run_localize_writes_predictions_and_summary(tmp_path, memory_root, oracle_memory):
    # A small split of house_011's bundled subtasks (two per type), beside copies of its images.
    picked = []
    for t in ("object", "image", "language"):
        picked += [s for s in load_goat_split("goat_val") if s.scene_id.endswith("house_011.glb") and s.type == t][:2]
    split_dir = tmp_path / "goat" / "small"
    (split_dir / "images").mkdir(parents=True)
    for s in picked:
        for f in (s.image, s.image_ids):
            if f:
                shutil.copy(GOAT_DIR / "goat_val" / f, split_dir / f)
    with gzip.open(split_dir / "small.json.gz", "wt") as f:
        json.dump({"info": {}, "subtasks": [s.to_json() for s in picked]}, f)

    summary = run_localize("small", "oracle", "none", k=5, out=tmp_path / "out", memory_root=memory_root,
                           split_root=tmp_path / "goat")
    assert summary["memory_built_now"] == {"houses/val/house_011.glb": False}  # the session's memory
    assert summary["n_by_type"] == {"object": 2, "image": 2, "language": 2}
    assert summary["sr"] == 1.0 and summary["sr_by_type"] == {"object": 1.0, "image": 1.0, "language": 1.0}
    assert summary["storage_bytes"] == oracle_memory.stats.bytes and summary["build_s"] > 0
    assert summary["query_ms"] > 0
    assert summary["run_on"] == {"device": "cpu", "device_name": "cpu", "precision": None}  # the oracle runs no model
    written = json.loads((tmp_path / "out" / "summary.json").read_text())
    for key in ("k", "sr", "sr_by_type", "build_s", "storage_bytes", "query_ms", "perception", "noise", "fusion",
                "rerank"):
        assert key in written
    lines = [json.loads(x) for x in (tmp_path / "out" / "predictions.jsonl").read_text().splitlines()]
    assert len(lines) == 6 and all(len(r["top_k"]) <= 5 and r["success"] for r in lines)
    assert {r["type"] for r in lines} == {"object", "image", "language"}

    limited = run_localize("small", limit=1, memory_root=memory_root, split_root=tmp_path / "goat", fusion=False,
                           rerank=False)
    assert limited["n_by_type"]["object"] == 1 and not limited["fusion"] and not limited["rerank"]
    with pytest.raises(ValueError, match="unknown perception"):
        run_localize("small", perception="clip", split_root=tmp_path / "goat")
    with pytest.raises(ValueError, match="model directories"):
        run_localize("small", perception="siglip2+qwen2.5-vl+sam3", split_root=tmp_path / "goat",
                     memory_root=memory_root)
    assert set(PERCEPTION) == {"oracle", "siglip2+qwen2.5-vl+sam3"}


def test_the_summary_says_where_the_real_models_ran():
    from navbench.localize.benchmark import ModelDirs, _run_on
    got = _run_on("siglip2+qwen2.5-vl+sam3", ModelDirs(device="cpu", precision="bf16"))
    assert got == {"device": "cpu", "device_name": "cpu", "precision": "bf16"}
