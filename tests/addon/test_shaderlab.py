"""ShaderLab import and export in Blender: the operators (Import ShaderLab…, paste, Export), the
CLI's export from a .blend file, and reading a material through the bridge."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import bpy
import pytest

import addon
from blendlib.blender import write_pass
from blendlib.core.vocabulary import (
    BlendFactor,
    BlendOp,
    CompareFunction,
    Cull,
    Lighting,
    Pass,
    Queue,
    pass_to_dict,
    preset,
)
from blendlib.formats.shaderlab import parse_shaderlab
from tests.formats.test_shaderlab import GOOD, _run, cleaned
from tests.support.shared import BUILTIN_SHADERS


@pytest.fixture(scope="module")
def blender():
    """The add-on registered (it registers this module's operators), restored afterwards."""
    from types import SimpleNamespace

    from addon import shaderlab

    registered = hasattr(bpy.types.Material, "unity")
    if not registered:
        addon.register()
    yield SimpleNamespace(register=shaderlab.register, apply_result=shaderlab.ops.apply_result,
                          draw_import_export=shaderlab.panel.draw_import_export)
    if not registered:
        addon.unregister()


def test_addon_package_registers_the_operators():
    """addon.register() registers the ShaderLab operators and Link Unity Project."""
    registered = hasattr(bpy.types.Material, "unity")
    if not registered:
        addon.register()
    try:
        assert hasattr(bpy.types, "UNITY_OT_shaderlab_import")
        assert hasattr(bpy.types, "UNITY_OT_shaderlab_import_clipboard")
        assert hasattr(bpy.types, "UNITY_OT_shaderlab_export")
        assert hasattr(bpy.types, "UNITY_OT_link_unity_project")
    finally:
        if not registered:
            addon.unregister()


def _new_material(name="M"):
    mat = bpy.data.materials.new(name)
    u = mat.unity
    u.queue = "Overlay"
    u.queue_offset = 7
    u.color = (0.1, 0.2, 0.3, 0.4)
    u.cutoff = 0.9
    u.main_tex_tiling = (3.0, 4.0)
    u.main_tex_filter = "Point"
    for _ in range(3):
        item = u.passes.add()
        item.name = "Old"
        item.cull = "Off"
    return mat


def _snapshot(mat):
    u = mat.unity
    data = {k: (tuple(v) if hasattr(v, "__len__") and not isinstance(v, str) else v)
            for k in ("enabled", "queue", "queue_offset", "color", "alpha_scale", "cutoff", "lighting",
                      "main_tex_tiling", "main_tex_offset", "main_tex_filter", "main_tex_wrap")
            for v in [getattr(u, k)]}
    data["passes"] = [{k: getattr(p, k) for k in pass_to_dict(Pass())} for p in u.passes]
    return data


def _call(op, mat, **kw):
    with bpy.context.temp_override(material=mat):
        return op(**kw)


def test_operator_import_file_replaces_settings(blender, tmp_path):
    path = tmp_path / "both.shader"
    path.write_text(cleaned("000#3"), encoding="utf-8")
    mat = _new_material()
    assert _call(bpy.ops.unity.shaderlab_import, mat, filepath=str(path)) == {"FINISHED"}
    u = mat.unity
    assert u.enabled and u.queue == "Transparent" and u.queue_offset == 0
    assert tuple(u.color) == (1, 1, 1, 1) and u.cutoff == 0.5 and u.alpha_scale == 1 and u.lighting == "Lambert"
    assert [(p.name, p.cull, p.zwrite, p.blend, p.src_blend, p.dst_blend, p.color_mask) for p in u.passes] == [
        ("Pass 1", "Front", False, True, "SrcAlpha", "OneMinusSrcAlpha", {"R", "G", "B", "A"}),
        ("Pass 2", "Back", False, True, "SrcAlpha", "OneMinusSrcAlpha", {"R", "G", "B", "A"}),
    ]
    # Texture settings are not in a .shader file: kept, unless asked to reset them.
    assert tuple(u.main_tex_tiling) == (3.0, 4.0) and u.main_tex_filter == "Point"
    assert _call(bpy.ops.unity.shaderlab_import, mat, filepath=str(path), reset_texture=True) == {"FINISHED"}
    assert tuple(u.main_tex_tiling) == (1.0, 1.0) and u.main_tex_filter == "Bilinear"


def test_operator_import_error_changes_nothing(blender, tmp_path):
    mat = _new_material()
    before = _snapshot(mat)
    for i, text in enumerate([GOOD.replace("OneMinusSrcAlpha", "OneMinusSrcAlfa"), GOOD[:120],
                              GOOD.replace("ColorMask RGB", "ColorMask 5")]):
        path = tmp_path / f"bad{i}.shader"
        path.write_text(text, encoding="utf-8")
        with pytest.raises(RuntimeError) as err:
            _call(bpy.ops.unity.shaderlab_import, mat, filepath=str(path))
        assert f"bad{i}.shader:" in str(err.value)
        assert _snapshot(mat) == before
    with pytest.raises(RuntimeError, match="cannot read"):
        _call(bpy.ops.unity.shaderlab_import, mat, filepath=str(tmp_path / "missing.shader"))
    assert _snapshot(mat) == before


def test_operator_import_clipboard(blender):
    mat = _new_material()
    before = _snapshot(mat)
    text = cleaned("002#3")
    assert _call(bpy.ops.unity.shaderlab_import_clipboard, mat, text=text) == {"FINISHED"}
    u = mat.unity
    assert u.enabled and u.queue == "Transparent" and len(u.passes) == 2
    assert u.passes[0].color_mask == set() and u.passes[0].zwrite and not u.passes[0].blend
    assert u.passes[1].blend and not u.passes[1].zwrite
    # Headless Blender has no system clipboard: an empty clipboard is an error that changes nothing.
    mat2 = _new_material("M2")
    bpy.context.window_manager.clipboard = ""
    if bpy.context.window_manager.clipboard == "":
        with pytest.raises(RuntimeError, match="clipboard is empty"):
            _call(bpy.ops.unity.shaderlab_import_clipboard, mat2)
        assert _snapshot(mat2) == before
    with pytest.raises(RuntimeError, match=r"<clipboard>:1:1"):
        _call(bpy.ops.unity.shaderlab_import_clipboard, mat2, text="Pass { }")
    assert _snapshot(mat2) == before


def test_apply_is_atomic_when_assignment_fails(blender):
    mat = _new_material()
    before = _snapshot(mat)
    result = parse_shaderlab(cleaned("000#3"))
    broken = replace(result, material=replace(result.material, lighting="NotALighting"))
    with pytest.raises(ValueError, match="NotALighting"):
        blender.apply_result(mat, broken)
    assert _snapshot(mat) == before


def test_operator_export_then_import_gives_back_the_settings(blender, tmp_path):
    mat = _new_material("Exported")
    u = mat.unity
    u.enabled = True
    u.queue = "Transparent"
    u.queue_offset = -3
    u.lighting = "Unlit"
    u.passes.clear()
    queue, passes = preset("Alpha Blend ZWrite")
    for p in passes + (Pass(name="Stencilled", stencil=True, stencil_ref=5, stencil_comp=CompareFunction.Greater,
                            offset_factor=-1.0, offset_units=-2.0, alpha_test=True, ztest=CompareFunction.Always,
                            blend=True, separate_alpha=True, src_blend=BlendFactor.DstColor,
                            dst_blend=BlendFactor.Zero, src_blend_alpha=BlendFactor.One,
                            dst_blend_alpha=BlendFactor.One, blend_op_alpha=BlendOp.Max),):
        write_pass(u.passes.add(), p)  # the schema's writer (an outline colour None is its switch off)
    before = _snapshot(mat)
    out = tmp_path / "exported.shader"
    assert _call(bpy.ops.unity.shaderlab_export, mat, filepath=str(out)) == {"FINISHED"}
    text = out.read_text(encoding="utf-8")
    assert text.startswith('Shader "Unity Passes/Exported"') and "Stencil" in text and "Greater" in text
    other = bpy.data.materials.new("Other")
    assert _call(bpy.ops.unity.shaderlab_import, other, filepath=str(out)) == {"FINISHED"}
    got = _snapshot(other)
    for key in ("main_tex_tiling", "main_tex_offset", "main_tex_filter", "main_tex_wrap"):
        got.pop(key), before.pop(key)  # not in a .shader file
    assert got["color"] == pytest.approx(before.pop("color")) and got.pop("color")
    assert got == before


def test_cli_export_from_a_blend_file(blender, tmp_path):
    mat = _new_material("CliMat")
    u = mat.unity
    u.enabled = True
    u.queue = "AlphaTest"
    u.queue_offset = 0
    u.passes.clear()
    item = u.passes.add()
    item.name = "Cutout"
    item.alpha_test = True
    item.cull = "Off"
    mat.use_fake_user = True  # saved without an object using it
    blend_path = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend_path), copy=True)
    out = tmp_path / "cli.shader"
    r = _run(["-m", "blendlib", "shaderlab", "--export", str(blend_path), "--material", "CliMat", "-o", str(out)])
    assert r.returncode == 0, r.stderr
    result = parse_shaderlab(out.read_text(encoding="utf-8"))
    assert result.name == "Unity Passes/CliMat" and result.material.queue is Queue.AlphaTest
    assert result.passes == (Pass(name="Cutout", alpha_test=True, cull=Cull.Off),)
    assert result.material.color == pytest.approx((0.1, 0.2, 0.3, 0.4))
    bad = tmp_path / "bad.shader"
    r = _run(["-m", "blendlib", "shaderlab", "--export", str(blend_path), "--material", "Nope", "-o", str(bad)])
    assert r.returncode == 1 and not bad.exists()
    (line,) = r.stderr.strip().splitlines()
    assert line.startswith(f"error: {blend_path}: no material named 'Nope' (materials: ")
    assert "CliMat" in line.split("(materials: ")[1]


