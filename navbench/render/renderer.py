"""Fast headless rendering of a :class:`~navbench.scene.asset.SceneAsset`: RGB, depth and instance ids.

A thin layer over pyrender on OSMesa (default) or EGL, built for a few CPU cores:

* Unlit ``RenderFlags.FLAT`` shading of the scene's vertex colours (lighting costs several times
  more, and our scenes carry their shading in the colours), or of its base-colour textures for a
  textured scan (trilinear, unlit, as Habitat renders scans); ``RenderFlags.DEPTH_ONLY`` when only
  depth is asked.
* One ``OffscreenRenderer`` for the life of a :class:`Renderer`; only the camera node moves.
* Per-node overhead (Python and GL calls per drawn node) dominates at agent resolutions, so
  static geometry is merged into spatial chunks of at most ``max_chunk_faces`` triangles, made by
  recursive median splits of the xz plane; chunks whose bounding box lies entirely outside the
  view frustum are hidden for that frame (conservative test against the six frustum planes).
  Most chunks of a compact house are in view, so the default keeps houses of up to 60k triangles
  in one node and culling pays only on large scans. Geometry is indexed (shared vertices,
  triangles in file order), which draws faster than one vertex per corner.
* Scans are geometry-bound (a 64-pixel frame costs about what a 224-pixel one does), and from
  inside a room most chunks in the frustum are behind walls. Scenes of
  :data:`OCCLUSION_MIN_FACES` or more triangles are cut into chunks of at most
  :data:`OCCLUSION_CHUNK_FACES` and also skip chunks that rays cast from the camera's cell never
  reach (:class:`_PotentiallyVisible`). The visible chunks are handed to pyrender nearest first.
* On OSMesa, frames are drawn by :class:`_DirectDraw`: pyrender's own compiled programs, vertex
  arrays, textures and state, set up once per renderer, so a frame is one ``V`` uniform, a bind and
  a draw per visible chunk, and one ``glReadPixels`` per image, rows top first
  (``GL_MESA_pack_invert``), straight into the output arrays. pyrender's ``render()`` (Python per
  node, per uniform and per state, and flipped copies of what it reads) cost about as much as the
  rasterizing itself at 224x224. Images are pyrender's bit for bit (tests/render/test_image_equality.py);
  EGL keeps pyrender's path.
* Instance ids come from a second set of chunk nodes whose vertex colours encode ``id + 1`` as a
  24-bit RGB integer (structure and background decode to -1). It is drawn, FLAT and single-sampled,
  only when ids are asked for; depth+ids without RGB is one pass.

Conventions (Habitat): metres, y up, a camera with identity rotation looks along -z with +y up (also
OpenGL's camera frame); quaternions are ``[x, y, z, w]``. Images have row 0 at the top. Depth is
linear z-depth along the optical axis (not ray length), float32 metres, 0 where nothing was hit
within ``[znear, zfar]``.

Pixel convention of :func:`intrinsics`: pixel ``(u, v)`` (column, row) has its centre at integer
coordinates, so the image spans ``[-0.5, W - 0.5]`` and the principal point of the symmetric GL
frustum is ``((W - 1) / 2, (H - 1) / 2)``. :func:`backproject` uses the same convention.

Importing this module sets ``PYOPENGL_PLATFORM`` to ``osmesa`` unless it is already set (set it to
``egl`` before the first import to use EGL), ``LP_NUM_THREADS`` to 0 unless set (fork safety, below), and patches pyrender's shader cache (see
:func:`_patch_shader_cache`). It never creates a GL context; :class:`Renderer` does.
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

import contextlib  # noqa: E402
import ctypes  # noqa: E402
import functools  # noqa: E402
import gc  # noqa: E402
import math  # noqa: E402
from collections.abc import Iterator  # noqa: E402
from dataclasses import dataclass  # noqa: E402

import numpy as np  # noqa: E402
import OpenGL  # noqa: E402
import OpenGL.contextdata  # noqa: E402
import OpenGL.platform  # noqa: E402
import pyrender  # noqa: E402
import pyrender.renderer  # noqa: E402
import pyrender.shader_program  # noqa: E402
import trimesh  # noqa: E402
from OpenGL.GL import (  # noqa: E402
    GL_COLOR_BUFFER_BIT,
    GL_DEPTH_BUFFER_BIT,
    GL_DEPTH_COMPONENT,
    GL_FLOAT,
    GL_LINEAR,
    GL_LINEAR_MIPMAP_LINEAR,
    GL_REPEAT,
    GL_RGB,
    GL_RGBA,
    GL_TEXTURE_2D,
    GL_TRIANGLES,
    GL_UNSIGNED_BYTE,
    GL_UNSIGNED_INT,
)
from pyrender.constants import GLTF, RenderFlags  # noqa: E402

from navbench.scene.asset import STRUCTURE_ID, SceneAsset  # noqa: E402

PLATFORMS = ("osmesa", "egl")
MAX_INSTANCE_ID = (1 << 24) - 2  # id + 1 must fit in 24 bits of RGB


class RenderError(ValueError):
    """Bad renderer input (camera config, pose, platform, scene ids); the message names the value."""


def bound_platform() -> str:
    """The platform PyOpenGL bound itself to on first import: "osmesa", "egl", or another module name."""
    return type(OpenGL.platform.PLATFORM).__module__.rsplit(".", 1)[-1]


# --------------------------------------------------------------------------------------------------
# pyrender shader-cache fix
# --------------------------------------------------------------------------------------------------


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


def _patch_shader_cache() -> None:
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


_patch_shader_cache()


# --------------------------------------------------------------------------------------------------
# Camera model
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CameraConfig:
    """Pinhole camera: image size in pixels, horizontal field of view, clip planes in metres."""

    width: int = 224
    height: int = 224
    hfov_deg: float = 79.0
    znear: float = 0.05
    zfar: float = 50.0

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise RenderError(f"camera size must be positive, got {self.width}x{self.height}")
        if not 0.0 < self.hfov_deg < 180.0:
            raise RenderError(f"camera hfov_deg must be in (0, 180), got {self.hfov_deg}")
        if not 0.0 < self.znear < self.zfar:
            raise RenderError(f"camera needs 0 < znear < zfar, got znear={self.znear} zfar={self.zfar}")

    @property
    def yfov(self) -> float:
        """Vertical field of view in radians (square pixels)."""
        return 2.0 * float(np.arctan(np.tan(np.radians(self.hfov_deg) / 2.0) * self.height / self.width))


def intrinsics(cfg: CameraConfig) -> np.ndarray:
    """3x3 pinhole matrix K for ``cfg`` (OpenCV axes: x right, y down, z forward).

    ``fx = (W / 2) / tan(hfov / 2)``, ``fy = fx`` (square pixels), principal point
    ``((W - 1) / 2, (H - 1) / 2)``: pixel centres sit at integer coordinates (module docstring).
    """
    fx = (cfg.width / 2.0) / np.tan(np.radians(cfg.hfov_deg) / 2.0)
    cx, cy = (cfg.width - 1) / 2.0, (cfg.height - 1) / 2.0
    return np.array([[fx, 0.0, cx], [0.0, fx, cy], [0.0, 0.0, 1.0]], dtype=np.float64)


def camera_pose(position: np.ndarray, rotation_xyzw: np.ndarray) -> np.ndarray:
    """4x4 camera-to-world transform from a position ``[x, y, z]`` and a quaternion ``[x, y, z, w]``."""
    p = np.asarray(position, dtype=np.float64)
    q = np.asarray(rotation_xyzw, dtype=np.float64)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise RenderError(f"camera position must be 3 finite numbers, got {np.asarray(position).tolist()}")
    if q.shape != (4,) or not np.isfinite(q).all() or np.linalg.norm(q) < 1e-8:
        raise RenderError(f"camera rotation must be a non-zero [x, y, z, w] quaternion, got {q.tolist()}")
    pose = np.eye(4)
    pose[:3, :3] = _quat_matrix(q)  # normalises q; scalar-last like Habitat
    pose[:3, 3] = p
    return pose


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    """``Rotation.from_quat(q).as_matrix()`` in plain float arithmetic, the same operations in the
    same order (equal to scipy's bit for bit; tests/render checks), at a fifth of its per-call cost."""
    x, y, z, w = (float(v) for v in q)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return np.array([[x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw)],
                     [2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw)],
                     [2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2]])


