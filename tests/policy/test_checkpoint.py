"""Checkpoint save/load: habitat layouts, fp16 round trip, precise errors, safe unpickling."""

from __future__ import annotations

import copy
import os
import pickle
import sys
import types
from pathlib import Path

import numpy as np
import pytest
import torch

from navbench.policy import (
    CheckpointError,
    InferenceConfig,
    PointNavAgentPolicy,
    PointNavResNetPolicy,
    load_checkpoint,
    read_checkpoint,
    save_checkpoint,
)


@pytest.fixture(scope="module")
def policy() -> PointNavResNetPolicy:
    torch.manual_seed(0)
    p = PointNavResNetPolicy().eval()
    # Spread the logits as a trained policy would (habitat's actor init leaves them near-tied).
    torch.nn.init.normal_(p.action_distribution.linear.weight, std=0.3)
    return p


@pytest.fixture(scope="module")
def saved(policy: PointNavResNetPolicy, tmp_path_factory) -> Path:
    return save_checkpoint(tmp_path_factory.mktemp("ckpt") / "policy.pth", policy, {"trained_steps": 0})


def _rollout_actions(policy: PointNavResNetPolicy, steps: int = 3) -> np.ndarray:
    rng = np.random.default_rng(0)
    agent = PointNavAgentPolicy(policy, 4, InferenceConfig(channels_last=False))
    out = []
    for _ in range(steps):
        depth = rng.random((4, 224, 224, 1), dtype=np.float32)
        goal = np.stack([rng.uniform(0.5, 5, 4), rng.uniform(-3, 3, 4)], -1)
        out.append(agent.act(depth, goal))
    return np.stack(out)


def test_fp16_round_trip_keeps_actions_and_file_small(policy: PointNavResNetPolicy, saved: Path) -> None:
    assert 15e6 < saved.stat().st_size < 19e6
    data = read_checkpoint(saved)
    assert data.config == {"trained_steps": 0}
    assert data.state_dict["net.visual_fc.1.weight"].dtype == torch.float16
    loaded = load_checkpoint(saved)
    assert loaded.state_dict()["net.visual_fc.1.weight"].dtype == torch.float32
    np.testing.assert_array_equal(_rollout_actions(loaded), _rollout_actions(policy))


def test_fp32_save_is_exact(policy: PointNavResNetPolicy, tmp_path: Path) -> None:
    path = save_checkpoint(tmp_path / "fp32.pth", policy, {}, fp16=False)
    target = copy.deepcopy(policy)
    for param in target.parameters():
        torch.nn.init.zeros_(param)
    loaded = load_checkpoint(path, target)
    assert loaded is target
    for k, v in policy.state_dict().items():
        assert torch.equal(loaded.state_dict()[k], v), k


def test_actor_critic_prefix_and_bare_state_dict_load(policy: PointNavResNetPolicy, tmp_path: Path) -> None:
    sd = policy.state_dict()
    prefixed = tmp_path / "prefixed.pth"
    torch.save({"state_dict": {f"actor_critic.{k}": v for k, v in sd.items()}, "config": {}}, prefixed)
    bare = tmp_path / "bare.pth"
    torch.save(sd, bare)
    for path in (prefixed, bare):
        loaded = load_checkpoint(path)
        assert torch.equal(loaded.state_dict()["critic.fc.weight"], sd["critic.fc.weight"])


def test_wrong_shape_names_the_tensor(policy: PointNavResNetPolicy, tmp_path: Path) -> None:
    sd = dict(policy.state_dict())
    sd["net.visual_fc.1.weight"] = torch.zeros(512, 1024)
    path = tmp_path / "wrong_shape.pth"
    torch.save({"state_dict": sd, "config": {}}, path)
    target = copy.deepcopy(policy)
    torch.nn.init.zeros_(target.critic.fc.weight)
    before = target.state_dict()["critic.fc.weight"].clone()
    with pytest.raises(CheckpointError, match=r"wrong_shape\.pth.*net\.visual_fc\.1\.weight \(512, 1024\)"):
        load_checkpoint(path, target)
    assert torch.equal(target.state_dict()["critic.fc.weight"], before)  # nothing half-loaded


def test_missing_and_unexpected_keys_are_named(policy: PointNavResNetPolicy, tmp_path: Path) -> None:
    sd = dict(policy.state_dict())
    del sd["net.tgt_embeding.bias"]
    path = tmp_path / "missing.pth"
    torch.save({"state_dict": sd}, path)
    with pytest.raises(CheckpointError, match=r"missing\.pth: missing 1 tensor\(s\): net\.tgt_embeding\.bias"):
        load_checkpoint(path)
    sd = dict(policy.state_dict(), **{"net.extra.weight": torch.zeros(3)})
    path = tmp_path / "extra.pth"
    torch.save({"state_dict": sd}, path)
    with pytest.raises(CheckpointError, match=r"unexpected tensor\(s\): net\.extra\.weight"):
        load_checkpoint(path)


