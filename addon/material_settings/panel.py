"""Panels: "Unity Material" (Material Properties, with its pass list and Presets menu), "Unity
Camera" (Render Properties) and "Unity Light" (Light Properties)."""

from __future__ import annotations

import bpy

from blendlib.blender import derived_light_values, light_settings, read_pass
from blendlib.blender.vrm_addon import summary as vrm_addon_summary
from blendlib.core.vocabulary import NEVER, PASS_PRESETS, Queue, pass_draws, pass_state_text, queue_text

from .. import ENGINE_ID
from ..shaderlab.panel import draw_import_export
from .ops import (
    UNITY_OT_apply_preset,
    UNITY_OT_fill_from_principled,
    UNITY_OT_pass_add,
    UNITY_OT_pass_duplicate,
    UNITY_OT_pass_move,
    UNITY_OT_pass_remove,
    UNITY_OT_use_standard_view,
)


def shaderlab_preview(item) -> str:
    """The pass's state as one line of ShaderLab (the list row and the pass box show it)."""
    try:
        return pass_state_text(read_pass(item))
    except ValueError as exc:  # e.g. an out-of-range stored value
        return f"invalid pass: {exc}"


def exact_view(scene) -> bool:
    """Whether the colour management shows and saves the frame values exactly."""
    view = scene.view_settings
    return (view.view_transform == "Standard" and view.look == "None" and view.exposure == 0.0
            and view.gamma == 1.0 and not view.use_curve_mapping
            and scene.display_settings.display_device == "sRGB")


def draw_rule(material_settings, item) -> tuple[str, str]:
    """How ``item`` (a pass of ``material_settings``) draws in the forward path, and why
    (:func:`blendlib.core.vocabulary.pass_draws`); an unreadable pass draws as stored."""
    try:
        passes = tuple(read_pass(p) for p in material_settings.passes)
        return pass_draws(read_pass(item), passes)
    except ValueError as exc:
        return NEVER, f"invalid pass: {exc}"


class UNITY_UL_passes(bpy.types.UIList):
    """Passes of a Unity material, drawn from top to bottom; passes the forward path does not draw
    are greyed (the pass box below says why)"""

    bl_idname = "UNITY_UL_passes"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0, flt_flag=0):
        if self.layout_type in {"DEFAULT", "COMPACT"}:
            layout.active = draw_rule(data, item)[0] != NEVER
            split = layout.split(factor=0.3)
            split.prop(item, "name", text="", emboss=False, icon="RENDERLAYERS")
            split.label(text=shaderlab_preview(item))
        else:
            layout.alignment = "CENTER"
            layout.label(text=str(index + 1))


class UNITY_MT_presets(bpy.types.Menu):
    """Pass-state presets of the tutorials"""

    bl_idname = "UNITY_MT_presets"
    bl_label = "Unity Presets"

    def draw(self, context):
        layout = self.layout
        for name in PASS_PRESETS:
            layout.operator(UNITY_OT_apply_preset.bl_idname, text=name).preset = name


class _MaterialPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return getattr(context, "material", None) is not None and hasattr(context.material, "unity")


