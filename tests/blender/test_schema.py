"""The schema of ``Material.unity`` / ``Scene.unity``: the stored integers (a file format), the writers
registered and unregistered, schema versions and the migration of files saved by 0.1."""

from __future__ import annotations

import bpy
import pytest

import addon
from addon.material_settings import properties
from addon.material_settings.migration import migrate_on_load
from blendlib import blender
from blendlib.blender import migration, schema
from blendlib.core.vocabulary import (
    COLOR_MASK_BITS,
    BlendFactor,
    CompareFunction,
    Cull,
    Material,
    Pass,
    Queue,
    TextureWrap,
    color_mask_bits,
    color_mask_from_bits,
    preset,
)
from tests.support.blender_fixtures import empty_scene

# The integers Blender stores for each enum item. Changing one changes the meaning of every saved
# file: add a schema version and a migration step (blendlib/blender/migration.py) instead.
COMPARE = {"Never": 0, "Less": 1, "Greater": 2, "LEqual": 3, "GEqual": 4, "Equal": 5, "NotEqual": 6, "Always": 7}
FACTOR = {"One": 0, "Zero": 1, "SrcColor": 2, "SrcAlpha": 3, "DstColor": 4, "DstAlpha": 5, "OneMinusSrcColor": 6,
          "OneMinusSrcAlpha": 7, "OneMinusDstColor": 8, "OneMinusDstAlpha": 9, "SrcAlphaSaturate": 10}
BLEND_OP = {"Add": 0, "Sub": 1, "RevSub": 2, "Min": 3, "Max": 4}
STENCIL_OP = {"Keep": 0, "Zero": 1, "Replace": 2, "IncrSat": 3, "DecrSat": 4, "Invert": 5, "IncrWrap": 6,
              "DecrWrap": 7}
ENUM_NUMBERS = {
    "pass": {
        "cull": {"Back": 0, "Front": 1, "Off": 2},
        "ztest": {k: v for k, v in COMPARE.items() if k != "Never"},
        "src_blend": FACTOR, "dst_blend": FACTOR, "blend_op": BLEND_OP,
        "src_blend_alpha": FACTOR, "dst_blend_alpha": FACTOR, "blend_op_alpha": BLEND_OP,
        "stencil_comp": COMPARE,
        "stencil_pass": STENCIL_OP, "stencil_fail": STENCIL_OP, "stencil_zfail": STENCIL_OP,
        # schema version 3
        "alpha_test_comp": COMPARE,
        "light_mode": {"Always": 0, "ForwardBase": 1, "ForwardAdd": 2, "Vertex": 3, "VertexLM": 4, "VertexLMRGBM": 5,
                       "ShadowCaster": 6, "ShadowCollector": 7, "Meta": 8, "Deferred": 9, "PrepassBase": 10,
                       "PrepassFinal": 11, "MotionVectors": 12, "Other": 13},
        # the outline vertex program (issue 28), appended in version 3
        "outline_mode": {"Off": 0, "World": 1, "Screen": 2},
        "outline_formula": {"MToon0x": 0, "MToon10": 1},
    },
    "material": {
        "queue": {"Background": 0, "Geometry": 1, "AlphaTest": 2, "Transparent": 3, "Overlay": 4},
        "main_tex_filter": {"Bilinear": 0, "Point": 1, "Trilinear": 2},  # Trilinear appended in version 3
        "main_tex_wrap": {"Repeat": 0, "Clamp": 1},
        "outline_width_tex_filter": {"Bilinear": 0, "Point": 1, "Trilinear": 2},  # version 4
        "outline_width_tex_wrap": {"Repeat": 0, "Clamp": 1},
        "lighting": {"Lambert": 0, "Unlit": 1},
        "vertex_color": {"Off": 0, "Multiply": 1, "Particle": 2},
    },
    "scene": {
        "color_space": {"Gamma": 0, "Linear": 1},
        "sort_mode": {"Default": 0, "Perspective": 1, "Orthographic": 2, "CustomAxis": 3},
    },
    "light": {
        "render_mode": {"Auto": 0, "Important": 1, "NotImportant": 2},
    },
}
#: ColorMask bits since schema version 2 (Unity's ColorWriteMask); version 1 stored R=1, G=2, B=4, A=8.
COLOR_MASK = {"R": 8, "G": 4, "B": 2, "A": 1}
FIELDS = {"pass": blender.PASS_FIELDS, "material": blender.MATERIAL_FIELDS, "scene": blender.SCENE_FIELDS,
          "light": blender.LIGHT_FIELDS}


@pytest.fixture
def registered():
    was = hasattr(bpy.types.Material, "unity")
    if not was:
        addon.register()
    yield
    if not was:
        addon.unregister()


@pytest.fixture
def unregistered():
    was = hasattr(bpy.types.Material, "unity")
    if was:
        addon.unregister()
    yield
    if was:
        addon.register()


def raw(id_block) -> dict:
    """The stored ``unity`` group as a plain dict (what a .blend file holds)."""
    group = id_block.bl_system_properties_get()["unity"]
    return group.to_dict()


