"""State as Unity compiles it (SPEC §11.1): commands consumed exactly, globals, AlphaToMask,
render targets, advanced BlendOps, ZTest Never, LightModes (§11.2) and the record's drawn/reason."""

from __future__ import annotations

import pytest

from blendlib.core.vocabulary import BlendFactor, BlendOp, CompareFunction, Cull, LightMode, Pass
from blendlib.formats.shaderlab import ShaderLabError, parse_shaderlab

F = BlendFactor


def _shader(pass_body: str, sub: str = "", props: str = "", category: str = "") -> str:
    return (f'Shader "T" {{ Properties {{ {props} }} Category {{ {category} SubShader {{ {sub} '
            f"Pass {{ {pass_body} }} }} }} }}")


def _one(pass_body: str, **kw) -> Pass:
    (p,) = parse_shaderlab(_shader(pass_body, **kw)).passes
    return p


def test_several_commands_share_a_line_with_ignored_ones_among_them():
    """The particles' 'Cull Off Lighting Off ZWrite Off', with Fog blocks and BindChannels between."""
    text = _shader("", category="Cull Off Lighting Off ZWrite Off Fog { Color (0,0,0,0) } Blend One One "
                                "BindChannels { Bind \"Color\", color } ColorMask RGB LOD 100 ZTest Greater")
    result = parse_shaderlab(text)
    (p,) = result.passes
    assert p.cull is Cull.Off and not p.zwrite and p.blend and (p.src_blend, p.dst_blend) == (F.One, F.One)
    assert p.color_mask == frozenset("RGB") and p.ztest is CompareFunction.Greater
    messages = [w.split(": ", 1)[1] for w in result.warnings]
    assert "Fog ignored: fog is not drawn" in messages
    assert "BindChannels ignored: vertex data is bound by name here" in messages
    assert any(m.startswith("LOD ignored") for m in messages)


def test_an_unknown_command_is_skipped_up_to_the_next_command_on_its_line():
    result = parse_shaderlab(_shader("Frobnicate 1 2 { x } Cull Front Wibble 3 ZWrite Off"))
    (p,) = result.passes
    assert p.cull is Cull.Front and not p.zwrite
    assert sum("unknown command" in w for w in result.warnings) == 2


def test_category_subshader_pass_inheritance_command_by_command():
    text = ('Shader "T" { Category { ZWrite Off Cull Front Blend One One SubShader { Cull Off ZTest Always '
            'Pass { Name "A" } Pass { Name "B" Cull Back Blend Off } } } }')
    a, b = parse_shaderlab(text).passes
    assert (a.zwrite, a.cull, a.blend, a.ztest) == (False, Cull.Off, True, CompareFunction.Always)
    assert (b.zwrite, b.cull, b.blend, b.ztest) == (False, Cull.Back, False, CompareFunction.Always)


@pytest.mark.parametrize("word,want", [("On", True), ("Off", False), ("True", True), ("false", False),
                                       ("[_A2M]", True), ("[_Zero]", False)])
def test_alpha_to_mask_values(word, want):
    """'AlphaToMask True' (AlphaTest-VertexLit.shader) and '[_AlphaToMask]' (CameraFacingBillboardTree)."""
    p = _one(f"AlphaToMask {word}", props='_A2M ("a", Float) = 1 _Zero ("z", Float) = 0')
    assert p.alpha_to_mask is want


def test_globals_read_as_zero_and_the_gui_ztest_as_lequal():
    result = parse_shaderlab(_shader("ZTest [unity_GUIZTestMode] Cull [_NotDeclared] Blend [_SrcG] [_DstG]"))
    (p,) = result.passes
    assert p.ztest is CompareFunction.LEqual  # CompareFunction.LessEqual = 4, what Unity's UI sets
    assert p.cull is Cull.Off  # 0
    assert (p.src_blend, p.dst_blend) == (F.Zero, F.Zero)
    assert sum("a global, which Unity reads as 0" in w for w in result.warnings) == 3
    assert sum("unity_GUIZTestMode" in w for w in result.warnings) == 1


def test_render_targets_other_than_zero_are_ignored():
    result = parse_shaderlab(_shader("Blend SrcAlpha OneMinusSrcAlpha Blend 1 One One ColorMask RGB "
                                     "ColorMask A 2 Blend 0 DstColor Zero"))
    (p,) = result.passes
    assert (p.src_blend, p.dst_blend) == (F.DstColor, F.Zero)  # Blend 0 … is render target 0
    assert p.color_mask == frozenset("RGB")
    assert sum("ignored: the frame is render target 0" in w for w in result.warnings) == 2


@pytest.mark.parametrize("op", ["Multiply", "Screen", "HSLLuminosity", "LogicalXor", "[_Op]"])
def test_logical_and_advanced_blend_ops_draw_as_add(op):
    result = parse_shaderlab(_shader(f"Blend One One BlendOp {op}", props='_Op ("op", Float) = 21'))
    (p,) = result.passes
    assert p.blend_op is BlendOp.Add
    assert any("draws as Add" in w for w in result.warnings)


def test_an_arithmetic_blend_op_property_is_read_by_unity_numbering():
    result = parse_shaderlab(_shader("Blend One One BlendOp [_Op]", props='_Op ("op", Float) = 4'))
    assert result.passes[0].blend_op is BlendOp.Max and not any("BlendOp" in w for w in result.warnings)


