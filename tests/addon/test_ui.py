"""The add-on's panels, list and menu draw without errors and show what they should.

Blender builds no real UILayout in background mode, so the draw functions run against a
recording layout that checks what a real one would reject: every ``prop()`` must name an
RNA property of its data, every ``operator()``/``menu()`` a registered class.
"""

from __future__ import annotations

from types import SimpleNamespace

import bpy
import pytest

import addon
from blendlib.core.vocabulary import PASS_PRESETS
from tests.support.blender_fixtures import add_cube, empty_scene


class RecordingLayout:
    """Stands in for bpy.types.UILayout; collects labels, properties, operators and menus."""

    def __init__(self, log: dict):
        self.log = log
        self.active = True
        self.enabled = True
        self.alignment = "EXPAND"
        self.use_property_split = False
        self.use_property_decorate = True

    def _child(self, *args, **kwargs):
        return RecordingLayout(self.log)

    row = column = box = split = column_flow = grid_flow = _child

    def separator(self, *args, **kwargs):
        pass

    def label(self, *, text="", **kwargs):
        self.log["labels"].append(text)

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, f"{type(data).__name__} has no property {name!r}"
        self.log["props"].append(name)

    def operator(self, idname, **kwargs):
        module, _, name = idname.partition(".")
        assert hasattr(getattr(bpy.ops, module), name), f"operator {idname} is not registered"
        self.log["operators"].append(idname)

        rna = getattr(getattr(bpy.ops, module), name).get_rna_type()

        class Properties:  # e.g. ``.direction = "UP"``: the operator must have that property
            def __setattr__(self, key, value):
                assert key in rna.properties, f"{idname} has no property {key!r}"

        return Properties()

    def menu(self, idname, **kwargs):
        assert hasattr(bpy.types, idname), f"menu {idname} is not registered"
        self.log["menus"].append(idname)

    def template_list(self, list_id, list_name, data, prop, active_data, active_prop, **kwargs):
        assert hasattr(bpy.types, list_id)
        assert prop in data.bl_rna.properties and active_prop in active_data.bl_rna.properties
        self.log["props"].append(prop)

    def template_ID(self, data, name, **kwargs):
        assert name in data.bl_rna.properties
        self.log["props"].append(name)


def _draw(cls, **context):
    """Run a panel's poll, draw_header and draw with a recording layout (``self`` stands in:
    Blender's struct classes cannot be instantiated outside a real region)."""
    log = {"labels": [], "props": [], "operators": [], "menus": []}
    panel = SimpleNamespace(layout=RecordingLayout(log))
    ctx = SimpleNamespace(**context)
    assert cls.poll(ctx)
    if "draw_header" in vars(cls):
        cls.draw_header(panel, ctx)
    cls.draw(panel, ctx)
    return log


@pytest.fixture()
def material():
    addon.register()
    scene = empty_scene()
    mat = bpy.data.materials.new("Glass")
    add_cube("Cube", 2.0, material=mat)
    with bpy.context.temp_override(material=mat):
        bpy.ops.unity.apply_preset(preset="Alpha Blend ZWrite")
    return scene, mat


def test_material_panel_shows_queue_number_and_every_material_property(material):
    scene, mat = material
    mat.unity.queue_offset = 1
    from addon.ui import UNITY_PT_material

    log = _draw(UNITY_PT_material, material=mat, scene=scene)
    assert any("3001" in text and "Transparent+1" in text for text in log["labels"]), log["labels"]
    for name in ("enabled", "queue", "queue_offset", "color", "main_tex", "main_tex_tiling", "main_tex_offset",
                 "main_tex_filter", "main_tex_wrap", "alpha_scale", "cutoff", "lighting"):
        assert name in log["props"], name
    assert "unity.shaderlab_import" in log["operators"] and "unity.shaderlab_export" in log["operators"]
    assert "UNITY_MT_presets" in log["menus"]


def test_passes_panel_lists_passes_with_shaderlab_preview_and_every_pass_property(material):
    scene, mat = material
    from addon.ui import UNITY_PT_material_passes, UNITY_UL_passes

    mat.unity.active_pass_index = 1
    log = _draw(UNITY_PT_material_passes, material=mat, scene=scene)
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
    from addon.ui import UNITY_PT_camera

    scene.view_settings.view_transform = "AgX"
    log = _draw(UNITY_PT_camera, scene=scene)
    for name in ("color_space", "hdr", "clear_color", "ambient_from_world", "ambient_color", "sort_mode", "sort_axis"):
        assert name in log["props"], name
    assert any("AgX" in text for text in log["labels"]) and "unity.use_standard_view" in log["operators"]
    scene.view_settings.view_transform = "Standard"
    assert not any("AgX" in text for text in _draw(UNITY_PT_camera, scene=scene)["labels"])


def test_presets_menu_offers_every_preset(material):
    from addon.operators import UNITY_MT_presets

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
    from addon.ui import shaderlab_preview
    from blendlib import blender
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
