"""The Unity settings of materials and scenes (addon/material_settings): the Material.unity / Scene.unity
properties, save and reload, the presets and pass operators, and the panels, drawn against the
recording layout of :mod:`tests.addon.recording`."""

from __future__ import annotations

from types import SimpleNamespace

import bpy
import numpy as np
import pytest

import addon
from addon.material_settings.panel import (
    UNITY_MT_presets,
    UNITY_PT_camera,
    UNITY_PT_material,
    UNITY_PT_material_passes,
    UNITY_UL_passes,
    shaderlab_preview,
)
from blendlib import blender
from blendlib.blender import read_pass
from blendlib.core.vocabulary import PASS_PRESETS, Pass, preset
from tests.addon.recording import RecordingLayout, draw_panel
from tests.support.blender_fixtures import add_cube, empty_scene, principled_material


@pytest.fixture(autouse=True)
def registered():
    addon.register()
    yield
    addon.unregister()


PASS_SPEC = {
    "name": ("STRING", "Pass", None),
    "cull": ("ENUM", "Back", {"Back", "Front", "Off"}),
    "zwrite": ("BOOLEAN", True, None),
    "ztest": ("ENUM", "LEqual", {"Less", "Greater", "LEqual", "GEqual", "Equal", "NotEqual", "Always"}),
    "blend": ("BOOLEAN", False, None),
    "src_blend": ("ENUM", "One", "factors"),
    "dst_blend": ("ENUM", "Zero", "factors"),
    "blend_op": ("ENUM", "Add", {"Add", "Sub", "RevSub", "Min", "Max"}),
    "separate_alpha": ("BOOLEAN", False, None),
    "src_blend_alpha": ("ENUM", "One", "factors"),
    "dst_blend_alpha": ("ENUM", "Zero", "factors"),
    "blend_op_alpha": ("ENUM", "Add", {"Add", "Sub", "RevSub", "Min", "Max"}),
    "color_mask": ("ENUM", {"R", "G", "B", "A"}, {"R", "G", "B", "A"}),
    "offset_factor": ("FLOAT", 0.0, None),
    "offset_units": ("FLOAT", 0.0, None),
    "alpha_test": ("BOOLEAN", False, None),
    "stencil": ("BOOLEAN", False, None),
    "stencil_ref": ("INT", 0, None),
    "stencil_read_mask": ("INT", 255, None),
    "stencil_write_mask": ("INT", 255, None),
    "stencil_comp": ("ENUM", "Always", {"Never", "Less", "Equal", "LEqual", "Greater", "NotEqual", "GEqual", "Always"}),
    "stencil_pass": ("ENUM", "Keep", "ops"),
    "stencil_fail": ("ENUM", "Keep", "ops"),
    "stencil_zfail": ("ENUM", "Keep", "ops"),
    # SPEC §12
    "alpha_to_mask": ("BOOLEAN", False, None),
    "alpha_test_comp": ("ENUM", "GEqual", {"Never", "Less", "Equal", "LEqual", "Greater", "NotEqual", "GEqual",
                                           "Always"}),
    "light_mode": ("ENUM", "ForwardBase", {"Always", "ForwardBase", "ForwardAdd", "Vertex", "VertexLM",
                                           "VertexLMRGBM", "ShadowCaster", "ShadowCollector", "Meta", "Deferred",
                                           "PrepassBase", "PrepassFinal", "MotionVectors", "Other"}),
    # the outline vertex program (issue 28)
    "outline_mode": ("ENUM", "Off", {"Off", "World", "Screen"}),
    "outline_width": ("FLOAT", 0.0, None),
    "outline_formula": ("ENUM", "MToon0x", {"MToon0x", "MToon10"}),
    "outline_max_distance": ("FLOAT", 1.0, None),
}
FACTORS = {"One", "Zero", "SrcColor", "SrcAlpha", "DstColor", "DstAlpha", "OneMinusSrcColor", "OneMinusSrcAlpha",
           "OneMinusDstColor", "OneMinusDstAlpha", "SrcAlphaSaturate"}
OPS = {"Keep", "Zero", "Replace", "IncrSat", "DecrSat", "Invert", "IncrWrap", "DecrWrap"}


