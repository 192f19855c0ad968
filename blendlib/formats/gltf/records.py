"""What an import gives per material (:class:`ImportedMaterial`) and per file (:class:`GltfImport`),
their JSON record, and the small readers the material importers share."""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field
from typing import Any

from ...core import colorspace
from ...core.vocabulary import Material
from ..shaderlab import material_record, parse_queue

#: The one warning of every import (SPEC §11.6): the colour is approximated, the rest is exact.
SHADING_APPROXIMATION = ("MToon and PBR shading are approximated by Lambert of _Color x _MainTex; "
                         "render order, coverage and blending are as Unity draws them")


class MaterialError(ValueError):
    """A material value Unity would not take; the importer turns it into one GltfError line."""


@dataclass(frozen=True)
class ImportedMaterial:
    """One glTF material as Unity draws it.

    ``material``: the :class:`~blendlib.core.vocabulary.Material` (named as the glTF material, no
    texture pixels); ``main_tex``: the glTF texture index that is ``_MainTex`` (None: white);
    ``importer``: which of UniVRM's importers took it (e.g. ``"VRM 0.x VRM/MToon"``); ``extra``:
    what the material says beyond the Unity settings (shader, render queue number, MToon's render
    mode and outline); ``warnings``: one line each, naming the material.
    """

    index: int
    material: Material
    main_tex: int | None
    importer: str
    warnings: tuple[str, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)
    #: The glTF texture index that is MToon's outline-width texture (None: none, ×1), and its
    #: encoding: ``"sRGB"`` (VRM 0.x imports it as a colour texture) or ``"Data"`` (VRM 1.0: linear).
    outline_width_tex: int | None = None
    outline_width_encoding: str = "sRGB"

    def record(self) -> dict[str, Any]:
        """The material's JSON record: THE record ``shaderlab --json`` prints
        (:func:`blendlib.formats.shaderlab.material_record`)."""
        return material_record(self.material.name, self.material, self.warnings, self.extra)


@dataclass(frozen=True)
class GltfImport:
    """A file's materials as Unity draws them (index order) and the import's warnings."""

    path: str
    vrm: str | None  # "0.x", "1.0" or None (plain glTF)
    materials: tuple[ImportedMaterial, ...]
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The JSON of ``python -m blendlib import --json``: the file, its VRM version, one material
        record per material (with its glTF ``index`` and ``importer``), and the warnings."""
        records = []
        for imported in self.materials:
            records.append({"index": imported.index, "importer": imported.importer} | imported.record())
        return {"file": self.path, "vrm": self.vrm, "materials": records, "warnings": list(self.warnings)}


# --------------------------------------------------------------------------- shared readers


def f32(value: float) -> float:
    """``value`` rounded to float32: Unity's material floats, colours and vectors are float32 (so are
    the values Blender stores)."""
    try:
        return struct.unpack("<f", struct.pack("<f", float(value)))[0]
    except OverflowError:
        return math.copysign(math.inf, value)


def number(value: Any, what: str) -> float:
    """A finite JSON number, as the float32 Unity keeps; MaterialError otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise MaterialError(f"{what} is not a number ({value!r})")
    rounded = f32(value)
    if not math.isfinite(rounded):
        raise MaterialError(f"{what} {value!r} is too large for a float32")
    return rounded


def queue_fields(number_value: int, what: str) -> dict[str, Any]:
    """``queue`` and ``queue_offset`` of a render-queue number (the nearest named queue at or below it
    plus an offset, as ShaderLab import writes ``"Queue"="2450"``); MaterialError outside Unity's
    0..5000."""
    if not 0 <= number_value <= 5000:
        raise MaterialError(f"{what} {number_value} is outside Unity's render queues 0..5000")
    queue, offset = parse_queue(str(int(number_value)))
    return {"queue": queue, "queue_offset": offset}


def gamma_color(factor: Any, what: str, default=(1.0, 1.0, 1.0, 1.0)) -> tuple[float, float, float, float]:
    """A glTF linear RGBA factor as a Unity colour property (sRGB-encoded RGB, alpha as is), as
    UniGLTF converts ``baseColorFactor`` (``ToColor4(ColorSpace.Linear, ColorSpace.sRGB)``)."""
    r, g, b, a = rgba_values(factor, what, default)
    return (f32(colorspace.encode(r)), f32(colorspace.encode(g)), f32(colorspace.encode(b)), a)


def rgba_values(value: Any, what: str, default=(1.0, 1.0, 1.0, 1.0)) -> tuple[float, float, float, float]:
    """Four finite numbers (a colour as stored); ``default`` when absent; MaterialError otherwise."""
    if value is None:
        return tuple(default)
    if not isinstance(value, list) or len(value) != 4:
        raise MaterialError(f"{what} is not four numbers ({value!r})")
    r, g, b, a = (number(v, what) for v in value)
    return (r, g, b, a)
