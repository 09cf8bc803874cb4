"""The part of Magnum's Python API habitat-lab's navigation uses, served by navbench
(:mod:`navbench.habitat_sim.magnum`)."""

import sys

from navbench.habitat_sim.magnum import *  # noqa: F403
from navbench.habitat_sim.magnum import math_ as math
from navbench.habitat_sim.magnum import trade

sys.modules[f"{__name__}.math"] = math
sys.modules[f"{__name__}.trade"] = trade
__path__: list[str] = []
