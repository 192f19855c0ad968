"""The import operator and its File › Import menu entry.

The file is read and checked before anything changes (one error line for a truncated file, a JSON
chunk that is not JSON, an unknown required extension, an index out of range); then Blender's glTF
importer adds the geometry and every material gets its Unity settings, enabled, with its ``_MainTex``.
"""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, StringProperty
from bpy.types import Operator
from bpy_extras.io_utils import ImportHelper

from blendlib.blender import gltf_import
from blendlib.formats.gltf import GltfError


class UNITY_OT_import_vrm(Operator, ImportHelper):
    """Import a VRM or glTF file; each material gets the Unity settings UniVRM or UniGLTF set for Unity's
    built-in pipeline"""

    bl_idname = "unity.import_vrm"
    bl_label = "Import VRM/glTF with Unity Settings"
    bl_options = {"REGISTER", "UNDO", "PRESET"}

    filename_ext = ".vrm"
    filter_glob: StringProperty(default="*.vrm;*.glb;*.gltf", options={"HIDDEN"})
    add_camera: BoolProperty(
        name="Add Camera",
        description="When the file has no camera, add one framing the model (the scene's camera if it has none)",
        default=True,
    )
    add_sun: BoolProperty(
        name="Add Sun",
        description="When the scene has no Sun, add one lighting the model's front (Unity's main light)",
        default=True,
    )

    def execute(self, context):
        path = bpy.path.abspath(self.filepath)
        try:
            done = gltf_import.import_gltf(path, context.scene, add_camera=self.add_camera, add_sun=self.add_sun)
        except GltfError as exc:
            self.report({"ERROR"}, " ".join(str(exc).split()))
            return {"CANCELLED"}
        for warning in (*done.result.warnings, *done.warnings):
            self.report({"WARNING"}, warning)
        count = sum(m is not None for m in done.materials) - len(done.addon_materials)
        kind = f"VRM {done.result.vrm}" if done.result.vrm else "glTF"
        vrm = f", {len(done.addon_materials)} with VRM Add-on MToon settings" if done.addon_materials else ""
        self.report({"INFO"}, f"Imported {kind}: {len(done.objects)} objects, {count} materials with Unity settings"
                              f"{vrm}")
        return {"FINISHED"}


def menu_entry(self, context) -> None:
    self.layout.operator(UNITY_OT_import_vrm.bl_idname, text="VRM/glTF with Unity Settings (.vrm/.glb/.gltf)")


def add_menu_entry() -> None:
    remove_menu_entry()  # twice-safe
    bpy.types.TOPBAR_MT_file_import.append(menu_entry)


def remove_menu_entry() -> None:
    try:
        bpy.types.TOPBAR_MT_file_import.remove(menu_entry)
    except (ValueError, RuntimeError):
        pass


CLASSES = (UNITY_OT_import_vrm,)
