"""Scenes: meshes and their annotations, navigability and geodesics."""

# Which rules decide navigability (the grid and the layered surfaces); a change that moves any geodesic or
# collision bumps it (CHANGELOG). Here, not in navigability.py, so a run's protocol is known without loading
# the geometry stack. 2: only the passages Habitat's navmesh admits (NavGrid._navmesh_topology).
NAVIGABILITY_VERSION = 2
