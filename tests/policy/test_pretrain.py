"""Encoder pre-training: the geometric targets are where the walls are, flips mirror frame and targets
together, and a few updates reduce the loss on real rendered frames."""

import dataclasses
import math

import numpy as np
import pytest
import torch
import trimesh

from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig
from navbench.policy.pretrain import (
    GeometryHead,
    PretrainConfig,
    batch_tensors,
    fov_mask,
    free_distances,
    generate,
    losses,
    navigability_patch,
    patch_offsets,
)
from navbench.scene.navigability import NavGrid

FACING_PLUS_X = -math.pi / 2  # yaw 0 faces -z; turning right (negative yaw) by 90 deg faces +x


def _box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    b = trimesh.creation.box(hi - lo)
    b.apply_translation((lo + hi) / 2)
    return b


@pytest.fixture(scope="module")
def room() -> NavGrid:
    """6 x 6 m floor, a wall across x = 3 (face at 2.95) from z = 0 to z = 6: the agent's way is blocked."""
    return NavGrid.from_mesh(trimesh.util.concatenate([_box((0, -0.1, 0), (6, 0, 6)),
                                                       _box((2.95, 0, 0), (3.05, 2.5, 6))]))


def test_free_run_stops_at_the_wall_less_the_radius(room: NavGrid) -> None:
    p = np.array([1.0, room.floor_height, 3.0])
    free = free_distances(room, p, FACING_PLUS_X, (0.0, 30.0, -30.0), max_range=4.0) * 4.0
    expected = 2.95 - 0.18 - 1.0  # wall face, less the agent's radius, less the start
    assert free[0] == pytest.approx(expected, abs=0.06)
    # 30 deg either side the wall is further along the ray: 1 / cos(30 deg) as far, both sides alike
    assert free[1] == pytest.approx(expected / math.cos(math.radians(30)), abs=0.08)
    assert free[2] == pytest.approx(free[1], abs=0.06)
    # facing away from the wall the run is capped by the range or the room's far side (x = 0 - radius)
    back = free_distances(room, p, -FACING_PLUS_X, (0.0,), max_range=4.0)[0] * 4.0
    assert back == pytest.approx(1.0 - 0.18, abs=0.06)


def test_patch_rows_go_away_from_the_agent_and_columns_to_its_right(room: NavGrid) -> None:
    fwd, right = patch_offsets(16, 0.25)
    # facing +x at x = 1: the wall band (x in 2.77..3.23 with the radius) is 1.77..2.23 m ahead
    patch = navigability_patch(room, np.array([1.0, 0.0, 3.0]), FACING_PLUS_X, fwd, right)
    assert patch[:7].all() and not patch[7:9].any()
    # facing -z at z = 3 the wall is to the right, 1.77..2.23 m: only the last column (1.875 m) is in it
    patch = navigability_patch(room, np.array([1.0, 0.0, 3.0]), 0.0, fwd, right)
    near = fwd[:, 0] < 2.5  # z > 0.5, still on the floor
    assert patch[near][:, (right[0] > -0.5) & (right[0] < 1.5)].all() and not patch[:, -1].any()
    mask = fov_mask(fwd, right, 79.0)
    assert mask[-1, 8] and not mask[0, 0] and (mask == mask[:, ::-1]).all()


def test_flip_mirrors_depth_and_targets_together() -> None:
    rng = np.random.default_rng(0)
    data = {"depth": rng.integers(0, 256, (2, 112, 112), dtype=np.uint8),
            "free": rng.random((2, 13), dtype=np.float32), "patch": rng.random((2, 16, 16)) > 0.5}
    d0, f0, p0 = batch_tensors(data, np.array([0, 1]))
    d1, f1, p1 = batch_tensors(data, np.array([0, 1]), flip=np.array([True, False]))
    assert torch.equal(d1[0], d0[0].flip(-1)) and torch.equal(d1[1], d0[1])
    assert torch.equal(f1[0], f0[0].flip(-1)) and torch.equal(p1[0], p0[0].flip(-1))
    assert d0.shape == (2, 1, 112, 112) and d0.max() <= 1.0


def test_rendered_frames_have_targets_and_a_few_updates_reduce_the_loss() -> None:
    cfg = PretrainConfig(frames_per_scene=3, batch_size=8, lr=1e-3)
    data = generate(cfg)
    assert data["depth"].shape == (24, 112, 112) and data["depth"].dtype == np.uint8
    assert data["free"].shape == (24, 13) and ((data["free"] >= 0) & (data["free"] <= 1)).all()
    assert 0.0 < data["patch"].mean() < 1.0
    assert len({d.tobytes() for d in data["depth"]}) == 24  # different poses, different frames
    torch.manual_seed(0)
    policy = PointNavResNetPolicy(PolicyNetConfig())
    head = GeometryHead(512, 13, 16)
    fwd, right = patch_offsets(16, 0.25)
    mask = torch.from_numpy(fov_mask(fwd, right, 79.0).astype(np.float32))
    params = [*policy.net.visual_encoder.parameters(), *policy.net.visual_fc.parameters(), *head.parameters()]
    opt = torch.optim.Adam(params, lr=cfg.lr)
    batch = batch_tensors(data, np.arange(8))
    history = []
    for _ in range(40):  # 0.90 -> 0.26 on the bundled train houses
        loss = losses(policy, head, batch, mask, cfg)["loss"]
        opt.zero_grad()
        loss.backward()
        opt.step()
        history.append(loss.item())
    assert history[-1] < 0.6 * history[0], history


def test_tiny_pretrain_run_logs_and_writes_a_habitat_checkpoint(tmp_path) -> None:
    from navbench.policy.checkpoint import load_checkpoint
    from navbench.policy.pretrain import pretrain

    cfg = PretrainConfig(frames_per_scene=2, heldout_frames=4, updates=2, batch_size=4, log_every=1, save_every=2)
    last = pretrain(cfg, tmp_path / "enc.pth", tmp_path / "state", log=lambda _: None)
    assert last["update"] == 2 and np.isfinite(last["val_loss"])
    assert (tmp_path / "enc.log.csv").read_text().count("\n") == 3  # header + two rows
    assert load_checkpoint(tmp_path / "enc.pth") is not None


def test_bf16_updates_train_in_bfloat16_and_track_fp32(tmp_path) -> None:
    from navbench.policy.pretrain import pretrain

    cfg = PretrainConfig(frames_per_scene=2, heldout_frames=4, updates=3, batch_size=4, log_every=3, save_every=3)
    last = {bf16: pretrain(dataclasses.replace(cfg, bf16=bf16), tmp_path / f"enc{bf16}.pth", tmp_path / "state",
                           log=lambda _: None) for bf16 in (False, True)}
    # the same frames, batches and seed: only the precision of the updates' forward pass differs, so the
    # held-out loss (computed in fp32) moves a little, not a lot
    assert last[True]["val_loss"] != last[False]["val_loss"]
    assert last[True]["val_loss"] == pytest.approx(last[False]["val_loss"], rel=0.05)
