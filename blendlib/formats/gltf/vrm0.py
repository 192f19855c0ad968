"""VRM 0.x materials (``extensions.VRM.materialProperties[i]``, paired with ``materials[i]``) as
UniVRM's legacy loader sets them — the loader VSeeFace and VMagicMirror use (the lead's decision).

UniVRM copies what the file stores (research-vrm §1.2; ``BuiltInVrmMToonMaterialImporter.cs``
@d6699b56, applied by ``MaterialFactory.cs`` @fcb4f184): ``floatProperties`` by ``SetFloat`` (no
clamping; no ``ValidateProperties``), ``renderQueue`` as stored (−1 or absent: the shader's queue,
MToon's ``"Queue" = "Geometry"``), keywords from ``keywordMap`` only, ``_MainTex``'s offset and
scale from ``vectorProperties["_MainTex"]`` = [offset x, offset y, scale x, scale y] in Unity's UV
space (set with the texture, so only when ``textureProperties["_MainTex"]`` exists). Missing floats
take MToon's Properties defaults (``MToon.shader`` @1499e25a)::

    _Cutoff 0.5  _BlendMode 0  _OutlineWidthMode 0  _CullMode 2.0  _OutlineCullMode 1.0
    _SrcBlend 1.0  _DstBlend 0.0  _ZWrite 1.0  _AlphaToMask 0.0  _OutlineWidth 0.5
    _OutlineScaledMaxDistance 1  _OutlineColorMode 0  _OutlineLightingMix 1

The importer order (``BuiltInVrmMaterialDescriptorGenerator.cs`` @58f2f7ff): the legacy
``VRM/UnlitTransparentZWrite`` first, then any shader name except ``VRM_USE_GLTFSHADER`` (which
falls back to UniGLTF, :mod:`.unigltf`), with ``FallbackShaders`` renaming ``VRM/UnlitTexture`` →
``Unlit/Texture``, ``VRM/UnlitTransparent`` → ``Unlit/Transparent``, ``VRM/UnlitCutout`` →
``Unlit/Transparent Cutout``, ``UniGLTF/StandardVColor`` → ``UniGLTF/UniUnlit``. Colours in
``vectorProperties`` are Unity colour values (gamma): ``_Color`` is taken as is.
"""

from __future__ import annotations

from typing import Any

from ...core.vocabulary import BlendFactor, Cull, Lighting, LightMode, Material, Pass, VertexColor
from ..shaderlab.state import _CULL_BY_NUMBER, _FACTOR_BY_NUMBER
from .container import GltfDocument
from .mtoon import (
    BLEND_CLIP_MTOON0,
    OUTLINE_NONE,
    OUTLINE_SCREEN,
    OUTLINE_WORLD,
    mtoon_passes,
    outline_colour,
    outline_width_sampler,
)
from .records import ImportedMaterial, MaterialError, number, queue_fields, rgba_values
from .textures import sampler_settings
from .unigltf import standard_passes, uniunlit_pass

MTOON = "VRM/MToon"
UNLIT_TRANSPARENT_ZWRITE = "VRM/UnlitTransparentZWrite"
USE_GLTF_SHADER = "VRM_USE_GLTFSHADER"

#: MToon 0.x's Properties defaults that decide the state (MToon.shader).
MTOON_DEFAULTS = {"_Cutoff": 0.5, "_BlendMode": 0.0, "_OutlineWidthMode": 0.0, "_CullMode": 2.0,
                  "_OutlineCullMode": 1.0, "_SrcBlend": 1.0, "_DstBlend": 0.0, "_ZWrite": 1.0,
                  "_AlphaToMask": 0.0, "_OutlineWidth": 0.5, "_OutlineScaledMaxDistance": 1.0,
                  "_OutlineColorMode": 0.0, "_OutlineLightingMix": 1.0}
