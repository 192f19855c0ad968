"""Unity's own built-in shaders (shared/corpus/unity-builtin-shaders-2019.4) import as Unity compiles
and draws them (issue 27, SPEC §11.1–11.4).

Every expected value below is taken from the shader's own text, quoted beside it (or, for the
passes Unity generates, from the compiled listings cited in docs/unity-shaders.md); none from
this importer's output.
"""

from __future__ import annotations

import json
import time

import pytest

from blendlib.cli import main as cli_main
from blendlib.core.vocabulary import (
    BlendFactor,
    CompareFunction,
    Cull,
    Lighting,
    LightMode,
    Queue,
    StencilOp,
    VertexColor,
)
from blendlib.formats.shaderlab import parse_shaderlab_file
from tests.support.shared import BUILTIN_SHADERS

EXTRA = BUILTIN_SHADERS / "DefaultResourcesExtra"
pytestmark = pytest.mark.skipif(not EXTRA.is_dir(), reason="shared/corpus is not available")

F = BlendFactor
RGB, RGBA = frozenset("RGB"), frozenset("RGBA")


def _import(name: str):
    return parse_shaderlab_file(str(EXTRA / name))


def _drawn_names(result) -> list[tuple[str, str]]:
    return [(e["name"], e["light_mode"]) for e in result.to_dict()["passes"] if e["drawn"]]


# --------------------------------------------------------------------------- the whole corpus


def test_every_builtin_shader_imports_in_process_without_a_traceback(capsys):
    """All 192 files: exit status 0, one JSON record on stdout, no traceback, in under 10 s."""
    files = sorted(BUILTIN_SHADERS.rglob("*.shader"))
    assert len(files) == 192
    start = time.perf_counter()
    names = set()
    for path in files:
        assert cli_main(["shaderlab", str(path)]) == 0, path
        out, err = capsys.readouterr()
        assert "Traceback" not in out + err, path
        record = json.loads(out)
        assert set(record) == {"name", "material", "passes", "warnings", "extra"}
        assert all("drawn" in p and "reason" in p and "light_mode" in p for p in record["passes"])
        assert all("\n" not in w for w in record["warnings"])
        names.add(record["name"])
    assert time.perf_counter() - start < 10.0
    assert {"Standard", "UI/Default", "Sprites/Default", "Particles/Standard Unlit",
            "Legacy Shaders/Transparent/Cutout/VertexLit"} <= names


# --------------------------------------------------------------------------- legacy particles

# Each file's Category: 'Tags { "Queue"="Transparent" ... }', its Blend/ColorMask lines, and
# 'Cull Off Lighting Off ZWrite Off' (Lighting between Cull and ZWrite: ZWrite must still be read).
PARTICLES = {
    # "Blend SrcAlpha One" / "ColorMask RGB" / "2.0f * i.color * _TintColor * tex2D(_MainTex, i.texcoord)"
    "Particle Add.shader": (F.SrcAlpha, F.One, RGB, VertexColor.Particle),
    # "Blend One OneMinusSrcAlpha" / "col.rgb = _TintColor.rgb * tex.rgb * i.color.rgb * 2.0f"
    "Particle AddMultiply.shader": (F.One, F.OneMinusSrcAlpha, RGB, VertexColor.Particle),
    # "Blend One OneMinusSrcColor" / "half4 col = i.color * tex2D(_MainTex, i.texcoord)"
    "Particle AddSmooth.shader": (F.One, F.OneMinusSrcColor, RGB, VertexColor.Multiply),
    # "Blend SrcAlpha OneMinusSrcAlpha" / "o.color = v.color * _TintColor" + "2.0f * i.color * tex2D(...)"
    "Particle Alpha Blend.shader": (F.SrcAlpha, F.OneMinusSrcAlpha, RGB, VertexColor.Particle),
    # "Blend SrcAlpha OneMinusSrcAlpha" / "2.0f * i.color * lerp(colA, colB, i.blend)"
    "Particle Anim Alpha Blend.shader": (F.SrcAlpha, F.OneMinusSrcAlpha, RGB, VertexColor.Particle),
    # "Blend DstColor One" / "fixed4 col = i.color * tex2D(_MainTex, i.texcoord)"
    "Particle Blend.shader": (F.DstColor, F.One, RGB, VertexColor.Multiply),
    # "Blend Zero SrcColor" (no ColorMask) / "half4 prev = i.color * tex2D(_MainTex, i.texcoord)"
    "Particle Multiply.shader": (F.Zero, F.SrcColor, RGBA, VertexColor.Multiply),
    # "Blend DstColor SrcColor" / "col.rgb = tex.rgb * i.color.rgb * 2"
    "Particle MultiplyDouble.shader": (F.DstColor, F.SrcColor, RGB, VertexColor.Multiply),
    # "Blend One OneMinusSrcAlpha" / "return i.color * tex2D(_MainTex, i.texcoord) * i.color.a"
    "Particle Premultiply Blend.shader": (F.One, F.OneMinusSrcAlpha, RGB, VertexColor.Multiply),
}


