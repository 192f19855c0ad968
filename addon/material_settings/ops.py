"""Operators of the Unity Material and Unity Camera panels: pass list editing, presets, Fill from
Principled BSDF, Use Standard View Transform."""

from __future__ import annotations

import bpy

from blendlib.blender import principled_inputs, read_pass, write_material, write_pass
from blendlib.core.vocabulary import PASS_PRESETS, Pass, preset


def copy_pass(src, dst) -> None:
    """Copy every field of the pass property group ``src`` into ``dst``."""
    write_pass(dst, read_pass(src))


def apply_preset(mat, name: str) -> None:
    """Set ``mat.unity`` to a preset of :data:`PASS_PRESETS`: enabled, its queue (offset 0) and passes."""
    queue, passes = preset(name)
    write_material(mat, enabled=True, queue=queue, queue_offset=0, passes=passes)


def fill_from_principled(mat) -> bool:
    """_Color from the Principled BSDF Base Color (sRGB-encoded) and Alpha, _MainTex from an Image
    Texture linked to Base Color. Returns False when the material has no Principled BSDF."""
    tree = getattr(mat, "node_tree", None)
    if tree is None or not any(n.type == "BSDF_PRINCIPLED" for n in tree.nodes):
        return False
    color, image = principled_inputs(mat)
    write_material(mat, color=color, main_tex=image)
    return True


class _MaterialOperator:
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return getattr(context, "material", None) is not None


class _SelectedPassOperator(_MaterialOperator):
    """Operators on the selected pass: they need a material with at least ``min_passes`` passes."""

    min_passes = 1

    @classmethod
    def poll(cls, context):
        mat = getattr(context, "material", None)
        return mat is not None and len(mat.unity.passes) >= cls.min_passes

    @staticmethod
    def selected_index(unity) -> int:
        return min(unity.active_pass_index, len(unity.passes) - 1)


class UNITY_OT_pass_add(_MaterialOperator, bpy.types.Operator):
    """Add a pass after the selected one"""

    bl_idname = "unity.pass_add"
    bl_label = "Add Pass"

    def execute(self, context):
        unity = context.material.unity
        item = unity.passes.add()
        write_pass(item, Pass(name=f"Pass {len(unity.passes)}"))
        target = min(unity.active_pass_index + 1, len(unity.passes) - 1) if len(unity.passes) > 1 else 0
        unity.passes.move(len(unity.passes) - 1, target)
        unity.active_pass_index = target
        return {"FINISHED"}


class UNITY_OT_pass_remove(_SelectedPassOperator, bpy.types.Operator):
    """Remove the selected pass"""

    bl_idname = "unity.pass_remove"
    bl_label = "Remove Pass"

    def execute(self, context):
        unity = context.material.unity
        index = self.selected_index(unity)
        unity.passes.remove(index)
        unity.active_pass_index = max(0, min(index, len(unity.passes) - 1))
        return {"FINISHED"}


class UNITY_OT_pass_move(_SelectedPassOperator, bpy.types.Operator):
    """Move the selected pass up or down (passes draw from top to bottom)"""

    bl_idname = "unity.pass_move"
    bl_label = "Move Pass"

    direction: bpy.props.EnumProperty(
        items=[("UP", "Up", "Draw earlier"), ("DOWN", "Down", "Draw later")], name="Direction", default="UP")

    min_passes = 2

    def execute(self, context):
        unity = context.material.unity
        index = self.selected_index(unity)
        target = index - 1 if self.direction == "UP" else index + 1
        if not 0 <= target < len(unity.passes):
            return {"CANCELLED"}
        unity.passes.move(index, target)
        unity.active_pass_index = target
        return {"FINISHED"}


class UNITY_OT_pass_duplicate(_SelectedPassOperator, bpy.types.Operator):
    """Duplicate the selected pass (the copy is drawn right after it)"""

    bl_idname = "unity.pass_duplicate"
    bl_label = "Duplicate Pass"

    def execute(self, context):
        unity = context.material.unity
        index = self.selected_index(unity)
        item = unity.passes.add()
        copy_pass(unity.passes[index], item)
        unity.passes.move(len(unity.passes) - 1, index + 1)
        unity.active_pass_index = index + 1
        return {"FINISHED"}


class UNITY_OT_apply_preset(_MaterialOperator, bpy.types.Operator):
    """Replace the queue and passes with a preset from the tutorials (enables the Unity material)"""

    bl_idname = "unity.apply_preset"
    bl_label = "Apply Unity Preset"

    preset: bpy.props.EnumProperty(
        items=[(name, name, f"Apply the {name} preset") for name in PASS_PRESETS], name="Preset")

    def execute(self, context):
        apply_preset(context.material, self.preset)
        self.report({"INFO"}, f"Applied preset {self.preset!r}")
        return {"FINISHED"}


class UNITY_OT_fill_from_principled(_MaterialOperator, bpy.types.Operator):
    """Set _Color from the Principled BSDF Base Color and Alpha, and _MainTex from an Image Texture
    linked to Base Color"""

    bl_idname = "unity.fill_from_principled"
    bl_label = "Fill from Principled BSDF"

    def execute(self, context):
        if not fill_from_principled(context.material):
            self.report({"WARNING"}, f"Material {context.material.name!r} has no Principled BSDF node")
            return {"CANCELLED"}
        return {"FINISHED"}


class UNITY_OT_use_standard_view(bpy.types.Operator):
    """Set the Standard view transform, no look, exposure 0, gamma 1, no curves and no dither, so that
    displayed and saved 8-bit images hold exactly the Unity frame values"""

    bl_idname = "unity.use_standard_view"
    bl_label = "Use Standard View Transform"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        scene = context.scene
        view = scene.view_settings
        scene.display_settings.display_device = "sRGB"
        view.view_transform = "Standard"
        view.look = "None"
        view.exposure = 0.0
        view.gamma = 1.0
        view.use_curve_mapping = False
        scene.render.dither_intensity = 0.0
        return {"FINISHED"}


CLASSES = (
    UNITY_OT_pass_add,
    UNITY_OT_pass_remove,
    UNITY_OT_pass_move,
    UNITY_OT_pass_duplicate,
    UNITY_OT_apply_preset,
    UNITY_OT_fill_from_principled,
    UNITY_OT_use_standard_view,
)
