"""The renderer's per-frame draw path on OSMesa: pyrender's programs, buffers and state, without its Python.

Frames are one ``V`` uniform, a bind and a draw per visible chunk, and one ``glReadPixels`` per
image, rows top first (``GL_MESA_pack_invert``), straight into the output arrays. pyrender's
``render()`` (Python per node, per uniform and per state, and flipped copies of what it reads) cost
about as much as the rasterizing itself at 224x224. Images are pyrender's bit for bit
(tests/render/test_image_equality.py).
"""

from __future__ import annotations

# isort: off
import navbench.render.gl_platform  # noqa: F401  (first: binds the platform before OpenGL is imported)
# isort: on

import ctypes
import functools

import numpy as np
import OpenGL.platform
import pyrender
from OpenGL.GL import (
    GL_COLOR_BUFFER_BIT,
    GL_DEPTH_BUFFER_BIT,
    GL_DEPTH_COMPONENT,
    GL_FLOAT,
    GL_RGB,
    GL_RGBA,
    GL_TEXTURE_2D,
    GL_TRIANGLES,
    GL_UNSIGNED_BYTE,
    GL_UNSIGNED_INT,
)
from pyrender.constants import GLTF, RenderFlags

from navbench.render.camera import CameraConfig
from navbench.render.frame import RenderOutput

GL_PACK_INVERT_MESA = 0x8758  # GL_MESA_pack_invert: glReadPixels returns rows top first


@functools.cache
def raw_gl() -> dict:
    """The GL entry points of the per-frame path as plain ctypes functions of the bound GL library.

    PyOpenGL's wrappers convert arguments and call ``glGetError`` after every call (a few
    microseconds each, tens of calls a frame); these call the library directly. Mesa's exported
    ``gl*`` symbols dispatch to the current context.
    """
    lib = OpenGL.platform.PLATFORM.GL
    u, i, f, p = ctypes.c_uint, ctypes.c_int, ctypes.c_float, ctypes.c_void_p
    sigs = {
        "glClear": (u,), "glUseProgram": (u,), "glBindVertexArray": (u,), "glBindTexture": (u, u),
        "glColorMask": (ctypes.c_ubyte,) * 4, "glUniformMatrix4fv": (i, i, ctypes.c_ubyte, p),
        "glUniform1f": (i, f), "glUniform1i": (i, i), "glUniform3fv": (i, i, p), "glUniform4fv": (i, i, p),
        "glDrawElementsInstanced": (u, i, u, p, i), "glReadPixels": (i, i, i, i, u, u, p), "glFinish": (),
    }
    # Own function objects from prototypes (not ``getattr(lib, name)``, whose cached objects others may share).
    return {name: ctypes.CFUNCTYPE(None, *args)((name, lib)) for name, args in sigs.items()}


