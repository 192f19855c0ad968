"""ShaderLab import/export: seed listings, the grammar, malformed input, round trips, the CLI."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from dataclasses import fields, replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blendlib.cli import main as cli_main
from blendlib.core.vocabulary import (
    PASS_PRESETS,
    BlendFactor,
    BlendOp,
    CompareFunction,
    Cull,
    Lighting,
    LightMode,
    Material,
    Pass,
    Queue,
    StencilOp,
    pass_to_dict,
    preset,
)
from blendlib.formats.shaderlab import (
    ShaderLabError,
    canonical_pass,
    export_shaderlab,
    parse_queue,
    parse_shaderlab,
)
from tests.support.shared import REPO, SHARED

SEEDS = SHARED / "seeds"

SA, OMSA = BlendFactor.SrcAlpha, BlendFactor.OneMinusSrcAlpha

# --------------------------------------------------------------------------- seed listings
#
# The tutorials hold their shaders in three shapes: line-numbered Markdown fences that a
# PDF scan split into several fences (000, 003), an HTML <pre> block (001) and plain text
# (001, 002). The cleaning below is test code: the parser only ever sees ShaderLab.

_FENCE_RE = re.compile(r"^```[^\n]*\n(.*?)^```", re.M | re.S)
_NUMBER_RE = re.compile(r"^\s*(\d+)(?:\s*\|)?(?:[ \t]|$)")


def _numbered_listings(text: str) -> list[str]:
    """Listings in line-numbered fences, number prefixes removed. A fence continues the previous
    one when its first line number follows on from that fence's last (a page break in the scan)."""
    groups: list[list[str]] = []
    current: list[str] | None = None
    last = None
    for m in _FENCE_RE.finditer(text):
        lines, numbers = [], []
        for line in m.group(1).splitlines():
            n = _NUMBER_RE.match(line)
            if n:
                numbers.append(int(n.group(1)))
                line = line[n.end():]
            lines.append(line)
        if not numbers:
            current = None
            continue
        if current is not None and numbers[0] > 1 and last - 5 <= numbers[0] <= last + 2:
            current.extend(lines)
        else:
            current = lines
            groups.append(current)
        last = numbers[-1]
    out = []
    for lines in groups:
        starts = [i for i, line in enumerate(lines) if line.lstrip().startswith('Shader "')]
        if starts:
            out.append("\n".join(lines[starts[0]:]))
    return out


def _plain_listings(text: str) -> list[str]:
    """``Shader "..." { ... }`` in plain text or HTML <pre>: from the Shader line to its balancing brace."""
    text = re.sub(r"</?pre[^>]*>", "\n", text)
    out = []
    for m in re.finditer(r'^Shader "', text, re.M):
        depth = 0
        for i in range(m.start(), len(text)):
            if text[i] == "{":
                depth += 1
            elif text[i] == "}":
                depth -= 1
                if depth == 0:
                    out.append(text[m.start(): i + 1])
                    break
    return out


_SHADERLAB_START = re.compile(
    r'^\s*(?:"|\{|\}|//|/\*|_|\[|(?:Shader|Properties|SubShader|Pass|Tags|Cull|ZWrite|ZTest|Blend|BlendOp|'
    r"ColorMask|Offset|Stencil|CGPROGRAM|ENDCG|Fallback|Name|LOD)\b)",
    re.I,
)


def _rejoin_wrapped_comments(listing: str) -> tuple[str, int]:
    """The PDF scan wrapped long ``//`` comments onto numbered lines of their own ("AlphaTest;",
    "(Projectors) 的影响。"). Outside CGPROGRAM, a line after a comment line that cannot start
    ShaderLab is such a tail: make it a comment again. Returns the text and how many were fixed."""
    out, fixed, in_cg, prev_comment = [], 0, False, False
    for line in listing.splitlines():
        stripped = line.strip()
        if re.match(r"CGPROGRAM\b", stripped):
            in_cg = True
        if not in_cg and prev_comment and stripped and not _SHADERLAB_START.match(line):
            line = "// " + stripped
            fixed += 1
        if re.match(r"ENDCG\b", stripped):
            in_cg = False
        prev_comment = line.strip().startswith("//") if stripped else prev_comment
        out.append(line)
    return "\n".join(out), fixed


def _insert_after(listing: str, marker: str, occurrence: int, text: str) -> str:
    """Insert lines after the ``occurrence``-th (1-based) line that starts with ``marker``."""
    lines = listing.splitlines()
    hits = [i for i, line in enumerate(lines) if line.strip().startswith(marker)]
    lines.insert(hits[occurrence - 1] + 1, text)
    return "\n".join(lines)


def seed_listings() -> dict[str, str]:
    """Every ``Shader "..."`` listing of shared/seeds, keyed ``<seed>#<n>``, cleaned and repaired."""
    out = {}
    for path in sorted(SEEDS.glob("*.txt")):
        text = path.read_text(encoding="utf-8")
        listings = _numbered_listings(text) or _plain_listings(text)
        for n, listing in enumerate(listings, 1):
            out[f"{path.stem[:3]}#{n}"] = listing
    return out


RAW = seed_listings()

# Damage of the scan that the generic cleaning cannot know: braces the page breaks dropped.
# The book's C_8 Blend ends "} ENDCG } } Fallback ... }"; the scan lost the two closing braces
# after ENDCG. C_8 Blend BothSide lost the brace closing its first Pass.
_REPAIRS = {
    "000#2": lambda s: _insert_after(s, "ENDCG", 1, "        }\n    }"),
    "000#3": lambda s: _insert_after(s, "ENDCG", 1, "        }"),
}


def cleaned(key: str) -> str:
    text, _ = _rejoin_wrapped_comments(RAW[key])
    return _REPAIRS.get(key, lambda s: s)(text)


