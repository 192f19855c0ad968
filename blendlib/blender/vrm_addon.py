"""Materials of the VRM Add-on for Blender, read without that add-on: the Unity state UniVRM draws
for the add-on's export (SPEC §11.6).

The add-on keeps a material's MToon settings in ``material["vrm_addon_extension"]["mtoon1"]`` (ID
properties: the system properties of Blender 5, the custom ones in files read from older versions)
and in the sockets of its node group. Which holds a value depends on the add-on version that saved
the material (``mtoon1.addon_version``), as its own migration reads them
(``editor/mtoon1/migration.py`` @0676a430; research-vrm §6.1):

* the material is an MToon material when ``mtoon1.enabled`` is set and its node
  ``Mtoon1Material.Mtoon1Output`` uses the group ``VRM Add-on MToon 1.0 Output Revision 1``;
* alpha mode and cutoff: before 2.20.55 ``material.blend_method`` (OPAQUE, CLIP, BLEND/HASHED) and
  ``alpha_threshold``; from 2.20.55 the sockets ``Alpha Mode`` (0 OPAQUE, 1 MASK, 2 BLEND) and
  ``Alpha Cutoff``;
* double sided: ``not material.use_backface_culling`` (every version);
* ``transparent_with_z_write``, ``render_queue_offset_number``, ``outline_width_mode`` (0 none,
  1 world, 2 screen), ``outline_width_factor``, ``outline_color_factor``,
  ``outline_lighting_mix_factor``, the base colour and its
  texture: before 2.20.62 the ID properties (``extensions.vrmc_materials_mtoon``,
  ``pbr_metallic_roughness``; absent = the add-on's defaults: sampler filters NEAREST, wraps
  REPEAT); from 2.20.62 the sockets ``Transparent With Z-Write``, ``Render Queue Offset Number``,
  ``Outline Width Mode``, ``Outline Width``, ``Outline Color``, ``Outline LightingMix``, ``Lit Color``,
  ``Lit Color Alpha``
  and the texture's nodes ``Mtoon1BaseColorTexture.Image`` / ``.Uv``;
* VRM 0.x only: ``mtoon0_render_queue`` (2000), ``mtoon0_front_cull_mode`` (False),
  ``mtoon0_outline_scaled_max_distance`` (1).

The armature's ``vrm_addon_extension.spec_version`` (an enum stored as 0 "0.0" or 1 "1.0"; absent:
its first item, 0.0) selects the exporter (:mod:`blendlib.formats.gltf.vrm_addon`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from ..formats.gltf.records import ImportedMaterial
from ..formats.gltf.vrm_addon import (
    ALPHA_MODES,
    OUTLINE_WIDTH_MODES,
    AddonMToon,
    AddonTexture,
    addon_material,
    texture_images,
)
from ..formats.gltf.vrm_advice import VrmSettings

EXTENSION_KEY = "vrm_addon_extension"
OUTPUT_NODE = "Mtoon1Material.Mtoon1Output"
OUTPUT_GROUP = "VRM Add-on MToon 1.0 Output Revision 1"
SOCKETS_FOR_ALPHA = (2, 20, 55)
SOCKETS_FOR_THE_REST = (2, 20, 62)


def _extension(id_block: Any) -> Any:
    """``id_block``'s stored ``vrm_addon_extension`` group: the system properties (Blender 5, the add-on
    installed when saved), else the custom properties (files from older Blender versions)."""
    getter = getattr(id_block, "bl_system_properties_get", None)
    stored = getter() if getter is not None else None
    group = stored.get(EXTENSION_KEY) if stored is not None else None
    if group is None:
        try:
            group = id_block.get(EXTENSION_KEY)
        except (AttributeError, TypeError):
            group = None
    return group if hasattr(group, "get") else None


def _get(group: Any, *path: str, default: Any = None) -> Any:
    for key in path:
        if group is None or not hasattr(group, "get"):
            return default
        group = group.get(key)
    return default if group is None else group


def _output_node(mat: Any) -> Any:
    tree = getattr(mat, "node_tree", None)
    node = tree.nodes.get(OUTPUT_NODE) if tree is not None else None
    if node is None or getattr(node, "node_tree", None) is None or node.node_tree.name != OUTPUT_GROUP:
        return None
    return node


def _socket(node: Any, name: str, default: Any) -> Any:
    socket = node.inputs.get(name) if node is not None else None
    value = getattr(socket, "default_value", None)
    if value is None:
        return default
    return tuple(value) if hasattr(value, "__len__") else value


def _version(values: Any) -> tuple[int, int, int]:
    try:
        major, minor, patch = (int(v) for v in values)
        return major, minor, patch
    except (TypeError, ValueError):
        return (0, 0, 0)


def _texture_from_ids(info: Any) -> AddonTexture | None:
    image = _get(info, "index", "source")
    if image is None or not hasattr(image, "bl_rna"):
        return None
    sampler = _get(info, "index", "sampler", default={})
    transform = _get(info, "extensions", "khr_texture_transform", default={})
    return AddonTexture(
        image=image, mag_filter=int(_get(sampler, "mag_filter", default=9728)),
        min_filter=int(_get(sampler, "min_filter", default=9728)),
        wrap_s=int(_get(sampler, "wrap_s", default=10497)), wrap_t=int(_get(sampler, "wrap_t", default=10497)),
        offset=tuple(float(v) for v in _get(transform, "offset", default=(0.0, 0.0))),
        scale=tuple(float(v) for v in _get(transform, "scale", default=(1.0, 1.0))))


def _texture_from_nodes(mat: Any, info: Any) -> AddonTexture | None:
    """From 2.20.62: the image node's image and interpolation, the UV group's offset, scale and wraps."""
    nodes = mat.node_tree.nodes
    image_node, uv = nodes.get("Mtoon1BaseColorTexture.Image"), nodes.get("Mtoon1BaseColorTexture.Uv")
    image = getattr(image_node, "image", None)
    if image is None:
        return None
    sampler = _get(info, "index", "sampler", default={})
    mag = 9728 if image_node.interpolation == "Closest" else 9729
    return AddonTexture(
        image=image, mag_filter=mag, min_filter=int(_get(sampler, "min_filter", default=9728)),
        wrap_s=int(_socket(uv, "Wrap S", 10497)), wrap_t=int(_socket(uv, "Wrap T", 10497)),
        offset=(float(_socket(uv, "UV Offset X", 0.0)), float(_socket(uv, "UV Offset Y", 0.0))),
        scale=(float(_socket(uv, "UV Scale X", 1.0)), float(_socket(uv, "UV Scale Y", 1.0))))


def addon_mtoon(mat: Any) -> AddonMToon | None:
    """The MToon settings of a ``bpy.types.Material`` of the VRM Add-on, or None when it is not one."""
    mtoon1 = _get(_extension(mat), "mtoon1")
    if mtoon1 is None or not _get(mtoon1, "enabled", default=0) or _get(mtoon1, "is_outline_material", default=0):
        return None
    node = _output_node(mat)
    if node is None:
        return None
    version = _version(_get(mtoon1, "addon_version", default=(0, 0, 0)))
    sources: dict[str, str] = {}
    if version < SOCKETS_FOR_ALPHA:
        blend_method = getattr(mat, "blend_method", "OPAQUE")
        alpha_mode = "BLEND" if blend_method in ("BLEND", "HASHED") else "MASK" if blend_method == "CLIP" else "OPAQUE"
        alpha_cutoff = float(mat.alpha_threshold)
        sources["alpha_mode"] = "material.blend_method"
    else:
        number = int(round(float(_socket(node, "Alpha Mode", 0))))
        alpha_mode = ALPHA_MODES[number] if 0 <= number < len(ALPHA_MODES) else "OPAQUE"
        alpha_cutoff = float(_socket(node, "Alpha Cutoff", 0.5))
        sources["alpha_mode"] = "socket Alpha Mode"
    mtoon_ids = _get(mtoon1, "extensions", "vrmc_materials_mtoon", default={})
    base_ids = _get(mtoon1, "pbr_metallic_roughness", default={})
    base_info = _get(base_ids, "base_color_texture")
    if version < SOCKETS_FOR_THE_REST:
        zwrite = bool(_get(mtoon_ids, "transparent_with_z_write", default=0))
        offset = int(_get(mtoon_ids, "render_queue_offset_number", default=0))
        outline = int(_get(mtoon_ids, "outline_width_mode", default=0))
        width = float(_get(mtoon_ids, "outline_width_factor", default=0.0))
        outline_color = tuple(float(v) for v in _get(mtoon_ids, "outline_color_factor", default=(0.0, 0.0, 0.0)))
        outline_mix = float(_get(mtoon_ids, "outline_lighting_mix_factor", default=1.0))
        factor = tuple(float(v) for v in _get(base_ids, "base_color_factor", default=(1.0, 1.0, 1.0, 1.0)))
        texture = _texture_from_ids(base_info)
        sources["mtoon"] = "ID properties (add-on before 2.20.62)"
    else:
        zwrite = bool(_socket(node, "Transparent With Z-Write", 0))
        offset = int(round(float(_socket(node, "Render Queue Offset Number", 0))))
        outline = int(round(float(_socket(node, "Outline Width Mode", 0))))
        width = float(_socket(node, "Outline Width", 0.0))
        outline_color = tuple(float(v) for v in _socket(node, "Outline Color", (0.0, 0.0, 0.0))[:3])
        outline_mix = float(_socket(node, "Outline LightingMix", 1.0))
        lit = _socket(node, "Lit Color", (1.0, 1.0, 1.0, 1.0))
        factor = (float(lit[0]), float(lit[1]), float(lit[2]), float(_socket(node, "Lit Color Alpha", 1.0)))
        texture = _texture_from_nodes(mat, base_info)
        sources["mtoon"] = "node group sockets (add-on 2.20.62 and later)"
    return AddonMToon(
        name=mat.name, alpha_mode=alpha_mode, alpha_cutoff=alpha_cutoff,
        double_sided=not mat.use_backface_culling, transparent_with_z_write=zwrite,
        render_queue_offset_number=offset,
        outline_width_mode=OUTLINE_WIDTH_MODES[outline] if 0 <= outline < 3 else "none",
        outline_width_factor=width, outline_color_factor=outline_color, outline_lighting_mix_factor=outline_mix,
        outline_width_multiply_texture=_texture_from_ids(_get(mtoon_ids, "outline_width_multiply_texture")),
        base_color_factor=factor,
        base_color_texture=texture,
        mtoon0_render_queue=int(_get(mtoon1, "mtoon0_render_queue", default=2000)),
        mtoon0_front_cull_mode=bool(_get(mtoon1, "mtoon0_front_cull_mode", default=0)),
        mtoon0_outline_scaled_max_distance=float(_get(mtoon1, "mtoon0_outline_scaled_max_distance", default=1.0)),
        addon_version=version, sources=sources)


def armature_of(obj: Any) -> Any:
    """The armature object deforming or parenting ``obj`` (None when there is none)."""
    for modifier in getattr(obj, "modifiers", ()):
        if modifier.type == "ARMATURE" and modifier.object is not None:
            return modifier.object
    parent = obj.parent
    while parent is not None:
        if parent.type == "ARMATURE":
            return parent
        parent = parent.parent
    return None


def spec_version(mat: Any) -> str:
    """``"0.x"`` or ``"1.0"``: the ``spec_version`` of the VRM armature of the objects that use ``mat``
    (else of the file's only VRM armature; absent: the add-on's default, 0.0)."""
    import bpy

    armatures = []
    for obj in bpy.data.objects:
        if obj.type == "MESH" and any(slot.material == mat for slot in obj.material_slots):
            armature = armature_of(obj)
            if armature is not None and _extension(armature.data) is not None:
                armatures.append(armature.data)
    if not armatures:
        armatures = [a for a in bpy.data.armatures if _extension(a) is not None]
    if not armatures:
        return "0.x"
    return "1.0" if int(_get(_extension(armatures[0]), "spec_version", default=0)) == 1 else "0.x"


def derived_material(mat: Any) -> tuple[ImportedMaterial, Any, Any, AddonMToon] | None:
    """(the Unity state UniVRM draws, the ``_MainTex`` and the outline-width Blender images or None, the
    add-on's settings) of a material of the VRM Add-on; None for any other material."""
    mtoon = addon_mtoon(mat)
    if mtoon is None:
        return None
    imported = addon_material(mtoon, spec_version(mat))
    image, width_image = texture_images(mtoon, imported)
    return imported, image, width_image, mtoon


def summary(mat: Any) -> str | None:
    """One line for the Unity Material panel, e.g. ``VRM Add-on MToon: Transparent → queue 2952, Cull
    Front, ZWrite Off, Blend SrcAlpha OneMinusSrcAlpha, clip alpha < 0.0009765625 (VRM 0.x export)``
    (the FORWARD_BASE pass); None for other materials."""
    derived = derived_material(mat)
    if derived is None:
        return None
    imported, _image, _width_image, mtoon = derived
    material = imported.material
    base = material.passes[0]
    words = [f"queue {material.render_queue}", f"Cull {base.cull}", f"ZWrite {'On' if base.zwrite else 'Off'}",
             f"Blend {base.src_blend} {base.dst_blend}"]
    if base.alpha_test:
        words.append(f"clip alpha < {material.cutoff:g}")
    if base.alpha_to_mask:
        words.append("AlphaToMask On")
    words.append(f"outline {imported.extra['outline']['mode']}")
    return f"VRM Add-on MToon: {mtoon.render_mode} → {', '.join(words)} (VRM {spec_version(mat)} export)"


# --------------------------------------------------------------------------- advice in VRM terms


def advice_settings() -> dict[str, VrmSettings]:
    """Per material name, the VRM Add-on settings its state comes from: every add-on MToon material
    whose Unity settings are off (``settings=`` of :func:`blendlib.explain.advice.advise`). Reads
    bpy: call it on the main thread, with the DrawScene."""
    import bpy

    from .schema import material_values

    out = {}
    for mat in bpy.data.materials:
        mtoon = None if material_values(mat)["enabled"] else addon_mtoon(mat)
        if mtoon is not None:
            out[mat.name] = VrmSettings(mtoon, spec_version(mat))
    return out


#: The settings the advice writes, and the socket that holds each from add-on 2.20.62 (2.20.55 for the
#: alpha mode); the ID property path of the others (``mtoon0_render_queue`` has no socket).
_ADVICE_SOCKETS = {"render_queue_offset_number": "Render Queue Offset Number",
                   "transparent_with_z_write": "Transparent With Z-Write", "alpha_mode": "Alpha Mode"}
_ADVICE_IDS = {"render_queue_offset_number": ("extensions", "vrmc_materials_mtoon"),
               "transparent_with_z_write": ("extensions", "vrmc_materials_mtoon"), "mtoon0_render_queue": ()}


def apply_settings(mat: Any, fields: dict[str, Any]) -> AddonMToon:
    """Write advised VRM settings (``AddonMToon`` field → value: ``render_queue_offset_number``,
    ``mtoon0_render_queue``, ``transparent_with_z_write``, ``alpha_mode``) where the add-on keeps them:
    the ID properties ``vrm_addon_extension.mtoon1`` and the output group's sockets (the add-on
    2.20.61 mirrors them, 2.20.62 reads the sockets), so its export carries the fix. Returns the
    settings read back; ValueError (one line, nothing written) for a material that is not the
    add-on's, an unknown field or an alpha mode an add-on older than 2.20.55 keeps in ``blend_method``."""
    from .schema import material_values

    mtoon = addon_mtoon(mat)
    if mtoon is None:
        raise ValueError(f"material {mat.name!r} is not a VRM Add-on MToon material")
    if material_values(mat)["enabled"]:
        raise ValueError(f"material {mat.name!r}: its Unity settings are on and decide what it draws; "
                         "change those (or turn them off to use the VRM Add-on's)")
    unknown = sorted(set(fields) - {*_ADVICE_SOCKETS, *_ADVICE_IDS})
    if unknown:
        raise ValueError(f"material {mat.name!r}: no VRM setting {unknown[0]!r} to write")
    wanted = replace(mtoon, **fields)  # checks the alpha mode's name
    if "alpha_mode" in fields and mtoon.addon_version < SOCKETS_FOR_ALPHA:
        raise ValueError(f"material {mat.name!r}: the VRM Add-on {'.'.join(map(str, mtoon.addon_version))} keeps "
                         "the alpha mode in the material's blend method; set it in the add-on's panel")
    mtoon1 = _get(_extension(mat), "mtoon1")
    node = _output_node(mat)
    if "alpha_mode" in fields and node.inputs.get(_ADVICE_SOCKETS["alpha_mode"]) is None:
        raise ValueError(f"material {mat.name!r}: the VRM Add-on's output group has no Alpha Mode socket")
    for key, value in fields.items():
        stored = ALPHA_MODES.index(value) if key == "alpha_mode" else int(value)
        path = _ADVICE_IDS.get(key)
        if path is not None:
            group = mtoon1
            for name in path:
                if group.get(name) is None:
                    group[name] = {}
                group = group[name]
            group[key] = stored
        socket = node.inputs.get(_ADVICE_SOCKETS.get(key, "")) if key in _ADVICE_SOCKETS else None
        if socket is not None:
            socket.default_value = float(stored)
    got = addon_mtoon(mat)
    if any(getattr(got, key) != getattr(wanted, key) for key in fields):
        raise ValueError(f"material {mat.name!r}: the VRM settings did not read back as written")
    return got


# --------------------------------------------------------------------------- writing (the add-on's format)

#: The add-on version the writer stores: the corpus files' (alpha mode in sockets, the rest in ID properties).
WRITTEN_VERSION = (2, 20, 61)
_FLOAT_SOCKETS = ("Double Sided", "Transparent With Z-Write", "Render Queue Offset Number", "Lit Color Alpha",
                  "Outline Width Mode", "Outline Width", "Outline LightingMix", "Alpha Mode", "Alpha Cutoff")
_COLOR_SOCKETS = ("Lit Color", "Outline Color")


def _output_group() -> Any:
    """The node group ``VRM Add-on MToon 1.0 Output Revision 1`` with the sockets read here (the add-on
    replaces it with its full group when it migrates the file)."""
    import bpy

    group = bpy.data.node_groups.get(OUTPUT_GROUP)
    if group is None:
        group = bpy.data.node_groups.new(OUTPUT_GROUP, "ShaderNodeTree")
    names = {item.name for item in group.interface.items_tree if getattr(item, "in_out", None) == "INPUT"}
    for name in (*_COLOR_SOCKETS, *_FLOAT_SOCKETS):
        if name not in names:
            kind = "NodeSocketColor" if name in _COLOR_SOCKETS else "NodeSocketFloat"
            group.interface.new_socket(name, in_out="INPUT", socket_type=kind)
    return group


def _texture_ids(texture: AddonTexture) -> dict[str, Any]:
    """A texture info as the add-on's ID properties hold it (what :func:`_texture_from_ids` reads)."""
    return {"index": {"source": texture.image, "sampler": {
                "mag_filter": texture.mag_filter, "min_filter": texture.min_filter,
                "wrap_s": texture.wrap_s, "wrap_t": texture.wrap_t}},
            "extensions": {"khr_texture_transform": {"offset": list(texture.offset), "scale": list(texture.scale)}}}


def write_addon_mtoon(mat: Any, mtoon: AddonMToon) -> None:
    """Store ``mtoon`` on a ``bpy.types.Material`` as the VRM Add-on 2.20.61 stores it: the ID properties
    ``vrm_addon_extension.mtoon1`` (system properties), the output node group's sockets, and
    ``use_backface_culling``; the node tree gets a Principled BSDF with the base colour (and its
    texture) so that EEVEE and Blender's glTF exporter see the material too. The material's Unity
    settings are left as they are (off: it renders through :func:`derived_material`)."""
    texture = mtoon.base_color_texture
    base: dict[str, Any] = {"base_color_factor": list(mtoon.base_color_factor)}
    if texture is not None:
        base["base_color_texture"] = _texture_ids(texture)
    mode = OUTLINE_WIDTH_MODES.index(mtoon.outline_width_mode)
    mtoon1 = {
        "enabled": 1, "addon_version": list(WRITTEN_VERSION), "is_outline_material": 0,
        "pbr_metallic_roughness": base,
        "extensions": {"vrmc_materials_mtoon": {
            "transparent_with_z_write": int(mtoon.transparent_with_z_write),
            "render_queue_offset_number": int(mtoon.render_queue_offset_number),
            "outline_width_mode": mode, "outline_width_factor": float(mtoon.outline_width_factor),
            "outline_color_factor": [float(c) for c in mtoon.outline_color_factor],
            "outline_lighting_mix_factor": float(mtoon.outline_lighting_mix_factor),
            **({} if mtoon.outline_width_multiply_texture is None else
               {"outline_width_multiply_texture": _texture_ids(mtoon.outline_width_multiply_texture)})}},
        "mtoon0_render_queue": int(mtoon.mtoon0_render_queue),
        "mtoon0_front_cull_mode": int(mtoon.mtoon0_front_cull_mode),
        "mtoon0_outline_scaled_max_distance": float(mtoon.mtoon0_outline_scaled_max_distance),
    }
    mat.bl_system_properties_get(do_create=True)[EXTENSION_KEY] = {"mtoon1": mtoon1}
    mat.use_backface_culling = not mtoon.double_sided
    tree = mat.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    tree.links.new(bsdf.outputs[0], output.inputs["Surface"])
    bsdf.inputs["Base Color"].default_value = mtoon.base_color_factor
    bsdf.inputs["Alpha"].default_value = mtoon.base_color_factor[3]
    if texture is not None:
        image_node = tree.nodes.new("ShaderNodeTexImage")
        image_node.name = "Mtoon1BaseColorTexture.Image"
        image_node.image = texture.image
        image_node.interpolation = "Closest" if texture.mag_filter == 9728 else "Linear"
        tree.links.new(image_node.outputs["Color"], bsdf.inputs["Base Color"])
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = _output_group()
    node.name = OUTPUT_NODE
    sockets = {"Double Sided": float(mtoon.double_sided),
               "Transparent With Z-Write": float(mtoon.transparent_with_z_write),
               "Render Queue Offset Number": float(mtoon.render_queue_offset_number),
               "Lit Color Alpha": float(mtoon.base_color_factor[3]), "Outline Width Mode": float(mode),
               "Outline Width": float(mtoon.outline_width_factor),
               "Outline LightingMix": float(mtoon.outline_lighting_mix_factor),
               "Alpha Mode": float(ALPHA_MODES.index(mtoon.alpha_mode)), "Alpha Cutoff": float(mtoon.alpha_cutoff)}
    for name, value in sockets.items():
        node.inputs[name].default_value = value
    node.inputs["Lit Color"].default_value = tuple(mtoon.base_color_factor)
    node.inputs["Outline Color"].default_value = (*mtoon.outline_color_factor, 1.0)


def write_armature_spec_version(armature: Any, spec: str) -> None:
    """Store the VRM Add-on's ``spec_version`` (``"0.x"`` → 0, ``"1.0"`` → 1) on an armature's data."""
    value = {"0.x": 0, "1.0": 1}[spec]
    armature.bl_system_properties_get(do_create=True)[EXTENSION_KEY] = {
        "spec_version": value, "addon_version": list(WRITTEN_VERSION)}
