"""The VRM Add-on's exported ``.vrm`` files (``shared/corpus/vrm-addon/``) import with the state UniVRM sets.

Expected values come from each file's JSON and UniVRM's importers as quoted in SPEC §11.6 and
research-vrm (§1.2 legacy 0.x loader: values as stored; §1.3 MToon 0.x pass headers; §2.2
MToonValidator; §4 UniGLTF), never from this importer's output. Per pass:
FORWARD_BASE ``Cull [_CullMode] Blend [_SrcBlend] [_DstBlend] ZWrite [_ZWrite] BlendOp Add, Max``,
outline ``Cull [_OutlineCullMode]`` (1.0: Front) ``Offset 1, 1``, FORWARD_ADD ``Blend [_SrcBlend] One
ZWrite Off``, ShadowCaster ``ZWrite On``.
"""

from __future__ import annotations

import pytest

from blendlib.core.vocabulary import (
    BlendFactor,
    BlendOp,
    CompareFunction,
    Cull,
    LightMode,
    OutlineFormula,
    OutlineMode,
    pass_draws,
)
from blendlib.formats.gltf import BLEND_CLIP_MTOON0, BLEND_CLIP_MTOON1, SHADING_APPROXIMATION, import_file
from tests.support.gltf_docs import corpus_dir

CORPUS = corpus_dir()
pytestmark = pytest.mark.skipif(CORPUS is None, reason="shared/corpus not found beside the repository")

One, Zero, SrcAlpha, OMSA = BlendFactor.One, BlendFactor.Zero, BlendFactor.SrcAlpha, BlendFactor.OneMinusSrcAlpha
World, Screen, MToon0x, MToon10 = OutlineMode.World, OutlineMode.Screen, OutlineFormula.MToon0x, OutlineFormula.MToon10


def _materials(name):
    result = import_file(CORPUS / "vrm-addon" / name)
    return result, {m.material.name: m for m in result.materials}


def _check_mtoon(imported, *, queue, cull, outline_cull, src, dst, zwrite, alpha_to_mask, clip, outline,
                 outline_name):
    """Every pass of an MToon material against the pass headers with these property values;
    ``outline``: None (no outline keyword: the pass clips everything, ``clip(-1)``, and is not listed)
    or (OutlineMode, width, OutlineFormula, max distance) of its vertex program."""
    m = imported.material
    assert m.render_queue == queue
    if outline is None:
        base, add, shadow = m.passes
        assert [p.name for p in m.passes] == ["FORWARD_BASE", "FORWARD_ADD", "ShadowCaster"]
        drawn = [base, add]
    else:
        base, line, add, shadow = m.passes
        assert [p.name for p in m.passes] == ["FORWARD_BASE", outline_name, "FORWARD_ADD", "ShadowCaster"]
        assert line.light_mode is LightMode.ForwardBase
        assert (line.outline_mode, line.outline_width, line.outline_formula, line.outline_max_distance) == (
            outline[0], pytest.approx(outline[1], rel=1e-7), outline[2], outline[3])
        assert (line.cull, line.zwrite, line.offset_factor, line.offset_units) == (outline_cull, zwrite, 1.0, 1.0)
        assert (line.alpha_test, line.alpha_test_comp) == (clip is not None, CompareFunction.GEqual)
        drawn = [base, line, add]
    assert [p.light_mode for p in (base, add, shadow)] == [LightMode.ForwardBase, LightMode.ForwardAdd,
                                                           LightMode.ShadowCaster]
    for p in drawn:
        p_cull, p_dst = (outline_cull, dst) if p.outline_mode is not OutlineMode.Off else (
            (cull, One) if p is add else (cull, dst))
        assert (p.cull, p.blend, p.src_blend, p.dst_blend, p.blend_op) == (p_cull, True, src, p_dst, BlendOp.Add)
        # BlendOp Add, Max: the alpha channel takes max(src, dst).
        assert (p.separate_alpha, p.src_blend_alpha, p.dst_blend_alpha, p.blend_op_alpha) == (True, src, p_dst,
                                                                                            BlendOp.Max)
        assert p.ztest is CompareFunction.LEqual
        assert p.alpha_to_mask is alpha_to_mask
    assert (base.zwrite, add.zwrite) == (zwrite, False)
    assert (base.offset_factor, base.offset_units, add.offset_units) == (0.0, 0.0, 0.0)
    assert base.outline_mode is add.outline_mode is OutlineMode.Off
    assert (shadow.cull, shadow.zwrite, shadow.blend) == (cull, True, False)
    assert base.alpha_test is add.alpha_test is (clip is not None)
    if clip is not None:
        assert m.cutoff == pytest.approx(clip, rel=1e-6) and base.alpha_test_comp is CompareFunction.GEqual
    # ShadowCaster never draws; the others do (ForwardAdd per extra light).
    assert [pass_draws(p, m.passes)[0] for p in m.passes] == ["once"] * (len(drawn) - 1) + ["per light", "never"]


