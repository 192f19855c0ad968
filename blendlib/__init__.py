"""Unity Passes for Blender: the library.

Layers, one folder each: :mod:`blendlib.core` (the bpy-free renderer: a
:class:`DrawScene` in, a :class:`Frame` of numpy buffers out), :mod:`blendlib.explain` (the
tools that explain a frame), :mod:`blendlib.formats` (ShaderLab and image files, bpy-free),
:mod:`blendlib.runtime` (processes and threads: the viewport's scheduler and band helper),
:mod:`blendlib.blender` (the only layer that touches bpy) and :mod:`blendlib.cli`.
:func:`render`, :func:`render_view` and :func:`write_image` import the Blender layer lazily so
that ``import blendlib`` works without bpy.

This namespace is the library's face for callers outside it (the add-on among them): the
scene and result types, the errors a render raises (:class:`SceneError`,
:class:`RenderCancelled`) and the observer hooks (:class:`FrameObserver`), each defined once
in :mod:`blendlib.core`.
"""

from __future__ import annotations

from .core.pipeline import render_scene
from .core.records import Frame, FrameObserver, RenderCancelled
from .core.scene import Camera, DrawScene, Light, Mesh, Renderer, SceneError
from .core.vocabulary import Material, Pass, Texture

__all__ = [
    "Camera", "DrawScene", "Frame", "FrameObserver", "Light", "Material", "Mesh", "Pass", "RenderCancelled",
    "Renderer", "SceneError", "Texture", "analyze", "draw_list", "pixel_history", "render", "render_scene",
    "render_view", "write_image",
]


def render(scene=None, **kwargs) -> Frame:
    """Render a ``bpy.types.Scene`` (default: the context scene) with the Unity pipeline.

    Returns a :class:`Frame` whose ``color`` (H, W, 4) float32 holds the stored frame
    values and ``depth`` (H, W) float32 the window depth; row 0 is the top.
    ``until_draw=K``: the frame after draw call K (1-based; 0 = the cleared frame).
    """
    from . import blender

    return blender.render(scene, **kwargs)


def render_view(scene, view_matrix, projection_matrix, width: int, height: int, **kwargs) -> Frame:
    """Render a ``bpy.types.Scene`` (None: the context scene) through a view's 4x4 matrices.

    The Frame a camera with ``view_matrix`` (world → view) and ``projection_matrix`` (view →
    clip) would give at ``width`` x ``height``: what the viewport's Rendered shading shows.
    Matrices are ``mathutils.Matrix`` or anything numpy accepts. The scene is left unchanged.
    """
    from .blender import viewport

    return viewport.render_view(scene, view_matrix, projection_matrix, width, height, **kwargs)


def analyze(scene=None, *, advice: bool = True, max_advice: int = 5, **kwargs):
    """The sorted reference, sort error, inversions, overdraw and advice of a ``bpy.types.Scene``
    (default: the context scene) as F12 renders it: a :class:`blendlib.explain.sorted_reference.Analysis`.
    A :class:`DrawScene` is analysed directly. ``advice``: check a fix for each of the
    ``max_advice`` largest inversion pairs (:mod:`blendlib.explain.advice`). Other keyword
    arguments go to :func:`blendlib.explain.sorted_reference.analyze` (``progress``,
    ``should_cancel``, ``workers``)."""
    from .explain.advice import analyze_and_advise

    if not isinstance(scene, DrawScene):
        from . import blender

        scene = blender.draw_scene_final(scene)
    return analyze_and_advise(scene, max_advice=max_advice if advice else 0, **kwargs)


def draw_list(scene=None, **kwargs):
    """The draw calls of a ``bpy.types.Scene`` (default: the context scene) in order, each a
    :class:`blendlib.explain.framedebug.DrawStats` (``.call``, ``.triangles``, ``.fragments``,
    ``.written``; ``.to_json()`` gives the JSON item of docs/json.md). Costs one render."""
    from .blender import framedebug

    return framedebug.draw_list(scene, **kwargs)


def pixel_history(scene, x: int, y: int, **kwargs):
    """The history of pixel (``x`` from the left, ``y`` from the top) of a ``bpy.types.Scene``
    (None: the context scene): a :class:`blendlib.explain.framedebug.PixelHistory` of every
    fragment rasterised there (``.to_json()`` gives the JSON object of docs/json.md). Costs one render."""
    from .blender import framedebug

    return framedebug.pixel_history(scene, x, y, **kwargs)


def write_image(frame: Frame, name: str, **kwargs):
    """Write a frame's colour into the ``bpy.types.Image`` called ``name`` (created if needed)."""
    from . import blender

    return blender.write_image(frame, name, **kwargs)
