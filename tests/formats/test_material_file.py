"""Unity material files (.mat, SPEC §11.5): Unity's YAML read exactly, the three layouts, the shader by
guid or built-in fileID, saved properties, keywords, render queue, disabled passes, textures and
their importer settings — and a Standard Fade material rendered as Unity blends it.

Fixtures: tests/fixtures/unity_project/ (a small Unity project; its .mat files follow the real
files quoted in research-surface.md §9: ml-agents' GrayTransparent.mat for the 2017+ layout,
parser fixtures for 5.5's first/second list, keijiro's Kvant/KinoBloom materials for Unity 4–5.4's
repeated ``data:`` keys, EntityComponentSystemSamples' Glass.mat for 2021.2's m_ValidKeywords).
The Standard shader's state per mode is StandardShaderGUI.SetupMaterialWithBlendMode's
(UnityCsReference, Editor/Mono/Inspector/StandardShaderGUI.cs):
Opaque _SrcBlend One, _DstBlend Zero, _ZWrite 1, no keyword, queue -1; Cutout the same with
_ALPHATEST_ON and queue AlphaTest (2450); Fade SrcAlpha, OneMinusSrcAlpha, _ZWrite 0, _ALPHABLEND_ON,
Transparent (3000); Transparent One, OneMinusSrcAlpha, _ZWrite 0, _ALPHAPREMULTIPLY_ON, 3000.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.cli import main as cli_main
from blendlib.core.scene import DrawScene
from blendlib.core.vocabulary import (
    BlendFactor,
    CompareFunction,
    Cull,
    Lighting,
    LightMode,
    Material,
    Queue,
    StencilOp,
    TextureFilter,
    TextureWrap,
    VertexColor,
)
from blendlib.formats.shaderlab import (
    ShaderLabError,
    UnityFileError,
    import_material_file,
    project_materials,
    read_material_file,
)
from blendlib.formats.shaderlab.material_file import parse_material_file
from blendlib.formats.shaderlab.unity_yaml import Repeated, load_documents
from tests.reference.scenes import quad, renderer, screen_camera
from tests.support.shared import BUILTIN_SHADERS

PROJECT = Path(__file__).resolve().parents[1] / "fixtures" / "unity_project"
ASSETS = PROJECT / "Assets"
MATERIALS = ASSETS / "Materials"
SEARCH = (str(BUILTIN_SHADERS),)
F = BlendFactor
needs_corpus = pytest.mark.skipif(not BUILTIN_SHADERS.is_dir(), reason="shared/corpus is not available")


def _import(relative: str):
    return import_material_file(MATERIALS / relative, SEARCH)


# --------------------------------------------------------------------------- Unity's YAML


def test_yaml_scalars_stay_as_written():
    """An all-digit guid is not read as a number (YAML 1.1 would read it as octal), 'Off' is not False,
    '.5' and '1:20' stay text; the header's tag and anchor, a 'stripped' document, a second document
    after the first's %TAG directive all read."""
    text = ("%YAML 1.1\n%TAG !u! tag:unity3d.com,2011:\n--- !u!1 &100 stripped\nGameObject:\n  m_Name: A\n"
            "--- !u!21 &2100000\nMaterial:\n  guid: 00000000000000001000000000000000\n  word: Off\n"
            "  half: .5\n  time: 1:20\n  empty: \n--- !u!114 &-1670072366105214709\nMonoBehaviour:\n  version: 10\n")
    docs = load_documents(text, "x.mat")
    assert [(c, f) for c, f, _ in docs] == [(1, 100), (21, 2100000), (114, -1670072366105214709)]
    material = docs[1][2]["Material"]
    assert material == {"guid": "00000000000000001000000000000000", "word": "Off", "half": ".5", "time": "1:20",
                         "empty": ""}


def test_repeated_keys_keep_every_value():
    docs = load_documents("--- !u!21 &1\nMaterial:\n  m_Floats:\n    data:\n      first: {name: _A}\n"
                          "      second: 1\n    data:\n      first: {name: _B}\n      second: 2\n")
    data = docs[0][2]["Material"]["m_Floats"]["data"]
    assert isinstance(data, Repeated) and [d["first"]["name"] for d in data] == ["_A", "_B"]