@pytest.mark.parametrize("name", sorted(PARTICLES))
def test_legacy_particles_draw_without_depth_writes(name):
    src, dst, mask, vertex_color = PARTICLES[name]
    result = _import(name)
    m = result.material
    assert (m.queue, m.queue_offset) == (Queue.Transparent, 0)
    (p,) = m.passes  # one untagged Pass: LightMode Always, drawn once
    assert p.light_mode is LightMode.Always and _drawn_names(result) == [(p.name, "Always")]
    assert p.cull is Cull.Off and not p.zwrite and p.ztest is CompareFunction.LEqual
    assert p.blend and (p.src_blend, p.dst_blend) == (src, dst)
    assert p.color_mask == mask and not p.alpha_test and not p.stencil
    assert m.vertex_color is vertex_color and m.lighting is Lighting.Unlit
    if vertex_color is VertexColor.Particle:
        assert m.tint_color == (0.5, 0.5, 0.5, 0.5)  # '_TintColor ("Tint Color", Color) = (0.5,0.5,0.5,0.5)'


def test_the_exact_particle_forms_are_not_warned_and_the_others_are():
    assert not any("vertex colour" in w for w in _import("Particle Add.shader").warnings)
    assert not any("vertex colour" in w for w in _import("Particle Alpha Blend.shader").warnings)
    warned = _import("Particle Multiply.shader").warnings  # "lerp(half4(1,1,1,1), prev, prev.a)"
    assert any("lerp(half4(1,1,1,1), prev, prev.a)" in w and "approximated" in w for w in warned)
    # "col.rgb *= col.a" with "Blend One OneMinusSrcColor": the destination factor reads the premultiplied
    # colour, so the premultiplication cannot move into the blend.
    assert any("premultiplies" in w and "approximated" in w for w in _import("Particle AddSmooth.shader").warnings)


def test_legacy_vertexlit_blended_particles_are_fixed_function():
    """'Lighting On', 'ColorMaterial AmbientAndDiffuse', 'SetTexture [_MainTex] { combine primary * texture }',
    'Blend SrcAlpha OneMinusSrcAlpha', 'ZWrite Off', 'ColorMask RGB', 'Cull Off'."""
    result = _import("Particle VertexLit Blended.shader")
    (p,) = result.passes
    assert p.cull is Cull.Off and not p.zwrite and p.color_mask == RGB
    assert (p.src_blend, p.dst_blend) == (F.SrcAlpha, F.OneMinusSrcAlpha)
    m = result.material
    assert m.lighting is Lighting.Lambert and m.vertex_color is VertexColor.Multiply
    # The SubShader's 'Tags { "LightMode" = "Vertex" }' is not a Pass tag: the pass is Always.
    assert p.light_mode is LightMode.Always


# --------------------------------------------------------------------------- sprites, UI, unlit


