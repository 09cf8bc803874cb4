"""``habitat_sim.geo``: habitat-sim's frame constants (y up, -z forward, x right)."""

import numpy as np

UP = np.array([0.0, 1.0, 0.0])
GRAVITY = np.array([0.0, -1.0, 0.0])
FRONT = np.array([0.0, 0.0, -1.0])
BACK = np.array([0.0, 0.0, 1.0])
LEFT = np.array([-1.0, 0.0, 0.0])
RIGHT = np.array([1.0, 0.0, 0.0])
