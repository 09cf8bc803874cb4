"""Scans from the internet: a texture whose decoded size is a bomb, and files past the input cap, are one
line naming the file, refused before anything is decoded."""

from __future__ import annotations

import struct
import sys
import zlib

import pytest

sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
import scanfix as F  # noqa: E402

from navbench.scene.asset import SceneError, load_scene  # noqa: E402


def _png_header_only(width: int, height: int) -> bytes:
    """A PNG that declares ``width`` x ``height`` 1-bit pixels (a few hundred bytes; never decoded)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    ihdr = struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + \
        chunk(b"IEND", b"")


def test_a_texture_bomb_is_refused_before_decoding(tmp_path):
    glb = F.write_glb(tmp_path / "bomb.glb", _png_header_only(9000, 9000), "image/png")
    with pytest.raises(SceneError, match=r"bomb\.glb: image 0: texture of 9000 x 9000 pixels"):
        load_scene(glb)


def test_a_scan_past_the_input_cap_is_one_line(tmp_path, monkeypatch):
    glb = F.write_png_glb(tmp_path / "big.glb", F.checkerboard())
    monkeypatch.setenv("NAVBENCH_MAX_INPUT_BYTES", "1K")
    with pytest.raises(SceneError, match=r"big\.glb: larger than 1 KiB"):
        load_scene(glb)
