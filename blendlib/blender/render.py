"""Rendering a Blender scene with the Unity pipeline, and writing a Frame back as a Blender image.

The rule of the Python API: what renders or explains a scene's frame — :func:`render`,
:func:`draw_scene` (the frame debugger's draw list, pixel history and Capture), the analysis —
sees what F12 renders: Blender's render-mode evaluation (modifier render levels, render
visibility), through :func:`render_final` (a capture engine run by Blender's render
operator keeps the Frame in memory). Given a ``depsgraph`` (e.g. the viewport's,
``bpy.context.evaluated_depsgraph_get()``, what the Rendered viewport shows) they use that
evaluation instead; :func:`blendlib.render_view` always shows the viewport's.
"""

from __future__ import annotations

import contextlib
import operator
from collections.abc import Callable
from typing import Any

import numpy as np

from ..core import colorspace, pipeline
from ..core.drawlist import draw_calls
from ..core.scene import SceneError
from ..runtime import bandprocs
from .extract import build_draw_scene
from .files import scene_arg
from .pixels import bottom_first


def render(scene: Any = None, depsgraph: Any = None, progress: Callable[[float], None] | None = None,
           should_cancel: Callable[[], bool] | None = None, until_draw: int | None = None) -> pipeline.Frame:
    """Render a Blender scene with the Unity pipeline; see :func:`blendlib.render`.

    ``scene``: a ``bpy.types.Scene``, its name, or None (the context scene). ``depsgraph`` None:
    the frame F12 renders (:func:`render_final`, Render Region included); a depsgraph: that
    evaluation of the scene, the whole frame. ``until_draw`` K: the frame after draw call K
    (docs/framedebugger.md; 0 = the cleared frame; an integer up to the number of draw calls).
    The Frame's ``warnings`` hold the extraction warnings followed by the core's.
    Raises :class:`SceneError` (no camera, bad input) or :class:`pipeline.RenderCancelled`.
    """
    if depsgraph is None:
        return render_final(scene, progress=progress, should_cancel=should_cancel, until_draw=until_draw)
    return _render_evaluated(scene_arg(scene), depsgraph, progress, should_cancel, until_draw)


def checked_until_draw(until_draw: Any, calls: int | None = None) -> int | None:
    """``until_draw`` as an int: None stays None; an integer from 0 to ``calls`` (the frame's
    number of draw calls, when known). TypeError for a non-integer (1.5 is not draw 1),
    SceneError for a number out of range."""
    if until_draw is None:
        return None
    if isinstance(until_draw, bool):
        raise TypeError("until_draw must be an integer, got a bool")
    try:
        k = operator.index(until_draw)
    except TypeError:
        raise TypeError(f"until_draw must be an integer, got {until_draw!r}") from None
    if k < 0:
        raise SceneError(f"until_draw must be 0 or more (got {k})")
    if calls is not None and k > calls:
        raise SceneError(f"until_draw {k} is beyond the last draw call: the frame has {calls} "
                         f"(0 = the cleared frame, {calls} = the whole frame)")
    return k


def _render_evaluated(scene: Any, depsgraph: Any, progress: Callable[[float], None] | None,
                      should_cancel: Callable[[], bool] | None, until_draw: Any) -> pipeline.Frame:
    """The frame of ``scene`` as ``depsgraph`` evaluates it (the capture engine's, or a caller's)."""
    draw = build_draw_scene(scene, depsgraph)
    if until_draw is None:
        frame = render_frame(draw, progress=progress, should_cancel=should_cancel)
    else:
        calls = draw_calls(draw)
        until_draw = checked_until_draw(until_draw, len(calls))
        frame = pipeline.render_scene(draw, progress=progress, should_cancel=should_cancel, until_draw=until_draw,
                                      calls=calls)
    extra = [w for w in draw.warnings if w not in frame.warnings]
    frame.warnings[:0] = extra
    frame.warnings[:] = one_warning_per_cause(frame.warnings)
    return frame


def render_frame(draw: Any, progress: Callable[[float], None] | None = None,
                 should_cancel: Callable[[], bool] | None = None) -> pipeline.Frame:
    """A final frame of a DrawScene (F12, :func:`render`): :func:`pipeline.render_scene`'s frame, bit
    for bit, drawn in two bands by this process and a helper process when the frame is large
    (:func:`blendlib.runtime.bandprocs.final_renderer`: threads of one process wait on each
    other's interpreter lock on frames of short array calls)."""
    return bandprocs.final_renderer()(draw, progress=progress, should_cancel=should_cancel)


def one_warning_per_cause(warnings: list[str]) -> list[str]:
    """The warnings without repeats: an image the extraction could not read (its line names the file)
    is not reported again by the core's "file missing" line; identical lines are listed once."""
    unread = {w.split(": cannot read ", 1)[0] for w in warnings if w.startswith("image ") and ": cannot read " in w}
    out: dict[str, None] = {}
    for w in warnings:
        if not (w.endswith(": file missing, drawn magenta") and w.rsplit(": ", 1)[0] in unread):
            out[w] = None
    return list(out)


