"""A ``.vrm`` file's MToon materials as the VRM Add-on for Blender's MToon settings (bpy-free).

Importing a ``.vrm`` (the lead's decision, issue 28), an MToon material gets the settings the VRM
Add-on keeps (:class:`~.vrm_addon.AddonMToon`) instead of Unity settings, so that it goes through
the one path the add-on's own ``.blend`` files use: the Unity Material panel's line, sort advice in
VRM terms (``renderQueueOffsetNumber`` within MToon's clamp, ``mtoon0_render_queue``), and Apply
Advice writing the add-on's settings, which its exporter carries.

:func:`addon_mtoon_of` reads the settings back from the file's values, inverting what the add-on's
exporters write (:mod:`.vrm_addon`'s docstring):

* VRM 1.0: ``alphaMode``, ``alphaCutoff``, ``doubleSided``, ``baseColorFactor``, the base colour
  texture (its sampler, its ``KHR_texture_transform``), ``transparentWithZWrite``,
  ``renderQueueOffsetNumber`` (as stored: UniVRM's validator clamps it on both paths),
  ``outlineWidthMode``, ``outlineWidthFactor``, ``outlineColorFactor``, ``outlineLightingMixFactor``,
  ``outlineWidthMultiplyTexture``;
* VRM 0.x: the alpha mode from the keywords (``_ALPHATEST_ON`` MASK, ``_ALPHABLEND_ON`` BLEND,
  with ``_ZWrite`` 1 Transparent With Z-Write), ``renderQueue`` as ``mtoon0_render_queue``,
  ``_CullMode`` (1: ``mtoon0_front_cull_mode``, 0: double sided), ``_Color`` and ``_OutlineColor``
  as ``factor ** (1 / 2.2)`` (so ``factor = value ** 2.2``), ``_OutlineWidth`` / 100 (world) or /
  200 (screen), the outline colour keyword and ``_OutlineLightingMix``, ``_MainTex`` with its
  ``[ox, 1 − oy − sy, sx, sy]``, ``_OutlineWidthTexture``.

The add-on cannot hold every file: a VRM 0.x file may state a combination its exporter never
writes (``_OutlineCullMode`` 0, ``_AlphaToMask`` 1, an outline without a colour keyword,
``VRM/UnlitTransparentZWrite``, ...). So the settings are kept only when the add-on's export of them
gives exactly the state the direct import gave (:func:`addon_mtoon_of` checks it): same Material
(queue, passes with cull, ZWrite, blend, alpha test and outline with its colour, colour, cutoff,
``_MainTex`` settings, outline-width texture settings), same textures. The others keep Unity
settings, with a warning naming what differs.
"""

from __future__ import annotations

from dataclasses import fields, replace
from typing import Any

from .container import GltfDocument
from .records import ImportedMaterial
from .textures import LINEAR, LINEAR_MIPMAP_LINEAR, NEAREST, REPEAT
from .vrm1 import EXTENSION as MTOON1
from .vrm_addon import OUTLINE_WIDTH_MODES, AddonMToon, AddonTexture, addon_material

#: The outline modes of the import records (``extra.outline.mode``) by the add-on's names.
_OUTLINE_NAMES = {"none": "none", "world": "worldCoordinates", "screen": "screenCoordinates"}


def _texture(document: GltfDocument, index: int | None, tiling_offset: tuple | None = None) -> AddonTexture | None:
    """An :class:`AddonTexture` for glTF texture ``index`` (its ``image`` the index itself: the
    Blender layer puts the image in), its sampler as stored (none: UniGLTF's default, which LINEAR /
    LINEAR_MIPMAP_LINEAR / REPEAT give) and ``tiling_offset`` = ((ox, oy), (sx, sy)) in glTF's UV space."""
    if index is None:
        return None
    sampler = document.texture_sampler(index)
    if sampler is None:
        mag, minf, wrap_s, wrap_t = LINEAR, LINEAR_MIPMAP_LINEAR, REPEAT, REPEAT
    else:
        mag, minf = sampler.get("magFilter", NEAREST), sampler.get("minFilter", NEAREST)
        wrap_s, wrap_t = sampler.get("wrapS", REPEAT), sampler.get("wrapT", REPEAT)
    offset, scale = tiling_offset or ((0.0, 0.0), (1.0, 1.0))
    return AddonTexture(image=index, mag_filter=mag, min_filter=minf, wrap_s=wrap_s, wrap_t=wrap_t,
                        offset=offset, scale=scale)


def _gltf_transform(info: dict[str, Any]) -> tuple:
    transform = (info.get("extensions") or {}).get("KHR_texture_transform") or {}
    return tuple(float(v) for v in transform.get("offset", (0.0, 0.0))), \
        tuple(float(v) for v in transform.get("scale", (1.0, 1.0)))


def _vrm1(document: GltfDocument, imported: ImportedMaterial) -> AddonMToon:
    material = document.list("materials")[imported.index]
    mtoon = material["extensions"][MTOON1]
    extra = imported.extra
    base = material.get("pbrMetallicRoughness") or {}
    info = base.get("baseColorTexture")
    texture = _texture(document, imported.main_tex, _gltf_transform(info) if isinstance(info, dict) else None)
    return AddonMToon(
        name=imported.material.name, alpha_mode=extra["alpha_mode"],
        alpha_cutoff=float(material.get("alphaCutoff", 0.5)), double_sided=extra["double_sided"],
        transparent_with_z_write=extra["transparent_with_z_write"],
        render_queue_offset_number=extra["render_queue_offset_number"],
        outline_width_mode=_OUTLINE_NAMES[extra["outline"]["mode"]],
        outline_width_factor=float(extra["outline"]["width"]),
        outline_color_factor=tuple(float(c) for c in extra["outline"]["color"]),
        outline_lighting_mix_factor=float(mtoon.get("outlineLightingMixFactor", 1.0)),
        base_color_factor=tuple(float(c) for c in base.get("baseColorFactor", (1.0, 1.0, 1.0, 1.0))),
        base_color_texture=texture, outline_width_multiply_texture=_texture(document, imported.outline_width_tex))