class UNITY_PT_material(_MaterialPanel, bpy.types.Panel):
    bl_idname = "UNITY_PT_material"
    bl_label = "Unity Material"

    def draw_header(self, context):
        self.layout.prop(context.material.unity, "enabled", text="")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        unity = context.material.unity
        row = layout.row(align=True)
        row.menu(UNITY_MT_presets.bl_idname, icon="PRESET")
        row.operator(UNITY_OT_fill_from_principled.bl_idname, icon="NODE_MATERIAL")
        draw_import_export(layout)
        vrm_line = None if unity.enabled else vrm_addon_summary(context.material)
        if vrm_line is not None:  # read-only: the state comes from the VRM Add-on's MToon settings
            box = layout.box()
            box.label(text=vrm_line, icon="INFO")
            box.label(text="Off: renders as UniVRM draws the VRM Add-on's export (these settings are unused).")
        elif not unity.enabled:
            box = layout.box()
            box.label(text="Off: renders opaque (queue Geometry, one default pass, Lambert)", icon="INFO")
            box.label(text="with the Principled BSDF Base Color/Alpha and its linked Image Texture.")
        body = layout.column()
        body.active = unity.enabled
        col = body.column(align=True)
        col.prop(unity, "queue")
        col.prop(unity, "queue_offset")
        number = Queue.parse(unity.queue).number + unity.queue_offset
        col.label(text=f'Render queue {number}  ("Queue"="{queue_text(Queue.parse(unity.queue), unity.queue_offset)}")')
        body.separator()
        body.prop(unity, "color")
        body.template_ID(unity, "main_tex", new="image.new", open="image.open")
        col = body.column(align=True)
        col.prop(unity, "main_tex_tiling")
        col.prop(unity, "main_tex_offset")
        col = body.column(align=True)
        col.prop(unity, "main_tex_filter")
        col.prop(unity, "main_tex_wrap")
        col.prop(unity, "main_tex_mipmaps")
        sub = col.column(align=True)
        sub.active = unity.main_tex_mipmaps
        sub.prop(unity, "main_tex_preserve_coverage")
        body.prop(unity, "alpha_scale")
        body.prop(unity, "cutoff")
        body.prop(unity, "lighting")
        body.prop(unity, "vertex_color")
        sub = body.column()
        sub.active = unity.vertex_color == "Particle"
        sub.prop(unity, "tint_color")
        body.template_ID(unity, "outline_width_tex", new="image.new", open="image.open")
        row = body.row(align=True)
        row.active = unity.outline_width_tex is not None
        row.prop(unity, "outline_width_tex_filter")
        row.prop(unity, "outline_width_tex_wrap")


class UNITY_PT_material_passes(_MaterialPanel, bpy.types.Panel):
    bl_idname = "UNITY_PT_material_passes"
    bl_label = "Passes"
    bl_parent_id = "UNITY_PT_material"

    def draw(self, context):
        layout = self.layout
        unity = context.material.unity
        layout.active = unity.enabled
        row = layout.row()
        row.template_list(UNITY_UL_passes.bl_idname, "", unity, "passes", unity, "active_pass_index", rows=3)
        side = row.column(align=True)
        side.operator(UNITY_OT_pass_add.bl_idname, icon="ADD", text="")
        side.operator(UNITY_OT_pass_remove.bl_idname, icon="REMOVE", text="")
        side.separator()
        side.operator(UNITY_OT_pass_duplicate.bl_idname, icon="DUPLICATE", text="")
        side.menu(UNITY_MT_presets.bl_idname, icon="PRESET", text="")
        side.separator()
        side.operator(UNITY_OT_pass_move.bl_idname, icon="TRIA_UP", text="").direction = "UP"
        side.operator(UNITY_OT_pass_move.bl_idname, icon="TRIA_DOWN", text="").direction = "DOWN"
        if not unity.passes:
            layout.label(text="No passes: one default pass (Cull Back ZWrite On ZTest LEqual Blend Off)",
                         icon="INFO")
            return
        item = unity.passes[min(unity.active_pass_index, len(unity.passes) - 1)]
        draw_pass(layout, item, draw_rule(unity, item))


def draw_pass(layout, item, rule: tuple[str, str] | None = None) -> None:
    box = layout.box()
    box.label(text=shaderlab_preview(item), icon="TEXT")
    if rule is not None:
        box.label(text=("Not drawn: " if rule[0] == NEVER else "") + rule[1],
                  icon="HIDE_ON" if rule[0] == NEVER else "INFO")
    col = box.column()
    col.use_property_split = True
    col.use_property_decorate = False
    col.prop(item, "name")
    col.prop(item, "light_mode")
    sub = col.column(align=True)
    sub.prop(item, "cull")
    sub.prop(item, "zwrite")
    sub.prop(item, "ztest")
    col.separator()
    col.prop(item, "blend")
    sub = col.column(align=True)
    sub.active = item.blend
    sub.prop(item, "src_blend")
    sub.prop(item, "dst_blend")
    sub.prop(item, "blend_op")
    sub.prop(item, "separate_alpha")
    alpha = sub.column(align=True)
    alpha.active = item.blend and item.separate_alpha
    alpha.prop(item, "src_blend_alpha")
    alpha.prop(item, "dst_blend_alpha")
    alpha.prop(item, "blend_op_alpha")
    col.separator()
    row = col.row(align=True, heading="ColorMask")
    row.prop(item, "color_mask", expand=True)
    sub = col.column(align=True)
    sub.prop(item, "offset_factor")
    sub.prop(item, "offset_units")
    col.prop(item, "alpha_test")
    sub = col.column()
    sub.active = item.alpha_test
    sub.prop(item, "alpha_test_comp")
    col.prop(item, "alpha_to_mask")
    col.separator()
    col.prop(item, "outline_mode")
    sub = col.column(align=True)
    sub.active = item.outline_mode != "Off"
    sub.prop(item, "outline_width")
    sub.prop(item, "outline_formula")
    sub.prop(item, "outline_max_distance")
    row = sub.row(align=True)
    row.prop(item, "outline_colored", text="")
    colour = row.row(align=True)
    colour.active = item.outline_colored
    colour.prop(item, "outline_color")
    mix = sub.row()
    mix.active = item.outline_colored
    mix.prop(item, "outline_lighting_mix")
    col.separator()
    col.prop(item, "stencil")
    sub = col.column(align=True)
    sub.active = item.stencil
    for name in ("stencil_ref", "stencil_read_mask", "stencil_write_mask", "stencil_comp",
                 "stencil_pass", "stencil_fail", "stencil_zfail"):
        sub.prop(item, name)