def test_every_seed_listing_is_found():
    names = {k: re.match(r'\s*Shader "([^"]*)"', v).group(1) for k, v in RAW.items()}
    assert names == {
        "000#1": "Unity Shaders Book/C_8/C_8 Alpha Test",
        "000#2": "Unity Shaders Book/C_8/C_8 Blend",
        "000#3": "Unity Shaders Book/C_8/C_8 Blend BothSide",
        "001#1": "Custom/AlphaTest",
        "001#2": "Custom/AlphaBlendShader",
        "001#3": "Custom/AlphaBlendShader",
        "002#1": "MyShader/Tranparent/AlphaTest",
        "002#2": "MyShader/Transparent/AlphaBlend",
        "002#3": "MyShader/Transparent/AlphaBlend",
        "002#4": "MyShader/Transparent/AlphaBlendBothSide",
        "003#1": "Cg shader using blending",
        "003#2": "Cg shader using blending",
    }


def test_the_scan_damage_is_reported_with_a_position():
    """Uncleaned, the damaged book listings do not import: the error says where."""
    with pytest.raises(ShaderLabError) as err:
        parse_shaderlab(RAW["000#1"], "C_8 Alpha Test.shader")
    assert (err.value.line, err.value.column) == (17, 13)  # "AlphaTest;" inside Tags { }
    assert str(err.value).startswith("C_8 Alpha Test.shader:17:13: expected a tag")
    text, fixed = _rejoin_wrapped_comments(RAW["000#1"])
    assert fixed == 3
    with pytest.raises(ShaderLabError) as err:  # C_8 Blend without its two closing braces
        parse_shaderlab(_rejoin_wrapped_comments(RAW["000#2"])[0])
    assert (err.value.line, err.value.column) == (12, 5) and "SubShader is never closed" in err.value.message
    with pytest.raises(ShaderLabError) as err:
        parse_shaderlab(RAW["000#3"])
    assert (err.value.line, err.value.column) == (86, 5)  # the second Pass, inside the first
    assert err.value.message == "Pass inside a Pass: is the '}' closing the Pass at 18:8 missing?"



def test_a_word_where_a_colour_goes_is_reported_with_its_position():
    """A fixed-function ``Color`` followed by a word (here a stray line run into the next command,
    as the fuzz test found: ``i.color ZWrite Off``) is a positioned error, not a crash; the
    literal and the reference forms import."""
    with pytest.raises(ShaderLabError) as err:
        parse_shaderlab('Shader "T" {\n SubShader { Pass {\n  Color ZWrite Off\n } }\n}\n', "t.shader")
    assert (err.value.line, err.value.column) == (3, 9)
    assert str(err.value) == ("t.shader:3:9: expected a colour (r, g, b, a) or a [Property] for Color, "
                              "found 'ZWrite'")
    for colour in ("(1, 0.5, 0, 1)", "[_Tint]"):
        parse_shaderlab('Shader "T" {\n Properties { _Tint ("Tint", Color) = (1, 1, 1, 1) }\n'
                        f' SubShader {{ Pass {{\n  Color {colour}\n }} }}\n}}\n', "t.shader")

ALWAYS, OTHER = LightMode.Always, LightMode.Other


def _blend_pass(name="Pass", **kw):
    return Pass(name=name, zwrite=False, blend=True, src_blend=SA, dst_blend=OMSA, **kw)


_LAMBERT_TEST = dict(queue=Queue.AlphaTest, lighting=Lighting.Lambert, render_type="TransparentCutout")
_LAMBERT_BLEND = dict(queue=Queue.Transparent, lighting=Lighting.Lambert, render_type="Transparent")

# What each listing's text states.
SEED_EXPECTED = {
    "000#1": dict(**_LAMBERT_TEST, cutoff=0.5, alpha_scale=1.0, color=(1, 1, 1, 1),
                  passes=[Pass(name="Pass", alpha_test=True)],  # "// Cull Off" is commented out
                  light_modes=["ForwardBase"], fallback="Transparent/Cutout/VertexLit", ignore_projector=True),
    "000#2": dict(**_LAMBERT_BLEND, alpha_scale=1.0, passes=[_blend_pass()], light_modes=["ForwardBase"],
                  fallback="Transparent/VertexLit", ignore_projector=True),
    "000#3": dict(**_LAMBERT_BLEND, alpha_scale=1.0,
                  passes=[_blend_pass("Pass 1", cull=Cull.Front), _blend_pass("Pass 2", cull=Cull.Back)],
                  light_modes=["ForwardBase", "ForwardBase"], fallback="Transparent/VertexLit"),
    # clip(texColor.a - _AlphaValue): the cutoff is _AlphaValue's default.
    "001#1": dict(**_LAMBERT_TEST, cutoff=0.5, passes=[Pass(name="Pass", alpha_test=True)],
                  light_modes=["ForwardBase"], fallback="Tranaparent/Cutout/VertexLit", ignore_projector=True),
    "001#2": dict(**_LAMBERT_BLEND, alpha_scale=0.5, passes=[_blend_pass()],
                  fallback="Transparent/Cutout/VertexLit"),
    "001#3": dict(**_LAMBERT_BLEND, alpha_scale=0.5,
                  passes=[_blend_pass("Pass 1", cull=Cull.Front), _blend_pass("Pass 2", cull=Cull.Back)]),
    # No _Color property: _Color stays white (the listing's fragment uses the texture only).
    # The URP tutorial's passes are tagged "UniversalForward": not a LightMode of the built-in
    # forward path, so Other (listed, never drawn: SPEC §11.2).
    "002#1": dict(**_LAMBERT_TEST, cutoff=0.5, color=(1, 1, 1, 1),
                  passes=[Pass(name="Pass", alpha_test=True, light_mode=OTHER)],
                  light_modes=["UniversalForward"], fallback="Transparent/Cutout/VertexLit"),
    "002#2": dict(**_LAMBERT_BLEND, alpha_scale=1.0, passes=[_blend_pass(light_mode=OTHER)]),
    # The depth prepass: ZWrite On, ColorMask 0, no program, no LightMode (Always).
    "002#3": dict(**_LAMBERT_BLEND, alpha_scale=1.0,
                  passes=[Pass(name="Pass 1", zwrite=True, color_mask=frozenset(), light_mode=ALWAYS),
                          _blend_pass("Pass 2", light_mode=OTHER)],
                  light_modes=[None, "UniversalForward"]),
    "002#4": dict(**_LAMBERT_BLEND, passes=[_blend_pass("Pass 1", cull=Cull.Front, light_mode=OTHER),
                                            _blend_pass("Pass 2", cull=Cull.Back, light_mode=OTHER)]),
    # The wikibook's unlit shaders: no _LightColor0, no LightMode. The first returns semitransparent green.
    "003#1": dict(queue=Queue.Transparent, lighting=Lighting.Unlit, color=(0.0, 1.0, 0.0, 0.3),
                  passes=[_blend_pass(light_mode=ALWAYS)], light_modes=[None], fallback=None, render_type=None),
    "003#2": dict(queue=Queue.Transparent, lighting=Lighting.Unlit, color=(1, 1, 1, 1),
                  passes=[_blend_pass("Pass 1", cull=Cull.Front, light_mode=ALWAYS),
                          _blend_pass("Pass 2", cull=Cull.Back, light_mode=ALWAYS)]),
}