_CAPTURE_ENGINE_ID = "UNITY_PASSES_CAPTURE"
_capture: dict[str, Any] = {}
_capture_engine: list = []


def _capture_engine_class() -> Any:
    """A minimal render engine that renders with the Unity pipeline and keeps the Frame in memory.

    Registered on first use (not listed for users: the add-on's engine is ``UNITY_PASSES``).
    """
    import bpy

    if _capture_engine:
        return _capture_engine[0]

    class UnityPassesCaptureEngine(bpy.types.RenderEngine):
        bl_idname = _CAPTURE_ENGINE_ID
        bl_label = "Unity Passes (capture)"
        bl_use_preview = False

        def render(self, depsgraph):
            try:
                job = _capture.get("job")
                if job is not None:  # e.g. build the draw scene only (draw_scene_final)
                    _capture["frame"] = job(depsgraph)
                    return
                _capture["frame"] = _render_evaluated(depsgraph.scene, depsgraph, _capture.get("progress"),
                                                      _capture.get("should_cancel"), _capture.get("until_draw"))
            except Exception as exc:  # noqa: BLE001 - handed back to render_final's caller
                _capture["error"] = exc

    bpy.utils.register_class(UnityPassesCaptureEngine)
    _capture_engine.append(UnityPassesCaptureEngine)
    return UnityPassesCaptureEngine


def render_final(scene: Any = None, progress: Callable[[float], None] | None = None,
                 should_cancel: Callable[[], bool] | None = None, frame: int | None = None,
                 until_draw: int | None = None, _job: Callable[[Any], Any] | None = None) -> pipeline.Frame:
    """Render as F12 does: through Blender's render-mode depsgraph.

    :func:`render` uses the viewport depsgraph (Python cannot make a render-mode one), so
    modifiers evaluate with their viewport settings there. This runs ``bpy.ops.render.render``
    with a capture engine instead, so modifier render levels and render visibility apply
    exactly as for F12 and ``blender -b -E UNITY_PASSES``. The scene's render engine is set
    for the call and restored; no image is written, and the user's "Render Result" keeps its
    renders (:func:`_render_result_kept`). ``frame``: the frame to set first (the
    scene's current frame is restored afterwards); ``until_draw``: stop after that draw call
    (docs/framedebugger.md). A Render Region (``use_border``) gives what F12 writes: the region only with
    Crop, else the full size with only the region filled. Raises like :func:`render`.
    """
    import bpy

    from .extract import render_size

    scene = scene_arg(scene)
    if scene.camera is None:  # checked here: the operator would fail with its own wording
        raise SceneError(f"scene {scene.name!r} has no camera")
    width, height = render_size(scene)
    if width < 1 or height < 1:  # Blender's own "Image too small" would come as a second line
        raise SceneError(f"scene {scene.name!r}: the render size is {width}x{height} pixels "
                         "(resolution x percentage); it must be at least 1x1")
    region = border_region(scene, width, height)
    engine = _capture_engine_class()
    previous = scene.render.engine
    previous_frame = (scene.frame_current, scene.frame_subframe)
    _capture.clear()
    checked_until_draw(until_draw)  # a non-integer or a negative number before Blender renders
    _capture.update(progress=progress, should_cancel=should_cancel, until_draw=until_draw, job=_job)
    scene.render.engine = engine.bl_idname
    try:
        with bpy.context.temp_override(scene=scene), _render_result_kept():
            if frame is not None:
                scene.frame_set(frame)
            try:
                bpy.ops.render.render(scene=scene.name)
            except RuntimeError as exc:
                lines = str(exc).strip().splitlines()
                reason = lines[-1].removeprefix("Error: ").strip() if lines else "unknown error"
                raise SceneError(f"scene {scene.name!r}: Blender cannot render it ({reason})") from None
    finally:
        scene.render.engine = previous
        if frame is not None and (scene.frame_current, scene.frame_subframe) != previous_frame:
            scene.frame_set(previous_frame[0], subframe=previous_frame[1])
    if "error" in _capture:
        error = _capture.pop("error")
        _capture.clear()
        raise error
    if "frame" not in _capture:
        raise SceneError(f"scene {scene.name!r}: Blender did not render it (no view layer enabled for rendering?)")
    result = _capture.pop("frame")
    _capture.clear()
    if not isinstance(result, pipeline.Frame):  # a _job's result (draw_scene_final): not an image
        return result
    return apply_border(result, region, bool(scene.render.use_crop_to_border))


#: The Render Result slot the capture renders into when the user has a Render Result.
CAPTURE_SLOT = "Unity Passes (capture)"


@contextlib.contextmanager
def _render_result_kept():
    """Blender's render operator renders into the active slot of the "Render Result" image
    (created by the first render). The capture draws no pixels there: without a Render Result
    before, the one the operator creates is removed again; with one, the capture renders into
    a slot of its own (:data:`CAPTURE_SLOT`, made once, reused after) and the user's active slot,
    with their last F12 render, is made active again."""
    import bpy

    results = [image for image in bpy.data.images if image.type == "RENDER_RESULT"]
    slots = results[0].render_slots if results else None
    active = slots.active_index if slots is not None else None
    if slots is not None:
        slot = next((x for x in slots if x.name == CAPTURE_SLOT), None) or slots.new(name=CAPTURE_SLOT)
        slots.active = slot
    try:
        yield
    finally:
        if slots is None:
            for image in [i for i in bpy.data.images if i.type == "RENDER_RESULT"]:
                bpy.data.images.remove(image)
        else:
            slots.active_index = active