def backproject(
    depth: np.ndarray, cfg: CameraConfig, position: np.ndarray, rotation_xyzw: np.ndarray
) -> np.ndarray:
    """World points (H, W, 3) float32 of a depth image rendered from this camera; NaN where depth is 0."""
    depth = np.asarray(depth, dtype=np.float32)
    if depth.shape != (cfg.height, cfg.width):
        raise RenderError(f"depth shape {depth.shape} does not match camera {cfg.height}x{cfg.width}")
    k = intrinsics(cfg)
    v, u = np.mgrid[0 : cfg.height, 0 : cfg.width].astype(np.float32)
    # OpenCV ray (x right, y down, z forward) -> GL/Habitat camera frame (x right, y up, -z forward).
    cam = np.stack(
        [(u - k[0, 2]) / k[0, 0] * depth, -(v - k[1, 2]) / k[1, 1] * depth, -depth], axis=-1
    )
    pose = camera_pose(position, rotation_xyzw)
    world = cam @ pose[:3, :3].T.astype(np.float32) + pose[:3, 3].astype(np.float32)
    world[depth <= 0] = np.nan
    return world


def frustum_planes(view_proj: np.ndarray) -> np.ndarray:
    """(6, 4) unit-normal planes ``(a, b, c, d)`` of the clip frustum of a GL view-projection matrix.

    A world point is inside iff ``a x + b y + c z + d >= 0`` for all six (Gribb-Hartmann).
    """
    m = np.asarray(view_proj, dtype=np.float64)
    rows = [m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]]
    planes = np.stack(rows)
    return planes / np.linalg.norm(planes[:, :3], axis=1, keepdims=True)