def test_vrm0_export_imports_as_the_legacy_loader_draws_it():
    result, mats = _materials("mtoon1_2_20_61_vrm0.vrm")
    assert result.vrm == "0.x"
    assert result.warnings[0] == SHADING_APPROXIMATION
    # Opaque: renderQueue -1 (MToon's "Queue" = "Geometry"), _CullMode 1 (Front), _OutlineCullMode 1,
    # _SrcBlend 1 _DstBlend 0 _ZWrite 1, no alpha keyword, MTOON_OUTLINE_WIDTH_WORLD, _OutlineWidth 6.25,
    # _OutlineScaledMaxDistance 2.
    _check_mtoon(mats["Opaque"], queue=2000, cull=Cull.Front, outline_cull=Cull.Front, src=One, dst=Zero,
                 zwrite=True, alpha_to_mask=False, clip=None, outline=(World, 6.25, MToon0x, 2.0),
                 outline_name="FORWARD_BASE_ONLY_OUTLINE")
    # Cutout: renderQueue 2450, _CullMode 2, _ALPHATEST_ON, _Cutoff 0.25, no outline keyword.
    _check_mtoon(mats["Cutout"], queue=2450, cull=Cull.Back, outline_cull=Cull.Front, src=One, dst=Zero,
                 zwrite=True, alpha_to_mask=False, clip=0.25, outline=None,
                 outline_name="FORWARD_BASE_ONLY_OUTLINE")
    # Transparent: renderQueue 2952 kept as stored, _CullMode 1, _SrcBlend 5 _DstBlend 10 _ZWrite 0,
    # _ALPHABLEND_ON (clip at 1/1024, D3D11), MTOON_OUTLINE_WIDTH_SCREEN, _OutlineWidth 0 (the pass draws,
    # pushed by nothing), _OutlineScaledMaxDistance 2.
    _check_mtoon(mats["Transparent"], queue=2952, cull=Cull.Front, outline_cull=Cull.Front, src=SrcAlpha,
                 dst=OMSA, zwrite=False, alpha_to_mask=False, clip=1 / 1024, outline=(Screen, 0.0, MToon0x, 2.0),
                 outline_name="FORWARD_BASE_ONLY_OUTLINE")
    # TransparentWithZWrite: renderQueue 2550, _CullMode 2, 5/10, _ZWrite 1, _ALPHABLEND_ON, SCREEN 2.5, max 1.
    _check_mtoon(mats["TransparentWithZWrite"], queue=2550, cull=Cull.Back, outline_cull=Cull.Front, src=SrcAlpha,
                 dst=OMSA, zwrite=True, alpha_to_mask=False, clip=1 / 1024, outline=(Screen, 2.5, MToon0x, 1.0),
                 outline_name="FORWARD_BASE_ONLY_OUTLINE")
    assert BLEND_CLIP_MTOON0 == 0.0009765625


