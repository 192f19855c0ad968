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
``_OutlineScaledMaxDistance``). The outline colour (``_OutlineColor``, ``outlineColorFactor``) is
recorded, not drawn: the pass shades like FORWARD_BASE (the approximation of MToon's colour, SPEC
§11.6).
"""

from __future__ import annotations

from ...core.vocabulary import BlendFactor, BlendOp, CompareFunction, Cull, LightMode, OutlineFormula, OutlineMode, Pass

#: MToon 0.x's BLEND clip: ``const half EPSILON_FP16 = 0.0009765625;`` (MToonCore.cginc).
BLEND_CLIP_MTOON0 = 0.0009765625
#: MToon 1.0's BLEND clip: ``static const float EPS_COL = 0.00001;`` (vrmc_materials_mtoon_utility.hlsl),
#: the float32 nearest to 0.00001.
BLEND_CLIP_MTOON1 = 9.999999747378752e-06

OUTLINE_NONE, OUTLINE_WORLD, OUTLINE_SCREEN = "none", "world", "screen"
_OUTLINE_PROGRAM = {OUTLINE_WORLD: OutlineMode.World, OUTLINE_SCREEN: OutlineMode.Screen}


def mtoon_passes(*, version: str, cull: Cull, outline_cull: Cull, src: BlendFactor, dst: BlendFactor,
                 zwrite: bool, alpha_to_mask: bool, alpha_test: bool, outline_mode: str,
                 outline_width: float = 0.0, outline_max_distance: float = 1.0) -> tuple[Pass, ...]:
    """MToon ``version``'s passes (``"0.x"`` or ``"1.0"``) for the given property values: FORWARD_BASE,
    the outline pass (only with an outline mode), FORWARD_ADD, ShadowCaster. ``alpha_test``: the
    fragment program clips (``_ALPHATEST_ON`` or ``_ALPHABLEND_ON``); ``outline_mode``:
    :data:`OUTLINE_NONE`, :data:`OUTLINE_WORLD` or :data:`OUTLINE_SCREEN`; ``outline_width``: 0.x
    ``_OutlineWidth`` / 1.0 ``outlineWidthFactor``; ``outline_max_distance``: 0.x
    ``_OutlineScaledMaxDistance`` (1.0 has none: its screen width is capped by the projection)."""
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
                   outline_max_distance=float(outline_max_distance) if version == "0.x" else 1.0)
    return base, outline, add, shadow
