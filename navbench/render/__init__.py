"""Headless rendering: RGB, linear depth and instance ids of a scene from a camera pose.

Importing this package sets ``PYOPENGL_PLATFORM`` unless already set (EGL on a GPU, else OSMesa) and
patches pyrender's shader cache; it creates no GL context (a :class:`Renderer` does).

Modules: :mod:`.camera` (camera model, poses, backprojection; plain numpy), :mod:`.renderer` (the
:class:`Renderer`), :mod:`.chunk_meshes` (the scene as chunked pyrender meshes), :mod:`.culling`
(frustum and occlusion culling), :mod:`.gl_direct` (the per-frame draw path on OSMesa),
:mod:`.frame` (a frame and its id encoding), :mod:`.gl_platform`, :mod:`.osmesa_local` and :mod:`.pyrender_fixes`.
"""

from navbench.render.camera import CameraConfig, RenderError, backproject_image, camera_pose, intrinsics
from navbench.render.frame import RenderOutput, decode_ids, encode_ids
from navbench.render.renderer import Renderer

__all__ = [
    "CameraConfig",
    "Renderer",
    "RenderError",
    "RenderOutput",
    "backproject_image",
    "camera_pose",
    "decode_ids",
    "encode_ids",
    "intrinsics",
]
