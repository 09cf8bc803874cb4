"""Fixture writers for the scan tests: textured quads in GLB / OBJ+MTL / PLY and a Basis GLB, written
byte by byte here (not with navbench's own writers), so the loader is checked against the formats."""

from __future__ import annotations

import io
import json
import struct
from pathlib import Path

import numpy as np
from PIL import Image

CHECK_A = (200, 30, 40)
CHECK_B = (20, 180, 220)
QUAD_Z = -2.0  # the quad spans x, y in [-1, 1] at z = QUAD_Z, facing +z (towards a camera at the origin)


def checkerboard(size: int = 256, squares: int = 8) -> np.ndarray:
    """(size, size, 3) uint8; square (row 0, col 0) at the image's top-left is CHECK_A."""
    k = size // squares
    rows, cols = np.mgrid[0:size, 0:size] // k
    return np.where(((rows + cols) % 2 == 0)[..., None], CHECK_A, CHECK_B).astype(np.uint8)


def expected_checker(x: np.ndarray, y: np.ndarray, size: int = 256, squares: int = 8):
    """Colour at quad point (x, y) and the distance in texels to the nearest square edge."""
    u, v = (x + 1) / 2, (y + 1) / 2  # glTF: v = 0 at the image's top row
    col, row = u * size, (1 - v) * size
    k = size / squares
    ci, ri = np.floor(col / k), np.floor(row / k)
    edge = np.minimum(np.minimum(col - ci * k, (ci + 1) * k - col), np.minimum(row - ri * k, (ri + 1) * k - row))
    colour = np.where((((ri + ci) % 2) == 0)[..., None], CHECK_A, CHECK_B)
    return colour, edge


def _png(img: np.ndarray) -> bytes:
    out = io.BytesIO()
    Image.fromarray(img).save(out, format="PNG")
    return out.getvalue()


QUAD_POS = np.array([[-1, -1, QUAD_Z], [1, -1, QUAD_Z], [1, 1, QUAD_Z], [-1, 1, QUAD_Z]], np.float32)
QUAD_UV_GLTF = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)  # glTF: v down from the top row
QUAD_IDX = np.array([0, 1, 2, 0, 2, 3], np.uint32)


def _crc16(data: bytes) -> int:
    """basis_universal's CRC-16 (``basist::crc16`` in ``transcoder/basisu_transcoder.cpp``, initial value 0)."""
    crc = 0xFFFF
    for b in data:
        q = (b ^ (crc >> 8)) & 0xFFFF
        k = ((q >> 4) ^ q) & 0xFFFF
        crc = ((crc << 8) ^ k ^ (k << 5) ^ (k << 12)) & 0xFFFF
    return ~crc & 0xFFFF


