"""Tiny randomly initialised SigLIP, Qwen2.5-VL and SAM 3 checkpoints written to local directories, shaped
like transformers' own model tests (hidden size 32, one layer), with word-level tokenizers built offline:
what benchmarks/gpu_check.py runs the real-model backends on. Needs transformers and tokenizers.

    PYTHONPATH=$PWD python benchmarks/tiny_models.py DIR     # writes DIR/siglip2, DIR/qwen_vl, DIR/sam3
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

WORDS = ["yes", "[PAD]", "[UNK]", "no", "is", "a", "red", "chair", "bed", "visible", "in", "this", "image", "?",
         "reply", "only", ":", "/", "<", ">", "-", "visibility", "user", "assistant", "system", "you", "are",
         "helpful", "."] + [str(i) for i in range(11)]
QWEN_SPECIAL = ("<|im_start|>", "<|im_end|>", "<|vision_start|>", "<|vision_end|>", "<|image_pad|>",
                "<|video_pad|>")


def tiny_tokenizer(special=()):
    import transformers
    from tokenizers import AddedToken, Tokenizer, models, pre_tokenizers

    tok = Tokenizer(models.WordLevel({w: i for i, w in enumerate(WORDS)}, unk_token="[UNK]"))
    tok.pre_tokenizer = pre_tokenizers.Whitespace()
    tok.add_special_tokens([AddedToken(s, special=True) for s in special])
    fast = transformers.PreTrainedTokenizerFast(tokenizer_object=tok, pad_token="[PAD]", unk_token="[UNK]")
    return fast, tok.get_vocab_size()


def write_siglip(d: Path) -> Path:
    import torch
    import transformers

    tokenizer, vocab = tiny_tokenizer()
    torch.manual_seed(0)
    config = transformers.SiglipConfig(
        text_config=dict(vocab_size=vocab, hidden_size=32, intermediate_size=37, num_hidden_layers=1,
                         num_attention_heads=4, max_position_embeddings=64, pad_token_id=1, bos_token_id=None,
                         eos_token_id=None),
        vision_config=dict(image_size=32, patch_size=8, hidden_size=32, intermediate_size=37, num_hidden_layers=1,
                           num_attention_heads=4))
    transformers.SiglipModel(config).save_pretrained(d)
    image_processor = getattr(transformers, "SiglipImageProcessorPil", None) or transformers.SiglipImageProcessor
    transformers.SiglipProcessor(image_processor=image_processor(size={"height": 32, "width": 32}),
                                 tokenizer=tokenizer).save_pretrained(d)
    return d


def write_qwen(d: Path) -> Path:
    import torch
    import transformers

    tokenizer, vocab = tiny_tokenizer(QWEN_SPECIAL)
    ids = {s: tokenizer.convert_tokens_to_ids(s) for s in QWEN_SPECIAL}
    torch.manual_seed(0)
    config = transformers.Qwen2_5_VLConfig(
        text_config=dict(vocab_size=vocab, hidden_size=32, intermediate_size=37, num_hidden_layers=1,
                         num_attention_heads=4, num_key_value_heads=2, max_position_embeddings=512,
                         rope_parameters={"rope_type": "default", "rope_theta": 10000.0, "mrope_section": [1, 1, 2]},
                         bos_token_id=None, eos_token_id=ids["<|im_end|>"], pad_token_id=1),
        vision_config=dict(depth=1, hidden_size=32, intermediate_size=24, num_heads=4, out_hidden_size=32,
                           patch_size=14, spatial_merge_size=2, temporal_patch_size=2, window_size=28,
                           fullatt_block_indexes=[0]),
        image_token_id=ids["<|image_pad|>"], video_token_id=ids["<|video_pad|>"],
        vision_start_token_id=ids["<|vision_start|>"], vision_end_token_id=ids["<|vision_end|>"])
    transformers.Qwen2_5_VLForConditionalGeneration(config).save_pretrained(d)
    tokenizer.save_pretrained(d)
    image_processor = getattr(transformers, "Qwen2VLImageProcessorPil", None) or transformers.Qwen2VLImageProcessor
    image_processor(min_pixels=56 * 56, max_pixels=84 * 84, patch_size=14, merge_size=2,
                    temporal_patch_size=2).save_pretrained(d)
    return d


def write_sam3(d: Path) -> Path:
    import torch
    import transformers

    tokenizer, vocab = tiny_tokenizer()
    torch.manual_seed(0)
    config = transformers.Sam3Config(
        vision_config=dict(backbone_config=dict(model_type="sam3_vit_model", hidden_size=32, intermediate_size=64,
                                                num_hidden_layers=1, num_attention_heads=4, image_size=56,
                                                patch_size=14, window_size=2, global_attn_indexes=[0],
                                                pretrain_image_size=56),
                           fpn_hidden_size=32, backbone_feature_sizes=[[16, 16], [8, 8], [4, 4]]),
        text_config=dict(vocab_size=vocab, hidden_size=32, intermediate_size=64, num_hidden_layers=1,
                         num_attention_heads=4, max_position_embeddings=32, projection_dim=32, pad_token_id=1,
                         bos_token_id=3, eos_token_id=4),
        geometry_encoder_config=dict(hidden_size=32, num_layers=1, num_attention_heads=4, intermediate_size=64),
        detr_encoder_config=dict(hidden_size=32, num_layers=1, num_attention_heads=4, intermediate_size=64),
        detr_decoder_config=dict(hidden_size=32, num_layers=1, num_queries=8, num_attention_heads=4,
                                 intermediate_size=64),
        mask_decoder_config=dict(hidden_size=32, num_upsampling_stages=2, num_attention_heads=4))
    transformers.Sam3Model(config).save_pretrained(d)
    tokenizer.save_pretrained(d)
    (d / "preprocessor_config.json").write_text(json.dumps({
        "image_processor_type": "Sam3ImageProcessor", "size": {"height": 56, "width": 56}, "resample": 2,
        "do_rescale": True, "rescale_factor": 1 / 255, "do_normalize": True,
        "image_mean": [0.5, 0.5, 0.5], "image_std": [0.5, 0.5, 0.5]}))
    return d


def write_all(root: Path) -> dict[str, Path]:
    """The three checkpoints under ``root``, as :class:`navbench.localize.benchmark.ModelDirs` fields."""
    out = {}
    for name, write in (("siglip2", write_siglip), ("qwen_vl", write_qwen), ("sam3", write_sam3)):
        (root / name).mkdir(parents=True, exist_ok=True)
        out[name] = write(root / name)
    return out


if __name__ == "__main__":
    print(write_all(Path(sys.argv[1])))