def check_props(group, spec):
    props = group.bl_rna.properties
    for name, (kind, default, items) in spec.items():
        prop = props[name]
        assert prop.type == kind, name
        assert prop.description, name
        value = getattr(group, name)
        if kind == "FLOAT" and prop.array_length:
            np.testing.assert_allclose(tuple(value), default, atol=1e-6, err_msg=name)
        elif kind == "FLOAT":
            assert value == pytest.approx(default), name
        else:
            assert value == default, name
        if items is not None:
            items = {"factors": FACTORS, "ops": OPS}.get(items, items) if isinstance(items, str) else items
            assert set(prop.enum_items.keys()) == items, name


def test_spec_properties_and_defaults():
    empty_scene()
    mat = bpy.data.materials.new("M")
    u = mat.unity
    check_props(u, {
        "enabled": ("BOOLEAN", False, None),
        "queue": ("ENUM", "Geometry", {"Background", "Geometry", "AlphaTest", "Transparent", "Overlay"}),
        "queue_offset": ("INT", 0, None),
        "color": ("FLOAT", (1, 1, 1, 1), None),
        "main_tex_tiling": ("FLOAT", (1, 1), None),
        "main_tex_offset": ("FLOAT", (0, 0), None),
        "main_tex_filter": ("ENUM", "Bilinear", {"Bilinear", "Point", "Trilinear"}),
        "main_tex_mipmaps": ("BOOLEAN", False, None),
        "main_tex_preserve_coverage": ("BOOLEAN", False, None),
        "vertex_color": ("ENUM", "Off", {"Off", "Multiply", "Particle"}),
        "tint_color": ("FLOAT", (0.5, 0.5, 0.5, 0.5), None),
        "main_tex_wrap": ("ENUM", "Repeat", {"Repeat", "Clamp"}),
        "alpha_scale": ("FLOAT", 1.0, None),
        "cutoff": ("FLOAT", 0.5, None),
        "lighting": ("ENUM", "Lambert", {"Lambert", "Unlit"}),
    })
    props = u.bl_rna.properties
    assert props["color"].subtype == "COLOR_GAMMA" and props["main_tex"].fixed_type.identifier == "Image"
    assert props["passes"].type == "COLLECTION" and "active_pass_index" in props
    p = u.passes.add()
    check_props(p, PASS_SPEC)
    assert p.bl_rna.properties["color_mask"].is_enum_flag
    s = bpy.context.scene.unity
    check_props(s, {
        "color_space": ("ENUM", "Gamma", {"Gamma", "Linear"}),
        "hdr": ("BOOLEAN", False, None),
        "clear_color": ("FLOAT", (0.19, 0.30, 0.47, 0.0), None),
        "ambient_from_world": ("BOOLEAN", True, None),
        "ambient_color": ("FLOAT", (0.2, 0.2, 0.2), None),
        "sort_mode": ("ENUM", "Default", {"Default", "Perspective", "Orthographic", "CustomAxis"}),
        "sort_axis": ("FLOAT", (0, 0, 1), None),
        "msaa": ("INT", 1, None),
        "pixel_light_count": ("INT", 4, None),
    })
    for name in ("clear_color", "ambient_color"):
        assert s.bl_rna.properties[name].subtype == "COLOR_GAMMA"
    assert u.bl_rna.properties["tint_color"].subtype == "COLOR_GAMMA"
    light = bpy.data.lights.new("L", "SPOT")
    check_props(light.unity, {
        "use_blender_values": ("BOOLEAN", True, None),
        "intensity": ("FLOAT", 1.0, None),
        "range": ("FLOAT", 10.0, None),
        "spot_angle": ("FLOAT", 30.0, None),
        "render_mode": ("ENUM", "Auto", {"Auto", "Important", "NotImportant"}),
    })


