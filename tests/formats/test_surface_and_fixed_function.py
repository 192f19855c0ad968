"""Surface shaders (SPEC §11.3) and fixed-function passes (§11.4).

Surface-shader state per option is what Unity's compiled listings show (docs/unity-shaders.md
quotes them: the compiled ``Legacy Shaders/Transparent/Diffuse`` for alpha:fade, the generated
code of alpha:premul, alphatest, noforwardadd, addshadow); fixed-function meanings are the Unity
manual's legacy pages ("Material", "SetTexture", "Alpha testing").
"""

from __future__ import annotations

import pytest

from blendlib.core.vocabulary import BlendFactor, CompareFunction, Cull, Lighting, LightMode, VertexColor
from blendlib.formats.shaderlab import parse_shaderlab

F = BlendFactor
RGB = frozenset("RGB")

SURF = """Shader "S" {{
Properties {{ _Color ("c", Color) = (0.5, 0.25, 1, 0.75) _MainTex ("t", 2D) = "white" {{}}
              _Cutoff ("cut", Range(0, 1)) = 0.3 _MyCut ("my", Range(0, 1)) = 0.7 }}
SubShader {{
    Tags {{ "Queue"="Transparent" }}
    {state}
CGPROGRAM
#pragma surface surf {model} {options}
sampler2D _MainTex; fixed4 _Color;
struct Input {{ float2 uv_MainTex; }};
void surf (Input IN, inout SurfaceOutput o) {{
    fixed4 c = tex2D(_MainTex, IN.uv_MainTex) * _Color;
    o.Albedo = c.rgb; o.Alpha = c.a;
}}
ENDCG
}}
}}"""


def _surf(options: str, model: str = "Lambert", state: str = ""):
    return parse_shaderlab(SURF.format(options=options, model=model, state=state))


def _by_mode(result):
    return {p.light_mode: p for p in result.passes}


def test_opaque_surface_shader_passes():
    """No option: FORWARD base (no state), FORWARD add 'ZWrite Off Blend One One', PREPASS base and
    final ('ZWrite Off'), DEFERRED, Meta ('Cull Off')."""
    result = _surf("")
    assert [(p.name, p.light_mode) for p in result.passes] == [
        ("FORWARD", LightMode.ForwardBase), ("FORWARD", LightMode.ForwardAdd), ("PREPASS", LightMode.PrepassBase),
        ("PREPASS", LightMode.PrepassFinal), ("DEFERRED", LightMode.Deferred), ("Meta", LightMode.Meta)]
    passes = _by_mode(result)
    base, add = passes[LightMode.ForwardBase], passes[LightMode.ForwardAdd]
    assert base.zwrite and not base.blend and base.color_mask == frozenset("RGBA")
    assert not add.zwrite and (add.src_blend, add.dst_blend) == (F.One, F.One)
    assert not passes[LightMode.PrepassFinal].zwrite and passes[LightMode.Meta].cull is Cull.Off
    assert result.material.lighting is Lighting.Lambert and result.material.color == (0.5, 0.25, 1, 0.75)
    assert not any("surf()" in w for w in result.warnings)  # the common tex2D(_MainTex, ...) * _Color form


@pytest.mark.parametrize("option,model,base,add", [
    ("alpha:fade", "Lambert", (F.SrcAlpha, F.OneMinusSrcAlpha), (F.SrcAlpha, F.One)),
    ("alpha:premul", "Lambert", (F.One, F.OneMinusSrcAlpha), (F.One, F.One)),
    ("alpha", "Lambert", (F.SrcAlpha, F.OneMinusSrcAlpha), (F.SrcAlpha, F.One)),  # auto: fade for simple models
    ("alpha:auto", "BlinnPhong", (F.SrcAlpha, F.OneMinusSrcAlpha), (F.SrcAlpha, F.One)),
    ("alpha:blend", "Lambert", (F.SrcAlpha, F.OneMinusSrcAlpha), (F.SrcAlpha, F.One)),
])
def test_alpha_options(option, model, base, add):
    """SubShader-level 'ZWrite Off ColorMask RGB' for every generated pass (the Meta pass too); no
    PREPASS/DEFERRED passes."""
    result = _surf(option, model)
    passes = _by_mode(result)
    assert set(passes) == {LightMode.ForwardBase, LightMode.ForwardAdd, LightMode.Meta}
    for p in passes.values():
        assert not p.zwrite and p.color_mask == RGB
    assert (passes[LightMode.ForwardBase].src_blend, passes[LightMode.ForwardBase].dst_blend) == base
    assert (passes[LightMode.ForwardAdd].src_blend, passes[LightMode.ForwardAdd].dst_blend) == add
    assert any("alpha:blend imported as alpha:fade" in w for w in result.warnings) is (option == "alpha:blend")


