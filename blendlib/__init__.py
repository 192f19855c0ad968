"""Unity Passes for Blender: the library.

The renderer core (:mod:`blendlib.pipeline` and the stage modules it calls) is
free of bpy: it takes a :class:`blendlib.scene.DrawScene` and returns a
:class:`blendlib.pipeline.Frame` of numpy buffers. Only :mod:`blendlib.bridge`
touches Blender; :func:`render` and :func:`write_image` import it lazily so that
``import blendlib`` works without bpy.
"""

from __future__ import annotations

from .pipeline import Frame, render_scene
from .scene import Camera, DrawScene, Light, Mesh, Renderer, SceneError
from .shaderlab import Material, Pass, Texture

__all__ = [
    "Camera", "DrawScene", "Frame", "Light", "Material", "Mesh", "Pass", "Renderer",
    "SceneError", "Texture", "render", "render_scene", "write_image",
]


def render(scene=None, **kwargs) -> Frame:
    """Render a ``bpy.types.Scene`` (default: the context scene) with the Unity pipeline.

    Returns a :class:`Frame` whose ``color`` (H, W, 4) float32 holds the stored frame
    values and ``depth`` (H, W) float32 the window depth; row 0 is the top.
    """
    from . import bridge

    return bridge.render(scene, **kwargs)


def write_image(frame: Frame, name: str, **kwargs):
    """Write a frame's colour into the ``bpy.types.Image`` called ``name`` (created if needed)."""
    from . import bridge

    return bridge.write_image(frame, name, **kwargs)
