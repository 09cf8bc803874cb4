"""Pre-train the PointNav policy's depth encoder on geometry the navigability grid gives for free.

    navbench train --config configs/pointnav/2h.toml                # the recipes' first stage, `encoder`
    navbench train encoder --out runs/pointnav/encoder.pth          # resumable: add --resume
    navbench train dagger --init runs/pointnav/encoder.pth ...      # then the recurrent policy (train.py)

Why: imitation labels (one of four actions, often ambiguous) are a weak signal for a ResNet that
starts from random weights, and on 2 CPU cores few encoder samples per second fit the budget. Here every
frame comes with dense targets that follow from the frame alone:

- ``free``: how far the agent could walk straight along 13 headings across the field of view
  (-36..36 deg), by :meth:`NavGrid.try_step` with the agent's radius, capped at ``ray_range``;
- ``patch``: a 16x16 egocentric top-down navigability patch (0.25 m cells, 4 m ahead, 4 m wide),
  scored only on cells inside the horizontal field of view.

Frames are rendered at uniformly random navigable positions and headings of the bundled train houses
(depth only, exactly the env's sensor via :func:`navbench.env.sensors.normalize_depth`), stored 2x2 pooled as
uint8 (the network's own first step is that 2x2 pool). The network trained is ``net.visual_encoder`` +
``net.visual_fc`` plus a training-only linear head on the 512-d ``visual_fc`` output (not in the shipped
state_dict). Horizontal flips (targets mirrored) double the data. The result is a habitat-layout checkpoint whose
other weights are at their initialisation, the ``--init`` of the DAgger stage.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from navbench.env.config import EnvConfig
from navbench.env.sensors import normalize_depth
from navbench.loop_progress import progress
from navbench.paths import SCENES_DIR
from navbench.policy.checkpoint import save_checkpoint, save_train_state
from navbench.policy.config import PretrainConfig
from navbench.policy.csv_log import log_row
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig
from navbench.render.camera import CameraConfig
from navbench.render.renderer import Renderer
from navbench.scene.cache import load_scene_and_navgrid
from navbench.scene.navigability import NavGrid
from navbench.scene.pose import heading_vector, quat_from_yaw


# ------------------------------------------------------------------------------------------- targets
def free_distances(navgrid: NavGrid, position, yaw: float, headings_deg, max_range: float) -> np.ndarray:
    """Fraction of ``max_range`` the agent can walk straight along each heading (relative to ``yaw``)."""
    p = np.asarray(position, np.float64)
    out = np.empty(len(headings_deg), np.float32)
    for k, h in enumerate(headings_deg):
        q, _ = navgrid.try_step(p, p + max_range * heading_vector(yaw + math.radians(h)))
        out[k] = math.hypot(q[0] - p[0], q[2] - p[2]) / max_range
    return out


def patch_offsets(cells: int, cell_size: float) -> tuple[np.ndarray, np.ndarray]:
    """(forward, right) centres of the egocentric patch, each (cells, cells); rows go away from the agent."""
    fwd = (np.arange(cells) + 0.5) * cell_size
    right = (np.arange(cells) - cells / 2 + 0.5) * cell_size
    return np.meshgrid(fwd, right, indexing="ij")


def navigability_patch(navgrid: NavGrid, position, yaw: float, fwd: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Navigable flags of the grid at the agent-frame offsets ``(fwd, right)``."""
    c, s = math.cos(yaw), math.sin(yaw)
    # agent frame (forward, right) -> world xz; the same rotation as sensors.from_agent_frame, vectorised
    x = position[0] + c * right - s * fwd
    z = position[2] - s * right - c * fwd
    return navgrid._navigable_xz(x, z)


def fov_mask(fwd: np.ndarray, right: np.ndarray, hfov_deg: float) -> np.ndarray:
    return np.abs(np.degrees(np.arctan2(right, fwd))) <= hfov_deg / 2


