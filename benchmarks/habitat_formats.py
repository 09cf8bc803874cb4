"""Write small files in the layouts Habitat's own tools write, byte by byte from the upstream sources.

    python benchmarks/habitat_formats.py --out /tmp/habitat-formats

Then, from the printed paths::

    navbench run --agent oracle --episodes OUT/ovon/val_unseen.json.gz --scene-dir OUT/scene_datasets
    navbench run --agent oracle --episodes OUT/objectnav_hssd/val.json.gz --scene-dir OUT/scene_datasets
    navbench localize --episodes OUT/goat_bench/val_seen.json.gz --scene-dir OUT/scene_datasets

What is written, and where each detail comes from:

* ``scene_datasets/hm3d/``: an HM3D v0.2 scan (``hm3d_annotated_basis.scene_dataset_config.json``,
  ``val/00800-abcDEFghiJK/abcDEFghiJK.basis.glb`` + ``.semantic.glb`` + ``.semantic.txt``). The render
  mesh's texture is a ``.basis`` file referenced through ``GOOGLE_texture_basis`` with ``mimeType``
  ``image/x-basis``, no ``extensionsUsed`` and the image bundled in a bufferView, as habitat-sim's
  ``tools/create_basis_compressed_glbs.py`` produces through magnum-plugins'
  ``src/MagnumPlugins/GltfImporter/Test/gltf2basis.py`` and ``gltf2glb.py --bundle-images``; the
  ``.basis`` is stored bottom row first with ``cBASISHeaderFlagYFlipped`` set, as magnum's
  ``BasisImageConverter`` (``y_flip=true``) writes it (container: basis_universal
  ``transcoder/basisu_file_headers.h``). ``semantic.txt`` rows are ``id,HEX,"name",region`` after the
  ``HM3D Semantic Annotations`` header (habitat-sim ``src/esp/scene/HM3DSemanticScene.cpp``).
  Needs the ``alktx2`` encoder for the UASTC payload; without it the texture is a PNG.
* ``ovon/val_unseen.json.gz``: HM3D-OVON episodes (naokiyokoyama/ovon ``ovon/dataset/objectnav_generator.py``):
  goal ``object_id``s are habitat-sim object names ``{raw name}_{index among that name's rows}``
  (HM3DSemanticScene.cpp), view points carry a ``radius``, episodes carry ``children_object_categories``.
* ``goat_bench/val_seen.json.gz``: GOAT-Bench episodes (Ram81/goat-bench ``goat_bench/dataset/goat_dataset.py``):
  ``tasks`` ``[category, object|description|image, object_id, (image index)]``, top-level ``goals``
  keyed ``{scene basename}_{category}`` with ``lang_desc`` and ``image_goals`` (habitat-lab
  ``habitat/tasks/nav/instance_image_nav_task.py``: ``position``, ``rotation`` [x, y, z, w], ``hfov``,
  ``image_dimensions`` (H, W)).
* ``instance_imagenav/val/``: InstanceImageNav episodes as habitat-lab's ``InstanceImageNavDatasetV1``
  reads them (``habitat/datasets/image_nav/instance_image_nav_dataset.py``): ``val.json.gz`` with no
  episodes and ``content/{scan}.json.gz`` with ``goals`` keyed ``{scan}_{object_id}`` (view points and
  ``image_goals``: world camera poses, pitch and roll included, ``hfov``, ``image_dimensions`` (H, W)) and
  episodes naming ``goal_object_id`` and ``goal_image_id``.
* ``scene_datasets/hssd/``: an HSSD-style scene instance (habitat-sim ``docs/pages/attributesJSON.rst``,
  ``src/esp/metadata/managers/SceneInstanceAttributesManager.cpp``): ``scenes/room.scene_instance.json``
  with a stage and object instances (``rotation`` [w, x, y, z], ``uniform_scale``, ``non_uniform_scale``,
  ``motion_type``, ``translation_origin`` ``asset_local`` for the scene and ``COM`` for one instance),
  object configs found by hash name under ``objects/``, each with a ``semantic_id`` named by
  ``semantics/hssd_semantic_lexicon.json``.
* ``objectnav_hssd/val.json.gz``: ObjectNav-v1 episodes (habitat-lab
  ``habitat/datasets/object_nav/object_nav_dataset.py``) in that scene instance.
"""