#: MToon 0.x's ``_OutlineColor ("Outline Color", Color) = (0,0,0,1)``.
OUTLINE_COLOR_DEFAULT = (0.0, 0.0, 0.0, 1.0)
#: UniUnlit's Properties defaults (UniUnlit.shader).
UNIUNLIT_DEFAULTS = {"_Cutoff": 0.5, "_CullMode": 2.0, "_SrcBlend": 1.0, "_DstBlend": 0.0, "_ZWrite": 1.0}
#: Standard's (corpus DefaultResourcesExtra/Standard.shader: ``_Cutoff`` 0.5, ``_SrcBlend`` 1.0,
#: ``_DstBlend`` 0.0, ``_ZWrite`` 1.0).
STANDARD_DEFAULTS = {"_Cutoff": 0.5, "_SrcBlend": 1.0, "_DstBlend": 0.0, "_ZWrite": 1.0}

#: MToon 0.x's ``RenderMode`` numbers (``_BlendMode``).
RENDER_MODES = {0: "Opaque", 1: "Cutout", 2: "Transparent", 3: "TransparentWithZWrite"}

FALLBACK_SHADERS = {"VRM/UnlitTexture": "Unlit/Texture", "VRM/UnlitTransparent": "Unlit/Transparent",
                    "VRM/UnlitCutout": "Unlit/Transparent Cutout", "UniGLTF/StandardVColor": "UniGLTF/UniUnlit"}


class _Properties:
    """One ``materialProperties`` entry: its floats over a shader's defaults, its keywords, its queue."""

    def __init__(self, entry: dict[str, Any], where: str, defaults: dict[str, float]):
        self.entry, self.where = entry, where
        floats = entry.get("floatProperties") or {}
        keywords = entry.get("keywordMap") or {}
        if not isinstance(floats, dict) or not isinstance(keywords, dict):
            raise MaterialError(f"{where}: floatProperties and keywordMap must be objects")
        self.floats = defaults | {k: number(v, f"{where}: floatProperties.{k}") for k, v in floats.items()}
        self.keywords = {k for k, v in keywords.items() if v is True}

    def float(self, key: str) -> float:
        return self.floats[key]

    def enum(self, key: str, table: dict[int, Any], what: str) -> Any:
        """A float read as Unity's ``(int)`` of it through an enum ``table``; MaterialError outside it."""
        value = self.floats[key]
        member = table.get(int(value))
        if member is None:
            choices = ", ".join(f"{n} {m}" for n, m in table.items())
            raise MaterialError(f"{self.where}: {key} {value:g} is not a {what} ({choices})")
        return member

    def queue(self, shader_queue: int) -> tuple[int, dict[str, Any]]:
        """The render-queue number (−1 or absent: ``shader_queue``) and its Material fields."""
        raw = self.entry.get("renderQueue", -1)
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise MaterialError(f"{self.where}: renderQueue is not an integer ({raw!r})")
        value = shader_queue if raw == -1 else raw
        return value, queue_fields(value, f"{self.where}: renderQueue")

    def vector(self, key: str) -> Any:
        return (self.entry.get("vectorProperties") or {}).get(key)

    def texture(self, key: str) -> int | None:
        return (self.entry.get("textureProperties") or {}).get(key)


def _main_tex(document: GltfDocument, props: _Properties, warnings: list[str], with_st: bool = True
              ) -> tuple[int | None, dict[str, Any]]:
    """(texture index, ``_MainTex`` fields) of ``textureProperties["_MainTex"]`` with its sampler and
    ``vectorProperties["_MainTex"]`` as tiling/offset (``with_st``)."""
    texture = props.texture("_MainTex")
    if texture is None:
        return None, {}
    fields = sampler_settings(document.texture_sampler(texture), f"{props.where}: texture {texture}", warnings)
    vector = props.vector("_MainTex")
    if with_st and vector is not None:
        ox, oy, sx, sy = rgba_values(vector, f"{props.where}: vectorProperties._MainTex")
        fields |= {"main_tex_tiling": (sx, sy), "main_tex_offset": (ox, oy)}
    return texture, fields


