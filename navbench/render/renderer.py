"""Fast headless rendering of a :class:`~navbench.scene.asset.SceneAsset`: RGB, depth and instance ids.

A thin layer over pyrender on OSMesa (default) or EGL, built for a few CPU cores:

* Unlit ``RenderFlags.FLAT`` shading of the scene's vertex colours (lighting costs several times
  more, and our scenes carry their shading in the colours), or of its base-colour textures for a
  textured scan (trilinear, unlit, as Habitat renders scans); ``RenderFlags.DEPTH_ONLY`` when only
  depth is asked.
* One ``OffscreenRenderer`` for the life of a :class:`Renderer`; only the camera node moves.
* Static geometry is merged into spatial chunks of at most ``max_chunk_faces`` triangles
  (:mod:`navbench.render.chunk_meshes`); chunks outside the view frustum are hidden for that frame
  (:mod:`navbench.render.culling`). Most chunks of a compact house are in view, so the default keeps
  houses of up to 60k triangles in one node and culling pays only on large scans.
* Scans are geometry-bound (a 64-pixel frame costs about what a 224-pixel one does), and from
  inside a room most chunks in the frustum are behind walls. Scenes of
  :data:`~navbench.render.culling.OCCLUSION_MIN_FACES` or more triangles get finer chunks and also
  skip chunks that rays cast from the camera's cell never reach. The visible chunks are handed to
  pyrender nearest first.
* On OSMesa, frames are drawn by :class:`~navbench.render.gl_direct.DirectDraw` (pyrender's own
  programs, vertex arrays, textures and state, set up once per renderer, without pyrender's
  per-frame Python); images are pyrender's bit for bit (tests/render/test_image_equality.py). EGL
  keeps pyrender's path.
* Instance ids come from a second set of chunk nodes whose vertex colours encode ``id + 1``
  (:mod:`navbench.render.frame`). It is drawn, FLAT and single-sampled, only when ids are asked for;
  depth+ids without RGB is one pass.

Camera conventions are :mod:`navbench.render.camera`'s (pinhole, or orthographic with ``ortho_scale``).
Depth is linear z-depth along the optical axis, float32 metres, 0 where nothing was hit within
``[znear, zfar]``.

Importing this module binds PyOpenGL's platform (:mod:`navbench.render.gl_platform`) and patches
pyrender's shader cache (:mod:`navbench.render.pyrender_fixes`). It never creates a GL context;
:class:`Renderer` does. Renderers still open when the interpreter exits are closed by an ``atexit``
hook, while the GL library can still be used (a renderer freed during module teardown would make
PyOpenGL try imports that no longer work).
"""

from __future__ import annotations

# isort: off
import navbench.render.gl_platform  # noqa: F401  (first: binds the platform before OpenGL is imported)
# isort: on

import atexit
import gc
import os
import weakref

import numpy as np
import pyrender
from pyrender.constants import RenderFlags

from navbench.render.camera import CameraConfig, RenderError, camera_pose
from navbench.render.chunk_meshes import chunk_meshes, spatial_chunks, texture_material, two_sided_faces
from navbench.render.culling import (
    OCCLUSION_CHUNK_FACES,
    OCCLUSION_MIN_FACES,
    PotentiallyVisible,
    boxes_in_frustum,
    frustum_planes,
)
from navbench.render.frame import MAX_INSTANCE_ID, RenderOutput, decode_ids, rgba_of
from navbench.render.gl_direct import DirectDraw
from navbench.render.gl_platform import AUTO, PLATFORMS, bound_platform
from navbench.render.pyrender_fixes import multisample_disabled
from navbench.scene.annotations import STRUCTURE_ID
from navbench.scene.asset import SceneAsset

# Renderers not yet closed; _close_open_renderers closes them at interpreter exit.
_OPEN: weakref.WeakSet[Renderer] = weakref.WeakSet()


def _close_open_renderers() -> None:
    """Close the renderers this process made and has not closed, before module teardown (atexit). A
    forked child that runs its exit hooks leaves the renderers it inherited from its parent alone."""
    for renderer in list(_OPEN):
        if renderer._pid == os.getpid():
            try:
                renderer.close()
            except Exception:  # a context already broken: nothing more to free at exit
                pass


