"""VRM 1.0 materials with ``VRMC_materials_mtoon`` as UniVRM's built-in importer sets them: the glTF
``alphaMode`` / ``alphaCutoff`` / ``doubleSided`` and the extension's values through MToon's
validator (``MToonValidator.cs`` @8a7d0a82, ``SetUnityShaderPassSettings``)::

    Opaque:                     One  Zero              ZWrite On   AlphaToMask Off  queue 2000 (offset forced to 0)
    Cutout (MASK):              One  Zero              ZWrite On   AlphaToMask On   queue 2450 (offset forced to 0)
    Transparent (BLEND):        SrcAlpha OneMinusSrcAlpha ZWrite Off AlphaToMask Off
                                renderQueueOffset = Mathf.Clamp(renderQueueOffset, -9, 0); queue 3000 + offset
    BLEND + transparentWithZWrite: SrcAlpha OneMinusSrcAlpha ZWrite On AlphaToMask Off
                                renderQueueOffset = Mathf.Clamp(renderQueueOffset, 0, +9);
                                queue RenderQueue.GeometryLast + 1 + offset (2501 + offset)
    doubleSided: _CullMode Off, else Back; the outline pass is always Cull Front.

Keywords: ``_ALPHATEST_ON`` for Cutout, ``_ALPHABLEND_ON`` for Transparent, the outline keyword
from ``outlineWidthMode``. Missing values: ``alphaMode`` OPAQUE (an unknown one too, with a
warning), ``alphaCutoff`` 0.5, ``renderQueueOffsetNumber`` 0, ``transparentWithZWrite`` false,
``outlineWidthMode`` none (VRMC_materials_mtoon schema). ``_Color`` is ``baseColorFactor``
converted to gamma, ``_MainTex`` the ``baseColorTexture`` with its ``KHR_texture_transform``.
"""

from __future__ import annotations

from typing import Any

from ...core.vocabulary import BlendFactor, Cull, Lighting, Material
from .container import GltfDocument
from .mtoon import (
    BLEND_CLIP_MTOON1,
    OUTLINE_NONE,
    OUTLINE_SCREEN,
    OUTLINE_WORLD,
    mtoon_passes,
    outline_colour,
    outline_width_sampler,
)
from .records import ImportedMaterial, MaterialError, gamma_color, number, queue_fields
from .unigltf import alpha_cutoff, alpha_mode, base_color_texture

EXTENSION = "VRMC_materials_mtoon"
OUTLINE_MODES = {"none": OUTLINE_NONE, "worldCoordinates": OUTLINE_WORLD, "screenCoordinates": OUTLINE_SCREEN}


def validated_queue(mode: str, transparent_with_zwrite: bool, offset: int) -> tuple[int, int, str]:
    """(render queue, offset after the validator's clamp, MToon render mode) for a glTF ``mode``."""
    if mode == "OPAQUE":
        return 2000, 0, "Opaque"
    if mode == "MASK":
        return 2450, 0, "Cutout"
    if not transparent_with_zwrite:
        clamped = max(-9, min(0, offset))
        return 3000 + clamped, clamped, "Transparent"
    clamped = max(0, min(9, offset))
    return 2501 + clamped, clamped, "TransparentWithZWrite"


def _outline_color(mtoon: dict[str, Any], where: str) -> tuple[float, float, float]:
    """``outlineColorFactor`` (linear RGB; the schema's default ``[0, 0, 0]``)."""
    value = mtoon.get("outlineColorFactor", [0.0, 0.0, 0.0])
    if not isinstance(value, list) or len(value) != 3:
        raise MaterialError(f"{where}: {EXTENSION}.outlineColorFactor is not three numbers ({value!r})")
    r, g, b = (number(v, f"{where}: {EXTENSION}.outlineColorFactor") for v in value)
    return r, g, b


def _outline_colour_fields(mtoon: dict[str, Any], where: str, warnings: list[str]) -> dict[str, Any]:
    """The outline pass's colour: ``outlineColorFactor`` as UniVRM sets ``_OutlineColor`` (linear →
    gamma, as ``_Color``) and ``outlineLightingMixFactor`` (the schema's default 1)."""
    r, g, b, _ = gamma_color([*_outline_color(mtoon, where), 1.0], f"{where}: {EXTENSION}.outlineColorFactor")
    mix = number(mtoon.get("outlineLightingMixFactor", 1.0), f"{where}: {EXTENSION}.outlineLightingMixFactor")
    colour, mix = outline_colour((r, g, b), mix, where, warnings)
    return {"outline_color": colour, "outline_lighting_mix": mix}


