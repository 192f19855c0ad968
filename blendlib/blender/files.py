"""Opening .blend files and finding scenes in them (the CLI and the ShaderLab export use these)."""

from __future__ import annotations

from typing import Any

from ..core.scene import SceneError


def open_blend(path: Any) -> Any:
    """Open a .blend file (replacing Blender's current data) and return ``bpy.data``.

    Raises :class:`SceneError` with one line naming the file and Blender's reason.
    """
    import os

    import bpy

    try:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(str(path)), load_ui=False)
    except RuntimeError as exc:
        lines = str(exc).strip().splitlines()
        reason = lines[-1].removeprefix("Error: ").strip() if lines else "unknown error"
        raise SceneError(f"{path}: cannot open .blend file ({reason})") from None
    return bpy.data


def scene_named(name: str | None, where: Any = "file") -> Any:
    """The scene called ``name`` (the context scene for None); SceneError naming the choices."""
    import bpy

    if name is None:
        return bpy.context.scene
    scene = bpy.data.scenes.get(name)
    if scene is None:
        names = ", ".join(repr(s.name) for s in bpy.data.scenes)
        raise SceneError(f"{where}: no scene named {name!r} (scenes: {names})")
    return scene



def material_named(name: str, where: Any = "file") -> Any:
    """The ``bpy.types.Material`` called ``name``; SceneError naming the materials there are."""
    import bpy

    mat = bpy.data.materials.get(name)
    if mat is None:
        names = ", ".join(sorted(m.name for m in bpy.data.materials)) or "none"
        raise SceneError(f"{where}: no material named {name!r} (materials: {names})")
    return mat
