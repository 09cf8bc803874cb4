"""Base-colour textures of scan meshes: checks, Basis Universal decoding, and the per-part texture table.

glTF images are checked before trimesh parses the file, because trimesh drops an image it cannot
decode without a word and the scene would then render grey or white. Basis Universal images are
read in both forms Habitat meets:

* ``GOOGLE_texture_basis``: ``.basis`` files with ``mimeType`` ``image/x-basis``, the texture's
  ``source`` moved into the extension; this is what habitat-sim's ``tools/create_basis_compressed_glbs.py``
  writes for the ``*.basis.glb`` releases (through magnum-plugins'
  ``src/MagnumPlugins/GltfImporter/Test/gltf2basis.py`` and ``gltf2glb.py --bundle-images``, which
  declare no ``extensionsUsed``);
* ``KHR_texture_basisu``: the Khronos extension, KTX2 (or ``.basis``) payloads.

Both are transcoded to RGBA8 with the ``opengl-basisu`` package (Binomial's basis_universal). A
``.basis`` file flagged Y-flipped (``cBASISHeaderFlagYFlipped``, basis_universal
``transcoder/basisu_file_headers.h``) has its rows back in glTF order after decoding: magnum's
``BasisImageConverter`` (``y_flip=true`` by default) stores the image bottom row first and sets the
flag; for KTX2 it writes ``KTXorientation`` ``ru`` instead (KTX 2.0 spec, section 5.2), read the same way.
A texture whose only source is an extension navbench cannot decode is refused, naming the file
and the extension. In the GLB that trimesh parses, each decoded image is replaced by a
1x1 PNG whose text chunk names the decoded image (:data:`DECODED`), which :func:`texture_image`
swaps back in, so the large image is neither re-encoded nor copied through trimesh.
"""

from __future__ import annotations

import io
import json
import struct
from pathlib import Path

import numpy as np

from navbench.safeio import InputTooLarge, read_input
from navbench.scene.errors import SceneError

BASISU = "KHR_texture_basisu"
GOOGLE_BASIS = "GOOGLE_texture_basis"
BASIS_EXTENSIONS = (BASISU, GOOGLE_BASIS)
_BASIS_MIMES = ("image/ktx2", "image/x-basis", "image/basis")
_KTX2_MAGIC = b"\xabKTX 20\xbb\r\n\x1a\n"
_BASIS_MAGIC = b"sB"
_PLACEHOLDER_KEY = "navbench-decoded"
DECODED: dict[str, np.ndarray] = {}  # placeholder token -> decoded RGBA, filled by prepare_glb


def read_glb(data: bytes, path: Path) -> tuple[dict, bytes]:
    """(JSON header, BIN chunk) of a binary glTF file."""
    if len(data) < 20 or data[:4] != b"glTF":
        raise SceneError(f"{path}: not a binary glTF file (bad magic)")
    (json_len, json_type) = struct.unpack_from("<II", data, 12)
    if json_type != 0x4E4F534A or 20 + json_len > len(data):
        raise SceneError(f"{path}: corrupt GLB (first chunk is not a complete JSON chunk)")
    try:
        header = json.loads(data[20:20 + json_len])
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SceneError(f"{path}: corrupt GLB JSON chunk ({exc})") from None
    rest = 20 + json_len
    binary = b""
    if rest + 8 <= len(data):
        bin_len, _ = struct.unpack_from("<II", data, rest)
        binary = data[rest + 8:rest + 8 + bin_len]
    return header, binary


def write_glb(header: dict, binary: bytes) -> bytes:
    js = json.dumps(header, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    out = struct.pack("<II", len(js), 0x4E4F534A) + js
    if binary:
        out += struct.pack("<II", len(binary), 0x004E4942) + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(out)) + out


def _view_bytes(header: dict, binary: bytes, index: int, path: Path) -> bytes:
    try:
        view = header["bufferViews"][index]
        start = int(view.get("byteOffset", 0))
        return binary[start:start + int(view["byteLength"])]
    except (IndexError, KeyError, TypeError, ValueError):
        raise SceneError(f"{path}: image refers to a missing bufferView {index}") from None