@pytest.mark.parametrize("text,words", [
    ("--- !u!21 &1\nMaterial:\n  m_Shader: {fileID: 46\n", "not valid YAML"),
    ("--- !u!1 &1\nGameObject:\n  m_Name: A\n", "no Material document"),
    ("--- !u!21 &1\nMaterial:\n  m_Name: A\n", "no m_Shader"),
    ("--- !u!21 &1\nMaterial:\n  m_Shader: {fileID: 46, guid: x}\n  m_CustomRenderQueue: soon\n", "not a number"),
    ("--- !u!21 &1\nMaterial:\n  m_Shader: {fileID: 46, guid: x}\n  m_CustomRenderQueue: -1e16\n", "neither -1 nor"),
    ("--- !u!21 &1\nMaterial:\n  m_Shader: {fileID: 46, guid: x}\n  m_CustomRenderQueue: 5001\n", "within 0..5000"),
])
def test_bad_material_files_are_one_line_errors(text, words):
    with pytest.raises(UnityFileError) as err:
        parse_material_file(text, "bad.mat")
    assert words in str(err.value) and str(err.value).startswith("bad.mat") and "\n" not in str(err.value)


def test_the_three_layouts_read_the_same_values():
    new = read_material_file(MATERIALS / "Standard" / "Fade.mat")
    old = read_material_file(MATERIALS / "Standard55" / "Fade.mat")
    oldest = read_material_file(MATERIALS / "Unity4" / "Fade.mat")
    for mat in (new, old, oldest):
        assert mat.colors["_Color"] == (0.8, 0.4, 0.2, 0.6)
        assert (mat.floats["_SrcBlend"], mat.floats["_DstBlend"], mat.floats["_ZWrite"]) == (5, 10, 0)
        assert mat.keywords == {"_ALPHABLEND_ON"} and mat.custom_render_queue == 3000
        assert (mat.shader_file_id, mat.shader_guid) == (46, "0000000000000000f000000000000000")
        assert mat.textures["_MainTex"].guid == "12345678901234567890123456789012"
    assert new.textures["_MainTex"].scale == (2.0, 3.0) and new.textures["_MainTex"].offset == (0.25, 0.5)
    assert oldest.floats["_Cutoff"] == pytest.approx(0.35)  # ".349999994"
    assert new.name == "Standard Fade" and old.name == "Standard55 Fade" and oldest.name == "Unity4 Fade"
    assert read_material_file(MATERIALS / "Unity4" / "Diffuse.mat").keywords == frozenset()  # Unity 4: '[]'


def test_2021_materials_read_their_valid_keywords_after_another_document():
    mat = read_material_file(MATERIALS / "Standard2021" / "Transparent.mat")
    assert mat.name == "Standard2021 Transparent" and mat.keywords == {"_ALPHAPREMULTIPLY_ON"}
    assert mat.disabled_passes == ("SHADOWCASTER",) and mat.tags == {"RenderType": "Transparent"}


# --------------------------------------------------------------------------- Standard, four modes


# mode: (queue, (src, dst) of FORWARD, zwrite, alpha test)
STANDARD = {
    "Opaque": (Queue.Geometry, (F.One, F.Zero), True, False),
    "Cutout": (Queue.AlphaTest, (F.One, F.Zero), True, True),
    "Fade": (Queue.Transparent, (F.SrcAlpha, F.OneMinusSrcAlpha), False, False),
    # One OneMinusSrcAlpha with the diffuse premultiplied in the shader (PreMultiplyAlpha): drawn as
    # Blend SrcAlpha OneMinusSrcAlpha, One OneMinusSrcAlpha.
    "Transparent": (Queue.Transparent, (F.SrcAlpha, F.OneMinusSrcAlpha), False, False),
}


