"""Reading and writing files navbench does not control: size caps, names from data, symlink-safe writes.

- :func:`open_input` / :func:`read_input` read a file (gunzipped when it ends in ``.gz``) and stop with
  :class:`InputTooLarge` past a cap on its (decompressed) size: ``NAVBENCH_MAX_INPUT_BYTES`` (bytes,
  or with a ``K``/``M``/``G`` suffix), default 1 GiB, well above any real episode split.
- :func:`safe_name` turns an episode id, scene id or agent name into a file name component;
  :func:`child` joins it to a directory and checks the result stays inside.
- :func:`write_private` replaces a file through a fresh temporary file opened without following symlinks.
- :func:`printable` escapes control bytes so a peer's text cannot rewrite a terminal line.
"""

from __future__ import annotations

import gzip
import io
import os
import re
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

DEFAULT_MAX_INPUT_BYTES = 1 << 30
_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30}


class InputTooLarge(ValueError):
    """A file is larger (decompressed) than the input cap; the message names the file and the cap."""


def max_input_bytes() -> int:
    """The cap on one input file's decompressed size: ``NAVBENCH_MAX_INPUT_BYTES`` or 1 GiB."""
    raw = os.environ.get("NAVBENCH_MAX_INPUT_BYTES", "").strip().upper().removesuffix("B").removesuffix("I")
    if not raw:
        return DEFAULT_MAX_INPUT_BYTES
    m = re.fullmatch(r"(\d+)\s*([KMG]?)", raw)
    if not m or int(m.group(1)) <= 0:
        raise ValueError(f"NAVBENCH_MAX_INPUT_BYTES={os.environ['NAVBENCH_MAX_INPUT_BYTES']!r}: expected a "
                         f"positive size such as 2G or 500M")
    return int(m.group(1)) * _UNITS[m.group(2)]


def _size(n: int) -> str:
    for unit, div in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= div and n % div == 0:
            return f"{n // div} {unit}"
    return f"{n} bytes"


def too_large(path: str | Path, cap: int, what: str = "decompressed") -> InputTooLarge:
    return InputTooLarge(f"{path}: larger than {_size(cap)} {what} (a decompression bomb or not an input "
                         f"file? raise NAVBENCH_MAX_INPUT_BYTES to read it)")


class _Capped(io.RawIOBase):
    """A binary stream that raises :class:`InputTooLarge` once more than ``cap`` bytes were read."""

    def __init__(self, inner: BinaryIO, path: Path, cap: int, raw: BinaryIO | None = None) -> None:
        self.inner, self.path, self.cap, self.count = inner, path, cap, 0
        self.raw = raw  # the file under a GzipFile, which closing the GzipFile leaves open

    def readable(self) -> bool:
        return True

    def readinto(self, b) -> int:
        data = self.inner.read(min(len(b), self.cap + 1 - self.count) or 1)
        self.count += len(data)
        if self.count > self.cap:
            raise too_large(self.path, self.cap)
        b[:len(data)] = data
        return len(data)

    def close(self) -> None:
        self.inner.close()
        if self.raw is not None:
            self.raw.close()
        super().close()


def open_input(path: str | Path, cap: int | None = None, gunzip: bool = True) -> BinaryIO:
    """``path`` opened for reading in binary (gunzipped when it ends in ``.gz`` and ``gunzip``), raising
    :class:`InputTooLarge` as soon as more than ``cap`` (default :func:`max_input_bytes`) bytes come out."""
    path = Path(path)
    cap = max_input_bytes() if cap is None else cap
    fh: BinaryIO = open(path, "rb")
    raw = None
    if gunzip and path.suffix == ".gz":
        raw, fh = fh, gzip.GzipFile(fileobj=fh, mode="rb")  # type: ignore[assignment]
    elif os.fstat(fh.fileno()).st_size > cap:
        fh.close()
        raise too_large(path, cap, "on disk")
    return io.BufferedReader(_Capped(fh, path, cap, raw), 1 << 20)  # type: ignore[return-value]


def read_input(path: str | Path, cap: int | None = None, gunzip: bool = True) -> bytes:
    """The whole of ``path`` (gunzipped when ``.gz``), at most ``cap`` bytes, else :class:`InputTooLarge`."""
    with open_input(path, cap, gunzip) as fh:
        return fh.read()