def test_alpha_auto_premultiplies_for_physically_based_models():
    """'alpha or alpha:auto … premultiplied transparency (same as alpha:premul) for physically based
    lighting functions'; Standard's premultiplication moves into the blend (Blend SrcAlpha …, One …)."""
    result = _surf("alpha", "Standard")
    base = _by_mode(result)[LightMode.ForwardBase]
    assert (base.src_blend, base.dst_blend, base.separate_alpha) == (F.SrcAlpha, F.OneMinusSrcAlpha, True)
    assert (base.src_blend_alpha, base.dst_blend_alpha) == (F.One, F.OneMinusSrcAlpha)
    assert any("lighting model Standard is drawn as Lambert" in w for w in result.warnings)


def test_alphatest_clips_at_the_named_property_in_every_pass():
    """'alphatest:_MyCut' → 'clip (o.Alpha - _MyCut)' and ColorMask RGB; the cutoff is _MyCut's 0.7."""
    result = _surf("alphatest:_MyCut")
    passes = _by_mode(result)
    for mode in (LightMode.ForwardBase, LightMode.ForwardAdd, LightMode.PrepassBase, LightMode.Deferred):
        assert passes[mode].alpha_test and passes[mode].alpha_test_comp is CompareFunction.GEqual
    assert not passes[LightMode.Meta].alpha_test
    assert passes[LightMode.ForwardBase].color_mask == RGB and passes[LightMode.ForwardBase].zwrite
    assert result.material.cutoff == 0.7 and result.extra["cutoff_property"] == "_MyCut"


def test_pass_options():
    passes = _by_mode(_surf("noforwardadd nometa addshadow exclude_path:prepass"))
    assert set(passes) == {LightMode.ForwardBase, LightMode.Deferred, LightMode.ShadowCaster}
    caster = passes[LightMode.ShadowCaster]
    assert caster.zwrite and caster.ztest is CompareFunction.LEqual
    assert set(_by_mode(_surf("exclude_path:forward exclude_path:deferred"))) == {
        LightMode.PrepassBase, LightMode.PrepassFinal, LightMode.Meta}


def test_decal_options_are_imported_and_warned():
    base = _by_mode(_surf("decal:add"))[LightMode.ForwardBase]
    assert (base.src_blend, base.dst_blend, base.zwrite) == (F.One, F.One, False)
    result = _surf("decal:blend")
    base = _by_mode(result)[LightMode.ForwardBase]
    assert (base.src_blend, base.dst_blend, base.zwrite) == (F.SrcAlpha, F.OneMinusSrcAlpha, False)
    assert any("decal:blend imported as" in w for w in result.warnings)


def test_author_state_is_inherited_and_generated_pass_state_wins():
    """'Cull Off' at SubShader level reaches every generated pass; the author's 'Blend One One' is
    overridden by alpha:fade's pass-level 'Blend SrcAlpha OneMinusSrcAlpha'."""
    passes = _by_mode(_surf("alpha:fade", state="Cull Off Blend One One"))
    assert all(p.cull is Cull.Off for p in passes.values())
    base = passes[LightMode.ForwardBase]
    assert (base.src_blend, base.dst_blend) == (F.SrcAlpha, F.OneMinusSrcAlpha)


def test_a_surf_body_of_another_form_is_warned():
    text = SURF.format(options="", model="Lambert", state="").replace(
        "tex2D(_MainTex, IN.uv_MainTex) * _Color", "_Color.bgra")
    assert any("imported as _MainTex × _Color" in w for w in parse_shaderlab(text).warnings)


def test_hand_written_passes_keep_their_place_around_generated_ones():
    text = SURF.format(options="noforwardadd nometa exclude_path:deferred exclude_path:prepass", model="Lambert",
                       state='Pass { Name "PRE" ZWrite On ColorMask 0 }')
    assert [p.name for p in parse_shaderlab(text).passes] == ["PRE", "FORWARD"]


# --------------------------------------------------------------------------- fixed-function

