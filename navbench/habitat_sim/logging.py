"""``habitat_sim.logging``: the simulator's logger."""

import logging as _logging

logger = _logging.getLogger("habitat_sim")
