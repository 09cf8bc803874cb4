"""The scene as pyrender meshes: static geometry merged into spatial chunks, each a colour and an id mesh.

Per-node overhead (Python and GL calls per drawn node) dominates at agent resolutions, so static
geometry is merged into spatial chunks of at most ``max_faces`` triangles, made by recursive median
splits of the xz plane (:func:`spatial_chunks`), which :mod:`navbench.render.culling` can then skip.
Geometry is indexed (shared vertices, triangles in file order), which draws faster than one vertex
per corner. Vertex colours are drawn unlit (``RenderFlags.FLAT``); a textured scan's faces carry
base-colour textures instead (trilinear, unlit, as Habitat renders scans). Each chunk also has an id
mesh whose vertex colours encode ``id + 1`` (:func:`navbench.render.frame.encode_ids`).
"""

from __future__ import annotations

# isort: off
import navbench.render.gl_platform  # noqa: F401  (first: binds the platform before OpenGL is imported)
# isort: on

import numpy as np
import pyrender
import trimesh
from OpenGL.GL import GL_LINEAR, GL_LINEAR_MIPMAP_LINEAR, GL_REPEAT
from pyrender.constants import GLTF

from navbench.render.frame import MAX_INSTANCE_ID, encode_ids
from navbench.scene.asset import SceneAsset


def two_sided_faces(asset: SceneAsset) -> np.ndarray:
    """(F,) bool: faces drawn with both windings. Textured faces are single-sided, as Habitat draws
    scans with back-face culling; vertex-coloured faces follow :func:`open_surface_faces`."""
    mesh = asset.mesh
    if asset.face_texture is None:
        return open_surface_faces(mesh)
    out = np.zeros(len(mesh.faces), dtype=bool)
    plain = np.flatnonzero(asset.face_texture < 0)
    if len(plain):
        out[plain] = open_surface_faces(trimesh.Trimesh(mesh.vertices, mesh.faces[plain], process=False))
    return out


def spatial_chunks(points_xz: np.ndarray, max_faces: int) -> list[np.ndarray]:
    """Group face indices (by their xz centroids) into compact chunks of at most ``max_faces``.

    Recursive median split along the longer xz extent (a k-d tree's leaves): chunks stay spatially
    tight, so frustum culling can drop them, and balanced, so none is needlessly small.
    """
    chunks: list[np.ndarray] = []
    stack = [np.arange(len(points_xz))]
    while stack:
        idx = stack.pop()
        if len(idx) <= max_faces:
            # Back in file order: neighbouring triangles share vertices, which llvmpipe's vertex
            # cache exploits; a spatially sorted order draws markedly slower.
            chunks.append(np.sort(idx))
            continue
        pts = points_xz[idx]
        axis = int(np.argmax(np.ptp(pts, axis=0)))
        order = np.argsort(pts[:, axis], kind="stable")
        half = len(idx) // 2
        stack += [idx[order[half:]], idx[order[:half]]]
    return chunks


def open_surface_faces(mesh: trimesh.Trimesh) -> np.ndarray:
    """(F,) bool: faces of connected components that are not closed, consistently wound solids.

    Closed, consistently wound solids are seen only from the side their faces point to (outside,
    for a solid), so back-face culling draws them correctly and saves their hidden half. Open
    surfaces (single quads as walls, ground planes, broken meshes) may be seen from either side and
    are drawn with both windings. Vertices are merged by position first, because exporters often
    split them along colour seams.
    """
    welded = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    welded.merge_vertices()
    # Closed and consistently wound <=> every undirected edge is used as often in one direction as
    # in the other (2 for a manifold edge; 4 where two closed solids touch along an edge).
    _, edge_group = np.unique(welded.edges_sorted, axis=0, return_inverse=True)
    edge_group = edge_group.reshape(-1)
    forward = welded.edges[:, 0] < welded.edges[:, 1]
    balance = np.bincount(edge_group, weights=np.where(forward, 1.0, -1.0))
    good_edge = balance[edge_group] == 0
    bad_face = np.zeros(len(welded.faces), dtype=bool)
    np.logical_or.at(bad_face, welded.edges_face, ~good_edge)
    labels = trimesh.graph.connected_component_labels(welded.face_adjacency, node_count=len(welded.faces))
    return np.isin(labels, np.unique(labels[bad_face]))


