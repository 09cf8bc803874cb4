"""The OpenGL platform navbench renders on, chosen before anything imports PyOpenGL.

Importing this module sets ``PYOPENGL_PLATFORM`` to ``osmesa`` unless it is already set (set it to
``egl`` before the first import to use EGL) and ``LP_NUM_THREADS`` to 0 unless set (fork safety,
below). Every module of :mod:`navbench.render` that imports PyOpenGL or pyrender imports this one first.
"""

from __future__ import annotations

import os

# PyOpenGL binds its platform on first import, so this must run before pyrender is imported.
os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
# llvmpipe (OSMesa) starts its rasterizer threads with the first GL context and keeps them for the
# life of the process; a process forked after that (multiprocessing's default on Linux, e.g.
# Gymnasium's AsyncVectorEnv) inherits the thread pool without its threads and hangs on its first
# draw. Rasterizing on the calling thread keeps forked workers usable and is no slower at agent
# resolutions (benchmarks/render_anchor.py --lp 0 / --lp 2 on 2 shared cores: the same frames/s and
# CPU per frame within noise, for navbench and the plain pyrender path alike); Mesa reads this when
# the first context is created. It cannot be left to forked children: what hangs is the parent's
# llvmpipe state, made with the parent's first context, before anyone knows a fork will follow.
os.environ.setdefault("LP_NUM_THREADS", "0")

import OpenGL.platform  # noqa: E402

PLATFORMS = ("osmesa", "egl")


def bound_platform() -> str:
    """The platform PyOpenGL bound itself to on first import: "osmesa", "egl", or another module name."""
    return type(OpenGL.platform.PLATFORM).__module__.rsplit(".", 1)[-1]
