"""Does navbench run right, and fast, on this machine's GPU? One table; exit 1 when a check fails.

    PYTHONPATH=$PWD python benchmarks/gpu_check.py [--device cuda:N] [--episodes 20] [--seconds 2]

Checks, each against the CPU on the same machine:

- the shipped PointNav policy's logits on the GPU (batch 16, eight recurrent steps): the largest difference
  and how often the argmax agrees;
- a PointNav val run of ``--episodes`` episodes (the shipped policy, its default decoding) on the GPU and on
  the CPU: how many episodes end the same (success and steps), SR and SPL of each;
- the real perception backends (SigLIP2, Qwen2.5-VL, SAM 3) on tiny random checkpoints
  (benchmarks/tiny_models.py; skipped without transformers): forward passes on the GPU agree with the CPU's;
- EGL against OSMesa: the same 16 views of a bundled house rendered by each (skipped without libEGL);
- speed: policy frames/s at batch 1, 8 and 64 on the GPU; EGL RGB-D frames/s at 224x224.

Without CUDA it prints one line and exits 0. ``--device cpu`` runs every check with the CPU on both sides
(what the tests use to exercise the script where there is no GPU). Under 5 minutes on one GPU.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


@dataclass
class Row:
    check: str
    value: str
    criterion: str
    ok: bool | None  # None: a figure, or skipped


def _table(rows: list[Row]) -> str:
    verdict = {True: "ok", False: "FAIL", None: "-"}
    lines = ["| check | value | passes when | result |", "|---|---|---|---|"]
    lines += [f"| {r.check} | {r.value} | {r.criterion} | {verdict[r.ok]} |" for r in rows]
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------------ checks
def policy_logits(device: str) -> list[Row]:
    import torch

    from navbench.agents.options import DEFAULT_CHECKPOINT
    from navbench.policy.checkpoint import load_checkpoint
    from navbench.policy.net import prepare_depth

    rng = np.random.default_rng(0)
    n, steps = 16, 8
    depth = prepare_depth(rng.random((steps * n, 224, 224, 1), dtype=np.float32)).reshape(steps, n, 224, 224, 1)
    goal = torch.as_tensor(np.stack([rng.uniform(0.5, 5, (steps, n)), rng.uniform(-3, 3, (steps, n))], -1),
                           dtype=torch.float32)
    prev = torch.as_tensor(rng.integers(0, 4, (steps, n)))
    masks = torch.ones(steps, n, dtype=torch.bool)
    masks[0] = False
    out = {}
    for d in ("cpu", device):
        policy = load_checkpoint(DEFAULT_CHECKPOINT).eval().to(d)
        with torch.inference_mode():
            logits, _, _ = policy(depth.to(d), goal.to(d), prev.to(d), masks.to(d), policy.initial_hidden(n, d))
        out[d] = logits.float().cpu()
    diff = float((out["cpu"] - out[device]).abs().max())
    same = float((out["cpu"].argmax(-1) == out[device].argmax(-1)).float().mean())
    same_n = n * steps
    # cuDNN convolutions run in TF32 by default (torch.backends.cudnn.allow_tf32), as in a run
    return [Row("policy logits, max abs diff vs CPU", f"{diff:.2e}", "< 5e-2", diff < 5e-2),
            Row("policy argmax agreement vs CPU", f"{100 * same:.1f}% of {same_n}", ">= 97%", same >= 0.97)]


def pointnav_run(device: str, episodes: int, work: Path) -> list[Row]:
    import navbench
    from navbench.loop_progress import silenced

    res = {}
    for d in ("cpu", device):
        out = work / f"pointnav_{d.replace(':', '')}"
        with silenced():
            s = navbench.evaluate("pointnav", task="pointnav", split="val", limit=episodes, out=out, overwrite=True,
                                  device=d)
        recs = {r["episode_id"]: r for r in map(json.loads, open(out / "episodes.jsonl"))}
        res[d] = (s, recs)
    (cs, cr), (gs, gr) = res["cpu"], res[device]
    same = sum(cr[k]["success"] == gr[k]["success"] and cr[k]["num_steps"] == gr[k]["num_steps"] for k in cr)
    failed = cs["num_failed"] + gs["num_failed"]
    dsr, dspl = abs(cs["success"] - gs["success"]), abs(cs["spl"] - gs["spl"])
    return [Row(f"PointNav val, {episodes} episodes: outcomes equal to the CPU's", f"{same} of {len(cr)}",
                "(reported)", None),
            Row("PointNav SR: CPU / GPU", f"{100 * cs['success']:.1f} / {100 * gs['success']:.1f}",
                "no failed episode; |diff| <= 15 points", failed == 0 and dsr <= 0.15),
            Row("PointNav SPL: CPU / GPU", f"{100 * cs['spl']:.1f} / {100 * gs['spl']:.1f}",
                "|diff| <= 15 points", dspl <= 0.15)]


def backends(device: str, work: Path) -> list[Row]:
    try:
        import tokenizers  # noqa: F401
        import transformers  # noqa: F401
    except ImportError as exc:
        return [Row("real-model backends", f"skipped ({exc.name} not installed)", "-", None)]
    sys.path.insert(0, str(HERE))
    from tiny_models import write_all

    from navbench.localize.backends import QwenVLReranker, Sam3Segmenter, Siglip2Encoder

    dirs = write_all(work / "tiny_models")
    rng = np.random.default_rng(1)
    images = [rng.integers(0, 256, size=(60, 80, 3), dtype=np.uint8) for _ in range(4)]
    rows = []
    enc = {d: Siglip2Encoder(dirs["siglip2"], device=d) for d in ("cpu", device)}
    cos = min(float(np.sum(enc["cpu"].encode_images(images) * enc[device].encode_images(images), 1).min()),
              float(np.sum(enc["cpu"].encode_text(["red chair", "bed"]) * enc[device].encode_text(["red chair", "bed"]),
                           1).min()))
    rows.append(Row("SigLIP2 embeddings: min cosine to the CPU's", f"{cos:.6f}", "> 0.999", cos > 0.999))
    bf16 = Siglip2Encoder(dirs["siglip2"], device=device, precision="bf16").encode_images(images)
    cos16 = float(np.sum(enc["cpu"].encode_images(images) * bf16, 1).min())
    rows.append(Row("SigLIP2 bf16 embeddings: min cosine to the CPU's fp32", f"{cos16:.4f}", "> 0.98", cos16 > 0.98))
    vlm = {d: QwenVLReranker(dirs["qwen_vl"], device=d, max_new_tokens=4) for d in ("cpu", device)}
    replies = [(vlm["cpu"].reply(im, "red chair"), vlm[device].reply(im, "red chair")) for im in images]
    # a random model's next-token logits lie close together: a near tie may break the other way
    rows.append(Row("Qwen2.5-VL greedy replies equal to the CPU's", f"{sum(a == b for a, b in replies)} of "
                    f"{len(replies)}", ">= 2 of 4", sum(a == b for a, b in replies) >= 2))
    seg = {d: Sam3Segmenter(dirs["sam3"], device=d, score_threshold=0.0) for d in ("cpu", device)}
    outs = [(seg["cpu"].segment(im, "red chair"), seg[device].segment(im, "red chair")) for im in images]
    dscore = max(abs(a[1] - b[1]) for a, b in outs)
    agree = min(1.0 if a[0] is None and b[0] is None else
                float(np.mean(a[0] == b[0])) if a[0] is not None and b[0] is not None else 0.0 for a, b in outs)
    # a random model's mask logits sit near the threshold, so the masks' agreement is reported, not judged
    rows.append(Row("SAM 3: max score diff / min mask agreement vs CPU", f"{dscore:.2e} / {100 * agree:.2f}%",
                    "score < 1e-2", dscore < 1e-2))
    return rows


_RENDER = """
import json, sys, time
import numpy as np
from navbench.render import Renderer
from navbench.render.gl_platform import bound_platform
from navbench.scene.asset import load_scene
scene, poses_file, out_file, seconds = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
poses = np.load(poses_file)
try:
    r = Renderer(load_scene(scene))
