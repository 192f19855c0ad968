"""``Material.unity`` and ``Scene.unity``: bpy properties built from the schema in :mod:`blendlib.blender`.

The schema (names, defaults, enum item numbers) lives next to the code that reads
stored values back without the add-on, so the two can never disagree.
"""

from __future__ import annotations

import bpy

from blendlib.blender import FLAG_BITS, MATERIAL_FIELDS, PASS_FIELDS, SCENE_FIELDS, Field
from blendlib.core.vocabulary import QUEUE_NUMBERS, Queue

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


def make_property(f: Field, pass_type=None):
    kw = {"name": f.label, "description": f.description}
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
        items = [(c, c, f"Write the {c} channel", bit) for c, bit in FLAG_BITS.items()]
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
    """Material.unity: the Unity material (SPEC §3)."""


class UnitySceneSettings(bpy.types.PropertyGroup):
    """Scene.unity: Unity camera / player settings (SPEC §3)."""


UnityPassSettings.__annotations__ = {f.name: make_property(f) for f in PASS_FIELDS}
UnityMaterialSettings.__annotations__ = {f.name: make_property(f, UnityPassSettings) for f in MATERIAL_FIELDS}
UnityMaterialSettings.__annotations__["active_pass_index"] = bpy.props.IntProperty(
    name="Active Pass", description="Pass selected in the list", default=0, min=0)
UnitySceneSettings.__annotations__ = {f.name: make_property(f) for f in SCENE_FIELDS}

CLASSES = (UnityPassSettings, UnityMaterialSettings, UnitySceneSettings)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Material.unity = bpy.props.PointerProperty(
        type=UnityMaterialSettings, name="Unity Material", description="Unity built-in pipeline material settings")
    bpy.types.Scene.unity = bpy.props.PointerProperty(
        type=UnitySceneSettings, name="Unity Camera", description="Unity built-in pipeline frame settings")


def unregister() -> None:
    for owner in (bpy.types.Scene, bpy.types.Material):
        if hasattr(owner, "unity"):
            del owner.unity
    for cls in reversed(CLASSES):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
