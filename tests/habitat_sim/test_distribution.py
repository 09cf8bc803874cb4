"""compat/habitat-sim: the top-level habitat_sim, magnum and corrade modules over navbench.habitat_sim."""

import subprocess
import sys
import tomllib
from pathlib import Path

from navbench._version import __version__

COMPAT = Path(__file__).resolve().parents[2] / "compat" / "habitat-sim"
ROOT = COMPAT.parents[1]


def _run(code: str, *paths: Path) -> subprocess.CompletedProcess:
    path = ":".join(str(p) for p in (*paths, COMPAT, ROOT))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={"PYTHONPATH": path, "PATH": "/usr/bin:/bin"})


def test_distribution_metadata_follows_navbench():
    meta = tomllib.loads((COMPAT / "pyproject.toml").read_text())
    assert meta["project"]["name"] == "navbench-habitat-sim"
    assert meta["project"]["version"] == __version__
    assert f"navbench=={__version__}" in meta["project"]["dependencies"]
    assert sorted(meta["tool"]["setuptools"]["packages"]) == ["corrade", "habitat_sim", "magnum"]


def test_top_level_modules_are_navbenchs():
    out = _run("""
import habitat_sim, magnum, corrade
import habitat_sim.agent.agent, habitat_sim.utils.common, habitat_sim._ext.habitat_sim_bindings
from habitat_sim.nav import NavMeshSettings
import navbench.habitat_sim as nb
assert habitat_sim.utils.common is nb.utils.common
assert habitat_sim.agent.agent.AgentState is nb.AgentState and NavMeshSettings is nb.NavMeshSettings
assert magnum.Vector3 is nb.magnum.Vector3 and magnum.trade.ImporterManager is nb.magnum.trade.ImporterManager
assert magnum.math.dot(magnum.Vector3(1, 2, 3), magnum.Vector3(1, 1, 1)) == 6.0
try:
    from habitat_sim.utils import profiling_utils
    raise SystemExit("profiling_utils imported")
except ImportError:
    pass
try:
    import habitat_sim.config
    raise SystemExit("a second copy of navbench.habitat_sim.config imported")
except ImportError:
    pass
print(habitat_sim.__version__, habitat_sim.__navbench__)
""")
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [f"0.3.3+navbench.{__version__}", __version__]


def test_a_real_habitat_sim_beside_it_is_refused(tmp_path):
    dist = tmp_path / "habitat_sim-0.3.3.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: habitat-sim\nVersion: 0.3.3\n")
    out = _run("import habitat_sim", tmp_path)
    assert out.returncode != 0
    assert "a real habitat-sim 0.3.3 is installed beside navbench-habitat-sim" in out.stderr.strip().splitlines()[-1]
