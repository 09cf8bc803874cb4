"""Whether this CPU computes bfloat16 natively, and the warning a training run prints when it does not.

PyTorch runs ``torch.autocast("cpu", dtype=torch.bfloat16)`` on any x86 CPU, but only CPUs with AVX512-BF16 or
AMX have bf16 instructions; elsewhere oneDNN emulates them and the ResNet runs several times slower than in fp32
(``benchmarks/policy_speed.py --all`` measures it). ``navbench train`` warns before a stage whose bf16 options
(encoder ``--bf16``, dagger ``--bf16``/``--act-bf16``, ppo ``--act-bf16``) would run emulated.

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
            "emulated here and runs slower than fp32 (navbench.policy.precision)")
