"""glTF / VRM material import on small synthetic documents: VRM 1.0's clamps, every alphaMode, VRM 0.x
defaults and legacy shaders, samplers, KHR_texture_transform, the JSON record.

Expected numbers are written from the sources the modules cite (UniVRM's MToonValidator, UniGLTF's
importers and TextureSamplerUtil, the shaders' Properties blocks), not from the importer.
"""

from __future__ import annotations

import json

import pytest

from blendlib.core.vocabulary import (
    BlendFactor,
    BlendOp,
    Cull,
    Lighting,
    LightMode,
    OutlineFormula,
    OutlineMode,
    Queue,
    TextureFilter,
    TextureWrap,
    VertexColor,
)
from blendlib.formats.gltf import GltfError, document_from_json, import_materials
from blendlib.formats.gltf.textures import sampler_settings, texture_transform_st
from tests.support.gltf_docs import triangles_document

One, Zero, SrcAlpha, OMSA = BlendFactor.One, BlendFactor.Zero, BlendFactor.SrcAlpha, BlendFactor.OneMinusSrcAlpha


def _import(doc):
    doc = {k: v for k, v in doc.items() if k != "__buffer__"}
    return import_materials(document_from_json(doc, "test.gltf"))


def _mtoon1(alpha_mode, *, offset=None, zwrite=None, double_sided=None, cutoff=None, outline=None):
    mtoon = {"specVersion": "1.0"}
    if offset is not None:
        mtoon["renderQueueOffsetNumber"] = offset
    if zwrite is not None:
        mtoon["transparentWithZWrite"] = zwrite
    if outline is not None:
        mtoon["outlineWidthMode"], mtoon["outlineWidthFactor"] = outline
    material = {"name": "M", "extensions": {"VRMC_materials_mtoon": mtoon}}
    if alpha_mode is not None:
        material["alphaMode"] = alpha_mode
    if double_sided is not None:
        material["doubleSided"] = double_sided
    if cutoff is not None:
        material["alphaCutoff"] = cutoff
    doc = triangles_document([material])
    doc["extensions"] = {"VRMC_vrm": {"specVersion": "1.0"}}
    return _import(doc).materials[0]


# MToonValidator.SetUnityShaderPassSettings: Opaque and Cutout force the offset to 0; Transparent
# clamps it to [-9, 0] over 3000; TransparentWithZWrite to [0, +9] over RenderQueue.GeometryLast + 1.
@pytest.mark.parametrize("mode,zwrite,offset,queue", [
    ("OPAQUE", False, 7, 2000), ("OPAQUE", False, -9, 2000), (None, False, 3, 2000),
    ("MASK", False, -3, 2450), ("MASK", False, 9, 2450),
    ("BLEND", False, -20, 2991), ("BLEND", False, -9, 2991), ("BLEND", False, -5, 2995),
    ("BLEND", False, 0, 3000), ("BLEND", False, 5, 3000), (("BLEND", False, None, 3000)),
    ("BLEND", True, -5, 2501), ("BLEND", True, 0, 2501), ("BLEND", True, 4, 2505),
    ("BLEND", True, 9, 2510), ("BLEND", True, 20, 2510),
    ("OPAQUE", True, 5, 2000),  # transparentWithZWrite only matters with BLEND
])
def test_vrm1_render_queue_clamps(mode, zwrite, offset, queue):
    imported = _mtoon1(mode, zwrite=zwrite, offset=offset)
    assert imported.material.render_queue == queue


