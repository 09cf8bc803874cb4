"""SigLIP2 retrieval encoder (reference: google/siglip2-so400m-patch14-384) from a local directory.

The fixed-resolution SigLIP2 checkpoints load as ``SiglipModel`` through ``AutoModel``; their text
tower was trained on text padded to 64 tokens, so queries are padded to ``max_length=64`` (shorter
padding changes the embeddings). ``get_image_features``/``get_text_features`` return a tensor in
transformers 4.x and an output object (``.pooler_output``) in 5.x; both are accepted.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from navbench.device import torch_dtype
from navbench.localize.backends.base import BackendError, check_image, check_model_dir, import_transformers
from navbench.memory.index import l2_normalize


def _features(output) -> torch.Tensor:  # noqa: F821 - torch is imported lazily
    return output if hasattr(output, "shape") else output.pooler_output


class Siglip2Encoder:
    """:class:`~navbench.localize.backends.base.Encoder` over a SigLIP/SigLIP2 checkpoint directory."""

    modality = "rgb"

    def __init__(self, model_dir: str | Path, device: str = "cpu", batch_size: int = 16,
                 text_max_length: int = 64, precision: str = "fp32") -> None:
        transformers = import_transformers()
        import torch

        path = check_model_dir(model_dir)
        self.model_dir = path
        self.device = torch.device(device)
        self.dtype = torch_dtype(precision)
        self.batch_size = batch_size
        self.text_max_length = text_max_length
        self.model = transformers.AutoModel.from_pretrained(path).to(self.device, self.dtype).eval()
        self.processor = transformers.AutoProcessor.from_pretrained(path)
        self._torch = torch

    @property
    def name(self) -> str:
        """Embedding-space id recorded with a memory's index (the checkpoint directory's name)."""
        return f"siglip2:{self.model_dir.name}"

    def encode_images(self, images: Sequence[np.ndarray]) -> np.ndarray:
        out = []
        for start in range(0, len(images), self.batch_size):
            batch = [check_image(im) for im in images[start:start + self.batch_size]]
            # BatchFeature.to casts floating tensors only (the pixels), never token ids
            inputs = self.processor(images=batch, return_tensors="pt").to(self.device).to(self.dtype)
            with self._torch.inference_mode():
                out.append(_features(self.model.get_image_features(**inputs)).float().cpu().numpy())
        return self._finish(out)

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        out = []
        for start in range(0, len(texts), self.batch_size):
            batch = list(texts[start:start + self.batch_size])
            inputs = self.processor(text=batch, padding="max_length", max_length=self.text_max_length,
                                    truncation=True, return_tensors="pt").to(self.device)
            with self._torch.inference_mode():
                out.append(_features(self.model.get_text_features(**inputs)).float().cpu().numpy())
        return self._finish(out)

    @staticmethod
    def _finish(chunks: list[np.ndarray]) -> np.ndarray:
        if not chunks:
            raise BackendError("nothing to encode: the input list is empty")
        return l2_normalize(np.concatenate(chunks), "SigLIP2 embedding")