def test_vrm0_colours_and_main_tex_are_the_stored_unity_values():
    _, mats = _materials("mtoon1_2_20_61_vrm0.vrm")
    opaque = mats["Opaque"].material
    # vectorProperties._MainTex = [-0.125, -0.125, 1.5, 1.0]: offset (x, y), scale (x, y).
    assert (opaque.main_tex_tiling, opaque.main_tex_offset) == ((1.5, 1.0), (-0.125, -0.125))
    # _Color [0.5325205447199813, 0, 0, 0.5] as stored (float32), alpha 1: Opaque MToon writes alpha 1.
    assert opaque.color == pytest.approx((0.5325205447199813, 0.0, 0.0, 1.0), rel=1e-7)
    assert mats["Opaque"].extra["_Color"][3] == 0.5
    # texture 0 → sampler 0: minFilter 9729 (LINEAR) → Bilinear without mipmaps; wrapS CLAMP_TO_EDGE.
    assert (opaque.main_tex_filter.value, opaque.main_tex_mipmaps, opaque.main_tex_wrap.value) == (
        "Bilinear", False, "Clamp")
    assert mats["Opaque"].main_tex == 0
    transparent = mats["Transparent"].material
    assert (transparent.main_tex_tiling, transparent.main_tex_offset) == ((2.0, 1.0), (1.0, -1.0))
    assert transparent.color[3] == 0.0  # _Color.a 0: every fragment clipped at 1/1024
    # Cutout has no _MainTex texture: no ST either (set only with the texture).
    cutout = mats["Cutout"]
    assert cutout.main_tex is None and cutout.material.main_tex_tiling == (1.0, 1.0)
    assert mats["Opaque"].extra["outline"] == {"mode": "world", "width": 6.25, "width_world_m": 0.0625,
                                              "scaled_max_distance": 2.0, "formula": "0.x",
                                              "color": [0.0, 0.0, pytest.approx(0.7297400528407231), 1.0]}
    # Cutout: _OutlineColor [0, 0, 0, 1] stored, no outline keyword (_OutlineWidthMode 0 agrees: no warning).
    assert mats["Cutout"].extra["outline"]["color"] == [0.0, 0.0, 0.0, 1.0]
    assert not any("_OutlineWidthMode" in w for m in mats.values() for w in m.warnings)


def test_vrm1_export_imports_through_mtoons_validator():
    result, mats = _materials("mtoon1_2_20_61_vrm1.vrm")
    assert result.vrm == "1.0"
    # Cutout: MASK, cutoff 0.25, doubleSided false, offset -8 forced to 0: 2450, AlphaToMask On.
    _check_mtoon(mats["Cutout"], queue=2450, cull=Cull.Back, outline_cull=Cull.Front, src=One, dst=Zero,
                 zwrite=True, alpha_to_mask=True, clip=0.25, outline=None, outline_name="FORWARD_BASE_OUTLINE")
    # Opaque: doubleSided true → Cull Off, offset -9 forced to 0: 2000; outline worldCoordinates 0.0625 m.
    _check_mtoon(mats["Opaque"], queue=2000, cull=Cull.Off, outline_cull=Cull.Front, src=One, dst=Zero,
                 zwrite=True, alpha_to_mask=False, clip=None, outline=(World, 0.0625, MToon10, 1.0),
                 outline_name="FORWARD_BASE_OUTLINE")
    # Transparent: BLEND, offset 8 clamped to 0 → 3000, ZWrite Off, clip at EPS_COL.
    _check_mtoon(mats["Transparent"], queue=3000, cull=Cull.Off, outline_cull=Cull.Front, src=SrcAlpha, dst=OMSA,
                 zwrite=False, alpha_to_mask=False, clip=1e-5, outline=(Screen, 0.0, MToon10, 1.0),
                 outline_name="FORWARD_BASE_OUTLINE")
    # TransparentWithZWrite: BLEND + transparentWithZWrite, offset 9 → 2501 + 9 = 2510.
    _check_mtoon(mats["TransparentWithZWrite"], queue=2510, cull=Cull.Back, outline_cull=Cull.Front, src=SrcAlpha,
                 dst=OMSA, zwrite=True, alpha_to_mask=False, clip=1e-5, outline=(Screen, 0.0125, MToon10, 1.0),
                 outline_name="FORWARD_BASE_OUTLINE")
    assert BLEND_CLIP_MTOON1 == pytest.approx(1e-5, rel=1e-7)
    assert mats["TransparentWithZWrite"].extra["render_queue_offset_number"] == 9
    assert mats["TransparentWithZWrite"].extra["render_queue_offset_validated"] == 9
    assert mats["Transparent"].extra["render_queue_offset_validated"] == 0
    assert mats["Opaque"].extra["outline"]["color"] == [0.0, 0.0, 0.5]  # outlineColorFactor as stored (linear)