@needs_corpus
@pytest.mark.parametrize("folder", ["Standard", "Standard55"])
@pytest.mark.parametrize("mode", sorted(STANDARD))
def test_standard_in_every_mode_and_layout(folder, mode):
    queue, factors, zwrite, alpha_test = STANDARD[mode]
    result = _import(f"{folder}/{mode}.mat")
    m = result.material
    assert m.name == f"{folder} {mode}" and (m.queue, m.queue_offset) == (queue, 0)
    assert result.extra["shader"] == "Standard"
    forward, delta = m.passes[:2]
    assert (forward.name, forward.light_mode, delta.light_mode) == ("FORWARD", LightMode.ForwardBase,
                                                                    LightMode.ForwardAdd)
    assert forward.blend and (forward.src_blend, forward.dst_blend) == factors and forward.zwrite is zwrite
    assert forward.alpha_test is alpha_test and delta.alpha_test is alpha_test
    assert not delta.zwrite  # FORWARD_DELTA: 'Blend [_SrcBlend] One' 'ZWrite Off'
    assert delta.dst_blend is F.One
    assert forward.separate_alpha is (mode == "Transparent")
    if mode == "Transparent":
        assert (forward.src_blend_alpha, forward.dst_blend_alpha) == (F.One, F.OneMinusSrcAlpha)
    assert m.color == (0.8, 0.4, 0.2, 0.6) and m.cutoff == 0.35 and m.lighting is Lighting.Lambert
    assert m.main_tex_tiling == (2.0, 3.0) and m.main_tex_offset == (0.25, 0.5)
    assert [e["name"] for e in result.to_dict()["passes"] if e["drawn"]] == ["FORWARD"]


@needs_corpus
def test_the_oldest_layout_and_2021_layout_import_the_same_modes():
    fade = _import("Unity4/Fade.mat").material.passes[0]
    assert (fade.src_blend, fade.dst_blend, fade.zwrite) == (F.SrcAlpha, F.OneMinusSrcAlpha, False)
    result = _import("Standard2021/Transparent.mat")
    forward = result.material.passes[0]
    assert (forward.src_blend, forward.dst_blend, forward.separate_alpha) == (F.SrcAlpha, F.OneMinusSrcAlpha, True)
    caster = next(e for e in result.to_dict()["passes"] if e["name"] == "ShadowCaster")
    assert not caster["drawn"] and "disabledShaderPasses" in caster["reason"]
    assert "ShadowCaster" not in [p.name for p in result.material.passes]


# --------------------------------------------------------------------------- a custom shader's [_Prop] state


def test_a_custom_shader_takes_its_state_from_the_material():
    """CustomBlend.shader: 'Blend [_SrcBlend] [_DstBlend] ZWrite [_ZWrite] Cull [_Cull] ZTest [_ZTest]
    ColorMask [_ColorMask] Stencil { Ref [_Ref] Comp [_StencilComp] Pass [_StencilOp] }' and '#pragma
    shader_feature _ALPHATEST_ON' around 'clip(col.a - _Cutoff)'; Custom.mat: _SrcBlend 1, _DstBlend 1,
    _ZWrite 0, _Cull 0, _ZTest 8, _ColorMask 14, _Ref 3, _StencilComp 3, _StencilOp 2, _Cutoff 0.25,
    keyword _ALPHATEST_ON, m_CustomRenderQueue 3100, disabledShaderPasses [SHADOWCASTER]."""
    result = import_material_file(MATERIALS / "Custom.mat")  # the shader is found by its .meta guid
    m = result.material
    assert m.name == "Custom Additive" and result.extra["shader"] == "Custom/PropBlend"
    assert (m.queue, m.queue_offset) == (Queue.Transparent, 100)
    (p,) = m.passes
    assert (p.src_blend, p.dst_blend, p.zwrite, p.cull, p.ztest) == (F.One, F.One, False, Cull.Off,
                                                                      CompareFunction.Always)
    assert p.color_mask == frozenset("RGB")
    assert p.stencil and (p.stencil_ref, p.stencil_comp, p.stencil_pass) == (3, CompareFunction.Equal,
                                                                             StencilOp.Replace)
    assert p.alpha_test and p.alpha_test_comp is CompareFunction.GEqual and m.cutoff == 0.25
    assert m.color == (0.5, 1.0, 0.25, 0.75)
    listed = result.to_dict()["passes"]
    assert [e["name"] for e in listed] == ["Pass 1", "ShadowCaster"] and not listed[1]["drawn"]
    # Without the keyword the clip is compiled out.
    text = (MATERIALS / "Custom.mat").read_text().replace("m_ShaderKeywords: _ALPHATEST_ON", "m_ShaderKeywords: ")
    plain = MATERIALS.parent / "Custom_no_keyword.mat"
    try:
        plain.write_text(text)
        assert not import_material_file(plain).material.passes[0].alpha_test
    finally:
        plain.unlink()


