"""The Blender layer: the only part of :mod:`blendlib` that touches bpy (always inside functions).

- :mod:`.schema`: the one reader/writer of ``Material.unity`` / ``Scene.unity``.
- :mod:`.extract`: a Blender scene → :class:`blendlib.core.scene.DrawScene`.
- :mod:`.render`: render a scene (viewport or F12 depsgraph), write a Frame into an Image.
- :mod:`.files`: open .blend files, find scenes.
"""

from __future__ import annotations

from .extract import (
    build_draw_scene,
    material_from_blender,
    mesh_arrays,
    principled_inputs,
    render_size,
    render_visible_objects,
    world_ambient,
)
from .files import material_named, open_blend, scene_named
from .render import draw_scene_final, linear_rgba, render, render_final, write_image
from .schema import (
    FLAG_BITS,
    MATERIAL_FIELDS,
    PASS_FIELDS,
    SCENE_FIELDS,
    Field,
    pass_from_values,
    read_group,
    scene_settings,
    unity_props,
)

__all__ = [
    "FLAG_BITS", "MATERIAL_FIELDS", "PASS_FIELDS", "SCENE_FIELDS", "Field", "build_draw_scene", "draw_scene_final",
    "linear_rgba",
    "material_from_blender", "material_named", "mesh_arrays", "open_blend", "pass_from_values", "principled_inputs",
    "read_group",
    "render", "render_final", "render_size", "render_visible_objects", "scene_settings", "scene_named",
    "unity_props", "world_ambient", "write_image",
]