FF = """Shader "FF" {{
Properties {{ _Color ("c", Color) = (0.5, 0.25, 1, 0.5) _MainTex ("t", 2D) = "white" {{}}
              _Cutoff ("cut", Range(0, 1)) = 0.4 _Const ("k", Color) = (0.5, 0.5, 0.5, 0.25) }}
SubShader {{ Pass {{ {body} }} }}
}}"""


def _ff(body: str):
    return parse_shaderlab(FF.format(body=body))


def test_unlit_combine_texture_primary_is_a_vertex_colour_multiply():
    """'SetTexture [_MainTex] { combine texture * primary }' with Lighting Off and no Color: primary is
    the vertex colour."""
    m = _ff("SetTexture [_MainTex] { combine texture * primary }").material
    assert (m.lighting, m.vertex_color, m.color) == (Lighting.Unlit, VertexColor.Multiply, (1.0, 1.0, 1.0, 1.0))


def test_color_command_and_constant_colour_fold_into_the_colour():
    m = _ff("Color [_Color] SetTexture [_MainTex] { constantColor [_Const] combine texture * primary * constant }"
            ).material
    assert m.vertex_color is VertexColor.Off and m.lighting is Lighting.Unlit
    assert m.color == pytest.approx((0.25, 0.125, 0.5, 0.125))  # _Color x _Const
    m = _ff("Color (1, 0.5, 0.5, 1) SetTexture [_MainTex] { combine texture * primary DOUBLE }").material
    assert m.color == pytest.approx((2.0, 1.0, 1.0, 1.0))  # unlit DOUBLE: x2 on the colour


def test_lit_fixed_function_uses_the_material_block():
    """'Material { Diffuse [_Color] } Lighting On' 'combine texture * primary DOUBLE': Lambert of
    _Color; the fixed-function lighting inputs are half the programmable ones, which DOUBLE undoes."""
    result = _ff("Material { Diffuse [_Color] Emission (0.1, 0, 0, 0) } Lighting On "
                 "SetTexture [_MainTex] { combine texture * primary DOUBLE }")
    m = result.material
    assert m.lighting is Lighting.Lambert and m.color == (0.5, 0.25, 1.0, 0.5)
    assert any("Lighting On" in w and "approximated" in w for w in result.warnings)
    assert any("Material Emission is not drawn" in w for w in result.warnings)
    m = _ff("Lighting On ColorMaterial AmbientAndDiffuse SetTexture [_MainTex] { combine primary * texture DOUBLE }"
            ).material
    assert m.vertex_color is VertexColor.Multiply and m.color == (1.0, 1.0, 1.0, 1.0)


@pytest.mark.parametrize("command,comp", [
    ("AlphaTest Greater [_Cutoff]", CompareFunction.Greater), ("AlphaTest GEqual [_Cutoff]", CompareFunction.GEqual),
    ("AlphaTest Less 0.4", CompareFunction.Less), ("AlphaTest LEqual [_Cutoff]", CompareFunction.LEqual),
    ("AlphaTest Equal [_Cutoff]", CompareFunction.Equal), ("AlphaTest NotEqual [_Cutoff]", CompareFunction.NotEqual),
    ("AlphaTest Never", CompareFunction.Never), ("Alphatest Greater [_Cutoff]", CompareFunction.Greater),
])
def test_alpha_test_command(command, comp):
    result = _ff(f"{command} SetTexture [_MainTex] {{ combine texture }}")
    (p,) = result.passes
    assert p.alpha_test and p.alpha_test_comp is comp
    assert result.material.cutoff == 0.4


@pytest.mark.parametrize("command", ["AlphaTest Off", "AlphaTest Always", "AlphaTest off"])
def test_alpha_test_off_and_always_test_nothing(command):
    (p,) = _ff(f"{command} SetTexture [_MainTex] {{ combine texture }}").passes
    assert not p.alpha_test


def test_combiners_that_are_not_products_are_warned():
    result = _ff("SetTexture [_MainTex] { combine texture lerp (texture) primary }")
    assert any("drawn as texture × primary (approximated)" in w for w in result.warnings)


def test_fixed_function_commands_in_a_program_pass_are_listed_as_ignored():
    result = parse_shaderlab('Shader "T" { SubShader { Pass { Lighting On Material { Diffuse (1,1,1,1) } '
                             "CGPROGRAM\nfloat4 frag() : SV_Target { return 1; }\nENDCG } } }")
    assert sum("ignored: the pass has a program" in w for w in result.warnings) == 2
    assert result.material.lighting is Lighting.Unlit