def test_normalizer_checkpoint_builds_matching_policy(policy: PointNavResNetPolicy, tmp_path: Path) -> None:
    # habitat's RGB policies carry the running normaliser's buffers; depth-only ones (VLFM) do not.
    prefix = "net.visual_encoder.running_mean_and_var."
    sd = dict(policy.state_dict())
    sd |= {prefix + "_mean": torch.full((1, 1, 1, 1), 0.4), prefix + "_var": torch.full((1, 1, 1, 1), 0.04)}
    sd[prefix + "_count"] = torch.tensor(1000.0)
    path = tmp_path / "rgb_style.pth"
    torch.save({"state_dict": sd, "config": {}}, path)
    loaded = load_checkpoint(path)
    assert loaded.cfg.normalize_visual_inputs
    assert loaded.net.visual_encoder.running_mean_and_var._mean.item() == pytest.approx(0.4)
    with pytest.raises(CheckpointError,
                       match=r"3 unexpected tensor\(s\): net\.visual_encoder\.running_mean_and_var\._"):
        load_checkpoint(path, copy.deepcopy(policy))


@pytest.mark.parametrize(
    "content, message",
    [
        (b"", "not a PyTorch checkpoint"),
        (b"this is a text file\n", "not a PyTorch checkpoint"),
        (pickle.dumps({"a": 1}), "not a PyTorch checkpoint"),
    ],
)
@pytest.mark.filterwarnings("ignore:Detected pickle protocol")
def test_non_checkpoint_files_are_refused(tmp_path: Path, content: bytes, message: str) -> None:
    path = tmp_path / "bogus.pth"
    path.write_bytes(content)
    with pytest.raises(CheckpointError, match=rf"bogus\.pth.*{message}"):
        load_checkpoint(path)


def test_truncated_zip_is_refused(saved: Path, tmp_path: Path) -> None:
    path = tmp_path / "truncated.pth"
    path.write_bytes(saved.read_bytes()[: saved.stat().st_size // 2])
    with pytest.raises(CheckpointError, match=r"truncated\.pth"):
        load_checkpoint(path)


def test_other_pickled_objects_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "list.pth"
    torch.save([torch.zeros(2)], path)
    with pytest.raises(CheckpointError, match=r"list\.pth: holds a list"):
        load_checkpoint(path)
    path = tmp_path / "meta.pth"
    torch.save({"epoch": 3, "note": "no weights"}, path)
    with pytest.raises(CheckpointError, match=r"meta\.pth: has no 'state_dict'"):
        load_checkpoint(path)
    with pytest.raises(CheckpointError, match=r"absent\.pth: no such checkpoint file"):
        load_checkpoint(tmp_path / "absent.pth")


def test_foreign_config_classes_become_inert(policy: PointNavResNetPolicy, tmp_path: Path, monkeypatch) -> None:
    # A stand-in for habitat's OmegaConf config: classes and a callable from a module that is not
    # importable at load time (as omegaconf is not installed here).
    fake_pkg, fake_mod = types.ModuleType("fakeomegaconf"), types.ModuleType("fakeomegaconf.dictconfig")

    class DictConfig:
        def __init__(self, content: dict) -> None:
            self._content = content

    class _Hook:
        def __reduce__(self):
            return (make_marker, (str(marker),))

    def make_marker(p: str) -> None:
        Path(p).mkdir()

    for obj, name in ((DictConfig, "DictConfig"), (make_marker, "make_marker")):
        obj.__module__, obj.__qualname__ = "fakeomegaconf.dictconfig", name
        setattr(fake_mod, name, obj)
    monkeypatch.setitem(sys.modules, "fakeomegaconf", fake_pkg)
    monkeypatch.setitem(sys.modules, "fakeomegaconf.dictconfig", fake_mod)
    marker = tmp_path / "executed"
    path = tmp_path / "habitat_with_omegaconf.pth"
    config = DictConfig({"rl": {"ppo": {"hidden_size": 512}}, "hook": _Hook()})
    torch.save({"state_dict": policy.state_dict(), "config": config, "extra_state": {"step": 10}}, path)
    monkeypatch.delitem(sys.modules, "fakeomegaconf.dictconfig")
    monkeypatch.delitem(sys.modules, "fakeomegaconf")

    data = read_checkpoint(path)
    assert data.config is None
    loaded = load_checkpoint(path)
    assert torch.equal(loaded.state_dict()["critic.fc.weight"], policy.state_dict()["critic.fc.weight"])
    assert not marker.exists()


class _Mkdir:
    """Pickles as a call to os.mkdir: would create ``marker`` if the loader executed globals."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.mkdir, (str(self.marker),))


def test_dangerous_globals_are_refused_not_run(policy: PointNavResNetPolicy, tmp_path: Path) -> None:
    marker = tmp_path / "executed"
    path = tmp_path / "hostile.pth"
    torch.save({"state_dict": policy.state_dict(), "config": _Mkdir(marker)}, path)
    with pytest.raises(CheckpointError, match=r"hostile\.pth: refused by torch\.load\(weights_only=True\).*mkdir"):
        load_checkpoint(path)
    assert not marker.exists()


def test_config_must_be_json_like(policy: PointNavResNetPolicy, tmp_path: Path) -> None:
    path = save_checkpoint(tmp_path / "ok.pth", policy, {"out": tmp_path / "x", "n": np.int64(3), "t": (1, 2)})
    assert read_checkpoint(path).config == {"out": str(tmp_path / "x"), "n": 3, "t": [1, 2]}
    with pytest.raises(CheckpointError, match=r"bad\.pth: config must be JSON-like"):
        save_checkpoint(tmp_path / "bad.pth", policy, {"when": object()})
