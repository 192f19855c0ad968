"""The add-on's VRM feature: File › Import › VRM/glTF with Unity Settings, and the Unity Material panel's
read-only line for a material whose state comes from the VRM Add-on for Blender's MToon settings."""

from __future__ import annotations

import bpy
import pytest

import addon
from blendlib import blender
from blendlib.blender import vrm_addon
from blendlib.formats.gltf.vrm_addon import AddonMToon
from tests.addon.recording import draw_panel
from tests.support.blender_fixtures import empty_scene
from tests.support.gltf_docs import triangles_document, write_glb


@pytest.fixture(autouse=True)
def registered():
    addon.register()
    yield
    addon.unregister()


def _menu_entries():
    from addon.vrm_import.ops import menu_entry

    return [f for f in bpy.types.TOPBAR_MT_file_import._dyn_ui_initialize() if f is menu_entry]


def test_registers_the_operator_and_one_menu_entry_twice_safely():
    addon.register()
    assert hasattr(bpy.ops.unity, "import_vrm")
    assert len(_menu_entries()) == 1
    addon.unregister()
    addon.unregister()
    assert not hasattr(bpy.types, "UNITY_OT_import_vrm") and _menu_entries() == []
    addon.register()
    assert len(_menu_entries()) == 1


def test_the_operator_imports_with_unity_settings_and_reports_a_bad_file(tmp_path):
    empty_scene()
    good = write_glb(tmp_path / "a.glb", triangles_document(
        [{"name": "Cut", "alphaMode": "MASK", "alphaCutoff": 0.3, "extensions": {"KHR_materials_unlit": {}}}]))
    assert bpy.ops.unity.import_vrm(filepath=str(good), add_camera=False, add_sun=False) == {"FINISHED"}
    mat = bpy.data.materials["Cut"]
    assert mat.unity.enabled and mat.unity.queue == "AlphaTest" and mat.unity.cutoff == pytest.approx(0.3)
    assert mat.unity.passes[0].alpha_test and mat.unity.passes[0].light_mode == "Always"
    before = len(bpy.data.objects), len(bpy.data.materials)
    bad = tmp_path / "bad.vrm"
    bad.write_bytes(good.read_bytes()[:40])
    with pytest.raises(RuntimeError, match="truncated"):  # the operator's ERROR report
        bpy.ops.unity.import_vrm(filepath=str(bad))
    assert (len(bpy.data.objects), len(bpy.data.materials)) == before


def test_panel_shows_the_state_derived_from_the_vrm_addon():
    scene = empty_scene()
    mat = bpy.data.materials.new("Hair")
    vrm_addon.write_addon_mtoon(mat, AddonMToon(name="Hair", alpha_mode="BLEND", render_queue_offset_number=-3,
                                                double_sided=True))
    from addon.material_settings.panel import UNITY_PT_material

    labels = draw_panel(UNITY_PT_material, material=mat, scene=scene)["labels"]
    # no armature: the add-on's default spec_version 0.0, i.e. its VRM 0.x export (mtoon0_render_queue 2000)
    assert ("VRM Add-on MToon: Transparent → queue 2000, Cull Off, ZWrite Off, Blend SrcAlpha OneMinusSrcAlpha, "
            "clip alpha < 0.000976562, outline none (VRM 0.x export)") in labels
    assert not any(text.startswith("Off: renders opaque") for text in labels)
    blender.write_material(mat, enabled=True)  # Unity settings on: they win, no VRM line
    labels = draw_panel(UNITY_PT_material, material=mat, scene=scene)["labels"]
    assert not any(text.startswith("VRM Add-on MToon") for text in labels)