@pytest.mark.parametrize("mode,zwrite,src,dst,zw,a2m,clip", [
    ("OPAQUE", False, One, Zero, True, False, None),
    ("MASK", False, One, Zero, True, True, 0.3),
    ("BLEND", False, SrcAlpha, OMSA, False, False, 1e-5),
    ("BLEND", True, SrcAlpha, OMSA, True, False, 1e-5),
])
def test_vrm1_state_per_mode(mode, zwrite, src, dst, zw, a2m, clip):
    m = _mtoon1(mode, zwrite=zwrite, cutoff=0.3, outline=("worldCoordinates", 0.02)).material
    base, outline, add, _ = m.passes
    assert (base.src_blend, base.dst_blend, base.zwrite, base.alpha_to_mask) == (src, dst, zw, a2m)
    assert (add.src_blend, add.dst_blend, add.zwrite) == (src, One, False)
    assert base.alpha_test is (clip is not None)
    if clip is not None:
        assert m.cutoff == pytest.approx(clip, rel=1e-6)
    # "front-face culling is always used for drawing outlines ... regardless of the doubleSided value"
    assert outline.cull is Cull.Front
    # the outline pass: FORWARD_BASE's blend, ZWrite and clip, Offset 1, 1
    assert (outline.src_blend, outline.dst_blend, outline.zwrite, outline.alpha_test) == (src, dst, zw, base.alpha_test)


def test_vrm1_double_sided_and_outline():
    both = _mtoon1("OPAQUE", double_sided=True, outline=("screenCoordinates", 0.01))
    base, outline, add, shadow = both.material.passes
    assert (base.cull, add.cull, shadow.cull, outline.cull) == (Cull.Off, Cull.Off, Cull.Off, Cull.Front)
    assert outline.name == "FORWARD_BASE_OUTLINE" and not outline.alpha_test
    # screenCoordinates → _MTOON_OUTLINE_SCREEN: MToon_GetOutlineVertex's screen branch, width outlineWidthFactor
    assert (outline.outline_mode, outline.outline_width, outline.outline_formula) == (
        OutlineMode.Screen, pytest.approx(0.01, rel=1e-7), OutlineFormula.MToon10)
    assert both.extra["outline"] == {"mode": "screen", "width": pytest.approx(0.01), "width_world_m": None,
                                     "formula": "1.0", "color": [0.0, 0.0, 0.0]}
    world = _mtoon1("OPAQUE", outline=("worldCoordinates", 0.0625)).material.passes[1]
    assert (world.outline_mode, world.outline_width, world.outline_formula) == (
        OutlineMode.World, 0.0625, OutlineFormula.MToon10)  # metres along the world normal
    one = _mtoon1("OPAQUE", double_sided=False)
    assert one.material.passes[0].cull is Cull.Back
    # outlineWidthMode none (the default): the outline pass clips everything (clip(-1)): not drawn
    assert [p.name for p in one.material.passes] == ["FORWARD_BASE", "FORWARD_ADD", "ShadowCaster"]
    assert all(p.outline_mode is OutlineMode.Off for p in one.material.passes)


def test_vrm1_unknown_alpha_mode_is_opaque_with_a_warning():
    imported = _mtoon1("ADDITIVE")
    assert imported.material.render_queue == 2000
    assert any("unknown alphaMode 'ADDITIVE'" in w for w in imported.warnings)