MAX_TEXTURE_PIXELS = 8192 * 8192  # 256 MB as RGBA; scans' textures are 4096 x 4096 at most


def _check_pixels(width: int, height: int, where: str) -> None:
    """Refuse a texture whose decoded size would pass :data:`MAX_TEXTURE_PIXELS` (a decompression bomb)."""
    if width * height > MAX_TEXTURE_PIXELS:
        raise SceneError(f"{where}: texture of {width} x {height} pixels is larger than {MAX_TEXTURE_PIXELS} "
                         f"pixels (a decompression bomb?)")


def decode_basis(blob: bytes, where: str, extension: str = BASISU) -> np.ndarray:
    """(H, W, 4) uint8 RGBA of the top mip level of a KTX2/Basis Universal image, row 0 at the top;
    ``extension`` (the glTF extension that referenced it) is named in every error."""
    try:
        import opengl_basisu
    except ImportError:
        raise SceneError(f"{where}: uses {extension} (Basis Universal) textures, which need the opengl-basisu "
                         f"package (pip install opengl-basisu)") from None
    try:
        texture = opengl_basisu.open(bytes(blob))
        _check_pixels(int(texture.width), int(texture.height), where)
        rgba = np.asarray(texture.transcode(opengl_basisu.Target.RGBA8).data, dtype=np.uint8)
    except (ValueError, IndexError) as exc:  # BasisuError is a ValueError
        raise SceneError(f"{where}: cannot decode {extension} texture ({type(exc).__name__}: {exc})") from None
    if getattr(texture, "y_flipped", False) or _ktx2_orientation(blob)[1:2] == "u":
        rgba = rgba[::-1]
    return np.ascontiguousarray(rgba.reshape(texture.height, texture.width, 4))


def _ktx2_orientation(blob: bytes) -> str:
    """The ``KTXorientation`` value of a KTX2 file (``"rd"``: rows top down, ``"ru"``: bottom up), "" if
    absent. KTX 2.0 spec: the key/value data's offset and length are the header's bytes 56-63; each entry
    is a u32 length, ``key NUL value``, padded to 4 bytes."""
    if blob[:12] != _KTX2_MAGIC or len(blob) < 80:
        return ""
    offset, length = struct.unpack_from("<II", blob, 56)
    pos, end = offset, min(offset + length, len(blob))
    while pos + 4 <= end:
        (n,) = struct.unpack_from("<I", blob, pos)
        entry = blob[pos + 4:pos + 4 + n]
        key, _, value = entry.partition(b"\0")
        if key == b"KTXorientation":
            return value.rstrip(b"\0").decode("ascii", "replace")
        pos += 4 + n + (-n % 4)
    return ""


def _image_bytes(header: dict, binary: bytes, img: dict, index: int, path: Path) -> bytes:
    """An image's bytes: from its bufferView, a data: URI, or a file beside the GLB."""
    if "bufferView" in img:
        return _view_bytes(header, binary, img["bufferView"], path)
    uri = str(img.get("uri", ""))
    if uri.startswith("data:"):
        import base64

        try:
            return base64.b64decode(uri.split(",", 1)[1])
        except (IndexError, ValueError):
            raise SceneError(f"{path}: image {index} has a malformed data: URI") from None
    from urllib.parse import unquote

    f = path.parent / unquote(uri)
    if not uri or not f.is_file():
        raise SceneError(f"{path}: texture image {index} not found: {f}")
    try:
        return read_input(f, gunzip=False)
    except InputTooLarge as exc:
        raise SceneError(str(exc)) from None


def _is_basis(img: dict, blob: bytes) -> bool:
    return img.get("mimeType", "") in _BASIS_MIMES or blob[:12] == _KTX2_MAGIC or blob[:2] == _BASIS_MAGIC


