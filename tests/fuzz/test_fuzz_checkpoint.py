"""Fuzz the checkpoint reader: truncated files, wrong dtypes, pickled objects, missing and extra keys.

A checkpoint must load into a policy whose weights are the file's, or fail as one line naming the file.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import pytest
import torch
from fuzzlib import read_or_error
from hypothesis import given
from hypothesis import strategies as st

from navbench.paths import POLICIES_DIR
from navbench.policy.checkpoint import load_checkpoint, read_checkpoint, save_checkpoint
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig

SHIPPED = POLICIES_DIR / "pointnav_navbench.pth"


@pytest.fixture(scope="module")
def shipped_state(tmp_path_factory) -> dict:
    """The state_dict of a small policy of the shipped architecture (the 17 MB one is slow to rewrite)."""
    cfg = PolicyNetConfig(hidden_size=16, num_layers=1, base_planes=8, ngroups=4)
    path = save_checkpoint(tmp_path_factory.mktemp("ckpt") / "small.pth", PointNavResNetPolicy(cfg), {"n": 1})
    return read_checkpoint(path).state_dict


def _save(obj, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(obj, path)
    return path


def check_checkpoint(path: Path) -> None:
    policy = read_or_error(load_checkpoint, path)
    if policy is not None:
        for name, t in policy.state_dict().items():
            assert not t.is_floating_point() or torch.isfinite(t).all(), f"{name} loaded non-finite"


class Payload:
    """A foreign class a pickled checkpoint may name."""

    def __reduce__(self):
        return (os.getcwd, ())


def test_truncation(fuzz_dir):
    small = {"state_dict": {"net.a": torch.ones(3), "net.b": torch.zeros(2, 2)}, "config": {"x": 1}}
    buf = io.BytesIO()
    torch.save(small, buf)
    data = buf.getvalue()
    path = fuzz_dir / "ckpt_trunc" / "c.pth"
    path.parent.mkdir(parents=True, exist_ok=True)
    for cut in range(0, len(data), max(1, len(data) // 300)):
        path.write_bytes(data[:cut])
        read_or_error(read_checkpoint, path)
        check_checkpoint(path)


def test_shipped_truncated(fuzz_dir):
    data = SHIPPED.read_bytes()
    path = fuzz_dir / "ckpt_trunc_shipped" / "c.pth"
    path.parent.mkdir(parents=True, exist_ok=True)
    for cut in (0, 10, 100, 1000, len(data) // 2, len(data) - 100, len(data) - 1):
        path.write_bytes(data[:cut])
        check_checkpoint(path)


@given(kind=st.sampled_from(["int64", "bool", "float64", "complex64", "half", "nan", "inf", "scalar", "empty"]),
       index=st.integers(0, 10_000))
def test_dtype_and_value_swaps(kind, index, shipped_state, fuzz_dir):
    state = dict(shipped_state)
    key = sorted(state)[index % len(state)]
    t = state[key]
    state[key] = {"int64": lambda: t.long(), "bool": lambda: t.bool(), "float64": lambda: t.double(),
                  "complex64": lambda: t.to(torch.complex64), "half": lambda: t.half(),
                  "nan": lambda: torch.full_like(t.float(), float("nan")),
                  "inf": lambda: torch.full_like(t.float(), float("inf")),
                  "scalar": lambda: torch.tensor(1.0), "empty": lambda: torch.empty(0)}[kind]()
    check_checkpoint(_save({"state_dict": state, "config": {}}, fuzz_dir / "ckpt_dtype" / "c.pth"))


@given(op=st.sampled_from(["drop", "extra", "rename", "prefix", "non_tensor", "config_type"]),
       index=st.integers(0, 10_000))
def test_key_mutations(op, index, shipped_state, fuzz_dir):
    state = dict(shipped_state)
    key = sorted(state)[index % len(state)]
    doc: object = {"state_dict": state, "config": {}}
    if op == "drop":
        del state[key]
    elif op == "extra":
        state["net.fuzz"] = torch.zeros(1)
    elif op == "rename":
        state[key + "_x"] = state.pop(key)
    elif op == "prefix":
        doc = {"actor_critic." + k: v for k, v in state.items()}
    elif op == "non_tensor":
        state[key] = [1.0, 2.0]
    else:
        doc = {"state_dict": state, "config": [1, 2]}
    check_checkpoint(_save(doc, fuzz_dir / "ckpt_keys" / "c.pth"))


@pytest.mark.parametrize("obj", ["list", "tensor", "none", "payload", "payload_in_config", "empty_dict",
                                 "state_dict_list", "nested"])
def test_odd_objects(obj, shipped_state, fuzz_dir):
    doc = {"list": [1, 2, 3], "tensor": torch.zeros(3), "none": None, "payload": Payload(),
           "payload_in_config": {"state_dict": shipped_state, "config": {"x": Payload()}},
           "empty_dict": {}, "state_dict_list": {"state_dict": [torch.zeros(1)]},
           "nested": {"state_dict": {"state_dict": shipped_state}}}[obj]
    check_checkpoint(_save(doc, fuzz_dir / "ckpt_odd" / f"{obj}.pth"))


@pytest.mark.parametrize("content", [b"", b"\x00" * 100, b"PK\x03\x04garbage", b"\x80\x02}q\x00.", b"not a checkpoint"])
def test_garbage_files(content, fuzz_dir):
    path = fuzz_dir / "ckpt_garbage" / "c.pth"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(content)
    check_checkpoint(path)


def test_directory_and_missing(fuzz_dir):
    (fuzz_dir / "ckpt_dir.pth").mkdir(exist_ok=True)
    check_checkpoint(fuzz_dir / "ckpt_dir.pth")
    check_checkpoint(fuzz_dir / "no_such.pth")