# UniGLTF: KHR_materials_unlit → UniUnlit (one untagged pass, Cull from doubleSided); else Standard.
@pytest.mark.parametrize("mode,unlit,double_sided,queue,src,dst,zwrite,clip,cull", [
    ("OPAQUE", True, False, 2000, One, Zero, True, False, Cull.Back),
    ("OPAQUE", True, True, 2000, One, Zero, True, False, Cull.Off),
    ("MASK", True, True, 2450, One, Zero, True, True, Cull.Off),
    ("BLEND", True, False, 3000, SrcAlpha, OMSA, False, False, Cull.Back),
    ("OPAQUE", False, False, 2000, One, Zero, True, False, Cull.Back),
    ("MASK", False, True, 2450, One, Zero, True, True, Cull.Back),   # PBR ignores doubleSided
    ("BLEND", False, True, 3000, SrcAlpha, OMSA, False, False, Cull.Back),
])
def test_plain_gltf_alpha_modes(mode, unlit, double_sided, queue, src, dst, zwrite, clip, cull):
    material = {"name": "M", "alphaMode": mode, "doubleSided": double_sided, "alphaCutoff": 0.75,
                "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1.0, 0.4]}}
    if unlit:
        material["extensions"] = {"KHR_materials_unlit": {}}
    imported = _import(triangles_document([material])).materials[0]
    m = imported.material
    first = m.passes[0]
    assert m.render_queue == queue
    assert (first.src_blend, first.dst_blend, first.zwrite, first.alpha_test, first.cull) == (
        src, dst, zwrite, clip, cull)
    if clip:
        assert m.cutoff == 0.75
    if unlit:
        assert imported.importer == "glTF UniGLTF/UniUnlit" and len(m.passes) == 1
        assert (first.light_mode, first.blend_op_alpha, m.lighting) == (LightMode.Always, BlendOp.Max, Lighting.Unlit)
    else:
        assert imported.importer == "glTF Standard"
        assert [p.name for p in m.passes] == ["FORWARD", "FORWARD_DELTA", "ShadowCaster", "DEFERRED", "META"]
        assert (m.passes[1].src_blend, m.passes[1].dst_blend) == (src, One)
        assert m.lighting is Lighting.Lambert
        assert any("doubleSided is ignored" in w for w in imported.warnings) is double_sided
    # baseColorFactor is linear: _Color = its sRGB encoding (alpha kept, or 1 in OPAQUE).
    assert m.color[1] == pytest.approx(1.055 * 0.25 ** (1 / 2.4) - 0.055, rel=1e-6)
    assert m.color[3] == pytest.approx(1.0 if mode == "OPAQUE" else 0.4, rel=1e-6)


def test_uniunlit_multiplies_vertex_colour_when_the_primitive_has_one():
    doc = triangles_document([{"name": "A", "extensions": {"KHR_materials_unlit": {}}},
                              {"name": "B", "extensions": {"KHR_materials_unlit": {}}}])
    doc["meshes"][1]["primitives"][0]["attributes"]["COLOR_0"] = 0
    a, b = _import(doc).materials
    assert (a.material.vertex_color, b.material.vertex_color) == (VertexColor.Off, VertexColor.Multiply)


def _vrm0(entry, material=None, textures=0, samplers=None):
    doc = triangles_document([material or {"name": "M"}], textures=textures, samplers=samplers)
    doc["extensions"] = {"VRM": {"materialProperties": [entry]}}
    return _import(doc).materials[0]


def test_vrm0_missing_values_take_mtoons_defaults():
    # MToon.shader: _CullMode 2.0, _OutlineCullMode 1.0, _SrcBlend 1.0, _DstBlend 0.0, _ZWrite 1.0,
    # _AlphaToMask 0.0; renderQueue absent = -1 = "Queue" = "Geometry".
    m = _vrm0({"shader": "VRM/MToon"}).material
    base, add, shadow = m.passes  # no outline keyword: the outline pass clips everything
    assert m.render_queue == 2000 and m.queue is Queue.Geometry
    assert (base.cull, base.src_blend, base.dst_blend, base.zwrite, base.alpha_to_mask) == (
        Cull.Back, One, Zero, True, False)
    assert not base.alpha_test and m.color == (1.0, 1.0, 1.0, 1.0)
    # _OutlineWidth 0.5, _OutlineScaledMaxDistance 1 and _OutlineCullMode 1 (Front) when only the keyword is set
    world = _vrm0({"shader": "VRM/MToon", "floatProperties": {"_OutlineWidthMode": 1},
                   "keywordMap": {"MTOON_OUTLINE_WIDTH_WORLD": True}})
    outline = world.material.passes[1]
    assert (outline.name, outline.cull, outline.outline_mode, outline.outline_width, outline.outline_formula,
            outline.outline_max_distance) == ("FORWARD_BASE_ONLY_OUTLINE", Cull.Front, OutlineMode.World, 0.5,
                                              OutlineFormula.MToon0x, 1.0)
    assert world.extra["outline"]["color"] == [0.0, 0.0, 0.0, 1.0]  # _OutlineColor = (0,0,0,1)
    assert not world.warnings


def test_vrm0_outline_screen_mode_values_and_the_keyword_rule():
    entry = {"shader": "VRM/MToon", "floatProperties": {"_OutlineWidthMode": 2, "_OutlineWidth": 0.75,
                                                        "_OutlineScaledMaxDistance": 4, "_OutlineCullMode": 2},
             "keywordMap": {"MTOON_OUTLINE_WIDTH_SCREEN": True},
             "vectorProperties": {"_OutlineColor": [0.25, 0.5, 1.0, 1.0]}}
    imported = _vrm0(entry)
    outline = imported.material.passes[1]
    # MToon 0.x screen: 0.01 * _OutlineWidth * normalize(n_clip.xy) * min(w, _OutlineScaledMaxDistance)
    assert (outline.outline_mode, outline.outline_width, outline.outline_formula, outline.outline_max_distance,
            outline.cull) == (OutlineMode.Screen, 0.75, OutlineFormula.MToon0x, 4.0, Cull.Back)
    assert imported.extra["outline"]["color"] == [0.25, 0.5, 1.0, 1.0]
    # _OutlineWidthMode 1 without the keyword: the shader reads the keyword (clip(-1)); a warning says so.
    entry = {"shader": "VRM/MToon", "floatProperties": {"_OutlineWidthMode": 1, "_OutlineWidth": 2}}
    lone = _vrm0(entry)
    assert [p.name for p in lone.material.passes] == ["FORWARD_BASE", "FORWARD_ADD", "ShadowCaster"]
    assert lone.warnings == ("material 'M': _OutlineWidthMode 1 disagrees with the keywords (outline none); "
                             "UniVRM sets the keywords from keywordMap, so the outline is none",)


def test_vrm0_values_are_kept_as_stored_without_validation():
    # _BlendMode says Opaque, but UniVRM's loader copies the floats: ZWrite Off and Blend 5/10 draw.
    entry = {"shader": "VRM/MToon", "renderQueue": 3100, "floatProperties": {
        "_BlendMode": 0, "_SrcBlend": 5, "_DstBlend": 10, "_ZWrite": 0, "_CullMode": 0, "_OutlineCullMode": 2,
        "_AlphaToMask": 1},
        "keywordMap": {"MTOON_OUTLINE_WIDTH_WORLD": True, "_ALPHATEST_ON": False}}
    imported = _vrm0(entry)
    m = imported.material
    base, outline, _, _ = m.passes
    assert m.render_queue == 3100 and m.queue is Queue.Transparent and m.queue_offset == 100
    assert (base.src_blend, base.dst_blend, base.zwrite, base.cull, outline.cull) == (
        SrcAlpha, OMSA, False, Cull.Off, Cull.Back)
    assert base.alpha_to_mask and not base.alpha_test and not outline.alpha_test
    assert imported.extra["render_mode"] == "Opaque"


def test_vrm0_keywords_decide_the_clip():
    blend = _vrm0({"shader": "VRM/MToon", "floatProperties": {"_Cutoff": 0.7},
                   "keywordMap": {"_ALPHABLEND_ON": True}}).material
    assert blend.passes[0].alpha_test and blend.cutoff == 0.0009765625
    cutout = _vrm0({"shader": "VRM/MToon", "floatProperties": {"_Cutoff": 0.7},
                    "keywordMap": {"_ALPHATEST_ON": True}}).material
    assert cutout.passes[0].alpha_test and cutout.cutoff == pytest.approx(0.7)
    both = _vrm0({"shader": "VRM/MToon", "keywordMap": {"_ALPHATEST_ON": True, "_ALPHABLEND_ON": True}})
    assert any("both on" in w for w in both.warnings)


@pytest.mark.parametrize("shader,queue,zwrite,blend,clip,light_mode", [
    # Unlit/Texture: Tags { "RenderType"="Opaque" }; Unlit/Transparent: "Queue"="Transparent", ZWrite Off,
    # Blend SrcAlpha OneMinusSrcAlpha; Unlit/Transparent Cutout: "Queue"="AlphaTest", clip(col.a - _Cutoff).
    ("VRM/UnlitTexture", 2000, True, False, False, LightMode.Always),
    ("VRM/UnlitTransparent", 3000, False, True, False, LightMode.Always),
    ("VRM/UnlitCutout", 2450, True, False, True, LightMode.Always),
])
def test_vrm0_legacy_unlit_shaders(shader, queue, zwrite, blend, clip, light_mode):
    m = _vrm0({"shader": shader, "floatProperties": {"_Cutoff": 0.4}}).material
    (p,) = m.passes
    assert (m.render_queue, p.zwrite, p.blend, p.alpha_test, p.light_mode, m.lighting) == (
        queue, zwrite, blend, clip, light_mode, Lighting.Unlit)
    if blend:
        assert (p.src_blend, p.dst_blend) == (SrcAlpha, OMSA)
    if clip:
        assert m.cutoff == pytest.approx(0.4)


def test_vrm0_use_gltf_shader_and_unknown_shaders_fall_back_to_unigltf():
    gltf = _vrm0({"shader": "VRM_USE_GLTFSHADER"}, {"name": "M", "alphaMode": "BLEND"})
    assert gltf.importer == "glTF Standard" and gltf.material.render_queue == 3000
    other = _vrm0({"shader": "lilToon"}, {"name": "M", "alphaMode": "MASK"})
    assert other.importer == "glTF Standard" and other.material.render_queue == 2450
    assert "shader 'lilToon' is not one UniVRM or Unity ships" in other.warnings[0]


def test_vrm0_main_tex_vector_is_offset_then_scale():
    entry = {"shader": "VRM/MToon", "textureProperties": {"_MainTex": 0},
             "vectorProperties": {"_MainTex": [0.25, -0.5, 2.0, 3.0]}}
    imported = _vrm0(entry, textures=1)
    assert imported.main_tex == 0
    assert (imported.material.main_tex_offset, imported.material.main_tex_tiling) == ((0.25, -0.5), (2.0, 3.0))


@pytest.mark.parametrize("min_filter,expected", [
    # TextureSamplerUtil.ImportFilterMode
    (9728, (TextureFilter.Point, False)), (9984, (TextureFilter.Point, False)),
    (9986, (TextureFilter.Point, True)), (9729, (TextureFilter.Bilinear, False)),
    (9985, (TextureFilter.Bilinear, True)), (9987, (TextureFilter.Bilinear, True)),
])
def test_sampler_min_filter(min_filter, expected):
    fields = sampler_settings({"minFilter": min_filter}, "t", [])
    assert (fields["main_tex_filter"], fields["main_tex_mipmaps"]) == expected


def test_sampler_defaults_and_wraps():
    # No sampler: SamplerParam.Default (Repeat, Bilinear, mipmaps); a sampler without minFilter: NEAREST.
    assert sampler_settings(None, "t", []) == {"main_tex_filter": TextureFilter.Bilinear,
                                               "main_tex_wrap": TextureWrap.Repeat, "main_tex_mipmaps": True}
    assert sampler_settings({}, "t", [])["main_tex_filter"] is TextureFilter.Point
    assert sampler_settings({"wrapS": 33071, "wrapT": 33071}, "t", [])["main_tex_wrap"] is TextureWrap.Clamp
    warnings = []
    assert sampler_settings({"wrapS": 33648, "wrapT": 33648}, "t", warnings)["main_tex_wrap"] is TextureWrap.Repeat
    assert warnings == ["t: MIRRORED_REPEAT (Unity's Mirror) is drawn as Repeat"]


def test_khr_texture_transform_flips_v_as_unigltf():
    warnings = []
    info = {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.25, 0.1], "scale": [2.0, 0.5]}}}
    # VerticalFlipScaleOffset: offset.y = 1 - o.y - s.y = 1 - 0.1 - 0.5 = 0.4
    assert texture_transform_st(info, "t", warnings) == ((2.0, 0.5), (0.25, pytest.approx(0.4)))
    info["extensions"]["KHR_texture_transform"]["rotation"] = 0.5
    texture_transform_st(info, "t", warnings)
    assert warnings == ["t: KHR_texture_transform rotation 0.5 is ignored, as UniGLTF ignores it"]
    assert texture_transform_st({"index": 0}, "t", []) == ((1.0, 1.0), (0.0, 0.0))


