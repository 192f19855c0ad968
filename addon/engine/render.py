"""The "Unity Passes" render engine (F12, Ctrl+F12, ``blender -b file.blend -E UNITY_PASSES -f 1``).

Passes of the render result:
- ``Combined``: the frame as linear RGB with alpha 1 — what a screen shows. Gamma mode and
  Linear LDR store sRGB-encoded values; they are decoded here, so the Standard view
  transform (no look, no dither) turns them back into exactly the stored 8-bit values.
- ``UnityAlpha``: the frame's own alpha channel (e.g. the clear colour's alpha).
- ``Depth``: the depth buffer as OpenGL window depth 0..1 (not Blender's camera distance).
- With ``ViewLayer.unity_analysis.use_passes`` (:mod:`addon.sort_analysis`): ``UnitySortedReference``
  (RGBA, like Combined but with its alpha), ``UnitySortError`` and ``UnityOverdraw`` (X rasterised,
  Y written, Z 0) of docs/sorting.md.

The viewport's Rendered shading (``view_update`` / ``view_draw``) lives in :mod:`.viewport`.
"""

from __future__ import annotations

import bpy
import numpy as np

import blendlib
from blendlib import RenderCancelled, SceneError, blender
from blendlib.blender.pixels import bottom_first
from blendlib.blender.render import one_warning_per_cause

from .. import ENGINE_ID
from ..sort_analysis import passes as sort_passes
from ..sort_analysis.properties import passes_enabled
from . import viewport

ALPHA_PASS = "UnityAlpha"
DEPTH_PASS = "Depth"


def result_arrays(frame) -> dict[str, np.ndarray]:
    """Pass name → (H*W, channels) float32, bottom row first (Blender's order)."""
    return {
        "Combined": bottom_first(blender.linear_rgba(frame, opaque=True)),
        ALPHA_PASS: bottom_first(frame.color[..., 3]),
        DEPTH_PASS: bottom_first(frame.depth),
    }


def _region_rows(array: np.ndarray, height: int, width: int, region) -> np.ndarray:
    """The Render Region's part of a (H*W, C) bottom-first pass array (the array itself without one)."""
    if region is None:
        return array
    x0, x1, y0, y1 = region
    grid = array.reshape(height, width, -1)[y0:y1, x0:x1]  # bottom first: y counts from the bottom
    return np.ascontiguousarray(grid).reshape((y1 - y0) * (x1 - x0), -1)