def ktx2_to_basis(ktx2: bytes, y_flipped: bool = False) -> bytes:
    """A ``.basis`` file holding the top level of a UASTC KTX2 file without supercompression.

    Layout from basis_universal ``transcoder/basisu_file_headers.h``: the 77-byte packed
    ``basis_file_header`` (signature ``sB``, version 0x13, header CRC-16 over the bytes after that
    field, data size and CRC-16 over everything after the header, 1 slice, 1 image, tex format 1 =
    UASTC 4x4, flags 2 = ``cBASISHeaderFlagYFlipped``, tex type 0 = 2D, slice descriptions at byte 77),
    then one 23-byte ``basis_slice_desc`` and the slice's UASTC blocks. The KTX2 header (Khronos KTX 2.0
    spec, section 3) gives the size at bytes 20-27, the supercompression scheme at 44 and level 0's
    byte offset and length at 80-95.
    """
    w, h = struct.unpack_from("<II", ktx2, 20)
    (scheme,) = struct.unpack_from("<I", ktx2, 44)
    assert scheme == 0, "supercompressed KTX2 has no plain UASTC blocks to copy"
    offset, length = struct.unpack_from("<QQ", ktx2, 80)
    blocks = ktx2[offset:offset + length]
    header_size, slice_size = 77, 23
    def u24(v: int) -> bytes:
        return v.to_bytes(3, "little")

    desc = (u24(0) + bytes([0, 0]) + struct.pack("<HHHHII", w, h, -(-w // 4), -(-h // 4),
                                                 header_size + slice_size, len(blocks))
            + struct.pack("<H", _crc16(blocks)))
    data = desc + blocks
    rest = (struct.pack("<IH", len(data), _crc16(data)) + u24(1) + u24(1) + bytes([1])
            + struct.pack("<H", 2 if y_flipped else 0) + bytes([0]) + u24(0) + struct.pack("<III", 0, 0, 0)
            + struct.pack("<HI", 0, 0) + u24(0) + struct.pack("<HI", 0, 0) + u24(0)
            + struct.pack("<IIIII", 0, 0, header_size, 0, 0))
    head = struct.pack("<HHHH", 0x4273, 0x13, header_size, _crc16(rest)) + rest
    assert len(head) == header_size and len(desc) == slice_size
    return head + data


def ktx2_with_orientation(ktx2: bytes, orientation: str) -> bytes:
    """The KTX2 file with its key/value data replaced by ``KTXorientation`` = ``orientation`` (KTX 2.0 spec:
    index at bytes 48-79, key/value data = u32 length + ``key NUL value NUL`` padded to 4, level index at
    80 with absolute offsets; level data aligned to 16 bytes for UASTC)."""
    dfd_off, dfd_len, kvd_off, kvd_len = struct.unpack_from("<IIII", ktx2, 48)
    (levels,) = struct.unpack_from("<I", ktx2, 40)
    entry = b"KTXorientation\0" + orientation.encode() + b"\0"
    kvd = struct.pack("<I", len(entry)) + entry + b"\0" * (-len(entry) % 4)
    head = bytearray(ktx2[:80 + 24 * levels])
    body = bytearray(ktx2[dfd_off:dfd_off + dfd_len])
    new_kvd_off = len(head) + len(body)
    body += kvd
    body += b"\0" * (-(len(head) + len(body)) % 16)
    struct.pack_into("<II", head, 56, new_kvd_off, len(kvd))
    struct.pack_into("<QQ", head, 64, 0, 0)
    data = bytearray()
    for i in range(levels):
        off, length, raw = struct.unpack_from("<QQQ", ktx2, 80 + 24 * i)
        new_off = len(head) + len(body) + len(data)
        data += ktx2[off:off + length] + b"\0" * (-length % 16)
        struct.pack_into("<QQQ", head, 80 + 24 * i, new_off, length, raw)
    return bytes(head + body + data)


def write_glb(path: Path, image_bytes: bytes, mime: str, basisu: bool = False, extension: str | None = None,
              declare: bool = True) -> Path:
    """A one-quad GLB whose material's baseColorTexture is the given image.

    ``basisu`` (or ``extension="KHR_texture_basisu"``) references the image through the Khronos
    extension; ``extension="GOOGLE_texture_basis"`` writes the texture as magnum-plugins'
    ``GltfImporter/Test/gltf2basis.py`` does (the ``source`` moved into the extension, the image's
    ``mimeType`` ``image/x-basis``) and then as ``gltf2glb.py --bundle-images`` packs it (the image in
    a bufferView with a ``name``; no ``extensionsUsed`` is declared by that tool, so ``declare=False``
    reproduces it exactly)."""
    if basisu:
        extension = "KHR_texture_basisu"
    chunks = [QUAD_POS.tobytes(), QUAD_UV_GLTF.tobytes(), QUAD_IDX.tobytes(), image_bytes]
    views, blob = [], b""
    for c in chunks:
        blob += b"\0" * (-len(blob) % 4)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(c)})
        blob += c
    blob += b"\0" * (-len(blob) % 4)
    texture = {"extensions": {extension: {"source": 0}}} if extension else {"source": 0}
    gltf = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "name": "quad"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}],
        "textures": [texture], "images": [{"bufferView": 3, "mimeType": mime, "name": "checker"}],
        "buffers": [{"byteLength": len(blob)}], "bufferViews": views[:3] + [views[3]],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": QUAD_POS.min(0).tolist(), "max": QUAD_POS.max(0).tolist()},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5125, "count": 6, "type": "SCALAR"},
        ],
    }
    if extension and declare:
        gltf["extensionsUsed"] = gltf["extensionsRequired"] = [extension]
    js = json.dumps(gltf).encode()
    js += b" " * (-len(js) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(blob), 0x004E4942) + blob
    path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
    return path