def _texture_source(tex: dict, t: int, path: Path) -> tuple[object, str | None]:
    """(image index or None, the Basis extension it came through or None) of glTF texture ``t``.

    A texture's image is its Basis extension's ``source`` (either extension), else its own ``source``
    (the glTF 2.0 fallback). A texture with neither but another extension carrying a ``source``
    (``EXT_texture_webp``, ``MSFT_texture_dds``, ...) is refused: trimesh would drop it and the
    surface would render white.
    """
    extensions = tex.get("extensions") or {}
    if not isinstance(extensions, dict):
        raise SceneError(f"{path}: texture {t} has a malformed 'extensions' entry")
    for name in BASIS_EXTENSIONS:
        ext = extensions.get(name)
        if isinstance(ext, dict) and "source" in ext:
            return ext["source"], name
    if "source" in tex:
        return tex["source"], None
    others = sorted(k for k, v in extensions.items() if isinstance(v, dict) and "source" in v)
    if others:
        raise SceneError(f"{path}: texture {t} uses the {others[0]} extension, which navbench cannot decode "
                         f"(readable: PNG/JPEG images, {' and '.join(BASIS_EXTENSIONS)})")
    return None, None
def _read_scan(path: Path) -> bytes:
    """A scan file's bytes, at most the input cap (``NAVBENCH_MAX_INPUT_BYTES``, see :mod:`navbench.safeio`)."""
    try:
        return read_input(path, gunzip=False)
    except InputTooLarge as exc:
        raise SceneError(str(exc)) from None


def prepare_glb(path: Path) -> bytes | None:
    """The GLB's bytes with Basis textures decoded, or None when the file can be read as it is.

    Every image a texture uses is checked: an undecodable one raises :class:`SceneError` naming the
    file, the image and (for Basis payloads) the extension.
    """
    data = _read_scan(path)
    header, binary = read_glb(data, path)
    images = header.get("images", [])
    textures = header.get("textures", [])
    if not textures:
        return None
    from PIL import Image

    replaced: dict[int, bytes] = {}
    external: dict[int, bytes] = {}
    new_binary = bytearray(binary)
    for t, tex in enumerate(textures):
        index, extension = _texture_source(tex, t, path)
        if index is None:
            continue
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(images):
            raise SceneError(f"{path}: texture {t} refers to a missing image {index}")
        img = images[index]
        blob = _image_bytes(header, binary, img, index, path)
        if _is_basis(img, blob):
            if index not in replaced:
                token = f"{path}#{index}"
                named = extension or (GOOGLE_BASIS if img.get("mimeType") == "image/x-basis" else BASISU)
                DECODED[token] = decode_basis(blob, f"{path}: image {index}", named)
                replaced[index] = _placeholder(token)
            tex["source"] = index
            for name in BASIS_EXTENSIONS:
                (tex.get("extensions") or {}).pop(name, None)
        else:
            try:
                with Image.open(io.BytesIO(blob)) as im:
                    _check_pixels(*im.size, f"{path}: image {index}")
                    im.verify()
            except SceneError:
                raise
            except Exception as exc:  # PIL raises many types for a bad image
                raise SceneError(f"{path}: texture image {index} ({img.get('mimeType', 'unknown type')}) "
                                 f"cannot be decoded ({type(exc).__name__}: {exc})") from None
            if "bufferView" not in img:
                external[index] = blob  # trimesh reads the rewritten GLB from memory: embed it
    if not replaced:
        return None
    buffers = header.setdefault("buffers", [])
    if not buffers:
        buffers.append({"byteLength": 0})
    elif "uri" in buffers[0]:
        raise SceneError(f"{path}: Basis Universal textures in a GLB whose first buffer is an external file are "
                         f"not supported; embed the buffer")
    for index, blob in external.items():
        new_binary += b"\0" * (-len(new_binary) % 4)
        header.setdefault("bufferViews", []).append(
            {"buffer": 0, "byteOffset": len(new_binary), "byteLength": len(blob)})
        new_binary += blob
        images[index] = {"bufferView": len(header["bufferViews"]) - 1,
                         "mimeType": images[index].get("mimeType", "image/png")}
    for index, bmp in replaced.items():
        new_binary += b"\0" * (-len(new_binary) % 4)
        header.setdefault("bufferViews", []).append(
            {"buffer": 0, "byteOffset": len(new_binary), "byteLength": len(bmp)})
        new_binary += bmp
        images[index] = {"bufferView": len(header["bufferViews"]) - 1, "mimeType": "image/png"}
    header["buffers"][0]["byteLength"] = len(new_binary)
    for key in ("extensionsUsed", "extensionsRequired"):
        if key in header:
            header[key] = [e for e in header[key] if e not in BASIS_EXTENSIONS]
    return write_glb(header, bytes(new_binary))