def test_sprites_default():
    """'Cull Off' 'Lighting Off' 'ZWrite Off' 'Blend One OneMinusSrcAlpha', Queue Transparent; its
    fragment is UnitySprites.cginc's SpriteFrag: 'SampleSpriteTexture (IN.texcoord) * IN.color;
    c.rgb *= c.a' — premultiplied in the shader, which the import moves into the blend."""
    result = _import("Sprites-Default.shader")
    m = result.material
    assert m.queue is Queue.Transparent and m.vertex_color is VertexColor.Multiply
    (p,) = m.passes
    assert p.cull is Cull.Off and not p.zwrite and p.light_mode is LightMode.Always
    assert (p.src_blend, p.dst_blend, p.separate_alpha, p.src_blend_alpha, p.dst_blend_alpha) == (
        F.SrcAlpha, F.OneMinusSrcAlpha, True, F.One, F.OneMinusSrcAlpha)
    assert any("premultiplies its colour" in w and "draws the same" in w for w in result.warnings)


def test_ui_default():
    """'ZTest [unity_GUIZTestMode]' → LEqual (warned); 'Stencil { Ref [_Stencil] Comp [_StencilComp]
    Pass [_StencilOp] ReadMask [_StencilReadMask] WriteMask [_StencilWriteMask] }' from the defaults
    '_StencilComp ... = 8' (Always), '_Stencil ... = 0', '_StencilOp ... = 0' (Keep), masks 255;
    'ColorMask [_ColorMask]' with '_ColorMask ... = 15'; 'Blend SrcAlpha OneMinusSrcAlpha'; 'Cull Off';
    'ZWrite Off'; the alpha clip only under '#ifdef UNITY_UI_ALPHACLIP' ('_UseUIAlphaClip ... = 0': off)."""
    result = _import("UI/UI-Default.shader")
    (p,) = result.passes
    assert p.name == "Default" and p.light_mode is LightMode.Always
    assert p.ztest is CompareFunction.LEqual
    assert any("[unity_GUIZTestMode]" in w and "LEqual" in w for w in result.warnings)
    assert p.stencil and (p.stencil_ref, p.stencil_comp, p.stencil_pass) == (0, CompareFunction.Always, StencilOp.Keep)
    assert (p.stencil_read_mask, p.stencil_write_mask) == (255, 255)
    assert p.color_mask == RGBA and p.cull is Cull.Off and not p.zwrite
    assert (p.src_blend, p.dst_blend) == (F.SrcAlpha, F.OneMinusSrcAlpha)
    assert not p.alpha_test and result.material.vertex_color is VertexColor.Multiply  # 'OUT.color = v.color * _Color'


def test_ui_default_font_draws_with_its_fallback():
    """'UI/Default Font' has no SubShader, only 'FallBack "UI/Default"': Unity draws UI/Default's."""
    result = _import("UI/UI-DefaultFont.shader")
    assert result.material.queue is Queue.Transparent
    (p,) = result.passes
    assert p.name == "Default" and (p.src_blend, p.dst_blend) == (F.SrcAlpha, F.OneMinusSrcAlpha)
    assert any('Fallback "UI/Default"' in w for w in result.warnings)


def test_unlit_transparent_and_cutout():
    """Unlit-Alpha: 'Tags {"Queue"="Transparent" ...}' 'ZWrite Off' 'Blend SrcAlpha OneMinusSrcAlpha';
    Unlit-AlphaTest: 'Tags {"Queue"="AlphaTest" ...}' and 'clip(col.a - _Cutoff);'."""
    result = _import("Unlit/Unlit-Alpha.shader")
    (p,) = result.passes
    assert result.material.queue is Queue.Transparent and not p.zwrite
    assert (p.src_blend, p.dst_blend) == (F.SrcAlpha, F.OneMinusSrcAlpha) and p.light_mode is LightMode.Always
    result = _import("Unlit/Unlit-AlphaTest.shader")
    (p,) = result.passes
    assert result.material.queue is Queue.AlphaTest and p.zwrite and not p.blend
    assert p.alpha_test and p.alpha_test_comp is CompareFunction.GEqual and result.material.cutoff == 0.5