def border_region(scene: Any, width: int, height: int) -> tuple[int, int, int, int] | None:
    """The Render Region of ``scene`` in pixels of a ``width`` x ``height`` frame, as Blender computes
    it (border × size in float32, truncated): (x0, x1, y0, y1) with y counted from the bottom row,
    or None when the region is off (``use_border`` False) or covers the whole frame."""
    r = scene.render
    if not r.use_border:
        return None
    f32 = np.float32
    x0, x1 = (int(f32(v) * f32(width)) for v in (r.border_min_x, r.border_max_x))
    y0, y1 = (int(f32(v) * f32(height)) for v in (r.border_min_y, r.border_max_y))
    x0, x1 = max(0, min(x0, width)), max(0, min(x1, width))
    y0, y1 = max(0, min(y0, height)), max(0, min(y1, height))
    if x1 - x0 < 1 or y1 - y0 < 1:
        raise SceneError(f"scene {scene.name!r}: the Render Region is smaller than one pixel "
                         f"({x1 - x0}x{y1 - y0} of {width}x{height})")
    if (x0, x1, y0, y1) == (0, width, 0, height):
        return None
    return x0, x1, y0, y1


def apply_border(frame: pipeline.Frame, region: tuple[int, int, int, int] | None, crop: bool) -> pipeline.Frame:
    """The frame as a render with a Render Region writes it: ``crop`` gives the region only; without
    crop the full size, the region filled and the rest transparent black (colour 0, depth 1 = far,
    stencil 0), as Blender does. ``region`` from :func:`border_region` (None: the frame as is)."""
    if region is None:
        return frame
    x0, x1, y0, y1 = region
    h = frame.color.shape[0]
    rows = slice(h - y1, h - y0)  # row 0 is the top; the region's y counts from the bottom
    cols = slice(x0, x1)
    if crop:
        arrays = [np.ascontiguousarray(a[rows, cols]) for a in (frame.color, frame.depth, frame.stencil)]
    else:
        arrays = [np.zeros_like(frame.color), np.ones_like(frame.depth), np.zeros_like(frame.stencil)]
        for out, a in zip(arrays, (frame.color, frame.depth, frame.stencil), strict=True):
            out[rows, cols] = a[rows, cols]
    return pipeline.Frame(arrays[0], arrays[1], arrays[2], warnings=list(frame.warnings), encoded=frame.encoded)


def draw_scene_final(scene: Any = None, frame: int | None = None) -> Any:
    """The :class:`DrawScene` of ``scene`` as F12 evaluates it (render-mode depsgraph, see
    :func:`render_final`), without rendering: what the draw list and pixel history explain."""
    from .extract import build_draw_scene as build

    return render_final(scene, frame=frame, _job=lambda depsgraph: build(depsgraph.scene, depsgraph))


def draw_scene(scene: Any = None, depsgraph: Any = None) -> Any:
    """The :class:`DrawScene` the tools that explain a frame see (module docstring): F12's
    (:func:`draw_scene_final`) without ``depsgraph``, else that evaluation's."""
    if depsgraph is None:
        return draw_scene_final(scene)
    return build_draw_scene(scene_arg(scene), depsgraph)


def linear_rgba(frame: pipeline.Frame, encoded: bool | None = None, opaque: bool = False) -> np.ndarray:
    """The frame as linear RGBA float32 (row 0 top): encoded frame values are decoded to linear.
    ``opaque``: alpha 1 (what a screen shows, the Combined pass)."""
    if encoded is None:
        encoded = frame.encoded
    color = np.array(frame.color, dtype=np.float32, copy=True)
    if encoded:
        color[..., :3] = colorspace.decode_fast(color[..., :3]).astype(np.float32)
    if opaque:
        color[..., 3] = 1.0
    return color


def write_image(frame: pipeline.Frame, name: str, *, encoded: bool | None = None, opaque: bool = False) -> Any:
    """Write a frame into the ``bpy.types.Image`` called ``name`` (created, or resized, as a float image).

    The image holds linear RGB (encoded frame values decoded; ``encoded`` overrides what the
    frame says) and the frame's alpha (or 1 with ``opaque``), bottom row first as Blender stores it,
    so that the Image Editor with the Standard view transform shows the frame values.
    """
    import bpy

    h, w = frame.color.shape[:2]
    image = bpy.data.images.get(name)
    if image is not None and (not image.is_float or image.source != "GENERATED"):
        bpy.data.images.remove(image)
        image = None
    if image is None:
        image = bpy.data.images.new(name, width=w, height=h, alpha=True, float_buffer=True)
    elif tuple(image.size) != (w, h):
        image.scale(w, h)
    rgba = linear_rgba(frame, encoded=encoded, opaque=opaque)
    image.pixels.foreach_set(bottom_first(rgba).ravel())
    image.update()
    return image

