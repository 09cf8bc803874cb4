"""Qwen2.5-VL re-ranker (reference: Qwen/Qwen2.5-VL-7B-Instruct) from a local directory.

``Qwen2_5_VLProcessor`` cannot be constructed without torchvision (its video-processor slot is checked
against a class that needs it, and torchvision does not install beside our torch wheel), so this
backend composes the processor's two parts itself: the checkpoint's image processor (transformers
falls back to its PIL implementation) and its tokenizer. The text is the exact string Qwen's chat
template renders for one user turn holding one image and the prompt, with the image placeholder
repeated once per merged vision patch, as the processor would do. Decoding is greedy.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from navbench.device import torch_dtype
from navbench.localize.backends.base import BackendError, check_image, check_model_dir, import_transformers
from navbench.localize.vlm import CAPTION_PROMPT, CAPTION_TOKENS, format_prompt, parse_reply

IMAGE_TOKEN = "<|image_pad|>"
# Image queries: the re-ranker and segmenter are prompted with text, so the goal image is captioned first.
CHAT_TEMPLATE = (
    "<|im_start|>system\nYou are a helpful assistant.<|im_end|>\n"
    "<|im_start|>user\n<|vision_start|>{image}<|vision_end|>{prompt}<|im_end|>\n"
    "<|im_start|>assistant\n"
)


class QwenVLReranker:
    """:class:`~navbench.localize.backends.base.Reranker` asking Qwen2.5-VL the reference prompt; also
    the captioner that turns an image query into a text prompt (:meth:`describe`)."""

    modality = "rgb"

    def __init__(self, model_dir: str | Path, device: str = "cpu", max_new_tokens: int = 8,
                 caption_tokens: int = CAPTION_TOKENS, precision: str = "fp32") -> None:
        transformers = import_transformers()
        import torch

        path = check_model_dir(model_dir)
        self.model_dir = path
        self.device = torch.device(device)
        self.dtype = torch_dtype(precision)
        self.max_new_tokens = max_new_tokens
        self.caption_tokens = caption_tokens
        model = transformers.Qwen2_5_VLForConditionalGeneration.from_pretrained(path)
        self.model = model.to(self.device, self.dtype).eval()
        self.tokenizer = transformers.AutoTokenizer.from_pretrained(path)
        self.image_processor = transformers.AutoImageProcessor.from_pretrained(path)
        image_token_id = self.tokenizer.convert_tokens_to_ids(IMAGE_TOKEN)
        if image_token_id != self.model.config.image_token_id:
            raise BackendError(f"{path}: tokenizer maps {IMAGE_TOKEN} to {image_token_id}, the model expects "
                               f"{self.model.config.image_token_id}")
        self._torch = torch

    def reply(self, image: np.ndarray, query: str) -> str:
        """The model's raw answer to the reference prompt about ``query`` in ``image``."""
        return self.generate(image, format_prompt(query), self.max_new_tokens)

    def describe(self, image: np.ndarray) -> str:
        """Captioner for image queries: a short name of the object in the centre of ``image``."""
        return self.generate(image, CAPTION_PROMPT, self.caption_tokens).strip().rstrip(".")

    def generate(self, image: np.ndarray, prompt: str, max_new_tokens: int) -> str:
        """Greedy answer to ``prompt`` about ``image``."""
        vision = self.image_processor(images=[check_image(image)], return_tensors="pt")
        grid = vision["image_grid_thw"]
        n_tokens = int(grid[0].prod()) // int(self.image_processor.merge_size) ** 2
        text = CHAT_TEMPLATE.format(image=IMAGE_TOKEN * n_tokens, prompt=prompt)
        tokens = self.tokenizer(text, return_tensors="pt")
        with self._torch.inference_mode():
            out = self.model.generate(
                input_ids=tokens["input_ids"].to(self.device),
                attention_mask=tokens["attention_mask"].to(self.device),
                pixel_values=vision["pixel_values"].to(self.device, self.dtype),
                image_grid_thw=grid.to(self.device),
                max_new_tokens=max_new_tokens,
                do_sample=False,
            )
        return self.tokenizer.decode(out[0, tokens["input_ids"].shape[1]:], skip_special_tokens=True)

    def score(self, image: np.ndarray, query: str) -> tuple[bool, float]:
        return parse_reply(self.reply(image, query))
