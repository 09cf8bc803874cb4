"""The GOAT-style localisation benchmark: SR@K per query type over a split, with memory cost and latency.

A subtask succeeds when any of the top-K predicted goal centres lies within ``radius`` (1.5 m) of any
ground-truth position in the xz plane; the reported ``sr`` is the mean of the per-type rates (GOAT's
average), so a type with more subtasks does not weigh more.

Perception is chosen by name from :data:`PERCEPTION`: each entry builds a :class:`Perception` for one
scene from the scene's annotations (the oracle needs them), a :class:`NoiseProfile` and the local model
directories (:class:`ModelDirs`; real models are never downloaded).

    navbench localize --split goat_val --perception oracle --noise none [--no-fusion] --out DIR
    navbench localize --episodes val_seen.json.gz --scene-dir data/scene_datasets   # a GOAT-Bench file

A GOAT-Bench episode file (:mod:`navbench.localize.goatbench`) is scored the same way; there oracle
perception is told each query's instances from the file's own goals
(:func:`~navbench.localize.backends.oracle.teach`), since its categories and descriptions are open
vocabulary.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from navbench.localize.backends.base import BackendError
from navbench.localize.backends.oracle import (
    NoiseProfile,
    OracleCaptioner,
    OracleDepthNoise,
    OracleEncoder,
    OracleReranker,
    OracleSegmenter,
    noise_profile,
    teach,
)
from navbench.localize.goat import GOAT_DIR, load_goat_split, split_path
from navbench.localize.pipeline import (
    QUERY_TYPES,
    Localizer,
    LocalizerConfig,
    Perception,
)
from navbench.loop_progress import progress
from navbench.memory.prescan import PrescanConfig, load_or_build_memory
from navbench.paths import SCENES_DIR
from navbench.scene.asset import SceneAsset, load_scene

SUCCESS_RADIUS = 1.5  # metres, xz plane
# The benchmark's memory: the agent's camera, stored at 160 x 120 (the paper's storage-saving setting).
BENCHMARK_PRESCAN = PrescanConfig(store_resolution=(160, 120))


@dataclass(frozen=True)
class ModelDirs:
    """The real perception stack: its local checkpoint directories, the device the models run on
    (resolved: ``"cpu"`` or ``"cuda:N"``) and their precision (``fp32``, ``bf16``, ``fp16``)."""

    siglip2: Path | None = None
    qwen_vl: Path | str | None = None  # a directory, or an OpenAI-compatible server's URL (served_vlm)
    sam3: Path | None = None
    device: str = "cpu"
    precision: str = "fp32"


def served_vlm(value: object) -> bool:
    """Whether a ``qwen_vl`` value is the URL of an OpenAI-compatible server (``http://HOST:PORT/v1``)."""
    return isinstance(value, str) and value.startswith(("http://", "https://"))


def model_dirs(models: dict[str, str], device: str = "cpu", precision: str = "fp32") -> ModelDirs:
    """:class:`ModelDirs` from ``--siglip2/--qwen-vl/--sam3`` values: directories as paths, a served VLM's URL
    as it is."""
    return ModelDirs(**{k: v if k == "qwen_vl" and served_vlm(v) else Path(v) for k, v in models.items() if v},
                     device=device, precision=precision)


def oracle_perception(asset: SceneAsset, noise: NoiseProfile, models: ModelDirs) -> Perception:
    return Perception(OracleEncoder(asset.objects), OracleReranker(asset.objects, noise),
                      OracleSegmenter(asset.objects, noise), OracleCaptioner(asset.objects),
                      OracleDepthNoise(noise) if noise.depth_noise_std > 0 else None)


def model_perception(asset: SceneAsset, noise: NoiseProfile, models: ModelDirs) -> Perception:
    """SigLIP2 retrieval, Qwen2.5-VL re-ranking and captioning, SAM 3 masks, all from local directories."""
    if not noise.is_noiseless:
        raise ValueError("noise profiles simulate perception errors for the oracle only; use noise='none'")
    missing = [k for k in ("siglip2", "qwen_vl", "sam3") if getattr(models, k) is None]
    if missing:
        raise ValueError(f"perception 'siglip2+qwen2.5-vl+sam3' needs model directories for: {', '.join(missing)}")
    encoder, vlm, segmenter = _load_models(models)
    return Perception(encoder, vlm, segmenter, captioner=vlm)


@functools.lru_cache(maxsize=1)
def _load_models(models: ModelDirs) -> tuple[Any, Any, Any]:
    """The three models, loaded once per process and device: every scene's stack, and every env slot of a
    worker (its envs batched), shares them, so one worker holds one copy of each on its GPU. A served VLM
    (``qwen_vl`` a URL) is asked over HTTP instead: every worker shares the server's one copy."""
    from navbench.localize.backends import OpenAIReranker, QwenVLReranker, Sam3Segmenter, Siglip2Encoder

    run_on = dict(device=models.device, precision=models.precision)
    vlm = OpenAIReranker.from_url(str(models.qwen_vl)) if served_vlm(models.qwen_vl) else \
        QwenVLReranker(models.qwen_vl, **run_on)
    return Siglip2Encoder(models.siglip2, **run_on), vlm, Sam3Segmenter(models.sam3, **run_on)


def _run_on(perception: str, models: ModelDirs) -> dict[str, Any]:
    """Where the localisation's models ran: the device (and its name) and precision of the real models; the
    oracle's stack runs no model, on the CPU (``precision`` None)."""
    from navbench.device import device_name

    if PERCEPTION.get(perception) is not model_perception:
        return {"device": "cpu", "device_name": "cpu", "precision": None}
    out = {"device": models.device, "device_name": device_name(models.device), "precision": models.precision}
    return {**out, "vlm_server": str(models.qwen_vl)} if served_vlm(models.qwen_vl) else out


PERCEPTION: dict[str, Callable[[SceneAsset, NoiseProfile, ModelDirs], Perception]] = {
    "oracle": oracle_perception,
    "siglip2+qwen2.5-vl+sam3": model_perception,
}


def success_at_k(predictions: np.ndarray | Sequence[Sequence[float]], gt_positions: np.ndarray, k: int,
                 radius: float = SUCCESS_RADIUS) -> bool:
    """Any of the first ``k`` predicted centres within ``radius`` (xz) of any ground-truth position."""
    pred = np.asarray(predictions, dtype=np.float64).reshape(-1, 3)[:k]
    gt = np.asarray(gt_positions, dtype=np.float64).reshape(-1, 3)
    if len(pred) == 0 or len(gt) == 0:
        return False
    d = np.hypot(pred[:, None, 0] - gt[None, :, 0], pred[:, None, 2] - gt[None, :, 2])
    return bool((d <= radius).any())


def sr_by_type(records: Sequence[dict]) -> tuple[float, dict[str, float]]:
    """(mean over query types of the per-type success rate, per-type rates) from records with
    ``type`` and ``success``; types without records are left out of both."""
    by_type: dict[str, float] = {}
    for t in QUERY_TYPES:
        hits = [bool(r["success"]) for r in records if r["type"] == t]
        if hits:
            by_type[t] = float(np.mean(hits))
    return (float(np.mean(list(by_type.values()))) if by_type else 0.0), by_type


def _teach_subtask(stack: Perception, sub, query) -> None:
    """Oracle backends learn which instances a GOAT-Bench query names, from the subtask's own goals (an
    image query: the text the captioner will give for it)."""
    text = query.text
    if query.type == "image":
        if not isinstance(stack.captioner, OracleCaptioner):
            return
        try:
            text = stack.captioner.describe(query.image_ids)
        except BackendError:  # the localiser reports the same failure for this query
            return
    teach(stack, text, sub.gt_positions)


def run_localize(split: str = "goat_val", perception: str = "oracle", noise: str = "none", fusion: bool = True,
                 rerank: bool = True, k: int = 5, out: str | Path | None = None, limit: int | None = None,
                 memory_root: str | Path | None = None, models: ModelDirs = ModelDirs(),
                 prescan: PrescanConfig = BENCHMARK_PRESCAN, split_root: str | Path | None = None,
                 scenes_dir: str | Path = SCENES_DIR, localizer_config: LocalizerConfig = LocalizerConfig(),
                 on_query: Callable[..., None] | None = None, episodes: str | Path | None = None,
                 scene_dir: str | Path | None = None) -> dict:
    """Localise every subtask of ``split`` (the first ``limit`` only, if given) and return the summary.

    Memories are built (or reused) per scene under ``memory_root`` (default the user cache). With
    ``out``, writes ``predictions.jsonl`` and ``summary.json`` there. ``fusion`` and ``rerank``
    override the fields of ``localizer_config``. ``on_query(localizer, query, candidates, record, scene_path)``
    is called after each query (e.g. to draw it); it must not change anything. With ``episodes`` (a
    GOAT-Bench file), its subtasks are localised instead of ``split``'s, in scenes resolved under
    ``scene_dir`` as Habitat resolves ``scene_id``s.
    """
    if perception not in PERCEPTION:
        raise ValueError(f"unknown perception {perception!r} (choose from {', '.join(PERCEPTION)})")
    profile = noise_profile(noise)
    config = dataclasses.replace(localizer_config, rerank=rerank, fusion=fusion)
    scenes_dir = Path(scenes_dir)
    goatbench = episodes is not None
    if goatbench:
        from navbench.localize.goatbench import load_goatbench
        from navbench.scene.datasets import resolve_scene

        subtasks = load_goatbench(episodes)[:limit]
        split, split_dir = Path(episodes).name, None
        scene_root = Path(scene_dir) if scene_dir is not None else scenes_dir
    else:
        root = GOAT_DIR if split_root is None else Path(split_root)
        split_dir = split_path(split, root).parent
        subtasks = load_goat_split(split, root)[:limit]

    records: list[dict] = []
    build_s: dict[str, float] = {}
    storage: dict[str, int] = {}
    built_now: dict[str, bool] = {}
    latencies: list[float] = []
    cpu_times: list[float] = []  # process CPU time: less disturbed than wall time on a shared machine
    for scene_id in dict.fromkeys(s.scene_id for s in subtasks):  # first-seen order
        scene_path = resolve_scene(scene_id, scene_root) if goatbench else scenes_dir / scene_id
        asset = load_scene(scene_path)
        stack = PERCEPTION[perception](asset, profile, models)
        memory = load_or_build_memory(scene_path, memory_root, prescan, stack.encoder)
        build_s[scene_id] = memory.stats.build_seconds
        storage[scene_id] = memory.stats.bytes
        built_now[scene_id] = memory.built_now
        localizer = Localizer.from_perception(memory, stack, config)
        mine = [s for s in subtasks if s.scene_id == scene_id]
        for sub in progress(mine, len(mine), f"localize {Path(scene_id).name.split('.')[0]}"):
            query = sub.to_query(asset) if goatbench else sub.to_query(split_dir)
            if goatbench:
                _teach_subtask(stack, sub, query)
            start, cpu = time.perf_counter(), time.process_time()
            candidates = localizer.localize(query)
            latencies.append(time.perf_counter() - start)
            cpu_times.append(time.process_time() - cpu)
            centres = [c.centre.tolist() for c in candidates[:k]]
            records.append({
                "id": sub.id, "scene_id": scene_id, "type": sub.type,
                "query": sub.query if sub.type != "image" else getattr(sub, "image", None),
                "prompt": localizer.last_trace.prompt,
                "top_k": [[round(v, 4) for v in c] for c in centres],
                "gt_positions": sub.gt_positions.round(4).tolist(),
                "success": success_at_k(centres, sub.gt_positions, k),
            })
            if on_query is not None:
                on_query(localizer, query, candidates, records[-1], scene_path)
    sr, by_type = sr_by_type(records)
    summary = {
        "split": split, "k": k, "sr": sr, "sr_by_type": by_type,
        "n_by_type": {t: sum(r["type"] == t for r in records) for t in QUERY_TYPES},
        "build_s": float(sum(build_s.values())), "build_s_per_scene": build_s,
        "storage_bytes": int(sum(storage.values())), "storage_bytes_per_scene": storage,
        "memory_built_now": built_now,
        "query_ms": 1000.0 * float(np.mean(latencies)) if latencies else 0.0,
        "query_ms_p95": 1000.0 * float(np.percentile(latencies, 95)) if latencies else 0.0,
        "query_cpu_ms": 1000.0 * float(np.mean(cpu_times)) if cpu_times else 0.0,
        "perception": perception, "noise": noise, "fusion": fusion, "rerank": rerank,
        "prescan": prescan.to_json(),
        "run_on": _run_on(perception, models),
    }
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        with open(out / "predictions.jsonl", "w") as f:
            for r in records:
                f.write(json.dumps(r) + "\n")
        (out / "summary.json").write_text(json.dumps(summary, indent=1))
    return summary