atexit.register(_close_open_renderers)


class Renderer:
    """Renders one scene from arbitrary camera poses. Reuse it: construction uploads the scene.

    ``platform`` must be the one PyOpenGL is bound to (:func:`bound_platform`, fixed by
    ``PYOPENGL_PLATFORM`` when OpenGL is first imported); ``"auto"`` (default) is that one.
    ``max_chunk_faces`` bounds the triangles merged into one node (see the module docstring);
    ``frustum_culling=False`` draws every chunk (for checking the culling); ``occlusion_culling``
    (default: on for scenes of :data:`OCCLUSION_MIN_FACES` triangles or more) skips chunks hidden
    from the camera's cell.
    One instance holds one GL context; use it from one thread, and call :meth:`close` (or use it
    as a context manager) to free the context.
    """

    _closes = 0  # closes in this process: every 16th runs a full garbage collection (see close)

    def __init__(
        self,
        asset: SceneAsset,
        camera: CameraConfig = CameraConfig(),
        platform: str = AUTO,
        max_chunk_faces: int = 60_000,
        frustum_culling: bool = True,
        occlusion_culling: bool | None = None,
    ) -> None:
        bound = bound_platform()
        platform = bound if platform == AUTO else platform
        if platform not in PLATFORMS:
            raise RenderError(f"platform must be one of {(AUTO, *PLATFORMS)}, got {platform!r}")
        if platform != bound:
            raise RenderError(
                f"platform {platform!r} requested but PyOpenGL is bound to {bound!r}; set "
                f"PYOPENGL_PLATFORM={platform} before anything imports OpenGL (e.g. navbench.render)"
            )
        if max_chunk_faces < 1:
            raise RenderError(f"max_chunk_faces must be >= 1, got {max_chunk_faces}")
        face_ids = np.asarray(asset.face_ids)
        if face_ids.shape != (len(asset.mesh.faces),):
            raise RenderError(f"{asset.path}: face_ids shape {face_ids.shape} != ({len(asset.mesh.faces)},)")
        if len(face_ids) and (face_ids.min() < STRUCTURE_ID or face_ids.max() > MAX_INSTANCE_ID):
            raise RenderError(f"{asset.path}: instance ids must lie in [-1, {MAX_INSTANCE_ID}]")

        self.asset = asset
        self.camera = camera
        self.platform = platform
        self.frustum_culling = frustum_culling
        # Scan-sized scenes: chunks hidden behind walls are skipped too (see PotentiallyVisible).
        # (Not for an orthographic camera, whose rays do not start at the camera's cell.)
        self.occlusion_culling = (len(asset.mesh.faces) >= OCCLUSION_MIN_FACES and not camera.orthographic
                                  if occlusion_culling is None else occlusion_culling)
        if self.occlusion_culling and camera.orthographic:
            raise RenderError("occlusion_culling needs a pinhole camera (an orthographic view is not seen from "
                              "the camera's cell)")
        if self.occlusion_culling:
            max_chunk_faces = min(max_chunk_faces, OCCLUSION_CHUNK_FACES)

        self._scene = pyrender.Scene(bg_color=np.zeros(4), ambient_light=np.zeros(3))
        if camera.orthographic:  # pyrender's magnifications are half the view's extent
            half_w, half_h = (e / 2.0 for e in camera.ortho_extent)
            self._cam = pyrender.OrthographicCamera(xmag=half_w, ymag=half_h, znear=camera.znear, zfar=camera.zfar)
        else:
            self._cam = pyrender.PerspectiveCamera(
                yfov=camera.yfov, znear=camera.znear, zfar=camera.zfar, aspectRatio=camera.width / camera.height
            )
        self._cam_node = self._scene.add(self._cam, pose=np.eye(4))
        self._proj = self._cam.get_projection_matrix(camera.width, camera.height)

        self._colour_nodes: list[pyrender.Node] = []
        self._id_nodes: list[pyrender.Node] = []
        two_sided = two_sided_faces(asset)
        self.num_two_sided_faces = int(two_sided.sum())
        # One GL texture and material per base-colour image, shared by every chunk that uses it.
        self._materials = [texture_material(img) for img in asset.textures] if asset.is_textured else []
        box_min, box_max = [], []
        chunks = spatial_chunks(asset.mesh.triangles_center[:, [0, 2]], max_chunk_faces)
        self._pvs = PotentiallyVisible(asset.mesh, chunks) if self.occlusion_culling else None
        for faces in chunks:
            colour_mesh, id_mesh, lo, hi = chunk_meshes(asset, faces, two_sided, self._materials)
            self._colour_nodes.append(self._scene.add(colour_mesh))
            self._id_nodes.append(self._scene.add(id_mesh))
            box_min.append(lo)
            box_max.append(hi)
        self._box_min = np.asarray(box_min)
        self._box_max = np.asarray(box_max)

        # Last: the GL context (pyrender picks OSMesa/EGL from PYOPENGL_PLATFORM).
        self._gl: pyrender.OffscreenRenderer | None = pyrender.OffscreenRenderer(camera.width, camera.height)
        # The draw list lives in a list the override closes over (not in self): no reference cycle.
        self._draw_list: list[pyrender.Node] = []
        draw_list = self._draw_list
        self._gl._renderer._sorted_mesh_nodes = lambda scene: draw_list
        # OSMesa: frames are drawn by DirectDraw (pyrender's programs, buffers and state, without
        # pyrender's per-frame Python). EGL keeps pyrender's path (its multisampled framebuffer).
        self._direct = (DirectDraw.create(self._scene, self._gl, self._colour_nodes, self._id_nodes,
                                           self._box_min, self._box_max, camera)
                        if platform == "osmesa" else None)
        self._pid = os.getpid()
        _OPEN.add(self)

    # -- public --------------------------------------------------------------------------------

    @property
    def num_chunks(self) -> int:
        return len(self._colour_nodes)

    @property
    def num_shader_programs(self) -> int:
        """Compiled programs in pyrender's cache (diagnostic: a handful while the cache works)."""
        gl = self._require_open()
        return len(gl._renderer._program_cache._program_cache)

    def visible_chunks(self, position: np.ndarray, rotation_xyzw: np.ndarray) -> np.ndarray:
        """(num_chunks,) bool: chunks the frustum test keeps for this camera pose."""
        return self._visible(camera_pose(position, rotation_xyzw))

    def render(
        self,
        position: np.ndarray,
        rotation_xyzw: np.ndarray,
        rgb: bool = True,
        depth: bool = True,
        ids: bool = False,
        rgba: bool = False,
    ) -> RenderOutput:
        """Render from the camera at ``position`` (world, metres) with orientation ``rotation_xyzw``; with
        ``rgba`` the colour is (H, W, 4) RGBA with alpha 255 (read so from GL where the draw is direct)."""
        if not (rgb or depth or ids):
            raise RenderError("render() needs at least one of rgb, depth, ids")
        gl = self._require_open()
        pose = camera_pose(position, rotation_xyzw)
        if self._direct is not None:
            view = np.linalg.inv(pose)
            # One chunk: drawing it when it is out of view yields what skipping it would (nothing
            # survives clipping), so the test is skipped; it is most of a small house's frames.
            keep = self._visible(pose, view) if self.num_chunks > 1 else None
            return self._direct.render(pose, view, keep, rgb, depth, ids, rgba)
        if rgba:
            out = self.render(position, rotation_xyzw, rgb, depth, ids)
            out.rgb = None if out.rgb is None else rgba_of(out.rgb)
            return out
        self._scene.set_pose(self._cam_node, pose)
        keep = self._visible(pose)

        out = RenderOutput(rgb=None, depth=None, ids=None)
        if rgb or (depth and not ids):
            self._show(colour=keep, ids=None)
            if rgb:
                colour, z = self._draw(gl, RenderFlags.FLAT)
                out.rgb = np.ascontiguousarray(colour)
                out.depth = self._linear(z) if depth else None
            else:
                out.depth = self._linear(self._draw(gl, RenderFlags.DEPTH_ONLY))
        if ids:
            self._show(colour=None, ids=keep)
            id_colour, z = self._draw(gl, RenderFlags.FLAT)
            out.ids = decode_ids(id_colour)
            if depth and out.depth is None:
                out.depth = self._linear(z)  # same geometry, so the id pass's depth is the depth image
        return out

    def close(self) -> None:
        """Free the GL context and buffers. Idempotent."""
        if self._gl is not None:
            gl, self._gl = self._gl, None
            self._direct = None
            # What OffscreenRenderer.delete() does, minus the full gc.collect() it ends with on every
            # call, which is slow in a process holding many Python objects (a policy, a replay buffer)
            # and would be paid on every scene switch. The GL buffers and context are freed here; the
            # old scene's cyclic Python garbage is collected on every 16th close instead, which keeps
            # RSS flat (benchmarks/scene_switch.py checks both).
            gl._platform.make_current()
            gl._renderer.delete()
            gl._platform.delete_context()
            gl._renderer = gl._platform = None
            Renderer._closes += 1
            if Renderer._closes % 16 == 0:
                gc.collect()

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # interpreter shutdown: GL may already be gone
            pass

    # -- internals -----------------------------------------------------------------------------

    def _require_open(self) -> pyrender.OffscreenRenderer:
        if self._gl is None:
            raise RenderError(f"renderer for {self.asset.path} is closed")
        return self._gl

    def _visible(self, pose: np.ndarray, view: np.ndarray | None = None) -> np.ndarray:
        keep = np.ones(self.num_chunks, dtype=bool)
        if self.frustum_culling:
            planes = frustum_planes(self._proj @ (np.linalg.inv(pose) if view is None else view))
            keep = boxes_in_frustum(planes, self._box_min, self._box_max)
        if self._pvs is not None:
            keep &= self._pvs(pose[:3, 3])
        return keep

    def _linear(self, depth: np.ndarray) -> np.ndarray:
        """pyrender's depth image as z-depth in metres. pyrender linearizes every depth buffer with the
        perspective formula ``D = 2 n f / (f + n - x (f - n))`` of its value ``x`` in [-1, 1]; an orthographic
        buffer is linear, ``D = (x (f - n) + f + n) / 2``, which is ``f + n - n f / D_perspective``."""
        if not self.camera.orthographic:
            return depth
        n, f = self.camera.znear, self.camera.zfar
        d = depth.astype(np.float64)
        hit = d > 0
        d[hit] = f + n - n * f / d[hit]
        return d.astype(np.float32)

    def _show(self, colour: np.ndarray | None, ids: np.ndarray | None) -> None:
        """Make the chunks flagged in ``colour`` / ``ids`` visible in that node set; None hides the set.

        pyrender sorts every mesh node far-to-near on each pass (a Python loop over all nodes); the
        renderer is handed the visible ones near-to-far instead, so hidden chunks cost nothing and
        nearer geometry fills the depth buffer first.
        """
        draw = []
        for nodes, keep in ((self._colour_nodes, colour), (self._id_nodes, ids)):
            for i, node in enumerate(nodes):
                node.mesh.is_visible = bool(keep is not None and keep[i])
            if keep is not None:
                idx = np.flatnonzero(keep)
                if len(idx) > 1:
                    cam = self._scene.get_pose(self._cam_node)[:3, 3]
                    centre = (self._box_min[idx] + self._box_max[idx]) / 2.0
                    idx = idx[np.argsort(np.linalg.norm(centre - cam, axis=1), kind="stable")]
                draw += [nodes[i] for i in idx]
        self._draw_list[:] = draw

    def _draw(self, gl: pyrender.OffscreenRenderer, flags: int):
        if self.platform == "egl":
            # pyrender draws into a 4x multisampled buffer on EGL and resolves it with averaging,
            # which would blend id colours at edges into ids that do not exist. With
            # GL_MULTISAMPLE off every sample takes the pixel-centre value, so the resolve is
            # exact and EGL frames equal OSMesa's (single-sampled) ones.
            with multisample_disabled():
                return gl.render(self._scene, flags)
        return gl.render(self._scene, flags)
