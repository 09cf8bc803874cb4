"""navbench: a CPU-friendly, Habitat-style benchmark harness for embodied navigation.

``import navbench`` registers the Gymnasium ids ``navbench/PointNav-v0`` and ``navbench/ObjectNav-v0``
(entry points are strings, so nothing heavy is imported until an env is made).
"""

import gymnasium as _gym

__version__ = "0.1.0"

for _id, _entry in (("navbench/PointNav-v0", "navbench.env.pointnav:PointNavEnv"),
                    ("navbench/ObjectNav-v0", "navbench.env.objectnav:ObjectNavEnv")):
    if _id not in _gym.registry:
        # Habitat truncates at 500 steps inside the env; no TimeLimit wrapper on top of that.
        _gym.register(id=_id, entry_point=_entry, disable_env_checker=True)


def evaluate(*args, **kwargs):
    """Evaluate an agent over a split and return the summary: see :func:`navbench.api.evaluate`."""
    from navbench.api import evaluate as _evaluate
    return _evaluate(*args, **kwargs)
