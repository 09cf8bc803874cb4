"""``habitat_sim.scene``: scene-graph nodes (a translation and a rotation under a parent) and the semantic scene's
types (objects, categories, levels, regions).

A :class:`SceneNode` is Magnum's TranslationRotationScalingTransformation3D without scaling: its local
transformation is ``T(translation) R(rotation)``, its absolute one the parent's times that. Agents and sensors
are nodes; the renderer draws each sensor at its node's absolute pose.
"""

from __future__ import annotations

import enum

import numpy as np

from navbench.habitat_sim import magnum as mn
from navbench.habitat_sim.geo import OBB


class SceneNodeType(enum.Enum):
    EMPTY = 0
    SENSOR = 1
    AGENT = 2
    CAMERA = 3
    OBJECT = 4


class SceneNode:
    def __init__(self, parent: SceneNode | None = None) -> None:
        self.parent = parent
        self._translation = mn.Vector3()
        self._rotation = mn.Quaternion()
        self.type = SceneNodeType.EMPTY

    @property
    def object(self) -> SceneNode:
        return self

    @property
    def node(self) -> SceneNode:
        return self

    # Magnum's getters return values (a copy: changing it leaves the node alone); its setters take any 3-vector
    @property
    def translation(self) -> mn.Vector3:
        return mn.Vector3(self._translation)

    @translation.setter
    def translation(self, value) -> None:
        self._translation = mn.Vector3(value)

    @property
    def rotation(self) -> mn.Quaternion:
        return mn.Quaternion._make(*self._rotation._floats())

    @rotation.setter
    def rotation(self, value) -> None:
        if not isinstance(value, mn.Quaternion):
            raise TypeError(f"SceneNode.rotation must be a magnum Quaternion, got {type(value).__name__}")
        self._rotation = mn.Quaternion._make(*value._floats())

    def reset_transformation(self) -> None:
        self._translation = mn.Vector3()
        self._rotation = mn.Quaternion()

    def translate(self, v) -> SceneNode:
        """Translate in the parent's frame."""
        self._translation = self._translation + mn.Vector3(v)
        return self

    def translate_local(self, v) -> SceneNode:
        """Translate in the node's own (rotated) frame."""
        self._translation = self._translation + self._rotation.transform_vector(mn.Vector3(v))
        return self

    def rotate(self, angle, normalized_axis) -> SceneNode:
        """Rotate in the parent's frame (applied after the current rotation)."""
        self._rotation = mn.Quaternion.rotation(angle, normalized_axis) * self._rotation
        return self

    def rotate_local(self, angle, normalized_axis) -> SceneNode:
        """Rotate about the node's own axis (applied before the current rotation)."""
        self._rotation = self._rotation * mn.Quaternion.rotation(angle, normalized_axis)
        return self

    def rotate_x(self, angle) -> SceneNode:
        return self.rotate(angle, mn.Vector3.x_axis())

    def rotate_y(self, angle) -> SceneNode:
        return self.rotate(angle, mn.Vector3.y_axis())

    def rotate_z(self, angle) -> SceneNode:
        return self.rotate(angle, mn.Vector3.z_axis())

    def rotate_x_local(self, angle) -> SceneNode:
        return self.rotate_local(angle, mn.Vector3.x_axis())

    def rotate_y_local(self, angle) -> SceneNode:
        return self.rotate_local(angle, mn.Vector3.y_axis())

    @property
    def transformation(self) -> mn.Matrix4:
        return mn.Matrix4.from_(np.asarray(self._rotation.to_matrix()), np.asarray(self._translation))

    @transformation.setter
    def transformation(self, m: mn.Matrix4) -> None:
        a = np.asarray(m, dtype=np.float64)
        self.rotation = mn.Quaternion.from_matrix(a[:3, :3])
        self.translation = mn.Vector3(a[:3, 3])

    def absolute_transformation(self) -> mn.Matrix4:
        own = self.transformation
        return own if self.parent is None else self.parent.absolute_transformation() @ own

    @property
    def absolute_translation(self) -> mn.Vector3:
        if self.parent is None:
            return mn.Vector3(self._translation)
        return self.parent.absolute_translation + self.parent.absolute_rotation().transform_vector(self._translation)

    def absolute_rotation(self) -> mn.Quaternion:
        if self.parent is None:
            return self.rotation
        return self.parent.absolute_rotation() * self._rotation


class SemanticCategory:
    """An object or region category: ``index(mapping)`` and ``name(mapping)``. habitat-sim's HM3D categories and
    navbench's own answer ``""`` and ``"category"``; other mappings give ``"UNKNOWN"`` (index unchanged)."""

    def __init__(self, index: int, name: str) -> None:
        self._index, self._name = index, name

    def index(self, mapping: str = "") -> int:
        return self._index

    def name(self, mapping: str = "") -> str:
        return self._name if mapping in ("", "category") else "UNKNOWN"

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._index}, {self._name!r})"