@pytest.mark.parametrize("key", sorted(SEED_EXPECTED))
def test_seed_listing_imports_to_what_its_text_states(key):
    result = parse_shaderlab(cleaned(key), f"{key}.shader")
    want = SEED_EXPECTED[key]
    m = result.material
    assert isinstance(m, Material) and m.name == result.name and m.main_tex is None
    assert result.to_dict()["material"]["enabled"] is True
    assert m.queue is want["queue"] and m.queue_offset == 0
    assert m.lighting is want["lighting"]
    for k in ("cutoff", "alpha_scale"):
        if k in want:
            assert getattr(m, k) == want[k]
    if "color" in want:
        assert m.color == pytest.approx(want["color"])
    assert list(result.passes) == want["passes"]
    for k in ("light_modes", "fallback", "render_type", "ignore_projector"):
        if k in want:
            assert result.extra[k] == want[k], k
    assert result.extra["subshader_count"] == 1
    # Every pass states its Cull/ZWrite/Blend in the text; nothing else is left at a surprising value.
    for p in result.passes:
        assert p.ztest is CompareFunction.LEqual and not p.stencil and not p.separate_alpha


def test_seed_warnings_name_what_was_not_imported():
    w = parse_shaderlab(cleaned("001#1")).warnings
    assert any("_AlphaValue" in x and "cutoff" in x for x in w)
    w = parse_shaderlab(cleaned("002#1")).warnings
    assert any("UniversalForward" in x for x in w)
    w = parse_shaderlab(cleaned("003#2")).warnings
    assert any("different constant colours" in x for x in w)
    assert sum("discards fragments" in x for x in w) == 2
    assert parse_shaderlab(cleaned("000#2")).warnings == ()


_SNIPPET = 'Shader "S" {{ SubShader {{ Tags {{ "Queue"="Transparent" }} Pass {{ {} }} }} }}'


def test_book_blend_mode_snippets_match_the_presets():
    """The book's table of common blend types (seed 000), each wrapped in a pass, gives the preset state."""
    text = (SEEDS / "000_1e00087376ad7eb8.txt").read_text(encoding="utf-8")
    start = text.index("//正常(Normal)")
    block = text[start: text.index("对应的效果如图")]
    block = "\n".join(_NUMBER_RE.sub("", line) for line in block.splitlines() if "```" not in line)
    snippets = [s.strip() for s in re.split(r"\n\s*(?=//)", block) if s.strip()]
    by_name = {}
    for s in snippets:
        head, _, body = s.partition("\n")
        by_name[head] = body.split("//等同于")[0]
    mapping = {"//正常(Normal)，即透明度混合": "Alpha Blend", "//柔和相加(Soft Additive)": "Soft Additive",
               "//正片叠底(Multiply)，即相乘": "Multiply", "//两倍相乘(2x Multiply)": "2x Multiply",
               "//变暗(Darken)": "Darken", "//变量(Lighten)": "Lighten", "//线性减淡(Linnear Dodge)": "Linear Dodge"}
    for head, preset_name in mapping.items():
        body = by_name[head]
        (got,) = parse_shaderlab(_SNIPPET.format("ZWrite Off " + body)).passes
        (want,) = preset(preset_name)[1]
        assert got == replace(want, name="Pass", light_mode=ALWAYS), head  # untagged: Always
    # Screen: the book's first spelling equals Soft Additive; the "equivalently" one is the preset.
    screen = by_name["//滤色(Screen)"]
    (got,) = parse_shaderlab(_SNIPPET.format("ZWrite Off " + screen)).passes
    assert (got.src_blend, got.dst_blend) == (BlendFactor.OneMinusDstColor, BlendFactor.One)
    (got,) = parse_shaderlab(_SNIPPET.format("ZWrite Off Blend One OneMinusSrcColor")).passes
    assert got == replace(preset("Screen")[1][0], name="Pass", light_mode=ALWAYS)


def test_four_factor_blend_from_the_book():
    (p,) = parse_shaderlab(_SNIPPET.format("Blend SrcAlpha OneMinusSrcAlpha, One Zero")).passes
    assert p.blend and p.separate_alpha
    assert (p.src_blend, p.dst_blend, p.src_blend_alpha, p.dst_blend_alpha) == (
        SA, OMSA, BlendFactor.One, BlendFactor.Zero)


# --------------------------------------------------------------------------- the grammar


