"""Perception backend protocols: one small interface per role in the localisation pipeline.

* :class:`Encoder` embeds keyframes and queries into one space for retrieval (SigLIP2);
* :class:`Reranker` answers "is the target visible here, and how well" for one view (a VLM);
* :class:`Segmenter` returns the target's mask in one view (SAM 3).

Images are H x W x 3 uint8 RGB numpy arrays throughout. Real backends import ``transformers`` lazily
(in their constructors), so ``import navbench`` never needs the ``models`` extra; oracle backends
(:mod:`.oracle`) implement the same protocols from the renderer's instance ids.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

MODELS_EXTRA_HINT = "install the models extra: pip install 'navbench[models]'"


@runtime_checkable
class Encoder(Protocol):
    def encode_images(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """(N, D) float32, L2-normalised."""
        ...

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """(N, D) float32, L2-normalised, in the image embedding space."""
        ...


@runtime_checkable
class Reranker(Protocol):
    def score(self, image: np.ndarray, query: str) -> tuple[bool, float]:
        """(target visible?, visibility in [0, 1])."""
        ...


@runtime_checkable
class Segmenter(Protocol):
    def segment(self, image: np.ndarray, query: str) -> tuple[np.ndarray | None, float]:
        """(H x W bool mask of the best instance, or None if nothing was found; its score)."""
        ...


class BackendError(ValueError):
    """A backend cannot be built or used (missing model directory, bad reply); names the path or value."""


class MissingExtraError(ImportError):
    """The optional ``models`` dependencies are not installed."""


def import_transformers():
    """The ``transformers`` module, or :class:`MissingExtraError` with the install hint."""
    try:
        import transformers
    except ImportError as e:
        raise MissingExtraError(f"{MODELS_EXTRA_HINT} ({e})") from None
    return transformers


def check_model_dir(model_dir: str | Path, required: Sequence[str] = ("config.json",)) -> Path:
    """``model_dir`` as a Path, or :class:`BackendError` naming what is missing (models load from disk only)."""
    path = Path(model_dir).expanduser()
    if not path.is_dir():
        raise BackendError(f"model directory not found: {path}")
    missing = [name for name in required if not (path / name).is_file()]
    if missing:
        raise BackendError(f"model directory {path} lacks {', '.join(missing)}")
    return path


_MAX_HEADER = 100 << 20  # bytes of a safetensors header read at most


def checkpoint_parameters(model_dir: str | Path) -> int:
    """How many weights the ``*.safetensors`` files of ``model_dir`` hold, from their headers alone (each
    file's first 8 bytes give its JSON header's length, the header each tensor's shape); nothing is
    unpickled and no weight is read. A BackendError naming the file for one that is not safetensors."""
    import json
    import math
    import struct

    path = check_model_dir(model_dir, ())
    files = sorted(path.glob("*.safetensors"))
    if not files:
        raise BackendError(f"{path}: no *.safetensors files")
    total = 0
    for f in files:
        try:
            with open(f, "rb") as fh:
                (n,) = struct.unpack("<Q", fh.read(8))
                if n > _MAX_HEADER:
                    raise ValueError(f"a {n}-byte header")
                header = json.loads(fh.read(n))
            total += sum(math.prod(t["shape"]) for k, t in header.items() if k != "__metadata__")
        except (OSError, ValueError, KeyError, TypeError, struct.error, RecursionError) as exc:
            raise BackendError(f"{f}: not a safetensors file ({type(exc).__name__}: {exc})"[:300]) from None
    return int(total)


def check_image(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise BackendError(f"images must be HxWx3 uint8 RGB, got shape {image.shape} dtype {image.dtype}")
    return image
