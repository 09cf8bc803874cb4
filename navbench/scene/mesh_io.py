"""Reading a mesh file (GLB/glTF, OBJ, PLY) into one merged triangle mesh with per-face object ids.

Inside a GLB, geometry belonging to object ``k`` sits under a node named ``obj_{k}``; every other
node is structure and gets :data:`~navbench.scene.annotations.STRUCTURE_ID`. Base-colour textures
are kept beside the vertex colours (:mod:`navbench.scene.textures` decodes them).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import trimesh

from navbench.scene.annotations import STRUCTURE_ID
from navbench.scene.errors import SceneError

OBJECT_NODE = re.compile(r"^obj_(\d+)$")


def read_mesh(path: Path) -> tuple[trimesh.Trimesh, np.ndarray, np.ndarray | None, np.ndarray | None,
                                   list[np.ndarray]]:
    """Merged mesh (vertex colours), per-face ids from ``obj_{k}`` node names, and the texture table.

    Returns ``(mesh, face_ids, uv, face_texture, textures)``; the last three are None, None, [] for a
    scene without textures, which keeps the vertex-colour path exactly as it was.
    """
    from navbench.scene import textures as tx

    suffix = path.suffix.lower()
    source: object = str(path)
    kwargs: dict = {}
    if suffix == ".glb":
        prepared = tx.prepare_glb(path)
        if prepared is not None:
            source, kwargs = trimesh.util.wrap_as_stream(prepared), {"file_type": "glb"}
    elif suffix == ".gltf":
        tx.check_gltf_images(path)
    elif suffix == ".obj":
        tx.check_obj_textures(path)
    try:
        loaded = trimesh.load(source, force="scene", process=False, **kwargs)
        return _merge_parts(path, loaded)
    except SceneError:
        raise
    except Exception as exc:  # trimesh raises many types for a bad file
        raise SceneError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from None
    finally:
        tx.forget_decoded(path)


def _merge_parts(path: Path, loaded: trimesh.Scene):
    from navbench.scene import textures as tx

    parts: list[trimesh.Trimesh] = []
    ids: list[np.ndarray] = []
    part_uv: list[np.ndarray | None] = []
    part_tex: list[int] = []
    images: list[np.ndarray] = []
    image_index: dict[int, int] = {}
    for node in loaded.graph.nodes_geometry:
        transform, geom_name = loaded.graph[node]
        geom = loaded.geometry[geom_name]
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        part = geom
        if not np.allclose(transform, np.eye(4)):
            part = geom.copy()
            part.apply_transform(transform)
        tex = -1
        uv = None
        colours = None
        if part.visual.kind == "texture":
            material = part.visual.material
            image = getattr(material, "baseColorTexture", None) or getattr(material, "image", None)
            if image is not None and part.visual.uv is not None and len(part.visual.uv) == len(part.vertices):
                key = id(image)
                if key not in image_index:
                    image_index[key] = len(images)
                    images.append(tx.texture_image(part.visual))
                tex = image_index[key]
                uv = np.asarray(part.visual.uv, np.float32)
                # Vertex colours (for consumers of the merged mesh's colours): the texel under each vertex.
                colours = tx.sample(images[tex], uv)
        if colours is None:
            colours = _vertex_colours(part)
        part = trimesh.Trimesh(part.vertices, part.faces, vertex_colors=colours, process=False)
        m = OBJECT_NODE.match(str(node)) or OBJECT_NODE.match(str(geom_name))
        parts.append(part)
        ids.append(np.full(len(part.faces), int(m.group(1)) if m else STRUCTURE_ID, np.int32))
        part_uv.append(uv)
        part_tex.append(tex)
    if not parts:
        raise SceneError(f"{path}: mesh has no triangles")
    mesh = trimesh.util.concatenate(parts) if len(parts) > 1 else parts[0]
    face_ids = np.concatenate(ids)
    if not np.isfinite(mesh.vertices).all():
        raise SceneError(f"{path}: mesh has non-finite vertex coordinates")
    if not images:
        return mesh, face_ids, None, None, []
    uv_all = np.concatenate([u if u is not None else np.zeros((len(p.vertices), 2), np.float32)
                             for u, p in zip(part_uv, parts)])
    face_texture = np.concatenate([np.full(len(p.faces), t, np.int32) for t, p in zip(part_tex, parts)])
    return mesh, face_ids, uv_all, face_texture, images


def _vertex_colours(mesh: trimesh.Trimesh) -> np.ndarray:
    """RGBA uint8 per vertex, whatever the file stored (vertex colours, a material, or nothing)."""
    visual = mesh.visual
    try:
        if visual.kind in ("vertex", "face"):
            # trimesh interpolates face colours onto vertices; our scenes never share a vertex
            # between differently coloured faces, so nothing is blurred.
            return np.asarray(visual.vertex_colors, np.uint8)
        if visual.kind == "texture":
            return np.asarray(visual.to_color().vertex_colors, np.uint8)
    except Exception:
        pass
    return np.tile(np.array([180, 180, 180, 255], np.uint8), (len(mesh.vertices), 1))
