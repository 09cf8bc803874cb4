"""The render anchor's plain pyrender path: FLAT RGB-D or DEPTH_ONLY on the scene merged into one node.

The plainest fast way to render with pyrender on OSMesa: one ``OffscreenRenderer``, the static scene
merged into a single mesh node (vertex colours kept), and pyrender's shader cache made to hit under
OSMesa (the context id normalised to an integer), with nothing of navbench. It renders the anchor's
300 poses (``benchmarks/anchor_scenes.py``) at 224x224, HFOV 79 deg, after 30 warm-up frames, and
prints one JSON line: frames/s per pass (``fps``, median ``fps_med``) and CPU ms per frame.

    SBS_DIR=/tmp/sbs PYOPENGL_PLATFORM=osmesa python benchmarks/anchor_pyrender.py simple rgbd 3
"""

import ctypes
import json
import os
import statistics as st
import sys
import time
from pathlib import Path

assert os.environ.get("PYOPENGL_PLATFORM") == "osmesa", "set PYOPENGL_PLATFORM=osmesa"

import OpenGL.contextdata  # noqa: E402

_get_context = OpenGL.contextdata.getContext


def _context_id(context=None):
    """The current context as an integer address, so pyrender's shader cache hits under OSMesa."""
    value = _get_context(context)
    return value if isinstance(value, int) else ctypes.cast(value, ctypes.c_void_p).value


OpenGL.contextdata.getContext = _context_id

import numpy as np  # noqa: E402
import pyrender  # noqa: E402
import trimesh  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import anchor_scenes  # noqa: E402

W = H = 224
HFOV = np.deg2rad(79.0)


def main() -> None:
    scene, mode = sys.argv[1], sys.argv[2]
    reps = int(sys.argv[3]) if len(sys.argv) > 3 else 5
    poses = anchor_scenes.mats()
    loaded = trimesh.load(str(anchor_scenes.scene_path(os.environ.get("SBS_DIR", "."), scene)))
    merged = trimesh.util.concatenate(list(loaded.geometry.values()))  # one node, per-vertex colours kept
    ps = pyrender.Scene(bg_color=[0, 0, 0, 0], ambient_light=[0.6, 0.6, 0.6])
    ps.add(pyrender.Mesh.from_trimesh(merged, smooth=False))
    f = (W / 2) / np.tan(HFOV / 2)
    cam = ps.add(pyrender.IntrinsicsCamera(fx=f, fy=f, cx=W / 2, cy=H / 2, znear=0.05, zfar=50.0), pose=poses[0])
    r = pyrender.OffscreenRenderer(W, H)
    flags = {"rgbd": pyrender.RenderFlags.FLAT, "depth": pyrender.RenderFlags.DEPTH_ONLY}[mode]

    def frame(i: int):
        ps.set_pose(cam, poses[i])
        return r.render(ps, flags=flags)

    for i in range(30):  # warm-up
        frame(i)
    fps, cpu, t0s, t1s = [], [], [], []
    for _ in range(reps):
        a, c = time.time(), time.process_time()
        for i in range(len(poses)):
            frame(i)
        b = time.time()
        fps.append(len(poses) / (b - a))
        cpu.append(1e3 * (time.process_time() - c) / len(poses))
        t0s.append(a)
        t1s.append(b)
    print(json.dumps(dict(engine="pyrender", scene=scene, mode=mode, LP=os.environ.get("LP_NUM_THREADS", "dflt"),
                          fps_med=st.median(fps), fps=[round(x, 1) for x in fps],
                          cpu_ms_per_frame=round(st.median(cpu), 2), t_start=t0s[0], t_end=t1s[-1],
                          frames=len(poses) * reps)), flush=True)
    r.delete()


if __name__ == "__main__":
    main()
