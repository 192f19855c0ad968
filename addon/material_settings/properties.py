"""``Material.unity``, ``Scene.unity`` and ``Light.unity``: bpy properties built from the schema in
:mod:`blendlib.blender`.

The schema (names, defaults, enum item numbers) lives next to the code that reads
stored values back without the add-on, so the two can never disagree.

Each group also stores ``schema_version``. Editing any property records the current
version (:func:`blendlib.blender.stamp_version`); :mod:`.migration` brings the settings of
files saved by older versions to the current one as they load.
"""

from __future__ import annotations

import bpy

from blendlib.blender import (
    LIGHT_FIELDS,
    MATERIAL_FIELDS,
    PASS_FIELDS,
    SCENE_FIELDS,
    SCHEMA_VERSION,
    Field,
    stamp_version,
)
from blendlib.blender.migration import FIRST_VERSION, VERSION_KEY
from blendlib.core.vocabulary import COLOR_MASK_BITS, QUEUE_NUMBERS, Queue

_ITEM_NOTES = {
    **{q.value: f"{q.value} = {QUEUE_NUMBERS[q]}" for q in Queue},
    "Background": "Background = 1000: drawn first, front to back",
    "Geometry": "Geometry = 2000: opaque objects, front to back",
    "AlphaTest": "AlphaTest = 2450: alpha-tested objects, front to back",
    "Transparent": "Transparent = 3000: blended objects, back to front",
    "Overlay": "Overlay = 4000: drawn last, back to front",
    "Gamma": "Gamma: no conversions; blending on sRGB-encoded values",
    "Linear": "Linear: decode sRGB inputs, blend in linear space, store sRGB-encoded (sRGB framebuffer)",
    "Default": "Perspective for perspective cameras, Orthographic for orthographic ones",
    "Perspective": "Distance from the camera to each object's bounds centre",
    "Orthographic": "Depth along the camera's view axis",
    "CustomAxis": "Position along the Sort Axis",
    "Lambert": "Ambient + main light x max(0, N.L) (the book's ForwardBase fragment)",
    "Unlit": "Albedo only",
    "Trilinear": "Bilinear within the two nearest mip levels, blended (Bilinear without mipmaps)",
    "Multiply": "Albedo and alpha x the vertex colour (Sprites, UI, fixed-function primary)",
    "Particle": "2 x vertex colour x _TintColor x texture (the legacy particle shaders)",
    "Always": "Always: drawn once",
    "ForwardBase": "ForwardBase: drawn once, with the main directional light",
    "ForwardAdd": "ForwardAdd: drawn once per additional per-pixel light",
    "Vertex": "Vertex: drawn only when the material has no ForwardBase/ForwardAdd pass (legacy Vertex Lit)",
    "Other": "A LightMode the forward rendering path does not know: never drawn",
    "Auto": "Per-pixel by importance, within the Pixel Light Count",
    "Important": "Always per-pixel",
    "NotImportant": "Never per-pixel (vertex/SH lights are not drawn by Unity Passes)",
}


def enum_items(f: Field) -> list[tuple[str, str, str, int]]:
    return [(ident, ident, _ITEM_NOTES.get(ident, f"{f.label} {ident}"), number) for ident, number in f.items()]


def _edited(self, context) -> None:
    """Update callback of every property: the owner's settings are now of the current version."""
    stamp_version(self.id_data)


def _snapped(f: Field):
    """Update callback of an int field with ``choices`` (MSAA 1, 2, 4, 8): a value between two
    choices snaps down to the lower one (3 → 2, 7 → 4), then the version is stamped."""

    def update(self, context) -> None:
        value = getattr(self, f.name)
        if value not in f.choices:
            setattr(self, f.name, max((c for c in f.choices if c <= value), default=min(f.choices)))
            return  # the assignment calls this again with an allowed value
        stamp_version(self.id_data)

    return update