def _one(body: str, sub: str = "", props: str = "") -> Pass:
    text = f'Shader "T" {{ Properties {{ {props} }} SubShader {{ {sub} Pass {{ {body} }} }} }}'
    (p,) = parse_shaderlab(text).passes
    return p


def test_state_commands_case_insensitive_and_comments():
    p = _one("cull OFF /* c */ zwrite off // x\n ztest GEQUAL blend srcalpha ONE blendop revsub colormask rb "
             "offset -1, -2.5")
    assert p.cull is Cull.Off and not p.zwrite and p.ztest is CompareFunction.GEqual
    assert p.blend and (p.src_blend, p.dst_blend, p.blend_op) == (SA, BlendFactor.One, BlendOp.RevSub)
    assert p.color_mask == {"R", "B"} and (p.offset_factor, p.offset_units) == (-1.0, -2.5)
    assert not p.separate_alpha


def test_ztest_off_is_always_and_blend_off():
    p = _one("ZTest Off Blend Off")
    assert p.ztest is CompareFunction.Always and not p.blend


def test_blendop_two_ops_sets_separate_alpha():
    p = _one("Blend One One BlendOp Add, Max")
    assert p.separate_alpha and (p.blend_op, p.blend_op_alpha) == (BlendOp.Add, BlendOp.Max)
    assert (p.src_blend_alpha, p.dst_blend_alpha) == (BlendFactor.One, BlendFactor.One)
    p = _one("BlendOp Sub Blend SrcAlpha One, Zero One")  # order does not matter; one op for both
    assert p.separate_alpha and (p.blend_op, p.blend_op_alpha) == (BlendOp.Sub, BlendOp.Sub)
    assert (p.src_blend_alpha, p.dst_blend_alpha) == (BlendFactor.Zero, BlendFactor.One)


@pytest.mark.parametrize("mask,want", [("0", set()), ("RGBA", set("RGBA")), ("A", {"A"}), ("gba", set("GBA")),
                                       ("RGB", set("RGB"))])
def test_color_mask(mask, want):
    assert _one(f"ColorMask {mask}").color_mask == want


def test_subshader_state_applies_to_all_passes_and_pass_overrides():
    text = ('Shader "T" { SubShader { Tags { "Queue"="Transparent+1" } ZWrite Off Cull Off '
            "Blend SrcAlpha OneMinusSrcAlpha Pass { Name \"A\" } Pass { Name \"B\" Cull Back ZWrite On } } }")
    r = parse_shaderlab(text)
    a, b = r.passes
    assert (a.name, a.cull, a.zwrite, a.blend) == ("A", Cull.Off, False, True)
    assert (b.name, b.cull, b.zwrite, b.blend, b.src_blend) == ("B", Cull.Back, True, True, SA)
    assert (r.material.queue, r.material.queue_offset) == (Queue.Transparent, 1)


def test_category_is_flattened_and_later_subshaders_are_ignored():
    text = ('Shader "T" { Category { ZWrite Off Blend One One SubShader { Pass { } } SubShader { Pass { Cull Front } '
            "Pass { } } } }")
    r = parse_shaderlab(text)
    (p,) = r.passes
    assert not p.zwrite and p.blend and (p.src_blend, p.dst_blend) == (BlendFactor.One, BlendFactor.One)
    assert p.cull is Cull.Back and r.extra["subshader_count"] == 2
    assert any("only the first SubShader" in w for w in r.warnings)


@pytest.mark.parametrize("queue,want", [
    ("Transparent", (Queue.Transparent, 0)), ("Transparent+1", (Queue.Transparent, 1)),
    ("Geometry-10", (Queue.Geometry, -10)), ("alphatest", (Queue.AlphaTest, 0)),
    ("2450", (Queue.AlphaTest, 0)), ("2600", (Queue.AlphaTest, 150)), ("3000", (Queue.Transparent, 0)),
    ("4500", (Queue.Overlay, 500)), ("500", (Queue.Background, -500)), ("Overlay + 2", (Queue.Overlay, 2)),
])
def test_queue_tags(queue, want):
    assert parse_queue(queue) == want
    r = parse_shaderlab(f'Shader "T" {{ SubShader {{ Tags {{ "Queue"="{queue}" }} Pass {{ }} }} }}')
    assert (r.material.queue, r.material.queue_offset) == want


def test_properties_and_property_references():
    props = """
        _Color ("Tint", Color) = (0.25, 0.5, 0.75, 0.6)
        [NoScaleOffset] _MainTex ("Tex", 2D) = "white" {}
        _Cutoff ("Cutoff", Range(0, 1)) = 0.3
        _AlphaScale ("Alpha", Range(0,1)) = 0.4
        [Enum(UnityEngine.Rendering.CullMode)] _Cull ("Cull", Float) = 1
        [Enum(Off, 0, On, 1)] _ZWrite ("ZWrite", Float) = 0
        [Toggle] _Unused ("Toggle", Float) = 1
        [Enum(UnityEngine.Rendering.CompareFunction)] _ZTest ("ZTest", Float) = 7
        [Enum(UnityEngine.Rendering.BlendMode)] _Src ("Src", Float) = 5
        [Enum(UnityEngine.Rendering.BlendMode)] _Dst ("Dst", Float) = 10
        [Enum(UnityEngine.Rendering.BlendOp)] _Op ("Op", Float) = 4
        _Mask ("Mask", Int) = 14
        _Ref ("Ref", Int) = 3
        [Header(Stencil settings, with (parentheses))] _Comp ("Comp", Float) = 3
        _SPass ("Pass", Float) = 2
        _Factor ("Factor", Float) = -1
    """
    body = ("Cull [_Cull] ZWrite [_ZWrite] ZTest [_ZTest] Blend [_Src] [_Dst] BlendOp [_Op] ColorMask [_Mask] "
            "Offset [_Factor], -1 Stencil { Ref [_Ref] Comp [_Comp] Pass [_SPass] }")
    text = f'Shader "T" {{ Properties {{ {props} }} SubShader {{ Pass {{ {body} }} }} }}'
    r = parse_shaderlab(text)
    (p,) = r.passes
    assert p.cull is Cull.Front and not p.zwrite and p.ztest is CompareFunction.GEqual
    assert p.blend and (p.src_blend, p.dst_blend, p.blend_op) == (SA, OMSA, BlendOp.Max)
    assert p.color_mask == {"R", "G", "B"} and (p.offset_factor, p.offset_units) == (-1.0, -1.0)
    assert p.stencil and (p.stencil_ref, p.stencil_comp, p.stencil_pass) == (3, CompareFunction.Equal,
                                                                           StencilOp.Replace)
    assert (p.stencil_read_mask, p.stencil_write_mask, p.stencil_fail) == (255, 255, StencilOp.Keep)
    m = r.material
    assert m.color == (0.25, 0.5, 0.75, 0.6) and m.cutoff == 0.3 and m.alpha_scale == 0.4
    assert m.main_tex is None and r.extra["main_tex_default"] == "white"
    attrs = {x["name"]: x["attributes"] for x in r.extra["properties"]}
    assert attrs["_Cull"] == ["Enum(UnityEngine.Rendering.CullMode)"] and attrs["_Unused"] == ["Toggle"]
    assert attrs["_Comp"] == ["Header(Stencil settings, with (parentheses))"]


