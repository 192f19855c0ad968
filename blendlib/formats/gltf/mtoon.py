"""MToon's passes in Unity's built-in pipeline, as the shaders state them, for given property values.

MToon 0.x (vrm-c/UniVRM ``Assets/VRM/MToon/Shaders/MToon.shader`` @1499e25a, ``_MToonVersion`` 39)
and MToon 1.0 (``Assets/VRM10/MToon10/Shaders/vrmc_materials_mtoon.shader`` @5d116ee8) have the
same four passes in one SubShader (``Tags { "RenderType" = "Opaque"  "Queue" = "Geometry" }``)::

    Pass { Name "FORWARD_BASE"                Tags { "LightMode" = "ForwardBase" }
           Cull [_CullMode]  Blend [_SrcBlend] [_DstBlend]  ZWrite [_ZWrite]  ZTest LEqual
           BlendOp Add, Max  AlphaToMask [_AlphaToMask] }
    Pass { Name "FORWARD_BASE_ONLY_OUTLINE"   Tags { "LightMode" = "ForwardBase" }      (1.0: "FORWARD_BASE_OUTLINE")
           Cull [_OutlineCullMode]            (1.0: Cull Front)
           Blend [_SrcBlend] [_DstBlend]  ZWrite [_ZWrite]  ZTest LEqual  Offset 1, 1
           BlendOp Add, Max  AlphaToMask [_AlphaToMask] }
    Pass { Name "FORWARD_ADD"                 Tags { "LightMode" = "ForwardAdd" }
           Cull [_CullMode]  Blend [_SrcBlend] One  ZWrite Off  ZTest LEqual
           BlendOp Add, Max  AlphaToMask [_AlphaToMask] }
    Pass { Name "ShadowCaster"                Tags { "LightMode" = "ShadowCaster" }
           Cull [_CullMode]  ZWrite On  ZTest LEqual }

(1.0 names the properties ``_M_CullMode`` etc.). ``BlendOp Add, Max`` is a separate alpha
operation; the passes here state it as the ShaderLab importer does (``separate_alpha`` with the
colour factors and ``blend_op_alpha`` Max).

The fragment programs (``MToonCore.cginc`` @f230f388; ``vrmc_materials_mtoon_geometry_alpha.hlsl``
@885adb71) decide the alpha test from keywords:

* ``_ALPHATEST_ON``: ``clip((a - _Cutoff) / max(fwidth(a), ε) + 0.5 - _Cutoff)`` — the lead's
  decision: approximated by ``clip(a - _Cutoff)`` (exact when ``_Cutoff`` is 0.5 and the alpha is
  flat), output alpha 1;
* ``_ALPHABLEND_ON``: alpha = ``_Color.a × tex.a``, clipped below a small threshold: MToon 0.x
  ``clip(alpha - EPSILON_FP16)`` (1/1024, under ``#ifdef SHADER_API_D3D11``: the Windows
  platform the VRM applications run on), MToon 1.0 ``clip(alpha - EPS_COL)`` (0.00001);
  expressed as an alpha test with the material's cutoff set to that threshold (the lead's decision);
* neither: alpha 1, no clip.

The outline pass discards everything (``clip(-1)`` under ``MTOON_CLIP_IF_OUTLINE_IS_NONE``) unless
an outline width mode is on (0.x: keyword ``MTOON_OUTLINE_WIDTH_WORLD``/``_SCREEN``; 1.0:
``outlineWidthMode``), so without one it is not listed: it draws nothing. With one, its vertex
program pushes the vertices out along the normal (:mod:`blendlib.core.outline`): the pass carries
``outline_mode`` World/Screen, ``outline_width`` (0.x ``_OutlineWidth``, 1.0
``outlineWidthFactor``), ``outline_formula`` (MToon0x / MToon10) and ``outline_max_distance`` (0.x
``_OutlineScaledMaxDistance``).

Its fragments take MToon's outline colour, the pass's ``outline_color`` and
``outline_lighting_mix`` (:mod:`blendlib.core.shade`): MToon 0.x (``MToonCore.cginc`` @f230f388,
``frag_forward``'s last step)::

    #ifdef MTOON_OUTLINE_COLOR_FIXED
        col = lerp(col, _OutlineColor, i.isOutline);
    #elif MTOON_OUTLINE_COLOR_MIXED
        col = lerp(col, _OutlineColor * lerp(half3(1, 1, 1), col, _OutlineLightingMix), i.isOutline);

(``isOutline`` is 1 in the outline pass: FIXED is the colour alone, mix 0; neither keyword leaves the
lit colour: no outline colour); MToon 1.0 (``vrmc_materials_mtoon_lighting_mtoon.hlsl`` @77b90796,
``GetMToonLighting``)::

    const half3 outlineCol = _OutlineColor.rgb * lerp(half3(1, 1, 1), baseCol, _OutlineLightingMix);
    return half4(outlineCol, input.alpha);

Alpha is the base pass's in both. ``col`` / ``baseCol`` is MToon's toon-lit colour; here the
Lambert colour that approximates it (docs/vrm.md).
"""

from __future__ import annotations

from typing import Any

from ...core.vocabulary import BlendFactor, BlendOp, CompareFunction, Cull, LightMode, OutlineFormula, OutlineMode, Pass
from .container import GltfDocument
from .textures import sampler_settings