def _outline_colour(imported):
    line = next(p for p in imported.material.passes if p.outline_mode is not OutlineMode.Off)
    return line.outline_color, line.outline_lighting_mix


def test_corpus_outlines_draw_in_mtoons_outline_colour():
    """MToon 0.x: ``MTOON_OUTLINE_COLOR_MIXED`` → ``_OutlineColor * lerp(1, col, _OutlineLightingMix)``, the
    stored ``_OutlineColor`` (gamma) and ``_OutlineLightingMix``; MToon 1.0: ``_OutlineColor`` is
    ``outlineColorFactor`` linear → gamma, mix ``outlineLightingMixFactor`` (values from the files)."""
    _, v0 = _materials("mtoon1_2_20_61_vrm0.vrm")
    # Opaque: _OutlineColor [0, 0, 0.7297400528407231, 1], _OutlineLightingMix 0.5, MTOON_OUTLINE_COLOR_MIXED.
    colour, mix = _outline_colour(v0["Opaque"])
    assert colour == pytest.approx((0.0, 0.0, 0.7297400528407231), rel=1e-7) and mix == 0.5
    colour, mix = _outline_colour(v0["TransparentWithZWrite"])  # [0.5325.., 0.5325.., 0], mix 0.75
    assert colour == pytest.approx((0.5325205447199813, 0.5325205447199813, 0.0), rel=1e-7) and mix == 0.75
    assert _outline_colour(v0["Transparent"])[1] == 1.0
    _, v1 = _materials("mtoon1_2_20_61_vrm1.vrm")
    # Opaque: outlineColorFactor [0, 0, 0.5] → sRGB encode(0.5) = 1.055 * 0.5^(1/2.4) - 0.055, mix 0.5.
    colour, mix = _outline_colour(v1["Opaque"])
    assert colour == pytest.approx((0.0, 0.0, 1.055 * 0.5 ** (1 / 2.4) - 0.055), rel=1e-6) and mix == 0.5
    colour, mix = _outline_colour(v1["TransparentWithZWrite"])  # [0.25, 0.25, 0], mix 0.75
    assert colour == pytest.approx((1.055 * 0.25 ** (1 / 2.4) - 0.055,) * 2 + (0.0,), rel=1e-6) and mix == 0.75
    assert not any("outline" in w for m in (*v0.values(), *v1.values()) for w in m.warnings)


def test_corpus_outline_width_textures_are_read_for_outlined_materials():
    """0.x ``textureProperties._OutlineWidthTexture`` (imported sRGB by UniVRM's legacy loader, the
    default case of ``VRMMToonTextureImporter``); 1.0 ``outlineWidthMultiplyTexture`` (imported linear,
    ``Vrm10MToonTextureImporter.TryGetLinearTexture``). The files' Transparent materials have one."""
    _, v0 = _materials("mtoon1_2_20_61_vrm0.vrm")
    _, v1 = _materials("mtoon1_2_20_61_vrm1.vrm")
    assert (v0["Transparent"].outline_width_tex, v0["Transparent"].outline_width_encoding) == (12, "sRGB")
    assert (v1["Transparent"].outline_width_tex, v1["Transparent"].outline_width_encoding) == (13, "Data")
    assert all(m.outline_width_tex is None for name, m in (*v0.items(), *v1.items()) if name != "Transparent")


