"""The one schema of the Unity settings stored in Blender: ``Material.unity`` and ``Scene.unity``.

The add-on builds its bpy properties from the field tables here; everything that reads
the stored settings goes through the readers (:func:`material_values`,
:func:`scene_settings`, :func:`read_pass`) and everything that writes them through the
writers (:func:`write_material`, :func:`write_pass`, :func:`write_scene_settings`), so
names, defaults and the integers Blender stores for enum items agree everywhere.

Readers and writers work whether or not the add-on is registered: unregistered, they
use the stored ID properties (``bl_system_properties_get()``) with the same integers;
absent values take the defaults of the data model. Each group stores its schema
version (:mod:`.migration`): readers migrate values of older versions as they read,
writers migrate the stored group in place before they write and stamp the version.

This module does not import bpy at module level. It is longer than the project's ~600 lines
because the field tables (the stored file format, one row per property with its description) and
the one reader/writer of them belong together.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from ..core.vocabulary import (
    CHANNELS,
    MSAA_SAMPLES,
    BlendFactor,
    BlendOp,
    ColorSpace,
    CompareFunction,
    Cull,
    Lighting,
    LightMode,
    LightRenderMode,
    Material,
    OutlineFormula,
    OutlineMode,
    Pass,
    Queue,
    SortMode,
    StencilOp,
    TextureFilter,
    TextureWrap,
    VertexColor,
    color_mask_bits,
    color_mask_from_bits,
    pass_from_dict,
)
from .migration import SCHEMA_VERSION, VERSION_KEY, migrate_light, migrate_material, migrate_scene, stored_version


@dataclass(frozen=True)
class Field:
    """One add-on property.

    ``kind``: ``bool``, ``int``, ``float``, ``enum``, ``flags``, ``color``, ``vector``,
    ``string``, ``image`` or ``passes``. Enum items are stored by Blender as the index
    of the member in its :mod:`blendlib.core.vocabulary` enum class (``enum_items`` may
    list a subset, e.g. ZTest without ``Never``); ``flags`` (ColorMask) as the bits of
    :data:`blendlib.core.vocabulary.COLOR_MASK_BITS` (Unity's ColorWriteMask: A=1, B=2,
    G=4, R=8). ``tests/blender/test_schema.py`` pins every number.
    """

    name: str
    kind: str
    default: Any
    label: str
    description: str
    enum: Any = None
    enum_items: tuple = ()
    size: int = 0
    subtype: str = "NONE"
    min: float | None = None
    max: float | None = None
    soft_min: float | None = None
    soft_max: float | None = None
    #: An ``int`` field's allowed values (e.g. MSAA 1, 2, 4, 8); empty: any in [min, max].
    choices: tuple = ()

    def items(self):
        """``(identifier, number)`` pairs of an enum field, in display order."""
        members = self.enum_items or tuple(self.enum)
        return [(m.value, list(self.enum).index(m)) for m in members]


PASS_FIELDS: tuple[Field, ...] = (
    Field("name", "string", "Pass", "Name", "Pass name (ShaderLab Name \"...\"); for your reference only"),
    Field("cull", "enum", "Back", "Cull",
          "Cull: which faces are not drawn (front = the side Blender's normal points to)", enum=Cull),
    Field("zwrite", "bool", True, "ZWrite", "ZWrite On/Off: write the fragment depth to the depth buffer"),
    Field("ztest", "enum", "LEqual", "ZTest", "ZTest: depth comparison that a fragment must pass",
          enum=CompareFunction, enum_items=tuple(c for c in CompareFunction if c is not CompareFunction.Never)),
    Field("blend", "bool", False, "Blend", "Blend on (factors below) or Blend Off (write the shader colour)"),
    Field("src_blend", "enum", "One", "Src", "Blend source factor (multiplies the shader colour)", enum=BlendFactor),
    Field("dst_blend", "enum", "Zero", "Dst", "Blend destination factor (multiplies the frame colour)",
          enum=BlendFactor),
    Field("blend_op", "enum", "Add", "BlendOp", "BlendOp: how source and destination terms are combined",
          enum=BlendOp),
    Field("separate_alpha", "bool", False, "Separate Alpha",
          "Use separate blend factors and op for the alpha channel (Blend A B, C D)"),
    Field("src_blend_alpha", "enum", "One", "Src Alpha", "Alpha blend source factor", enum=BlendFactor),
    Field("dst_blend_alpha", "enum", "Zero", "Dst Alpha", "Alpha blend destination factor", enum=BlendFactor),
    Field("blend_op_alpha", "enum", "Add", "BlendOp Alpha", "Alpha BlendOp", enum=BlendOp),
    Field("color_mask", "flags", frozenset(CHANNELS), "ColorMask",
          "ColorMask: channels written to the colour buffer (none = ColorMask 0)"),
    Field("offset_factor", "float", 0.0, "Offset Factor", "Offset factor (glPolygonOffset factor: slope scale)",
          soft_min=-10.0, soft_max=10.0),
    Field("offset_units", "float", 0.0, "Offset Units", "Offset units (glPolygonOffset units of 2^-24 depth)",
          soft_min=-100.0, soft_max=100.0),
    Field("alpha_test", "bool", False, "Alpha Test", "clip(alpha - _Cutoff) in this pass"),
    Field("stencil", "bool", False, "Stencil", "Enable the Stencil { } block of this pass"),
    Field("stencil_ref", "int", 0, "Ref", "Stencil Ref value", min=0, max=255),
    Field("stencil_read_mask", "int", 255, "ReadMask", "Stencil ReadMask", min=0, max=255),
    Field("stencil_write_mask", "int", 255, "WriteMask", "Stencil WriteMask", min=0, max=255),
    Field("stencil_comp", "enum", "Always", "Comp", "Stencil Comp: (Ref & ReadMask) Comp (stencil & ReadMask)",
          enum=CompareFunction),
    Field("stencil_pass", "enum", "Keep", "Pass", "Stencil operation when stencil and depth tests pass",
          enum=StencilOp),
    Field("stencil_fail", "enum", "Keep", "Fail", "Stencil operation when the stencil test fails", enum=StencilOp),
    Field("stencil_zfail", "enum", "Keep", "ZFail", "Stencil operation when the depth test fails", enum=StencilOp),
    # Schema version 3 (SPEC §12): appended; absent values take these defaults, which draw as before.
    Field("alpha_to_mask", "bool", False, "AlphaToMask",
          "AlphaToMask On: with MSAA the fragment covers a share of its pixel's samples given by its alpha"),
    Field("alpha_test_comp", "enum", "GEqual", "Alpha Comparison",
          "Alpha test: a fragment survives when alpha <comparison> _Cutoff (GEqual = clip(a - _Cutoff))",
          enum=CompareFunction),
    Field("light_mode", "enum", "ForwardBase", "LightMode",
          "Tags { \"LightMode\"=... }: Always and ForwardBase draw once, ForwardAdd once per extra per-pixel "
          "light, Vertex only without forward passes, the others never", enum=LightMode),
    # The outline vertex program (MToon's outline pass, SPEC §11.6; issue 28): appended in schema
    # version 3 too; absent values are Off, which draws the vertices as before.
    Field("outline_mode", "enum", "Off", "Outline",
          "Outline vertex program (MToon's outline pass): vertices pushed out along their normal before "
          "projection, by a width in scene units (World) or a share of the screen height (Screen)",
          enum=OutlineMode),
    Field("outline_width", "float", 0.0, "Outline Width",
          "MToon's outline width: 0.x's _OutlineWidth (World: centimetres; Screen: % of the screen height), "
          "1.0's outlineWidthFactor (World: metres; Screen: share of the screen height)",
          min=0.0, soft_max=10.0),
    Field("outline_formula", "enum", "MToon0x", "Outline Formula",
          "Which MToon's outline arithmetic: VRM 0.x's VRM/MToon or VRM 1.0's VRM10/MToon10", enum=OutlineFormula),
    Field("outline_max_distance", "float", 1.0, "Outline Max Distance",
          "MToon 0.x's _OutlineScaledMaxDistance: in Screen mode the outline stops growing with distance "
          "beyond this clip w", min=0.0, soft_min=1.0, soft_max=10.0),
    # Schema version 4 (issue 28): MToon's outline colour, appended; absent, the pass draws the
    # material's lit colour as before. ``outline_colored`` off is the core's ``outline_color`` None.
    Field("outline_colored", "bool", False, "Outline Color",
          "Draw this pass in MToon's outline colour (0.x _OutlineColor, 1.0 outlineColorFactor) instead of the "
          "material's lit colour"),
    Field("outline_color", "color", (0.0, 0.0, 0.0), "Outline Color",
          "MToon's outline colour (sRGB-encoded, like a Unity colour property)", size=3, subtype="COLOR_GAMMA",
          min=0.0, soft_max=1.0),
    Field("outline_lighting_mix", "float", 0.0, "Outline Lighting Mix",
          "MToon's _OutlineLightingMix / outlineLightingMixFactor: colour × lerp(1, lit colour, mix); "
          "0 the outline colour alone", min=0.0, max=1.0),
)


MATERIAL_FIELDS: tuple[Field, ...] = (
    Field("enabled", "bool", False, "Unity Material",
          "Render with these Unity settings; off: a default opaque material from the Principled BSDF"),
    Field("queue", "enum", "Geometry", "Queue", "Render queue (Tags { \"Queue\"=... })", enum=Queue),
    Field("queue_offset", "int", 0, "Offset", "Added to the queue number (\"Transparent+1\")",
          soft_min=-100, soft_max=100),
    Field("color", "color", (1.0, 1.0, 1.0, 1.0), "_Color", "_Color (sRGB-encoded, like a Unity colour property)",
          size=4, subtype="COLOR_GAMMA", min=0.0, soft_max=1.0),
    Field("main_tex", "image", None, "_MainTex", "_MainTex (none = white)"),
    Field("main_tex_tiling", "vector", (1.0, 1.0), "Tiling", "_MainTex tiling (_MainTex_ST.xy)", size=2,
          soft_min=-100.0, soft_max=100.0),
    Field("main_tex_offset", "vector", (0.0, 0.0), "Offset", "_MainTex offset (_MainTex_ST.zw)", size=2,
          soft_min=-10.0, soft_max=10.0),
    Field("main_tex_filter", "enum", "Bilinear", "Filter",
          "Sampler filter mode (Trilinear: between mip levels when mipmaps are on)", enum=TextureFilter),
    Field("main_tex_wrap", "enum", "Repeat", "Wrap", "Sampler wrap mode", enum=TextureWrap),
    Field("alpha_scale", "float", 1.0, "_AlphaScale", "_AlphaScale: multiplies the alpha", min=0.0, max=1.0,
          subtype="FACTOR"),
    Field("cutoff", "float", 0.5, "_Cutoff", "_Cutoff: alpha-tested passes discard alpha < _Cutoff", min=0.0,
          max=1.0, subtype="FACTOR"),
    Field("lighting", "enum", "Lambert", "Lighting",
          "Lambert: the book's ForwardBase fragment (ambient + main light); Unlit: albedo only", enum=Lighting),
    Field("passes", "passes", (), "Passes", "Passes drawn in order (none = one default pass)"),
    # Schema version 3 (SPEC §12): appended; absent values take these defaults, which draw as before.
    Field("main_tex_mipmaps", "bool", False, "Mip Maps",
          "Sample _MainTex through its mip chain (2x2 box downsampling, as Unity's texture importer)"),
    Field("main_tex_preserve_coverage", "bool", False, "Preserve Coverage",
          "Mip Maps Preserve Coverage: scale each mip level's alpha so that its coverage at _Cutoff stays level 0's"),
    Field("vertex_color", "enum", "Off", "Vertex Color",
          "How the shader uses the mesh's vertex colour i.color: Multiply (albedo and alpha x i.color: sprites, "
          "UI) or Particle (2 x i.color x _TintColor x tex)", enum=VertexColor),
    Field("tint_color", "color", (0.5, 0.5, 0.5, 0.5), "_TintColor",
          "_TintColor of the particle shaders (sRGB-encoded, like a Unity colour property)", size=4,
          subtype="COLOR_GAMMA", min=0.0, soft_max=1.0),
    # Schema version 4 (issue 28): MToon's outline-width texture, appended; absent: none (×1).
    Field("outline_width_tex", "image", None, "Outline Width Texture",
          "MToon's outline-width texture (_OutlineWidthTexture / outlineWidthMultiplyTexture): an outline pass's "
          "width times its red channel at the vertex's _MainTex coordinates (none = x1; a Non-Color image is "
          "read as data)"),
    Field("outline_width_tex_filter", "enum", "Bilinear", "Width Filter",
          "Sampler filter mode of the outline-width texture (sampled at mip level 0)", enum=TextureFilter),
    Field("outline_width_tex_wrap", "enum", "Repeat", "Width Wrap", "Sampler wrap mode of the outline-width texture",
          enum=TextureWrap),
)


SCENE_FIELDS: tuple[Field, ...] = (
    Field("color_space", "enum", "Gamma", "Color Space",
          "Unity's Player colour space: Gamma blends encoded values, Linear blends in linear space", enum=ColorSpace),
    Field("hdr", "bool", False, "HDR", "HDR float colour buffer; off: 8-bit UNORM buffer"),
    Field("clear_color", "color", (0.19, 0.30, 0.47, 0.0), "Clear Color",
          "Camera background colour (sRGB-encoded, Solid Color clear)", size=4, subtype="COLOR_GAMMA",
          min=0.0, soft_max=1.0),
    Field("ambient_from_world", "bool", True, "Ambient from World",
          "Ambient = the World background colour (Background Color x Strength)"),
    Field("ambient_color", "color", (0.2, 0.2, 0.2), "Ambient Color",
          "Ambient colour (sRGB-encoded) when not taken from the World", size=3, subtype="COLOR_GAMMA",
          min=0.0, soft_max=1.0),
    Field("sort_mode", "enum", "Default", "Sort Mode",
          "Transparency sort: camera distance (Perspective), view depth (Orthographic) or along an axis",
          enum=SortMode),
    Field("sort_axis", "vector", (0.0, 0.0, 1.0), "Sort Axis", "Axis for the CustomAxis sort mode", size=3,
          soft_min=-1.0, soft_max=1.0, subtype="XYZ"),
    # Schema version 3 (SPEC §12).
    Field("msaa", "int", 1, "MSAA", "Anti-aliasing samples per pixel (Unity's Quality setting): 1 (off), 2, 4 or 8",
          min=1, max=8, choices=MSAA_SAMPLES),
    Field("pixel_light_count", "int", 4, "Pixel Light Count",
          "Per renderer, at most this many forward lights (besides the main Sun) are per-pixel and draw the "
          "ForwardAdd passes (Unity's Quality setting; Important lights always are)", min=0, soft_max=8),
)


#: ``Light.unity`` (SPEC §12): a Blender Point, Spot or Sun light as a Unity forward light. With
#: ``use_blender_values`` the intensity, range and spot angle follow the Blender light
#: (:func:`blendlib.blender.lights.derived_light_values`); off, the values stored here.
LIGHT_FIELDS: tuple[Field, ...] = (
    Field("use_blender_values", "bool", True, "From Blender Light",
          "Intensity, range and spot angle follow the Blender light; off: the values below"),
    Field("intensity", "float", 1.0, "Intensity", "Light.intensity (the light colour is multiplied by it)",
          min=0.0, soft_max=8.0),
    Field("range", "float", 10.0, "Range", "Light.range in metres: point and spot lights reach no farther",
          min=0.0, soft_max=100.0, subtype="DISTANCE"),
    Field("spot_angle", "float", 30.0, "Spot Angle", "Light.spotAngle: the full cone angle in degrees",
          min=1.0, max=179.0),
    Field("render_mode", "enum", "Auto", "Render Mode",
          "Important: always per-pixel; Not Important: never per-pixel; Auto: per-pixel by importance within "
          "the Pixel Light Count", enum=LightRenderMode),
)


_BY_NAME = {
    "material": {f.name: f for f in MATERIAL_FIELDS},
    "pass": {f.name: f for f in PASS_FIELDS},
    "scene": {f.name: f for f in SCENE_FIELDS},
    "light": {f.name: f for f in LIGHT_FIELDS},
}


# Reading


def _stored_value(f: Field, raw: Any) -> Any:
    """A stored ID-property value (or an RNA value) → the identifier form used by the core."""
    if f.kind == "enum":
        if isinstance(raw, str):
            return raw
        members = list(f.enum)
        idx = int(raw)
        return members[idx].value if 0 <= idx < len(members) else f.default
    if f.kind == "flags":
        if isinstance(raw, (set, frozenset)):
            return frozenset(raw)
        return color_mask_from_bits(int(raw) & 15)
    if f.kind in ("color", "vector"):
        return tuple(float(v) for v in raw)
    if f.kind == "bool":
        return bool(raw)
    if f.kind == "int":
        return int(raw)
    if f.kind == "float":
        return float(raw)
    if f.kind == "string":
        return str(raw)
    return raw


def _as_float32(value: Any) -> Any:
    if isinstance(value, tuple):
        return tuple(float(np.float32(v)) for v in value)
    return float(np.float32(value))


def read_group(source: Any, fields: tuple[Field, ...]) -> dict[str, Any]:
    """Plain dict of a property group of the current schema version: ``source`` is an RNA
    PropertyGroup, a stored IDPropertyGroup, a dict, or None (all defaults). Passes come back
    as a list of dicts. Use :func:`material_values` / :func:`scene_settings` for an ID block:
    they migrate older versions first."""
    out: dict[str, Any] = {}
    for f in fields:
        raw = None
        if source is not None:
            if hasattr(source, "bl_rna"):
                raw = getattr(source, f.name, None)
            else:
                try:
                    raw = source.get(f.name)
                except AttributeError:
                    raw = None
        if f.kind == "passes":
            out[f.name] = [read_group(item, PASS_FIELDS) for item in (raw or ())]
        elif f.kind == "image":
            out[f.name] = raw
        elif raw is None:  # never set: the default, as Blender would store it (float32)
            out[f.name] = _stored_value(f, _as_float32(f.default)) if f.kind in ("float", "color", "vector") \
                else f.default
        else:
            out[f.name] = _stored_value(f, raw)
    return out


def _system_store(id_block: Any, create: bool = False) -> Any:
    """The ID properties that hold registered add-on properties (Blender 5: system properties)."""
    getter = getattr(id_block, "bl_system_properties_get", None)
    if getter is not None:
        return getter(do_create=True) if create else getter()
    return id_block  # Blender < 5.0 keeps add-on properties with the custom properties


def stored_group(id_block: Any) -> Any:
    """The stored ``unity`` ID property group of a material or scene (None when nothing is stored)."""
    store = _system_store(id_block)
    if store is None:
        return None
    try:
        return store.get("unity")
    except (AttributeError, TypeError):
        return None


def unity_props(id_block: Any) -> Any:
    """``id_block.unity`` when the add-on is registered, else its stored group (or None)."""
    group = getattr(id_block, "unity", None)
    if group is not None and hasattr(group, "bl_rna"):
        return group
    return stored_group(id_block)


def _current_source(id_block: Any, migrate) -> Any:
    """What to read the settings from: the RNA group or the stored group when they are of the
    current schema version, else the stored values migrated to it (a dict)."""
    stored = stored_group(id_block)
    if stored_version(stored) >= SCHEMA_VERSION or stored is None:
        return unity_props(id_block)
    return migrate(stored.to_dict() if hasattr(stored, "to_dict") else dict(stored))


def material_values(mat: Any) -> dict[str, Any]:
    """``Material.unity`` as a dict of identifiers (defaults where absent; passes as dicts)."""
    return read_group(_current_source(mat, migrate_material), MATERIAL_FIELDS)


def scene_settings(scene: Any) -> dict[str, Any]:
    """``Scene.unity`` as a dict of identifiers (defaults where absent)."""
    return read_group(_current_source(scene, migrate_scene), SCENE_FIELDS)


def light_settings(light: Any) -> dict[str, Any]:
    """``Light.unity`` of a ``bpy.types.Light`` (the light data) as a dict (defaults where absent)."""
    return read_group(_current_source(light, migrate_light), LIGHT_FIELDS)


def material_from_values(name: str, values: Mapping[str, Any], main_tex: Any = None,
                         outline_width_tex: Any = None) -> Material:
    """The :class:`Material` of :func:`material_values` output (an enabled material): every schema
    field the dataclass holds, enums parsed; ``main_tex`` and ``outline_width_tex`` the converted
    textures (or None)."""
    kwargs: dict[str, Any] = {"name": name, "main_tex": main_tex, "outline_width_tex": outline_width_tex}
    for f in MATERIAL_FIELDS:
        if f.name in ("enabled", "main_tex", "outline_width_tex"):
            continue
        value = values[f.name]
        if f.kind == "passes":
            value = tuple(pass_from_values(p) for p in value) or (Pass(),)
        elif f.kind == "enum":
            value = f.enum.parse(value)
        elif f.kind in ("color", "vector"):
            value = tuple(value)
        kwargs[f.name] = value
    return Material(**kwargs)


def pass_from_values(values: dict[str, Any]) -> Pass:
    """A :class:`Pass` from a dict of :data:`PASS_FIELDS` values (identifiers, set colour mask;
    ``outline_colored`` off: no outline colour) or of :func:`~blendlib.core.vocabulary.pass_to_dict`."""
    values = {k: (sorted(v) if k == "color_mask" else v) for k, v in values.items()}
    if not values.pop("outline_colored", values.get("outline_color") is not None):
        values["outline_color"] = None
    return pass_from_dict(values)


def read_pass(item: Any) -> Pass:
    """The :class:`Pass` of one registered pass property group (an item of ``Material.unity.passes``)."""
    return pass_from_values(read_group(item, PASS_FIELDS))


# Writing


def _encode(f: Field, value: Any, rna: bool) -> Any:
    """A value (enum member or identifier, channel set, number, Image) → what is assigned: the RNA
    value when the add-on is registered (``rna``), else the stored ID-property value. ValueError
    on a value the field cannot hold."""
    if f.kind == "enum":
        member = value if isinstance(value, f.enum) else f.enum.parse(str(value))
        numbers = dict(f.items())
        if member.value not in numbers:
            raise ValueError(f"{f.label}: {member.value} is not allowed (choices: {', '.join(numbers)})")
        return member.value if rna else numbers[member.value]
    if f.kind == "flags":
        mask = frozenset(value)
        if not mask <= frozenset(CHANNELS):
            raise ValueError(f"{f.label}: {sorted(mask)} is not a subset of RGBA")
        return set(mask) if rna else color_mask_bits(mask)
    if f.kind in ("color", "vector"):
        out = tuple(float(v) for v in value)
        if len(out) != f.size:
            raise ValueError(f"{f.label}: expected {f.size} numbers, got {len(out)}")
        return out if rna else list(_as_float32(out))  # RNA stores float32: so does this
    if f.kind == "bool":
        return bool(value)
    if f.kind == "int":
        number = int(value)
        if number != value or (f.min is not None and number < f.min) or (f.max is not None and number > f.max):
            raise ValueError(f"{f.label}: {value!r} is not an integer in the allowed range")
        if f.choices and number not in f.choices:
            raise ValueError(f"{f.label}: {value!r} is not one of {', '.join(str(c) for c in f.choices)}")
        return number
    if f.kind == "float":
        return float(value) if rna else _as_float32(float(value))
    if f.kind == "string":
        return str(value)
    if f.kind == "image":
        if value is not None and not hasattr(value, "bl_rna"):
            raise ValueError(f"{f.label}: expected a Blender image or None, got {type(value).__name__}")
        return value
    raise ValueError(f"cannot write a {f.kind} field")


def _pass_field(p: Pass, name: str) -> Any:
    """The value of :data:`PASS_FIELDS` field ``name`` for ``p`` (the outline colour's switch and
    its colour, black when off, stand for the core's ``outline_color`` or None)."""
    if name == "outline_colored":
        return p.outline_color is not None
    if name == "outline_color" and p.outline_color is None:
        return _BY_NAME["pass"][name].default
    return getattr(p, name)


def _encode_pass(p: Pass | Mapping[str, Any], rna: bool) -> dict[str, Any]:
    if not isinstance(p, Pass):
        p = pass_from_values(dict(p))
    return {f.name: _encode(f, _pass_field(p, f.name), rna) for f in PASS_FIELDS}


def _encode_values(kind: str, values: Mapping[str, Any], rna: bool) -> dict[str, Any]:
    table = _BY_NAME[kind]
    unknown = sorted(set(values) - set(table))
    if unknown:
        raise ValueError(f"unknown {kind} setting(s): {', '.join(unknown)}")
    out = {}
    for name, value in values.items():
        f = table[name]
        out[name] = [_encode_pass(p, rna) for p in value] if f.kind == "passes" else _encode(f, value, rna)
    return out


def _registered(id_block: Any) -> Any:
    group = getattr(id_block, "unity", None)
    return group if group is not None and hasattr(group, "bl_rna") else None


def _assign(id_block: Any, kind: str, values: Mapping[str, Any]) -> None:
    """Validate every value first (nothing is written on a bad one), bring the stored group to
    the current version, then assign through RNA (registered) or the stored ID properties."""
    group = _registered(id_block)
    encoded = _encode_values(kind, values, rna=group is not None)
    migrate_stored(id_block)
    if group is not None:
        for name, value in encoded.items():
            if name == "passes":
                group.passes.clear()
                for item_values in value:
                    item = group.passes.add()
                    for key, v in item_values.items():
                        setattr(item, key, v)
                if hasattr(group, "active_pass_index"):
                    group.active_pass_index = 0
            else:
                setattr(group, name, value)
        setattr(group, VERSION_KEY, SCHEMA_VERSION)
        return
    store = _system_store(id_block, create=True)
    if store.get("unity") is None:
        store["unity"] = {}
    stored = store["unity"]
    for name, value in encoded.items():
        if value is None:  # an empty image pointer: nothing stored
            if name in stored:
                del stored[name]
        else:
            stored[name] = value
    stored[VERSION_KEY] = SCHEMA_VERSION


def material_fields(material: Material) -> dict[str, Any]:
    """The ``Material.unity`` values of a :class:`Material`: every schema field it holds except
    the textures (a :class:`~blendlib.core.vocabulary.Texture` is pixels, not a Blender image)."""
    names = {f.name for f in MATERIAL_FIELDS}
    return {f.name: getattr(material, f.name) for f in fields(Material)
            if f.name in names and f.name not in ("main_tex", "outline_width_tex")}


def write_material(mat: Any, material: Material | None = None, **values: Any) -> None:
    """Write ``Material.unity`` of a ``bpy.types.Material``: the fields of ``material`` (all but
    ``main_tex``, see :func:`material_fields`), then ``values`` by :data:`MATERIAL_FIELDS` name
    (enum members or identifiers, channel sets, ``main_tex`` a ``bpy.types.Image`` or None,
    ``passes`` :class:`Pass` objects or dicts of pass values). Fields not given keep their values.

    ValueError names a bad value; nothing is written then. Writing ``passes`` replaces the
    whole pass list and selects the first pass.
    """
    merged = ({} if material is None else material_fields(material)) | values
    _assign(mat, "material", merged)


def write_pass(item: Any, p: Pass) -> None:
    """Write every field of ``p`` into one registered pass property group (an item of
    ``Material.unity.passes``); the owning material's group is brought to the current version."""
    encoded = _encode_pass(p, rna=True)
    owner = getattr(item, "id_data", None)
    if owner is not None:
        migrate_stored(owner)
    for key, value in encoded.items():
        setattr(item, key, value)
    if owner is not None:
        stamp_version(owner)


def write_scene_settings(scene: Any, **values: Any) -> None:
    """Write ``Scene.unity`` of a ``bpy.types.Scene`` by :data:`SCENE_FIELDS` name (enum members or
    identifiers, numbers, colours); fields not given keep their values. ValueError: nothing written."""
    _assign(scene, "scene", values)


def write_light_settings(light: Any, **values: Any) -> None:
    """Write ``Light.unity`` of a ``bpy.types.Light`` by :data:`LIGHT_FIELDS` name; fields not given keep
    their values. ValueError: nothing written."""
    _assign(light, "light", values)


# Versions


def stamp_version(id_block: Any) -> None:
    """Record that ``id_block``'s stored Unity settings are of the current schema version (the
    add-on calls this when a property is edited; the writers do it themselves)."""
    group = _registered(id_block)
    if group is not None:
        if getattr(group, VERSION_KEY, SCHEMA_VERSION) != SCHEMA_VERSION:
            setattr(group, VERSION_KEY, SCHEMA_VERSION)
        return
    stored = stored_group(id_block)
    if stored is not None:
        stored[VERSION_KEY] = SCHEMA_VERSION


def _apply_changes(target: Any, old: Any, new: Any) -> None:
    """Write into the stored group ``target`` the leaves where ``new`` differs from ``old``."""
    for key, value in new.items():
        before = old.get(key) if isinstance(old, Mapping) else None
        if isinstance(value, Mapping) and isinstance(before, Mapping):
            _apply_changes(target[key], before, value)
        elif isinstance(value, list) and isinstance(before, list) and len(value) == len(before) \
                and all(isinstance(v, Mapping) for v in value):
            for i, (b, v) in enumerate(zip(before, value, strict=True)):
                _apply_changes(target[key][i], b, v)
        elif value != before:
            target[key] = value


def migrate_stored(id_block: Any) -> bool:
    """Bring the stored Unity settings of a material or scene to the current schema version, in
    place. Returns whether anything was migrated. Linked (library) data is left alone: the
    readers migrate it as they read."""
    stored = stored_group(id_block)
    if stored is None or stored_version(stored) >= SCHEMA_VERSION:
        return False
    if getattr(id_block, "library", None) is not None:
        return False
    migrate = {"Scene": migrate_scene, "Light": migrate_light}.get(_rna_base(id_block), migrate_material)
    old = stored.to_dict() if hasattr(stored, "to_dict") else dict(stored)
    _apply_changes(stored, old, migrate(old))
    return True


def _rna_base(id_block: Any) -> str | None:
    """``"Scene"``, ``"Light"`` (any light type: PointLight, SpotLight, ...), ``"Material"`` or None."""
    rna = getattr(id_block, "bl_rna", None)
    while rna is not None:
        if rna.identifier in ("Scene", "Light", "Material"):
            return rna.identifier
        rna = rna.base
    return None


def migrate_data(data: Any) -> int:
    """Migrate every material, scene and light of ``bpy.data`` (or a like object); returns how many changed."""
    lights = getattr(data, "lights", ())
    return sum(migrate_stored(block) for block in (*data.materials, *data.scenes, *lights))
