"""The "Unity Frame Debugger" panel in the Image Editor's sidebar (tab "Unity")."""

from __future__ import annotations

import bpy

from blendlib.blender.framedebug import IMAGE_NAME

from .ops import UNITY_OT_frame_debugger_capture, UNITY_OT_frame_debugger_pixel, current_capture


class UNITY_UL_frame_debugger_draws(bpy.types.UIList):
    """The captured draw calls: number, queue, object, pass and its state"""

    bl_idname = "UNITY_UL_frame_debugger_draws"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0, flt_flag=0):
        if self.layout_type in {"DEFAULT", "COMPACT"}:
            split = layout.split(factor=0.35)
            split.label(text=f"{item.index}  {item.queue}  {item.object}  {item.pass_name}")
            split.label(text=item.state)
        else:
            layout.alignment = "CENTER"
            layout.label(text=str(item.index))


class UNITY_UL_frame_debugger_fragments(bpy.types.UIList):
    """The picked pixel's fragments: draw, object, triangle, depth, result"""

    bl_idname = "UNITY_UL_frame_debugger_fragments"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0, flt_flag=0):
        if self.layout_type in {"DEFAULT", "COMPACT"}:
            face = "-" if item.polygon < 0 else str(item.polygon)
            layout.label(text=f"{item.draw} {item.object} tri {item.triangle} face {face} "
                              f"z {item.depth:.5f}: {item.result}",
                         icon="CHECKMARK" if item.result == "written" else "X")
        else:
            layout.label(text=str(item.draw))


class _ImageSidebar:
    bl_space_type = "IMAGE_EDITOR"
    bl_region_type = "UI"
    bl_category = "Unity"

    @classmethod
    def poll(cls, context):
        return context.scene is not None and hasattr(context.scene, "unity_frame_debugger")


class UNITY_PT_frame_debugger(_ImageSidebar, bpy.types.Panel):
    bl_idname = "UNITY_PT_frame_debugger"
    bl_label = "Unity Frame Debugger"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.unity_frame_debugger
        layout.operator(UNITY_OT_frame_debugger_capture.bl_idname, icon="RENDER_STILL")
        cap = current_capture(context.scene)
        if cap is None:
            layout.label(text="Capture renders the scene once and lists its draw calls.", icon="INFO")
            return
        layout.label(text=settings.status)
        layout.template_list(UNITY_UL_frame_debugger_draws.bl_idname, "", settings, "draws", settings,
                             "active_draw", rows=6)
        layout.prop(settings, "draw", slider=True)
        row = layout.row(align=True)
        row.prop(settings, "buffer", expand=True)
        layout.prop(settings, "highlight")
        layout.label(text=f'Shown in the image "{IMAGE_NAME}"', icon="IMAGE_DATA")
        if settings.draw == 0 or settings.draw > len(settings.draws):
            layout.label(text="Draw 0: the cleared frame")
            return
        item = settings.draws[settings.draw - 1]
        box = layout.box()
        box.label(text=f"Draw {item.index}: {item.object} slot {item.slot}, {item.material}, "
                       f"pass {item.pass_index} \"{item.pass_name}\"")
        box.label(text=f"Queue {item.queue}, distance {item.distance:.3f}")
        box.label(text=item.state, icon="TEXT")
        box.label(text=f"{item.triangles} triangles, {item.fragments} fragments, {item.written} written")


class UNITY_PT_frame_debugger_pixel(_ImageSidebar, bpy.types.Panel):
    bl_idname = "UNITY_PT_frame_debugger_pixel"
    bl_label = "Pixel History"
    bl_parent_id = "UNITY_PT_frame_debugger"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.unity_frame_debugger
        row = layout.row(align=True)
        row.prop(settings, "pixel_x")
        row.prop(settings, "pixel_y")
        row = layout.row(align=True)
        row.operator(UNITY_OT_frame_debugger_pixel.bl_idname, text="Pick Pixel", icon="EYEDROPPER")
        typed = row.operator(UNITY_OT_frame_debugger_pixel.bl_idname, text="X, Y", icon="RESTRICT_SELECT_OFF")
        typed.x, typed.y = settings.pixel_x, settings.pixel_y
        if not settings.pixel_text:
            layout.label(text="Pick a pixel of the image, or type X (from the left) and Y (from the top).")
            return
        layout.label(text=settings.pixel_text)
        if not settings.fragments:
            layout.label(text="No fragment touched this pixel.")
            return
        layout.template_list(UNITY_UL_frame_debugger_fragments.bl_idname, "", settings, "fragments", settings,
                             "active_fragment", rows=4)
        if 0 <= settings.active_fragment < len(settings.fragments):
            f = settings.fragments[settings.active_fragment]
            box = layout.box()
            box.label(text=f"Draw {f.draw} {f.object} \"{f.pass_name}\", triangle {f.triangle}: {f.result}")
            box.label(text="Source " + " ".join(f"{v:.4f}" for v in f.source))
            box.label(text="Before " + " ".join(f"{v:.4f}" for v in f.before))
            box.label(text="After  " + " ".join(f"{v:.4f}" for v in f.after))
            box.label(text=f"Depth {f.depth:.6f}, stencil {f.stencil_before} -> {f.stencil_after}")


CLASSES = (UNITY_UL_frame_debugger_draws, UNITY_UL_frame_debugger_fragments, UNITY_PT_frame_debugger,
           UNITY_PT_frame_debugger_pixel)