class UnityPassesRenderEngine(bpy.types.RenderEngine):
    """Renders what Unity's built-in pipeline draws (render queues, ZWrite/ZTest, Blend, ColorMask, ...)."""

    bl_idname = ENGINE_ID
    bl_label = "Unity Passes"
    bl_use_preview = False
    bl_use_postprocess = True
    bl_use_eevee_viewport = True  # the viewport's Material Preview keeps working

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        self.register_pass(scene, renderlayer, ALPHA_PASS, 1, "A", "VALUE")
        self.register_pass(scene, renderlayer, DEPTH_PASS, 1, "Z", "VALUE")
        if passes_enabled(renderlayer):
            for name, channels, ids, kind in sort_passes.render_passes():
                self.register_pass(scene, renderlayer, name, channels, ids, kind)

    def render(self, depsgraph):
        scene = depsgraph.scene
        width, height = self.resolution_x, self.resolution_y
        self.update_stats("", "Unity Passes: reading the scene")
        self.update_progress(0.0)
        try:
            draw = blender.build_draw_scene(scene, depsgraph)
            if (draw.camera.width, draw.camera.height) != (width, height):
                raise SceneError(f"render size {width}x{height} differs from the camera's "
                                 f"{draw.camera.width}x{draw.camera.height}")
            # A Render Region: the whole frame is rendered, the region handed over (Blender
            # crops it or places it in the full-size image itself).
            region = blender.border_region(scene, width, height)
            self.update_stats("", f"Unity Passes: {len(draw.renderers)} renderers")
            analysed = passes_enabled(depsgraph.view_layer)
            if analysed:
                analysis = blendlib.analyze(draw, advice=False, progress=self._progress,
                                            should_cancel=self.test_break)
                frame = analysis.frame
            else:
                frame = blender.render_frame(draw, progress=self._progress, should_cancel=self.test_break)
        except RenderCancelled:
            # An error report (not a bare return) also stops write_still / animation from saving
            # an empty frame when the break did not come from Blender's own Esc handling.
            self.report({"ERROR"}, "Unity Passes: render cancelled")
            return
        except SceneError as exc:
            self.report({"ERROR"}, f"Unity Passes: {exc}")
            return
        except MemoryError:
            self.report({"ERROR"}, "Unity Passes: out of memory (lower the resolution)")
            return
        except Exception as exc:  # noqa: BLE001 - a report, not a traceback in the UI
            self.report({"ERROR"}, f"Unity Passes: internal error: {type(exc).__name__}: {exc}")
            return
        if self.test_break():
            self.report({"ERROR"}, "Unity Passes: render cancelled")
            return
        try:  # everything after the render reports its failure: an error report stops Blender saving
            for warning in one_warning_per_cause(frame.warnings):
                self.report({"WARNING"}, f"Unity Passes: {warning}")
            extra = sort_passes.result_arrays(analysis) if analysed else None
            self._write_result(depsgraph, frame, region, extra, width, height)
        except Exception as exc:  # noqa: BLE001 - an error report stops Blender from saving the image
            self.report({"ERROR"}, f"Unity Passes: internal error: {type(exc).__name__}: {exc}")
            return
        self.update_progress(1.0)

    def _write_result(self, depsgraph, frame, region, extra: dict | None, width: int, height: int) -> None:
        """Hand the passes to Blender: the Render Region's part when ``region`` is set (``extra``:
        more (H*W, C) bottom-first pass arrays of the full frame, e.g. the sort analysis)."""
        frame_h = frame.color.shape[0]
        frame = blender.apply_border(frame, region, crop=True)
        arrays = result_arrays(frame)
        view_layer = depsgraph.view_layer
        self.add_pass(ALPHA_PASS, 1, "A")
        if extra is not None:
            for name, array in extra.items():
                arrays[name] = _region_rows(array, frame_h, width, region)
            for name, channels, ids, _ in sort_passes.render_passes():
                self.add_pass(name, channels, ids)
        if not view_layer.use_pass_z:
            self.add_pass(DEPTH_PASS, 1, "Z")
        result = self.begin_result(0, 0, width, height)
        cancel = True
        try:
            got = (result.resolution_x, result.resolution_y)
            h, w = frame.color.shape[:2]
            if got != (w, h):
                raise SceneError(f"Blender's render result is {got[0]}x{got[1]}, the frame {w}x{h}")
            layer = result.layers[0]
            for p in layer.passes:
                if p.name in arrays:
                    p.rect = arrays[p.name]
            cancel = False
        finally:
            self.end_result(result, cancel=cancel)

    def _progress(self, fraction: float) -> None:
        self.update_progress(float(fraction))

    # -- viewport (Rendered shading): see addon/viewport.py ----------------------------------------
    def _viewport(self) -> viewport.ViewportSession:
        session = getattr(self, "_viewport_session", None)
        if session is None:
            session = viewport.ViewportSession(viewport.redraw_callback(self))
            self._viewport_session = session
        return session

    def view_update(self, context, depsgraph):
        self._viewport().update(depsgraph)

    def view_draw(self, context, depsgraph):
        self._viewport().draw(self, context, depsgraph)

    def __del__(self):
        # Blender frees the engine when the viewport leaves Rendered shading: stop its worker.
        try:
            session = self.__dict__.get("_viewport_session")
        except ReferenceError:
            return
        if session is not None:
            session.close()