# ---------------------------------------------------------------------------------------------- data
def generate(cfg: PretrainConfig, env_cfg: EnvConfig = EnvConfig(rgb=False)) -> dict[str, np.ndarray]:
    """Render frames at random poses in the bundled train houses with their targets (seeded)."""
    rng = np.random.default_rng(cfg.seed)
    fwd, right = patch_offsets(cfg.patch_cells, cfg.patch_cell_size)
    nav_cfg = env_cfg.nav_grid_config()
    camera = CameraConfig(width=env_cfg.width, height=env_cfg.height, hfov_deg=env_cfg.hfov_deg)
    depth, free, patch = [], [], []
    for scene in sorted((SCENES_DIR / "houses" / "train").glob("*.glb")):
        asset, navgrid = load_scene_and_navgrid(scene, nav_cfg)
        with Renderer(asset, camera, platform=env_cfg.gl_platform) as renderer:
            for _ in range(cfg.frames_per_scene):
                p = navgrid.sample_navigable_point(rng)
                yaw = float(rng.uniform(-math.pi, math.pi))
                out = renderer.render(p + np.array([0.0, env_cfg.agent_height, 0.0]), quat_from_yaw(yaw),
                                      rgb=False, depth=True)
                d = normalize_depth(out.depth, env_cfg.min_depth, env_cfg.max_depth, True)[..., 0]
                d = d.reshape(d.shape[0] // 2, 2, d.shape[1] // 2, 2).mean(axis=(1, 3))  # the net's 2x2 pool
                depth.append(np.round(d * 255).astype(np.uint8))
                free.append(free_distances(navgrid, p, yaw, cfg.ray_headings_deg, cfg.ray_range))
                patch.append(navigability_patch(navgrid, p, yaw, fwd, right))
    order = rng.permutation(len(depth))
    return {"depth": np.stack(depth)[order], "free": np.stack(free)[order], "patch": np.stack(patch)[order]}


def load_or_generate(cfg: PretrainConfig, path: Path) -> dict[str, np.ndarray]:
    """The frame set for ``cfg``, cached at ``path`` (it takes a few minutes to render)."""
    key = json.dumps({k: v for k, v in dataclasses.asdict(cfg).items()
                      if k in ("frames_per_scene", "ray_headings_deg", "ray_range", "patch_cells",
                               "patch_cell_size", "seed")}, sort_keys=True)
    if path.is_file():
        with np.load(path) as z:
            if str(z["key"]) == key:
                return {k: z[k] for k in ("depth", "free", "patch")}
    data = generate(cfg)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, key=np.array(key), **data)
    tmp.replace(path)
    return data


# ------------------------------------------------------------------------------------------ training
class GeometryHead(torch.nn.Module):
    """Training-only head: visual_fc's 512-d output -> free-space rays and patch logits."""

    def __init__(self, dim: int, rays: int, patch_cells: int):
        super().__init__()
        self.rays = rays
        self.linear = torch.nn.Linear(dim, rays + patch_cells * patch_cells)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        y = self.linear(x)
        return y[:, :self.rays], y[:, self.rays:]


