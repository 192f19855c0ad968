"""The VRM Add-on for Blender's MToon settings as the JSON its exporters write (bpy-free).

A material of the add-on (``material.vrm_addon_extension.mtoon1``) draws in Unity as UniVRM draws
the add-on's export, and which export depends on the armature's ``spec_version`` (0 or absent:
VRM 0.x, 1: VRM 1.0; the lead's decision). :func:`export_document` writes the one material as that
exporter writes it, as a small glTF document that :func:`~.importer.import_material` then maps
like any file — so a ``.blend`` and its own export give the same Unity state by construction, and
the tests check this module against the add-on's real exports (``shared/corpus/vrm-addon/``).

VRM 0.x (``vrm0_exporter.py``, ``write_mtoon1_downgraded_material``; research-vrm §6.2)::

    OPAQUE:        _BlendMode 0  _SrcBlend 1 _DstBlend 0  _ZWrite 1  renderQueue -1
    MASK:          _BlendMode 1  _SrcBlend 1 _DstBlend 0  _ZWrite 1  _ALPHATEST_ON  renderQueue mtoon0_render_queue
                   _Cutoff alpha_cutoff
    BLEND:         _BlendMode 2  _SrcBlend 5 _DstBlend 10 _ZWrite 0  renderQueue mtoon0_render_queue
    BLEND + TZW:   _BlendMode 3  _SrcBlend 5 _DstBlend 10 _ZWrite 1  renderQueue mtoon0_render_queue
    keyword_map["_ALPHABLEND_ON"] = material.blend_method not in ("OPAQUE", "CLIP")
    _CullMode 1 if mtoon0_front_cull_mode, elif use_backface_culling 2, else 0;  _OutlineCullMode 1
    _OutlineWidthMode 0/1/2 and MTOON_OUTLINE_WIDTH_WORLD / _SCREEN by outline_width_mode
    _OutlineWidth = outline_width_factor * 100 (world) / * 200 (screen) / 0.0 (none); _OutlineScaledMaxDistance
    vector_properties["_Color"] = convert.linear_to_srgb(base_color_factor)   (x ** (1 / 2.2))
    vector_properties["_OutlineColor"] = convert.linear_to_srgb(outline_color_factor) + [1]
    _OutlineLightingMix = outline_lighting_mix_factor; _OutlineColorMode = 1 if that mix > 0 else 0
    and with an outline MTOON_OUTLINE_COLOR_MIXED / _FIXED by it (none: mix 0, mode 0, no keyword)

``blend_method`` follows the add-on's alpha mode in the Blender versions it was written for
(OPAQUE, CLIP, BLEND/HASHED); Blender 4.2 and later read every material's ``blend_method`` as
HASHED or BLEND, so ``_ALPHABLEND_ON`` is derived here from the alpha mode (the corpus files,
exported from Blender 2.93, agree; an export made in Blender ≥ 4.2 may set it on every material —
docs/vrm.md). The offset and scale of ``_MainTex`` are the base colour texture's
``KHR_texture_transform`` flipped to Unity's UV space, ``(ox, 1 − oy − sy, sx, sy)``.

VRM 1.0 (``vrm1_exporter.py``, ``create_mtoon1_material_dict``): ``alphaMode``, ``alphaCutoff`` (MASK
only), ``doubleSided``, ``baseColorFactor``/``baseColorTexture`` with its ``KHR_texture_transform``,
``KHR_materials_unlit`` and ``VRMC_materials_mtoon`` with ``transparentWithZWrite``,
``renderQueueOffsetNumber`` (unclamped: UniVRM's validator clamps it), ``outlineWidthMode``,
``outlineWidthFactor``, ``outlineColorFactor`` and ``outlineLightingMixFactor``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .container import GltfDocument, document_from_json
from .importer import import_material
from .records import ImportedMaterial

ALPHA_MODES = ("OPAQUE", "MASK", "BLEND")
OUTLINE_WIDTH_MODES = ("none", "worldCoordinates", "screenCoordinates")


@dataclass(frozen=True)
class AddonTexture:
    """The base colour texture of an add-on material: ``image`` (any key; the Blender layer passes the
    image), its sampler numbers as the add-on stores them (GL constants) and its texture transform."""

    image: Any
    mag_filter: int = 9728
    min_filter: int = 9728
    wrap_s: int = 10497
    wrap_t: int = 10497
    offset: tuple[float, float] = (0.0, 0.0)
    scale: tuple[float, float] = (1.0, 1.0)


@dataclass(frozen=True)
class AddonMToon:
    """The MToon settings of one add-on material that decide what Unity draws (the add-on's defaults)."""

    name: str
    alpha_mode: str = "OPAQUE"
    alpha_cutoff: float = 0.5
    double_sided: bool = False
    transparent_with_z_write: bool = False
    render_queue_offset_number: int = 0
    outline_width_mode: str = "none"
    outline_width_factor: float = 0.0
    #: ``outline_color_factor`` (linear RGB; the add-on's default black).
    outline_color_factor: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: ``outline_lighting_mix_factor`` (the add-on's default 1, VRMC_materials_mtoon's).
    outline_lighting_mix_factor: float = 1.0
    base_color_factor: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    base_color_texture: AddonTexture | None = None
    #: ``outline_width_multiply_texture`` (exported as 0.x ``_OutlineWidthTexture``, 1.0
    #: ``outlineWidthMultiplyTexture``; its transform is exported but MToon samples it at the base
    #: colour texture's coordinates).
    outline_width_multiply_texture: AddonTexture | None = None
    mtoon0_render_queue: int = 2000
    mtoon0_front_cull_mode: bool = False
    mtoon0_outline_scaled_max_distance: float = 1.0
    addon_version: tuple[int, int, int] = (0, 0, 0)
    #: Where each value was read from (the add-on's version rules), for the panel and the docs.
    sources: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.alpha_mode not in ALPHA_MODES:
            raise ValueError(f"material {self.name!r}: unknown VRM Add-on alpha mode {self.alpha_mode!r}")
        if self.outline_width_mode not in OUTLINE_WIDTH_MODES:
            raise ValueError(f"material {self.name!r}: unknown VRM Add-on outline width mode "
                             f"{self.outline_width_mode!r}")

    @property
    def render_mode(self) -> str:
        """The add-on's render mode as its panel names it."""
        if self.alpha_mode == "OPAQUE":
            return "Opaque"
        if self.alpha_mode == "MASK":
            return "Cutout"
        return "Transparent With Z-Write" if self.transparent_with_z_write else "Transparent"


def _srgb_gamma(value: float) -> float:
    # The add-on's convert.linear_to_srgb: the 2.2 power (0.25 → 0.5325205447199813 in the corpus export).
    return max(0.0, float(value)) ** (1 / 2.2)


def _texture_json(mtoon: AddonMToon) -> tuple[list, list, list, dict[str, int]]:
    """(images, samplers, textures) arrays for the base colour and outline-width textures (those the
    material has), and the texture index of each by role (``"base"``, ``"width"``)."""
    images, samplers, textures, index = [], [], [], {}
    for role, texture in (("base", mtoon.base_color_texture), ("width", mtoon.outline_width_multiply_texture)):
        if texture is None:
            continue
        index[role] = len(textures)
        samplers.append({"magFilter": texture.mag_filter, "minFilter": texture.min_filter,
                         "wrapS": texture.wrap_s, "wrapT": texture.wrap_t})
        images.append({"name": role})
        textures.append({"source": index[role], "sampler": index[role]})
    return images, samplers, textures, index


def _vrm0_entry(mtoon: AddonMToon, index: dict[str, int]) -> dict[str, Any]:
    floats: dict[str, float] = {"_Cutoff": 0.5}
    keywords: dict[str, bool] = {}
    if mtoon.alpha_mode == "OPAQUE":
        floats |= {"_BlendMode": 0, "_SrcBlend": 1, "_DstBlend": 0, "_ZWrite": 1}
        queue = -1
    elif mtoon.alpha_mode == "MASK":
        floats |= {"_BlendMode": 1, "_SrcBlend": 1, "_DstBlend": 0, "_ZWrite": 1, "_Cutoff": mtoon.alpha_cutoff}
        keywords["_ALPHATEST_ON"] = True
        queue = mtoon.mtoon0_render_queue
    elif not mtoon.transparent_with_z_write:
        floats |= {"_BlendMode": 2, "_SrcBlend": 5, "_DstBlend": 10, "_ZWrite": 0}
        queue = mtoon.mtoon0_render_queue
    else:
        floats |= {"_BlendMode": 3, "_SrcBlend": 5, "_DstBlend": 10, "_ZWrite": 1, "_Cutoff": mtoon.alpha_cutoff}
        queue = mtoon.mtoon0_render_queue
    keywords["_ALPHABLEND_ON"] = mtoon.alpha_mode == "BLEND"
    if mtoon.mtoon0_front_cull_mode:
        floats["_CullMode"] = 1
    else:
        floats["_CullMode"] = 0 if mtoon.double_sided else 2
    floats["_OutlineCullMode"] = 1
    mode = OUTLINE_WIDTH_MODES.index(mtoon.outline_width_mode)
    floats["_OutlineWidthMode"] = mode
    floats["_OutlineWidth"] = 0.0  # the exporter's value without an outline (vrm0_exporter.py)
    if mode == 1:
        keywords["MTOON_OUTLINE_WIDTH_WORLD"] = True
        floats["_OutlineWidth"] = mtoon.outline_width_factor * 100
    elif mode == 2:
        keywords["MTOON_OUTLINE_WIDTH_SCREEN"] = True
        floats["_OutlineWidth"] = mtoon.outline_width_factor * 200
    floats["_OutlineScaledMaxDistance"] = mtoon.mtoon0_outline_scaled_max_distance
    mixed = mtoon.outline_lighting_mix_factor > 0
    floats["_OutlineLightingMix"] = mtoon.outline_lighting_mix_factor if mode else 0.0
    floats["_OutlineColorMode"] = 1 if mixed and mode else 0
    if mode:
        keywords["MTOON_OUTLINE_COLOR_MIXED" if mixed else "MTOON_OUTLINE_COLOR_FIXED"] = True
    r, g, b, a = mtoon.base_color_factor
    vectors: dict[str, list[float]] = {"_Color": [_srgb_gamma(r), _srgb_gamma(g), _srgb_gamma(b), float(a)],
                                       "_OutlineColor": [*(_srgb_gamma(c) for c in mtoon.outline_color_factor), 1.0]}
    textures: dict[str, int] = {}
    texture = mtoon.base_color_texture
    if texture is not None:
        textures["_MainTex"] = index["base"]
        (ox, oy), (sx, sy) = texture.offset, texture.scale
        vectors["_MainTex"] = [ox, 1.0 - oy - sy, sx, sy]
    if "width" in index:
        textures["_OutlineWidthTexture"] = index["width"]
    return {"name": mtoon.name, "shader": "VRM/MToon", "renderQueue": queue, "floatProperties": floats,
            "keywordMap": keywords, "vectorProperties": vectors, "textureProperties": textures}


def vrm1_material_json(mtoon: AddonMToon, index: dict[str, int]) -> dict[str, Any]:
    """The glTF material the add-on's VRM 1.0 exporter writes for ``mtoon`` (texture indices by role)."""
    base: dict[str, Any] = {"baseColorFactor": list(mtoon.base_color_factor)}
    texture = mtoon.base_color_texture
    if texture is not None:
        base["baseColorTexture"] = {"index": index["base"], "extensions": {"KHR_texture_transform": {
            "offset": list(texture.offset), "scale": list(texture.scale)}}}
    material: dict[str, Any] = {
        "name": mtoon.name, "alphaMode": mtoon.alpha_mode, "doubleSided": mtoon.double_sided,
        "pbrMetallicRoughness": base,
        "extensions": {"KHR_materials_unlit": {}, "VRMC_materials_mtoon": {
            "specVersion": "1.0", "transparentWithZWrite": mtoon.transparent_with_z_write,
            "renderQueueOffsetNumber": mtoon.render_queue_offset_number,
            "outlineWidthMode": mtoon.outline_width_mode, "outlineWidthFactor": mtoon.outline_width_factor,
            "outlineColorFactor": list(mtoon.outline_color_factor),
            "outlineLightingMixFactor": mtoon.outline_lighting_mix_factor}},
    }
    if "width" in index:
        material["extensions"]["VRMC_materials_mtoon"]["outlineWidthMultiplyTexture"] = {"index": index["width"]}
    if mtoon.alpha_mode == "MASK":
        material["alphaCutoff"] = mtoon.alpha_cutoff
    return material


def export_document(mtoon: AddonMToon, spec_version: str) -> GltfDocument:
    """The one-material document the add-on's exporter for ``spec_version`` (``"0.x"``/``"1.0"``) writes."""
    images, samplers, textures, index = _texture_json(mtoon)
    data: dict[str, Any] = {"asset": {"version": "2.0", "generator": "Unity Passes: VRM Add-on settings"},
                            "images": images, "samplers": samplers, "textures": textures}
    if spec_version == "0.x":
        material = {"name": mtoon.name, "alphaMode": mtoon.alpha_mode, "doubleSided": mtoon.double_sided,
                    "extensions": {"KHR_materials_unlit": {}}}
        data |= {"materials": [material], "extensions": {"VRM": {"materialProperties": [_vrm0_entry(mtoon, index)]}}}
    elif spec_version == "1.0":
        data |= {"materials": [vrm1_material_json(mtoon, index)], "extensions": {"VRMC_vrm": {"specVersion": "1.0"}}}
    else:
        raise ValueError(f"unknown VRM spec version {spec_version!r} (expected 0.x or 1.0)")
    return document_from_json(data, f"<VRM Add-on material {mtoon.name!r}>")


def addon_material(mtoon: AddonMToon, spec_version: str) -> ImportedMaterial:
    """The Unity state UniVRM draws ``mtoon`` with, after the add-on's ``spec_version`` export;
    ``main_tex`` / ``outline_width_tex`` index the textures of :func:`export_document` (their images:
    :func:`texture_images`)."""
    document = export_document(mtoon, spec_version)
    return import_material(document, 0, spec_version)


def texture_images(mtoon: AddonMToon, imported: ImportedMaterial) -> tuple[Any, Any]:
    """(the ``_MainTex`` image, the outline-width image) of :func:`addon_material`'s result: the
    images of ``mtoon``'s textures the imported material uses (None where it uses none)."""
    base = mtoon.base_color_texture.image if imported.main_tex is not None else None
    width = mtoon.outline_width_multiply_texture.image if imported.outline_width_tex is not None else None
    return base, width