def write_png_glb(path: Path, img: np.ndarray) -> Path:
    return write_glb(path, _png(img), "image/png")


def write_obj(dirpath: Path, img: np.ndarray, texture_name: str = "checker.png") -> Path:
    Image.fromarray(img).save(dirpath / texture_name)
    (dirpath / "quad.mtl").write_text(f"newmtl checker\nKd 1 1 1\nmap_Kd {texture_name}\n")
    lines = ["mtllib quad.mtl"] + [f"v {x} {y} {z}" for x, y, z in QUAD_POS]
    lines += [f"vt {u} {1 - v}" for u, v in QUAD_UV_GLTF]  # OBJ: v up from the bottom row
    lines += ["usemtl checker", "f 1/1 2/2 3/3", "f 1/1 3/3 4/4"]
    (dirpath / "quad.obj").write_text("\n".join(lines) + "\n")
    return dirpath / "quad.obj"


def write_ply(path: Path, colours: np.ndarray) -> Path:
    """ASCII PLY quad with per-vertex colours (4, 3)."""
    head = ["ply", "format ascii 1.0", "element vertex 4", "property float x", "property float y",
            "property float z", "property uchar red", "property uchar green", "property uchar blue",
            "element face 2", "property list uchar int vertex_indices", "end_header"]
    body = [f"{x} {y} {z} {r} {g} {b}" for (x, y, z), (r, g, b) in zip(QUAD_POS, colours)]
    body += ["3 0 1 2", "3 0 2 3"]
    path.write_text("\n".join(head + body) + "\n")
    return path