def test_properties_survive_save_and_reload(tmp_path):
    empty_scene()
    img = bpy.data.images.new("Tex", 2, 2)
    img.use_fake_user = True
    mat = bpy.data.materials.new("Glass")
    mat.use_fake_user = True
    u = mat.unity
    u.enabled, u.queue, u.queue_offset, u.color = True, "Transparent", 1, (0.1, 0.2, 0.3, 0.4)
    u.main_tex, u.main_tex_tiling, u.main_tex_filter, u.cutoff = img, (2.0, 3.0), "Point", 0.25
    p = u.passes.add()
    p.name, p.color_mask, p.ztest, p.blend, p.src_blend = "P1", {"R", "A"}, "Greater", True, "SrcAlphaSaturate"
    p.stencil, p.stencil_ref, p.stencil_comp, p.stencil_zfail = True, 7, "NotEqual", "DecrWrap"
    q = u.passes.add()
    q.color_mask = set()
    s = bpy.context.scene.unity
    s.color_space, s.hdr, s.clear_color, s.sort_mode = "Linear", True, (0.5, 0.5, 0.5, 1.0), "CustomAxis"
    path = tmp_path / "props.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    expected = blender.read_group(u, blender.MATERIAL_FIELDS)
    expected_scene = blender.read_group(s, blender.SCENE_FIELDS)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    u = bpy.data.materials["Glass"].unity
    assert (u.enabled, u.queue, u.queue_offset, u.main_tex.name, u.main_tex_filter) == \
        (True, "Transparent", 1, "Tex", "Point")
    assert [(x.name, x.color_mask, x.ztest, x.src_blend, x.stencil_ref, x.stencil_zfail) for x in u.passes] == [
        ("P1", {"R", "A"}, "Greater", "SrcAlphaSaturate", 7, "DecrWrap"), ("Pass", set(), "LEqual", "One", 0, "Keep")]
    assert bpy.context.scene.unity.color_space == "Linear" and bpy.context.scene.unity.sort_mode == "CustomAxis"
    # Without the add-on, the bridge reads the same values from the stored ID properties.
    addon.unregister()
    bpy.ops.wm.open_mainfile(filepath=str(path))
    mat = bpy.data.materials["Glass"]
    assert not hasattr(mat, "unity")
    got = blender.read_group(blender.unity_props(mat), blender.MATERIAL_FIELDS)
    assert got["main_tex"].name == "Tex"
    got["main_tex"] = expected["main_tex"] = None
    assert got == expected
    assert blender.read_group(blender.unity_props(bpy.context.scene), blender.SCENE_FIELDS) == expected_scene


@pytest.mark.parametrize("name", list(PASS_PRESETS))
def test_presets_set_documented_state(name):
    empty_scene()
    mat = bpy.data.materials.new("M")
    mat.unity.queue_offset = 5
    mat.unity.passes.add().name = "old"
    with bpy.context.temp_override(material=mat):
        assert bpy.ops.unity.apply_preset(preset=name) == {"FINISHED"}
    queue, passes = preset(name)
    assert mat.unity.enabled and mat.unity.queue == queue.value and mat.unity.queue_offset == 0
    assert tuple(read_pass(p) for p in mat.unity.passes) == passes
    assert all(isinstance(p, Pass) for p in passes)


def test_pass_list_operators_and_preview():
    empty_scene()
    mat = bpy.data.materials.new("M")
    u = mat.unity
    with bpy.context.temp_override(material=mat):
        bpy.ops.unity.pass_add()
        u.passes[0].blend = True
        u.passes[0].src_blend = "SrcAlpha"
        bpy.ops.unity.pass_duplicate()
        assert len(u.passes) == 2 and u.passes[1].src_blend == "SrcAlpha" and u.active_pass_index == 1
        u.passes[1].name = "Second"
        u.passes[1].cull = "Off"
        bpy.ops.unity.pass_move(direction="UP")
        assert [p.name for p in u.passes] == ["Second", "Pass 1"] and u.active_pass_index == 0
        bpy.ops.unity.pass_remove()
        assert [p.name for p in u.passes] == ["Pass 1"]
    assert shaderlab_preview(u.passes[0]) == "Cull Back ZWrite On ZTest LEqual Blend SrcAlpha Zero"


def test_fill_from_principled():
    empty_scene()
    mat, bsdf = principled_material("P", (0.5, 0.0, 1.0, 1.0), 0.3)
    with bpy.context.temp_override(material=mat):
        assert bpy.ops.unity.fill_from_principled() == {"FINISHED"}
    np.testing.assert_allclose(mat.unity.color, (0.735357, 0.0, 1.0, 0.3), atol=1e-5)  # sRGB-encoded 0.5
    img = bpy.data.images.new("T", 2, 2)
    node = mat.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = img
    mat.node_tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    with bpy.context.temp_override(material=mat):
        bpy.ops.unity.fill_from_principled()
    assert mat.unity.main_tex == img and tuple(mat.unity.color)[:3] == (1.0, 1.0, 1.0)



@pytest.fixture()
def material():
    scene = empty_scene()
    mat = bpy.data.materials.new("Glass")
    add_cube("Cube", 2.0, material=mat)
    with bpy.context.temp_override(material=mat):
        bpy.ops.unity.apply_preset(preset="Alpha Blend ZWrite")
    return scene, mat


