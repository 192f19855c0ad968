"""Frame Debugger operators: Capture, Pixel History; the capture cache and the image update.

Invoked from the UI, both run their render as a job (:mod:`addon.jobs`: a worker thread, progress
in the status bar, Esc cancels); ``execute`` (scripts, background tests) runs synchronously. The
capture (draw statistics, final frame, snapshots within
:data:`blendlib.explain.framedebug.SNAPSHOT_MEMORY`) is kept for one scene at a time, so moving
the draw slider replays from the nearest snapshot instead of rendering from scratch.
"""

from __future__ import annotations

import math
from functools import partial

import bpy
from bpy.props import IntProperty

from blendlib.blender import draw_scene_final
from blendlib.blender import framedebug as bfd
from blendlib.explain import framedebug as fd

from ..jobs import JobOperator

#: The one kept capture: scene pointer, capture id, FrameCapture.
_CAPTURE: dict = {}
_NEXT_ID = [0]


def forget_capture() -> None:
    _CAPTURE.clear()


def current_capture(scene) -> fd.FrameCapture | None:
    """The capture the scene's lists come from, or None (never captured, or since reloaded)."""
    settings = scene.unity_frame_debugger
    if (_CAPTURE.get("scene") == scene.as_pointer() and _CAPTURE.get("id") == settings.capture_id
            and settings.capture_id):
        return _CAPTURE["capture"]
    return None


def store_capture(scene, cap: fd.FrameCapture) -> None:
    """Keep ``cap`` for ``scene`` and fill the draw list; shows the whole frame."""
    _NEXT_ID[0] += 1
    _CAPTURE.clear()
    _CAPTURE.update(scene=scene.as_pointer(), id=_NEXT_ID[0], capture=cap)
    settings = scene.unity_frame_debugger
    settings.capture_id = _NEXT_ID[0]
    settings.draws.clear()
    for s in cap.stats:
        item = settings.draws.add()
        data = s.to_json()
        item.index, item.queue, item.distance = data["index"], data["queue"], data["distance"]
        item.object, item.slot, item.material = data["object"], data["slot"], data["material"]
        item.pass_index, item.pass_name, item.state = data["pass"], data["pass_name"], data["state"]
        item.triangles, item.fragments, item.written = data["triangles"], data["fragments"], data["written"]
    settings.fragments.clear()
    cam = cap.scene.camera
    settings.status = (f"{len(cap.stats)} draw calls, {cam.width}x{cam.height}; snapshots every {cap.interval} "
                       f"draws ({cap.snapshot_memory / 2**20:.0f} MB)" if cap.interval else
                       f"{len(cap.stats)} draw calls, {cam.width}x{cam.height}")
    if settings.draw != len(cap.stats):
        settings.draw = len(cap.stats)  # its update shows the frame
    else:
        show_selected(scene)


def show_selected(scene):
    """Write the selected buffer after the selected draw into the image "Unity Frame Debugger"."""
    settings = scene.unity_frame_debugger
    cap = current_capture(scene)
    if cap is None:
        return None
    return bfd.show(cap, min(settings.draw, len(cap.stats)), settings.buffer, settings.highlight)


def store_history(scene, history: fd.PixelHistory) -> None:
    settings = scene.unity_frame_debugger
    settings.fragments.clear()
    for f in history.fragments:
        item = settings.fragments.add()
        item.draw, item.object, item.pass_name = f.call.index, f.call.renderer.name, f.call.state.name
        item.triangle, item.polygon = f.triangle, -1 if f.polygon is None else f.polygon
        item.depth, item.source, item.before, item.after = f.depth, f.source, f.before, f.after
        item.stencil_before, item.stencil_after, item.result = f.stencil_before, f.stencil_after, f.result
    settings.pixel_x, settings.pixel_y = history.x, history.y
    rgba = " ".join(f"{v:.3f}" for v in history.final)
    settings.pixel_text = f"Pixel ({history.x}, {history.y}): {len(history.fragments)} fragments, final {rgba}"


def pixel_from_view(u: float, v: float, width: int, height: int) -> tuple[int, int] | None:
    """Image Editor view coordinates (0..1 across the image, v up) → (X from the left, Y from the
    top), or None outside the image."""
    if not (math.isfinite(u) and math.isfinite(v)):
        return None
    col, row_up = math.floor(u * width), math.floor(v * height)
    if not (0 <= col < width and 0 <= row_up < height):
        return None
    return col, height - 1 - row_up


