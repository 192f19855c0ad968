"""Import ShaderLab (file browser / clipboard) and Export ShaderLab (file browser) operators.

Import parses the whole ``.shader`` text first (:mod:`blendlib.formats.shaderlab`); on a
parse error it reports one line (``FILE:LINE:COL: message``) and changes nothing.
On success it replaces the material's Unity settings (``material.unity``) through the
schema's writer (:func:`blendlib.blender.write_material`): queue, offset, ``_Color``,
``_AlphaScale``, ``_Cutoff``, lighting and the pass list (cleared and rebuilt), and
turns ``enabled`` on. Every value is checked before any is assigned, so a value the
settings cannot hold changes nothing.

A ``.shader`` file holds no texture image, tiling/offset or sampler settings (in
Unity they belong to the material and the texture asset, and switching a
material's shader keeps them), so import keeps the material's ``main_tex``,
``main_tex_tiling``, ``main_tex_offset``, ``main_tex_filter`` and ``main_tex_wrap``
unless "Reset Texture Settings" is on, which sets them to the defaults.
"""

from __future__ import annotations

import os

import bpy
from bpy.props import BoolProperty, StringProperty
from bpy.types import Operator
from bpy_extras.io_utils import ExportHelper, ImportHelper

from blendlib import blender
from blendlib.core.vocabulary import queue_text
from blendlib.formats import shaderlab
from blendlib.formats.atomic import write_atomic

#: Material fields a .shader file does not hold: kept on import unless "Reset Texture Settings".
TEXTURE_FIELDS = ("main_tex", "main_tex_tiling", "main_tex_offset", "main_tex_filter", "main_tex_wrap")


def apply_result(material, result: shaderlab.ShaderLabResult, reset_texture: bool = False) -> None:
    """Replace ``material.unity`` with an import result, all or nothing (ValueError: nothing changed)."""
    values = blender.material_fields(result.material)
    if reset_texture:
        values["main_tex"] = None
    else:
        values = {k: v for k, v in values.items() if k not in TEXTURE_FIELDS}
    blender.write_material(material, enabled=True, **values)


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


class _ImportMixin:
    reset_texture: BoolProperty(
        name="Reset Texture Settings",
        description=("Also reset _MainTex, its tiling/offset and sampler settings to the defaults; a .shader "
                     "file does not hold them, so by default they are kept (as Unity keeps them when a "
                     "material's shader changes)"),
        default=False,
    )

    @classmethod
    def poll(cls, context):
        mat = getattr(context, "material", None)
        return mat is not None and hasattr(mat, "unity")

    def import_text(self, context, text: str, filename: str):
        try:
            result = shaderlab.parse_shaderlab(text, filename=filename)
        except shaderlab.ShaderLabError as exc:
            self.report({"ERROR"}, _one_line(str(exc)))
            return {"CANCELLED"}
        except Exception as exc:  # noqa: BLE001 - a report, never a traceback in the UI
            self.report({"ERROR"}, _one_line(f"{filename}: internal error: {type(exc).__name__}: {exc}"))
            return {"CANCELLED"}
        try:
            apply_result(context.material, result, self.reset_texture)
        except (TypeError, ValueError, AttributeError) as exc:
            self.report({"ERROR"}, _one_line(f"{filename}: cannot apply the settings: {exc}"))
            return {"CANCELLED"}
        for warning in result.warnings:
            self.report({"WARNING"}, _one_line(f"{filename}:{warning}"))
        n = len(result.passes)
        queue = queue_text(result.material.queue, result.material.queue_offset)
        self.report({"INFO"}, f'Imported "{result.name}": {n} pass{"" if n == 1 else "es"}, queue {queue}')
        return {"FINISHED"}


class UNITY_OT_shaderlab_import(_ImportMixin, Operator, ImportHelper):
    """Replace this material's Unity settings with those of a ShaderLab .shader file"""

    bl_idname = "unity.shaderlab_import"
    bl_label = "Import ShaderLab…"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".shader"
    filter_glob: StringProperty(default="*.shader", options={"HIDDEN"})

    def execute(self, context):
        path = self.filepath
        try:
            with open(path, encoding="utf-8-sig") as fh:
                text = fh.read()
        except (OSError, UnicodeDecodeError) as exc:
            self.report({"ERROR"}, _one_line(f"{path}: cannot read: {getattr(exc, 'strerror', None) or exc}"))
            return {"CANCELLED"}
        return self.import_text(context, text, os.path.basename(path) or path)


class UNITY_OT_shaderlab_import_clipboard(_ImportMixin, Operator):
    """Replace this material's Unity settings with the ShaderLab shader on the clipboard"""

    bl_idname = "unity.shaderlab_import_clipboard"
    bl_label = "Import ShaderLab from Clipboard"
    bl_options = {"REGISTER", "UNDO"}

    text: StringProperty(
        name="Text",
        description="ShaderLab source to import instead of the clipboard (for scripts)",
        default="",
        options={"HIDDEN", "SKIP_SAVE"},
    )

    def execute(self, context):
        text = self.text or context.window_manager.clipboard
        if not text.strip():
            self.report({"ERROR"}, "The clipboard is empty: copy a ShaderLab shader first")
            return {"CANCELLED"}
        return self.import_text(context, text, "<clipboard>")


class UNITY_OT_shaderlab_export(Operator, ExportHelper):
    """Write this material's Unity settings as a ShaderLab .shader file that Unity compiles"""

    bl_idname = "unity.shaderlab_export"
    bl_label = "Export ShaderLab…"
    bl_options = {"REGISTER"}

    filename_ext = ".shader"
    filter_glob: StringProperty(default="*.shader", options={"HIDDEN"})
    shader_name: StringProperty(
        name="Shader Name",
        description='The Shader "..." name (empty: "Unity Passes/<material name>")',
        default="",
    )

    @classmethod
    def poll(cls, context):
        mat = getattr(context, "material", None)
        return mat is not None and hasattr(mat, "unity")

    def invoke(self, context, event):
        if not self.filepath:
            stem = bpy.path.clean_name(context.material.name) or "material"
            self.filepath = os.path.join(os.path.dirname(bpy.data.filepath) or os.path.expanduser("~"),
                                         stem + self.filename_ext)
        return ExportHelper.invoke(self, context, event)

    def execute(self, context):
        mat = context.material
        material = blender.material_from_blender(mat)
        name = self.shader_name.strip() or f"Unity Passes/{mat.name}"
        text = shaderlab.export_shaderlab(material, name)
        path = bpy.path.abspath(self.filepath)
        try:
            write_atomic(path, text)
        except OSError as exc:
            self.report({"ERROR"}, _one_line(f"{path}: cannot write: {exc.strerror or exc}"))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Exported {name!r} to {path}")
        return {"FINISHED"}


CLASSES = (UNITY_OT_shaderlab_import, UNITY_OT_shaderlab_import_clipboard, UNITY_OT_shaderlab_export)
