"""The OpenGL platform navbench renders on, chosen before anything imports PyOpenGL.

Importing this module sets ``PYOPENGL_PLATFORM`` unless it is already set: ``egl`` when a GPU EGL can
render on is present (:func:`egl_device_present`), else ``osmesa`` (a CPU-only machine renders on
OSMesa, as the reference records were). Set it before the first import to choose. It also sets
``LP_NUM_THREADS`` to 0 unless set (fork safety, below), and points PyOpenGL's OSMesa at :mod:`.osmesa_local`,
which keeps Mesa's LLVM out of the global symbols (triton carries another). Every module of
:mod:`navbench.render` that imports PyOpenGL or pyrender imports this one first; ``gl_platform="auto"`` means
the bound platform.
"""

from __future__ import annotations

import ctypes.util
import glob
import importlib.util
import os
import sys
import warnings


def egl_device_present() -> bool:
    """Whether EGL has a GPU to render on: an NVIDIA device node with NVIDIA's EGL library (a container
    started without the graphics capability has the node but not the library), or a DRM render node with
    Mesa's. Mesa's EGL also runs on llvmpipe without a GPU, but there OSMesa's direct draw path is faster."""
    if ctypes.util.find_library("EGL") is None:
        return False
    if glob.glob("/dev/nvidia[0-9]*") and ctypes.util.find_library("EGL_nvidia") is not None:
        return True
    return bool(glob.glob("/dev/dri/renderD*")) and ctypes.util.find_library("EGL_mesa") is not None


def auto_platform() -> str:
    """What ``gl_platform="auto"`` binds when ``PYOPENGL_PLATFORM`` is not set: EGL on a GPU, else OSMesa."""
    return "egl" if egl_device_present() else "osmesa"


# PyOpenGL binds its platform on first import, so this must run before pyrender is imported.
if not os.environ.get("PYOPENGL_PLATFORM"):
    os.environ["PYOPENGL_PLATFORM"] = auto_platform()
# llvmpipe (OSMesa) starts its rasterizer threads with the first GL context and keeps them for the
# life of the process; a process forked after that (multiprocessing's default on Linux, e.g.
# Gymnasium's AsyncVectorEnv) inherits the thread pool without its threads and hangs on its first
# draw. Rasterizing on the calling thread keeps forked workers usable and is no slower at agent
# resolutions (benchmarks/render_anchor.py --lp 0 / --lp 2 on 2 shared cores: the same frames/s and
# CPU per frame within noise, for navbench and the plain pyrender path alike); Mesa reads this when
# the first context is created. It cannot be left to forked children: what hangs is the parent's
# llvmpipe state, made with the parent's first context, before anyone knows a fork will follow.
os.environ.setdefault("LP_NUM_THREADS", "0")

import OpenGL.plugins  # noqa: E402 (registers PyOpenGL's platform plug-ins; binds none)

# PyOpenGL binds its platform when OpenGL.platform is first imported: before that, its osmesa plug-in is
# pointed at the platform that keeps Mesa's LLVM out of the global symbols (see osmesa_local).
if "OpenGL.platform" not in sys.modules:
    _plugin = OpenGL.plugins.PlatformPlugin.by_name("osmesa")
    if _plugin is not None:
        _plugin.import_path = "navbench.render.osmesa_local.LocalOSMesaPlatform"

import OpenGL.platform  # noqa: E402


def _preload_triton_deepbind() -> bool:
    """Load triton's native library (if installed) with ``RTLD_DEEPBIND``, so it binds its own LLVM symbols
    before Mesa's already global ones; ``import triton`` later finds it loaded. False when there is none."""
    spec = importlib.util.find_spec("triton")  # finds the package without importing it
    roots = list(spec.submodule_search_locations or []) if spec is not None else []
    libs = sorted(glob.glob(os.path.join(roots[0], "_C", "libtriton*.so"))) if roots else []
    if not libs:
        return False
    ctypes.CDLL(libs[0], mode=os.RTLD_NOW | os.RTLD_LOCAL | os.RTLD_DEEPBIND)
    return True


# PyOpenGL was imported before navbench and loaded libOSMesa (and Mesa's LLVM) globally: a later
# `import triton` (torch.optim does it) would bind triton's LLVM to Mesa's and crash, unless triton's
# library binds itself first.
if type(OpenGL.platform.PLATFORM).__module__ == "OpenGL.platform.osmesa" and importlib.util.find_spec("triton"):
    try:
        if not _preload_triton_deepbind():
            raise OSError("no triton/_C/libtriton*.so")
    except OSError as exc:
        warnings.warn(f"PyOpenGL loaded OSMesa (and Mesa's LLVM) globally before navbench was imported, and "
                      f"triton's library could not be loaded first ({exc}): `import triton` (torch.optim does "
                      f"it) may crash the process; import navbench before pyrender or OpenGL",
                      RuntimeWarning, stacklevel=2)

PLATFORMS = ("osmesa", "egl")
AUTO = "auto"  # the platform PyOpenGL is bound to (EnvConfig.gl_platform's default)


def bound_platform() -> str:
    """The platform PyOpenGL bound itself to on first import: "osmesa", "egl", or another module name."""
    # the first of PyOpenGL's own platform classes in the MRO (LocalOSMesaPlatform is an OSMesaPlatform)
    module = next((c.__module__ for c in type(OpenGL.platform.PLATFORM).__mro__
                   if c.__module__.startswith("OpenGL.platform.")), type(OpenGL.platform.PLATFORM).__module__)
    return module.rsplit(".", 1)[-1]
