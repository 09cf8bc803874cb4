"""Asking for bf16 on a CPU that emulates it warns, for exactly the options that compute in bf16."""

import pytest
import torch

import navbench.policy.ppo as ppo
import navbench.policy.pretrain as pretrain
import navbench.policy.train as train
from navbench.cli import main
from navbench.policy.precision import emulated_bf16_warning, native_bf16

TRAINERS = {"encoder": pretrain, "dagger": train, "ppo": ppo}


def _cpu(monkeypatch, avx512_bf16: bool, amx: bool) -> None:
    monkeypatch.setattr(torch.cpu, "_is_avx512_bf16_supported", lambda: avx512_bf16, raising=False)
    monkeypatch.setattr(torch.cpu, "_is_amx_tile_supported", lambda: amx, raising=False)


@pytest.mark.parametrize(("avx512_bf16", "amx", "native"),
                         [(False, False, False), (True, False, True), (False, True, True)])
def test_native_bf16_follows_the_cpu_probes(monkeypatch, avx512_bf16, amx, native):
    _cpu(monkeypatch, avx512_bf16, amx)
    assert native_bf16() is native


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


def _fake_trainers(monkeypatch) -> list:
    started = []
    for name, module in TRAINERS.items():
        monkeypatch.setattr(module, "main", lambda cfg, *args, name=name, **kw: started.append((name, cfg)))
    return started


@pytest.mark.parametrize(("trainer", "flags", "warned"), [
    ("encoder", ["--bf16"], True), ("encoder", [], False),
    ("dagger", ["--bf16"], True), ("dagger", ["--act-bf16"], True), ("dagger", ["--no-bf16"], False),
    ("ppo", ["--act-bf16"], True), ("ppo", [], False)])
def test_train_warns_on_stderr_before_training(monkeypatch, capsys, trainer, flags, warned):
    _cpu(monkeypatch, False, False)
    started = _fake_trainers(monkeypatch)
    assert main(["train", trainer, "--out", "unused.pth", *flags]) == 0
    assert [name for name, _ in started] == [trainer]  # the run still starts: the warning refuses nothing
    assert ("bfloat16 is emulated here" in capsys.readouterr().err) is warned


def test_ppo_has_no_bf16_update_option(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["train", "ppo", "--bf16"])
    assert exit_.value.code == 2 and "--bf16" in capsys.readouterr().err


def test_a_recipe_warns_before_each_bf16_stage(monkeypatch, capsys, tmp_path):
    _cpu(monkeypatch, False, False)
    started = _fake_trainers(monkeypatch)
    assert main(["train", "--config", "configs/pointnav/2h.toml", "--out-dir", str(tmp_path)]) == 0
    assert [name for name, _ in started] == ["encoder", "dagger"]
    err = capsys.readouterr().err
    assert "warning: --bf16 on a CPU" in err and "warning: --bf16 and --act-bf16 on a CPU" in err