def test_ztest_never_is_listed_but_draws_nothing():
    text = 'Shader "T" { SubShader { Pass { Name "Hidden" ZTest Never } Pass { Name "Shown" } } }'
    result = parse_shaderlab(text)
    assert [p.name for p in result.passes] == ["Shown"]
    hidden = result.to_dict()["passes"][0]
    assert hidden["name"] == "Hidden" and hidden["drawn"] is False and hidden["reason"].startswith("ZTest Never")


@pytest.mark.parametrize("tag,mode,drawn", [
    (None, LightMode.Always, True), ("Always", LightMode.Always, True), ("ForwardBase", LightMode.ForwardBase, True),
    ("forwardadd", LightMode.ForwardAdd, False), ("ShadowCaster", LightMode.ShadowCaster, False),
    ("PrePassBase", LightMode.PrepassBase, False), ("Meta", LightMode.Meta, False),
    ("Deferred", LightMode.Deferred, False), ("MotionVectors", LightMode.MotionVectors, False),
    ("VertexLM", LightMode.VertexLM, False), ("UniversalForward", LightMode.Other, False),
])
def test_light_modes_and_what_draws(tag, mode, drawn):
    tags = f'Tags {{ "LightMode"="{tag}" }}' if tag else ""
    result = parse_shaderlab(_shader(tags))
    (p,) = result.passes
    assert p.light_mode is mode
    (entry,) = result.to_dict()["passes"]
    assert entry["light_mode"] == mode.value and entry["drawn"] is drawn
    assert result.extra["light_modes"] == [tag]


def test_vertex_passes_draw_only_without_forward_passes():
    vertex = 'Pass { Name "V" Tags { "LightMode"="Vertex" } }'
    alone = parse_shaderlab(f'Shader "T" {{ SubShader {{ {vertex} }} }}').to_dict()["passes"]
    assert alone[0]["drawn"] and "no forward passes" in alone[0]["reason"]
    beside = parse_shaderlab(f'Shader "T" {{ SubShader {{ Pass {{ Tags {{ "LightMode"="ForwardBase" }} }} '
                             f"{vertex} }} }}").to_dict()["passes"]
    assert beside[0]["drawn"] and not beside[1]["drawn"] and "forward passes" in beside[1]["reason"]


def test_bad_values_still_raise_one_positioned_error():
    with pytest.raises(ShaderLabError) as err:
        parse_shaderlab(_shader("AlphaToMask Maybe"), "x.shader")
    assert str(err.value).startswith("x.shader:1:") and "unknown AlphaToMask value 'Maybe'" in str(err.value)
    with pytest.raises(ShaderLabError, match="unknown ColorMaterial"):
        parse_shaderlab(_shader("ColorMaterial Sometimes"))
    with pytest.raises(ShaderLabError, match="unknown Material command"):
        parse_shaderlab(_shader("Material { Glow (1,1,1,1) }"))


def test_use_pass_and_fallback_through_a_search_path(tmp_path):
    """UsePass names are upper-cased ('Note that internally all pass names are uppercased'); all passes
    of the name are inserted (2019.4 manual), with their own state; a missing shader or pass, two
    shaders that use each other and a missing Fallback are warnings, never an error."""
    from blendlib.formats.shaderlab import parse_shaderlab_file

    (tmp_path / "Other.shader").write_text(
        'Shader "Lib/Other" { SubShader { ZWrite Off Pass { Name "Add" Blend One One } '
        'Pass { Name "ADD" Cull Front } Pass { Name "Solo" } } }', encoding="utf-8")
    (tmp_path / "Loop.shader").write_text('Shader "Lib/Loop" { SubShader { UsePass "User/OWN" Pass { Name "X" } } }',
                                          encoding="utf-8")
    user = tmp_path / "sub" / "User.shader"
    user.parent.mkdir()
    user.write_text('Shader "User" { SubShader { Cull Off UsePass "Lib/Other/ADD" Pass { Name "Own" } '
                    'UsePass "Lib/Missing/X" UsePass "Lib/Other/NOPE" UsePass "Lib/Loop/X" } }', encoding="utf-8")
    result = parse_shaderlab_file(str(user), (str(tmp_path),))
    add, add2, own, loop = result.passes  # Loop's UsePass back into User is a cycle, left out: one X
    assert (add.name, add.blend, add.zwrite, add.cull) == ("Add", True, False, Cull.Back)  # its own state
    assert (add2.name, add2.cull, add2.zwrite) == ("ADD", Cull.Front, False)
    assert (own.name, own.cull) == ("Own", Cull.Off) and loop.name == "X"
    w = " ".join(result.warnings)
    assert "2 passes have that name; all are inserted" in w
    assert "no shader named 'Lib/Missing'" in w and "has no pass named 'NOPE'" in w
    (tmp_path / "NoSub.shader").write_text('Shader "NoSub" { Fallback "Lib/Nowhere" }', encoding="utf-8")
    result = parse_shaderlab_file(str(tmp_path / "NoSub.shader"))
    assert result.passes == () and any('Fallback "Lib/Nowhere" is not on the search path' in x
                                       for x in result.warnings)


def test_use_pass_of_a_pass_of_the_same_shader():
    text = ('Shader "Self" { SubShader { Pass { Name "Base" Cull Front } UsePass "Self/BASE" '
            'UsePass "Self/MISSING" } }')
    result = parse_shaderlab(text)
    assert [(p.name, p.cull) for p in result.passes] == [("Base", Cull.Front), ("Base", Cull.Front)]
    assert any("Self has no pass named 'MISSING'" in w for w in result.warnings)
