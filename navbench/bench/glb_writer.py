"""A minimal GLB (binary glTF 2.0) writer: one mesh of one primitive, optionally textured or vertex-coloured.

Enough for scan-like test scenes (:mod:`navbench.bench.scan_fixture`): positions, triangle indices,
texture coordinates with an embedded image (JPEG/PNG, or KTX2 through ``KHR_texture_basisu``) and
RGBA vertex colours. Reading GLB is :mod:`navbench.scene.mesh_io`'s (through trimesh).
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np


def write_glb(path: Path, positions, faces, uv=None, image: bytes | None = None, mime: str = "image/jpeg",
         colours=None, basisu: bool = False) -> None:
    """A single-primitive GLB (uv in OpenGL convention, flipped to glTF's here)."""
    arrays = [np.asarray(positions, np.float32), np.asarray(faces, np.uint32).reshape(-1)]
    attrs = {"POSITION": 0}
    acc = [{"bufferView": 0, "componentType": 5126, "count": len(positions), "type": "VEC3",
            "min": arrays[0].min(0).tolist(), "max": arrays[0].max(0).tolist()},
           {"bufferView": 1, "componentType": 5125, "count": int(arrays[1].size), "type": "SCALAR"}]
    if uv is not None:
        g = np.asarray(uv, np.float32).copy()
        g[:, 1] = 1.0 - g[:, 1]
        arrays.append(g)
        attrs["TEXCOORD_0"] = len(acc)
        acc.append({"bufferView": len(arrays) - 1, "componentType": 5126, "count": len(g), "type": "VEC2"})
    if colours is not None:
        arrays.append(np.asarray(colours, np.uint8)[:, :4])
        attrs["COLOR_0"] = len(acc)
        acc.append({"bufferView": len(arrays) - 1, "componentType": 5121, "normalized": True,
                    "count": len(colours), "type": "VEC4"})
    blobs = [a.tobytes() for a in arrays] + ([image] if image is not None else [])
    views, blob = [], bytearray()
    for b in blobs:
        blob += b"\0" * (-len(blob) % 4)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(b)})
        blob += b
    blob += b"\0" * (-len(blob) % 4)
    prim = {"attributes": attrs, "indices": 1, "mode": 4}
    gltf = {"asset": {"version": "2.0", "generator": "navbench scan fixture"}, "scene": 0,
            "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "name": "scan"}], "meshes": [{"primitives": [prim]}],
            "accessors": acc, "bufferViews": views, "buffers": [{"byteLength": len(blob)}]}
    if image is not None:
        prim["material"] = 0
        gltf["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}]
        gltf["textures"] = [{"extensions": {"KHR_texture_basisu": {"source": 0}}} if basisu else {"source": 0}]
        gltf["images"] = [{"bufferView": len(views) - 1, "mimeType": mime}]
        if basisu:
            gltf["extensionsUsed"] = gltf["extensionsRequired"] = ["KHR_texture_basisu"]
    js = json.dumps(gltf, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(blob), 0x004E4942) + bytes(blob)
    path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