# --------------------------------------------------------------------------- legacy Transparent family


def test_transparent_diffuse_is_the_surface_shader_unity_compiles():
    """'#pragma surface surf Lambert alpha:fade' → Unity's compiled listing of this shader: FORWARD
    ForwardBase 'ZWrite Off Blend SrcAlpha OneMinusSrcAlpha ColorMask RGB', FORWARD ForwardAdd
    'Blend SrcAlpha One' 'ColorMask RGB' 'ZWrite Off', Meta 'Cull Off'; no deferred passes."""
    result = _import("Alpha-Diffuse.shader")
    m = result.material
    assert m.queue is Queue.Transparent and m.lighting is Lighting.Lambert
    base, add, meta = m.passes
    assert (base.name, base.light_mode, add.name, add.light_mode, meta.light_mode) == (
        "FORWARD", LightMode.ForwardBase, "FORWARD", LightMode.ForwardAdd, LightMode.Meta)
    assert (base.zwrite, base.src_blend, base.dst_blend, base.color_mask) == (False, F.SrcAlpha,
                                                                               F.OneMinusSrcAlpha, RGB)
    assert (add.zwrite, add.src_blend, add.dst_blend, add.color_mask) == (False, F.SrcAlpha, F.One, RGB)
    assert meta.cull is Cull.Off and not meta.zwrite
    assert _drawn_names(result) == [("FORWARD", "ForwardBase")]  # ForwardAdd: one directional light only


def test_cutout_diffuse_clips_in_every_generated_pass():
    """'#pragma surface surf Lambert alphatest:_Cutoff' → 'ColorMask RGB' and 'clip (o.Alpha - _Cutoff)'
    in FORWARD base; FORWARD add 'ZWrite Off Blend One One ColorMask RGB'; PREPASS and DEFERRED."""
    result = _import("AlphaTest-Diffuse.shader")
    assert result.material.queue is Queue.AlphaTest and result.material.cutoff == 0.5
    names = [(p.name, p.light_mode) for p in result.passes]
    assert names == [("FORWARD", LightMode.ForwardBase), ("FORWARD", LightMode.ForwardAdd),
                     ("PREPASS", LightMode.PrepassBase), ("PREPASS", LightMode.PrepassFinal),
                     ("DEFERRED", LightMode.Deferred), ("Meta", LightMode.Meta)]
    base, add = result.passes[:2]
    assert base.alpha_test and base.zwrite and not base.blend and base.color_mask == RGB
    assert add.alpha_test and not add.zwrite and (add.src_blend, add.dst_blend) == (F.One, F.One)


# '#pragma surface surf <model> alpha:fade' in each; 'Tags {"Queue"="Transparent" ...}'.
TRANSPARENT_SURFACE = {"Alpha-Bumped.shader": "Lambert", "Alpha-BumpSpec.shader": "BlinnPhong",
                       "Alpha-Diffuse.shader": "Lambert", "Alpha-Glossy.shader": "BlinnPhong",
                       "Alpha-Parallax.shader": "Lambert", "Alpha-ParallaxSpec.shader": "BlinnPhong"}
# '#pragma surface surf <model> alphatest:_Cutoff' in each; 'Tags {"Queue"="AlphaTest" ...}'.
CUTOUT_SURFACE = {"AlphaTest-Bumped.shader": "Lambert", "AlphaTest-BumpSpec.shader": "BlinnPhong",
                  "AlphaTest-Diffuse.shader": "Lambert", "AlphaTest-Glossy.shader": "BlinnPhong"}


@pytest.mark.parametrize("name", sorted(TRANSPARENT_SURFACE))
def test_every_transparent_surface_shader(name):
    result = _import(name)
    assert result.material.queue is Queue.Transparent and result.material.lighting is Lighting.Lambert
    assert [(p.light_mode, p.zwrite, p.src_blend, p.dst_blend, p.color_mask) for p in result.passes[:2]] == [
        (LightMode.ForwardBase, False, F.SrcAlpha, F.OneMinusSrcAlpha, RGB),
        (LightMode.ForwardAdd, False, F.SrcAlpha, F.One, RGB)]
    approximated = any("lighting model BlinnPhong is drawn as Lambert" in w for w in result.warnings)
    assert approximated is (TRANSPARENT_SURFACE[name] == "BlinnPhong")