class UNITY_PT_camera(bpy.types.Panel):
    bl_idname = "UNITY_PT_camera"
    bl_label = "Unity Camera"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"

    @classmethod
    def poll(cls, context):
        return context.scene is not None and hasattr(context.scene, "unity")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        scene = context.scene
        unity = scene.unity
        if scene.render.engine != ENGINE_ID:
            layout.label(text="Select the Unity Passes render engine to render with these settings", icon="INFO")
        layout.prop(unity, "color_space")
        layout.prop(unity, "hdr")
        layout.prop(unity, "clear_color")
        layout.prop(unity, "ambient_from_world")
        sub = layout.column()
        sub.active = not unity.ambient_from_world
        sub.prop(unity, "ambient_color")
        layout.prop(unity, "sort_mode")
        sub = layout.column()
        sub.active = unity.sort_mode == "CustomAxis"
        sub.prop(unity, "sort_axis")
        layout.prop(unity, "msaa")
        layout.prop(unity, "pixel_light_count")
        box = layout.box()
        box.label(text="Combined = the frame as linear RGB, alpha 1; passes UnityAlpha, Depth.", icon="INFO")
        box.label(text="The Standard view transform (no look, no dither) reproduces the frame values exactly.")
        if not exact_view(scene) or scene.render.dither_intensity != 0.0:
            box.label(text=f"Now: {scene.view_settings.view_transform}, dither "
                           f"{scene.render.dither_intensity:g}: displayed values differ", icon="ERROR")
            box.operator(UNITY_OT_use_standard_view.bl_idname, icon="CHECKMARK")


class UNITY_PT_light(bpy.types.Panel):
    """Light Properties › Unity Light: the light as a Unity forward light"""

    bl_idname = "UNITY_PT_light"
    bl_label = "Unity Light"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        light = getattr(context, "light", None)
        return light is not None and hasattr(light, "unity")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        light = context.light
        unity = light.unity
        if light.type == "AREA":
            layout.label(text="Area lights have no Unity forward counterpart: not drawn", icon="INFO")
            return
        layout.prop(unity, "render_mode")
        layout.prop(unity, "use_blender_values")
        col = layout.column(align=True)
        if unity.use_blender_values:
            derived = derived_light_values(light)
            col.label(text=f"Intensity {derived['intensity']:.4g}" + (
                "  (Strength)" if light.type == "SUN" else "  (Power / 4π / π, as glTF → Unity)"))
            if light.type != "SUN":
                col.label(text=f"Range {derived['range']:.4g} m" + (
                    "  (Custom Distance)" if light.use_custom_distance else "  (Unity's default)"))
            if light.type == "SPOT":
                col.label(text=f"Spot Angle {derived['spot_angle']:.4g}°  (Spot Size)")
        else:
            col.prop(unity, "intensity")
            if light.type != "SUN":
                col.prop(unity, "range")
            if light.type == "SPOT":
                col.prop(unity, "spot_angle")
        if light_settings(light)["render_mode"] == "NotImportant":
            layout.label(text="Not Important lights would be vertex/SH lights: not drawn", icon="INFO")


CLASSES = (UNITY_MT_presets, UNITY_UL_passes, UNITY_PT_material, UNITY_PT_material_passes, UNITY_PT_camera,
           UNITY_PT_light)
