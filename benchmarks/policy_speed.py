"""PointNav policy throughput: inference steps/s at batch 1, frames/s at batch 8, training samples/s.

    python benchmarks/policy_speed.py                 # default InferenceConfig, plus training
    python benchmarks/policy_speed.py --all           # fp32/bf16 x channels_last on/off
    python benchmarks/policy_speed.py --seconds 5 --threads 2

Targets on 2 threads: >= 75 steps/s at batch 1, >= 250 frames/s at batch 8.
"""

from __future__ import annotations

import argparse
import json

import torch

from navbench.policy import InferenceConfig, measure_policy_speed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="timing window per measurement")
    parser.add_argument("--threads", type=int, default=2, help="torch intra-op threads")
    parser.add_argument("--all", action="store_true", help="also time bf16 and channels_last variants")
    parser.add_argument("--no-train", action="store_true", help="skip the training measurement")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)

    variants = [InferenceConfig()]
    if args.all:
        variants = [InferenceConfig(bf16=b, channels_last=c) for b in (False, True) for c in (False, True)]
    for i, cfg in enumerate(variants):
        result = measure_policy_speed(args.seconds, cfg, training=(i == 0 and not args.no_train))
        row = {"bf16": cfg.bf16, "channels_last": cfg.channels_last, "threads": args.threads}
        row.update({k: round(v, 1) for k, v in result.items()})
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
