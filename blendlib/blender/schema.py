"""The one schema of the Unity settings stored in Blender: ``Material.unity`` and ``Scene.unity``.

The add-on builds its bpy properties from the field tables here, and everything that
reads the stored settings goes through :func:`read_group`, so names, defaults and the
integers Blender stores for enum items agree everywhere. When the add-on is not
registered, the settings are read from the stored ID properties
(``bl_system_properties_get()``); absent values take the defaults of the data model.

This module does not import bpy at module level.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.vocabulary import (
    CHANNELS,
    BlendFactor,
    BlendOp,
    ColorSpace,
    CompareFunction,
    Cull,
    Lighting,
    Pass,
    Queue,
    SortMode,
    StencilOp,
    TextureFilter,
    TextureWrap,
    pass_from_dict,
)


@dataclass(frozen=True)
class Field:
    """One add-on property.

    ``kind``: ``bool``, ``int``, ``float``, ``enum``, ``flags``, ``color``, ``vector``,
    ``string``, ``image`` or ``passes``. Enum items are stored by Blender as the index
    of the member in its :mod:`blendlib.shaderlab` enum class (``enum_items`` may
    list a subset, e.g. ZTest without ``Never``); ``flags`` (ColorMask) as bits
    R=1, G=2, B=4, A=8.
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

    def items(self):
        """``(identifier, number)`` pairs of an enum field, in display order."""
        members = self.enum_items or tuple(self.enum)
        return [(m.value, list(self.enum).index(m)) for m in members]


FLAG_BITS = {c: 1 << i for i, c in enumerate(CHANNELS)}


_FACTOR_DOC = "Blend factor"


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
    Field("main_tex_filter", "enum", "Bilinear", "Filter", "Sampler filter mode (no mipmaps)", enum=TextureFilter),
    Field("main_tex_wrap", "enum", "Repeat", "Wrap", "Sampler wrap mode", enum=TextureWrap),
    Field("alpha_scale", "float", 1.0, "_AlphaScale", "_AlphaScale: multiplies the alpha", min=0.0, max=1.0,
          subtype="FACTOR"),
    Field("cutoff", "float", 0.5, "_Cutoff", "_Cutoff: alpha-tested passes discard alpha < _Cutoff", min=0.0,
          max=1.0, subtype="FACTOR"),
    Field("lighting", "enum", "Lambert", "Lighting",
          "Lambert: the book's ForwardBase fragment (ambient + main light); Unlit: albedo only", enum=Lighting),
    Field("passes", "passes", (), "Passes", "Passes drawn in order (none = one default pass)"),
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
)


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
        bits = int(raw)
        return frozenset(c for c, b in FLAG_BITS.items() if bits & b)
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
    """Plain dict of a property group: ``source`` is an RNA PropertyGroup, a stored IDPropertyGroup,
    a dict, or None (all defaults). Passes come back as a list of dicts."""
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


def unity_props(id_block: Any) -> Any:
    """``id_block.unity`` when the add-on is registered, else its stored group (or None)."""
    group = getattr(id_block, "unity", None)
    if group is not None and hasattr(group, "bl_rna"):
        return group
    getter = getattr(id_block, "bl_system_properties_get", None)
    if getter is not None:
        store = getter()
        return None if store is None else store.get("unity")
    try:  # Blender < 5.0 keeps add-on properties with the custom properties
        return id_block.get("unity")
    except (AttributeError, TypeError):
        return None


def pass_from_values(values: dict[str, Any]) -> Pass:
    """A :class:`Pass` from a dict of :data:`PASS_FIELDS` values (identifiers, set colour mask)."""
    return pass_from_dict({k: (sorted(v) if k == "color_mask" else v) for k, v in values.items()})



def scene_settings(scene: Any) -> dict[str, Any]:
    """``Scene.unity`` as a dict of identifiers (defaults where absent)."""
    return read_group(unity_props(scene), SCENE_FIELDS)