def boxes_in_frustum(
    planes: np.ndarray, box_min: np.ndarray, box_max: np.ndarray, margin: float = 1e-3
) -> np.ndarray:
    """(N,) bool: False only for axis-aligned boxes certainly outside the frustum (conservative).

    A box is outside when its corner furthest along some plane's normal is still behind that plane;
    boxes straddling a frustum edge outside a corner may be kept, never the reverse.
    """
    n = planes[:, :3]  # (6, 3)
    far_corner = np.where(n[None] >= 0.0, box_max[:, None, :], box_min[:, None, :])  # (N, 6, 3)
    dist = np.einsum("npk,pk->np", far_corner, n) + planes[None, :, 3]
    return (dist >= -margin).all(axis=1)


# --------------------------------------------------------------------------------------------------
# Renderer
# --------------------------------------------------------------------------------------------------


@dataclass
class RenderOutput:
    """One frame; a field is None when it was not requested."""

    rgb: np.ndarray | None  # (H, W, 3) uint8
    depth: np.ndarray | None  # (H, W) float32 metres, 0 = nothing hit
    ids: np.ndarray | None  # (H, W) int32 object id, -1 = structure or background


def encode_ids(ids: np.ndarray) -> np.ndarray:
    """(N,) int ids -> (N, 4) uint8 RGBA colours holding ``id + 1`` in 24-bit little-endian RGB."""
    v = np.asarray(ids, dtype=np.int64) + 1
    rgba = np.stack([v & 255, (v >> 8) & 255, (v >> 16) & 255, np.full_like(v, 255)], axis=-1)
    return rgba.astype(np.uint8)


