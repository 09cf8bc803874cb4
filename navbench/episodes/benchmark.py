"""A procedural ObjectNav benchmark of any size, generated on demand (byte-identical for the same arguments):

    navbench generate benchmark --houses 36 --episodes-per-split 3000 --out DIR   # HM3D-OVON's val size

writes ``DIR/scenes/val/house_NNN.glb`` (+ ``.semantic.json``; houses of their own, disjoint from the
bundled, training and selection houses), the three OVON-style splits ``DIR/objectnav/SPLIT_hH.json.gz``
(val_seen, val_seen_synonyms, val_unseen; the episodes spread evenly over the houses), ``DIR/benchmark.json``
(its arguments, episode counts and how to run it) and ``DIR/SHA256SUMS`` (``sha256sum -c`` checks it).
Run a split with the command ``benchmark.json`` holds (its files state their ``split_version``, so they are
scored at the OVON-style splits' 0.25 m without a flag), e.g.

    navbench run --episodes DIR/objectnav/val_unseen_h36.json.gz --scene-dir DIR/scenes
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from navbench.episodes.generate import SceneGoals, objectnav_split
from navbench.episodes.io import save_dataset
from navbench.episodes.split_vocabulary import TRAIN_CATEGORIES, UNSEEN_CATEGORIES

# House seeds are dataset_seed * 1000 + i: 0 (bundled), 1 (policy training) and 2 (policy selection) are
# taken, so a benchmark generated with --seed S uses dataset seed HOUSE_SEED_BASE + S.
HOUSE_SEED_BASE = 100
SUCCESS_DISTANCE = 0.25  # navbench's OVON-style splits' (navbench.env.config.SUCCESS_DISTANCE["ovon"])
SPLITS = {"val_seen": (TRAIN_CATEGORIES, False), "val_seen_synonyms": (TRAIN_CATEGORIES, True),
          "val_unseen": (UNSEEN_CATEGORIES, False)}


def per_scene_counts(episodes: int, houses: int) -> list[int]:
    """``episodes`` spread over ``houses``: the first ``episodes % houses`` houses get one more."""
    return [episodes // houses + (1 if i < episodes % houses else 0) for i in range(houses)]


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def split_path(out: Path, split: str, houses: int) -> Path:
    return Path(out) / "objectnav" / f"{split}_h{houses}.json.gz"


def split_rng(seed: int, split: str) -> np.random.Generator:
    """The generator a split's episodes are drawn from, house after house in name order (so the first
    house's episodes can be redrawn from that house alone)."""
    return np.random.default_rng([seed, 7, list(SPLITS).index(split)])


def generate_benchmark(out: str | Path, houses: int = 36, episodes_per_split: int = 3000, seed: int = 0,
                       log=print) -> dict:
    """Write the benchmark into ``out`` (see the module docstring); returns benchmark.json's content."""
    from navbench.scene.procedural import generate_dataset

    if not 1 <= houses <= 1000:
        raise ValueError(f"--houses {houses}: expected 1 to 1000")
    if episodes_per_split < houses:
        raise ValueError(f"--episodes-per-split {episodes_per_split}: at least one per house ({houses})")
    out = Path(out)
    scene_dir = out / "scenes"
    generate_dataset(scene_dir, n_train=0, n_val=houses, seed=HOUSE_SEED_BASE + seed)
    goals = [SceneGoals(p, scene_dir) for p in sorted((scene_dir / "val").glob("*.glb"))]
    counts = per_scene_counts(episodes_per_split, houses)
    splits = {}
    for split, (cats, synonyms) in SPLITS.items():
        rng = split_rng(seed, split)
        ds = objectnav_split(list(zip(goals, counts)), cats, synonyms, rng, split, f"{split}: houses")
        path = split_path(out, split, houses)
        save_dataset(ds, path)
        splits[split] = {"file": path.relative_to(out).as_posix(), "episodes": len(ds.episodes),
                         "categories": len(ds.category_to_task_category_id)}
        n_cats = len(ds.category_to_task_category_id)
        log(f"{split}: {len(ds.episodes)} episodes over {n_cats} categories in {houses} houses")
    sd = SUCCESS_DISTANCE
    manifest = {"houses": houses, "episodes_per_split": episodes_per_split, "seed": seed,
                "house_dataset_seed": HOUSE_SEED_BASE + seed, "success_distance": sd, "splits": splits,
                "run": f"navbench run --episodes DIR/{splits['val_unseen']['file']} --scene-dir DIR/scenes"}
    (out / "benchmark.json").write_text(json.dumps(manifest, indent=1) + "\n")
    files = sorted(p for p in out.rglob("*") if p.is_file() and p.name != "SHA256SUMS")
    (out / "SHA256SUMS").write_text("".join(f"{_sha256(p)}  {p.relative_to(out).as_posix()}\n" for p in files))
    log(f"wrote {out} ({len(files)} files, checksums in {out / 'SHA256SUMS'})")
    return manifest