except Exception as exc:
    print(json.dumps({"error": f"{type(exc).__name__}: {exc}"[:200]})); sys.exit(0)
frames = [r.render(p, q, rgb=True, depth=True, ids=True) for p, q in zip(poses["pos"], poses["rot"])]
np.savez(out_file, rgb=np.stack([f.rgb for f in frames]), depth=np.stack([f.depth for f in frames]),
         ids=np.stack([f.ids for f in frames]))
n, t0 = 0, time.perf_counter()
while time.perf_counter() - t0 < seconds:
    p, q = poses["pos"][n % len(poses["pos"])], poses["rot"][n % len(poses["rot"])]
    r.render(p, q, rgb=True, depth=True)
    n += 1
print(json.dumps({"platform": bound_platform(), "fps": n / (time.perf_counter() - t0)}))
"""


def _render(platform: str, scene: Path, poses: Path, out: Path, seconds: float) -> dict:
    env = {**os.environ, "PYOPENGL_PLATFORM": platform, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    res = subprocess.run([sys.executable, "-c", _RENDER, str(scene), str(poses), str(out), str(seconds)],
                         env=env, capture_output=True, text=True, timeout=300)
    if res.returncode != 0:
        return {"error": (res.stderr.strip().splitlines() or [f"exit {res.returncode}"])[-1][:200]}
    return json.loads(res.stdout.strip().splitlines()[-1])


def egl_vs_osmesa(work: Path, seconds: float) -> list[Row]:
    from navbench.bench.speed import default_scene
    from navbench.scene.asset import load_scene
    from navbench.scene.navigability import NavGrid, NavGridConfig
    from navbench.scene.pose import quat_from_yaw

    scene = default_scene()
    grid = NavGrid.from_mesh(load_scene(scene).mesh, NavGridConfig())
    rng = np.random.default_rng(0)
    pos = np.stack([grid.sample_navigable_point(rng) + np.array([0.0, 0.88, 0.0]) for _ in range(16)])
    rot = np.stack([quat_from_yaw(float(y)) for y in rng.uniform(-np.pi, np.pi, 16)])
    np.savez(work / "poses.npz", pos=pos, rot=rot)
    got = {p: _render(p, scene, work / "poses.npz", work / f"{p}.npz", seconds) for p in ("osmesa", "egl")}
    if "error" in got["osmesa"]:
        return [Row("OSMesa renders", got["osmesa"]["error"], "renders", False)]
    if "error" in got["egl"]:
        return [Row("EGL vs OSMesa images", f"skipped (EGL: {got['egl']['error']})", "-", None)]
    a, b = np.load(work / "osmesa.npz"), np.load(work / "egl.npz")
    ids = float(np.mean(a["ids"] == b["ids"]))
    rgb = float(np.abs(a["rgb"].astype(np.int16) - b["rgb"].astype(np.int16)).mean())
    valid = (a["depth"] > 0) & (b["depth"] > 0)
    depth = float(np.percentile(np.abs(a["depth"] - b["depth"])[valid], 99)) if valid.any() else 0.0
    return [Row("EGL vs OSMesa: instance ids equal", f"{100 * ids:.3f}% of pixels", ">= 99.5%", ids >= 0.995),
            Row("EGL vs OSMesa: RGB mean abs diff", f"{rgb:.3f} / 255", "<= 2", rgb <= 2.0),
            Row("EGL vs OSMesa: depth 99th pct abs diff", f"{depth:.4f} m", "<= 0.01 m", depth <= 0.01),
            Row("OSMesa RGB-D frames/s, 224x224", f"{got['osmesa']['fps']:.0f}", "(figure)", None),
            Row("EGL RGB-D frames/s, 224x224", f"{got['egl']['fps']:.0f}", "(figure)", None)]


def policy_speed(device: str, seconds: float) -> list[Row]:
    import torch

    from navbench.agents.options import DEFAULT_CHECKPOINT
    from navbench.policy.checkpoint import load_checkpoint
    from navbench.policy.net import InferenceConfig
    from navbench.policy.speed import inference_rate

    torch.backends.cudnn.benchmark = True
    policy = load_checkpoint(DEFAULT_CHECKPOINT)
    return [Row(f"policy frames/s on {device}, batch {n}",
                f"{inference_rate(policy, n, InferenceConfig(decoding='argmax'), seconds, device):.0f}", "(figure)",
                None) for n in (1, 8, 64)]


# ------------------------------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--device", default="cuda", help="the GPU to check (default cuda; cpu: both sides the CPU)")
    p.add_argument("--episodes", type=int, default=20, help="PointNav val episodes run on each device")
    p.add_argument("--seconds", type=float, default=2.0, help="time per speed figure")
    p.add_argument("--skip", action="append", default=[], choices=("policy", "pointnav", "backends", "render", "speed"))
    args = p.parse_args(argv)

    import torch

    from navbench.device import DeviceError, resolve_device
    if args.device != "cpu" and not torch.cuda.is_available():
        print(f"gpu_check: skipped, torch {torch.__version__} sees no CUDA device")
        return 0
    try:
        device = resolve_device(args.device)
    except DeviceError as exc:
        print(f"gpu_check: {exc}", file=sys.stderr)
        return 2
    where = torch.cuda.get_device_name(torch.device(device)) if device.startswith("cuda") else "the CPU"
    t0 = time.perf_counter()
    rows: list[Row] = []
    with tempfile.TemporaryDirectory(prefix="navbench-gpu-check-") as tmp:
        work = Path(tmp)
        os.environ.setdefault("NAVBENCH_CACHE", str(work / "cache"))
        checks = [("policy", lambda: policy_logits(device)),
                  ("pointnav", lambda: pointnav_run(device, args.episodes, work)),
                  ("backends", lambda: backends(device, work)),
                  ("render", lambda: egl_vs_osmesa(work, args.seconds)),
                  ("speed", lambda: policy_speed(device, args.seconds))]
        for name, check in checks:
            if name in args.skip:
                continue
            try:
                with contextlib.redirect_stdout(sys.stderr):
                    rows += check()
            except Exception as exc:  # a check that crashes is a failed check, and the others still run
                rows.append(Row(name, f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"[:160],
                                "runs", False))
    print(f"navbench GPU check on {device} ({where}), torch {torch.__version__}, "
          f"{time.perf_counter() - t0:.0f} s\n")
    print(_table(rows))
    failed = [r.check for r in rows if r.ok is False]
    print(f"\n{len(failed)} check(s) failed" + (": " + "; ".join(failed) if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
