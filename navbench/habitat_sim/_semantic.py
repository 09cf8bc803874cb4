"""The semantic scene of a loaded scene, in habitat-sim's order and ids, and the per-face ids its SEMANTIC sensor
draws.

* HM3D (``{name}.semantic.txt`` + semantic mesh), as habitat-sim's ``SemanticScene::buildHM3DHouse``
  (``src/esp/scene/HM3DSemanticScene.cpp``): ``objects`` are object 0 (category ``"Unknown"``, region -1) and
  every row of semantic.txt, ordered by instance id; ``objects[k].id`` is ``"{raw name}_{instance id}"``. Where
  semantic.txt skips an id, habitat-sim's list is shorter and no longer indexed by id (habitat-lab's ObjectNav
  goal lookup then fails); here the gap holds an ``"Unknown"`` object, so ``objects[i]`` is always instance
  ``i``. Categories are the raw names, indexed in order of first appearance from ``"Unknown"`` = 0 (listed by
  index; habitat-sim lists them in hash order); regions are the region ids (ordered, -1 first), ``id``
  ``"_{region id}"``, no category; no levels. An object's ``aabb`` (and unrotated ``obb``) bounds its faces of
  the render mesh (habitat-sim bounds the largest connected part of its semantic-mesh vertices). The sensor
  draws every listed object's id (walls and floors too) and 0 where the colour is not listed.
* MP3D (``{name}.house`` + ``{name}_semantic.ply``), as ``SemanticScene::buildMp3dHouse``
  (``src/esp/scene/Mp3dSemanticScene.cpp``): levels, regions, categories and objects in file order; ``L``, ``R``
  and ``O`` positions and boxes turned from Matterport's z-up frame into Habitat's, as habitat-sim's default
  rotation does (``(x, y, z) -> (x, z, -y)``); an object's ``obb`` is its record's box and its ``aabb`` the box
  bounding that; ``objects[k].id`` is ``"{level}_{region}_{index}"``. The sensor draws each face's object index
  (0 for faces without one).
* navbench's own scenes (a ``.semantic.json`` sidecar, or none): the HM3D layout over navbench's instance ids:
  ``objects[i]`` is instance ``i`` for every ``i`` up to the largest (ids no object has are category
  ``"Unknown"``, as is ``objects[0]``), ``id`` ``"{category}_{i}"``; categories ``"Unknown"`` = 0 then in order
  of first appearance; one region per annotated room (``id`` the room's name, category the room's name), no
  levels. The sensor draws navbench's instance ids, 0 for structure.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from navbench.habitat_sim import magnum as mn
from navbench.habitat_sim.geo import OBB
from navbench.habitat_sim.scene import (
    Mp3dObjectCategory,
    Mp3dRegionCategory,
    SemanticCategory,
    SemanticLevel,
    SemanticObject,
    SemanticRegion,
    SemanticScene,
)

# habitat-sim's default rotation of a semantic scene descriptor: Quaternion::rotation(ESP_FRONT, ESP_GRAVITY),
# Matterport's z up to Habitat's y up (rows: the Habitat axes in Matterport coordinates)
_MP3D_TO_HABITAT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def load_semantics(asset) -> tuple[SemanticScene, np.ndarray]:
    """The semantic scene of ``asset`` and the (F,) int32 instance id of each of its faces for the SEMANTIC sensor
    (-1, drawn as 0, where none)."""
    from navbench.scene import datasets
    from navbench.scene.asset import semantic_path
    from navbench.scene.datasets import instances

    path = Path(asset.path)
    found = None
    # the files navbench.scene.asset.load_scene read the annotations from: a sidecar or a scene instance are its own
    if path.is_file() and not semantic_path(path).is_file() and not instances.is_scene_instance(path):
        found = datasets.annotation_files(path, datasets.stage_attributes(path))
    if found is None:
        return own_scene(asset), np.asarray(asset.face_ids, np.int32)
    kind, descriptor, sem_mesh, frame = found
    if kind == "hm3d":
        return hm3d_scene(asset, descriptor, sem_mesh, frame)
    return mp3d_scene(asset, descriptor, sem_mesh, frame)


def _face_boxes(asset, face_ids: np.ndarray) -> dict[int, mn.Range3D]:
    """The box bounding each id's faces (ids >= 0)."""
    tri = np.asarray(asset.mesh.vertices, np.float64)[np.asarray(asset.mesh.faces)]
    keep = face_ids >= 0
    ids, lo, hi = face_ids[keep], tri[keep].min(axis=1), tri[keep].max(axis=1)
    uniq, inverse = np.unique(ids, return_inverse=True)
    box_lo = np.full((len(uniq), 3), np.inf)
    box_hi = np.full((len(uniq), 3), -np.inf)
    np.minimum.at(box_lo, inverse, lo)
    np.maximum.at(box_hi, inverse, hi)
    return {int(k): mn.Range3D(box_lo[j], box_hi[j]) for j, k in enumerate(uniq)}


