"""The bundled data is found in a checkout, in an installed wheel's package data and through NAVBENCH_DATA;
the build carries every data directory; bundled recipes resolve by name from any directory."""

import re
import tomllib
from pathlib import Path

import pytest

import navbench
import navbench.paths as paths
from navbench.cli import main
from navbench.policy.recipe import bundled_recipes, load_recipe, recipe_path

PROJECT = Path(__file__).resolve().parents[1]


def test_checkout_data_root_holds_the_bundled_directories(monkeypatch):
    monkeypatch.delenv("NAVBENCH_DATA", raising=False)
    assert paths.data_root() == PROJECT
    for name in paths.DATA_DIRS:
        assert (PROJECT / name).is_dir(), name


def test_installed_package_data_wins_over_the_checkout_and_navbench_data_over_both(tmp_path, monkeypatch):
    monkeypatch.delenv("NAVBENCH_DATA", raising=False)
    pkg = tmp_path / "navbench"
    (pkg / "_data").mkdir(parents=True)
    monkeypatch.setattr(paths, "files", lambda name: pkg)
    assert paths.data_root() == pkg / "_data"
    monkeypatch.setenv("NAVBENCH_DATA", str(tmp_path / "elsewhere"))
    assert paths.data_root() == tmp_path / "elsewhere"


def test_the_build_carries_every_data_directory():
    setup = (PROJECT / "setup.py").read_text()
    manifest = (PROJECT / "MANIFEST.in").read_text().split()
    assert re.search(r"DATA_DIRS = \(([^)]*)\)", setup).group(1).replace('"', "").replace(" ", "").split(",") \
        == list(paths.DATA_DIRS)
    assert all(("graft", name) in zip(manifest, manifest[1:]) for name in paths.DATA_DIRS)


def test_metadata_and_version():
    meta = tomllib.loads((PROJECT / "pyproject.toml").read_text())["project"]
    assert meta["license"] == "MIT" and (PROJECT / "LICENSE").is_file()
    assert meta["classifiers"] and meta["urls"] and "version" in meta["dynamic"]
    assert re.fullmatch(r"\d+\.\d+\.\d+", navbench.__version__)


def test_version_flag(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"navbench {navbench.__version__}"


def test_bundled_recipes_resolve_by_name_from_any_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert {"pointnav/2h", "pointnav/full"} <= set(bundled_recipes())
    two_hours = paths.CONFIGS_DIR / "pointnav" / "2h.toml"
    for spec in ("2h", "2h.toml", "pointnav/2h", "configs/pointnav/2h.toml"):
        assert recipe_path(spec) == two_hours, spec
    assert load_recipe("2h").name == "2h"
    (tmp_path / "2h").write_text('name = "mine"\n[[stage]]\nname = "e"\ntrainer = "encoder"\n')
    assert load_recipe("2h").name == "mine"  # a file in the working directory comes first


def test_unknown_recipe_is_a_one_line_error(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["train", "--config", "nosuch"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "nosuch: recipe file not found" in err and "pointnav/2h" in err


def test_bundled_checkpoint_paths_resolve_from_any_directory(tmp_path, monkeypatch):
    from navbench.policy.checkpoint import CheckpointError, checkpoint_path, read_checkpoint

    monkeypatch.chdir(tmp_path)
    assert checkpoint_path("policies/pointnav_2h.pth") == paths.ROOT / "policies" / "pointnav_2h.pth"
    assert read_checkpoint("policies/pointnav_2h.pth").state_dict
    (tmp_path / "policies").mkdir()
    (tmp_path / "policies" / "pointnav_2h.pth").write_bytes(b"x")
    assert checkpoint_path("policies/pointnav_2h.pth") == Path("policies/pointnav_2h.pth")  # a local file first
    with pytest.raises(CheckpointError, match="^nosuch.pth: no such checkpoint file"):
        read_checkpoint("nosuch.pth")


def test_torch_is_a_range_and_ci_installs_the_tested_build_inside_it():
    from packaging.requirements import Requirement
    from packaging.version import Version

    deps = [Requirement(d) for d in tomllib.loads((PROJECT / "pyproject.toml").read_text())["project"]["dependencies"]]
    torch = next(r for r in deps if r.name == "torch")
    assert not any(s.operator in ("==", "===") for s in torch.specifier), torch
    pins = [Requirement(line) for line in (PROJECT / "constraints" / "ci.txt").read_text().splitlines()
            if line.strip() and not line.startswith("#")]
    tested = next(r for r in pins if r.name == "torch")
    (pin,) = tested.specifier
    assert pin.operator == "==" and Version(pin.version) in torch.specifier
    # the oldest release claimed has the checkpoint loading API navbench.policy.checkpoint uses (torch 2.5)
    assert Version("2.4.1") not in torch.specifier and Version("2.5.0") in torch.specifier
    makefile, wheel_check = (PROJECT / "Makefile").read_text(), (PROJECT / "tests" / "wheel_check.sh").read_text()
    assert "-c constraints/ci.txt" in makefile and "constraints/ci.txt" in wheel_check