def decode_ids(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 id image -> (H, W) int32 ids (black, i.e. structure or background, -> -1)."""
    # Pad to 4 bytes and reinterpret as little-endian int32 (R is the low byte): one copy, no shifts.
    padded = np.zeros(rgb.shape[:-1] + (4,), dtype=np.uint8)
    padded[..., :3] = rgb
    return padded.view(np.dtype("<i4"))[..., 0] - 1


class Renderer:
    """Renders one scene from arbitrary camera poses. Reuse it: construction uploads the scene.

    ``platform`` must be the one PyOpenGL is bound to (:func:`bound_platform`, fixed by
    ``PYOPENGL_PLATFORM`` when OpenGL is first imported).
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
        platform: str = "osmesa",
        max_chunk_faces: int = 60_000,
        frustum_culling: bool = True,
        occlusion_culling: bool | None = None,
    ) -> None:
        if platform not in PLATFORMS:
            raise RenderError(f"platform must be one of {PLATFORMS}, got {platform!r}")
        bound = bound_platform()
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
        # Scan-sized scenes: chunks hidden behind walls are skipped too (see _PotentiallyVisible).
        self.occlusion_culling = (len(asset.mesh.faces) >= OCCLUSION_MIN_FACES if occlusion_culling is None
                                  else occlusion_culling)
        if self.occlusion_culling:
            max_chunk_faces = min(max_chunk_faces, OCCLUSION_CHUNK_FACES)

        self._scene = pyrender.Scene(bg_color=np.zeros(4), ambient_light=np.zeros(3))
        self._cam = pyrender.PerspectiveCamera(
            yfov=camera.yfov, znear=camera.znear, zfar=camera.zfar, aspectRatio=camera.width / camera.height
        )
        self._cam_node = self._scene.add(self._cam, pose=np.eye(4))
        self._proj = self._cam.get_projection_matrix(camera.width, camera.height)

        self._colour_nodes: list[pyrender.Node] = []
        self._id_nodes: list[pyrender.Node] = []
        two_sided = _two_sided_faces(asset)
        self.num_two_sided_faces = int(two_sided.sum())
        # One GL texture and material per base-colour image, shared by every chunk that uses it.
        self._materials = [_texture_material(img) for img in asset.textures] if asset.is_textured else []
        box_min, box_max = [], []
        chunks = spatial_chunks(asset.mesh.triangles_center[:, [0, 2]], max_chunk_faces)
        self._pvs = _PotentiallyVisible(asset.mesh, chunks) if self.occlusion_culling else None
        for faces in chunks:
            colour_mesh, id_mesh, lo, hi = _chunk_meshes(asset, faces, two_sided, self._materials)
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
        # OSMesa: frames are drawn by _DirectDraw (pyrender's programs, buffers and state, without
        # pyrender's per-frame Python). EGL keeps pyrender's path (its multisampled framebuffer).
        self._direct = (_DirectDraw.create(self._scene, self._gl, self._colour_nodes, self._id_nodes,
                                           self._box_min, self._box_max, camera)
                        if platform == "osmesa" else None)

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
    ) -> RenderOutput:
        """Render from the camera at ``position`` (world, metres) with orientation ``rotation_xyzw``."""
        if not (rgb or depth or ids):
            raise RenderError("render() needs at least one of rgb, depth, ids")
        gl = self._require_open()
        pose = camera_pose(position, rotation_xyzw)
        if self._direct is not None:
            view = np.linalg.inv(pose)
            # One chunk: drawing it when it is out of view yields what skipping it would (nothing
            # survives clipping), so the test is skipped; it is most of a small house's frames.
            keep = self._visible(pose, view) if self.num_chunks > 1 else None
            return self._direct.render(pose, view, keep, rgb, depth, ids)
        self._scene.set_pose(self._cam_node, pose)
        keep = self._visible(pose)

        out = RenderOutput(rgb=None, depth=None, ids=None)
        if rgb or (depth and not ids):
            self._show(colour=keep, ids=None)
            if rgb:
                colour, z = self._draw(gl, RenderFlags.FLAT)
                out.rgb = np.ascontiguousarray(colour)
                out.depth = z if depth else None
            else:
                out.depth = self._draw(gl, RenderFlags.DEPTH_ONLY)
        if ids:
            self._show(colour=None, ids=keep)
            id_colour, z = self._draw(gl, RenderFlags.FLAT)
            out.ids = decode_ids(id_colour)
            if depth and out.depth is None:
                out.depth = z  # same geometry, so the id pass's depth is the depth image
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

    def __enter__(self) -> "Renderer":
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
            with _multisample_disabled():
                return gl.render(self._scene, flags)
        return gl.render(self._scene, flags)


GL_PACK_INVERT_MESA = 0x8758  # GL_MESA_pack_invert: glReadPixels returns rows top first


@functools.lru_cache(maxsize=None)
def _raw_gl() -> dict:
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