def texture_material(image: np.ndarray) -> pyrender.MetallicRoughnessMaterial:
    """Unlit base-colour material over ``image`` (RGBA, row 0 at the top): trilinear, repeating, as
    glTF's default sampler; FLAT rendering outputs the filtered texel as it is."""
    sampler = pyrender.Sampler(magFilter=GL_LINEAR, minFilter=GL_LINEAR_MIPMAP_LINEAR, wrapS=GL_REPEAT, wrapT=GL_REPEAT)
    texture = pyrender.Texture(source=np.ascontiguousarray(image), source_channels="RGBA", sampler=sampler)
    return pyrender.MetallicRoughnessMaterial(baseColorFactor=np.ones(4), baseColorTexture=texture, doubleSided=False)


def chunk_meshes(
    asset: SceneAsset, faces: np.ndarray, two_sided: np.ndarray,
    materials: list[pyrender.MetallicRoughnessMaterial] | None = None,
) -> tuple[pyrender.Mesh, pyrender.Mesh, np.ndarray, np.ndarray]:
    """Colour and id meshes of one chunk, plus its AABB.

    Everything is drawn with back-face culling (pyrender's DEPTH_ONLY pass always culls, so the
    FLAT passes must too to see the same geometry); faces flagged in ``two_sided`` are stored once
    per winding so they show from both sides. Textured faces of a textured scene are drawn as one
    primitive per texture (positions and UVs); the rest, and every untextured scene, with vertex
    colours. The id mesh is one primitive whatever the colour mesh's make-up.
    """
    mesh = asset.mesh
    tri = mesh.faces[faces]
    corner_ids = np.repeat(asset.face_ids[faces].astype(np.int64), 3)
    # Shared vertices, except that a vertex used by faces of two objects is split so each copy
    # carries one id colour: key = (vertex index, id + 1), packed into one int64.
    keys = tri.reshape(-1).astype(np.int64) * (MAX_INSTANCE_ID + 2) + (corner_ids + 1)
    uniq, inverse = np.unique(keys, return_inverse=True)
    vertex = uniq // (MAX_INSTANCE_ID + 2)
    positions = mesh.vertices[vertex].astype(np.float32)
    colours = np.asarray(mesh.visual.vertex_colors, dtype=np.uint8)[vertex].copy()
    colours[:, 3] = 255  # opaque: pyrender would otherwise blend and depth-sort
    id_colours = encode_ids(uniq % (MAX_INSTANCE_ID + 2) - 1)
    front = inverse.reshape(-1, 3).astype(np.uint32)
    indices = np.concatenate([front, front[two_sided[faces], ::-1]])
    material = pyrender.MetallicRoughnessMaterial(baseColorFactor=np.ones(4), doubleSided=False)

    def build(vertex_colours: np.ndarray) -> pyrender.Mesh:
        prim = pyrender.Primitive(
            positions=positions,
            indices=indices,
            color_0=vertex_colours,
            material=material,
            mode=GLTF.TRIANGLES,
        )
        return pyrender.Mesh(primitives=[prim])

    if not materials or asset.face_texture is None:
        return build(colours), build(id_colours), positions.min(axis=0), positions.max(axis=0)
    prims = []
    chunk_tex = asset.face_texture[faces]
    for t in np.unique(chunk_tex):
        sel = faces[chunk_tex == t]
        if t < 0:
            prims += build(colours).primitives if (chunk_tex < 0).all() else _colour_primitive(asset, sel, two_sided)
            continue
        tri_t = mesh.faces[sel]
        used, local = np.unique(tri_t.reshape(-1), return_inverse=True)
        front_t = local.reshape(-1, 3).astype(np.uint32)
        prims.append(pyrender.Primitive(
            positions=mesh.vertices[used].astype(np.float32),
            texcoord_0=asset.uv[used].astype(np.float32),
            indices=np.concatenate([front_t, front_t[two_sided[sel], ::-1]]),
            material=materials[int(t)],
            mode=GLTF.TRIANGLES,
        ))
    return pyrender.Mesh(primitives=prims), build(id_colours), positions.min(axis=0), positions.max(axis=0)


def _colour_primitive(asset: SceneAsset, faces: np.ndarray, two_sided: np.ndarray) -> list[pyrender.Primitive]:
    """The vertex-coloured faces of a chunk that also holds textured ones, as one primitive."""
    mesh = asset.mesh
    used, local = np.unique(mesh.faces[faces].reshape(-1), return_inverse=True)
    front = local.reshape(-1, 3).astype(np.uint32)
    colours = np.asarray(mesh.visual.vertex_colors, dtype=np.uint8)[used].copy()
    colours[:, 3] = 255
    return [pyrender.Primitive(
        positions=mesh.vertices[used].astype(np.float32), color_0=colours,
        indices=np.concatenate([front, front[two_sided[faces], ::-1]]),
        material=pyrender.MetallicRoughnessMaterial(baseColorFactor=np.ones(4), doubleSided=False),
        mode=GLTF.TRIANGLES,
    )]
