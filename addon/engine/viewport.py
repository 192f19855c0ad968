"""The engine's viewport (Rendered shading): ``view_update`` / ``view_draw``.

Main thread: ``view_update`` extracts the scene (bpy is not thread-safe) into a bpy-free
template; ``view_draw`` works out the region's view, submits template + view to the
:class:`~blendlib.runtime.scheduler.ViewportScheduler` when either changed (stale work is
cancelled there), and draws the newest finished frame. Worker thread: renders a reduced
frame, then the full one, and asks for a redraw after each.

Only :func:`draw_pixels` uses Blender's ``gpu`` module (it cannot run headless); everything
else is tested with it replaced.
"""

from __future__ import annotations

import dataclasses
import weakref
from collections.abc import Callable
from typing import Any

import numpy as np

from blendlib import SceneError, blender
from blendlib.blender import viewport
from blendlib.blender.pixels import bottom_first
from blendlib.runtime.scheduler import ViewportScheduler


def display_pixels(frame) -> np.ndarray:
    """(H*W*4,) float32 linear RGBA, bottom row first: exactly the F12 Combined pass (alpha 1), so
    Blender's display-space shader shows the colours F12 shows under the same view transform."""
    return bottom_first(blender.linear_rgba(frame, opaque=True)).ravel()


def draw_pixels(engine: Any, scene: Any, pixels: np.ndarray, size: tuple[int, int],
                rect: tuple[int, int, int, int]) -> None:
    """Draw ``pixels`` ((H*W*4,) float32, ``size`` = (W, H)) into ``rect`` (x, y, w, h) of the region,
    after Blender's RenderEngine template: a float texture, premultiplied blending and the
    display-space shader (view transform, look, exposure as for F12)."""
    import gpu
    from gpu_extras.presets import draw_texture_2d

    width, height = size
    buffer = gpu.types.Buffer("FLOAT", width * height * 4, pixels)
    texture = gpu.types.GPUTexture((width, height), format="RGBA32F", data=buffer)
    gpu.state.blend_set("ALPHA_PREMULT")
    engine.bind_display_space_shader(scene)
    draw_texture_2d(texture, (rect[0], rect[1]), rect[2], rect[3])
    engine.unbind_display_space_shader()
    gpu.state.blend_set("NONE")


DrawFunction = Callable[[Any, Any, np.ndarray, tuple[int, int], tuple[int, int, int, int]], None]


class ViewportSession:
    """The viewport state of one engine instance (Blender makes one engine per viewport).

    ``redraw``: called from the worker thread when a frame is ready (the engine's ``tag_redraw``).
    """

    def __init__(self, redraw: Callable[[], None], render: Callable[..., Any] | None = None):
        kwargs = {} if render is None else {"render": render}
        self.scheduler = ViewportScheduler(on_ready=redraw, **kwargs)
        self.template = None
        self._extracted = None  # the last template extracted: its unchanged parts are reused
        self.scene_version = 0
        self.submitted = None
        self.error: str | None = None
        self._pixels: tuple[Any, np.ndarray] | None = None  # (ViewFrame, its display pixels)

    def update(self, depsgraph: Any) -> None:
        """``view_update``: re-extract the scene (main thread); the next draw submits it."""
        self.scene_version += 1
        try:
            self.template = viewport.extract_template(depsgraph.scene, depsgraph, previous=self._extracted)
            self._extracted = self.template
            self.error = None
        except SceneError as exc:
            self.template = None
            self.error = str(exc)

    def draw(self, engine: Any, context: Any, depsgraph: Any, draw: DrawFunction = draw_pixels) -> bool:
        """``view_draw``: submit the current view when it or the scene changed; draw the newest frame.
        Returns whether a frame was drawn."""
        if self.template is None:
            self.update(depsgraph)
        request = viewport.region_view(depsgraph.scene, depsgraph, context.region, context.region_data)
        key = (self.scene_version, request.key)
        if self.template is not None and key != self.submitted:
            self.scheduler.submit(dataclasses.replace(self.template, camera=request.camera), key)
            self.submitted = key
        shown = self.scheduler.latest()
        message = self.error or self.scheduler.error
        if message:
            engine.update_stats("", f"Unity Passes: {message}")
        if shown is None:
            return False
        if self._pixels is None or self._pixels[0] is not shown:
            self._pixels = (shown, display_pixels(shown.frame))
        h, w = shown.frame.color.shape[:2]
        draw(engine, depsgraph.scene, self._pixels[1], (w, h), (request.x, request.y, request.width, request.height))
        return True

    def close(self) -> None:
        self.scheduler.close()


def redraw_callback(engine: Any) -> Callable[[], None]:
    """``engine.tag_redraw`` through a weak reference, so the worker does not keep the engine alive
    (Blender frees it when the viewport leaves Rendered shading)."""
    ref = weakref.ref(engine)

    def redraw() -> None:
        target = ref()
        if target is not None:
            try:
                target.tag_redraw()
            except ReferenceError:  # the engine's Blender data is already freed
                pass

    return redraw
