"""habitat-sim's Python API, served by navbench: this module is :mod:`navbench.habitat_sim`, and
``habitat_sim.<sub>`` is ``navbench.habitat_sim.<sub>``. ``__navbench__`` names the navbench version."""

import importlib
import importlib.metadata
import sys


def _refuse_real_habitat_sim() -> None:
    for name in ("habitat-sim", "habitat_sim"):
        try:
            version = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
        raise ImportError(f"habitat_sim: a real habitat-sim {version} is installed beside navbench-habitat-sim and "
                          "both provide this module; use a separate virtualenv for each")


_refuse_real_habitat_sim()

import navbench.habitat_sim as _impl  # noqa: E402
from navbench.habitat_sim import *  # noqa: E402,F403
from navbench.habitat_sim import __navbench__, __version__, cuda_enabled  # noqa: E402,F401

for _name in _impl.SUBMODULES:
    sys.modules[f"{__name__}.{_name}"] = importlib.import_module(f"navbench.habitat_sim.{_name}")
__path__ = []  # every submodule is registered above; nothing else is importable under habitat_sim
