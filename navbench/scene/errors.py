"""The scene layer's error type (re-exported by :mod:`navbench.scene.asset`)."""


class SceneError(ValueError):
    """A scene file is missing, unreadable or unusable; the message names the file."""