def vrm1_material(document: GltfDocument, index: int) -> ImportedMaterial:
    """Material ``index`` (which has ``VRMC_materials_mtoon``) as UniVRM 1.0 draws it."""
    material = document.list("materials")[index]
    name = material.get("name") if isinstance(material.get("name"), str) else f"Material_{index}"
    where = f"material {name!r}"
    mtoon = material["extensions"][EXTENSION]
    if not isinstance(mtoon, dict):
        raise MaterialError(f"{where}: {EXTENSION} is not an object")
    warnings: list[str] = []
    mode = alpha_mode(material, where, warnings)
    zwrite_flag = mtoon.get("transparentWithZWrite", False)
    if not isinstance(zwrite_flag, bool):
        raise MaterialError(f"{where}: {EXTENSION}.transparentWithZWrite is not true or false ({zwrite_flag!r})")
    raw_offset = number(mtoon.get("renderQueueOffsetNumber", 0), f"{where}: {EXTENSION}.renderQueueOffsetNumber")
    if raw_offset != int(raw_offset):
        raise MaterialError(f"{where}: {EXTENSION}.renderQueueOffsetNumber {raw_offset:g} is not an integer")
    queue, offset, render_mode = validated_queue(mode, zwrite_flag, int(raw_offset))
    outline_word = mtoon.get("outlineWidthMode", "none")
    outline = OUTLINE_MODES.get(outline_word)
    if outline is None:
        warnings.append(f"{where}: unknown outlineWidthMode {outline_word!r}; imported as none")
        outline = OUTLINE_NONE
    width = number(mtoon.get("outlineWidthFactor", 0.0), f"{where}: {EXTENSION}.outlineWidthFactor")
    double_sided = material.get("doubleSided", False) is True
    blend = mode == "BLEND"
    passes = mtoon_passes(
        version="1.0", cull=Cull.Off if double_sided else Cull.Back, outline_cull=Cull.Front,
        src=BlendFactor.SrcAlpha if blend else BlendFactor.One,
        dst=BlendFactor.OneMinusSrcAlpha if blend else BlendFactor.Zero,
        zwrite=not blend or zwrite_flag, alpha_to_mask=mode == "MASK", alpha_test=mode != "OPAQUE",
        outline_mode=outline, outline_width=width,
        **_outline_colour_fields(mtoon, where, warnings))
    texture, fields = base_color_texture(document, material, where, warnings)
    color = gamma_color((material.get("pbrMetallicRoughness") or {}).get("baseColorFactor"),
                        f"{where}.baseColorFactor")
    extra: dict[str, Any] = {
        "shader": "VRM10/MToon10", "render_queue": queue, "render_mode": render_mode, "alpha_mode": mode,
        "double_sided": double_sided, "transparent_with_z_write": zwrite_flag,
        "render_queue_offset_number": int(raw_offset), "render_queue_offset_validated": offset,
        "_Color": list(color),
        "outline": {"mode": outline, "width": width,
                    "width_world_m": width if outline == OUTLINE_WORLD else None, "formula": "1.0",
                    "color": list(_outline_color(mtoon, where))}}
    if mode == "OPAQUE":
        color = color[:3] + (1.0,)  # MToon writes alpha 1 without an alpha keyword
    cutoff = alpha_cutoff(material, where) if mode == "MASK" else BLEND_CLIP_MTOON1 if blend else 0.5
    width_tex = None
    width_info = mtoon.get("outlineWidthMultiplyTexture")
    if outline != OUTLINE_NONE and isinstance(width_info, dict) and width_info.get("index") is not None:
        # UniVRM imports it linear and samples it at _MainTex's coordinates (its own transform unused).
        width_tex = int(width_info["index"])
        fields |= outline_width_sampler(document, width_tex, where, warnings)
    out = Material(name=name, color=color, cutoff=cutoff, lighting=Lighting.Lambert, passes=passes,
                   **queue_fields(queue, f"{where}: render queue"), **fields)
    return ImportedMaterial(index, out, texture, "VRM 1.0 VRMC_materials_mtoon", tuple(warnings), extra,
                            width_tex, "Data")
