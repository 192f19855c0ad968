"""The Blender layer: the only part of :mod:`blendlib` that touches bpy (always inside functions).

- :mod:`.schema`: the one reader/writer of ``Material.unity`` / ``Scene.unity`` / ``Light.unity``;
  :mod:`.lights`: Blender lights as Unity forward lights (derived values);
  :mod:`.migration`: their schema versions and the migration of older stored values.
- :mod:`.extract`: a Blender scene → :class:`blendlib.core.scene.DrawScene`.
- :mod:`.render`: render a scene (as F12 does, or through a given depsgraph; the rule is in its
  docstring), write a Frame into an Image.
- :mod:`.files`: open .blend files, find scenes.
- :mod:`.gltf_import`: ``.vrm`` / ``.glb`` / ``.gltf`` through Blender's glTF importer, each material with
  the Unity settings UniVRM / UniGLTF set; :mod:`.vrm_addon`: the VRM Add-on for Blender's MToon
  materials, read (and written) in the add-on's format, drawn as UniVRM draws its export.
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
from .files import material_named, open_blend, scene_arg, scene_named
from .lights import derived_light_values, unity_light_values
from .migration import SCHEMA_VERSION
from .render import (
    apply_border,
    border_region,
    draw_scene,
    draw_scene_final,
    linear_rgba,
    render,
    render_final,
    render_frame,
    write_image,
)
from .schema import (
    LIGHT_FIELDS,
    MATERIAL_FIELDS,
    PASS_FIELDS,
    SCENE_FIELDS,
    Field,
    light_settings,
    material_fields,
    material_from_values,
    material_values,
    migrate_data,
    migrate_stored,
    pass_from_values,
    read_group,
    read_pass,
    scene_settings,
    stamp_version,
    unity_props,
    write_light_settings,
    write_material,
    write_pass,
    write_scene_settings,
)

__all__ = [
    "LIGHT_FIELDS", "derived_light_values", "light_settings", "material_from_values", "unity_light_values",
    "write_light_settings",
    "MATERIAL_FIELDS", "PASS_FIELDS", "SCENE_FIELDS", "SCHEMA_VERSION", "Field", "apply_border", "border_region",
    "build_draw_scene", "draw_scene", "draw_scene_final", "scene_arg",
    "linear_rgba",
    "material_fields", "material_from_blender", "material_named", "material_values", "mesh_arrays",
    "migrate_data", "migrate_stored", "open_blend", "pass_from_values", "principled_inputs", "read_group",
    "read_pass", "render", "render_final", "render_frame", "render_size", "render_visible_objects", "scene_named",
    "scene_settings", "stamp_version", "unity_props", "world_ambient", "write_image", "write_material",
    "write_pass", "write_scene_settings",
]
