"""A keyframe memory of the smallest bundled val house with oracle features, built once per session."""

from pathlib import Path

import pytest

from navbench.localize.backends.oracle import OracleEncoder
from navbench.localize.benchmark import BENCHMARK_PRESCAN
from navbench.memory.prescan import load_or_build_memory
from navbench.paths import SCENES_DIR
from navbench.scene.asset import load_scene

ORACLE_SCENE = SCENES_DIR / "houses" / "val" / "house_011.glb"


@pytest.fixture(scope="session")
def memory_root(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("memories")


@pytest.fixture(scope="session")
def oracle_scene():
    return load_scene(ORACLE_SCENE)


@pytest.fixture(scope="session")
def oracle_memory(memory_root, oracle_scene):
    """The benchmark's memory config (224 x 224 camera stored at 160 x 120), oracle embeddings."""
    memory = load_or_build_memory(ORACLE_SCENE, memory_root, BENCHMARK_PRESCAN, OracleEncoder(oracle_scene.objects))
    assert memory.built_now
    return memory
