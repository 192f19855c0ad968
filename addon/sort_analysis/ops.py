"""Operators: analyse the scene's sorting (a job: one progress bar over the render, step 2 and
the advice's measurements; Esc cancels any of them and keeps the previous list); apply a
suggested queue offset or sort setting, or a VRM Add-on setting where the material's state
comes from the VRM Add-on (so that the fix survives its export)."""

from __future__ import annotations

import json
from functools import partial

import bpy

import blendlib
from blendlib import blender
from blendlib.blender import vrm_addon

from ..jobs import JobOperator
from .properties import store


class UNITY_OT_sort_analyze(JobOperator, bpy.types.Operator):
    """Render the frame and its per-fragment sorted reference; list the objects drawn out of order (Esc cancels)"""

    bl_idname = "unity.sort_analyze"
    bl_label = "Analyze Sorting"
    bl_options = {"REGISTER"}

    report_prefix = "Unity Passes: "

    def _work(self, context):
        """The analysis of the scene as F12 renders it, its DrawScene read here on the main thread
        (None: reported why not)."""
        draw = self.read_scene(partial(blender.draw_scene_final, context.scene))
        # the VRM Add-on's settings, read here with the scene: advice in their terms (the job reads no bpy)
        return None if draw is None else partial(blendlib.analyze, draw, settings=vrm_addon.advice_settings())

    def execute(self, context):
        work = self._work(context)
        return {"CANCELLED"} if work is None else self.run_now(context, work)

    def invoke(self, context, event):
        work = self._work(context)
        return {"CANCELLED"} if work is None else self.start_job(context, work, "Analysing the sorting")

    def job_done(self, context, analysis) -> None:
        results = context.window_manager.unity_sort_results
        store(results, analysis)
        self.report({"INFO"}, f"Unity Passes: {results.summary}; {len(results.items)} inverted pairs")


class UNITY_OT_sort_apply_advice(bpy.types.Operator):
    """Apply the selected inversion's suggested queue offset, sort setting or VRM Add-on setting"""

    bl_idname = "unity.sort_apply_advice"
    bl_label = "Apply Advice"
    bl_options = {"REGISTER", "UNDO"}

    index: bpy.props.IntProperty(name="Index", description="Row of the inversion list (-1: the selected row)",
                                 default=-1)

    @classmethod
    def poll(cls, context):
        results = getattr(context.window_manager, "unity_sort_results", None)
        return results is not None and any(row.change for row in results.items)

    def execute(self, context):
        results = context.window_manager.unity_sort_results
        index = results.active_index if self.index < 0 else self.index
        if not 0 <= index < len(results.items) or not results.items[index].change:
            self.report({"ERROR"}, "Unity Passes: this inversion has no setting to apply (self-overlap: "
                                   "use the 'Alpha Blend ZWrite' preset, split the mesh or sort its faces)")
            return {"CANCELLED"}
        change = json.loads(results.items[index].change)
        if "vrm" in change:
            mat = bpy.data.materials.get(change["material"])
            if mat is None:
                self.report({"ERROR"}, f"Unity Passes: material {change['material']!r} not found")
                return {"CANCELLED"}
            try:
                vrm_addon.apply_settings(mat, change["vrm"])
            except ValueError as exc:
                self.report({"ERROR"}, f"Unity Passes: {exc}")
                return {"CANCELLED"}
            written = ", ".join(f"{key} {value}" for key, value in change["vrm"].items())
            done = f"material {mat.name!r}: VRM Add-on {written}"
        elif "material" in change:
            mat = bpy.data.materials.get(change["material"])
            if mat is None or not hasattr(mat, "unity"):
                self.report({"ERROR"}, f"Unity Passes: material {change['material']!r} not found")
                return {"CANCELLED"}
            mat.unity.queue_offset = int(change["queue_offset"])
            done = f"material {mat.name!r}: queue offset {mat.unity.queue_offset}"
        else:
            unity = context.scene.unity
            unity.sort_mode = change["sort_mode"]
            if "sort_axis" in change:
                unity.sort_axis = change["sort_axis"]
            done = f"scene sort mode {unity.sort_mode}"
        self.report({"INFO"}, f"Unity Passes: {done} (run Analyze Sorting again to check)")
        return {"FINISHED"}


CLASSES = (UNITY_OT_sort_analyze, UNITY_OT_sort_apply_advice)
