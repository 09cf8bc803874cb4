"""SAM 3 text-prompted segmenter (reference: facebook/sam3) from a local directory.

transformers' ``Sam3ImageProcessor`` (and with it ``Sam3Processor`` and
``post_process_instance_segmentation``) imports torchvision, which does not install beside our torch
wheel. So this backend reproduces the processor's input side from the checkpoint's
``preprocessor_config.json`` (resize to the model's square input, ignoring aspect ratio; rescale;
normalise) and tokenises the prompt like ``Sam3Processor`` (padded to 32 tokens). On the output side it
scores each query as sigmoid(pred_logits) * sigmoid(presence_logits), takes the best one, and
upsamples that query's mask logits to the image and thresholds them.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from navbench.device import torch_dtype
from navbench.localize.backends.base import BackendError, check_image, check_model_dir, import_transformers

TEXT_MAX_LENGTH = 32  # what Sam3Processor pads prompts to
_CV2_RESAMPLE = {0: cv2.INTER_NEAREST, 1: cv2.INTER_LANCZOS4, 2: cv2.INTER_LINEAR, 3: cv2.INTER_CUBIC}  # PIL ids


class Sam3Segmenter:
    """:class:`~navbench.localize.backends.base.Segmenter`: the highest-scoring SAM 3 instance mask."""

    modality = "rgb"

    def __init__(self, model_dir: str | Path, device: str = "cpu", score_threshold: float = 0.3,
                 mask_threshold: float = 0.5, precision: str = "fp32") -> None:
        transformers = import_transformers()
        import torch

        path = check_model_dir(model_dir)
        self.model_dir = path
        self.device = torch.device(device)
        self.dtype = torch_dtype(precision)
        # transformers' own post-processing defaults: 0.3 on the instance score, 0.5 on mask probability.
        self.score_threshold = score_threshold
        self.mask_threshold = mask_threshold
        self.model = transformers.Sam3Model.from_pretrained(path).to(self.device, self.dtype).eval()
        self.tokenizer = transformers.AutoTokenizer.from_pretrained(path)
        self._load_preprocessing(path)
        self._torch = torch

    def _load_preprocessing(self, path: Path) -> None:
        size = int(self.model.config.vision_config.backbone_config.image_size)
        cfg = {"size": {"height": size, "width": size}, "image_mean": [0.5, 0.5, 0.5], "image_std": [0.5, 0.5, 0.5],
               "rescale_factor": 1 / 255, "resample": 2, "do_normalize": True, "do_rescale": True}
        pre = path / "preprocessor_config.json"
        if pre.is_file():
            try:
                cfg.update(json.loads(pre.read_text()))
            except json.JSONDecodeError as e:
                raise BackendError(f"unreadable {pre}: {e}") from None
        self.input_size = (int(cfg["size"]["width"]), int(cfg["size"]["height"]))
        self.interpolation = _CV2_RESAMPLE.get(int(cfg["resample"]), cv2.INTER_LINEAR)
        self.rescale = float(cfg["rescale_factor"]) if cfg["do_rescale"] else 1.0
        self.mean = np.asarray(cfg["image_mean"], np.float32) if cfg["do_normalize"] else np.zeros(3, np.float32)
        self.std = np.asarray(cfg["image_std"], np.float32) if cfg["do_normalize"] else np.ones(3, np.float32)

    def pixel_values(self, image: np.ndarray) -> torch.Tensor:  # noqa: F821 - torch is imported lazily
        """The model input for one RGB image: (1, 3, h, w) float32."""
        resized = cv2.resize(check_image(image), self.input_size, interpolation=self.interpolation)
        x = (resized.astype(np.float32) * self.rescale - self.mean) / self.std
        return self._torch.from_numpy(np.ascontiguousarray(x.transpose(2, 0, 1)[None]))

    def segment(self, image: np.ndarray, query: str) -> tuple[np.ndarray | None, float]:
        torch = self._torch
        image = check_image(image)
        h, w = image.shape[:2]
        text = self.tokenizer([query], padding="max_length", max_length=TEXT_MAX_LENGTH, truncation=True,
                              return_tensors="pt")
        with torch.inference_mode():
            out = self.model(pixel_values=self.pixel_values(image).to(self.device, self.dtype),
                             input_ids=text["input_ids"].to(self.device),
                             attention_mask=text["attention_mask"].to(self.device))
            scores = out.pred_logits[0].float().sigmoid()
            if out.presence_logits is not None:
                scores = scores * out.presence_logits[0].float().sigmoid()
            best = int(scores.argmax())
            score = float(scores[best])
            if score < self.score_threshold:
                return None, score
            logits = torch.nn.functional.interpolate(out.pred_masks[:, best:best + 1].float(), size=(h, w),
                                                     mode="bilinear", align_corners=False)
            mask = (logits[0, 0].sigmoid() > self.mask_threshold).cpu().numpy()
        return (mask if mask.any() else None), score
