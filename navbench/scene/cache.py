"""Load a scene together with its navigability grid, caching the grid on disk; the same for the layered
surfaces of a multi-storey scene (:class:`~navbench.scene.layers.LayeredNav`).

Both are keyed by the mesh file's bytes, the mesh's placement, the grid config and the source of the
modules that build them, so editing a scene, changing the agent's radius or the building code rebuilds
them, and nothing else does. Arrays are stored as ``.npz`` (never pickles).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from functools import lru_cache
from pathlib import Path

import numpy as np

from navbench.paths import cache_dir
from navbench.scene import layers, navigability
from navbench.scene.asset import SceneAsset, SceneError, load_scene
from navbench.scene.layers import LayeredNav
from navbench.scene.navigability import NavGrid, NavGridConfig


@lru_cache(maxsize=64)
def file_digest(path: Path, mtime_ns: int, size: int) -> str:
    h = hashlib.sha1()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def scene_digest(path: str | Path) -> str:
    """sha1 of the scene file's bytes (memoised on path, mtime and size)."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: scene file not found")
    st = path.stat()
    return file_digest(path.resolve(), st.st_mtime_ns, st.st_size)


@lru_cache(maxsize=1)
def _builder_digest() -> str:
    return hashlib.sha1(Path(navigability.__file__).read_bytes()).hexdigest()


@lru_cache(maxsize=1)
def _layers_digest() -> str:
    # LayeredNav is built with the grid module's lattice and floor test too: both sources are in its key.
    return hashlib.sha1(Path(layers.__file__).read_bytes() + Path(navigability.__file__).read_bytes()).hexdigest()


# Largest grid built (250 m x 250 m at 5 cm): bigger means a scene in other units or stray geometry.
MAX_GRID_CELLS = 25_000_000


def _check_extent(bounds, cell_size: float) -> None:
    """Refuse a grid too large to allocate, before any per-cell array is built."""
    (x0, _, z0), (x1, _, z1) = bounds
    cells = ((x1 - x0) / cell_size + 2) * ((z1 - z0) / cell_size + 2)
    if cells > MAX_GRID_CELLS:
        raise SceneError(f"mesh spans {x1 - x0:.4g} x {z1 - z0:.4g} m: over {MAX_GRID_CELLS:.0e} grid cells of "
                         f"{cell_size} m (units not metres, or stray geometry?)")


def load_scene_and_navgrid(path: str | Path, config: NavGridConfig = NavGridConfig(), use_cache: bool = True,
                           floor_hint: float | None = None) -> tuple[SceneAsset, NavGrid]:
    """The scene and the grid of its floor; with ``floor_hint`` (an episode's start height), the grid of
    the storey a point at that height stands on (see :func:`navgrid_for`)."""
    asset = load_scene(Path(path))
    return asset, navgrid_for(asset, config, use_cache, floor_hint)


def navgrid_for(asset: SceneAsset, config: NavGridConfig = NavGridConfig(), use_cache: bool = True,
                floor_hint: float | None = None) -> NavGrid:
    """The (disk-cached) grid of ``asset``. The default floor serves every hint within half the agent's
    height of it, so single-floor scenes build one grid; another storey gets its own grid."""
    grid = _cached_grid(asset, config, use_cache)
    if floor_hint is None or config.floor_height is not None or \
            abs(floor_hint - grid.floor_height) <= config.agent_height / 2:
        return grid
    floor = round(NavGrid.floor_for(asset.mesh, floor_hint, config), 4)
    if abs(floor - grid.floor_height) <= config.max_climb / 2:
        return grid
    return _cached_grid(asset, dataclasses.replace(config, floor_height=floor), use_cache)


def _cache_file(asset: SceneAsset, config: NavGridConfig, builder: str, kind: str) -> Path:
    path = Path(asset.path)
    # The key covers the scene's bytes, its placement (a dataset config may rotate the mesh), the grid
    # config and the building code itself, so a change to any of them rebuilds instead of silently
    # reusing a grid made by other rules.
    placement = json.dumps(np.round(asset.mesh.bounds, 4).tolist())
    key = hashlib.sha1((scene_digest(path) + placement + json.dumps(dataclasses.asdict(config), sort_keys=True)
                        + builder).encode())
    return cache_dir(kind) / f"{path.name.split('.')[0]}-{key.hexdigest()[:16]}.npz"


def _cached_grid(asset: SceneAsset, config: NavGridConfig, use_cache: bool) -> NavGrid:
    path = Path(asset.path)
    cached = _cache_file(asset, config, _builder_digest(), "navgrid")
    if use_cache and cached.is_file():
        try:
            return NavGrid.load(cached)
        except (OSError, ValueError, KeyError, SceneError):
            pass  # a stale or partial cache file is rebuilt below
    try:
        _check_extent(asset.mesh.bounds, config.cell_size)
        grid = NavGrid.from_mesh(asset.mesh, config)
    except ValueError as exc:  # the grid builder's messages describe the mesh; name its file
        raise SceneError(f"{path}: {exc}") from None
    if use_cache:
        # A per-process temporary name: parallel workers may build the same grid at once, and each
        # must rename its own complete file into place (the last rename wins; both are identical).
        tmp = cached.with_name(f"{cached.stem}.{os.getpid()}.tmp.npz")
        grid.save(tmp)
        tmp.replace(cached)
    return grid


def load_scene_and_layers(path: str | Path, config: NavGridConfig = NavGridConfig(),
                          use_cache: bool = True) -> tuple[SceneAsset, LayeredNav]:
    """The scene and its layered surfaces (every storey, joined over stairs and ramps; disk-cached)."""
    asset = load_scene(Path(path))
    return asset, layers_for(asset, config, use_cache)


def layers_for(asset: SceneAsset, config: NavGridConfig = NavGridConfig(), use_cache: bool = True) -> LayeredNav:
    """The (disk-cached) :class:`LayeredNav` of ``asset``, keyed as the grid is (see the module docstring)."""
    path = Path(asset.path)
    cached = _cache_file(asset, config, _layers_digest(), "layers")
    if use_cache and cached.is_file():
        try:
            return LayeredNav.load(cached)
        except SceneError:
            pass  # a stale or partial cache file is rebuilt below
    try:
        _check_extent(asset.mesh.bounds, config.cell_size)
        nav = LayeredNav.from_mesh(asset.mesh, config)
    except ValueError as exc:
        raise SceneError(f"{path}: {exc}") from None
    if use_cache:
        tmp = cached.with_name(f"{cached.stem}.{os.getpid()}.tmp.npz")  # per process, as for the grid
        nav.save(tmp)
        tmp.replace(cached)
    return nav