def own_scene(asset) -> SemanticScene:
    scene = SemanticScene()
    unknown = SemanticCategory(0, "Unknown")
    categories: dict[str, SemanticCategory] = {"Unknown": unknown}
    regions: dict[str, SemanticRegion] = {}
    for room in asset.rooms:
        if room.name not in regions:
            regions[room.name] = SemanticRegion(len(regions), SemanticCategory(len(regions), room.name),
                                                mn.Range3D(room.aabb_min, room.aabb_max), name=room.name)
    top = max((int(k) for k in asset.objects), default=0)
    for oid in range(top + 1):
        obj = asset.objects.get(oid)
        if obj is None:
            scene.objects.append(SemanticObject(oid, unknown, mn.Range3D()))
            continue
        name = str(obj.category)
        cat = categories.setdefault(name, SemanticCategory(len(categories), name))
        region = regions.get(obj.room)
        scene.objects.append(SemanticObject(oid, cat, mn.Range3D(obj.aabb_min, obj.aabb_max), region))
        if region is not None:
            region.objects.append(scene.objects[-1])
    scene.categories = list(categories.values())
    scene.regions = list(regions.values())
    if len(asset.mesh.vertices):
        scene.aabb = mn.Range3D(*np.asarray(asset.mesh.bounds, np.float64))
    return scene


def hm3d_scene(asset, txt: Path, sem_mesh: Path, frame) -> tuple[SemanticScene, np.ndarray]:
    from navbench.scene.datasets import hm3d

    records = hm3d.read_semantic_txt(txt)
    labels = hm3d.face_labels(records, txt, sem_mesh, asset.mesh, frame)
    boxes = _face_boxes(asset, labels)
    rows = {0: ("Unknown", -1)}  # habitat-sim's object 0; a later row with id 0 replaces it, as there
    for oid, _, name, region in records:
        rows[oid] = (name, region)
    scene = SemanticScene()
    categories: dict[str, SemanticCategory] = {}
    regions: dict[int, SemanticRegion] = {}
    for name, region in [("Unknown", -1)] + [(n, r) for _, _, n, r in records]:  # first appearance, as habitat-sim
        categories.setdefault(name, SemanticCategory(len(categories), name))
        regions.setdefault(region, SemanticRegion(region))
    for oid in range(max(rows) + 1):  # an id semantic.txt skips is an Unknown object (see the module docstring)
        name, region = rows.get(oid, ("Unknown", -1))
        obj = SemanticObject(oid, categories[name], boxes.get(oid, mn.Range3D()), regions[region])
        regions[region].objects.append(obj)
        scene.objects.append(obj)
    scene.categories = sorted(categories.values(), key=lambda c: c.index())
    scene.regions = [regions[r] for r in sorted(regions)]
    listed = np.fromiter(rows, np.int64, len(rows))
    return scene, np.where(np.isin(labels, listed) & (labels > 0), labels, -1).astype(np.int32)


