"""The ShaderLab rows of the Unity Material panel: Import…, paste from the clipboard, Export…, and
Link Unity Project…."""

from __future__ import annotations

from .ops import UNITY_OT_shaderlab_export, UNITY_OT_shaderlab_import, UNITY_OT_shaderlab_import_clipboard
from .project import UNITY_OT_link_unity_project


def draw_import_export(layout) -> None:
    """Draw the Import/Export row and the Link Unity Project row into ``layout`` (the Unity Material
    panel's, under its presets)."""
    row = layout.row(align=True)
    row.operator(UNITY_OT_shaderlab_import.bl_idname, text="Import ShaderLab…", icon="IMPORT")
    row.operator(UNITY_OT_shaderlab_import_clipboard.bl_idname, text="", icon="PASTEDOWN")
    row.operator(UNITY_OT_shaderlab_export.bl_idname, text="Export ShaderLab…", icon="EXPORT")
    layout.row().operator(UNITY_OT_link_unity_project.bl_idname, text="Link Unity Project…", icon="LINKED")