def test_bad_material_values_are_one_line_errors():
    with pytest.raises(GltfError, match=r"test.gltf: material 'M': _CullMode 3 is not a CullMode"):
        _vrm0({"shader": "VRM/MToon", "floatProperties": {"_CullMode": 3}})
    with pytest.raises(GltfError, match=r"_SrcBlend is not a number"):
        _vrm0({"shader": "VRM/MToon", "floatProperties": {"_SrcBlend": "One"}})
    with pytest.raises(GltfError, match=r"renderQueue 6000 is outside Unity's render queues"):
        _vrm0({"shader": "VRM/MToon", "renderQueue": 6000})


def test_json_record_is_the_shaderlab_record_per_material():
    result = _import(triangles_document([{"name": "Glass", "alphaMode": "BLEND"}]))
    data = json.loads(json.dumps(result.to_dict()))
    record = data["materials"][0]
    assert set(record) == {"index", "importer", "name", "material", "passes", "warnings", "extra"}
    assert record["name"] == "Glass" and record["material"]["enabled"] is True
    assert record["material"]["queue"] == "Transparent"
    forward, delta, shadow = record["passes"][:3]
    assert (forward["light_mode"], forward["drawn"], forward["reason"]) == (
        "ForwardBase", True, "ForwardBase: drawn once, with the main directional light")
    assert (delta["light_mode"], delta["drawn"]) == ("ForwardAdd", False)  # one directional light only
    assert (shadow["drawn"], shadow["reason"]) == (False, "ShadowCaster: renders shadow maps and the depth "
                                                          "texture, not the frame")
    assert data["warnings"][0].startswith("MToon and PBR shading are approximated")