def test_reading_a_blender_material_agrees_with_the_bridge(blender):
    """The exporter reads a material through the bridge: what its schema reads, registered or from
    stored ID properties (the add-on unregistered)."""
    from blendlib import blender

    mat = _new_material("Read")
    u = mat.unity
    u.enabled = True
    u.lighting = "Unlit"
    u.passes[1].ztest = "Always"
    u.passes[1].color_mask = {"R", "A"}
    u.passes[2].stencil_comp = "Never"
    u.passes[2].blend_op_alpha = "RevSub"
    u.passes[2].dst_blend = "SrcAlphaSaturate"
    want = blender.read_group(blender.unity_props(mat), blender.MATERIAL_FIELDS)

    class Stored:  # what a reader sees when the add-on is not registered
        name = mat.name
        bl_system_properties_get = mat.bl_system_properties_get

    for source in (mat, Stored()):
        got = blender.material_from_blender(source)
        assert got.queue.value == want["queue"] and got.queue_offset == want["queue_offset"] == 7
        assert got.color == pytest.approx(want["color"]) and got.lighting is Lighting.Unlit
        assert got.cutoff == pytest.approx(want["cutoff"]) and got.main_tex_filter.value == want["main_tex_filter"]
        assert got.passes == tuple(blender.pass_from_values(p) for p in want["passes"])
        assert got.passes[1].ztest is CompareFunction.Always and got.passes[1].color_mask == {"R", "A"}
        assert got.passes[2].stencil_comp is CompareFunction.Never
    u.enabled = False
    disabled = blender.material_from_blender(mat)
    assert disabled.passes == (Pass(),) and disabled.queue is Queue.Geometry