from __future__ import annotations

import argparse
import gzip
import io
import json
import struct
from pathlib import Path

import numpy as np
from PIL import Image

SCAN, SCAN_DIR = "abcDEFghiJK", "val/00800-abcDEFghiJK"
HM3D_SCENE_ID = f"hm3d/{SCAN_DIR}/{SCAN}.basis.glb"
HSSD_SCENE_ID = "hssd/scenes/room.scene_instance.json"
HM3D_CONFIG = "./data/scene_datasets/hm3d/hm3d_annotated_basis.scene_dataset_config.json"
# (semantic id, HEX, raw name, region, part of room()): HM3D names the same raw name's instances 0, 1, ...
HM3D_ROWS = [(1, "1F77B4", "floor", 0, 0), (2, "FF7F0E", "wall", 0, 1), (3, "2CA02C", "armchair", 0, 2),
             (4, "D62728", "tv", 1, 3)]
PART_COLOURS = {0: (150, 120, 90), 1: (200, 200, 190), 2: (40, 160, 60), 3: (30, 30, 30)}


# ------------------------------------------------------------------------------------------ geometry
def box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f


def room() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 6 x 6 m floor, a wall, an armchair box and a tv box: (vertices, faces, part of each face)."""
    parts = [box((-3, -0.1, -3), (3, 0.0, 3)), box((-3, 0, -3), (3, 2.5, -2.9)),
             box((0.5, 0, -1.5), (1.0, 0.9, -1.0)), box((-1.5, 0.6, -2.9), (-0.5, 1.2, -2.8))]
    vs, fs, part, n = [], [], [], 0
    for k, (v, f) in enumerate(parts):
        vs.append(v)
        fs.append(f + n)
        part.append(np.full(len(f), k))
        n += len(v)
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(part)


def centre(part: int) -> list[float]:
    v, f, p = room()
    pts = v[np.unique(f[p == part])]
    return ((pts.min(0) + pts.max(0)) / 2).round(5).tolist()


# ------------------------------------------------------------------------------------------- glTF
def png(img: np.ndarray) -> bytes:
    out = io.BytesIO()
    Image.fromarray(img).save(out, format="PNG")
    return out.getvalue()


def glb(path: Path, positions, faces, colours=None, uv=None, image: bytes | None = None, mime: str = "image/png",
        extension: str | None = None) -> Path:
    """A one-primitive GLB (glTF 2.0 binary: 12-byte header, JSON chunk, BIN chunk). Per-face geometry
    (vertices unshared) so colours and uvs are per face. With ``extension`` the texture's source sits
    in that extension only, as gltf2basis.py writes it; the image is bundled unaligned, as gltf2glb.py does."""
    pos = np.asarray(positions, np.float32)
    idx = np.asarray(faces, np.uint32).reshape(-1)
    views, accessors, attrs = [], [], {}
    blob = b""

    def add(data: bytes, align: bool = True) -> int:
        nonlocal blob
        if align:
            blob += b"\0" * (-len(blob) % 4)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
        blob += data
        return len(views) - 1

    attrs["POSITION"] = len(accessors)
    accessors.append({"bufferView": add(pos.tobytes()), "componentType": 5126, "count": len(pos), "type": "VEC3",
                      "min": pos.min(0).tolist(), "max": pos.max(0).tolist()})
    if colours is not None:
        col = np.ascontiguousarray(colours, np.uint8)
        attrs["COLOR_0"] = len(accessors)
        accessors.append({"bufferView": add(col.tobytes()), "componentType": 5121, "normalized": True,
                          "count": len(col), "type": f"VEC{col.shape[1]}"})
    if uv is not None:
        attrs["TEXCOORD_0"] = len(accessors)
        accessors.append({"bufferView": add(np.ascontiguousarray(uv, np.float32).tobytes()), "componentType": 5126,
                          "count": len(uv), "type": "VEC2"})
    accessors.append({"bufferView": add(idx.tobytes()), "componentType": 5125, "count": len(idx), "type": "SCALAR"})
    prim = {"attributes": attrs, "indices": len(accessors) - 1}
    gltf = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0, "name": "mesh"}], "meshes": [{"primitives": [prim]}], "accessors": accessors}
    if image is not None:
        prim["material"] = 0
        gltf["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
                              "extensions": {"KHR_materials_unlit": {}}}]
        gltf["textures"] = [{"extensions": {extension: {"source": 0}}} if extension else {"source": 0}]
        gltf["images"] = [{"bufferView": add(image, align=False), "mimeType": mime, "name": "texture"}]
        gltf["extensionsUsed"] = ["KHR_materials_unlit"]
    gltf["bufferViews"] = views
    blob += b" " * (-len(blob) % 4)
    gltf["buffers"] = [{"byteLength": len(blob)}]
    js = json.dumps(gltf, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(blob), 0x004E4942) + blob
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
    return path


# ------------------------------------------------------------------------------------------ Basis
def _crc16(data: bytes) -> int:
    """basis_universal's ``basist::crc16`` (transcoder/basisu_transcoder.cpp), initial value 0."""
    crc = 0xFFFF
    for b in data:
        q = (b ^ (crc >> 8)) & 0xFFFF
        k = ((q >> 4) ^ q) & 0xFFFF
        crc = ((crc << 8) ^ k ^ (k << 5) ^ (k << 12)) & 0xFFFF
    return ~crc & 0xFFFF