def _outline_mode(props: _Properties, warnings: list[str]) -> str:
    """The outline pass's mode. The shader reads the keyword (``MTOON_OUTLINE_WIDTH_WORLD`` /
    ``_SCREEN``, set from ``keywordMap`` only); ``_OutlineWidthMode`` (0 none, 1 world, 2 screen) is
    what the inspector derives the keyword from, and a file where the two disagree gets a warning."""
    keywords = props.keywords
    if "MTOON_OUTLINE_WIDTH_WORLD" in keywords:
        outline = OUTLINE_WORLD
    elif "MTOON_OUTLINE_WIDTH_SCREEN" in keywords:
        outline = OUTLINE_SCREEN
    else:
        outline = OUTLINE_NONE
    stated = {0: OUTLINE_NONE, 1: OUTLINE_WORLD, 2: OUTLINE_SCREEN}.get(int(props.float("_OutlineWidthMode")))
    if stated != outline:
        warnings.append(f"{props.where}: _OutlineWidthMode {props.float('_OutlineWidthMode'):g} disagrees with the "
                        f"keywords (outline {outline}); UniVRM sets the keywords from keywordMap, so the "
                        f"outline is {outline}")
    return outline


def _outline_colour(props: _Properties, outline: str, warnings: list[str]
                    ) -> tuple[tuple[float, float, float] | None, float]:
    """(outline colour, lighting mix) of the outline pass. The shader reads the keyword:
    ``MTOON_OUTLINE_COLOR_FIXED`` the colour alone (mix 0), ``MTOON_OUTLINE_COLOR_MIXED`` the colour
    times ``lerp(1, lit, _OutlineLightingMix)``, neither the lit colour (None); ``_OutlineColorMode``
    (0 fixed, 1 mixed) is what the inspector derives them from: a keyword it disagrees with gets a
    warning."""
    keywords = props.keywords
    mode = "fixed" if "MTOON_OUTLINE_COLOR_FIXED" in keywords else \
        "mixed" if "MTOON_OUTLINE_COLOR_MIXED" in keywords else "none"
    if outline != OUTLINE_NONE and mode != "none":
        stated = {0: "fixed", 1: "mixed"}.get(int(props.float("_OutlineColorMode")))
        if stated != mode:
            warnings.append(f"{props.where}: _OutlineColorMode {props.float('_OutlineColorMode'):g} disagrees with "
                            f"the keywords (outline colour {mode}); UniVRM sets the keywords from keywordMap, so "
                            f"the outline colour is {mode}")
    if mode == "none":
        return None, 0.0
    rgba = rgba_values(props.vector("_OutlineColor"), f"{props.where}: vectorProperties._OutlineColor",
                       OUTLINE_COLOR_DEFAULT)
    return outline_colour(rgba, props.float("_OutlineLightingMix") if mode == "mixed" else 0.0, props.where,
                          warnings)


def _mtoon(document: GltfDocument, index: int, name: str, props: _Properties, warnings: list[str]
           ) -> ImportedMaterial:
    where = props.where
    keywords = props.keywords
    alpha_test_on, alpha_blend_on = "_ALPHATEST_ON" in keywords, "_ALPHABLEND_ON" in keywords
    if alpha_test_on and alpha_blend_on:
        warnings.append(f"{where}: keywords _ALPHATEST_ON and _ALPHABLEND_ON are both on (one multi_compile set: "
                        "Unity does not document which variant draws); imported as _ALPHATEST_ON")
        alpha_blend_on = False
    outline = _outline_mode(props, warnings)
    outline_color, outline_mix = _outline_colour(props, outline, warnings)
    queue, queue_values = props.queue(2000)
    texture, fields = _main_tex(document, props, warnings)
    color = rgba_values(props.vector("_Color"), f"{where}: vectorProperties._Color")
    cutoff = props.float("_Cutoff")
    if alpha_blend_on:
        cutoff = BLEND_CLIP_MTOON0
    elif not alpha_test_on:
        color = color[:3] + (1.0,)  # MToon writes alpha 1 without an alpha keyword
    passes = mtoon_passes(
        version="0.x", cull=props.enum("_CullMode", _CULL_BY_NUMBER, "CullMode"),
        outline_cull=props.enum("_OutlineCullMode", _CULL_BY_NUMBER, "CullMode"),
        src=props.enum("_SrcBlend", _FACTOR_BY_NUMBER, "BlendMode"),
        dst=props.enum("_DstBlend", _FACTOR_BY_NUMBER, "BlendMode"),
        zwrite=props.float("_ZWrite") != 0, alpha_to_mask=props.float("_AlphaToMask") != 0,
        alpha_test=alpha_test_on or alpha_blend_on, outline_mode=outline,
        outline_width=props.float("_OutlineWidth"), outline_max_distance=props.float("_OutlineScaledMaxDistance"),
        outline_color=outline_color, outline_lighting_mix=outline_mix)
    # _BlendMode only records the mode the author chose (UniVRM's loader does not re-derive the state from it).
    mode = RENDER_MODES.get(int(props.float("_BlendMode")), f"_BlendMode {props.float('_BlendMode'):g}")
    extra = {"shader": props.entry.get("shader"), "render_queue": queue, "render_mode": mode,
             "_BlendMode": props.float("_BlendMode"), "_Cutoff": props.float("_Cutoff"),
             "_Color": list(rgba_values(props.vector("_Color"), where)),
             "keywords": sorted(keywords), "outline": {
                 "mode": outline, "width": props.float("_OutlineWidth"),
                 "width_world_m": props.float("_OutlineWidth") * 0.01 if outline == OUTLINE_WORLD else None,
                 "scaled_max_distance": props.float("_OutlineScaledMaxDistance"), "formula": "0.x",
                 "color": list(rgba_values(props.vector("_OutlineColor"), f"{where}: vectorProperties._OutlineColor",
                                           OUTLINE_COLOR_DEFAULT))}}
    width_tex = props.texture("_OutlineWidthTexture") if outline != OUTLINE_NONE else None
    if width_tex is not None:  # sampled at _MainTex's coordinates (the property is [NoScaleOffset])
        fields |= outline_width_sampler(document, width_tex, where, warnings)
    material = Material(name=name, color=color, cutoff=cutoff, lighting=Lighting.Lambert, passes=passes,
                        **queue_values, **fields)
    return ImportedMaterial(index, material, texture, f"VRM 0.x {MTOON}", tuple(warnings), extra, width_tex, "sRGB")