class DirectDraw:
    """The per-frame draw path on OSMesa: pyrender's compiled programs, vertex arrays, textures and GL
    state, without pyrender's per-frame Python.

    ``pyrender.Renderer.render`` re-derives per frame what never changes here: it walks every node
    and primitive, looks up the program (building its defines), queries every uniform location by
    name, sets the projection, model and material uniforms and about a dozen pieces of state per
    draw through PyOpenGL's checked wrappers, then reads colour and depth back with ``glReadPixels``
    into fresh arrays and flips them (a strided RGB copy alone is about 0.2 ms at 224x224). This
    class does the set-up once: the programs are the ones pyrender compiled for these primitives
    (same shaders, same defines), the constant uniforms (P, M, material factors, texture unit) and
    the state pyrender sets per draw (depth test LESS, back-face culling, blending ONE/ZERO, filled
    polygons) are set at construction, and a frame sets V, binds and draws, through ctypes
    (:func:`raw_gl`). So the rasterized fragments are pyrender's.

    Read-back: ``glReadPixels`` with ``GL_PACK_INVERT_MESA`` writes rows top first, so RGB goes
    straight into the output array and depth into a preallocated one, linearized with pyrender's
    formula, operation for operation in float32, into the output. Ids are read as RGBA words. A
    depth-only pass writes no colour (``glColorMask``): the depth shader's constant colour was
    never read. The fixture test (tests/render/test_image_equality.py) holds the images to the old
    path's, bit for bit at the time of writing.

    Holds no reference to its :class:`navbench.render.renderer.Renderer` (whose ``__del__`` frees the context).
    """

    @classmethod
    def create(cls, scene: pyrender.Scene, gl: pyrender.OffscreenRenderer, colour_nodes: list, id_nodes: list,
               box_min: np.ndarray, box_max: np.ndarray, camera: CameraConfig) -> DirectDraw | None:
        """The direct path, or None if some primitive needs state it does not reproduce, or Mesa
        lacks ``GL_MESA_pack_invert``."""
        from OpenGL import GL
        from pyrender.constants import TexFlags

        for node in colour_nodes + id_nodes:
            for prim in node.mesh.primitives:
                m = prim.material
                if (prim.mode != GLTF.TRIANGLES or prim.indices is None or prim.poses is not None
                        or not isinstance(m, pyrender.MetallicRoughnessMaterial) or m.alphaMode != "OPAQUE"
                        or m.wireframe or m.doubleSided or m.tex_flags & ~TexFlags.BASE_COLOR):
                    return None
        gl._platform.make_current()
        n = GL.glGetIntegerv(GL.GL_NUM_EXTENSIONS)
        if b"GL_MESA_pack_invert" not in {GL.glGetStringi(GL.GL_EXTENSIONS, k) for k in range(int(n))}:
            return None
        return cls(scene, gl, colour_nodes, id_nodes, box_min, box_max, camera)

    def __init__(self, scene, gl, colour_nodes, id_nodes, box_min, box_max, camera: CameraConfig) -> None:
        from OpenGL import GL
        from OpenGL.osmesa import OSMesaMakeCurrent
        from pyrender.constants import ProgramFlags, TexFlags

        self._gl = raw_gl()
        platform = gl._platform
        self._make_current = functools.partial(OSMesaMakeCurrent, platform._context, platform._buffer,
                                               GL.GL_UNSIGNED_BYTE, camera.width, camera.height)
        self._w, self._h = camera.width, camera.height
        self._znear, self._zfar, self._ortho = camera.znear, camera.zfar, camera.orthographic
        self._centre = (box_min + box_max) / 2.0
        r = gl._renderer
        platform.make_current()
        r._update_context(scene, RenderFlags.FLAT)  # upload buffers and textures, as render() would
        proj = scene.main_camera_node.camera.get_projection_matrix(camera.width, camera.height)
        programs: dict[int, dict] = {}

        def program(prim, flags) -> dict:
            prog = r._get_primitive_program(prim, flags, ProgramFlags.USE_MATERIAL)
            info = programs.get(prog._program_id)
            if info is None:
                pid = prog._program_id
                loc = {n: GL.glGetUniformLocation(pid, n) for n in (
                    "V", "P", "M", "material.emissive_factor", "material.base_color_factor",
                    "material.metallic_factor", "material.roughness_factor", "material.base_color_texture")}
                info = programs[pid] = {"id": pid, "loc": loc, "V": loc["V"], "material": None}
                GL.glUseProgram(pid)
                self._uniform_matrix(loc["P"], proj)
                self._uniform_matrix(loc["M"], np.eye(4))  # every chunk node sits at the origin
            return info

        def draws(nodes: list, flags: int) -> list[list[tuple]]:
            out = []
            for node in nodes:
                chunk = []
                for prim in node.mesh.primitives:
                    m = prim.material
                    tex = m.baseColorTexture._texid if m.tex_flags & TexFlags.BASE_COLOR else None
                    chunk.append((program(prim, flags), prim._vaid, int(prim.indices.size), m, tex))
                out.append(chunk)
            return out

        self._flat = draws(colour_nodes, RenderFlags.FLAT)
        self._depth = draws(colour_nodes, RenderFlags.DEPTH_ONLY)
        self._ids = draws(id_nodes, RenderFlags.FLAT)
        GL.glUseProgram(0)
        # The state pyrender's forward pass sets for FLAT and DEPTH_ONLY draws of opaque, one-sided,
        # filled triangles; nothing else touches this context's state after this.
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        GL.glReadBuffer(GL.GL_FRONT)
        GL.glViewport(0, 0, self._w, self._h)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDepthRange(0.0, 1.0)
        GL.glClearColor(0.0, 0.0, 0.0, 0.0)  # the scene's bg_color
        GL.glEnable(GL.GL_MULTISAMPLE)  # as pyrender; OSMesa's buffer has one sample
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
        GL.glEnable(GL.GL_BLEND)
        GL.glBlendFunc(GL.GL_ONE, GL.GL_ZERO)
        GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
        GL.glDisable(GL.GL_PROGRAM_POINT_SIZE)
        GL.glActiveTexture(GL.GL_TEXTURE0)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)  # tight rows for any width (RGB rows of odd widths)
        GL.glPixelStorei(GL_PACK_INVERT_MESA, 1)
        self._colour_mask = True
        self._zbuf = np.empty((self._h, self._w), np.float32)
        self._words = np.empty((self._h, self._w), np.uint32)

    def _uniform_matrix(self, loc: int, m: np.ndarray) -> None:
        if loc != -1:  # transposed, as pyrender's set_uniform passes it
            m = np.ascontiguousarray(m, dtype=np.float32)
            self._gl["glUniformMatrix4fv"](loc, 1, 1, m.ctypes.data)

    def _set_material(self, info: dict, m) -> None:
        gl, loc = self._gl, info["loc"]
        for name, value in (("material.emissive_factor", m.emissiveFactor),
                            ("material.base_color_factor", m.baseColorFactor)):
            if loc[name] != -1:
                v = np.ascontiguousarray(value, dtype=np.float32)
                gl["glUniform3fv" if v.size == 3 else "glUniform4fv"](loc[name], 1, v.ctypes.data)
        for name, value in (("material.metallic_factor", m.metallicFactor),
                            ("material.roughness_factor", m.roughnessFactor)):
            if loc[name] != -1:
                gl["glUniform1f"](loc[name], float(value))
        if loc["material.base_color_texture"] != -1:
            gl["glUniform1i"](loc["material.base_color_texture"], 0)
        info["material"] = m

    def render(self, pose: np.ndarray, view: np.ndarray, keep: np.ndarray | None, rgb: bool, depth: bool,
               ids: bool, rgba: bool = False) -> RenderOutput:
        """One frame; ``keep`` flags the chunks to draw (None: all, in order); ``rgba``: the colour as RGBA."""
        self._make_current()
        if keep is None:
            idx = range(len(self._flat))
        else:
            idx = np.flatnonzero(keep)
            if len(idx) > 1:  # near to far, as Renderer._show orders pyrender's draw list
                idx = idx[np.argsort(np.linalg.norm(self._centre[idx] - pose[:3, 3], axis=1), kind="stable")]
        v = np.ascontiguousarray(view, dtype=np.float32)
        out = RenderOutput(rgb=None, depth=None, ids=None)
        read = self._gl["glReadPixels"]
        if rgb or (depth and not ids):
            self._pass(self._flat if rgb else self._depth, idx, v, colour=rgb)
            if rgb:
                out.rgb = np.empty((self._h, self._w, 4 if rgba else 3), np.uint8)
                read(0, 0, self._w, self._h, GL_RGBA if rgba else GL_RGB, GL_UNSIGNED_BYTE, out.rgb.ctypes.data)
                if rgba:  # the framebuffer's alpha is the clear colour's (0) where nothing was drawn
                    out.rgb[..., 3] = 255
            if depth:
                out.depth = self._read_depth()
        if ids:
            self._pass(self._ids, idx, v, colour=True)
            read(0, 0, self._w, self._h, GL_RGBA, GL_UNSIGNED_BYTE, self._words.ctypes.data)
            # id + 1 in the low 24 bits of the little-endian RGBA word (black: structure/background).
            words = np.bitwise_and(self._words, 0xFFFFFF)
            out.ids = words.view(np.int32)
            out.ids -= 1
            if depth and out.depth is None:
                out.depth = self._read_depth()  # same geometry, so the id pass's depth is the depth image
        return out

    def _pass(self, chunks: list, idx, view: np.ndarray, colour: bool) -> None:
        gl = self._gl
        if colour != self._colour_mask:
            gl["glColorMask"](colour, colour, colour, colour)
            self._colour_mask = colour
        gl["glClear"](GL_DEPTH_BUFFER_BIT | (GL_COLOR_BUFFER_BIT if colour else 0))
        use, bind, tex2d, draw = gl["glUseProgram"], gl["glBindVertexArray"], gl["glBindTexture"], gl[
            "glDrawElementsInstanced"]
        set_matrix, v = gl["glUniformMatrix4fv"], view.ctypes.data
        current, bound_tex = None, None
        for i in idx:
            for info, vao, count, material, tex in chunks[i]:
                if info is not current:
                    use(info["id"])
                    if info["V"] != -1:
                        set_matrix(info["V"], 1, 1, v)
                    current = info
                if colour and info["material"] is not material:
                    self._set_material(info, material)
                if tex is not None and tex != bound_tex:
                    tex2d(GL_TEXTURE_2D, tex)
                    bound_tex = tex
                bind(vao)
                draw(GL_TRIANGLES, count, GL_UNSIGNED_INT, None, 1)
        bind(0)
        use(0)

    def _read_depth(self) -> np.ndarray:
        z = self._zbuf
        self._gl["glReadPixels"](0, 0, self._w, self._h, GL_DEPTH_COMPONENT, GL_FLOAT, z.ctypes.data)
        near, far = self._znear, self._zfar
        if self._ortho:  # an orthographic depth buffer is linear in z: near at 0, far at 1
            d = np.multiply(z, far - near)
            d += near
            np.copyto(d, 0.0, where=z == 1.0)
            return d
        # pyrender's linearization, operation for operation in float32 (so the values are its values).
        d = np.multiply(z, 2.0)
        d -= 1.0
        d *= far - near
        np.subtract(far + near, d, out=d)
        np.divide(2.0 * near * far, d, out=d)
        np.copyto(d, 0.0, where=z == 1.0)
        return d
