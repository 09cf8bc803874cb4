"""Headless rendering: RGB, linear depth and instance ids of a scene from a camera pose.

Importing this package sets ``PYOPENGL_PLATFORM=osmesa`` unless already set and patches pyrender's
shader cache; it creates no GL context (a :class:`Renderer` does).
"""

from navbench.render.renderer import (
    CameraConfig,
    Renderer,
    RenderError,
    RenderOutput,
    backproject,
    camera_pose,
    decode_ids,
    encode_ids,
    intrinsics,
)

__all__ = [
    "CameraConfig",
    "Renderer",
    "RenderError",
    "RenderOutput",
    "backproject",
    "camera_pose",
    "decode_ids",
    "encode_ids",
    "intrinsics",
]
