"""Perception backends for the localiser. Protocols live in :mod:`.base`; the real backends
(``Siglip2Encoder``, ``QwenVLReranker``, ``OpenAIReranker``, ``Sam3Segmenter``) import transformers only
when constructed, so importing this package is cheap. The oracle backends (:mod:`.oracle`) work from
the renderer's instance ids, with optional simulated noise."""

from navbench.localize.backends.base import (
    MODELS_EXTRA_HINT,
    BackendError,
    Encoder,
    MissingExtraError,
    Reranker,
    Segmenter,
)
from navbench.localize.backends.openai_compat import OpenAIReranker
from navbench.localize.backends.oracle import (
    NOISE_PROFILES,
    NoiseProfile,
    OracleCaptioner,
    OracleDepthNoise,
    OracleEncoder,
    OracleReranker,
    OracleSegmenter,
    noise_profile,
)
from navbench.localize.backends.qwen_vl import QwenVLReranker
from navbench.localize.backends.sam3 import Sam3Segmenter
from navbench.localize.backends.siglip2 import Siglip2Encoder

__all__ = [
    "MODELS_EXTRA_HINT",
    "NOISE_PROFILES",
    "BackendError",
    "Encoder",
    "MissingExtraError",
    "NoiseProfile",
    "OpenAIReranker",
    "OracleCaptioner",
    "OracleDepthNoise",
    "OracleEncoder",
    "OracleReranker",
    "OracleSegmenter",
    "QwenVLReranker",
    "Reranker",
    "Sam3Segmenter",
    "Segmenter",
    "Siglip2Encoder",
    "noise_profile",
]