# ------------------------------------------------------------------------------------------- names
_UNSAFE = re.compile(r"[^A-Za-z0-9._+=@,-]+")
_RESERVED = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(10)), *(f"LPT{i}" for i in range(10))}


def safe_name(text: object, max_len: int = 100) -> str:
    """A file name component for ``text``: unchanged when it is already a plain name (letters, digits,
    ``._+=@,-``, not hidden, at most ``max_len`` characters); otherwise the unsafe runs become ``_`` and
    a checksum of ``text`` is appended, so ``"a/b"`` and ``"a_b"`` stay apart. Never empty, ``.`` or
    ``..``; the same text always gets the same name."""
    text = str(text)
    name = _UNSAFE.sub("_", text).lstrip(".") or "_"
    if name.split(".")[0].upper() in _RESERVED:
        name = "_" + name
    if name == text and len(name) <= max_len:
        return name
    return f"{name[:max_len - 9]}-{_crc(text):08x}"


def _crc(text: str) -> int:
    import zlib
    return zlib.crc32(text.encode("utf-8", "surrogatepass"))


class UniqueNames:
    """:func:`safe_name` for each id given, told apart by a counter in the rare case two still collide
    (also case-insensitively); the same id always gets the same name."""

    def __init__(self) -> None:
        self.by_id: dict[str, str] = {}
        self.taken: set[str] = set()

    def __call__(self, ident: object, suffix: str = "") -> str:
        key = str(ident)
        if key not in self.by_id:
            name, k = safe_name(key), 0
            while (name if k == 0 else f"{name}-{k}").lower() in self.taken:
                k += 1
            name = name if k == 0 else f"{name}-{k}"
            self.taken.add(name.lower())
            self.by_id[key] = name
        return self.by_id[key] + suffix


def child(directory: str | Path, name: str) -> Path:
    """``directory / name`` for a name made by :func:`safe_name`; ValueError if it would leave ``directory``."""
    directory = Path(directory)
    path = directory / name
    if name in ("", ".", "..") or "/" in name or "\\" in name or "\0" in name or \
            os.path.dirname(os.path.normpath(path)) != os.path.normpath(directory):
        raise ValueError(f"{directory}: refusing to write {name!r}, which is not a plain file name")
    return path


def own_dir(path: str | Path) -> Path:
    """``path`` as a real directory (created when missing): ValueError if it is a symlink, which could
    send what is written there anywhere."""
    path = Path(path)
    if path.is_symlink():
        raise ValueError(f"{path}: is a symlink; refusing to write through it (remove it to go on)")
    path.mkdir(parents=True, exist_ok=True)
    return path


def unlink_if_symlink(path: Path) -> Path:
    """Remove ``path`` if it is a symlink (a writer would follow it); the path is then written afresh."""
    if path.is_symlink():
        path.unlink()
    return path


# ------------------------------------------------------------------------------------------ writes
def write_private(path: str | Path, data: bytes | str | Callable[[BinaryIO], object], fsync: bool = True) -> None:
    """Replace ``path`` by ``data`` (or what ``data(file)`` writes) whole, through a temporary file created
    new (``O_EXCL``, never following a symlink) beside it, then renamed over it: a planted ``.name.tmp``
    symlink redirects nothing, and a crash leaves the old file or the new one. Raises OSError."""
    path = Path(path)
    if isinstance(data, str):
        data = data.encode()
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp")
    fd = os.open(tmp, flags, 0o644)
    try:
        with os.fdopen(fd, "wb") as fh:
            data(fh) if callable(data) else fh.write(data)
            fh.flush()
            if fsync:
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


# ------------------------------------------------------------------------------------------- text
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def printable(text: str, limit: int = 200) -> str:
    """``text`` with control characters (and bidi overrides) escaped as ``\\xNN``/``\\uNNNN``, cut
    to ``limit`` characters: safe to print on one terminal line."""
    out = _CONTROL.sub(lambda m: m.group(0).encode("unicode_escape").decode("ascii"), text)
    return out if len(out) <= limit else out[:limit - 3] + "..."