def _unlit_transparent_zwrite(document: GltfDocument, index: int, name: str, props: _Properties,
                              warnings: list[str]) -> ImportedMaterial:
    """``VRM/UnlitTransparentZWrite``: MToon 0.x in TransparentWithZWrite with Cull Back, no outline,
    lit and shade colours black and the texture as emission (RGB = tex.rgb, alpha = tex.a: Unlit, white),
    ``_MainTex_ST`` identity, and the stored renderQueue restored
    (``BuiltInVrmUnlitTransparentZWriteMaterialImporter.cs`` @b1bd8807)."""
    queue, queue_values = props.queue(2000)
    texture, fields = _main_tex(document, props, warnings, with_st=False)
    passes = mtoon_passes(version="0.x", cull=Cull.Back, outline_cull=Cull.Front, src=BlendFactor.SrcAlpha,
                          dst=BlendFactor.OneMinusSrcAlpha, zwrite=True, alpha_to_mask=False, alpha_test=True,
                          outline_mode=OUTLINE_NONE)
    material = Material(name=name, color=(1.0, 1.0, 1.0, 1.0), cutoff=BLEND_CLIP_MTOON0, lighting=Lighting.Unlit,
                        passes=passes, **queue_values, **fields)
    extra = {"shader": UNLIT_TRANSPARENT_ZWRITE, "render_queue": queue, "render_mode": "TransparentWithZWrite",
             "outline": {"mode": OUTLINE_NONE}}
    return ImportedMaterial(index, material, texture, f"VRM 0.x {UNLIT_TRANSPARENT_ZWRITE}", tuple(warnings), extra)