def test_stencil_block_literal():
    p = _one("Stencil { Ref 2 ReadMask 15 WriteMask 240 Comp NotEqual Pass IncrWrap Fail Zero ZFail Invert }")
    assert p.stencil and (p.stencil_ref, p.stencil_read_mask, p.stencil_write_mask) == (2, 15, 240)
    assert (p.stencil_comp, p.stencil_pass, p.stencil_fail, p.stencil_zfail) == (
        CompareFunction.NotEqual, StencilOp.IncrWrap, StencilOp.Zero, StencilOp.Invert)


def test_programs_decide_alpha_test_and_lighting():
    lambert = "CGPROGRAM\nfloat4 frag() : SV_Target { clip(a - _Cutoff); return _LightColor0; }\nENDCG"
    unlit = "CGPROGRAM\n// clip(a) is only a comment here; _LightColor0 too\nfloat4 frag() { return 1; }\nENDCG"
    r = parse_shaderlab(f'Shader "T" {{ SubShader {{ Pass {{ {lambert} }} Pass {{ {unlit} }} }} }}')
    assert [p.alpha_test for p in r.passes] == [True, False]
    assert r.material.lighting is Lighting.Lambert
    r = parse_shaderlab(f'Shader "T" {{ SubShader {{ Pass {{ {unlit} }} }} }}')
    assert r.material.lighting is Lighting.Unlit and not r.passes[0].alpha_test
    hlsl = "HLSLPROGRAM\nhalf4 frag() { clip(c.a - 0.5); return c * _LightColor0; }\nENDHLSL"
    r = parse_shaderlab(f'Shader "T" {{ SubShader {{ Pass {{ {hlsl} }} }} }}')
    assert r.passes[0].alpha_test and r.material.lighting is Lighting.Lambert


def test_program_text_with_braces_and_quotes_is_skipped():
    code = 'CGPROGRAM\n#include "UnityCG.cginc"\nstruct v2f { float4 pos; }; // }}} "\nchar c = \'{\';\nENDCG'
    (p,) = parse_shaderlab(f'Shader "T" {{ SubShader {{ Pass {{ Cull Front {code} ZWrite Off }} }} }}').passes
    assert p.cull is Cull.Front and not p.zwrite


def test_unknown_commands_warn_and_recorded_extras():
    text = """Shader "T" {
        SubShader {
            Tags { "Queue"="Transparent" "RenderType"="Transparent" "IgnoreProjector"="False" }
            LOD 100
            UsePass "Other/SHADOWCASTER"
            Pass {
                Tags { "LightMode"="ForwardBase" }
                Lighting Off
                Fog { Mode Off }
                Frobnicate 1 2 3
                AlphaToMask On
                Cull Front
            }
        }
        Fallback Off
    }"""
    r = parse_shaderlab(text)
    (p,) = r.passes
    assert p.cull is Cull.Front and p.alpha_to_mask and p.light_mode is LightMode.ForwardBase
    assert r.extra["use_pass"] == ["Other/SHADOWCASTER"] and r.extra["fallback"] == "Off"
    assert r.extra["render_type"] == "Transparent" and r.extra["ignore_projector"] is False
    assert r.extra["light_modes"] == ["ForwardBase"]
    w = r.warnings
    assert any(x.startswith("4:13: LOD ignored") for x in w)
    assert any(x.startswith("5:13: UsePass \"Other/SHADOWCASTER\": no shader named 'Other'") for x in w)
    assert any(x.startswith("9:17: Fog ignored: fog is not drawn") for x in w)
    assert any(x.startswith("10:17: unknown command 'Frobnicate' in Pass ignored") for x in w)
    assert not any("AlphaToMask" in x or "Lighting" in x for x in w)  # kept; Lighting Off: a fixed-function pass


def test_pass_names_with_spaces_and_quotes_export():
    m = Material(passes=(Pass(name="Back  Faces"), Pass(name='Say "hi"')))
    back = _roundtrip(m)
    assert [p.name for p in back.passes] == ["Back Faces", "Say 'hi'"]


# --------------------------------------------------------------------------- malformed input

GOOD = """Shader "Good" {
    Properties {
        _Color ("Tint", Color) = (1, 1, 1, 1)
    }
    SubShader {
        Tags { "Queue"="Transparent" }
        Pass {
            ZWrite Off
            Blend SrcAlpha OneMinusSrcAlpha
            ColorMask RGB
            CGPROGRAM
            float4 frag() : SV_Target { return _Color; }
            ENDCG
        }
    }
}
"""