def write_mesh_glb(path: Path, positions: np.ndarray, faces: np.ndarray, colours: np.ndarray | None = None,
                   node_names: list[tuple[str, np.ndarray]] | None = None, uv_gltf: np.ndarray | None = None,
                   png: bytes | None = None) -> Path:
    """A GLB of one or more vertex-coloured (or, with ``uv_gltf`` and ``png``, textured) primitives;
    ``node_names`` = [(name, face indices)] splits the faces into named nodes (default: one node 'mesh')."""
    node_names = node_names or [("mesh", np.arange(len(faces)))]
    blob = b""
    views, accessors, meshes, nodes = [], [], [], []

    def add(arr: np.ndarray) -> int:
        nonlocal blob
        blob += b"\0" * (-len(blob) % 4)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": arr.nbytes})
        blob += arr.tobytes()
        return len(views) - 1

    for name, sel in node_names:
        used, local = np.unique(faces[sel].reshape(-1), return_inverse=True)
        pos = positions[used].astype(np.float32)
        attrs = {"POSITION": len(accessors)}
        accessors.append({"bufferView": add(pos), "componentType": 5126, "count": len(pos), "type": "VEC3",
                          "min": pos.min(0).tolist(), "max": pos.max(0).tolist()})
        if colours is not None:
            col = np.asarray(colours, np.uint8)[used]
            attrs["COLOR_0"] = len(accessors)
            accessors.append({"bufferView": add(np.ascontiguousarray(col)), "componentType": 5121,
                              "normalized": True, "count": len(col), "type": f"VEC{col.shape[1]}"})
        if uv_gltf is not None:
            attrs["TEXCOORD_0"] = len(accessors)
            accessors.append({"bufferView": add(np.ascontiguousarray(uv_gltf[used], np.float32)),
                              "componentType": 5126, "count": len(used), "type": "VEC2"})
        idx = local.astype(np.uint32)
        accessors.append({"bufferView": add(idx), "componentType": 5125, "count": len(idx), "type": "SCALAR"})
        prim = {"attributes": attrs, "indices": len(accessors) - 1}
        if png is not None:
            prim["material"] = 0
        meshes.append({"primitives": [prim]})
        nodes.append({"mesh": len(meshes) - 1, "name": name})
    gltf = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}],
            "nodes": nodes, "meshes": meshes, "accessors": accessors, "bufferViews": views}
    if png is not None:
        gltf["images"] = [{"bufferView": add(np.frombuffer(png, np.uint8)), "mimeType": "image/png"}]
        gltf["textures"] = [{"source": 0}]
        gltf["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    blob += b"\0" * (-len(blob) % 4)
    gltf["buffers"] = [{"byteLength": len(blob)}]
    js = json.dumps(gltf).encode()
    js += b" " * (-len(js) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(blob), 0x004E4942) + blob
    path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
    return path


def box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """Closed box (8 vertices, 12 outward-wound triangles)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f


def room_scene() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 6 x 6 m floor slab, a wall box, a chair box and a tv box: (vertices, faces, part of each face:
    0 floor, 1 wall, 2 chair, 3 tv)."""
    parts = [box((-3, -0.1, -3), (3, 0.0, 3)), box((-3, 0, -3), (3, 2.5, -2.9)),
             box((0.5, 0, -1.5), (1.0, 0.9, -1.0)), box((-1.5, 0.6, -2.9), (-0.5, 1.2, -2.8))]
    vs, fs, part = [], [], []
    n = 0
    for k, (v, f) in enumerate(parts):
        vs.append(v)
        fs.append(f + n)
        part.append(np.full(len(f), k))
        n += len(v)
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(part)


HM3D_OBJECTS = [  # (id, hex colour, raw name, region, part of room_scene)
    (1, "1F77B4", "floor", 0, 0),
    (2, "FF7F0E", "wall", 0, 1),
    (3, "2CA02C", "armchair", 0, 2),
    (4, "D62728", "tv", 1, 3),
]


def write_hm3d_scene(root: Path, scan: str = "abcDEFghiJK", split: str = "val", index: int = 800,
                     textured_semantics: bool = False) -> Path:
    """HM3D v0.2 layout under ``root`` (= scene_datasets/hm3d): the annotated config, then
    ``{split}/{index:05d}-{scan}/{scan}.basis.glb`` (render mesh, here vertex-coloured grey),
    ``{scan}.semantic.glb`` (object colours per vertex) and ``{scan}.semantic.txt``. Returns the render mesh."""
    d = root / split / f"{index:05d}-{scan}"
    d.mkdir(parents=True, exist_ok=True)
    v, f, part = room_scene()
    grey = np.full((len(v), 4), 180, np.uint8)
    grey[:, 3] = 255
    mesh = write_mesh_glb(d / f"{scan}.basis.glb", v, f, grey)
    # Semantic mesh: vertices split per face so each face carries its object's colour at all corners.
    sv = v[f.reshape(-1)]
    sf = np.arange(len(sv)).reshape(-1, 3)
    colour = {p: bytes.fromhex(h) for _, h, _, _, p in HM3D_OBJECTS}
    if textured_semantics:
        # HM3D v0.2 paints objects into the semantic mesh's texture: one 8x8 block per object, each
        # face's corners mapped inside its object's block (glTF uv, v down from the top row).
        img = np.zeros((8, 8 * len(colour), 3), np.uint8)
        for p, c in colour.items():
            img[:, 8 * p:8 * p + 8] = list(c)
        corner = np.tile([[0.25, 0.25], [0.75, 0.25], [0.5, 0.75]], (len(f), 1))
        uv = np.column_stack([(np.repeat(part, 3) * 8 + corner[:, 0] * 8) / img.shape[1], corner[:, 1]])
        write_mesh_glb(d / f"{scan}.semantic.glb", sv, sf, uv_gltf=uv, png=_png(img))
    else:
        sc = np.array([list(colour[p]) + [255] for p in np.repeat(part, 3)], np.uint8)
        write_mesh_glb(d / f"{scan}.semantic.glb", sv, sf, sc)
    lines = ["HM3D Semantic Annotations"] + [f'{i},{h},"{n}",{r}' for i, h, n, r, _ in HM3D_OBJECTS]
    (d / f"{scan}.semantic.txt").write_text("\n".join(lines) + "\n")
    (root / "hm3d_annotated_basis.scene_dataset_config.json").write_text(json.dumps({
        "stages": {"default_attributes": {
            "requires_lighting": False,
            "semantic_asset": "%%CONFIG_NAME_AS_ASSET_FILENAME%%.semantic.glb",
            "semantic_descriptor_filename": "%%CONFIG_NAME_AS_ASSET_FILENAME%%.semantic.txt",
            "has_semantic_textures": textured_semantics},
            "paths": {".glb": [f"{split}/*/*.basis.glb"]}}}))
    return mesh


MP3D_HOUSE = """ASCII 1.1
H house_name unknown 0 0 0 0 0 3 3 2 0 1  0 0 0 0 0  -3 -3 -0.1 3 3 2.5  0 0 0 0 0
L 0 2 - 0 0 0  -3 -3 -0.1 3 3 2.5  0 0 0 0 0
R 0 0 0 0 l 0 0 0  -3 -3 -0.1 3 0 2.5  2.5 0 0 0 0
R 1 0 0 0 k 0 0 0  -3 0 -0.1 3 3 2.5  2.5 0 0 0 0
C 0 1 floor 2 floor 0 0 0 0 0
C 1 3 sofa#chair 3 chair 0 0 0 0 0
C 2 22 television 22 tv_monitor 0 0 0 0 0
O 0 0 0  0 0 0  1 0 0  0 1 0  3 3 0.05 0 0 0 0 0 0 0 0
O 1 0 1  0.75 1.25 0.45  1 0 0  0 1 0  0.25 0.25 0.45 0 0 0 0 0 0 0 0
O 2 1 2  -1 2.85 0.9  1 0 0  0 1 0  0.5 0.05 0.3 0 0 0 0 0 0 0 0
E 0 0 0 1 0 0 0 -3 -3 0 3 3 0 0 0 0 0 0
"""


def write_mp3d_scene(root: Path, scan: str = "17DRP5sb8fy") -> Path:
    """MP3D as Habitat ships it (z-up Matterport frame) under ``root`` (= scene_datasets/mp3d):
    ``mp3d.scene_dataset_config.json`` (up +z, front +y), ``{scan}/{scan}.glb``, ``{scan}/{scan}_semantic.ply``
    (binary, per-face ``object_id``) and ``{scan}/{scan}.house``. Returns the mesh path."""
    d = root / scan
    d.mkdir(parents=True, exist_ok=True)
    v, f, part = room_scene()  # y-up; Matterport z-up: (x, y, z)_habitat = (x, z, -y)_mp
    v_mp = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)
    grey = np.full((len(v), 4), 150, np.uint8)
    grey[:, 3] = 255
    mesh = write_mesh_glb(d / f"{scan}.glb", v_mp, f, grey)
    # Part -> .house object index: floor 0, wall -1 (unannotated), armchair 1, tv 2.
    obj = np.array([0, -1, 1, 2])[part].astype(np.int32)
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v_mp)}\nproperty float x\n"
            f"property float y\nproperty float z\nelement face {len(f)}\nproperty list uchar int vertex_indices\n"
            "property int object_id\nend_header\n").encode()
    body = v_mp.astype("<f4").tobytes()
    rec = np.zeros(len(f), dtype=[("n", "u1"), ("idx", "<i4", (3,)), ("obj", "<i4")])
    rec["n"], rec["idx"], rec["obj"] = 3, f, obj
    (d / f"{scan}_semantic.ply").write_bytes(head + body + rec.tobytes())
    (d / f"{scan}.house").write_text(MP3D_HOUSE)
    (root / "mp3d.scene_dataset_config.json").write_text(json.dumps({
        "stages": {"default_attributes": {"up": [0, 0, 1], "front": [0, 1, 0], "origin": [0, 0, 0],
                                          "semantic_asset": "%%CONFIG_NAME_AS_ASSET_FILENAME%%_semantic.ply"},
                   "paths": {".glb": ["*/*.glb"]}}}))
    return mesh
