"""``habitat_sim.scene``: scene-graph nodes (a translation and a rotation under a parent) and the semantic scene.

A :class:`SceneNode` is Magnum's TranslationRotationScalingTransformation3D without scaling: its local
transformation is ``T(translation) R(rotation)``, its absolute one the parent's times that. Agents and sensors
are nodes; the renderer draws each sensor at its node's absolute pose.
"""

from __future__ import annotations

import enum

import numpy as np

from navbench.habitat_sim import magnum as mn


class SceneNodeType(enum.Enum):
    EMPTY = 0
    SENSOR = 1
    AGENT = 2
    CAMERA = 3
    OBJECT = 4


class SceneNode:
    def __init__(self, parent: SceneNode | None = None) -> None:
        self.parent = parent
        self.translation = mn.Vector3()
        self.rotation = mn.Quaternion()
        self.type = SceneNodeType.EMPTY

    @property
    def object(self) -> SceneNode:
        return self

    @property
    def node(self) -> SceneNode:
        return self

    # Magnum's setters accept any 3-vector / quaternion
    def __setattr__(self, name, value) -> None:
        if name == "translation":
            value = mn.Vector3(value)
        elif name == "rotation" and not isinstance(value, mn.Quaternion):
            raise TypeError(f"SceneNode.rotation must be a magnum Quaternion, got {type(value).__name__}")
        object.__setattr__(self, name, value)

    def reset_transformation(self) -> None:
        self.translation = mn.Vector3()
        self.rotation = mn.Quaternion()

    def translate(self, v) -> SceneNode:
        """Translate in the parent's frame."""
        self.translation = self.translation + mn.Vector3(v)
        return self

    def translate_local(self, v) -> SceneNode:
        """Translate in the node's own (rotated) frame."""
        self.translation = self.translation + self.rotation.transform_vector(mn.Vector3(v))
        return self

    def rotate(self, angle, normalized_axis) -> SceneNode:
        """Rotate in the parent's frame (applied after the current rotation)."""
        self.rotation = mn.Quaternion.rotation(angle, normalized_axis) * self.rotation
        return self

    def rotate_local(self, angle, normalized_axis) -> SceneNode:
        """Rotate about the node's own axis (applied before the current rotation)."""
        self.rotation = self.rotation * mn.Quaternion.rotation(angle, normalized_axis)
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
        return mn.Matrix4.from_(np.asarray(self.rotation.to_matrix()), np.asarray(self.translation))

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
            return mn.Vector3(self.translation)
        return self.parent.absolute_translation + self.parent.absolute_rotation().transform_vector(self.translation)

    def absolute_rotation(self) -> mn.Quaternion:
        return self.rotation if self.parent is None else self.parent.absolute_rotation() * self.rotation


class SemanticCategory:
    def __init__(self, index: int, name: str) -> None:
        self._index, self._name = index, name

    def index(self, mapping: str = "") -> int:
        return self._index

    def name(self, mapping: str = "") -> str:
        return self._name


class SemanticLevel:
    def __init__(self, id: str = "0") -> None:  # noqa: A002  (habitat-sim's name)
        self.id = id
        self.aabb = mn.Range3D()
        self.objects: list[SemanticObject] = []
        self.regions: list[SemanticRegion] = []


class SemanticRegion:
    def __init__(self, id: str, category: SemanticCategory, aabb: mn.Range3D) -> None:  # noqa: A002
        self.id = id
        self.category = category
        self.aabb = aabb
        self.level: SemanticLevel | None = None
        self.objects: list[SemanticObject] = []


class SemanticObject:
    """An annotated object: ``id`` ``"{category}_{semantic_id}"``, ``semantic_id`` (the SEMANTIC sensor's value),
    ``category``, ``aabb`` (an ``mn.Range3D``), ``region``."""

    def __init__(self, semantic_id: int, category: SemanticCategory, aabb: mn.Range3D,
                 region: SemanticRegion | None = None) -> None:
        self.semantic_id = semantic_id
        self.id = f"{category.name()}_{semantic_id}"
        self.category = category
        self.aabb = aabb
        self.obb = None
        self.region = region


class SemanticScene:
    def __init__(self) -> None:
        self.objects: list[SemanticObject | None] = []
        self.categories: list[SemanticCategory] = []
        self.levels: list[SemanticLevel] = []
        self.regions: list[SemanticRegion] = []
        self.aabb = mn.Range3D()
        self.semantic_index_map: dict[int, int] = {}
