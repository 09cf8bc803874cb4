"""navbench: a CPU-friendly, Habitat-style benchmark harness for embodied navigation.

``import navbench`` registers the Gymnasium ids ``navbench/PointNav-v0`` and ``navbench/ObjectNav-v0``.
"""

__version__ = "0.1.0"
