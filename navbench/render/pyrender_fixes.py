"""Two corrections to pyrender's behaviour: its shader cache under OSMesa, and multisampling on EGL.

Importing this module patches pyrender's shader cache (see :func:`patch_shader_cache`).
"""

from __future__ import annotations

# isort: off
import navbench.render.gl_platform  # noqa: F401  (first: binds the platform before OpenGL is imported)
# isort: on

import contextlib
import ctypes
import functools
from collections.abc import Iterator

import OpenGL.contextdata
import pyrender
import pyrender.renderer
import pyrender.shader_program


def _context_address(ctx: object) -> object:
    """The integer address behind a GL context handle (OSMesa gives a fresh ctypes pointer per call)."""
    if isinstance(ctx, int):
        return ctx
    if isinstance(ctx, ctypes.c_void_p):
        return ctx.value
    try:
        return ctypes.cast(ctx, ctypes.c_void_p).value
    except (TypeError, ctypes.ArgumentError):
        return ctx


def patch_shader_cache() -> None:
    """Make ``ShaderProgramCache.get_program`` hit its cache under OSMesa. Idempotent.

    pyrender keys compiled programs by ``(OpenGL.contextdata.getContext(), shaders, defines)``.
    Under OSMesa ``getContext()`` returns a new ctypes pointer object on every call, and ctypes
    pointers hash by identity, so the lookup never hits: every draw compiles a new program and the
    cache grows without bound. The wrapper looks programs up under a key built from the context's
    integer address instead and re-files what the original method compiled under that key, so
    ``clear()`` still deletes every program exactly once.
    """
    cache_cls = pyrender.shader_program.ShaderProgramCache
    if getattr(cache_cls.get_program, "_navbench_patched", False):
        return
    original = cache_cls.get_program

    @functools.wraps(original)
    def get_program(self, vertex_shader, fragment_shader, geometry_shader=None, defines=None):
        defines = {} if defines is None else defines
        key = (
            "navbench",
            _context_address(OpenGL.contextdata.getContext()),
            vertex_shader,
            fragment_shader,
            geometry_shader,
            tuple(sorted(defines.items())),
        )
        program = self._program_cache.get(key)
        if program is None:
            program = original(self, vertex_shader, fragment_shader, geometry_shader, defines)
            for stale in [k for k, v in self._program_cache.items() if v is program]:
                del self._program_cache[stale]
            self._program_cache[key] = program
        return program

    get_program._navbench_patched = True  # type: ignore[attr-defined]
    cache_cls.get_program = get_program


patch_shader_cache()


@contextlib.contextmanager
def multisample_disabled() -> Iterator[None]:
    """Within the block, pyrender's ``glEnable(GL_MULTISAMPLE)`` (forward pass) becomes a disable."""
    enable = pyrender.renderer.glEnable

    def gl_enable(cap: int) -> None:
        if cap == pyrender.renderer.GL_MULTISAMPLE:
            pyrender.renderer.glDisable(cap)
        else:
            enable(cap)

    pyrender.renderer.glEnable = gl_enable
    try:
        yield
    finally:
        pyrender.renderer.glEnable = enable