def test_register_unregister_are_idempotent(blender):
    blender.register()
    blender.register()
    assert hasattr(bpy.types, "UNITY_OT_shaderlab_export")
    layout_calls = []

    class FakeRow:
        def operator(self, idname, **kw):
            layout_calls.append(idname)

    class FakeLayout:
        def row(self, align=False):
            return FakeRow()

    blender.draw_import_export(FakeLayout())
    assert layout_calls == ["unity.shaderlab_import", "unity.shaderlab_import_clipboard", "unity.shaderlab_export",
                            "unity.link_unity_project"]


# --------------------------------------------------------------------------- .mat files and Unity projects

PROJECT = Path(__file__).resolve().parents[1] / "fixtures" / "unity_project"
MATERIALS = PROJECT / "Assets" / "Materials"
needs_corpus = pytest.mark.skipif(not BUILTIN_SHADERS.is_dir(), reason="shared/corpus is not available")


@needs_corpus
def test_operator_imports_a_material_file_with_its_texture(blender):
    mat = _new_material("Anything")
    path = MATERIALS / "Standard" / "Fade.mat"
    assert _call(bpy.ops.unity.shaderlab_import, mat, filepath=str(path),
                 search_folder=str(BUILTIN_SHADERS)) == {"FINISHED"}
    u = mat.unity
    assert u.enabled and u.queue == "Transparent" and u.queue_offset == 0
    assert tuple(u.color) == pytest.approx((0.8, 0.4, 0.2, 0.6)) and u.cutoff == pytest.approx(0.35)
    forward = u.passes[0]
    assert (forward.name, forward.light_mode, forward.src_blend, forward.dst_blend, forward.zwrite) == (
        "FORWARD", "ForwardBase", "SrcAlpha", "OneMinusSrcAlpha", False)
    assert [p.light_mode for p in u.passes] == ["ForwardBase", "ForwardAdd", "ShadowCaster", "Deferred", "Meta"]
    # The texture, its m_Scale/m_Offset and its importer settings (Checker.png.meta: Point, Clamp, no mips).
    assert u.main_tex is not None and Path(bpy.path.abspath(u.main_tex.filepath)).name == "Checker.png"
    assert tuple(u.main_tex_tiling) == (2.0, 3.0) and tuple(u.main_tex_offset) == (0.25, 0.5)
    assert (u.main_tex_filter, u.main_tex_wrap, u.main_tex_mipmaps) == ("Point", "Clamp", False)
    images = len(bpy.data.images)
    assert _call(bpy.ops.unity.shaderlab_import, mat, filepath=str(path),
                 search_folder=str(BUILTIN_SHADERS)) == {"FINISHED"}
    assert len(bpy.data.images) == images  # the image is reused, not loaded again


