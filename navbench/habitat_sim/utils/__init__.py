"""``habitat_sim.utils``: the quaternion and colour helpers (``common``)."""