class Mp3dObjectCategory(SemanticCategory):
    """A ``.house`` ``C`` record: ``index()`` / ``name()`` are its mpcat40 index and name (mapping ``""`` or
    ``"mpcat40"``), ``index("raw")`` / ``name("raw")`` its category mapping's; -1 and ``""`` for another
    mapping and for an object without a category (habitat-sim's ``Mp3dSemanticScene.cpp``)."""

    def __init__(self, index: int = -1, raw_index: int = -1, raw_name: str = "", mpcat40_index: int = -1,
                 mpcat40_name: str = "") -> None:
        super().__init__(mpcat40_index, mpcat40_name)
        self.category_index = index
        self._raw_index, self._raw_name = raw_index, raw_name

    def index(self, mapping: str = "") -> int:
        return self._index if mapping in ("", "mpcat40") else self._raw_index if mapping == "raw" else -1

    def name(self, mapping: str = "") -> str:
        return self._name if mapping in ("", "mpcat40") else self._raw_name if mapping == "raw" else ""


# habitat-sim's kRegionCategoryMap (Mp3dSemanticScene.cpp): a region's one-letter label -> its name; the index is
# the label's rank in this table ordered by character, as std::map orders it
MP3D_REGION_NAMES = {
    "a": "bathroom", "b": "bedroom", "c": "closet", "d": "dining room", "e": "entryway/foyer/lobby",
    "f": "familyroom/lounge", "g": "garage", "h": "hallway", "i": "library", "j": "laundryroom/mudroom",
    "k": "kitchen", "l": "living room", "m": "meetingroom/conferenceroom", "n": "lounge", "o": "office",
    "p": "porch/terrace/deck", "r": "rec/game", "s": "stairs", "t": "toilet", "u": "utilityroom/toolroom",
    "v": "tv", "w": "workout/gym/exercise", "x": "outdoor", "y": "balcony", "z": "other room", "B": "bar",
    "C": "classroom", "D": "dining booth", "S": "spa/sauna", "Z": "junk"}
_MP3D_REGION_ORDER = sorted(MP3D_REGION_NAMES)


class Mp3dRegionCategory(SemanticCategory):
    """A region's label code: ``index()`` its rank in habitat-sim's table, ``name()`` its name; a code outside
    the table (``-``, unlabeled) ranks after the table, named ``"unlabeled"`` (habitat-sim raises there)."""

    def __init__(self, label_code: str) -> None:
        code = label_code[:1]
        rank = _MP3D_REGION_ORDER.index(code) if code in MP3D_REGION_NAMES else len(_MP3D_REGION_ORDER)
        super().__init__(rank, MP3D_REGION_NAMES.get(code, "unlabeled"))
        self.label_code = code

    def name(self, mapping: str = "") -> str:
        return self._name


class SemanticLevel:
    """A storey: ``id`` (its index as a string), ``aabb``, its ``regions`` and ``objects``."""

    def __init__(self, id: str = "0", aabb: mn.Range3D | None = None) -> None:  # noqa: A002  (habitat-sim's name)
        self.id = id
        self.aabb = mn.Range3D() if aabb is None else aabb
        self.position = mn.Vector3()
        self.objects: list[SemanticObject] = []
        self.regions: list[SemanticRegion] = []


class SemanticRegion:
    """A room: ``id`` (its name if it has one, else ``"{level id}_{index}"``, or ``"_{index}"`` without a level, as
    habitat-sim's ``SemanticRegion::id``), ``category`` (None where the dataset gives none), ``aabb``, ``level``,
    ``objects``."""

    def __init__(self, index: int, category: SemanticCategory | None = None, aabb: mn.Range3D | None = None,
                 level: SemanticLevel | None = None, name: str = "") -> None:
        self.index = index
        self.name = name
        self.category = category
        self.aabb = mn.Range3D() if aabb is None else aabb
        self.position = mn.Vector3()
        self.level = level
        self.objects: list[SemanticObject] = []

    @property
    def id(self) -> str:
        if self.name:
            return self.name
        return f"{self.level.id}_{self.index}" if self.level is not None else f"_{self.index}"


class SemanticObject:
    """An annotated object: ``semantic_id`` (the SEMANTIC sensor's value), ``id``, ``category``, ``aabb`` (an
    ``mn.Range3D``), ``obb`` (a ``geo.OBB``), ``region``.

    ``id`` is ``"{category name}_{semantic_id}"`` (habitat-sim's HM3D objects, and navbench's own), or, with
    ``id_from_region``, ``"{region id}_{semantic_id}"`` (habitat-sim's ``SemanticObject::id``, MP3D's objects)."""

    def __init__(self, semantic_id: int, category: SemanticCategory, aabb: mn.Range3D,
                 region: SemanticRegion | None = None, obb: OBB | None = None, id_from_region: bool = False) -> None:
        self.semantic_id = semantic_id
        self.category = category
        self.obb = OBB(aabb) if obb is None else obb
        self.aabb = aabb
        self.region = region
        self._id_from_region = id_from_region
        self._name = f"{category.name()}_{semantic_id}"

    @property
    def id(self) -> str:
        if not self._id_from_region:
            return self._name
        return f"{self.region.id}_{self.semantic_id}" if self.region is not None else f"_{self.semantic_id}"

    def __repr__(self) -> str:
        return f"SemanticObject({self.id!r}, semantic_id={self.semantic_id})"


class SemanticScene:
    """Objects, categories, levels and regions of the loaded scene (see :mod:`navbench.habitat_sim._semantic` for
    how each dataset's files fill them)."""

    def __init__(self) -> None:
        self.objects: list[SemanticObject] = []
        self.categories: list[SemanticCategory] = []
        self.levels: list[SemanticLevel] = []
        self.regions: list[SemanticRegion] = []
        self.aabb = mn.Range3D()
        self.semantic_index_map: dict[int, int] = {}
