"""Link Unity Project: every Blender material named as a ``.mat`` of a Unity project takes its settings.

The folder picker chooses the project (or its ``Assets/`` folder); every ``.mat`` under ``Assets/``
is matched by its ``m_Name`` to the Blender material of the same name, imported
(:func:`blendlib.formats.shaderlab.import_material_file`: its shader through the project's
``.meta`` files, Unity's built-in shaders from the "Shader Folder") and applied with its texture
(:func:`.ops.apply_material`). The report says what matched, which materials have no ``.mat``,
and which ``.mat`` could not be imported (its one-line error; that material is unchanged).
Running it again imports every match again, so the materials follow the project's files.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import bpy
from bpy.props import BoolProperty, StringProperty
from bpy.types import Operator

from blendlib.formats import shaderlab

from .ops import SHADER_FOLDER_DESCRIPTION, _one_line, apply_material, search_folders


@dataclass
class LinkReport:
    """What a link did: ``linked`` material name → ``.mat`` path, ``failed`` name → error,
    ``unmatched`` Blender materials without a ``.mat`` of their name, ``unused`` how many of the
    project's material names no Blender material has, ``warnings`` one line each."""

    project: str
    linked: dict[str, str] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    unmatched: list[str] = field(default_factory=list)
    unused: int = 0
    warnings: list[str] = field(default_factory=list)

    def summary(self) -> str:
        names = ", ".join(self.linked) or "none"
        out = f"Linked {len(self.linked)} material{'s' if len(self.linked) != 1 else ''} from {self.project}: {names}"
        if self.failed:
            out += f"; {len(self.failed)} not imported: {', '.join(self.failed)}"
        if self.unmatched:
            out += f"; no .mat for: {', '.join(self.unmatched)}"
        if self.unused:
            out += f"; {self.unused} .mat name{'s' if self.unused != 1 else ''} without a Blender material"
        return out


def link_project(folder: str, search: tuple[str, ...] = (), materials=None) -> LinkReport:
    """Link the Blender ``materials`` (default: every material of the file) to the ``.mat`` files
    of the Unity project in ``folder`` (see the module docstring)."""
    root = Path(folder)
    if not root.is_dir():
        raise ValueError(f"{folder}: not a folder")
    by_name = shaderlab.project_materials(root)
    report = LinkReport(str(root))
    materials = list(bpy.data.materials if materials is None else materials)
    names = {mat.name for mat in materials}
    report.unused = sum(1 for name in by_name if name not in names)
    for mat in materials:
        files = by_name.get(mat.name)
        if not files:
            if getattr(mat, "users", 1) or getattr(mat, "use_fake_user", False):
                report.unmatched.append(mat.name)
            continue
        if len(files) > 1:
            report.warnings.append(f"{mat.name}: {len(files)} .mat files have this name; linked to {files[0]}")
        try:
            result = shaderlab.import_material_file(files[0], search)
            warnings = apply_material(mat, result)
        except (shaderlab.ShaderLabError, OSError, ValueError, TypeError) as exc:
            report.failed[mat.name] = _one_line(str(exc))
            continue
        report.linked[mat.name] = files[0]
        report.warnings += [f"{mat.name}: {_one_line(w)}" for w in (*result.warnings, *warnings)]
    return report


class UNITY_OT_link_unity_project(Operator):
    """Give every material named as a .mat file of a Unity project that material's settings and
    texture (running it again updates them)"""

    bl_idname = "unity.link_unity_project"
    bl_label = "Link Unity Project…"
    bl_options = {"REGISTER", "UNDO"}

    directory: StringProperty(name="Unity Project", description="The Unity project folder (or its Assets folder)",
                              subtype="DIR_PATH", default="")
    filter_folder: BoolProperty(default=True, options={"HIDDEN", "SKIP_SAVE"})
    search_folder: StringProperty(name="Shader Folder", description=SHADER_FOLDER_DESCRIPTION, subtype="DIR_PATH",
                                  default="")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        folder = bpy.path.abspath(self.directory)
        try:
            report = link_project(folder, search_folders(self.search_folder))
        except ValueError as exc:
            self.report({"ERROR"}, _one_line(str(exc)))
            return {"CANCELLED"}
        for name, message in report.failed.items():
            self.report({"WARNING"}, f"{name}: not linked: {message}")
        for warning in report.warnings:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, report.summary())
        return {"FINISHED"}


CLASSES = (UNITY_OT_link_unity_project,)
