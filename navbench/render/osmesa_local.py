"""PyOpenGL's OSMesa platform with libOSMesa loaded ``RTLD_LOCAL``, so Mesa's LLVM stays out of the global symbols.

Mesa's llvmpipe links a shared libLLVM (``libLLVM-15.so`` on Debian 12). PyOpenGL loads libOSMesa with
``RTLD_GLOBAL`` (``OpenGL/platform/osmesa.py``), which puts that libLLVM's symbols in the process's global
scope. triton's ``libtriton.so`` carries its own LLVM and exports its symbols; loaded after Mesa's, its static
initialisers (``PassBuilder.cpp``'s debug counters) bind to Mesa's copy and crash on the first ``import
triton``, which ``torch.optim`` does through ``torch._dynamo``. Loaded locally, each library keeps its own
LLVM. PyOpenGL finds GL functions through ``OSMesaGetProcAddress`` and this handle, never the global scope.
:mod:`navbench.render.gl_platform` points PyOpenGL's ``osmesa`` plug-in here before it binds a platform.
"""

from __future__ import annotations

import ctypes

from OpenGL.platform import baseplatform, ctypesloader
from OpenGL.platform.osmesa import OSMesaPlatform


class LocalOSMesaPlatform(OSMesaPlatform):
    """:class:`OSMesaPlatform` whose libOSMesa (and the libLLVM it links) is loaded ``RTLD_LOCAL``."""

    @baseplatform.lazy_property
    def GL(self):  # noqa: N802 (PyOpenGL's name)
        try:
            return ctypesloader.loadLibrary(ctypes.cdll, "OSMesa", mode=ctypes.RTLD_LOCAL)
        except OSError as err:
            raise ImportError("Unable to load OpenGL library", *err.args) from None