def test_vrm1_base_color_is_linear_converted_and_texture_transform_flipped():
    _, mats = _materials("mtoon1_2_20_61_vrm1.vrm")
    opaque = mats["Opaque"].material
    # baseColorFactor (0.25, 0, 0, 0.5) linear → sRGB: 1.055 * 0.25 ** (1 / 2.4) - 0.055 = 0.53709873...
    assert opaque.color[0] == pytest.approx(0.5370987304831942, rel=1e-6)
    # KHR_texture_transform offset (-0.125, 0.125), scale (1.5, 1): Unity offset (-0.125, 1 - 0.125 - 1).
    assert (opaque.main_tex_tiling, opaque.main_tex_offset) == ((1.5, 1.0), (-0.125, -0.125))
    twz = mats["TransparentWithZWrite"].material
    # offset (-0.125, -0.25), scale (1, 2) → (-0.125, 1 + 0.25 - 2 = -0.75)
    assert (twz.main_tex_tiling, twz.main_tex_offset) == ((1.0, 2.0), (-0.125, -0.75))
    # texture 14 → sampler 13: minFilter 9985 (LINEAR_MIPMAP_NEAREST) → Bilinear with mipmaps.
    assert (twz.main_tex_filter.value, twz.main_tex_mipmaps) == ("Bilinear", True)


def test_material_vrm_legacy_shaders_and_gltf_fallbacks():
    result, mats = _materials("material.vrm")
    # MToonUnversioned: VRM/MToon, renderQueue -1, _CullMode 0 → Cull Off, no outline keyword.
    _check_mtoon(mats["MToonUnversioned"], queue=2000, cull=Cull.Off, outline_cull=Cull.Front, src=One, dst=Zero,
                 zwrite=True, alpha_to_mask=False, clip=None, outline=None,
                 outline_name="FORWARD_BASE_ONLY_OUTLINE")
    # TransparentZWrite: VRM/UnlitTransparentZWrite → MToon TransparentWithZWrite, Cull Back, the stored
    # renderQueue 2600 restored (outside MToon's 2501..2550), Unlit white x texture.
    tzw = mats["TransparentZWrite"]
    _check_mtoon(tzw, queue=2600, cull=Cull.Back, outline_cull=Cull.Front, src=SrcAlpha, dst=OMSA, zwrite=True,
                 alpha_to_mask=False, clip=1 / 1024, outline=None, outline_name="FORWARD_BASE_ONLY_OUTLINE")
    assert tzw.material.lighting.value == "Unlit" and tzw.material.color == (1.0, 1.0, 1.0, 1.0)
    assert tzw.main_tex == 2
    # VRM_USE_GLTFSHADER and PBR: Standard, opaque, 2000, Cull Back although doubleSided is true.
    for name in ("GLTF", "PrincipledBSDFBaseColor", "PrincipledBSDFBaseColorTexture1a", "glTF_2_0_default_material"):
        m = mats[name].material
        assert mats[name].importer == "glTF Standard"
        assert m.render_queue == 2000
        forward, delta, shadow, deferred, meta = m.passes
        assert (forward.light_mode, forward.cull, forward.zwrite, forward.src_blend, forward.dst_blend) == (
            LightMode.ForwardBase, Cull.Back, True, One, Zero)
        assert (delta.light_mode, delta.zwrite, delta.src_blend, delta.dst_blend) == (
            LightMode.ForwardAdd, False, One, One)
        assert (shadow.light_mode, deferred.light_mode, meta.light_mode, meta.cull) == (
            LightMode.ShadowCaster, LightMode.Deferred, LightMode.Meta, Cull.Off)
    assert any("'GLTF': doubleSided is ignored" in w for w in result.warnings)
    assert not any("glTF_2_0_default_material" in w for w in result.warnings)  # doubleSided false there