def _placeholder(token: str) -> bytes:
    from PIL import Image, PngImagePlugin

    info = PngImagePlugin.PngInfo()
    info.add_text(_PLACEHOLDER_KEY, token)
    out = io.BytesIO()
    Image.new("RGB", (1, 1)).save(out, format="PNG", pnginfo=info)
    return out.getvalue()


def check_gltf_images(path: Path) -> None:
    """A ``.gltf`` with Basis textures cannot be rewritten in place: say so rather than render grey."""
    try:
        header = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SceneError(f"{path}: corrupt glTF JSON ({exc})") from None
    for t, tex in enumerate(header.get("textures", [])):
        for name in BASIS_EXTENSIONS:
            if name in (tex.get("extensions") or {}):
                raise SceneError(f"{path}: {name} textures are read from .glb files only; pack this "
                                 f"glTF into a .glb")
        _texture_source(tex, t, path)
    for i, img in enumerate(header.get("images", [])):
        uri = img.get("uri", "")
        if uri and not uri.startswith("data:") and not (path.parent / uri).is_file():
            raise SceneError(f"{path}: texture image {i} not found: {path.parent / uri}")


def check_obj_textures(path: Path) -> None:
    """Every ``map_Kd`` of the OBJ's material libraries must exist (trimesh would drop it silently)."""
    try:
        text = path.read_text(errors="replace")
    except OSError as exc:
        raise SceneError(f"{path}: cannot read ({exc})") from None
    for line in text.splitlines():
        if not line.startswith("mtllib"):
            continue
        mtl = path.parent / line.split(None, 1)[1].strip()
        if not mtl.is_file():
            raise SceneError(f"{path}: material library not found: {mtl}")
        for mline in mtl.read_text(errors="replace").splitlines():
            parts = mline.strip().split()
            if parts and parts[0] == "map_Kd":
                tex = mtl.parent / parts[-1]
                if not tex.is_file():
                    raise SceneError(f"{mtl}: texture not found: {tex}")


def texture_image(visual) -> np.ndarray | None:
    """(H, W, 4) uint8 base-colour texture of a trimesh TextureVisuals (factor applied), or None."""
    material = getattr(visual, "material", None)
    if material is None or getattr(visual, "uv", None) is None:
        return None
    image = getattr(material, "baseColorTexture", None)
    if image is None:
        image = getattr(material, "image", None)
    if image is None:
        return None
    token = getattr(image, "info", {}).get(_PLACEHOLDER_KEY)
    if token is not None:
        rgba = DECODED[token]
    else:
        rgba = np.asarray(image.convert("RGBA") if hasattr(image, "convert") else image, dtype=np.uint8)
    if rgba.ndim == 2:
        rgba = np.repeat(rgba[..., None], 4, axis=2)
        rgba[..., 3] = 255
    factor = getattr(material, "baseColorFactor", None)
    if factor is not None:
        f = np.asarray(factor, dtype=np.float64).reshape(-1)[:4]
        f = f / 255.0 if f.max() > 1.0 else f
        if len(f) >= 3 and not np.allclose(f[:3], 1.0):
            rgba = rgba.copy()
            rgba[..., :3] = np.clip(rgba[..., :3] * f[None, None, :3] + 0.5, 0, 255).astype(np.uint8)
    return np.ascontiguousarray(rgba)


def forget_decoded(path: Path) -> None:
    """Drop the decoded images :func:`prepare_glb` kept for ``path``."""
    for token in [t for t in DECODED if t.startswith(f"{path}#")]:
        del DECODED[token]


def sample(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(N, 4) uint8 texels at OpenGL-convention ``uv`` (nearest, repeating)."""
    h, w = image.shape[:2]
    col = np.clip(np.floor((uv[:, 0] % 1.0) * w), 0, w - 1).astype(np.int64)
    row = np.clip(np.floor((1.0 - uv[:, 1] % 1.0) * h), 0, h - 1).astype(np.int64)
    return image[row, col]
