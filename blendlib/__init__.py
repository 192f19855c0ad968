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

The types are imported on first use (PEP 562): ``python -m blendlib`` imports this package
before its ``__main__`` runs, and the command line must install its Ctrl+C/SIGTERM handling
(:mod:`blendlib.cli.interrupts`) before the heavy imports (numpy, then bpy), or a Ctrl+C in
that window prints a traceback.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .core.pipeline import render_scene
    from .core.records import Frame, FrameObserver, RenderCancelled
    from .core.scene import Camera, DrawScene, Light, Mesh, Renderer, SceneError
    from .core.vocabulary import Material, Pass, Texture

#: Name → the module (relative to this package) that defines it.
_LAZY = {
    "render_scene": "core.pipeline",
    "Frame": "core.records", "FrameObserver": "core.records", "RenderCancelled": "core.records",
    "Camera": "core.scene", "DrawScene": "core.scene", "Light": "core.scene", "Mesh": "core.scene",
    "Renderer": "core.scene", "SceneError": "core.scene",
    "Material": "core.vocabulary", "Pass": "core.vocabulary", "Texture": "core.vocabulary",
}

__all__ = [
    "Camera", "DrawScene", "Frame", "FrameObserver", "Light", "Material", "Mesh", "Pass", "RenderCancelled",
    "Renderer", "SceneError", "Texture", "analyze", "draw_list", "pixel_history", "render", "render_scene",
    "render_view", "write_image",
]


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # later lookups are plain attribute reads
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


def render(scene=None, **kwargs) -> Frame:
    """Render a ``bpy.types.Scene`` (default: the context scene; or a scene's name) with the Unity
    pipeline, as F12 renders it: Blender's render-mode evaluation (modifier render levels,
    render visibility, the Render Region). ``depsgraph=``: that evaluation instead, e.g.
    ``bpy.context.evaluated_depsgraph_get()`` for what the viewport shows.

    Returns a :class:`Frame` whose ``color`` (H, W, 4) float32 holds the stored frame
    values and ``depth`` (H, W) float32 the window depth; row 0 is the top.
    ``until_draw=K``: the frame after draw call K (an integer, 1-based; 0 = the cleared frame;
    beyond the last draw call is an error).
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
    ``max_advice`` largest inversion pairs (:mod:`blendlib.explain.advice`), in VRM terms for the
    VRM Add-on's materials (``settings``: :func:`blendlib.blender.vrm_addon.advice_settings`, read
    from the open file for a ``bpy.types.Scene``; pass it with a DrawScene). Other keyword
    arguments go to :func:`blendlib.explain.sorted_reference.analyze` (``progress``,
    ``should_cancel``, ``workers``) and to :func:`blendlib.explain.advice.advise`
    (``measure_map``; default: the candidates shared with a forked copy of this process where
    that pays, :class:`blendlib.runtime.forked.ForkedMap`)."""
    from .core.scene import DrawScene
    from .explain.advice import analyze_and_advise
    from .runtime.forked import ForkedMap

    kwargs.setdefault("measure_map", ForkedMap())
    if not isinstance(scene, DrawScene):
        from . import blender
        from .blender import vrm_addon

        scene = blender.draw_scene_final(scene)
        kwargs.setdefault("settings", vrm_addon.advice_settings())
    return analyze_and_advise(scene, max_advice=max_advice if advice else 0, **kwargs)


def draw_list(scene=None, **kwargs):
    """The draw calls of a ``bpy.types.Scene`` (default: the context scene) in order, each a
    :class:`blendlib.explain.framedebug.DrawStats` (``.call``, ``.triangles``, ``.fragments``,
    ``.written``; ``.to_json()`` gives the JSON item of docs/json.md). Costs one render. The
    scene is evaluated as F12 renders it (see :func:`render`; ``depsgraph=`` for another)."""
    from .blender import framedebug

    return framedebug.draw_list(scene, **kwargs)


def pixel_history(scene, x: int, y: int, **kwargs):
    """The history of pixel (``x`` from the left, ``y`` from the top) of a ``bpy.types.Scene``
    (None: the context scene): a :class:`blendlib.explain.framedebug.PixelHistory` of every
    fragment rasterised there (``.to_json()`` gives the JSON object of docs/json.md). Costs one render.
    The scene is evaluated as F12 renders it (see :func:`render`; ``depsgraph=`` for another)."""
    from .blender import framedebug

    return framedebug.pixel_history(scene, x, y, **kwargs)


def write_image(frame: Frame, name: str, **kwargs):
    """Write a frame's colour into the ``bpy.types.Image`` called ``name`` (created if needed)."""
    from . import blender

    return blender.write_image(frame, name, **kwargs)