def test_vrm0_outline_colour_keywords_decide_the_outline_colour():
    """MToonCore.cginc: ``MTOON_OUTLINE_COLOR_FIXED`` → ``col = _OutlineColor`` (mix 0, whatever
    ``_OutlineLightingMix`` says); ``_MIXED`` → ``_OutlineColor * lerp(1, col, _OutlineLightingMix)``;
    neither → the lit colour; MToon.shader's defaults ``_OutlineLightingMix`` 1, ``_OutlineColor`` (0,0,0,1)."""
    def line(keywords, floats=None, vectors=None):
        imported = _vrm0({"shader": "VRM/MToon", "floatProperties": {"_OutlineWidthMode": 1, **(floats or {})},
                          "keywordMap": {"MTOON_OUTLINE_WIDTH_WORLD": True, **keywords},
                          "vectorProperties": vectors or {}})
        p = imported.material.passes[1]
        return p.outline_color, p.outline_lighting_mix, imported.warnings

    red = {"_OutlineColor": [1.0, 0.0, 0.0, 1.0]}
    assert line({"MTOON_OUTLINE_COLOR_FIXED": True}, {"_OutlineLightingMix": 0.7}, red) == ((1.0, 0.0, 0.0), 0.0, ())
    assert line({"MTOON_OUTLINE_COLOR_MIXED": True}, {"_OutlineColorMode": 1, "_OutlineLightingMix": 0.75},
                red) == ((1.0, 0.0, 0.0), 0.75, ())
    assert line({"MTOON_OUTLINE_COLOR_MIXED": True}, {"_OutlineColorMode": 1})[:2] == ((0.0, 0.0, 0.0), 1.0)
    assert line({}, {}, red) == (None, 0.0, ())
    colour, mix, warnings = line({"MTOON_OUTLINE_COLOR_MIXED": True}, {"_OutlineLightingMix": 2.0})
    assert mix == 1.0 and len(warnings) == 2  # _OutlineColorMode 0 disagrees; the mix is drawn clamped
    assert "_OutlineColorMode 0 disagrees" in warnings[0] and "outside 0..1" in warnings[1]


