"""Unity Passes for Blender: the add-on.

Registers ``Material.unity`` / ``Scene.unity``, the "Unity Material" and "Unity
Camera" panels, the pass operators and presets, the "Unity Passes" render
engine (``UNITY_PASSES``) and the "Unity Frame Debugger" (:mod:`.frame_debugger`).
The renderer is the bpy-free :mod:`blendlib` package:
on ``sys.path`` when run from the repository, installed from the wheel bundled
in the extension zip otherwise (``scripts/build_extension.py``).

``import addon; addon.register()`` works with the repository root on ``sys.path``;
``register()`` and ``unregister()`` may each be called twice in a row.
"""

from __future__ import annotations

bl_info = {
    "name": "Unity Passes",
    "author": "Unity Passes for Blender contributors",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "Render Properties > Render Engine: Unity Passes; Material Properties > Unity Material",
    "description": "Renders exactly what Unity's built-in pipeline draws for transparent and multi-pass materials",
    "category": "Render",
}

_registered = False


def register() -> None:
    global _registered
    if _registered:
        unregister()
    import bpy

    from . import engine, frame_debugger, operators, properties, shaderlab_ops, sort_analysis, ui

    properties.register()  # first: panels and operators use the properties
    for cls in operators.CLASSES + ui.CLASSES:
        bpy.utils.register_class(cls)
    sort_analysis.register()
    engine.register()
    shaderlab_ops.register()
    frame_debugger.register()
    _registered = True


def unregister() -> None:
    global _registered
    if not _registered:
        return
    import bpy

    from . import engine, frame_debugger, operators, properties, shaderlab_ops, sort_analysis, ui

    frame_debugger.unregister()
    shaderlab_ops.unregister()
    engine.unregister()
    sort_analysis.unregister()
    for cls in reversed(operators.CLASSES + ui.CLASSES):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
    properties.unregister()
    _registered = False