@pytest.mark.parametrize("text,line,col,words", [
    # unbalanced braces
    (GOOD.replace("        }\n    }\n}", "        }\n}"), 1, 15, "Shader is never closed"),
    (GOOD + "}\n", 17, 1, "after the end of the shader"),
    (GOOD.replace("Pass {", "Pass", 1), 8, 13, "expected '{' after Pass"),
    # unknown factor names
    (GOOD.replace("OneMinusSrcAlpha", "OneMinusSrcAlfa"), 9, 28, "unknown blend factor 'OneMinusSrcAlfa'"),
    (GOOD.replace("Blend SrcAlpha", "Blend Source"), 9, 19, "unknown blend factor 'Source'"),
    (GOOD.replace("ZWrite Off", "ZWrite Maybe"), 8, 20, "unknown ZWrite value"),
    (GOOD.replace("ZWrite Off", "ZTest Sometimes"), 8, 19, "unknown ZTest function 'Sometimes'"),
    (GOOD.replace("ZWrite Off", "Cull Sideways"), 8, 18, "unknown Cull mode"),
    (GOOD.replace("ZWrite Off", "BlendOp Multiplied"), 8, 21, "unknown BlendOp 'Multiplied'"),
    # bad ColorMask
    (GOOD.replace("ColorMask RGB", "ColorMask RGBX"), 10, 23, "bad ColorMask 'RGBX'"),
    (GOOD.replace("ColorMask RGB", "ColorMask RR"), 10, 23, "bad ColorMask 'RR'"),
    (GOOD.replace("ColorMask RGB", "ColorMask 2"), 10, 23, "bad ColorMask '2'"),
    # truncated files
    (GOOD[: GOOD.index("ENDCG")], 11, 13, "CGPROGRAM is never closed by ENDCG"),
    (GOOD[: GOOD.index("ColorMask")], 7, 14, "Pass is never closed"),
    (GOOD[: GOOD.index("SrcAlpha")], 9, 19, "expected a value for blend factor, found end of file"),
    (GOOD[: GOOD.index("Queue") + 8], 6, 24, "string is never closed"),
    ("", 1, 1, "expected 'Shader"),
    (GOOD[:20], 1, 15, "Shader is never closed"),
    # others
    (GOOD.replace("Tags {", "Tags { Queue"), 6, 16, 'expected a tag "Name"="Value"'),
    (GOOD.replace('"Queue"="Transparent"', '"Queue"="Sometimes"'), 6, 24, "unknown Queue 'Sometimes'"),
    (GOOD.replace("ZWrite Off", "Stencil { Ref 300 }"), 8, 27, "integer 0..255"),
    (GOOD.replace("ZWrite Off", "/* open comment"), 8, 13, "comment '/*' is never closed"),
    (GOOD.replace("ZWrite Off", "ZWrite Off;"), 8, 23, "unexpected character ';'"),
    (GOOD.replace("(1, 1, 1, 1)", "(1, 1, oops)"), 3, 41, "expected a number for a component of _Color"),
])
def test_malformed_input_raises_with_position(text, line, col, words):
    with pytest.raises(ShaderLabError) as err:
        parse_shaderlab(text, "bad.shader")
    e = err.value
    assert words in e.message, e.message
    assert (e.line, e.column) == (line, col), str(e)
    assert str(e) == f"bad.shader:{line}:{col}: {e.message}" and "\n" not in str(e)


def test_good_fixture_parses():
    (p,) = parse_shaderlab(GOOD).passes
    assert p.color_mask == {"R", "G", "B"} and p.blend and not p.zwrite


# --------------------------------------------------------------------------- export and round trips


def _roundtrip(material: Material) -> Material:
    text = export_shaderlab(material, "Round/Trip")
    result = parse_shaderlab(text, "roundtrip.shader")
    assert result.name == "Round/Trip"
    # The only warning: a pass whose LightMode is not one of the forward path's (Other) is never drawn.
    others = sum(p.light_mode is LightMode.Other for p in material.draw_passes)
    assert len(result.warnings) == others and all("LightMode 'Other'" in w for w in result.warnings), result.warnings
    return result.material


def _shader_fields(m: Material) -> dict:
    return {k: getattr(m, k) for k in ("queue", "queue_offset", "color", "alpha_scale", "cutoff", "lighting")}


def _read_back(back: Material, m: Material) -> bool:
    """``back`` (the import of ``m``'s export) holds ``m``'s settings: a float32 value (what Blender
    stores), written as its shortest float32 text, reads back to the same float32; any other
    double to itself."""
    def same(b: float, x: float) -> bool:
        return np.float32(b) == np.float32(x) if float(np.float32(x)) == x else b == x

    got, want = _shader_fields(back), _shader_fields(m)
    floats = [(got["alpha_scale"], want["alpha_scale"]), (got["cutoff"], want["cutoff"]),
              *zip(got["color"], want["color"], strict=True)]
    others = [k for k in got if k not in ("color", "alpha_scale", "cutoff")]
    return all(same(b, x) for b, x in floats) and all(got[k] == want[k] for k in others)


def test_float32_values_export_as_their_shortest_text():
    """Blender stores _Color and _Cutoff as float32: 0.6 is written 0.6, not 0.6000000238418579."""
    m = Material(name="M", color=(float(np.float32(0.6)), 0.2, 0.1, 0.5), cutoff=float(np.float32(0.3)))
    text = export_shaderlab(m, "F")
    assert '_Color ("Main Tint", Color) = (0.6, 0.2, 0.1, 0.5)' in text
    assert '_Cutoff ("Alpha Cutoff", Range(0, 1)) = 0.3' in text
    back = parse_shaderlab(text).material
    assert np.float32(back.color[0]) == np.float32(0.6) and np.float32(back.cutoff) == np.float32(0.3)


