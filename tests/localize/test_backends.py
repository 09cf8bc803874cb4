"""Each real perception backend run end to end on a tiny randomly initialised model saved to disk.

The checkpoints are ``benchmarks/tiny_models.py``'s (the GPU check runs on the same ones): configs shaped like
transformers' own model tests (hidden size 32, one layer), word-level tokenizers built offline from a small
vocabulary (tokenizers cannot be downloaded), image processors built offline (SAM 3's needs torchvision, so its
preprocessor_config.json is written directly, which is all the backend reads).
"""

import sys
from pathlib import Path

import numpy as np
import pytest

transformers = pytest.importorskip("transformers", reason="the models extra (transformers) is not installed")
torch = pytest.importorskip("torch")

from navbench.localize.backends import (  # noqa: E402
    MODELS_EXTRA_HINT,
    BackendError,
    Encoder,
    MissingExtraError,
    QwenVLReranker,
    Reranker,
    Sam3Segmenter,
    Segmenter,
    Siglip2Encoder,
)

sys.path.insert(0, str(Path(__file__).parents[2] / "benchmarks"))
from tiny_models import write_qwen, write_sam3, write_siglip  # noqa: E402


def has(name):
    return hasattr(transformers, name)


def images(rng):
    return [rng.integers(0, 256, size=shape, dtype=np.uint8) for shape in ((40, 60, 3), (50, 50, 3))]


# ------------------------------------------------------------------ SigLIP2
@pytest.fixture(scope="module")
def siglip_dir(tmp_path_factory):
    if not (has("SiglipModel") and has("SiglipImageProcessorPil")):
        pytest.skip("this transformers has no SiglipModel/SiglipImageProcessorPil")
    return write_siglip(tmp_path_factory.mktemp("siglip"))


def test_siglip2_encoder_matches_the_model_and_pads_text_to_64(siglip_dir):
    enc = Siglip2Encoder(siglip_dir, batch_size=1)
    assert isinstance(enc, Encoder)
    ims = images(np.random.default_rng(0))
    emb = enc.encode_images(ims)
    assert emb.shape == (2, 32) and emb.dtype == np.float32
    assert np.allclose(np.linalg.norm(emb, axis=1), 1.0, atol=1e-5)
    model = transformers.AutoModel.from_pretrained(siglip_dir).eval()
    proc = transformers.AutoProcessor.from_pretrained(siglip_dir)
    with torch.no_grad():
        out = model.get_image_features(**proc(images=ims, return_tensors="pt"))
        ref = getattr(out, "pooler_output", out).numpy()
    assert np.allclose(emb, ref / np.linalg.norm(ref, axis=1, keepdims=True), atol=1e-5)
    assert np.allclose(Siglip2Encoder(siglip_dir, batch_size=16).encode_images(ims), emb, atol=1e-5)

    text = enc.encode_text(["red chair", "bed"])
    assert text.shape == (2, 32) and np.allclose(np.linalg.norm(text, axis=1), 1.0, atol=1e-5)

    def ref_text(**pad):
        with torch.no_grad():
            o = model.get_text_features(**proc(text=["red chair"], return_tensors="pt", **pad))
        v = getattr(o, "pooler_output", o).numpy()[0]
        return v / np.linalg.norm(v)
    assert np.allclose(text[0], ref_text(padding="max_length", max_length=64), atol=1e-5)
    assert not np.allclose(text[0], ref_text(), atol=1e-3)  # unpadded text embeds differently
    with pytest.raises(BackendError, match="HxWx3 uint8"):
        enc.encode_images([np.zeros((4, 4), np.uint8)])


def test_missing_model_dir_and_missing_extra(tmp_path, monkeypatch):
    with pytest.raises(BackendError, match=f"model directory not found: {tmp_path / 'nope'}"):
        Siglip2Encoder(tmp_path / "nope")
    with pytest.raises(BackendError, match="lacks config.json"):
        Sam3Segmenter(tmp_path)
    monkeypatch.setitem(sys.modules, "transformers", None)  # makes `import transformers` fail
    for backend in (Siglip2Encoder, QwenVLReranker, Sam3Segmenter):
        with pytest.raises(MissingExtraError, match="install the models extra") as info:
            backend(tmp_path)
        assert isinstance(info.value, ImportError) and MODELS_EXTRA_HINT in str(info.value)


# ------------------------------------------------------------------ Qwen2.5-VL
@pytest.fixture(scope="module")
def qwen_dir(tmp_path_factory):
    if not (has("Qwen2_5_VLForConditionalGeneration") and has("Qwen2VLImageProcessorPil")):
        pytest.skip("this transformers has no Qwen2_5_VLForConditionalGeneration/Qwen2VLImageProcessorPil")
    return write_qwen(tmp_path_factory.mktemp("qwen"))


def test_qwen_vl_reranker_generates_and_parses(qwen_dir):
    rr = QwenVLReranker(qwen_dir, max_new_tokens=4)
    assert isinstance(rr, Reranker)
    ims = images(np.random.default_rng(1))
    # Two images of different sizes need different numbers of image tokens; a wrong count would make
    # the model refuse the input.
    replies = [rr.reply(im, "red chair") for im in ims]
    assert all(isinstance(r, str) for r in replies)
    assert rr.reply(ims[0], "red chair") == replies[0]  # greedy: deterministic
    yes, vis = rr.score(ims[1], "red chair")
    assert isinstance(yes, bool) and 0.0 <= vis <= 1.0
    # Rig the output layer so every logit ties: greedy decoding then emits token 0 ("yes") each step.
    with torch.no_grad():
        rr.model.lm_head.weight.zero_()
    assert rr.reply(ims[0], "red chair").split() == ["yes"] * 4
    assert rr.score(ims[0], "red chair") == (True, 0.5)
    # The same model captions image queries, with its own token budget.
    rr.caption_tokens = 3
    assert rr.describe(ims[0]).split() == ["yes"] * 3


