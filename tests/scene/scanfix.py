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


def write_glb(path: Path, image_bytes: bytes, mime: str, basisu: bool = False) -> Path:
    """A one-quad GLB whose material's baseColorTexture is the given image."""
    chunks = [QUAD_POS.tobytes(), QUAD_UV_GLTF.tobytes(), QUAD_IDX.tobytes(), image_bytes]
    views, blob = [], b""
    for c in chunks:
        blob += b"\0" * (-len(blob) % 4)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(c)})
        blob += c
    blob += b"\0" * (-len(blob) % 4)
    texture = {"extensions": {"KHR_texture_basisu": {"source": 0}}} if basisu else {"source": 0}
    gltf = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "name": "quad"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}],
        "textures": [texture], "images": [{"bufferView": 3, "mimeType": mime}],
        "buffers": [{"byteLength": len(blob)}], "bufferViews": views[:3] + [views[3]],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": QUAD_POS.min(0).tolist(), "max": QUAD_POS.max(0).tolist()},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5125, "count": 6, "type": "SCALAR"},
        ],
    }
    if basisu:
        gltf["extensionsUsed"] = gltf["extensionsRequired"] = ["KHR_texture_basisu"]
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
