"""bf16 is used by default only where the CPU computes it natively, and asking for it elsewhere warns."""

import pytest
import torch

import navbench.policy.ppo as ppo
from navbench.cli import main
from navbench.policy.precision import emulated_bf16_warning, native_bf16


def _cpu(monkeypatch, avx512_bf16: bool, amx: bool) -> None:
    monkeypatch.setattr(torch.cpu, "_is_avx512_bf16_supported", lambda: avx512_bf16, raising=False)
    monkeypatch.setattr(torch.cpu, "_is_amx_tile_supported", lambda: amx, raising=False)


@pytest.mark.parametrize(("avx512_bf16", "amx", "native"),
                         [(False, False, False), (True, False, True), (False, True, True)])
def test_native_bf16_follows_the_cpu_probes(monkeypatch, avx512_bf16, amx, native):
    _cpu(monkeypatch, avx512_bf16, amx)
    assert native_bf16() is native
    assert ppo.PPOConfig().bf16 is native  # PPO's default precision follows the CPU
    assert ppo.PPOConfig(bf16=True).bf16 and not ppo.PPOConfig(bf16=False).bf16  # an explicit choice stands


def test_a_torch_without_the_probes_counts_as_emulating(monkeypatch):
    monkeypatch.delattr(torch.cpu, "_is_avx512_bf16_supported", raising=False)
    monkeypatch.delattr(torch.cpu, "_is_amx_tile_supported", raising=False)
    assert native_bf16() is False


def test_the_warning_names_the_flags_only_on_an_emulating_cpu(monkeypatch):
    _cpu(monkeypatch, False, False)
    message = emulated_bf16_warning(["--bf16", "--act-bf16"])
    assert message.startswith("warning: --bf16 and --act-bf16 on a CPU without AVX512-BF16 or AMX")
    assert "\n" not in message
    assert emulated_bf16_warning([]) is None
    _cpu(monkeypatch, True, False)
    assert emulated_bf16_warning(["--bf16"]) is None


@pytest.mark.parametrize(("flags", "warned"), [(["--bf16", "--train-encoder"], True), (["--act-bf16"], True),
                                                (["--bf16"], False), (["--no-bf16"], False), ([], False)])
def test_train_warns_on_stderr_before_training(monkeypatch, capsys, flags, warned):
    # ppo's --bf16 alone is not warned about: a frozen-encoder update makes no bf16 pass (test_ppo.py)
    _cpu(monkeypatch, False, False)
    started = []

    def fake_training(args) -> int:
        started.append(args.bf16)
        return 0

    monkeypatch.setattr(ppo, "main_args", fake_training)
    assert main(["train", "ppo", "--out", "unused.pth", *flags]) == 0
    assert len(started) == 1  # the run still starts: the warning does not refuse the user's choice
    err = capsys.readouterr().err
    assert ("bfloat16 is emulated here" in err) is warned