# ------------------------------------------------------------------ SAM 3
@pytest.fixture(scope="module")
def sam3_dir(tmp_path_factory):
    if not has("Sam3Model"):
        pytest.skip("this transformers has no Sam3Model")
    return write_sam3(tmp_path_factory.mktemp("sam3"))


def test_sam3_segmenter_real_model_path(sam3_dir):
    seg = Sam3Segmenter(sam3_dir, score_threshold=0.0)
    assert isinstance(seg, Segmenter)
    im = images(np.random.default_rng(2))[0]
    x = seg.pixel_values(np.full((40, 60, 3), 255, np.uint8))
    assert tuple(x.shape) == (1, 3, 56, 56) and torch.allclose(x, torch.ones_like(x))
    mask, score = seg.segment(im, "red chair")
    assert 0.0 <= score <= 1.0
    assert mask is None or (mask.shape == (40, 60) and mask.dtype == bool)
    assert Sam3Segmenter(sam3_dir, score_threshold=1.01).segment(im, "red chair") == (None, pytest.approx(score))


def test_sam3_postprocessing_picks_best_query_and_upsamples(sam3_dir):
    seg = Sam3Segmenter(sam3_dir, score_threshold=0.3)
    low = torch.full((1, 3, 16, 16), -10.0)
    low[0, 1, 4:8, 8:12] = 10.0  # query 1: a square in rows 1/4..1/2, columns 1/2..3/4
    low[0, 0] = 10.0  # query 0 covers everything but scores low

    class Stub:
        def __call__(self, **inputs):
            assert inputs["input_ids"].shape == (1, 32)
            return transformers.modeling_outputs.ModelOutput(
                pred_logits=torch.tensor([[-4.0, 3.0, 0.0]]), presence_logits=torch.tensor([[2.0]]), pred_masks=low)

    seg.model = Stub()
    mask, score = seg.segment(np.zeros((80, 120, 3), np.uint8), "red chair")
    sig = lambda v: 1 / (1 + np.exp(-v))  # noqa: E731
    assert score == pytest.approx(sig(3.0) * sig(2.0), rel=1e-5)
    rows, cols = np.nonzero(mask)
    assert mask.shape == (80, 120)
    assert abs(rows.min() - 20) <= 1 and abs(rows.max() - 39) <= 1
    assert abs(cols.min() - 60) <= 1 and abs(cols.max() - 89) <= 1
    seg.score_threshold = 0.9  # best score 0.84 < 0.9: nothing found
    assert seg.segment(np.zeros((80, 120, 3), np.uint8), "red chair")[0] is None


# ------------------------------------------------------------------ device, precision, loaded once
def test_real_models_load_once_per_process_at_the_precision_asked(siglip_dir, qwen_dir, sam3_dir):
    from navbench.agents.registry import loads_models
    from navbench.localize.backends.oracle import NoiseProfile
    from navbench.localize.benchmark import ModelDirs, _load_models, model_perception

    models = ModelDirs(siglip2=siglip_dir, qwen_vl=qwen_dir, sam3=sam3_dir, device="cpu", precision="bf16")
    first = model_perception(None, NoiseProfile(), models)
    again = model_perception(None, NoiseProfile(), models)  # another scene's stack: the same models
    assert first.encoder is again.encoder and first.reranker is again.reranker is again.captioner
    assert first.segmenter is again.segmenter
    for backend in (first.encoder, first.reranker, first.segmenter):
        assert next(backend.model.parameters()).dtype == torch.bfloat16 and backend.device.type == "cpu"
    ims = images(np.random.default_rng(3))
    emb = first.encoder.encode_images(ims)
    assert emb.dtype == np.float32 and np.allclose(np.linalg.norm(emb, axis=1), 1.0, atol=1e-5)
    full = Siglip2Encoder(siglip_dir).encode_images(ims)
    assert np.all(np.sum(emb * full, axis=1) > 0.98)  # bf16 weights: close to fp32, not equal
    assert isinstance(first.reranker.reply(ims[0], "red chair"), str)
    mask, score = first.segmenter.segment(ims[0], "red chair")
    assert 0.0 <= score <= 1.0
    _load_models.cache_clear()
    assert loads_models("memory", {"perception": "siglip2+qwen2.5-vl+sam3"})
    assert not loads_models("memory", {}) and not loads_models("pointnav", {"perception": "x"})


def test_checkpoint_parameters_reads_safetensors_headers_only(tmp_path):
    import json
    import struct

    from navbench.localize.backends.base import checkpoint_parameters

    def write(path, tensors):
        header = json.dumps({"__metadata__": {"format": "pt"}, **{
            k: {"dtype": "BF16", "shape": s, "data_offsets": [0, 0]} for k, s in tensors.items()}}).encode()
        path.write_bytes(struct.pack("<Q", len(header)) + header)  # no weights: they are never read

    write(tmp_path / "model-00001-of-00002.safetensors", {"a": [1000, 64], "b": [64]})
    write(tmp_path / "model-00002-of-00002.safetensors", {"c": [3, 3, 8, 8]})
    assert checkpoint_parameters(tmp_path) == 1000 * 64 + 64 + 576
    (tmp_path / "model-00002-of-00002.safetensors").write_bytes(b"\xff" * 8 + b"{}")
    with pytest.raises(BackendError, match="model-00002-of-00002.safetensors: not a safetensors file"):
        checkpoint_parameters(tmp_path)
    with pytest.raises(BackendError, match="no \\*.safetensors"):
        checkpoint_parameters(tmp_path / "..")