# --------------------------------------------------------------------------- textures


@needs_corpus
def test_texture_settings_come_from_the_texture_meta():
    """Checker.png.meta: enableMipMap 0, filterMode 0 (Point), wrapU 1 (Clamp); Sprite.png.meta:
    textureType 8 (Sprite: no mipmaps unless stated), filterMode 2 (Trilinear), mipMapsPreserveCoverage 1
    at alphaTestReferenceValue 0.25; Plain.png.meta: no TextureImporter → Unity's defaults."""
    m = _import("Standard/Fade.mat").material
    assert (m.main_tex_mipmaps, m.main_tex_filter, m.main_tex_wrap) == (False, TextureFilter.Point,
                                                                         TextureWrap.Clamp)
    result = _import("Builtin/Sprite.mat")
    m = result.material
    assert (m.main_tex_mipmaps, m.main_tex_filter, m.main_tex_wrap) == (False, TextureFilter.Trilinear,
                                                                         TextureWrap.Repeat)
    assert m.main_tex_preserve_coverage and any("preserve coverage at 0.25" in w for w in result.warnings)
    assert result.main_tex_file == str((ASSETS / "Textures" / "Sprite.png").resolve())
    assert result.to_dict()["material"]["main_tex"] == result.main_tex_file
    m = import_material_file(MATERIALS / "Custom.mat").material
    assert (m.main_tex_mipmaps, m.main_tex_filter, m.main_tex_wrap) == (True, TextureFilter.Bilinear,
                                                                         TextureWrap.Repeat)


@needs_corpus
def test_builtin_shaders_by_file_id():
    """fileID 10753 Sprites/Default, 203 Legacy Shaders/Particles/Alpha Blended, 30 Legacy Shaders/
    Transparent/Diffuse, 10770 UI/Default (guid 0000000000000000f000000000000000)."""
    assert _import("Builtin/Sprite.mat").extra["shader"] == "Sprites/Default"
    smoke = _import("Builtin/Smoke.mat")
    assert smoke.extra["shader"] == "Legacy Shaders/Particles/Alpha Blended"
    m = smoke.material
    assert m.vertex_color is VertexColor.Particle and m.tint_color == (0.2794118, 0.2794118, 0.2794118, 0.57)
    assert m.main_tex_tiling == (2.0, 1.0) and m.main_tex_offset == (0.0, 0.5)
    assert _import("Builtin/Glass.mat").material.color == (0.5, 0.75, 1.0, 0.25)
    panel = _import("Builtin/Panel.mat")
    (p,) = panel.material.passes
    # '_Stencil 1, _StencilComp 3, _StencilOp 0, _StencilReadMask 1, _StencilWriteMask 0' and the keyword
    # UNITY_UI_ALPHACLIP: '#ifdef UNITY_UI_ALPHACLIP clip (color.a - 0.001);'.
    assert (p.stencil_ref, p.stencil_comp, p.stencil_pass, p.stencil_read_mask, p.stencil_write_mask) == (
        1, CompareFunction.Equal, StencilOp.Keep, 1, 0)
    assert p.alpha_test and panel.material.cutoff == 0.001


def test_a_missing_shader_is_one_clear_error():
    with pytest.raises(UnityFileError) as err:
        import_material_file(MATERIALS / "Standard" / "Fade.mat")  # no built-in shader folder to search
    assert "built-in shader 'Standard' (fileID 46) is not on the search path" in str(err.value)
    assert str(err.value).startswith(str(MATERIALS / "Standard" / "Fade.mat"))


# --------------------------------------------------------------------------- rendered as Unity blends it


