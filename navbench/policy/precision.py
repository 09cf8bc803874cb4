"""Whether this CPU computes bfloat16 natively, and the warning a training run prints when it does not.

PyTorch runs ``torch.autocast("cpu", dtype=torch.bfloat16)`` on any x86 CPU, but only CPUs with
AVX512-BF16 or AMX have bf16 instructions; elsewhere oneDNN emulates them. Measured on a 2-core AMD EPYC
with AVX2 only (session 33, torch 2.13.0, bf16 against fp32): an encoder-stage update (the ResNet's
forward and backward) 7.0 s against 0.66 s; policy inference at batch 8 45 frames/s against 227, both in
channels_last (``benchmarks/policy_speed.py --all``). (A frozen-encoder PPO update makes no bf16 pass at all:
PPOConfig.bf16 covers only the encoder's pass with train_encoder.)

    python -c "from navbench.policy.precision import native_bf16; print(native_bf16())"
"""

from __future__ import annotations

import torch


def native_bf16() -> bool:
    """True when this CPU has AVX512-BF16 or AMX, i.e. bfloat16 autocast is not emulated."""
    cpu = torch.cpu
    # Private probes of torch.cpu (present in torch 2.13); a torch without them counts as not native,
    # the safe answer: fp32 is never the slow path.
    probes = ("_is_avx512_bf16_supported", "_is_amx_tile_supported")
    return any(bool(getattr(cpu, name, lambda: False)()) for name in probes)


def emulated_bf16_warning(flags: list[str]) -> str | None:
    """The one-line warning for bf16 ``flags`` asked for on a CPU that emulates bf16 (None if native or none)."""
    if not flags or native_bf16():
        return None
    capability = torch.backends.cpu.get_cpu_capability()
    return (f"warning: {' and '.join(flags)} on a CPU without AVX512-BF16 or AMX ({capability}): bfloat16 is "
            "emulated here and runs slower than fp32, ~10x for the ResNet (navbench.policy.precision)")
