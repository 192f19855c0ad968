"""What the CG says (blendlib.formats.shaderlab.programs): keyword branches, the alpha test's forms,
vertex colours, premultiplication."""

from __future__ import annotations

import pytest

from blendlib.core.vocabulary import BlendFactor, CompareFunction, VertexColor
from blendlib.formats.shaderlab import parse_shaderlab
from blendlib.formats.shaderlab.programs import _condition, active_code, keyword_sets, keywords_in_effect

DECLARED = frozenset(["_A", "_B", "_C"])


@pytest.mark.parametrize("text,on,want", [
    ("_A", {"_A"}, True), ("!_A", {"_A"}, False), ("defined(_B)", {"_A"}, False), ("defined _A", {"_A"}, True),
    ("_A && _B", {"_A"}, False), ("_A || _B", {"_A"}, True), ("!(_A && _B)", {"_A"}, True),
    ("defined(_A) || !defined(_C)", set(), True),
    ("_A && OTHER", {"_A"}, None), ("(_A", {"_A"}, None), ("_A _B", set(), None), ("", set(), None),
    ("SHADER_API_D3D11", set(), None), ("_A == 1", {"_A"}, None),
])
def test_conditions_over_declared_keywords(text, on, want):
    assert _condition(text, DECLARED, frozenset(on)) is want


def test_active_code_takes_the_branches_of_the_keywords():
    code = "a\n#ifdef _A\nb\n#elif defined(_B)\nc\n#else\nd\n#endif\n#if UNKNOWN\ne\n#else\nf\n#endif\ng"
    assert active_code(code, DECLARED, frozenset(["_A"])).split() == ["a", "b", "e", "f", "g"]
    assert active_code(code, DECLARED, frozenset(["_B"])).split() == ["a", "c", "e", "f", "g"]
    assert active_code(code, DECLARED, frozenset()).split() == ["a", "d", "e", "f", "g"]


def test_keywords_in_effect_follow_unitys_variant_rules():
    sets = keyword_sets("#pragma multi_compile _ _A\n#pragma multi_compile_local _B _C\n"
                        "#pragma shader_feature_local _D\n#pragma multi_compile_fog\n")
    assert sets[:3] == [("multi_compile", ("_", "_A")), ("multi_compile", ("_B", "_C")), ("shader_feature", ("_D",))]
    assert ("multi_compile", ("_", "FOG_LINEAR", "FOG_EXP", "FOG_EXP2")) in sets
    # None of "_B _C" chosen: the first is the variant; "_ _A" and a lone shader_feature default to none.
    assert keywords_in_effect(sets, frozenset()) == {"_B"}
    assert keywords_in_effect(sets, frozenset(["_C", "_A", "_D", "_UNDECLARED"])) == {"_A", "_C", "_D"}


SHADER = """Shader "K" {{
Properties {{ _Cutoff ("c", Range(0,1)) = 0.5 [Toggle(_CLIP)] _Clip ("clip", Float) = {toggle}
              [KeywordEnum(None, Soft)] _Mode ("mode", Float) = {mode} }}
SubShader {{ Pass {{ Blend One OneMinusSrcAlpha CGPROGRAM
#pragma shader_feature _CLIP
#pragma multi_compile _MODE_NONE _MODE_SOFT
struct appdata {{ float4 vertex : POSITION; float4 color : COLOR; }};
fixed4 frag (v2f i) : SV_Target {{
    fixed4 c = tex2D(_MainTex, i.uv) * i.color;
    #ifdef _CLIP
    clip(c.a - _Cutoff);
    #endif
    #if _MODE_SOFT
    c.rgb *= c.a;
    #endif
    return c;
}}
ENDCG }} }} }}"""


def test_toggle_and_keyword_enum_defaults_choose_the_branches():
    (p,) = parse_shaderlab(SHADER.format(toggle=0, mode=0)).passes
    assert not p.alpha_test and (p.src_blend, p.separate_alpha) == (BlendFactor.One, False)
    result = parse_shaderlab(SHADER.format(toggle=1, mode=1))
    (p,) = result.passes
    assert p.alpha_test and p.alpha_test_comp is CompareFunction.GEqual
    assert (p.src_blend, p.dst_blend, p.src_blend_alpha, p.dst_blend_alpha) == (
        BlendFactor.SrcAlpha, BlendFactor.OneMinusSrcAlpha, BlendFactor.One, BlendFactor.OneMinusSrcAlpha)
    assert result.extra["keywords"] == ["_CLIP", "_MODE_SOFT"]
    assert result.material.vertex_color is VertexColor.Multiply  # "tex2D(_MainTex, i.uv) * i.color"
    # A .mat's keywords decide instead of the defaults.
    (p,) = parse_shaderlab(SHADER.format(toggle=1, mode=1), keywords=frozenset()).passes
    assert not p.alpha_test and not p.separate_alpha


@pytest.mark.parametrize("clip,comp,cutoff", [
    ("clip(c.a - _Cutoff);", CompareFunction.GEqual, 0.5), ("clip (c.a*_Color.a - _Other);", CompareFunction.GEqual,
                                                            0.25),
    ("clip(-(c.a - _Cutoff));", CompareFunction.LEqual, 0.5), ("clip(_Cutoff - c.a);", CompareFunction.LEqual, 0.5),
    ("clip(c.a - 0.125);", CompareFunction.GEqual, 0.125), ("clip(-1);", CompareFunction.Never, 0.5),
    ("if (!(c.a > _Cutoff)) discard;", CompareFunction.Greater, 0.5),
    ("if (!(c.a != _Cutoff)) discard;", CompareFunction.NotEqual, 0.5),
])
def test_alpha_test_forms(clip, comp, cutoff):
    text = ('Shader "T" { Properties { _Cutoff ("c", Range(0,1)) = 0.5 _Other ("o", Range(0,1)) = 0.25 } '
            f"SubShader {{ Pass {{ CGPROGRAM\nfixed4 frag () : SV_Target {{ fixed4 c = 1; {clip} return c; }}\n"
            "ENDCG } } }")
    result = parse_shaderlab(text)
    (p,) = result.passes
    assert p.alpha_test and p.alpha_test_comp is comp and result.material.cutoff == cutoff
    assert not any("discards fragments with its own condition" in w for w in result.warnings)