@needs_corpus
def test_standard_fade_renders_the_blend_computed_by_hand():
    """Standard Fade, _Color (0.8, 0.4, 0.2, 0.6), no texture, over an opaque backdrop of codes
    (51, 153, 255, 255); ambient 1 and no light, so the lit colour is the albedo. Blend SrcAlpha
    OneMinusSrcAlpha, 8-bit frame (stored floor(255 v + 0.5)):
    r 0.8*0.6 + 0.2*0.4 = 0.56 → 142.8 → 143; g 0.4*0.6 + 0.6*0.4 = 0.48 → 122.4 → 122;
    b 0.2*0.6 + 1.0*0.4 = 0.52 → 132.6 → 133; a 0.6*0.6 + 1.0*0.4 = 0.76 → 193.8 → 194."""
    from dataclasses import replace

    material = _import("Standard/Fade.mat").material
    material = replace(material, main_tex=None)  # the checker texture aside: _Color alone
    backdrop = Material(name="Backdrop", queue=Queue.Geometry, lighting=Lighting.Unlit,
                        color=(51 / 255, 153 / 255, 1.0, 1.0))
    scene = DrawScene(camera=screen_camera(8, 8), light=None, ambient=(1.0, 1.0, 1.0),
                      renderers=(renderer(quad(0, 0, 8, 8, z=-1.0), backdrop, name="Backdrop"),
                                 renderer(quad(2, 2, 6, 6, z=0.0), material, name="Fade")))
    frame = render_scene(scene, workers=1)
    codes = np.rint(frame.color * 255).astype(int)
    assert (codes[3, 3] == [143, 122, 133, 194]).all()
    assert (codes[0, 0] == [51, 153, 255, 255]).all()


# --------------------------------------------------------------------------- CLI and projects


@needs_corpus
def test_cli_imports_a_material_file(capsys):
    assert cli_main(["shaderlab", str(MATERIALS / "Standard" / "Cutout.mat"), "--search", SEARCH[0]]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["name"] == "Standard Cutout" and record["material"]["queue"] == "AlphaTest"
    assert record["extra"]["shader"] == "Standard" and record["passes"][0]["alpha_test"] is True
    assert record["material"]["main_tex"].endswith("Checker.png")


def test_cli_material_errors_are_one_line(tmp_path, capsys):
    assert cli_main(["shaderlab", str(MATERIALS / "Standard" / "Fade.mat")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "not on the search path" in err
    assert cli_main(["shaderlab", str(MATERIALS / "Custom.mat"), "--search", str(tmp_path / "nope")]) == 1
    assert "--search folder does not exist" in capsys.readouterr().err
    bad = tmp_path / "bad.mat"
    bad.write_text("--- !u!21 &1\nMaterial:\n  m_Shader: [unclosed\n")
    assert cli_main(["shaderlab", str(bad)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not valid YAML" in err and "Traceback" not in err


def test_project_materials_by_name():
    names = project_materials(PROJECT)
    assert names["Standard Fade"] == [str(MATERIALS / "Standard" / "Fade.mat")]
    assert names["Custom Additive"] == [str(MATERIALS / "Custom.mat")]
    assert names["Standard2021 Transparent"] == [str(MATERIALS / "Standard2021" / "Transparent.mat")]
    assert "" not in names  # the MonoBehaviour document's empty m_Name is not the material's
    assert len(names) == 16


def test_a_shader_import_error_in_a_material_names_the_shader(tmp_path):
    shader = tmp_path / "Assets" / "Bad.shader"
    shader.parent.mkdir()
    shader.write_text('Shader "Bad" { SubShader { Pass { Blend One Nope } } }')
    (tmp_path / "Assets" / "Bad.shader.meta").write_text("guid: 0123456789abcdef0123456789abcdef\n")
    mat = tmp_path / "Assets" / "Bad.mat"
    mat.write_text("--- !u!21 &2100000\nMaterial:\n  m_Name: Bad\n  m_Shader: {fileID: 4800000, guid: "
                   "0123456789abcdef0123456789abcdef, type: 3}\n")
    with pytest.raises(ShaderLabError) as err:
        import_material_file(mat)
    assert str(err.value).startswith(str(shader)) and "unknown blend factor 'Nope'" in str(err.value)
