"""Scenes: meshes and their annotations, navigability and geodesics."""

# Which rules decide navigability (the grid and the layered surfaces); a change that moves any geodesic or
# collision bumps it (CHANGELOG). Here, not in navigability.py, so a run's protocol is known without loading
# the geometry stack. 2: only the passages Habitat's navmesh admits (NavGrid._navmesh_topology).
NAVIGABILITY_VERSION = 2
# The rules of a scene with more than one storey: how storeys are found (a slope chaining floors split off) and
# the layered surfaces joining them. 3: spans from Recast's heightfield (every triangle rasterised into the
# columns it touches). One storey's geodesics are the grid's and did not change with it, so a run whose scenes
# each have one storey keeps NAVIGABILITY_VERSION (and its protocol id).
MULTI_STOREY_NAVIGABILITY_VERSION = 3