def test_vrm1_outline_colour_is_converted_to_gamma_with_the_mix():
    """UniVRM sets ``_OutlineColor`` from the linear ``outlineColorFactor`` as ``_Color`` from
    ``baseColorFactor`` (gamma), ``_OutlineLightingMix`` from ``outlineLightingMixFactor`` (default 1)."""
    def line(**mtoon):
        doc = triangles_document([{"name": "M", "extensions": {"VRMC_materials_mtoon": {
            "specVersion": "1.0", "outlineWidthMode": "worldCoordinates", "outlineWidthFactor": 0.01, **mtoon}}}])
        doc["extensions"] = {"VRMC_vrm": {"specVersion": "1.0"}}
        p = _import(doc).materials[0].material.passes[1]
        return p.outline_color, p.outline_lighting_mix

    assert line() == ((0.0, 0.0, 0.0), 1.0)
    colour, mix = line(outlineColorFactor=[1.0, 0.0031308, 0.5], outlineLightingMixFactor=0.25)
    assert colour == pytest.approx((1.0, 0.0031308 * 12.92, 1.055 * 0.5 ** (1 / 2.4) - 0.055), rel=1e-6)
    assert mix == 0.25


def test_vrm_addon_settings_of_an_mtoon_material_export_to_the_same_state():
    """An MToon material of a .vrm as the VRM Add-on's settings (formats/gltf/addon_settings.py): its
    export (the add-on's exporter's values) imports as the file did; what the add-on's 0.x exporter
    never writes (``_OutlineCullMode`` 0: it always writes 1) cannot be held: None and why."""
    from blendlib.formats.gltf.addon_settings import addon_mtoon_of
    from blendlib.formats.gltf.vrm_addon import addon_material

    entry = {"shader": "VRM/MToon", "renderQueue": 2990,
             "floatProperties": {"_BlendMode": 2, "_SrcBlend": 5, "_DstBlend": 10, "_ZWrite": 0, "_CullMode": 0,
                                 "_OutlineWidthMode": 1, "_OutlineWidth": 0.5, "_OutlineColorMode": 1,
                                 "_OutlineLightingMix": 0.5},
             "keywordMap": {"_ALPHABLEND_ON": True, "MTOON_OUTLINE_WIDTH_WORLD": True,
                            "MTOON_OUTLINE_COLOR_MIXED": True},
             "vectorProperties": {"_Color": [0.5, 0.25, 1.0, 0.5], "_OutlineColor": [1.0, 0.5, 0.0, 1.0]}}
    doc = triangles_document([{"name": "M"}])
    doc["extensions"] = {"VRM": {"materialProperties": [entry]}}
    document = document_from_json(doc, "t.vrm")
    imported = import_materials(document).materials[0]
    mtoon, why = addon_mtoon_of(document, imported, "0.x")
    assert why is None and mtoon.mtoon0_render_queue == 2990 and mtoon.double_sided
    assert (mtoon.alpha_mode, mtoon.outline_width_mode, mtoon.outline_lighting_mix_factor) == (
        "BLEND", "worldCoordinates", 0.5)
    assert addon_material(mtoon, "0.x").material == imported.material
    entry["floatProperties"]["_OutlineCullMode"] = 0
    document = document_from_json(doc, "t.vrm")
    imported = import_materials(document).materials[0]
    mtoon, why = addon_mtoon_of(document, imported, "0.x")
    assert mtoon is None and "passes would differ" in why and "keeps Unity settings" in why
    # not MToon: no settings, no reason
    assert addon_mtoon_of(document, _import(triangles_document([{"name": "G"}])).materials[0], None) == (None, None)
