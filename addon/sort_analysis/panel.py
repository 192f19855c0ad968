"""Render Properties › Unity Sort Analysis: the passes option, the inversion list and its advice."""

from __future__ import annotations

import bpy

from .. import ENGINE_ID
from .ops import UNITY_OT_sort_analyze, UNITY_OT_sort_apply_advice


class UNITY_UL_sort_inversions(bpy.types.UIList):
    """Inverted pairs: front object, behind object, pixels."""

    bl_idname = "UNITY_UL_sort_inversions"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.row(align=True)
        text = f"{item.front} over itself" if item.front == item.behind else f"{item.front} before {item.behind}"
        row.label(text=text, icon="SORTSIZE" if item.change else "MOD_MESHDEFORM")
        row.label(text=f"{item.pixels} px")


class UNITY_PT_sort_analysis(bpy.types.Panel):
    """Where the frame differs from a per-fragment sort, which objects are out of order, what to change."""

    bl_idname = "UNITY_PT_sort_analysis"
    bl_label = "Unity Sort Analysis"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.scene.render.engine == ENGINE_ID

    def draw(self, context):
        layout = self.layout
        settings = getattr(context.view_layer, "unity_analysis", None)
        if settings is not None:
            layout.prop(settings, "use_passes")
        layout.operator(UNITY_OT_sort_analyze.bl_idname, icon="VIEWZOOM")
        results = context.window_manager.unity_sort_results
        if results.summary:
            layout.label(text=results.summary)
        if not results.items:
            return
        layout.template_list(UNITY_UL_sort_inversions.bl_idname, "", results, "items", results, "active_index",
                             rows=3)
        if 0 <= results.active_index < len(results.items):
            item = results.items[results.active_index]
            box = layout.box()
            col = box.column(align=True)
            words, line = item.text.split(), ""
            for word in words:  # wrap the advice sentence
                if len(line) + len(word) > 60:
                    col.label(text=line)
                    line = ""
                line = f"{line} {word}".strip()
            if line:
                col.label(text=line)
            row = box.row()
            row.enabled = bool(item.change)
            row.operator(UNITY_OT_sort_apply_advice.bl_idname, icon="CHECKMARK")


CLASSES = (UNITY_UL_sort_inversions, UNITY_PT_sort_analysis)