def _floats(tokens: list[str], at: int, n: int = 3) -> np.ndarray:
    return np.array([float(t) for t in tokens[at:at + n]], np.float64)


def _mp3d_point(tokens: list[str], at: int) -> np.ndarray:
    return _MP3D_TO_HABITAT @ _floats(tokens, at)


def _mp3d_box(tokens: list[str], at: int) -> mn.Range3D:
    """``xlo ylo zlo xhi yhi zhi`` turned as habitat-sim turns it: centre rotated, sizes rotated and made positive."""
    lo, hi = _floats(tokens, at), _floats(tokens, at + 3)
    centre, half = _MP3D_TO_HABITAT @ ((lo + hi) / 2.0), np.abs(_MP3D_TO_HABITAT @ (hi - lo)) / 2.0
    return mn.Range3D(centre - half, centre + half)


def _mp3d_obb(tokens: list[str], at: int) -> OBB:
    """``px py pz a0x a0y a0z a1x a1y a1z r0 r1 r2``: centre, two axes (the third their cross product), radii."""
    a0, a1 = _mp3d_point(tokens, at + 3), _mp3d_point(tokens, at + 6)
    rotation = np.column_stack([a0, a1, np.cross(a0, a1)])
    return OBB(_mp3d_point(tokens, at), 2.0 * _floats(tokens, at + 9), mn.Quaternion.from_matrix(rotation))


def mp3d_scene(asset, house: Path, ply: Path, frame) -> tuple[SemanticScene, np.ndarray]:
    from navbench.scene.datasets import mp3d
    from navbench.scene.errors import SceneError

    if not house.is_file():
        raise SceneError(f"{ply}: its annotation file is missing: {house}")
    lines = mp3d.house_lines(house, version="1.1")
    scene = SemanticScene()
    for n, line in enumerate(lines[1:], start=2):
        t = line.split()
        if not t:
            continue
        try:
            if t[0] == "H":
                scene.aabb = _mp3d_box(t, 18)
            elif t[0] == "L":
                level = SemanticLevel(str(int(t[1])), _mp3d_box(t, 7))
                level.position = mn.Vector3(_mp3d_point(t, 4))
                scene.levels.append(level)
            elif t[0] == "R":
                parent = int(t[2])
                region = SemanticRegion(int(t[1]), Mp3dRegionCategory(t[5]), _mp3d_box(t, 9),
                                        scene.levels[parent] if parent >= 0 else None)
                region.position = mn.Vector3(_mp3d_point(t, 6))
                if region.level is not None:
                    region.level.regions.append(region)
                scene.regions.append(region)
            elif t[0] == "C":
                scene.categories.append(Mp3dObjectCategory(int(t[1]), int(t[2]), t[3].replace("#", " "), int(t[4]),
                                                           t[5]))
            elif t[0] == "O":
                parent, cat = int(t[2]), int(t[3])
                obb = _mp3d_obb(t, 4)
                obj = SemanticObject(int(t[1]), scene.categories[cat] if cat >= 0 else Mp3dObjectCategory(),
                                     obb.to_aabb(), scene.regions[parent] if parent >= 0 else None, obb,
                                     id_from_region=True)
                if obj.region is not None:
                    obj.region.objects.append(obj)
                scene.objects.append(obj)
        except (IndexError, ValueError):
            raise SceneError(f"{house}:{n}: malformed {t[0]} record: {line.strip()!r}") from None
    labels = mp3d.face_labels(ply, asset.mesh, frame) if ply.is_file() else np.full(len(asset.mesh.faces), -1)
    listed = np.array([o.semantic_id for o in scene.objects], np.int64)
    return scene, np.where(np.isin(labels, listed) & (labels > 0), labels, -1).astype(np.int32)


def render_asset(asset, face_ids: np.ndarray):
    """``asset`` with the SEMANTIC sensor's per-face ids (the same object when they are its own)."""
    if face_ids is asset.face_ids or np.array_equal(face_ids, asset.face_ids):
        return asset
    return dataclasses.replace(asset, face_ids=face_ids)

