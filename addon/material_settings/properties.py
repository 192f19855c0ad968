"""``Material.unity`` and ``Scene.unity``: bpy properties built from the schema in :mod:`blendlib.blender`.

The schema (names, defaults, enum item numbers) lives next to the code that reads
stored values back without the add-on, so the two can never disagree.

Each group also stores ``schema_version``. Editing any property records the current
version (:func:`blendlib.blender.stamp_version`); :mod:`.migration` brings the settings of
files saved by older versions to the current one as they load.
"""

from __future__ import annotations

import bpy

from blendlib.blender import (
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
}


def enum_items(f: Field) -> list[tuple[str, str, str, int]]:
    return [(ident, ident, _ITEM_NOTES.get(ident, f"{f.label} {ident}"), number) for ident, number in f.items()]


def _edited(self, context) -> None:
    """Update callback of every property: the owner's settings are now of the current version."""
    stamp_version(self.id_data)


def make_property(f: Field, pass_type=None):
    kw = {"name": f.label, "description": f.description}
    if f.kind != "passes":
        kw["update"] = _edited
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


UnityPassSettings.__annotations__ = {f.name: make_property(f) for f in PASS_FIELDS}
UnityMaterialSettings.__annotations__ = {f.name: make_property(f, UnityPassSettings) for f in MATERIAL_FIELDS}
UnityMaterialSettings.__annotations__["active_pass_index"] = bpy.props.IntProperty(
    name="Active Pass", description="Pass selected in the list", default=0, min=0)
UnitySceneSettings.__annotations__ = {f.name: make_property(f) for f in SCENE_FIELDS}
for _group in (UnityMaterialSettings, UnitySceneSettings):
    _group.__annotations__[VERSION_KEY] = bpy.props.IntProperty(
        name="Schema Version", default=FIRST_VERSION, min=FIRST_VERSION, options={"HIDDEN"},
        description=(f"Version of the stored settings' format (current: {SCHEMA_VERSION}; absent: "
                     f"{FIRST_VERSION}, saved by add-on 0.1); older settings are migrated when a file loads"))

CLASSES = (UnityPassSettings, UnityMaterialSettings, UnitySceneSettings)


def attach() -> None:
    """Add ``Material.unity`` and ``Scene.unity`` (the groups of :data:`CLASSES` must be registered)."""
    bpy.types.Material.unity = bpy.props.PointerProperty(
        type=UnityMaterialSettings, name="Unity Material", description="Unity built-in pipeline material settings")
    bpy.types.Scene.unity = bpy.props.PointerProperty(
        type=UnitySceneSettings, name="Unity Camera", description="Unity built-in pipeline frame settings")


def detach() -> None:
    for owner in (bpy.types.Scene, bpy.types.Material):
        if hasattr(owner, "unity"):
            del owner.unity
