"""Weight memory of the real perception models per worker, from your checkpoints' safetensors headers: each
model's parameter count (no weight is read) times the bytes a parameter takes at ``--precision``, and how many
copies ``--workers N`` loads (one per worker; none for a VLM given as a served URL, which the server holds once).
Weights only: activations, the CUDA context and the allocator's cache come on top.

    PYTHONPATH=$PWD python benchmarks/model_memory.py --siglip2 DIR --sam3 DIR --qwen-vl DIR|URL \\
        [--precision bf16] [--workers 4]
"""

from __future__ import annotations

import argparse
import sys

from navbench.localize.backends.base import BackendError, checkpoint_parameters
from navbench.localize.benchmark import served_vlm

BYTES = {"fp32": 4, "bf16": 2, "fp16": 2}


def rows(models: dict[str, str], precision: str, workers: int) -> list[tuple[str, str, str, str, str]]:
    out = []
    total = 0.0
    for name, where in models.items():
        if served_vlm(where):
            out.append((name, "served", "-", f"0 (one copy on {where})", "0"))
            continue
        n = checkpoint_parameters(where)
        gb = n * BYTES[precision] / 1e9
        total += gb * workers
        out.append((name, f"{n / 1e6:,.1f} M", f"{gb:.3f} GB", str(workers), f"{gb * workers:.3f} GB"))
    out.append(("all", "", "", "", f"{total:.3f} GB"))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--siglip2")
    p.add_argument("--sam3")
    p.add_argument("--qwen-vl")
    p.add_argument("--precision", default="bf16", choices=tuple(BYTES))
    p.add_argument("--workers", type=int, default=1)
    args = p.parse_args(argv)
    models = {k: v for k, v in (("siglip2", args.siglip2), ("sam3", args.sam3), ("qwen_vl", args.qwen_vl)) if v}
    if not models or args.workers < 1:
        p.error("give at least one model directory, and --workers >= 1")
    try:
        table = rows(models, args.precision, args.workers)
    except BackendError as exc:
        print(f"model_memory: {exc}", file=sys.stderr)
        return 2
    print(f"| model | parameters | weights per copy ({args.precision}) | copies | weights |")
    print("|---|---|---|---|---|")
    for r in table:
        print("| " + " | ".join(r) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