@pytest.mark.parametrize("name", sorted(CUTOUT_SURFACE))
def test_every_cutout_surface_shader(name):
    result = _import(name)
    assert result.material.queue is Queue.AlphaTest and result.material.cutoff == 0.5  # '_Cutoff (...) = 0.5'
    base, add = result.passes[:2]
    assert base.alpha_test and base.zwrite and not base.blend and base.color_mask == RGB
    assert add.alpha_test and (add.src_blend, add.dst_blend, add.zwrite) == (F.One, F.One, False)


def test_soft_edge_unlit_keeps_the_edges_below_the_cutoff():
    """'Cull Off'; pass 1 'clip(col.a - _Cutoff)' (alpha >= cutoff, ZWrite On); pass 2
    'Tags { "RequireOption" = "SoftVegetation" }' 'ZWrite off' 'Blend SrcAlpha OneMinusSrcAlpha'
    'clip(-(col.a - _Cutoff))' (alpha <= cutoff)."""
    result = _import("AlphaTest-SoftEdgeUnlit.shader")
    first, second = result.passes
    assert first.cull is Cull.Off and first.zwrite and first.alpha_test_comp is CompareFunction.GEqual
    assert second.cull is Cull.Off and not second.zwrite and second.alpha_test
    assert second.alpha_test_comp is CompareFunction.LEqual
    assert (second.src_blend, second.dst_blend) == (F.SrcAlpha, F.OneMinusSrcAlpha)
    assert any("SoftVegetation" in w for w in result.warnings)


def test_cutout_vertexlit_is_fixed_function_with_alpha_to_mask():
    """'Tags { "LightMode" = "Vertex" }' 'Alphatest Greater [_Cutoff]' 'AlphaToMask True' 'ColorMask RGB'
    'Material { Diffuse [_Color] ... }' 'Lighting On' 'Combine texture * primary DOUBLE, texture * primary';
    the lightmapped pass is 'LIGHTMODE = VertexLM' (never drawn here), then 'ShadowCaster'."""
    result = _import("AlphaTest-VertexLit.shader")
    vertex, lightmapped, caster = result.passes
    assert vertex.light_mode is LightMode.Vertex and lightmapped.light_mode is LightMode.VertexLM
    assert caster.light_mode is LightMode.ShadowCaster
    assert vertex.alpha_test and vertex.alpha_test_comp is CompareFunction.Greater
    assert vertex.alpha_to_mask and vertex.color_mask == RGB and vertex.zwrite
    assert _drawn_names(result) == [("Pass 1", "Vertex")]  # no forward pass: the Vertex pass draws
    m = result.material
    assert m.queue is Queue.AlphaTest and m.cutoff == 0.5 and m.lighting is Lighting.Lambert
    # Lit fixed-function colours are half the programmable ones; DOUBLE restores them: _Color x 1.
    assert m.color == (1.0, 1.0, 1.0, 1.0)


def test_transparent_vertexlit():
    """SubShader 'ZWrite Off' 'Blend SrcAlpha OneMinusSrcAlpha' 'ColorMask RGB'; a Vertex and a VertexLM pass."""
    result = _import("Alpha-VertexLit.shader")
    vertex, lightmapped = result.passes
    assert vertex.light_mode is LightMode.Vertex and lightmapped.light_mode is LightMode.VertexLM
    for p in (vertex, lightmapped):
        assert not p.zwrite and (p.src_blend, p.dst_blend) == (F.SrcAlpha, F.OneMinusSrcAlpha)
        assert p.color_mask == RGB
    assert _drawn_names(result) == [("Pass 1", "Vertex")]