class _DirectDraw:
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
    (:func:`_raw_gl`). So the rasterized fragments are pyrender's.

    Read-back: ``glReadPixels`` with ``GL_PACK_INVERT_MESA`` writes rows top first, so RGB goes
    straight into the output array and depth into a preallocated one, linearized with pyrender's
    formula, operation for operation in float32, into the output. Ids are read as RGBA words. A
    depth-only pass writes no colour (``glColorMask``): the depth shader's constant colour was
    never read. The fixture test (tests/render/test_image_equality.py) holds the images to the old
    path's, bit for bit at the time of writing.

    Holds no reference to its :class:`Renderer` (whose ``__del__`` frees the context).
    """

    @classmethod
    def create(cls, scene: pyrender.Scene, gl: pyrender.OffscreenRenderer, colour_nodes: list, id_nodes: list,
               box_min: np.ndarray, box_max: np.ndarray, camera: CameraConfig) -> "_DirectDraw | None":
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

        self._gl = _raw_gl()
        platform = gl._platform
        self._make_current = functools.partial(OSMesaMakeCurrent, platform._context, platform._buffer,
                                               GL.GL_UNSIGNED_BYTE, camera.width, camera.height)
        self._w, self._h = camera.width, camera.height
        self._znear, self._zfar = camera.znear, camera.zfar
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
               ids: bool) -> RenderOutput:
        """One frame; ``keep`` flags the chunks to draw (None: all, in order)."""
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
                out.rgb = np.empty((self._h, self._w, 3), np.uint8)
                read(0, 0, self._w, self._h, GL_RGB, GL_UNSIGNED_BYTE, out.rgb.ctypes.data)
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
        # pyrender's linearization, operation for operation in float32 (so the values are its values).
        near, far = self._znear, self._zfar
        d = np.multiply(z, 2.0)
        d -= 1.0
        d *= far - near
        np.subtract(far + near, d, out=d)
        np.divide(2.0 * near * far, d, out=d)
        np.copyto(d, 0.0, where=z == 1.0)
        return d



@contextlib.contextmanager
def _multisample_disabled() -> Iterator[None]:
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


OCCLUSION_MIN_FACES = 200_000  # scenes this large get occlusion culling by default
OCCLUSION_CHUNK_FACES = 8_000  # finer chunks, so walls hide whole chunks
PVS_CELL = 0.5  # metres: camera positions are grouped into cubes of this side
PVS_DIRECTIONS = 16384  # rays per sample point (about 1.6 deg apart)


class _PotentiallyVisible:
    """Chunks visible from a camera cell, found by casting rays from the cell's corners.

    The camera's position is put in a cube of side :data:`PVS_CELL`; the first time a cube is
    entered, the chunks seen from each of its 8 corners are the union of the chunks first hit by
    rays in :data:`PVS_DIRECTIONS` directions (Embree) and the chunks whose box holds the corner.
    Corners are shared by neighbouring cubes and computed once. Chunks behind walls are then
    skipped. Sampling, not an exact visibility proof: a chunk seen only through a gap narrower than
    the rays' spacing may be missed, which is why only scan-sized scenes (chunks of thousands of
    triangles, which rays hit many times) use it by default.
    """

    def __init__(self, mesh: trimesh.Trimesh, chunks: list[np.ndarray]) -> None:
        self._mesh = mesh
        self._face_chunk = np.empty(len(mesh.faces), np.int64)
        for k, faces in enumerate(chunks):
            self._face_chunk[faces] = k
        self._n = len(chunks)
        tri = mesh.triangles
        self._lo = np.array([tri[c].reshape(-1, 3).min(axis=0) for c in chunks])
        self._hi = np.array([tri[c].reshape(-1, 3).max(axis=0) for c in chunks])
        i = np.arange(PVS_DIRECTIONS) + 0.5  # Fibonacci sphere: near-uniform directions
        phi = np.arccos(1 - 2 * i / PVS_DIRECTIONS)
        theta = np.pi * (1 + 5 ** 0.5) * i
        self._dirs = np.stack([np.cos(theta) * np.sin(phi), np.cos(phi), np.sin(theta) * np.sin(phi)], axis=1)
        self._cells: dict[tuple[int, int, int], np.ndarray] = {}
        self._corners: dict[tuple[int, int, int], np.ndarray] = {}

    def __call__(self, position: np.ndarray) -> np.ndarray:
        cell = tuple(int(v) for v in np.floor(np.asarray(position) / PVS_CELL))
        vis = self._cells.get(cell)
        if vis is None:
            corners = [(cell[0] + x, cell[1] + y, cell[2] + z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
            self._add_corners([c for c in corners if c not in self._corners])
            vis = self._cells[cell] = np.logical_or.reduce([self._corners[c] for c in corners])
        return vis

    def _add_corners(self, corners: list[tuple[int, int, int]]) -> None:
        if not corners:
            return
        points = np.asarray(corners, float) * PVS_CELL
        hit = self._mesh.ray.intersects_first(np.repeat(points, len(self._dirs), axis=0),
                                              np.tile(self._dirs, (len(points), 1)))
        hit = hit.reshape(len(points), -1)
        for k, c in enumerate(corners):
            vis = np.all((points[k] >= self._lo - 1e-6) & (points[k] <= self._hi + 1e-6), axis=1)
            h = hit[k]
            vis[self._face_chunk[h[h >= 0]]] = True
            self._corners[c] = vis


def _two_sided_faces(asset: SceneAsset) -> np.ndarray:
    """(F,) bool: faces drawn with both windings. Textured faces are single-sided, as Habitat draws
    scans with back-face culling; vertex-coloured faces follow :func:`open_surface_faces`."""
    mesh = asset.mesh
    if asset.face_texture is None:
        return open_surface_faces(mesh)
    out = np.zeros(len(mesh.faces), dtype=bool)
    plain = np.flatnonzero(asset.face_texture < 0)
    if len(plain):
        out[plain] = open_surface_faces(trimesh.Trimesh(mesh.vertices, mesh.faces[plain], process=False))
    return out


def spatial_chunks(points_xz: np.ndarray, max_faces: int) -> list[np.ndarray]:
    """Group face indices (by their xz centroids) into compact chunks of at most ``max_faces``.

    Recursive median split along the longer xz extent (a k-d tree's leaves): chunks stay spatially
    tight, so frustum culling can drop them, and balanced, so none is needlessly small.
    """
    chunks: list[np.ndarray] = []
    stack = [np.arange(len(points_xz))]
    while stack:
        idx = stack.pop()
        if len(idx) <= max_faces:
            # Back in file order: neighbouring triangles share vertices, which llvmpipe's vertex
            # cache exploits; a spatially sorted order draws markedly slower.
            chunks.append(np.sort(idx))
            continue
        pts = points_xz[idx]
        axis = int(np.argmax(np.ptp(pts, axis=0)))
        order = np.argsort(pts[:, axis], kind="stable")
        half = len(idx) // 2
        stack += [idx[order[half:]], idx[order[:half]]]
    return chunks


def open_surface_faces(mesh: trimesh.Trimesh) -> np.ndarray:
    """(F,) bool: faces of connected components that are not closed, consistently wound solids.

    Closed, consistently wound solids are seen only from the side their faces point to (outside,
    for a solid), so back-face culling draws them correctly and saves their hidden half. Open
    surfaces (single quads as walls, ground planes, broken meshes) may be seen from either side and
    are drawn with both windings. Vertices are merged by position first, because exporters often
    split them along colour seams.
    """
    welded = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    welded.merge_vertices()
    # Closed and consistently wound <=> every undirected edge is used as often in one direction as
    # in the other (2 for a manifold edge; 4 where two closed solids touch along an edge).
    _, edge_group = np.unique(welded.edges_sorted, axis=0, return_inverse=True)
    edge_group = edge_group.reshape(-1)
    forward = welded.edges[:, 0] < welded.edges[:, 1]
    balance = np.bincount(edge_group, weights=np.where(forward, 1.0, -1.0))
    good_edge = balance[edge_group] == 0
    bad_face = np.zeros(len(welded.faces), dtype=bool)
    np.logical_or.at(bad_face, welded.edges_face, ~good_edge)
    labels = trimesh.graph.connected_component_labels(welded.face_adjacency, node_count=len(welded.faces))
    return np.isin(labels, np.unique(labels[bad_face]))


def _texture_material(image: np.ndarray) -> pyrender.MetallicRoughnessMaterial:
    """Unlit base-colour material over ``image`` (RGBA, row 0 at the top): trilinear, repeating, as
    glTF's default sampler; FLAT rendering outputs the filtered texel as it is."""
    sampler = pyrender.Sampler(magFilter=GL_LINEAR, minFilter=GL_LINEAR_MIPMAP_LINEAR, wrapS=GL_REPEAT, wrapT=GL_REPEAT)
    texture = pyrender.Texture(source=np.ascontiguousarray(image), source_channels="RGBA", sampler=sampler)
    return pyrender.MetallicRoughnessMaterial(baseColorFactor=np.ones(4), baseColorTexture=texture, doubleSided=False)


def _chunk_meshes(
    asset: SceneAsset, faces: np.ndarray, two_sided: np.ndarray,
    materials: list[pyrender.MetallicRoughnessMaterial] | None = None,
) -> tuple[pyrender.Mesh, pyrender.Mesh, np.ndarray, np.ndarray]:
    """Colour and id meshes of one chunk, plus its AABB.

    Everything is drawn with back-face culling (pyrender's DEPTH_ONLY pass always culls, so the
    FLAT passes must too to see the same geometry); faces flagged in ``two_sided`` are stored once
    per winding so they show from both sides. Textured faces of a textured scene are drawn as one
    primitive per texture (positions and UVs); the rest, and every untextured scene, with vertex
    colours. The id mesh is one primitive whatever the colour mesh's make-up.
    """
    mesh = asset.mesh
    tri = mesh.faces[faces]
    corner_ids = np.repeat(asset.face_ids[faces].astype(np.int64), 3)
    # Shared vertices, except that a vertex used by faces of two objects is split so each copy
    # carries one id colour: key = (vertex index, id + 1), packed into one int64.
    keys = tri.reshape(-1).astype(np.int64) * (MAX_INSTANCE_ID + 2) + (corner_ids + 1)
    uniq, inverse = np.unique(keys, return_inverse=True)
    vertex = uniq // (MAX_INSTANCE_ID + 2)
    positions = mesh.vertices[vertex].astype(np.float32)
    colours = np.asarray(mesh.visual.vertex_colors, dtype=np.uint8)[vertex].copy()
    colours[:, 3] = 255  # opaque: pyrender would otherwise blend and depth-sort
    id_colours = encode_ids(uniq % (MAX_INSTANCE_ID + 2) - 1)
    front = inverse.reshape(-1, 3).astype(np.uint32)
    indices = np.concatenate([front, front[two_sided[faces], ::-1]])
    material = pyrender.MetallicRoughnessMaterial(baseColorFactor=np.ones(4), doubleSided=False)

    def build(vertex_colours: np.ndarray) -> pyrender.Mesh:
        prim = pyrender.Primitive(
            positions=positions,
            indices=indices,
            color_0=vertex_colours,
            material=material,
            mode=GLTF.TRIANGLES,
        )
        return pyrender.Mesh(primitives=[prim])

    if not materials or asset.face_texture is None:
        return build(colours), build(id_colours), positions.min(axis=0), positions.max(axis=0)
    prims = []
    chunk_tex = asset.face_texture[faces]
    for t in np.unique(chunk_tex):
        sel = faces[chunk_tex == t]
        if t < 0:
            prims += build(colours).primitives if (chunk_tex < 0).all() else _colour_primitive(asset, sel, two_sided)
            continue
        tri_t = mesh.faces[sel]
        used, local = np.unique(tri_t.reshape(-1), return_inverse=True)
        front_t = local.reshape(-1, 3).astype(np.uint32)
        prims.append(pyrender.Primitive(
            positions=mesh.vertices[used].astype(np.float32),
            texcoord_0=asset.uv[used].astype(np.float32),
            indices=np.concatenate([front_t, front_t[two_sided[sel], ::-1]]),
            material=materials[int(t)],
            mode=GLTF.TRIANGLES,
        ))
    return pyrender.Mesh(primitives=prims), build(id_colours), positions.min(axis=0), positions.max(axis=0)


def _colour_primitive(asset: SceneAsset, faces: np.ndarray, two_sided: np.ndarray) -> list[pyrender.Primitive]:
    """The vertex-coloured faces of a chunk that also holds textured ones, as one primitive."""
    mesh = asset.mesh
    used, local = np.unique(mesh.faces[faces].reshape(-1), return_inverse=True)
    front = local.reshape(-1, 3).astype(np.uint32)
    colours = np.asarray(mesh.visual.vertex_colors, dtype=np.uint8)[used].copy()
    colours[:, 3] = 255
    return [pyrender.Primitive(
        positions=mesh.vertices[used].astype(np.float32), color_0=colours,
        indices=np.concatenate([front, front[two_sided[faces], ::-1]]),
        material=pyrender.MetallicRoughnessMaterial(baseColorFactor=np.ones(4), doubleSided=False),
        mode=GLTF.TRIANGLES,
    )]
