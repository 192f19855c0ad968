"""Property-based fuzzing of the ShaderLab importer.

Inputs are mutations of the book's listings (shared/seeds), of the exported presets and of
Unity's own surface, fixed-function and particle shaders: bytes deleted, duplicated, swapped,
replaced by ShaderLab-ish fragments (huge and non-finite numbers, braces, keywords, property
references, surface pragmas and options, fixed-function blocks, keyword branches). Every
outcome must be one of:

- a :class:`ShaderLabError` whose text starts ``FILE:LINE:COL:`` with a position inside the text;
- a result whose JSON is valid and finite (no ``Infinity``/``NaN``), and whose material builds.

Unity ``.mat`` files (the fixtures' layouts) are mutated the same way: a one-line
:class:`UnityFileError` naming the file, or values a shader imports with.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from blendlib.core.vocabulary import PASS_PRESETS, Material, preset
from blendlib.formats.shaderlab import (
    MAX_NESTING,
    ShaderLabError,
    UnityFileError,
    export_shaderlab,
    parse_shaderlab,
)
from blendlib.formats.shaderlab.material_file import parse_material_file
from tests.formats.test_shaderlab import RAW, cleaned
from tests.support.shared import BUILTIN_SHADERS

FILENAME = "fuzz.shader"
_POSITION_RE = re.compile(re.escape(FILENAME) + r":(\d+):(\d+): \S")


def _presets() -> list[str]:
    out = []
    for name in sorted(PASS_PRESETS):
        queue, passes = preset(name)
        out.append(export_shaderlab(Material(name=name, queue=queue, passes=passes)))
    return out


#: Unity's own shaders of each kind the importer reads: surface (alpha:fade, alphatest), fixed-function
#: (VertexLit, its AlphaTest and AlphaToMask; combiners with constants), particles, UI (stencil,
#: globals, keyword branches), Standard (keywords, [_Prop] state), GrabPass.
_UNITY = ["Alpha-Diffuse.shader", "AlphaTest-Diffuse.shader", "AlphaTest-VertexLit.shader", "Particle Add.shader",
          "Particle VertexLit Blended.shader", "UI/UI-Default.shader", "Standard.shader",
          "Particle Standard Unlit.shader", "Mobile/Mobile-Particle-Alpha.shader", "Lightmap-VertexLit.shader"]


def _unity_shaders() -> list[str]:
    folder = BUILTIN_SHADERS / "DefaultResourcesExtra"
    return [(folder / name).read_text(encoding="utf-8-sig") for name in _UNITY if (folder / name).is_file()]


CORPUS = [cleaned(key) for key in sorted(RAW)] + _presets() + _unity_shaders()

FRAGMENTS = [
    "{", "}", "(", ")", "[", "]", ",", "=", '"', "//", "/*", "*/", "\n", " ",
    "1e999", "-1e999", "1e308", "nan", "inf", "-0", "0x10", "255", "256", "3.5", "+", "-",
    "Pass", "SubShader", "Category {", "Properties", "Tags", "Stencil { Ref [_P] }", "Ref 1e999",
    "Cull [_P]", "ZTest [_P]", "Blend [_P] [_P]", "ColorMask [_P]", "Offset 1e999, 1", "Offset [_P], 0",
    '_P("p", Float) = 1e999', '_Color("c", Color) = (1e999, 0, 0, 1)', '_Cutoff("c", Range(0,1)) = 1e999',
    "CGPROGRAM", "ENDCG", "return fixed4(1-0.5,0,0,1);", "return fixed4(1e999,0,0,1);", "clip(a - _Cutoff);",
    "_LightColor0", '"Queue"="Transparent+1e999"', '"Queue"="99999999999999999999"', "\ufeff", "\x00", "é",
    # surface shaders
    "\n#pragma surface surf Lambert alpha:fade\n", "\n#pragma surface surf Standard alpha\n", "alphatest:_P",
    "alphatest:", "decal:blend", "decal:add", "alpha:premul", "noforwardadd", "exclude_path:forward", "addshadow",
    "nometa", "vertex:", "void surf (Input IN, inout SurfaceOutput o) { o.Albedo = 1; }",
    # fixed-function
    "SetTexture [_MainTex] { combine texture * primary DOUBLE, texture }", "SetTexture [_P] {", "combine",
    "combine previous lerp (texture) constant", "constantColor (1, 2", "constantColor [_P]", "Material {",
    "Material { Diffuse [_P] Shininess [_Color] }", "Diffuse (1,1,1,1)", "Lighting On", "Lighting [_P]",
    "ColorMaterial AmbientAndDiffuse", "SeparateSpecular On", "Color (1,0,0", "Color [_P]",
    "AlphaTest Greater [_P]", "AlphaTest", "AlphaTest Never 1e999", "AlphaToMask [_P]", "AlphaToMask True",
    # other commands and programs
    "GrabPass {", 'GrabPass { "_G" }', 'UsePass "X/Y"', 'UsePass "/"', 'Fallback "X"', "Fog { Mode Off }",
    "BindChannels {", "BlendOp Screen", "BlendOp [_P]", "Blend 1 One One", "ColorMask RGB 1", "ZTest Never",
    "ZTest [unity_GUIZTestMode]", "#ifdef _A\n", "#else\n", "#endif\n", "#if defined(_A) || !_B\n",
    "#pragma shader_feature _A\n", "#pragma multi_compile _ _A\n", "if (!(a > _P)) discard;", "clip(-1);",
    "i.color", "2.0f * i.color * _TintColor *", "c.rgb *= c.a;", '#include "UnitySprites.cginc"\n',
    '"LightMode"="ForwardAdd"', '"LightMode"="Vertex"', '"LightMode"=""',
]


def _mutate(draw, corpus: list[str], fragments: list[str], edits: int, span: int) -> str:
    """One text of ``corpus`` with 1..``edits`` edits of up to ``span`` characters: deleted,
    inserted or replaced by one of ``fragments``, or duplicated."""
    text = draw(st.sampled_from(corpus))
    for _ in range(draw(st.integers(1, edits))):
        n = len(text)
        i = draw(st.integers(0, n))
        j = draw(st.integers(i, min(n, i + span)))
        op = draw(st.sampled_from(["delete", "insert", "replace", "duplicate"]))
        if op == "delete":
            text = text[:i] + text[j:]
        elif op == "insert":
            text = text[:i] + draw(st.sampled_from(fragments)) + text[i:]
        elif op == "replace":
            text = text[:i] + draw(st.sampled_from(fragments)) + text[j:]
        else:
            text = text[:j] + text[i:j] + text[j:]
    return text


@st.composite
def mutated(draw) -> str:
    return _mutate(draw, CORPUS, FRAGMENTS, 6, 40)


def _reject_constant(name: str):
    raise AssertionError(f"JSON holds the non-finite constant {name}")


def _check(text: str) -> None:
    try:
        result = parse_shaderlab(text, filename=FILENAME)
    except ShaderLabError as exc:
        message = str(exc)
        m = _POSITION_RE.match(message)
        assert m, message
        assert "\n" not in message
        line, col = int(m.group(1)), int(m.group(2))
        lines = re.split(r"\r\n|\r|\n", text)
        assert 1 <= line <= len(lines), message
        assert 1 <= col <= len(lines[line - 1]) + 1, message
        return
    data = json.loads(result.to_json(), parse_constant=_reject_constant)
    assert isinstance(data["passes"], list), data
    material = result.material
    assert all(map(float.__eq__, material.color, material.color))  # finite: NaN != NaN
    assert all(abs(c) < float("inf") for c in material.color)
    for p in material.passes:
        assert abs(p.offset_factor) < float("inf") and abs(p.offset_units) < float("inf")


@settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_mutated_listings_give_a_positioned_error_or_finite_json(text):
    _check(text)


PROJECT = Path(__file__).resolve().parents[1] / "fixtures" / "unity_project"
MAT_CORPUS = [p.read_text(encoding="utf-8") for p in sorted(PROJECT.rglob("*.mat"))]
MAT_FRAGMENTS = [
    "\n", " ", ":", "- ", "{", "}", "[", "]", ",", "'", '"', "#", "&", "*", "!", "!u!21", "--- !u!21 &1\n",
    "--- !u!1 &2 stripped\n", "%TAG !u! tag:unity3d.com,2011:\n", "data:\n", "first:\n", "second: ",
    "name: _SrcBlend\n", "    - _ZWrite: ", "1e999", "nan", "-1", "00000000000000001000000000000000", "Off", ".5",
    "m_Shader: {fileID: 46, guid: 0000000000000000f000000000000000, type: 0}\n", "m_CustomRenderQueue: ",
    "{r: 1, g: 2}", "{x: nan, y: 1}", "m_ValidKeywords:\n  - _A\n", "\t", "\ufeff", "é",
]
CUSTOM_SHADER = (PROJECT / "Assets" / "Shaders" / "CustomBlend.shader").read_text(encoding="utf-8")


@st.composite
def mutated_material(draw) -> str:
    return _mutate(draw, MAT_CORPUS, MAT_FRAGMENTS, 5, 30)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_material())
def test_mutated_material_files_give_one_line_errors_or_values(text):
    try:
        mat = parse_material_file(text, "fuzz.mat")
    except UnityFileError as exc:
        assert str(exc).startswith("fuzz.mat") and "\n" not in str(exc)
        return
    assert all(abs(v) < float("inf") for v in mat.floats.values())
    assert all(abs(c) < float("inf") for color in mat.colors.values() for c in color)
    try:  # the values, keywords and queue as the custom shader imports them
        result = parse_shaderlab(CUSTOM_SHADER, "custom.shader", values=mat.values, keywords=mat.keywords,
                                 disabled_passes=mat.disabled_passes, material_name=mat.name,
                                 custom_render_queue=mat.custom_render_queue)
    except ShaderLabError as exc:
        assert str(exc).startswith("custom.shader:") and "\n" not in str(exc)
        return
    json.loads(result.to_json(), parse_constant=_reject_constant)


def test_the_corpus_itself_imports():
    for text in CORPUS:
        _check(text)
        parse_shaderlab(text, filename=FILENAME)  # no error at all


def test_nesting_deeper_than_the_limit_is_one_positioned_error():
    deep = 'Shader "a" {\n' + "Category {\n" * (MAX_NESTING + 1) + "}\n" * (MAX_NESTING + 1) + "}"
    try:
        parse_shaderlab(deep, filename=FILENAME)
    except ShaderLabError as exc:
        assert f"nested more than {MAX_NESTING} deep" in str(exc)
        assert str(exc).startswith(f"{FILENAME}:{MAX_NESTING + 2}:")
    else:
        raise AssertionError("no error")
    ok = 'Shader "a" {\n' + "Category {\n" * MAX_NESTING + "}\n" * MAX_NESTING + "}"
    parse_shaderlab(ok, filename=FILENAME)
    thousand = 'Shader "a" {' + "Category {" * 1000 + "}" * 1000 + "}"
    try:
        parse_shaderlab(thousand, filename=FILENAME)
    except ShaderLabError as exc:
        assert "nested more than" in str(exc)
    else:
        raise AssertionError("no error")


# --------------------------------------------------------------------------- the cases of issue 10

_PASS = 'Shader "a" {\nProperties { _P("p", Float) = %s }\nSubShader { Pass {\n%s\n} } }'


import pytest  # noqa: E402


@pytest.mark.parametrize("prop, command, line, col", [
    ("1", "Stencil { Ref 1e999 }", 4, 15),
    ("1e999", "Cull [_P]", 2, 31),
    ("1e999", "ZTest [_P]", 2, 31),
    ("1e999", "Blend [_P] Zero", 2, 31),
    ("1e999", "ColorMask [_P]", 2, 31),
    ("1e999", "Stencil { Ref [_P] }", 2, 31),
    ("1", "Offset 1e999, 0", 4, 8),
    ("1", "Offset 0, -1e999", 4, 11),
])
def test_non_finite_numbers_are_errors_at_their_position(prop, command, line, col):
    with pytest.raises(ShaderLabError) as err:
        parse_shaderlab(_PASS % (prop, command), filename=FILENAME)
    assert str(err.value).startswith(f"{FILENAME}:{line}:{col}: number ")
    assert "out of range" in str(err.value)


@pytest.mark.parametrize("prop", ['_Color("c", Color) = (1e999, 0, 0, 1)', '_Cutoff("c", Range(0, 1)) = 1e999',
                                  '_Cutoff("c", Float) = -1E+400'])
def test_non_finite_material_defaults_are_errors(prop):
    text = 'Shader "a" {\nProperties {\n' + prop + '\n}\nSubShader { Pass { } } }'
    with pytest.raises(ShaderLabError) as err:
        parse_shaderlab(text, filename=FILENAME)
    assert str(err.value).startswith(f"{FILENAME}:3:")


def test_constant_colour_expressions_in_cg_do_not_crash():
    body = "CGPROGRAM\nfixed4 frag() : SV_Target { return fixed4(1-0.5,0,0,1); }\nENDCG"
    result = parse_shaderlab(_PASS % ("1", body), filename=FILENAME)
    assert result.material.color == (1.0, 1.0, 1.0, 1.0)  # an expression is not a constant colour
    body = "CGPROGRAM\nfixed4 frag() : SV_Target { return fixed4(0.5h, .25, 1e0f, 1); }\nENDCG"
    result = parse_shaderlab(_PASS % ("1", body), filename=FILENAME)
    assert result.material.color == (0.5, 0.25, 1.0, 1.0)
    body = "CGPROGRAM\nfixed4 frag() : SV_Target { return fixed4(1e999, 0, 0, 1); }\nENDCG"
    result = parse_shaderlab(_PASS % ("1", body), filename=FILENAME)
    assert result.material.color == (1.0, 1.0, 1.0, 1.0)
    json.loads(result.to_json(), parse_constant=_reject_constant)


def test_repeated_warnings_are_capped_with_a_count():
    from blendlib.formats.shaderlab import MAX_REPEATED_WARNINGS

    text = 'Shader "a" { SubShader {\n' + "Foo 1\n" * 5000 + "Bar\n} }"
    result = parse_shaderlab(text, filename=FILENAME)
    foo = [w for w in result.warnings if "'Foo'" in w]
    assert len(foo) == MAX_REPEATED_WARNINGS + 1
    assert foo[:2] == ["2:1: unknown command 'Foo' in SubShader ignored",
                       "3:1: unknown command 'Foo' in SubShader ignored"]
    assert foo[-1] == (f"{MAX_REPEATED_WARNINGS + 2}:1: unknown command 'Foo' in SubShader ignored "
                       f"(and {5000 - MAX_REPEATED_WARNINGS - 1} more like this left out)")
    assert [w for w in result.warnings if "'Bar'" in w] == ["5002:1: unknown command 'Bar' in SubShader ignored"]


def test_many_passes_parse_in_linear_time_shape():
    # Not a timing test: 4000 passes give 4000 Pass objects with the state of each.
    text = 'Shader "a" { SubShader {\n' + "Pass { Cull Front ZWrite Off }\n" * 4000 + "} }"
    result = parse_shaderlab(text, filename=FILENAME)
    assert len(result.passes) == 4000
    assert {(p.cull.value, p.zwrite) for p in result.passes} == {("Front", False)}
