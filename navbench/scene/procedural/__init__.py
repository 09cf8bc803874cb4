"""Seeded procedural multi-room houses: floor plan, walls with doorways, furniture, GLB + semantic JSON.

``generate_house(seed)`` builds one house as a :class:`trimesh.Scene` plus its semantic annotation (the
schema of :mod:`navbench.scene.asset`, plus ``scene_id``, ``seed``, room ``type`` and ``doors``):

1. **Floor plan** (:mod:`.plan`). A rectangle of roughly ``n_rooms x 12-22 m^2`` is cut into 3-8
   rectangular rooms on a 5 cm integer grid, so adjacency tests are exact; a spanning tree of
   adjacent rooms gets doorways, so every room is reachable.
2. **Structure** (:mod:`.structure`). Walls are closed 0.1 m boxes on the room boundaries (with
   lintels above doorways), a floor slab per room with its own colour (node ``floor_<room>``), and a
   ceiling (node ``ceiling``).
3. **Furniture** (:mod:`.furnish`, objects from :mod:`.furniture`). Room recipes of categories,
   placed so doorways stay clear and the free floor stays connected; named instance colours.
4. **Assembly** (:mod:`.house`) and the bundled datasets on disk (:mod:`.dataset`); parameters in
   :mod:`.config`.

Everything is drawn from one ``numpy`` generator seeded with ``seed`` and no set/dict iteration order
or float formatting depends on anything else, so the same seed gives byte-identical GLB and JSON.

    navbench generate scenes            # the bundled houses (envs/houses), seed 0
    navbench generate policy-train      # + envs/houses_policy_train and its train_large episodes
    navbench generate policy-select     # + envs/houses_policy_select and its select episodes
"""

from navbench.scene.procedural.config import HouseConfig, HouseConfigError
from navbench.scene.procedural.dataset import (
    POLICY_SELECT_HOUSES,
    POLICY_TRAIN_HOUSES,
    generate_dataset,
    house_stats,
    write_house,
)
from navbench.scene.procedural.house import generate_house

__all__ = [
    "POLICY_SELECT_HOUSES",
    "POLICY_TRAIN_HOUSES",
    "HouseConfig",
    "HouseConfigError",
    "generate_dataset",
    "generate_house",
    "house_stats",
    "write_house",
]