@pytest.mark.parametrize("lighting", list(Lighting))
@pytest.mark.parametrize("name", list(PASS_PRESETS))
def test_presets_round_trip_exactly(name, lighting):
    queue, passes = preset(name)
    m = Material(name="M", queue=queue, passes=passes, lighting=lighting, color=(0.8, 0.6, 0.4, 0.5),
                 alpha_scale=0.7, cutoff=0.35)
    back = _roundtrip(m)
    assert back.passes == m.passes
    assert _shader_fields(back) == _shader_fields(m)


def test_export_style_matches_the_book():
    queue, passes = preset("Alpha Blend ZWrite")
    text = export_shaderlab(Material(name="Glass", queue=queue, passes=passes), None)
    assert text.startswith('Shader "Unity Passes/Glass"\n{\n    Properties\n')
    for needle in ['_Color ("Main Tint", Color) = (1, 1, 1, 1)', '_MainTex ("Main Tex", 2D) = "white" {}',
                   '_Cutoff ("Alpha Cutoff", Range(0, 1)) = 0.5', '_AlphaScale ("Alpha Scale", Range(0, 1)) = 1',
                   'Tags { "Queue"="Transparent" "IgnoreProjector"="True" "RenderType"="Transparent" }',
                   'Tags { "LightMode"="ForwardBase" }', "ColorMask 0", "Blend SrcAlpha OneMinusSrcAlpha",
                   "_LightColor0.rgb * albedo * max(0, dot(worldNormal, worldLightDir))",
                   'Fallback "Transparent/VertexLit"']:
        assert needle in text, needle
    assert text.count("CGPROGRAM") == 2 and text.count("ENDCG") == 2 and "clip(" not in text
    assert text.count("{") == text.count("}")
    queue, passes = preset("Alpha Test")
    text = export_shaderlab(Material(queue=queue, passes=passes, lighting=Lighting.Unlit), "X")
    assert "clip(texColor.a * _Color.a * _AlphaScale - _Cutoff);" in text and "_LightColor0" not in text
    assert '"RenderType"="TransparentCutout"' in text


_NAMES = st.text(alphabet="ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-.", min_size=1,
                 max_size=12)
_FLOATS = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
_UNIT = st.floats(min_value=0.0, max_value=1.0)
_BYTE = st.integers(0, 255)

passes_strategy = st.builds(
    Pass,
    name=_NAMES,
    cull=st.sampled_from(list(Cull)),
    zwrite=st.booleans(),
    ztest=st.sampled_from([c for c in CompareFunction if c is not CompareFunction.Never]),
    blend=st.booleans(),
    src_blend=st.sampled_from(list(BlendFactor)),
    dst_blend=st.sampled_from(list(BlendFactor)),
    blend_op=st.sampled_from(list(BlendOp)),
    separate_alpha=st.booleans(),
    src_blend_alpha=st.sampled_from(list(BlendFactor)),
    dst_blend_alpha=st.sampled_from(list(BlendFactor)),
    blend_op_alpha=st.sampled_from(list(BlendOp)),
    color_mask=st.frozensets(st.sampled_from(["R", "G", "B", "A"])),
    offset_factor=_FLOATS,
    offset_units=_FLOATS,
    alpha_test=st.booleans(),
    stencil=st.booleans(),
    stencil_ref=_BYTE,
    stencil_read_mask=_BYTE,
    stencil_write_mask=_BYTE,
    stencil_comp=st.sampled_from(list(CompareFunction)),
    stencil_pass=st.sampled_from(list(StencilOp)),
    stencil_fail=st.sampled_from(list(StencilOp)),
    stencil_zfail=st.sampled_from(list(StencilOp)),
    alpha_to_mask=st.booleans(),
    alpha_test_comp=st.sampled_from(list(CompareFunction)),
    light_mode=st.sampled_from(list(LightMode)),
)

materials_strategy = st.builds(
    Material,
    name=_NAMES,
    queue=st.sampled_from(list(Queue)),
    queue_offset=st.integers(-999, 999),
    color=st.tuples(_UNIT, _UNIT, _UNIT, _UNIT),
    alpha_scale=_UNIT,
    cutoff=_UNIT,
    lighting=st.sampled_from(list(Lighting)),
    passes=st.lists(passes_strategy, min_size=1, max_size=4).map(tuple),
)


@settings(max_examples=200, deadline=None)
@given(materials_strategy)
def test_random_materials_round_trip(m):
    back = _roundtrip(m)
    assert back.passes == tuple(canonical_pass(p) for p in m.passes)
    assert _read_back(back, m), (_shader_fields(back), _shader_fields(m))


@settings(max_examples=100, deadline=None)
@given(passes_strategy)
def test_canonical_pass_is_a_fixed_point_and_keeps_what_renders(p):
    c = canonical_pass(p)
    assert canonical_pass(c) == c
    keep = [f.name for f in fields(Pass) if not f.name.startswith(("src_blend", "dst_blend", "blend_op",
                                                                   "separate_alpha", "stencil_", "offset_",
                                                                   "alpha_test"))]
    assert all(getattr(c, k) == getattr(p, k) for k in keep)
    # The alpha test as it renders: Always keeps every fragment (no test), an inactive comparison is not kept.
    tests = p.alpha_test and p.alpha_test_comp is not CompareFunction.Always
    assert c.alpha_test is tests and c.alpha_test_comp is (p.alpha_test_comp if tests else CompareFunction.GEqual)
    # Offsets as Blender stores them: the same float32.
    assert np.float32(c.offset_factor) == np.float32(p.offset_factor)
    assert np.float32(c.offset_units) == np.float32(p.offset_units)
    if p.blend:
        assert (c.src_blend, c.dst_blend, c.blend_op, c.alpha_factors) == (
            p.src_blend, p.dst_blend, p.blend_op, p.alpha_factors)
    if p.stencil:
        assert c == replace(c, **{k: getattr(p, k) for k in pass_to_dict(p) if k.startswith("stencil_")})


