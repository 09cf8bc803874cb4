"""LayeredNav on disk: the cached surfaces are the built ones, a corrupt file is rebuilt, and the key follows the
scene's bytes and the config."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from navbench.scene.asset import SceneError, load_scene
from navbench.scene.cache import layers_for, load_scene_and_layers
from navbench.scene.layers import LayeredNav
from navbench.scene.navigability import NavGridConfig

sys.path.insert(0, str(Path(__file__).parent))
from storeys import UPPER, house


@pytest.fixture
def scene(tmp_path, monkeypatch) -> Path:
    monkeypatch.setenv("NAVBENCH_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "stairs.glb"
    house("stairs").export(path)
    return path


def _same(a: LayeredNav, b: LayeredNav) -> None:
    for k in ("origin", "cell", "height", "smooth", "navigable"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    assert a.shape == b.shape and a.config == b.config
    assert (a.graph != b.graph).nnz == 0  # the recomputed step lengths are the built ones, to the bit


def test_cached_surfaces_are_the_built_ones(scene, tmp_path):
    asset, built = load_scene_and_layers(scene)
    files = list((tmp_path / "cache" / "layers").glob("*.npz"))
    assert len(files) == 1
    loaded = LayeredNav.load(files[0])
    _same(built, LayeredNav.from_mesh(asset.mesh))
    _same(loaded, built)
    a, b = (1.0, 0.0, 2.6), (9.0, UPPER, 2.6)
    assert layers_for(asset).geodesic_distance(a, b) == built.geodesic_distance(a, b)
    assert not list(files[0].parent.glob("*.tmp.npz"))  # written under a temporary name, then renamed


def test_corrupt_cache_file_is_rebuilt(scene, tmp_path):
    asset, built = load_scene_and_layers(scene)
    (cached,) = (tmp_path / "cache" / "layers").glob("*.npz")
    cached.write_bytes(b"not a zip")
    _same(layers_for(asset), built)
    _same(LayeredNav.load(cached), built)  # and rewritten


def test_key_follows_config_and_scene_bytes(scene, tmp_path):
    asset = load_scene(scene)
    layers_for(asset)
    layers_for(asset, dataclasses.replace(NavGridConfig(), agent_radius=0.25))
    house(None).export(scene)  # same name, other bytes
    layers_for(load_scene(scene))
    assert len(list((tmp_path / "cache" / "layers").glob("*.npz"))) == 3


def test_a_cache_file_whose_arrays_disagree_is_rebuilt(scene, tmp_path):
    asset, built = load_scene_and_layers(scene)
    (cached,) = (tmp_path / "cache" / "layers").glob("*.npz")
    with np.load(cached) as d:
        arrays = {k: d[k] for k in d.files}
    arrays["height"] = arrays["height"][:-1]
    np.savez(cached, **arrays)
    with pytest.raises(SceneError, match="do not match"):
        LayeredNav.load(cached)
    _same(layers_for(asset), built)
