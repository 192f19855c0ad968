"""The ShaderLab row of the Unity Material panel: Import…, paste from the clipboard, Export…."""

from __future__ import annotations

from .ops import UNITY_OT_shaderlab_export, UNITY_OT_shaderlab_import, UNITY_OT_shaderlab_import_clipboard


def draw_import_export(layout) -> None:
    """Draw the Import/Export row into ``layout`` (the Unity Material panel's, under its presets)."""
    row = layout.row(align=True)
    row.operator(UNITY_OT_shaderlab_import.bl_idname, text="Import ShaderLab…", icon="IMPORT")
    row.operator(UNITY_OT_shaderlab_import_clipboard.bl_idname, text="", icon="PASTEDOWN")
    row.operator(UNITY_OT_shaderlab_export.bl_idname, text="Export ShaderLab…", icon="EXPORT")