def batch_tensors(data: dict[str, np.ndarray], idx: np.ndarray, flip: np.ndarray | None = None
                  ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Depth (B, 1, 112, 112) float in [0, 1], free (B, R), patch (B, C, C); ``flip`` mirrors left-right."""
    depth = data["depth"][idx].astype(np.float32) / 255.0
    free = data["free"][idx].copy()
    patch = data["patch"][idx].astype(np.float32)
    if flip is not None:
        depth[flip] = depth[flip][:, :, ::-1]
        free[flip] = free[flip][:, ::-1]  # headings run right-to-left symmetric about 0
        patch[flip] = patch[flip][:, :, ::-1]  # columns are "right" offsets, symmetric about 0
    return (torch.from_numpy(np.ascontiguousarray(depth))[:, None], torch.from_numpy(np.ascontiguousarray(free)),
            torch.from_numpy(np.ascontiguousarray(patch)))


def encoder_features(policy: PointNavResNetPolicy, pooled: torch.Tensor) -> torch.Tensor:
    """visual_fc output for pooled depth (B, 1, h, w): the net pools 2x2 first, so upsample 2x to undo it."""
    depth = pooled.repeat_interleave(2, dim=-1).repeat_interleave(2, dim=-2)
    depth = depth.contiguous(memory_format=torch.channels_last)
    return policy.net.visual_fc(policy.net.visual_encoder(depth))


def losses(policy, head, batch, mask: torch.Tensor, cfg: PretrainConfig) -> dict[str, torch.Tensor]:
    depth, free, patch = batch
    pred_free, pred_patch = head(encoder_features(policy, depth))
    m = mask.reshape(-1).expand(len(depth), -1)
    logits, target = pred_patch[m.bool()], patch.reshape(len(depth), -1)[m.bool()]
    out = {"free_mse": F.mse_loss(pred_free, free),
           "patch_bce": F.binary_cross_entropy_with_logits(logits, target)}
    out["loss"] = out["free_mse"] + cfg.patch_weight * out["patch_bce"]
    with torch.no_grad():
        out["free_mae_m"] = (pred_free - free).abs().mean() * cfg.ray_range
        out["patch_acc"] = ((logits > 0).float() == target).float().mean()
    return out


def pretrain(cfg: PretrainConfig, out: Path, state_dir: Path, resume: bool = False, log=print,
             device: str = "cpu") -> dict[str, float]:
    """Pre-train the visual encoder under ``cfg`` (or resume from ``state_dir``); the updates run on ``device``
    (resolved), the frames are rendered on the CPU."""
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    out, state_dir = Path(out), Path(state_dir)
    state_dir.mkdir(parents=True, exist_ok=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    log_path = out.with_suffix(".log.csv")
    t0 = time.time()
    data = load_or_generate(cfg, state_dir / "frames.npz")
    n = len(data["depth"])
    log(f"{n} frames ready in {time.time() - t0:.0f} s")
    train_n = n - cfg.heldout_frames
    fwd, right = patch_offsets(cfg.patch_cells, cfg.patch_cell_size)
    mask = torch.from_numpy(fov_mask(fwd, right, EnvConfig.hfov_deg).astype(np.float32)).to(device)

    policy = PointNavResNetPolicy(PolicyNetConfig()).to(device, memory_format=torch.channels_last)
    head = GeometryHead(policy.net.visual_fc[1].out_features, len(cfg.ray_headings_deg), cfg.patch_cells).to(device)
    params = list(policy.net.visual_encoder.parameters()) + list(policy.net.visual_fc.parameters()) + \
        list(head.parameters())
    opt = torch.optim.AdamW(params, lr=cfg.lr, weight_decay=cfg.weight_decay)
    floor = cfg.min_lr / cfg.lr
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda u: min(1.0, (u + 1) / cfg.warmup) * (
        floor + (1 - floor) * 0.5 * (1 + math.cos(math.pi * min(u, cfg.updates) / cfg.updates))))
    state_path = state_dir / "pretrain_state.pt"
    start, wall0 = 0, 0.0
    if resume and state_path.is_file():
        st = torch.load(state_path, weights_only=False)
        policy.load_state_dict(st["policy"])
        head.load_state_dict(st["head"])
        opt.load_state_dict(st["optimizer"])
        sched.load_state_dict(st["scheduler"])
        start, wall0 = st["update"], st["wall_s"]
        log(f"resumed at update {start}")
    elif log_path.exists():
        log_path.unlink()
    rng = np.random.default_rng([cfg.seed, start])
    t_start = time.time() - wall0
    heldout = np.arange(train_n, n)
    last: dict[str, float] = {}
    running: dict[str, list[float]] = {}
    policy.train()
    for u in progress(range(start, cfg.updates), desc="encoder updates"):
        idx = rng.integers(train_n, size=cfg.batch_size)
        batch = tuple(t.to(device) for t in batch_tensors(data, idx, flip=rng.random(cfg.batch_size) < 0.5))
        with torch.autocast(torch.device(device).type, dtype=torch.bfloat16, enabled=cfg.bf16):
            res = losses(policy, head, batch, mask, cfg)
        opt.zero_grad(set_to_none=True)
        res["loss"].backward()
        torch.nn.utils.clip_grad_norm_(params, 1.0)
        opt.step()
        sched.step()
        for k, v in res.items():
            running.setdefault(k, []).append(float(v.detach()))
        done = u + 1
        if done % cfg.log_every == 0 or done == cfg.updates:
            policy.eval()
            with torch.inference_mode():
                val = [losses(policy, head, tuple(t.to(device) for t in batch_tensors(data, heldout[i:i + 256])),
                              mask, cfg)
                       for i in range(0, len(heldout), 256)]
            policy.train()
            last = {"update": done, "samples": done * cfg.batch_size, "lr": sched.get_last_lr()[0],
                    **{f"train_{k}": float(np.mean(v)) for k, v in running.items()},
                    **{f"val_{k}": float(np.mean([float(r[k]) for r in val])) for k in val[0]},
                    "wall_s": time.time() - t_start}
            running = {}
            log(log_row(log_path, last))
        if done % cfg.save_every == 0 or done == cfg.updates:
            save_checkpoint(out, policy, {"pretrain_config": dataclasses.asdict(cfg), "update": done,
                                          "frames": n, "wall_s": time.time() - t_start,
                                          **{k: v for k, v in last.items() if k.startswith("val_")}})
            save_train_state(state_path, {"policy": policy.state_dict(), "head": head.state_dict(),
                                          "optimizer": opt.state_dict(), "scheduler": sched.state_dict(),
                                          "update": done, "wall_s": time.time() - t_start})
    return last


def main(cfg: PretrainConfig, out: Path, state_dir: Path, resume: bool, device: str = "cpu") -> dict[str, float]:
    """``navbench train encoder``: pre-train, print the last log row as JSON."""
    result = pretrain(cfg, out, state_dir, resume=resume, device=device)
    print(json.dumps(result))
    return result