@pytest.mark.parametrize("comp", list(CompareFunction))
def test_the_alpha_comparison_and_light_mode_round_trip(comp):
    """Each comparison is written into the exported CG (GEqual the book's clip(), Never clip(-1), the
    others 'if (!(alpha OP _Cutoff)) discard;') and read back; Always tests nothing."""
    p = Pass(name="Cut", alpha_test=True, alpha_test_comp=comp, alpha_to_mask=True, light_mode=LightMode.Vertex)
    text = export_shaderlab(Material(passes=(p,)), "Round/Trip")
    assert 'Tags { "LightMode"="Vertex" }' in text and "AlphaToMask On" in text
    if comp is CompareFunction.Greater:
        assert "if (!(texColor.a * _Color.a * _AlphaScale > _Cutoff)) discard;" in text
    (back,) = parse_shaderlab(text).passes
    assert back == canonical_pass(p)
    assert back.alpha_test is (comp is not CompareFunction.Always)
    assert back.alpha_test_comp is (CompareFunction.GEqual if comp is CompareFunction.Always else comp)


def test_empty_pass_list_exports_one_default_pass():
    back = _roundtrip(Material(passes=()))
    assert back.passes == (Pass(),)


# --------------------------------------------------------------------------- CLI


def test_cli_main_prints_json(tmp_path, capsys):
    path = tmp_path / "good.shader"
    path.write_text(GOOD, encoding="utf-8")
    assert cli_main(["shaderlab", str(path)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) == {"name", "material", "passes", "warnings", "extra"}
    assert out["name"] == "Good"
    assert out["material"]["queue"] == "Transparent" and out["material"]["queue_offset"] == 0
    assert out["material"]["enabled"] is True and out["material"]["main_tex"] is None
    assert out["material"]["color"] == [1, 1, 1, 1] and out["material"]["lighting"] == "Unlit"
    assert set(out["material"]) == {"enabled", "queue", "queue_offset", "color", "main_tex", "main_tex_tiling",
                                    "main_tex_offset", "main_tex_filter", "main_tex_wrap", "alpha_scale",
                                    "cutoff", "lighting", "main_tex_mipmaps", "main_tex_preserve_coverage",
                                    "vertex_color", "tint_color", "outline_width_tex", "outline_width_tex_filter",
                                    "outline_width_tex_wrap"}
    (p,) = out["passes"]
    assert p == pass_to_dict(Pass(name="Pass", zwrite=False, blend=True, src_blend=SA, dst_blend=OMSA,
                                  color_mask=frozenset("RGB"), light_mode=ALWAYS)) | {
        "drawn": True, "reason": "Always: drawn once"}
    assert p["color_mask"] == ["R", "G", "B"] and p["src_blend"] == "SrcAlpha"


def test_cli_main_errors(tmp_path, capsys):
    bad = tmp_path / "bad.shader"
    bad.write_text(GOOD.replace("ColorMask RGB", "ColorMask RGBX"), encoding="utf-8")
    assert cli_main(["shaderlab", str(bad)]) == 1
    cap = capsys.readouterr()
    assert cap.out == ""
    assert cap.err == f"error: {bad}:10:23: bad ColorMask 'RGBX' (use 0 or a combination of R, G, B, A)\n" \
        or (cap.err.count("\n") == 1 and cap.err.startswith(f"error: {bad}:10:23: bad ColorMask 'RGBX'"))
    assert cli_main(["shaderlab", str(tmp_path / "missing.shader")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "missing.shader" in err
    assert cli_main(["shaderlab"]) == 1
    assert capsys.readouterr().err.startswith("error: no .shader or .mat file given")
    with pytest.raises(SystemExit) as usage:  # argparse: usage errors exit 2
        cli_main(["shaderlab", "--bogus"])
    assert usage.value.code == 2
    capsys.readouterr()
    out = tmp_path / "x.shader"
    assert cli_main(["shaderlab", "--export", str(tmp_path / "nope.blend"), "--material", "M", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "no such file" in err
    assert not out.exists()


def _run(args, **kw):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=REPO, env=env, timeout=120,
                          **kw)


def test_cli_python_m_blendlib_shaderlab(tmp_path):
    path = tmp_path / "good.shader"
    path.write_text(GOOD, encoding="utf-8")
    r = _run(["-m", "blendlib", "shaderlab", str(path)])
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["material"]["queue"] == "Transparent"
    path.write_text(GOOD[:50], encoding="utf-8")
    r = _run(["-m", "blendlib", "shaderlab", str(path)])
    assert r.returncode == 1 and r.stdout == "" and len(r.stderr.strip().splitlines()) == 1
    assert r.stderr.startswith("error: ") and "good.shader:" in r.stderr
    path.write_text("Shader \"x\" { SubShader { Pass { Blend One Nope } } }", encoding="utf-8")
    r = _run(["-m", "blendlib", "shaderlab", str(path)])
    assert r.returncode == 1 and r.stdout == "" and r.stderr.strip() == (
        f"error: {path}:1:43: unknown blend factor 'Nope' (expected one of: One, Zero, SrcColor, SrcAlpha, "
        "DstColor, DstAlpha, OneMinusSrcColor, OneMinusSrcAlpha, OneMinusDstColor, OneMinusDstAlpha, "
        "SrcAlphaSaturate)")
    r = _run(["-m", "blendlib", "shaderlab", "--export", str(tmp_path / "none.blend"), "--material", "M", "-o",
              str(tmp_path / "o.shader")])
    assert r.returncode == 1 and "none.blend: no such file" in r.stderr and not (tmp_path / "o.shader").exists()