def make_property(f: Field, pass_type=None):
    kw = {"name": f.label, "description": f.description}
    if f.kind != "passes":
        kw["update"] = _snapped(f) if f.choices else _edited
    limits = {k: getattr(f, k) for k in ("min", "max", "soft_min", "soft_max") if getattr(f, k) is not None}
    if f.kind == "bool":
        return bpy.props.BoolProperty(default=f.default, **kw)
    if f.kind == "int":
        return bpy.props.IntProperty(default=f.default, **{k: int(v) for k, v in limits.items()}, **kw)
    if f.kind == "float":
        return bpy.props.FloatProperty(default=f.default, subtype=f.subtype, **limits, **kw)
    if f.kind == "enum":
        return bpy.props.EnumProperty(items=enum_items(f), default=f.default, **kw)
    if f.kind == "flags":
        items = [(c, c, f"Write the {c} channel", bit) for c, bit in COLOR_MASK_BITS.items()]
        return bpy.props.EnumProperty(items=items, default=set(f.default), options={"ENUM_FLAG"}, **kw)
    if f.kind in ("color", "vector"):
        return bpy.props.FloatVectorProperty(size=f.size, default=f.default, subtype=f.subtype, **limits, **kw)
    if f.kind == "string":
        return bpy.props.StringProperty(default=f.default, **kw)
    if f.kind == "image":
        return bpy.props.PointerProperty(type=bpy.types.Image, **kw)
    if f.kind == "passes":
        return bpy.props.CollectionProperty(type=pass_type, **kw)
    raise ValueError(f"unknown field kind {f.kind!r}")


class UnityPassSettings(bpy.types.PropertyGroup):
    """One ShaderLab Pass { } of a Unity material."""


class UnityMaterialSettings(bpy.types.PropertyGroup):
    """Material.unity: the Unity material (README "Data model")."""


class UnitySceneSettings(bpy.types.PropertyGroup):
    """Scene.unity: Unity camera / player settings (README "Data model")."""


class UnityLightSettings(bpy.types.PropertyGroup):
    """Light.unity: the light as a Unity forward light (README "Data model")."""


UnityPassSettings.__annotations__ = {f.name: make_property(f) for f in PASS_FIELDS}
UnityMaterialSettings.__annotations__ = {f.name: make_property(f, UnityPassSettings) for f in MATERIAL_FIELDS}
UnityMaterialSettings.__annotations__["active_pass_index"] = bpy.props.IntProperty(
    name="Active Pass", description="Pass selected in the list", default=0, min=0)
UnitySceneSettings.__annotations__ = {f.name: make_property(f) for f in SCENE_FIELDS}
UnityLightSettings.__annotations__ = {f.name: make_property(f) for f in LIGHT_FIELDS}
for _group in (UnityMaterialSettings, UnitySceneSettings, UnityLightSettings):
    _group.__annotations__[VERSION_KEY] = bpy.props.IntProperty(
        name="Schema Version", default=FIRST_VERSION, min=FIRST_VERSION, options={"HIDDEN"},
        description=(f"Version of the stored settings' format (current: {SCHEMA_VERSION}; absent: "
                     f"{FIRST_VERSION}, saved by add-on 0.1); older settings are migrated when a file loads"))

CLASSES = (UnityPassSettings, UnityMaterialSettings, UnitySceneSettings, UnityLightSettings)


def attach() -> None:
    """Add ``Material.unity``, ``Scene.unity`` and ``Light.unity`` (the groups of :data:`CLASSES` must be
    registered)."""
    bpy.types.Material.unity = bpy.props.PointerProperty(
        type=UnityMaterialSettings, name="Unity Material", description="Unity built-in pipeline material settings")
    bpy.types.Scene.unity = bpy.props.PointerProperty(
        type=UnitySceneSettings, name="Unity Camera", description="Unity built-in pipeline frame settings")
    bpy.types.Light.unity = bpy.props.PointerProperty(
        type=UnityLightSettings, name="Unity Light", description="The light as a Unity forward light")


def detach() -> None:
    for owner in (bpy.types.Light, bpy.types.Scene, bpy.types.Material):
        if hasattr(owner, "unity"):
            del owner.unity
