"""The "Unity Passes" render engine (``UNITY_PASSES``).

- :mod:`.render`: the engine class; F12, Ctrl+F12 and ``blender -b … -E UNITY_PASSES`` and the
  passes of its render result.
- :mod:`.viewport`: the 3D viewport's Rendered shading (scene read on the main thread, frames
  rendered on a worker); its one ``gpu`` drawing function, :func:`.viewport.draw_pixels`, is kept
  apart because Blender's ``gpu`` module does not run in background mode.

Registering also lists the engine in the ``COMPAT_ENGINES`` of Blender's own property panels
(dimensions, light, world, material slots), so they show while it is selected.
"""

from __future__ import annotations

from blendlib.runtime import bandprocs

from ..registration import feature
from .render import UnityPassesRenderEngine

CLASSES = (UnityPassesRenderEngine,)


def _compat_panels():
    """Built-in property panels (dimensions, light, world, material slots) shown for this engine too."""
    import bpy

    wanted = {"EEVEE_MATERIAL_PT_context_material", "EEVEE_WORLD_PT_surface", "DATA_PT_EEVEE_light"}
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if isinstance(engines, set) and ("BLENDER_RENDER" in engines or panel.__name__ in wanted):
            yield panel


def _attach() -> None:
    for panel in _compat_panels():
        panel.COMPAT_ENGINES.add(UnityPassesRenderEngine.bl_idname)


def _detach() -> None:
    for panel in _compat_panels():
        panel.COMPAT_ENGINES.discard(UnityPassesRenderEngine.bl_idname)
    # Final renders' helper process (large F12 frames are drawn in two bands): ended with the
    # engine; a render after registering again starts a new one.
    bandprocs.close_final_renderer()


register, unregister = feature(CLASSES, _attach, _detach)