def test_every_enum_number_is_pinned():
    for group, fields in FIELDS.items():
        enums = {f.name: dict(f.items()) for f in fields if f.kind == "enum"}
        assert enums == ENUM_NUMBERS[group], group
    assert COLOR_MASK_BITS == COLOR_MASK
    assert [f.name for f in blender.PASS_FIELDS if f.kind == "flags"] == ["color_mask"]
    assert migration.SCHEMA_VERSION == 4 and migration.VERSION_KEY == "schema_version"


def test_registered_properties_store_the_pinned_numbers(registered):
    for group, rna in (("pass", properties.UnityPassSettings), ("material", properties.UnityMaterialSettings),
                       ("scene", properties.UnitySceneSettings), ("light", properties.UnityLightSettings)):
        props = rna.bl_rna.properties
        for name, numbers in ENUM_NUMBERS[group].items():
            assert {i.identifier: i.value for i in props[name].enum_items} == numbers, name
    assert {i.identifier: i.value for i in properties.UnityPassSettings.bl_rna.properties["color_mask"].enum_items} \
        == COLOR_MASK


def test_color_mask_bits_are_unitys_color_write_mask():
    assert color_mask_bits(frozenset("RGBA")) == 15 and color_mask_bits(frozenset("A")) == 1
    assert color_mask_bits(frozenset("RG")) == 12
    assert all(color_mask_bits(color_mask_from_bits(b)) == b for b in range(16))
    with pytest.raises(ValueError):
        color_mask_from_bits(16)


def test_migration_of_version_1_reverses_the_color_mask_bits():
    v1 = {"enabled": 1, "queue": 3, "passes": [{"color_mask": 1}, {"color_mask": 3}, {"cull": 2}, {"color_mask": 14}]}
    got = migration.migrate_material(v1)
    # v1 R=1 → R=8; R|G=3 → 12; G|B|A=14 → 7; absent stays absent.
    assert got == {"enabled": 1, "queue": 3, "schema_version": 4,
                   "passes": [{"color_mask": 8}, {"color_mask": 12}, {"cull": 2}, {"color_mask": 7}]}
    assert v1["passes"][0] == {"color_mask": 1}, "the input is not changed"
    assert migration.migrate_material(got) == got, "current values are left as they are"
    assert migration.migrate_material(None) == {"schema_version": 4}
    assert migration.migrate_scene({"color_space": 1}) == {"color_space": 1, "schema_version": 4}
    with pytest.raises(ValueError, match="schema version 5"):
        migration.migrate_material({"schema_version": 5})


def _write_everything(mat, scene):
    material = Material(queue=Queue.Transparent, queue_offset=-2, color=(0.25, 0.5, 0.75, 0.5), cutoff=0.25,
                        passes=(Pass(name="Mask", color_mask=frozenset("RA"), ztest=CompareFunction.Always,
                                     stencil=True, stencil_ref=9, stencil_comp=CompareFunction.Never,
                                     offset_factor=-1.5),
                                Pass(cull=Cull.Off, blend=True, src_blend=BlendFactor.DstColor)))
    blender.write_material(mat, material, enabled=True, main_tex_wrap="Clamp")
    blender.write_scene_settings(scene, color_space="Linear", hdr=True, clear_color=(0.1, 0.2, 0.3, 0.4),
                                 sort_mode="CustomAxis", sort_axis=(0.0, 1.0, 0.0))
    return material


def _stored_and_read(mat, scene) -> tuple:
    values = blender.material_values(mat)
    return raw(mat), raw(scene), values, blender.scene_settings(scene)


def test_writers_store_the_same_numbers_registered_or_not(registered):
    results = []
    for register in (True, False):
        if not register:
            addon.unregister()
        try:
            empty_scene()
            mat = bpy.data.materials.new("W")
            material = _write_everything(mat, bpy.context.scene)
            stored, stored_scene, values, scene_values = _stored_and_read(mat, bpy.context.scene)
            results.append((stored, stored_scene, values, scene_values))
            got = blender.material_from_blender(mat)
            assert got.passes == material.passes and (got.queue, got.queue_offset) == (Queue.Transparent, -2)
            assert got.color == pytest.approx(material.color) and got.main_tex_wrap is TextureWrap.Clamp
        finally:
            if not register:
                addon.register()
    (a_mat, a_scene, a_values, a_sv), (b_mat, b_scene, b_values, b_sv) = results
    assert a_values == b_values and a_sv == b_sv
    assert a_scene == b_scene == {"color_space": 1, "hdr": True, "clear_color": pytest.approx([0.1, 0.2, 0.3, 0.4]),
                                  "sort_mode": 3, "sort_axis": [0.0, 1.0, 0.0], "schema_version": 4}
    assert a_mat["schema_version"] == b_mat["schema_version"] == 4
    assert [p["color_mask"] for p in a_mat["passes"]] == [p["color_mask"] for p in b_mat["passes"]] == [9, 15]
    assert a_mat["passes"][0]["stencil_comp"] == b_mat["passes"][0]["stencil_comp"] == 0  # Never
    assert a_mat["queue"] == b_mat["queue"] == 3 and a_mat["main_tex_wrap"] == b_mat["main_tex_wrap"] == 1
    assert a_values["passes"][0]["color_mask"] == frozenset("RA") and a_values["queue_offset"] == -2