class UNITY_OT_frame_debugger_capture(JobOperator, bpy.types.Operator):
    """Render the scene once with the Unity pipeline and list its draw calls (Esc cancels)"""

    bl_idname = "unity.frame_debugger_capture"
    bl_label = "Capture"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None and hasattr(context.scene, "unity_frame_debugger")

    def _draw_scene(self, context):
        return self.read_scene(partial(draw_scene_final, context.scene))

    def execute(self, context):
        draw = self._draw_scene(context)
        if draw is None:
            return {"CANCELLED"}
        return self.run_now(context, partial(fd.FrameCapture.capture, draw))

    def invoke(self, context, event):
        draw = self._draw_scene(context)
        if draw is None:
            return {"CANCELLED"}
        return self.start_job(context, partial(fd.FrameCapture.capture, draw), "Capturing the frame")

    def job_done(self, context, cap) -> None:
        store_capture(context.scene, cap)
        self.report({"INFO"}, context.scene.unity_frame_debugger.status)


class UNITY_OT_frame_debugger_pixel(JobOperator, bpy.types.Operator):
    """List every fragment of a pixel: click a pixel in the image (or give X and Y), Esc cancels"""

    bl_idname = "unity.frame_debugger_pixel"
    bl_label = "Pixel History"
    bl_options = {"REGISTER"}

    x: IntProperty(name="X", description="Pixel column, from the left", default=-1, min=-1)
    y: IntProperty(name="Y", description="Pixel row, from the top", default=-1, min=-1)

    @classmethod
    def poll(cls, context):
        return context.scene is not None and hasattr(context.scene, "unity_frame_debugger")

    def _draw_scene(self, context):
        cap = current_capture(context.scene)
        if cap is not None:
            return cap.scene  # the captured frame, so the history matches what is shown
        return self.read_scene(partial(draw_scene_final, context.scene))

    def _coordinates(self, context) -> tuple[int, int]:
        settings = context.scene.unity_frame_debugger
        x = settings.pixel_x if self.x < 0 else self.x
        y = settings.pixel_y if self.y < 0 else self.y
        return x, y

    def execute(self, context):
        draw = self._draw_scene(context)
        if draw is None:
            return {"CANCELLED"}
        x, y = self._coordinates(context)
        return self.run_now(context, partial(fd.pixel_history, draw, x, y))

    def invoke(self, context, event):
        if self.x >= 0 and self.y >= 0:
            return self.run_job(context, self.x, self.y)
        region = context.region
        if region is not None and region.type == "WINDOW" and context.area.type == "IMAGE_EDITOR":
            return self.pick(context, region, event.mouse_region_x, event.mouse_region_y)
        if context.area is None or context.area.type != "IMAGE_EDITOR":
            return self.execute(context)  # typed X/Y from the panel
        if context.workspace is not None:
            context.workspace.status_text_set("Click a pixel of the image (Esc or right-click to cancel)")
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal_without_job(self, context, event):
        if event.type in {"ESC", "RIGHTMOUSE"}:
            if context.workspace is not None:
                context.workspace.status_text_set(None)
            return {"CANCELLED"}
        if event.type != "LEFTMOUSE" or event.value != "PRESS":
            return {"RUNNING_MODAL"}
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        for region in context.area.regions:
            if region.type == "WINDOW" and 0 <= event.mouse_x - region.x < region.width \
                    and 0 <= event.mouse_y - region.y < region.height:
                return self.pick(context, region, event.mouse_x - region.x, event.mouse_y - region.y)
        self.report({"WARNING"}, "Click inside the image")
        return {"CANCELLED"}

    def pick(self, context, region, mx: int, my: int):
        draw = self._draw_scene(context)
        if draw is None:
            return {"CANCELLED"}
        u, v = region.view2d.region_to_view(mx, my)
        found = pixel_from_view(u, v, draw.camera.width, draw.camera.height)
        if found is None:
            self.report({"WARNING"}, "The mouse is not over the image")
            return {"CANCELLED"}
        return self.run_job(context, *found)

    def run_job(self, context, x: int, y: int):
        draw = self._draw_scene(context)
        if draw is None:
            return {"CANCELLED"}
        w, h = draw.camera.width, draw.camera.height
        if not (0 <= x < w and 0 <= y < h):  # checked before the worker starts
            self.report({"ERROR"}, f"pixel ({x}, {y}) is outside the {w}x{h} image")
            return {"CANCELLED"}
        return self.start_job(context, partial(fd.pixel_history, draw, x, y), f"Pixel history of ({x}, {y})")

    def job_done(self, context, history) -> None:
        store_history(context.scene, history)
        self.report({"INFO"}, context.scene.unity_frame_debugger.pixel_text)


CLASSES = (UNITY_OT_frame_debugger_capture, UNITY_OT_frame_debugger_pixel)
