"""Import ShaderLab (file browser: a ``.shader`` or a Unity ``.mat``; clipboard) and Export ShaderLab
(file browser) operators.

Import parses the whole file first (:mod:`blendlib.formats.shaderlab`); on an error it reports
one line (``FILE:LINE:COL: message``) and changes nothing. On success it replaces the
material's Unity settings (``material.unity``) through the schema's writer
(:func:`blendlib.blender.write_material`): queue, offset, ``_Color``, ``_AlphaScale``,
``_Cutoff``, lighting, vertex colours and ``_TintColor``, and the pass list (cleared and
rebuilt), and turns ``enabled`` on. Every value is checked before any is assigned, so a value
the settings cannot hold changes nothing.

A ``.shader`` file holds no texture image, tiling/offset or sampler settings (in Unity they
belong to the material and the texture asset, and switching a material's shader keeps them), so
a ``.shader`` import keeps the material's texture settings unless "Reset Texture Settings" is on.
A ``.mat`` holds them: its ``_MainTex`` image is loaded as a Blender image (:func:`apply_material`)
with the sampler settings of the texture's ``.meta``. Unity's built-in shaders (Standard,
Sprites/Default, …) are found in the "Shader Folder" (Unity's built-in shader source).
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
TEXTURE_FIELDS = ("main_tex", "main_tex_tiling", "main_tex_offset", "main_tex_filter", "main_tex_wrap",
                  "main_tex_mipmaps", "main_tex_preserve_coverage")


def apply_result(material, result: shaderlab.ShaderLabResult, reset_texture: bool = False) -> None:
    """Replace ``material.unity`` with a ``.shader`` import result, all or nothing (ValueError:
    nothing changed)."""
    values = blender.material_fields(result.material)
    if reset_texture:
        values["main_tex"] = None
    else:
        values = {k: v for k, v in values.items() if k not in TEXTURE_FIELDS}
    blender.write_material(material, enabled=True, **values)


def load_texture(result: shaderlab.ShaderLabResult):
    """``(image, warning)``: the ``.mat`` result's ``_MainTex`` file as a Blender image (an image
    already loaded from that file is reused; a non-colour texture gets Non-Color), or None."""
    path = result.main_tex_file
    if path is None:
        return None, None
    try:
        image = bpy.data.images.load(path, check_existing=True)
    except RuntimeError as exc:
        return None, f"{path}: cannot load the texture ({_one_line(exc)}); drawn without it"
    prop = result.extra.get("main_tex_property")
    settings = result.extra.get("textures", {}).get(prop, {})
    if settings.get("srgb") is False and image.colorspace_settings.name != "Non-Color":
        image.colorspace_settings.name = "Non-Color"
    return image, None


def apply_material(material, result: shaderlab.ShaderLabResult) -> list[str]:
    """Replace ``material.unity`` with a ``.mat`` import result, its texture loaded as a Blender
    image, all or nothing (ValueError: nothing changed; an image loaded for it is removed again).
    Returns the warnings of loading the texture."""
    existing = {image.name for image in bpy.data.images}
    image, warning = load_texture(result)
    try:
        blender.write_material(material, enabled=True, **(blender.material_fields(result.material)
                                                            | {"main_tex": image}))
    except ValueError:
        if image is not None and image.name not in existing:
            bpy.data.images.remove(image)
        raise
    return [warning] if warning else []


def search_folders(text: str) -> tuple[str, ...]:
    """The "Shader Folder" setting as search folders (Blender's // paths resolved)."""
    return (bpy.path.abspath(text),) if text.strip() else ()


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


SHADER_FOLDER_DESCRIPTION = ("A folder searched (with its subfolders) for shaders a file names: Unity's built-in "
                             "shader source for Standard, Sprites/Default, UI/Default, … (the 'Built in shaders' "
                             "download); a project's own shaders are found in its Assets folder")


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

    def import_text(self, context, text: str, filename: str, search: tuple[str, ...] = (),
                    folder: str | None = None):
        try:
            folders = shaderlab.AssetSearch([*([folder] if folder else []), *search])
            result = shaderlab.parse_shaderlab(text, filename=filename, search=folders)
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
        self.report_done(result)
        return {"FINISHED"}

    def report_done(self, result: shaderlab.ShaderLabResult) -> None:
        n = len(result.passes)
        queue = queue_text(result.material.queue, result.material.queue_offset)
        self.report({"INFO"}, f'Imported "{result.name}": {n} pass{"" if n == 1 else "es"}, queue {queue}')


class UNITY_OT_shaderlab_import(_ImportMixin, Operator, ImportHelper):
    """Replace this material's Unity settings with those of a ShaderLab .shader file or a Unity .mat
    material (its texture and sampler settings too)"""

    bl_idname = "unity.shaderlab_import"
    bl_label = "Import ShaderLab…"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".shader"
    filter_glob: StringProperty(default="*.shader;*.mat", options={"HIDDEN"})
    search_folder: StringProperty(name="Shader Folder", description=SHADER_FOLDER_DESCRIPTION, subtype="DIR_PATH",
                                  default="")

    def execute(self, context):
        path = bpy.path.abspath(self.filepath)
        search = search_folders(self.search_folder)
        if path.lower().endswith(".mat"):
            return self.import_material_file(context, path, search)
        try:
            with open(path, encoding="utf-8-sig") as fh:
                text = fh.read()
        except (OSError, UnicodeDecodeError) as exc:
            self.report({"ERROR"}, _one_line(f"{path}: cannot read: {getattr(exc, 'strerror', None) or exc}"))
            return {"CANCELLED"}
        return self.import_text(context, text, os.path.basename(path) or path, search, os.path.dirname(path))

    def import_material_file(self, context, path: str, search: tuple[str, ...]):
        try:
            result = shaderlab.import_material_file(path, search)
        except shaderlab.ShaderLabError as exc:
            self.report({"ERROR"}, _one_line(str(exc)))
            return {"CANCELLED"}
        except OSError as exc:
            self.report({"ERROR"}, _one_line(f"{path}: cannot read: {exc.strerror or exc}"))
            return {"CANCELLED"}
        except Exception as exc:  # noqa: BLE001 - a report, never a traceback in the UI
            self.report({"ERROR"}, _one_line(f"{path}: internal error: {type(exc).__name__}: {exc}"))
            return {"CANCELLED"}
        try:
            warnings = apply_material(context.material, result)
        except (TypeError, ValueError, AttributeError) as exc:
            self.report({"ERROR"}, _one_line(f"{path}: cannot apply the settings: {exc}"))
            return {"CANCELLED"}
        for warning in (*result.warnings, *warnings):
            self.report({"WARNING"}, _one_line(warning))
        self.report_done(result)
        return {"FINISHED"}


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