def basis_file(rgb: np.ndarray) -> bytes | None:
    """A ``.basis`` (UASTC 4x4) of ``rgb`` as magnum's BasisImageConverter writes it with ``y_flip=true``:
    bottom row first, ``cBASISHeaderFlagYFlipped`` set; None without the ``alktx2`` encoder.

    The UASTC blocks come from alktx2's KTX2 (KTX 2.0 spec: size at bytes 20-27, supercompression at
    44, level 0 offset/length at 80-95); the container is basis_universal's ``basis_file_header`` (77
    bytes packed: ``sB``, version 0x13, header size, header CRC-16, data size, data CRC-16, 1 slice,
    1 image, format 1 = UASTC, flags 2 = Y-flipped, type 0 = 2D, ..., slice descriptions at 77) and one
    23-byte ``basis_slice_desc``.
    """
    try:
        import alktx2
    except ImportError:
        return None
    flipped = np.ascontiguousarray(rgb[::-1])
    h, w = rgb.shape[:2]
    rgba = np.dstack([flipped, np.full((h, w), 255, np.uint8)])
    ktx2 = alktx2.encode_raw_rgba_to_ktx2(rgba.tobytes(), w, h, has_alpha=False, codec="uastc", quality=90)
    (scheme,) = struct.unpack_from("<I", ktx2, 44)
    offset, length = struct.unpack_from("<QQ", ktx2, 80)
    if scheme != 0:
        raise RuntimeError("alktx2 wrote a supercompressed KTX2; plain UASTC blocks expected")
    blocks = ktx2[offset:offset + length]
    def u24(v: int) -> bytes:
        return v.to_bytes(3, "little")

    desc = u24(0) + bytes([0, 0]) + struct.pack("<HHHHII", w, h, -(-w // 4), -(-h // 4), 100, len(blocks))
    desc += struct.pack("<H", _crc16(blocks))
    data = desc + blocks
    rest = (struct.pack("<IH", len(data), _crc16(data)) + u24(1) + u24(1) + bytes([1]) + struct.pack("<H", 2)
            + bytes([0]) + u24(0) + struct.pack("<III", 0, 0, 0) + struct.pack("<HI", 0, 0) + u24(0)
            + struct.pack("<HI", 0, 0) + u24(0) + struct.pack("<IIIII", 0, 0, 77, 0, 0))
    return struct.pack("<HHHH", 0x4273, 0x13, 77, _crc16(rest)) + rest + data


# ------------------------------------------------------------------------------------------ HM3D
def atlas() -> np.ndarray:
    """One 16 x 16 block per part, in the part's colour, with a darker 4-pixel checker inside."""
    img = np.zeros((16, 16 * len(PART_COLOURS), 3), np.uint8)
    yy, xx = np.mgrid[0:16, 0:16]
    for p, c in PART_COLOURS.items():
        block = np.tile(np.array(c, np.uint8), (16, 16, 1))
        block[((yy // 4 + xx // 4) % 2) == 1] //= 2
        img[:, 16 * p:16 * p + 16] = block
    return img


def write_hm3d(root: Path) -> Path:
    d = root / SCAN_DIR
    v, f, part = room()
    sv = v[f.reshape(-1)]
    sf = np.arange(len(sv)).reshape(-1, 3)
    img = atlas()
    corner = np.tile([[0.2, 0.2], [0.8, 0.2], [0.5, 0.8]], (len(f), 1))
    uv = np.column_stack([(np.repeat(part, 3) * 16 + corner[:, 0] * 16) / img.shape[1], corner[:, 1]])
    basis = basis_file(img)
    if basis is not None:
        glb(d / f"{SCAN}.basis.glb", sv, sf, uv=uv, image=basis, mime="image/x-basis", extension="GOOGLE_texture_basis")
    else:
        glb(d / f"{SCAN}.basis.glb", sv, sf, uv=uv, image=png(img))
    colour = {p: bytes.fromhex(h) for _, h, _, _, p in HM3D_ROWS}
    sc = np.array([list(colour[p]) + [255] for p in np.repeat(part, 3)], np.uint8)
    glb(d / f"{SCAN}.semantic.glb", sv, sf, colours=sc)
    rows = ["HM3D Semantic Annotations"] + [f'{i},{h},"{n}",{r}' for i, h, n, r, _ in HM3D_ROWS]
    (d / f"{SCAN}.semantic.txt").write_text("\n".join(rows) + "\n")
    (root / "hm3d_annotated_basis.scene_dataset_config.json").write_text(json.dumps({
        "stages": {"default_attributes": {
            "requires_lighting": False,
            "semantic_asset": "%%CONFIG_NAME_AS_ASSET_FILENAME%%.semantic.glb",
            "semantic_descriptor_filename": "%%CONFIG_NAME_AS_ASSET_FILENAME%%.semantic.txt"},
            "paths": {".glb": ["val/*/*.basis.glb"]}}}, indent=1))
    return d / f"{SCAN}.basis.glb"


def _view_point(x: float, z: float, yaw_quat=(0.0, 0.0, 0.0, 1.0), radius: float | None = None) -> dict:
    vp = {"agent_state": {"position": [round(x, 3), 0.0, round(z, 3)], "rotation": list(yaw_quat)}, "iou": 0.5}
    if radius is not None:
        vp["radius"] = radius
    return vp


OBSTACLES = [((0.5, -1.5), (1.0, -1.0)), ((-3.0, -3.0), (3.0, -2.9))]  # xz boxes of room()'s armchair and wall


def view_points(lo, hi, obstacles=OBSTACLES, radius: float | None = None) -> list[dict]:
    """Dense view points as Habitat's generators sample them: floor points on a 0.1 m grid within 1 m
    (xz) of the object's box, at least 0.25 m from it and from every obstacle, inside the room."""
    out = []
    for x in np.arange(-2.6, 2.61, 0.1):
        for z in np.arange(-2.6, 2.61, 0.1):
            d = np.hypot(max(lo[0] - x, 0, x - hi[0]), max(lo[2] - z, 0, z - hi[2]))
            clear = all(np.hypot(max(a[0] - x, 0, x - b[0]), max(a[1] - z, 0, z - b[1])) >= 0.25
                        for a, b in obstacles)
            if 0.25 <= d <= 1.0 and clear:
                out.append(_view_point(float(x), float(z), radius=radius))
    return out


def part_box(part: int) -> tuple[np.ndarray, np.ndarray]:
    v, f, p = room()
    pts = v[np.unique(f[p == part])]
    return pts.min(0), pts.max(0)


# (category as OVON names it, object_id as habitat-sim names it, part of room())
OVON_GOALS = [("armchair", "armchair_0", 2), ("tv", "tv_0", 3)]


def write_ovon(path: Path) -> Path:
    base = Path(HM3D_SCENE_ID).name
    goals = {f"{base}_{cat}": [{"object_category": cat, "object_id": oid, "position": centre(p),
                                "view_points": view_points(*part_box(p), radius=1.0)}]
             for cat, oid, p in OVON_GOALS}
    starts = [([2.0, 0.0, 2.0], [0.0, 0.0, 0.0, 1.0]), ([-2.0, 0.0, 1.5], [0.0, 0.7071068, 0.0, 0.7071068])]
    episodes = []
    for k, (cat, _, _) in enumerate(OVON_GOALS * 2):
        pos, rot = starts[k % 2]
        episodes.append({"episode_id": str(k), "scene_id": HM3D_SCENE_ID,
                         "scene_dataset_config": HM3D_CONFIG,
                         "additional_obj_config_paths": [], "start_position": pos, "start_rotation": rot,
                         "info": {"geodesic_distance": 3.0, "euclidean_distance": 2.5}, "goals": [],
                         "start_room": None, "shortest_paths": None, "object_category": cat,
                         "children_object_categories": []})
    return _write(path, {"episodes": episodes, "goals_by_category": goals, "category_to_task_category_id": {},
                         "category_to_scene_annotation_category_id": {}})


def write_goat_bench(path: Path) -> Path:
    base = Path(HM3D_SCENE_ID).name
    image_goal = {"position": [0.75, 0.88, 0.6], "rotation": [0.0, 0.0, 0.0, 1.0], "hfov": 79.0,
                  "image_dimensions": [224, 224], "frame_coverage": 0.3, "object_coverage": 0.9}
    goals = {
        f"{base}_armchair": [{"object_category": "armchair", "object_id": "armchair_0", "position": centre(2),
                              "children_object_categories": [], "view_points": view_points(*part_box(2)),
                              "lang_desc": "The green armchair stands in the middle of the room, away from the wall.",
                              "image_goals": [image_goal]}],
        f"{base}_tv": [{"object_category": "tv", "object_id": "tv_0", "position": centre(3),
                        "children_object_categories": [], "view_points": view_points(*part_box(3)),
                        "lang_desc": "The television hangs on the wall at the back of the room.",
                        "image_goals": []}],
    }
    tasks = [["armchair", "object", "armchair_0"], ["tv", "description", "tv_0"],
             ["armchair", "image", "armchair_0", 0], ["tv", "object", "tv_0"],
             ["armchair", "description", "armchair_0"]]
    episodes = [{"episode_id": "0", "scene_id": HM3D_SCENE_ID, "start_position": [2.0, 0.0, 2.0],
                 "start_rotation": [0.0, 0.0, 0.0, 1.0], "info": {}, "goals": [], "tasks": tasks}]
    return _write(path, {"episodes": episodes, "goals": goals})


def _quat(axis: int, deg: float) -> list[float]:
    q = [0.0, 0.0, 0.0, float(np.cos(np.radians(deg) / 2))]
    q[axis] = float(np.sin(np.radians(deg) / 2))
    return [round(v, 7) for v in q]


def _qmul(a, b) -> list[float]:
    (x1, y1, z1, w1), (x2, y2, z2, w2) = a, b
    return [round(v, 7) for v in (w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                                  w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2)]


def write_instance_imagenav(path: Path) -> Path:
    """``path`` (``{split}/{split}.json.gz``, no episodes) and ``content/{scan}.json.gz`` beside it."""
    def goal(sem_id: int, name: str, part: int, images: list[dict]) -> dict:
        return {"position": centre(part), "object_id": sem_id, "object_name": f"{name}_{sem_id}",
                "object_category": name, "object_surface_area": 1.0, "view_points": view_points(*part_box(part)),
                "image_goals": images}

    def image(pos, rot, hfov, dims) -> dict:
        return {"position": pos, "rotation": rot, "hfov": hfov, "image_dimensions": dims,
                "frame_coverage": 0.3, "object_coverage": 0.9}

    goals = {  # the armchair: pitched down 25 degrees; then also rolled 10 degrees, a 120 x 160 image
        f"{SCAN}_3": goal(3, "armchair", 2, [image([0.75, 1.2, 0.5], _quat(0, -25), 65, [512, 512]),
                                             image([0.9, 1.1, 0.4], _qmul(_quat(0, -20), _quat(2, 10)), 60,
                                                   [120, 160])]),
        f"{SCAN}_4": goal(4, "tv", 3, [image([-1.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0], 90, [96, 96])]),
    }
    starts = [([2.0, 0.0, 2.0], [0.0, 0.0, 0.0, 1.0]), ([-2.0, 0.0, 1.5], [0.0, 0.7071068, 0.0, 0.7071068])]
    episodes = []
    for k, (key, image_id) in enumerate([(f"{SCAN}_3", 1), (f"{SCAN}_4", 0), (f"{SCAN}_3", 0)]):
        pos, rot = starts[k % 2]
        g = goals[key]
        near = min(float(np.hypot(v["agent_state"]["position"][0] - pos[0], v["agent_state"]["position"][2] - pos[2]))
                   for v in g["view_points"])
        episodes.append({"episode_id": str(k), "scene_id": HM3D_SCENE_ID, "scene_dataset_config": HM3D_CONFIG,
                         "additional_obj_config_paths": [], "start_position": pos, "start_rotation": rot,
                         "info": {"geodesic_distance": round(near, 4), "euclidean_distance": round(near, 4)},
                         "goals": [], "object_category": g["object_category"],
                         "goal_object_id": str(g["object_id"]), "goal_image_id": image_id})
    _write(path.parent / "content" / f"{SCAN}.json.gz", {"goals": goals, "episodes": episodes})
    return _write(path, {"episodes": []})


# ------------------------------------------------------------------------------------------ HSSD
# Object instances: (config hash, semantic id, box, instance transform)
HSSD_OBJECTS = [
    ("1efdc3d37dfab1eb9f99117bb84c59003d684811", 3, ((-0.25, 0.0, -0.25), (0.25, 0.9, 0.25)),
     {"translation": [1.0, 0.0, -1.0], "rotation": [0.9238795, 0.0, 0.3826834, 0.0], "motion_type": "STATIC"}),
    ("7a9c3e20a1d4b5c6d7e8f9001122334455667788", 5, ((0.0, 0.0, 0.0), (1.0, 0.5, 0.4)),
     {"translation": [-1.5, 0.3, 1.0], "rotation": [1.0, 0.0, 0.0, 0.0], "uniform_scale": 1.2,
      "non_uniform_scale": [1.0, 1.0, 1.5], "motion_type": "DYNAMIC", "translation_origin": "COM"}),
]
HSSD_LEXICON = {"classes": [{"name": "chair", "id": 3}, {"name": "cabinet", "id": 5}]}


def hssd_object_box(k: int) -> tuple[np.ndarray, np.ndarray]:
    """World-space AABB of HSSD_OBJECTS[k] as habitat-sim places it (for tests)."""
    _, _, (lo, hi), inst = HSSD_OBJECTS[k]
    v, _ = box(lo, hi)
    s = float(inst.get("uniform_scale", 1.0)) * np.asarray(inst.get("non_uniform_scale", [1, 1, 1]), float)
    if inst.get("translation_origin") == "COM":
        v = v - (np.asarray(lo) + np.asarray(hi)) / 2
    w, x, y, z = inst["rotation"]
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    pts = (v * s) @ rot.T + np.asarray(inst["translation"])
    return pts.min(0), pts.max(0)


def write_hssd(root: Path) -> Path:
    v, f, part = room()
    keep = np.isin(part, [0, 1])
    used = np.unique(f[keep])
    remap = -np.ones(len(v), int)
    remap[used] = np.arange(len(used))
    grey = np.tile([170, 170, 170, 255], (len(used), 1)).astype(np.uint8)
    glb(root / "stages" / "room.glb", v[used], remap[f[keep]], colours=grey)
    (root / "stages" / "room.stage_config.json").write_text(json.dumps({"render_asset": "room.glb",
                                                                        "up": [0, 1, 0], "front": [0, 0, -1]}))
    for k, (name, sid, (lo, hi), _) in enumerate(HSSD_OBJECTS):
        bv, bf = box(lo, hi)
        colours = np.tile([60 + 80 * k, 90, 200 - 80 * k, 255], (len(bv), 1)).astype(np.uint8)
        d = root / "objects" / name[0]
        glb(d / f"{name}.glb", bv, bf, colours=colours)
        (d / f"{name}.object_config.json").write_text(json.dumps({"render_asset": f"{name}.glb",
                                                                  "semantic_id": sid}))
    (root / "semantics").mkdir(parents=True, exist_ok=True)
    (root / "semantics" / "hssd_semantic_lexicon.json").write_text(json.dumps(HSSD_LEXICON))
    instances = [dict({"template_name": name}, **inst) for name, _, _, inst in HSSD_OBJECTS]
    (root / "scenes").mkdir(parents=True, exist_ok=True)
    scene = root / "scenes" / "room.scene_instance.json"
    scene.write_text(json.dumps({"stage_instance": {"template_name": "stages/room"},
                                 "default_lighting": "", "translation_origin": "asset_local",
                                 "object_instances": instances}, indent=1))
    (root / "hssd.scene_dataset_config.json").write_text(json.dumps({
        "stages": {"paths": {".json": ["stages"]}}, "objects": {"paths": {".json": ["objects/*"]}},
        "scene_instances": {"paths": {".json": ["scenes"]}}}, indent=1))
    return scene


def write_objectnav_hssd(path: Path) -> Path:
    goals = {}
    for k, (name, _, _, _) in enumerate(HSSD_OBJECTS):
        lo, hi = hssd_object_box(k)
        cat = HSSD_LEXICON["classes"][k]["name"]
        c = ((lo + hi) / 2).round(5).tolist()
        boxes = [hssd_object_box(j) for j in range(len(HSSD_OBJECTS))]
        vp = view_points(lo, hi, [((a[0], a[2]), (b[0], b[2])) for a, b in boxes] + OBSTACLES[1:])
        goals[f"{Path(HSSD_SCENE_ID).name}_{cat}"] = [{"object_category": cat, "object_id": k, "object_name": name,
                                                      "position": c, "view_points": vp}]
    episodes = [{"episode_id": str(k), "scene_id": HSSD_SCENE_ID, "start_position": [2.0, 0.0, 2.0],
                 "start_rotation": [0.0, 0.0, 0.0, 1.0], "info": {"geodesic_distance": 3.0}, "goals": [],
                 "object_category": c["name"]} for k, c in enumerate(HSSD_LEXICON["classes"])]
    return _write(path, {"episodes": episodes, "goals_by_category": goals,
                         "category_to_task_category_id": {"chair": 0, "cabinet": 1},
                         "category_to_scene_annotation_category_id": {"chair": 3, "cabinet": 5}})


def _write(path: Path, data: dict) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(gzip.compress(json.dumps(data).encode(), mtime=0))
    return path


def write_all(out: str | Path) -> dict[str, Path]:
    out = Path(out)
    sd = out / "scene_datasets"
    return {"scene_datasets": sd, "hm3d_scene": write_hm3d(sd / "hm3d"), "hssd_scene": write_hssd(sd / "hssd"),
            "ovon": write_ovon(out / "ovon" / "val_unseen.json.gz"),
            "goat_bench": write_goat_bench(out / "goat_bench" / "val_seen.json.gz"),
            "instance_imagenav": write_instance_imagenav(out / "instance_imagenav" / "val" / "val.json.gz"),
            "objectnav_hssd": write_objectnav_hssd(out / "objectnav_hssd" / "val.json.gz")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    print(json.dumps({k: str(v) for k, v in write_all(args.out).items()}, indent=1))


if __name__ == "__main__":
    main()