def test_operator_material_file_errors_change_nothing(blender, tmp_path):
    mat = _new_material()
    before = _snapshot(mat)
    images = len(bpy.data.images)
    with pytest.raises(RuntimeError, match="not on the search path"):  # Standard without the shader folder
        _call(bpy.ops.unity.shaderlab_import, mat, filepath=str(MATERIALS / "Standard" / "Fade.mat"))
    bad = tmp_path / "bad.mat"
    bad.write_text("--- !u!21 &1\nMaterial:\n  m_Shader: [unclosed\n", encoding="utf-8")
    with pytest.raises(RuntimeError, match="not valid YAML"):
        _call(bpy.ops.unity.shaderlab_import, mat, filepath=str(bad))
    assert _snapshot(mat) == before and len(bpy.data.images) == images


@needs_corpus
def test_link_unity_project_matches_materials_by_name_and_updates_on_a_second_run(blender):
    from addon.shaderlab.project import link_project

    fade = bpy.data.materials.new("Standard Fade")
    custom = bpy.data.materials.new("Custom Additive")
    sprite = bpy.data.materials.new("Sprite")
    stranger = bpy.data.materials.new("Not In The Project")
    for mat in (fade, custom, sprite, stranger):
        mat.use_fake_user = True
    report = link_project(str(PROJECT), (str(BUILTIN_SHADERS),), [fade, custom, sprite, stranger])
    assert set(report.linked) == {"Standard Fade", "Custom Additive", "Sprite"}
    assert report.linked["Custom Additive"] == str(MATERIALS / "Custom.mat")
    assert report.unmatched == ["Not In The Project"] and not report.failed
    assert report.unused == 16 - 3
    assert fade.unity.enabled and fade.unity.queue == "Transparent" and fade.unity.passes[0].src_blend == "SrcAlpha"
    c = custom.unity
    assert (c.queue, c.queue_offset, c.passes[0].src_blend, c.passes[0].dst_blend) == ("Transparent", 100, "One",
                                                                                      "One")
    assert c.passes[0].stencil and c.passes[0].stencil_ref == 3 and c.passes[0].alpha_test
    assert sprite.unity.vertex_color == "Multiply" and sprite.unity.main_tex is not None
    assert not stranger.unity.enabled
    summary = report.summary()
    assert summary.startswith("Linked 3 materials from ") and "no .mat for: Not In The Project" in summary
    # Edited in Blender, linked again: the project's settings come back.
    c.queue_offset = 7
    c.passes[0].cull = "Back"
    again = link_project(str(PROJECT), (str(BUILTIN_SHADERS),), [custom])
    assert again.linked == {"Custom Additive": str(MATERIALS / "Custom.mat")}
    assert c.queue_offset == 100 and c.passes[0].cull == "Off"


@needs_corpus
def test_link_unity_project_operator_reports_failures_and_keeps_going(blender):
    fade = bpy.data.materials.new("Standard Cutout")
    fade.use_fake_user = True
    before = fade.unity.enabled
    # Without the built-in shader folder the Standard materials cannot be imported: reported, unchanged.
    assert bpy.ops.unity.link_unity_project(directory=str(PROJECT)) == {"FINISHED"}
    assert fade.unity.enabled == before
    assert bpy.ops.unity.link_unity_project(directory=str(PROJECT), search_folder=str(BUILTIN_SHADERS)) == {
        "FINISHED"}
    assert fade.unity.enabled and fade.unity.queue == "AlphaTest" and fade.unity.passes[0].alpha_test
    with pytest.raises(RuntimeError, match="not a folder"):
        bpy.ops.unity.link_unity_project(directory=str(PROJECT / "nope"))