#: MToon 0.x's BLEND clip: ``const half EPSILON_FP16 = 0.0009765625;`` (MToonCore.cginc).
BLEND_CLIP_MTOON0 = 0.0009765625
#: MToon 1.0's BLEND clip: ``static const float EPS_COL = 0.00001;`` (vrmc_materials_mtoon_utility.hlsl),
#: the float32 nearest to 0.00001.
BLEND_CLIP_MTOON1 = 9.999999747378752e-06

OUTLINE_NONE, OUTLINE_WORLD, OUTLINE_SCREEN = "none", "world", "screen"
_OUTLINE_PROGRAM = {OUTLINE_WORLD: OutlineMode.World, OUTLINE_SCREEN: OutlineMode.Screen}


def mtoon_passes(*, version: str, cull: Cull, outline_cull: Cull, src: BlendFactor, dst: BlendFactor,
                 zwrite: bool, alpha_to_mask: bool, alpha_test: bool, outline_mode: str,
                 outline_width: float = 0.0, outline_max_distance: float = 1.0,
                 outline_color: tuple[float, float, float] | None = None,
                 outline_lighting_mix: float = 0.0) -> tuple[Pass, ...]:
    """MToon ``version``'s passes (``"0.x"`` or ``"1.0"``) for the given property values: FORWARD_BASE,
    the outline pass (only with an outline mode), FORWARD_ADD, ShadowCaster. ``alpha_test``: the
    fragment program clips (``_ALPHATEST_ON`` or ``_ALPHABLEND_ON``); ``outline_mode``:
    :data:`OUTLINE_NONE`, :data:`OUTLINE_WORLD` or :data:`OUTLINE_SCREEN`; ``outline_width``: 0.x
    ``_OutlineWidth`` / 1.0 ``outlineWidthFactor``; ``outline_max_distance``: 0.x
    ``_OutlineScaledMaxDistance`` (1.0 has none: its screen width is capped by the projection);
    ``outline_color`` (COLOR_GAMMA rgb; None: the lit colour) and ``outline_lighting_mix``: as
    :func:`outline_colour` gives them."""
    def blend(dst_color: BlendFactor) -> dict:
        # Blend [_SrcBlend] [dst] + BlendOp Add, Max: the alpha channel keeps the factors, op Max.
        return dict(blend=True, src_blend=src, dst_blend=dst_color, blend_op=BlendOp.Add, separate_alpha=True,
                    src_blend_alpha=src, dst_blend_alpha=dst_color, blend_op_alpha=BlendOp.Max)

    common = dict(ztest=CompareFunction.LEqual, alpha_to_mask=alpha_to_mask, alpha_test=alpha_test)
    base = Pass(name="FORWARD_BASE", light_mode=LightMode.ForwardBase, cull=cull, zwrite=zwrite,
                **blend(dst), **common)
    add = Pass(name="FORWARD_ADD", light_mode=LightMode.ForwardAdd, cull=cull, zwrite=False,
               **blend(BlendFactor.One), **common)
    shadow = Pass(name="ShadowCaster", light_mode=LightMode.ShadowCaster, cull=cull, zwrite=True,
                  ztest=CompareFunction.LEqual)
    if outline_mode == OUTLINE_NONE:
        return base, add, shadow
    outline = Pass(name="FORWARD_BASE_ONLY_OUTLINE" if version == "0.x" else "FORWARD_BASE_OUTLINE",
                   light_mode=LightMode.ForwardBase, cull=outline_cull, zwrite=zwrite,
                   offset_factor=1.0, offset_units=1.0, **blend(dst), **common,
                   outline_mode=_OUTLINE_PROGRAM[outline_mode], outline_width=float(outline_width),
                   outline_formula=OutlineFormula.MToon0x if version == "0.x" else OutlineFormula.MToon10,
                   outline_max_distance=float(outline_max_distance) if version == "0.x" else 1.0,
                   outline_color=outline_color, outline_lighting_mix=float(outline_lighting_mix))
    return base, outline, add, shadow


def outline_width_sampler(document: GltfDocument, texture: int, where: str, warnings: list[str]) -> dict[str, Any]:
    """The Material fields of the outline-width texture's sampler: its filter and wrap (as
    ``_MainTex``'s, :func:`~.textures.sampler_settings`; sampled at level 0, so no mipmaps)."""
    fields = sampler_settings(document.texture_sampler(texture), f"{where}: texture {texture}", warnings)
    return {"outline_width_tex_filter": fields["main_tex_filter"], "outline_width_tex_wrap": fields["main_tex_wrap"]}


def outline_colour(rgb, mix: float, where: str, warnings: list[str]) -> tuple[tuple[float, float, float], float]:
    """(outline colour, lighting mix) as the outline pass takes them: a colour channel below 0
    drawn as 0 and a mix outside MToon's range 0..1 (``Range(0, 1)``) drawn clamped, each with a
    warning (Unity's SetFloat stores any value; the renderer draws in range)."""
    colour = tuple(float(c) for c in rgb[:3])
    if any(c < 0.0 for c in colour):
        warnings.append(f"{where}: outline colour {list(colour)} has a negative channel; drawn as 0")
        colour = tuple(max(0.0, c) for c in colour)
    mix = float(mix)
    if not 0.0 <= mix <= 1.0:
        warnings.append(f"{where}: outline lighting mix {mix:g} is outside 0..1; drawn as {min(1.0, max(0.0, mix)):g}")
        mix = min(1.0, max(0.0, mix))
    return colour, mix
