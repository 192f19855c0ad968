"""Migration of the stored Unity settings (``Material.unity``, ``Scene.unity``) between schema versions.

The integers Blender stores for the add-on's properties are a file format. Each
``Material.unity`` and ``Scene.unity`` group stores the version of that format in
``schema_version``; a group without it was saved by version 0.1 of the add-on
(schema version 1). Reading a group, or loading a file with the add-on registered,
migrates older values with the pure functions here.

Versions:

1. (0.1) ColorMask bits R=1, G=2, B=4, A=8.
2. ColorMask bits as Unity's ``ColorWriteMask``, A=1, B=2, G=4, R=8
   (:data:`blendlib.core.vocabulary.COLOR_MASK_BITS`); ``schema_version`` stored.
3. SPEC §12's names appended: per pass ``alpha_to_mask``, ``alpha_test_comp`` and
   ``light_mode``; per material ``main_tex_mipmaps``, ``main_tex_preserve_coverage``,
   ``vertex_color``, ``tint_color`` and the filter item ``Trilinear`` (appended, so the stored
   numbers of Bilinear and Point stay); per scene ``msaa`` and ``pixel_light_count``; the new
   ``Light.unity`` group. Nothing stored changes meaning: values absent from a version-2 group
   take defaults that draw as before (ForwardBase passes, GEqual alpha test, no mipmaps, no
   vertex colour, one sample), so the step only stamps the version.
4. MToon's outline colour appended per pass: ``outline_colored``, ``outline_color``,
   ``outline_lighting_mix``; per material the outline-width texture ``outline_width_tex``,
   ``outline_width_tex_filter``, ``outline_width_tex_wrap``. Absent from a version-3 group, the
   switch is off and there is no texture: the pass draws the material's lit colour and the
   outline its full width, as before; the step only stamps the version.

This module does not import bpy.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from ..core.vocabulary import color_mask_bits

#: The version the writers store and the readers expect.
SCHEMA_VERSION = 4

#: Name of the stored version in ``Material.unity`` and ``Scene.unity``.
VERSION_KEY = "schema_version"

#: The version of a group that stores none: saved by version 0.1.
FIRST_VERSION = 1

_V1_COLOR_MASK_BITS = {"R": 1, "G": 2, "B": 4, "A": 8}


def stored_version(values: Mapping[str, Any] | None) -> int:
    """The schema version of stored values (a dict or an ID property group; None: nothing stored)."""
    if values is None:
        return FIRST_VERSION
    version = values.get(VERSION_KEY)
    return FIRST_VERSION if version is None else int(version)


def _material_1_to_2(values: dict[str, Any]) -> dict[str, Any]:
    for item in values.get("passes") or ():
        if "color_mask" in item:
            bits = int(item["color_mask"])
            item["color_mask"] = color_mask_bits(frozenset(c for c, b in _V1_COLOR_MASK_BITS.items() if bits & b))
    return values


def _unchanged(values: dict[str, Any]) -> dict[str, Any]:
    return values


#: ``version -> function`` that turns stored values of that version into the next version's.
MATERIAL_STEPS: dict[int, Callable[[dict[str, Any]], dict[str, Any]]] = {1: _material_1_to_2, 2: _unchanged,
                                                                         3: _unchanged}
SCENE_STEPS: dict[int, Callable[[dict[str, Any]], dict[str, Any]]] = {1: _unchanged, 2: _unchanged, 3: _unchanged}
#: ``Light.unity`` is new in version 3: a group stored without a version holds version-3 values.
LIGHT_STEPS: dict[int, Callable[[dict[str, Any]], dict[str, Any]]] = {1: _unchanged, 2: _unchanged, 3: _unchanged}


def _copy(value: Any) -> Any:
    """A copy of nested dicts and lists; leaves (numbers, strings, ID references) are shared."""
    if isinstance(value, Mapping):
        return {k: _copy(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_copy(v) for v in value]
    return value


def _migrate(values: Mapping[str, Any] | None, steps: dict, what: str) -> dict[str, Any]:
    out = _copy(values or {})
    version = stored_version(out)
    if version > SCHEMA_VERSION:
        raise ValueError(f"{what} settings have schema version {version}; this version of the add-on reads "
                         f"up to {SCHEMA_VERSION}: update the add-on")
    while version < SCHEMA_VERSION:
        out = steps[version](out)
        version += 1
    out[VERSION_KEY] = SCHEMA_VERSION
    return out


def migrate_material(values: Mapping[str, Any] | None) -> dict[str, Any]:
    """Stored ``Material.unity`` values (a plain dict, any version) → a new dict of the current version.

    Values are as stored: enum items and ColorMask as integers, passes as a list of dicts.
    """
    return _migrate(values, MATERIAL_STEPS, "material")


def migrate_scene(values: Mapping[str, Any] | None) -> dict[str, Any]:
    """Stored ``Scene.unity`` values (any version) → a new dict of the current version."""
    return _migrate(values, SCENE_STEPS, "scene")


def migrate_light(values: Mapping[str, Any] | None) -> dict[str, Any]:
    """Stored ``Light.unity`` values → a new dict of the current version."""
    return _migrate(values, LIGHT_STEPS, "light")