def _unity_shader(document: GltfDocument, index: int, name: str, entry: dict[str, Any], shader: str,
                  warnings: list[str]) -> ImportedMaterial:
    """A shader UniVRM finds by name (after ``FallbackShaders``), with the stored floats and keywords."""
    where = f"material {name!r}"
    unity = FALLBACK_SHADERS.get(shader, shader)
    defaults = {"UniGLTF/UniUnlit": UNIUNLIT_DEFAULTS, "Standard": STANDARD_DEFAULTS}.get(unity, {"_Cutoff": 0.5})
    props = _Properties(entry, where, defaults)
    texture, fields = _main_tex(document, props, warnings)
    color = rgba_values(props.vector("_Color"), f"{where}: vectorProperties._Color")
    clips = "_ALPHATEST_ON" in props.keywords
    lighting = Lighting.Unlit
    vertex_color = VertexColor.Off
    if unity == "Unlit/Texture":  # Tags { "RenderType"="Opaque" }; tex2D only; UNITY_OPAQUE_ALPHA
        shader_queue, passes, color = 2000, (Pass(light_mode=LightMode.Always),), (1.0, 1.0, 1.0, 1.0)
    elif unity == "Unlit/Transparent":  # "Queue"="Transparent"; ZWrite Off; Blend SrcAlpha OneMinusSrcAlpha
        shader_queue, color = 3000, (1.0, 1.0, 1.0, 1.0)
        passes = (Pass(light_mode=LightMode.Always, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
                       dst_blend=BlendFactor.OneMinusSrcAlpha),)
    elif unity == "Unlit/Transparent Cutout":  # "Queue"="AlphaTest"; clip(col.a - _Cutoff)
        shader_queue, color = 2450, (1.0, 1.0, 1.0, 1.0)
        passes = (Pass(light_mode=LightMode.Always, alpha_test=True),)
    elif unity == "UniGLTF/UniUnlit":
        shader_queue = 2000
        passes = (uniunlit_pass(cull=props.enum("_CullMode", _CULL_BY_NUMBER, "CullMode"),
                                src=props.enum("_SrcBlend", _FACTOR_BY_NUMBER, "BlendMode"),
                                dst=props.enum("_DstBlend", _FACTOR_BY_NUMBER, "BlendMode"),
                                zwrite=props.float("_ZWrite") != 0, alpha_test=clips),)
        if "_VERTEXCOL_MUL" in props.keywords:
            vertex_color = VertexColor.Multiply
    elif unity == "Standard":
        shader_queue, lighting = 2000, Lighting.Lambert
        passes = standard_passes(src=props.enum("_SrcBlend", _FACTOR_BY_NUMBER, "BlendMode"),
                                 dst=props.enum("_DstBlend", _FACTOR_BY_NUMBER, "BlendMode"),
                                 zwrite=props.float("_ZWrite") != 0, alpha_test=clips)
    else:
        return None  # type: ignore[return-value]  # the caller falls back to the glTF material
    if unity in ("UniGLTF/UniUnlit", "Standard") and not (clips or "_ALPHABLEND_ON" in props.keywords):
        color = color[:3] + (1.0,)
    queue, queue_values = props.queue(shader_queue)
    material = Material(name=name, color=color, cutoff=props.float("_Cutoff"), lighting=lighting, passes=passes,
                        vertex_color=vertex_color, **queue_values, **fields)
    extra = {"shader": shader, "unity_shader": unity, "render_queue": queue, "keywords": sorted(props.keywords)}
    return ImportedMaterial(index, material, texture, f"VRM 0.x {shader}", tuple(warnings), extra)


def vrm0_material(document: GltfDocument, index: int, entry: dict[str, Any] | None,
                  gltf_fallback) -> ImportedMaterial:
    """Material ``index`` with its ``materialProperties`` entry (None: none for it) as UniVRM's 0.x
    loader imports it; ``gltf_fallback(index)`` imports the glTF material (UniGLTF)."""
    material = document.list("materials")[index]
    name = material.get("name") if isinstance(material.get("name"), str) else f"Material_{index}"
    where = f"material {name!r}"
    if entry is None:
        return gltf_fallback(index)
    shader = entry.get("shader")
    warnings: list[str] = []
    if shader == UNLIT_TRANSPARENT_ZWRITE:
        return _unlit_transparent_zwrite(document, index, name, _Properties(entry, where, MTOON_DEFAULTS), warnings)
    if shader == MTOON:
        return _mtoon(document, index, name, _Properties(entry, where, MTOON_DEFAULTS), warnings)
    if shader == USE_GLTF_SHADER or not isinstance(shader, str):
        return gltf_fallback(index)
    imported = _unity_shader(document, index, name, entry, shader, warnings)
    if imported is not None:
        return imported
    fallback = gltf_fallback(index)
    note = (f"{where}: shader {shader!r} is not one UniVRM or Unity ships (UniVRM needs it in the Unity "
            "project); imported from its glTF material instead")
    return ImportedMaterial(fallback.index, fallback.material, fallback.main_tex, fallback.importer,
                            (note, *fallback.warnings), fallback.extra)
