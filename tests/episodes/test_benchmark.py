"""`navbench generate benchmark`: the same arguments write the same bytes, with checksums that hold."""

import hashlib
import json

from navbench.api import resolve_episodes
from navbench.cli import main
from navbench.env.config import SUCCESS_DISTANCE
from navbench.episodes.benchmark import SUCCESS_DISTANCE as BENCH_SD
from navbench.episodes.benchmark import per_scene_counts, split_path
from navbench.episodes.io import load_dataset, save_dataset


def test_episodes_are_spread_evenly_over_houses():
    assert per_scene_counts(3000, 36) == [84] * 12 + [83] * 24 and sum(per_scene_counts(3000, 36)) == 3000
    assert BENCH_SD == SUCCESS_DISTANCE["ovon"]


def test_generate_benchmark_is_byte_identical_and_checksummed(tmp_path, capsys):
    for d in ("a", "b"):
        assert main(["generate", "benchmark", "--houses", "1", "--episodes-per-split", "5",
                     "--out", str(tmp_path / d)]) == 0
    sums = (tmp_path / "a" / "SHA256SUMS").read_text()
    assert sums == (tmp_path / "b" / "SHA256SUMS").read_text()
    listed = dict(line.split("  ")[::-1] for line in sums.splitlines())
    assert {"benchmark.json", "scenes/val/house_000.glb", "objectnav/val_unseen_h1.json.gz"} <= set(listed)
    for name, digest in listed.items():
        assert hashlib.sha256((tmp_path / "a" / name).read_bytes()).hexdigest() == digest, name
    ds = load_dataset(split_path(tmp_path / "a", "val_unseen", 1))
    assert len(ds.episodes) == 5 and {e.scene_id for e in ds.episodes} == {"val/house_000.glb"}
    manifest = json.loads((tmp_path / "a" / "benchmark.json").read_text())
    assert manifest["splits"]["val_seen"]["episodes"] == 5 and manifest["success_distance"] == 0.25
    # its files are scored at 0.25 m by default, as the bundled OVON-style splits are; a plain ObjectNav-v1 file
    # at Habitat's 0.1 m
    assert "--success-distance" not in manifest["run"]
    assert resolve_episodes(None, None, split_path(tmp_path / "a", "val_unseen", 1))[::3] == ("objectnav", 0.25)
    plain = tmp_path / "plain.json.gz"
    ds.extra.pop("split_version")
    save_dataset(ds, plain)
    assert resolve_episodes(None, None, plain)[::3] == ("objectnav", 0.1)
    assert "run a split with: navbench run --episodes" in capsys.readouterr().out
    assert main(["generate", "benchmark", "--houses", "3", "--episodes-per-split", "2", "--out",
                 str(tmp_path / "c")]) == 2