def test_material_panel_shows_queue_number_and_every_material_property(material):
    scene, mat = material
    mat.unity.queue_offset = 1
    log = draw_panel(UNITY_PT_material, material=mat, scene=scene)
    assert any("3001" in text and "Transparent+1" in text for text in log["labels"]), log["labels"]
    for name in ("enabled", "queue", "queue_offset", "color", "main_tex", "main_tex_tiling", "main_tex_offset",
                 "main_tex_filter", "main_tex_wrap", "alpha_scale", "cutoff", "lighting"):
        assert name in log["props"], name
    assert "unity.shaderlab_import" in log["operators"] and "unity.shaderlab_export" in log["operators"]
    assert "UNITY_MT_presets" in log["menus"]


def test_passes_panel_lists_passes_with_shaderlab_preview_and_every_pass_property(material):
    scene, mat = material
    mat.unity.active_pass_index = 1
    log = draw_panel(UNITY_PT_material_passes, material=mat, scene=scene)
    assert "passes" in log["props"]
    assert {"unity.pass_add", "unity.pass_remove", "unity.pass_duplicate", "unity.pass_move"} <= set(log["operators"])
    assert "Cull Back ZWrite Off ZTest LEqual Blend SrcAlpha OneMinusSrcAlpha" in log["labels"], log["labels"]
    for name in ("cull", "zwrite", "ztest", "blend", "src_blend", "dst_blend", "blend_op", "separate_alpha",
                 "src_blend_alpha", "dst_blend_alpha", "blend_op_alpha", "color_mask", "offset_factor",
                 "offset_units", "alpha_test", "stencil", "stencil_ref", "stencil_read_mask", "stencil_write_mask",
                 "stencil_comp", "stencil_pass", "stencil_fail", "stencil_zfail"):
        assert name in log["props"], name
    # The list row of the depth prepass shows its state in one line.
    row_log = {"labels": [], "props": [], "operators": [], "menus": []}
    ul = SimpleNamespace(layout_type="DEFAULT")
    UNITY_UL_passes.draw_item(ul, None, RecordingLayout(row_log), mat.unity, mat.unity.passes[0], 0, mat.unity,
                              "active_pass_index")
    assert row_log["labels"] == ["Cull Back ZWrite On ZTest LEqual Blend Off ColorMask 0"]


def test_camera_panel_warns_about_the_view_transform(material):
    scene, _ = material
    scene.view_settings.view_transform = "AgX"
    log = draw_panel(UNITY_PT_camera, scene=scene)
    for name in ("color_space", "hdr", "clear_color", "ambient_from_world", "ambient_color", "sort_mode", "sort_axis"):
        assert name in log["props"], name
    assert any("AgX" in text for text in log["labels"]) and "unity.use_standard_view" in log["operators"]
    scene.view_settings.view_transform = "Standard"
    assert not any("AgX" in text for text in draw_panel(UNITY_PT_camera, scene=scene)["labels"])


def test_presets_menu_offers_every_preset(material):
    log = {"labels": [], "props": [], "operators": [], "menus": []}
    presets: list[str] = []

    class MenuLayout(RecordingLayout):
        def operator(self, idname, text="", **kwargs):
            presets.append(text)
            return super().operator(idname, **kwargs)

    UNITY_MT_presets.draw(SimpleNamespace(layout=MenuLayout(log)), None)
    assert set(PASS_PRESETS) <= set(presets), set(PASS_PRESETS) - set(presets)


def test_panel_preview_and_export_write_the_same_state(material):
    """One writer of a pass's state text: the panel's preview line is the exporter's state lines
    joined, with Offset as the shortest text of the stored float32."""
    from blendlib.formats.shaderlab import export_shaderlab

    scene, mat = material
    item = mat.unity.passes[1]
    item.offset_factor, item.offset_units = 0.1234567, -2.0
    item.stencil, item.stencil_ref, item.stencil_comp = True, 3, "Equal"
    item.color_mask = {"R", "A"}
    item.alpha_test = True
    preview = shaderlab_preview(item)
    assert preview == ("Cull Back ZWrite Off ZTest LEqual Blend SrcAlpha OneMinusSrcAlpha ColorMask RA "
                       "Offset 0.1234567, -2 Stencil { Ref 3 ReadMask 255 WriteMask 255 Comp Equal Pass Keep "
                       "Fail Keep ZFail Keep } clip(a - _Cutoff)")
    text = export_shaderlab(blender.material_from_blender(mat), "X")
    block = text[text.index('Name "Blend"'):]
    lines = [line.strip() for line in block.splitlines()[3:10]]
    assert " ".join(lines) + " clip(a - _Cutoff)" == preview, lines
    assert "0.123457," not in text and "0.1234567016" not in text