def _linear(value: float) -> float:
    """The add-on's factor whose ``convert.linear_to_srgb`` (``x ** (1 / 2.2)``) is ``value``."""
    return max(0.0, float(value)) ** 2.2


def _vrm0(document: GltfDocument, imported: ImportedMaterial) -> AddonMToon:
    entry = document.json["extensions"]["VRM"]["materialProperties"][imported.index]
    floats = entry.get("floatProperties") or {}
    vectors = entry.get("vectorProperties") or {}
    keywords = {k for k, v in (entry.get("keywordMap") or {}).items() if v is True}
    alpha_mode = "MASK" if "_ALPHATEST_ON" in keywords else "BLEND" if "_ALPHABLEND_ON" in keywords else "OPAQUE"
    cull = floats.get("_CullMode", 2)
    outline = imported.extra["outline"]
    mode = _OUTLINE_NAMES[outline["mode"]]
    divisor = {"none": 1.0, "worldCoordinates": 100.0, "screenCoordinates": 200.0}[mode]
    mixed = "MTOON_OUTLINE_COLOR_MIXED" in keywords
    color = vectors.get("_Color") or [1.0, 1.0, 1.0, 1.0]
    outline_color = outline.get("color") or [0.0, 0.0, 0.0, 1.0]
    texture = None
    if imported.main_tex is not None:
        ox, oy, sx, sy = (float(v) for v in vectors.get("_MainTex") or (0.0, 0.0, 1.0, 1.0))
        texture = _texture(document, imported.main_tex, ((ox, 1.0 - oy - sy), (sx, sy)))
    return AddonMToon(
        name=imported.material.name, alpha_mode=alpha_mode, alpha_cutoff=float(floats.get("_Cutoff", 0.5)),
        double_sided=cull == 0, transparent_with_z_write=alpha_mode == "BLEND" and floats.get("_ZWrite", 1) == 1,
        outline_width_mode=mode, outline_width_factor=float(outline.get("width", 0.0)) / divisor,
        outline_color_factor=tuple(_linear(c) for c in outline_color[:3]),
        outline_lighting_mix_factor=float(floats.get("_OutlineLightingMix", 1.0)) if mixed else 0.0,
        base_color_factor=(*(_linear(c) for c in color[:3]), float(color[3])), base_color_texture=texture,
        outline_width_multiply_texture=_texture(document, imported.outline_width_tex),
        mtoon0_render_queue=int(imported.extra["render_queue"]), mtoon0_front_cull_mode=cull == 1,
        mtoon0_outline_scaled_max_distance=float(floats.get("_OutlineScaledMaxDistance", 1.0)))


def differences(a: ImportedMaterial, b: ImportedMaterial) -> list[str]:
    """What of the Unity state differs between two imports of one material (empty: nothing)."""
    out = [f.name for f in fields(a.material) if f.name != "name"
           and getattr(a.material, f.name) != getattr(b.material, f.name)]
    for name in ("main_tex", "outline_width_tex"):
        if (getattr(a, name) is None) != (getattr(b, name) is None):
            out.append(name)
    if a.outline_width_tex is not None and a.outline_width_encoding != b.outline_width_encoding:
        out.append("outline_width_encoding")
    return out


def addon_mtoon_of(document: GltfDocument, imported: ImportedMaterial, vrm: str | None
                   ) -> tuple[AddonMToon | None, str | None]:
    """(the VRM Add-on settings whose ``vrm`` export UniVRM draws as ``imported``, None) for an MToon
    material of a ``.vrm`` (VRM 0.x ``VRM/MToon``, VRM 1.0 ``VRMC_materials_mtoon``); (None, why) when
    the add-on cannot hold it (module docstring); (None, None) for any other material."""
    if vrm == "1.0" and imported.importer.startswith("VRM 1.0"):
        mtoon = _vrm1(document, imported)
    elif vrm == "0.x" and imported.importer == "VRM 0.x VRM/MToon":
        mtoon = _vrm0(document, imported)
    else:
        return None, None
    if mtoon.outline_width_mode not in OUTLINE_WIDTH_MODES:
        return None, f"material {mtoon.name!r}: outline mode {mtoon.outline_width_mode!r}"
    differ = differences(addon_material(mtoon, vrm), imported)
    if differ:
        return None, (f"material {mtoon.name!r}: the VRM Add-on's MToon settings cannot state this material "
                      f"({', '.join(differ)} would differ after its export); it keeps Unity settings")
    return mtoon, None


def with_images(mtoon: AddonMToon, image_of) -> AddonMToon:
    """``mtoon`` with each texture's ``image`` (a glTF texture index) replaced by ``image_of(index)``."""
    out = {}
    for name in ("base_color_texture", "outline_width_multiply_texture"):
        texture = getattr(mtoon, name)
        if texture is not None:
            out[name] = replace(texture, image=image_of(texture.image))
    return replace(mtoon, **out)