def test_a_bad_value_writes_nothing(registered):
    empty_scene()
    mat = bpy.data.materials.new("Bad")
    blender.write_material(mat, queue="Overlay", passes=[Pass(name="Keep")])
    before = raw(mat)
    for bad in (dict(queue="Nowhere"), dict(passes=[{"ztest": "Never"}]), dict(lighting="Phong", cutoff=0.1),
                dict(passes=[Pass(), {"stencil_ref": 256}]), dict(no_such_field=1)):
        with pytest.raises(ValueError):
            blender.write_material(mat, **bad)
        assert raw(mat) == before
    with pytest.raises(ValueError, match="ZTest"):
        blender.write_material(mat, passes=[{"ztest": CompareFunction.Never}])


def test_editing_a_property_records_the_current_version(registered):
    empty_scene()
    mat = bpy.data.materials.new("Edited")
    assert mat.unity.schema_version == 1  # nothing stored: as a 0.1 file
    item = mat.unity.passes.add()
    item.color_mask = {"R"}
    assert raw(mat)["schema_version"] == 4 and raw(mat)["passes"][0]["color_mask"] == 8
    bpy.context.scene.unity.hdr = True
    assert raw(bpy.context.scene)["schema_version"] == 4


def _save_v1_material(path, masks):
    """A file as version 0.1 wrote it: stored groups without a version, ColorMask R=1 ... A=8."""
    empty_scene()
    mat = bpy.data.materials.new("Old")
    mat.use_fake_user = True
    v1_bits = {"R": 1, "G": 2, "B": 4, "A": 8}
    mat.bl_system_properties_get(do_create=True)["unity"] = {
        "enabled": True, "queue": 3,
        "passes": [{"name": f"P{i}", "color_mask": sum(v1_bits[c] for c in m)} for i, m in enumerate(masks)]}
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)


MASKS = ["R", "RG", "GBA", "A", ""]


def test_a_v1_file_reads_the_same_unregistered(tmp_path, unregistered):
    path = tmp_path / "old.blend"
    _save_v1_material(path, MASKS)
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    mat = bpy.data.materials["Old"]
    assert [p["color_mask"] for p in blender.material_values(mat)["passes"]] == [frozenset(m) for m in MASKS]
    assert "schema_version" not in raw(mat), "reading does not write"
    assert blender.material_from_blender(mat).passes[2].color_mask == frozenset("GBA")


def test_a_v1_file_is_migrated_when_it_loads_registered(tmp_path, registered):
    path = tmp_path / "old.blend"
    addon.unregister()
    try:
        _save_v1_material(path, MASKS)
    finally:
        addon.register()
    assert migrate_on_load in bpy.app.handlers.load_post
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    mat = bpy.data.materials["Old"]
    assert raw(mat)["schema_version"] == 4
    assert [p["color_mask"] for p in raw(mat)["passes"]] == [8, 12, 7, 1, 0]
    assert [set(p.color_mask) for p in mat.unity.passes] == [set(m) for m in MASKS]
    assert [p["color_mask"] for p in blender.material_values(mat)["passes"]] == [frozenset(m) for m in MASKS]
    # A writer on a v1 group migrates it first: the passes it does not touch keep their meaning.
    addon.unregister()
    try:
        bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
        mat = bpy.data.materials["Old"]
        blender.write_material(mat, queue_offset=1)
        assert raw(mat)["schema_version"] == 4 and [p["color_mask"] for p in raw(mat)["passes"]] == [8, 12, 7, 1, 0]
    finally:
        addon.register()


def test_registering_migrates_loaded_files_and_unregistering_removes_the_handler(tmp_path, unregistered):
    path = tmp_path / "old.blend"
    _save_v1_material(path, ["R"])
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    assert migrate_on_load not in bpy.app.handlers.load_post
    addon.register()
    try:
        assert bpy.app.handlers.load_post.count(migrate_on_load) == 1
        addon.register()
        assert bpy.app.handlers.load_post.count(migrate_on_load) == 1
        assert set(bpy.data.materials["Old"].unity.passes[0].color_mask) == {"R"}
    finally:
        addon.unregister()
    addon.unregister()
    assert migrate_on_load not in bpy.app.handlers.load_post


def test_presets_and_copy_go_through_the_writers(registered):
    from addon.material_settings import ops as operators

    empty_scene()
    mat = bpy.data.materials.new("Preset")
    operators.apply_preset(mat, "Alpha Blend ZWrite")
    queue, passes = preset("Alpha Blend ZWrite")
    assert raw(mat)["schema_version"] == 4 and raw(mat)["passes"][0]["color_mask"] == 0
    assert blender.material_from_blender(mat).passes == passes and mat.unity.queue == queue.value
    item = mat.unity.passes.add()
    operators.copy_pass(mat.unity.passes[1], item)
    assert schema.read_pass(item) == passes[1]