# --------------------------------------------------------------------------- Standard particles (GrabPass)


@pytest.mark.parametrize("name", ["Particle Standard Unlit.shader", "Particle Standard Surface.shader"])
def test_standard_particles_import_past_their_grab_pass(name):
    """'GrabPass { Tags { "LightMode" = "Always" } "_GrabTexture" }' is consumed (a warning), the
    SubShader state 'BlendOp [_BlendOp] Blend [_SrcBlend] [_DstBlend] ZWrite [_ZWrite] Cull [_Cull]'
    takes the defaults 0 (Add), 1 (One), 0 (Zero), 1 (On), 2 (Back); the ForwardBase pass draws."""
    result = _import(name)
    assert any(w.split(": ", 1)[1].startswith("GrabPass ignored") for w in result.warnings)
    drawn = [p for p in result.passes if p.light_mode is LightMode.ForwardBase]
    assert len(drawn) == 1 and _drawn_names(result) == [(drawn[0].name, "ForwardBase")]
    p = drawn[0]
    assert (p.src_blend, p.dst_blend, p.zwrite, p.cull) == (F.One, F.Zero, True, Cull.Back)
    assert {q.light_mode for q in result.passes} >= {LightMode.ShadowCaster, LightMode.Other}  # Picking, selection
    assert result.material.vertex_color is VertexColor.Multiply  # UnityStandardParticles.cginc: "albedo *= i.color"


# --------------------------------------------------------------------------- UsePass and LightMode rules


def test_use_pass_inserts_the_named_pass_from_the_search_path():
    """Reflect-BumpVertexLit: 'UsePass "Reflective/Bumped Unlit/BASE"' — found as 'Legacy Shaders/
    Reflective/Bumped Unlit' (Unity's pre-5.0 name), whose 'Name "BASE"' pass is
    'Tags {"LightMode" = "Always"}'; then its own Vertex pass 'Blend One One ZWrite Off'."""
    result = _import("Reflect-BumpVertexLit.shader")
    base, vertex = result.passes
    assert (base.name, base.light_mode) == ("BASE", LightMode.Always)
    assert vertex.light_mode is LightMode.Vertex and (vertex.src_blend, vertex.dst_blend) == (F.One, F.One)
    assert not vertex.zwrite
    # No ForwardBase/ForwardAdd pass: the Vertex pass draws after the Always one.
    assert _drawn_names(result) == [("BASE", "Always"), ("Pass", "Vertex")]


def test_vertex_passes_do_not_draw_beside_forward_passes():
    """Standard: FORWARD ('"LightMode" = "ForwardBase"'), FORWARD_DELTA (ForwardAdd), ShadowCaster,
    DEFERRED, META: only FORWARD draws with one directional light."""
    result = _import("Standard.shader")
    assert [p.light_mode for p in result.passes] == [LightMode.ForwardBase, LightMode.ForwardAdd,
                                                     LightMode.ShadowCaster, LightMode.Deferred, LightMode.Meta]
    assert _drawn_names(result) == [("FORWARD", "ForwardBase")]
    reasons = {e["name"]: e["reason"] for e in result.to_dict()["passes"]}
    assert reasons["FORWARD_DELTA"].startswith("ForwardAdd: drawn once per additional per-pixel light")
    assert reasons["ShadowCaster"].startswith("ShadowCaster:")


def test_docs_unity_shaders_is_the_importers_current_output(tmp_path):
    """docs/unity-shaders.md is generated from this importer's output (scripts/make_unity_shader_table.py):
    what it says about each built-in shader is what the import gives today."""
    from scripts.make_unity_shader_table import main
    from tests.support.shared import REPO

    out = tmp_path / "unity-shaders.md"
    assert main(["--corpus", str(BUILTIN_SHADERS), "-o", str(out)]) == 0
    assert out.read_text(encoding="utf-8") == (REPO / "docs" / "unity-shaders.md").read_text(encoding="utf-8"), (
        "docs/unity-shaders.md is stale: run python -m scripts.make_unity_shader_table")
