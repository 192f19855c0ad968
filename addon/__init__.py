"""Unity Passes for Blender: the add-on, one folder per feature.

- :mod:`.material_settings`: ``Material.unity`` / ``Scene.unity``, the "Unity Material" and
  "Unity Camera" panels, the pass operators and presets, migration of older files.
- :mod:`.shaderlab`: Import / Export ShaderLab.
- :mod:`.vrm_import`: File › Import › VRM/glTF with Unity settings.
- :mod:`.sort_analysis`: Render Properties › Unity Sort Analysis and its F12 passes.
- :mod:`.engine`: the "Unity Passes" render engine (``UNITY_PASSES``), F12 and the viewport.
- :mod:`.frame_debugger`: the "Unity Frame Debugger" in the Image Editor.
- :mod:`.jobs`: the one job base of long operators (worker thread, progress, Esc cancels);
  :mod:`.registration`: how each feature registers.

Each feature's ``register``/``unregister`` is symmetric; bl_idnames and property names are a
file format and a public API (SPEC §3) and do not change. The renderer is the bpy-free
:mod:`blendlib` package (the add-on imports only its public faces: ``blendlib``,
``blendlib.blender*``, ``blendlib.formats*``, ``blendlib.explain*``, ``blendlib.core.vocabulary``):
on ``sys.path`` when run from the repository, installed from the wheel bundled in the extension
zip otherwise (``scripts/build_extension.py``).

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

#: The render engine's bl_idname (stored in ``scene.render.engine``).
ENGINE_ID = "UNITY_PASSES"

_registered = False


def _features():
    """The feature packages in registration order (unregistered in reverse): the Unity settings
    first (everything else reads them), the sort analysis' ``ViewLayer.unity_analysis`` before the
    engine whose render passes depend on it."""
    from . import engine, frame_debugger, material_settings, shaderlab, sort_analysis, vrm_import

    return (material_settings, sort_analysis, engine, shaderlab, vrm_import, frame_debugger)


def register() -> None:
    global _registered
    if _registered:
        unregister()
    for feature in _features():
        feature.register()
    _registered = True


def unregister() -> None:
    global _registered
    if not _registered:
        return
    for feature in reversed(_features()):
        feature.unregister()
    _registered = False
