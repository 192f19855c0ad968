"""Sort advice in VRM terms (issue 28 item 4, SPEC §11.6): on a VRM Add-on material (Unity settings
off) the advice proposes the add-on's own settings within MToon's clamps, Apply Advice writes them
into the add-on's settings (so that its export carries them), and the measured sort error falls as
the advice predicted.

Queues from the shaders' and validators' text: VRM 1.0 Transparent draws at ``3000 +
clamp(renderQueueOffsetNumber, -9, 0)`` (MToonValidator); VRM 0.x at ``renderQueue`` =
``mtoon0_render_queue`` as stored (the legacy loader), kept within MToon 0.x's Transparent range
2951–3000.
"""

from __future__ import annotations

import json
import math

import bpy
import pytest
from mathutils import Matrix

import addon
import blendlib
from blendlib.blender import vrm_addon
from blendlib.formats.gltf.vrm_addon import AddonMToon
from tests.support.blender_fixtures import add_plane, empty_scene


@pytest.fixture(autouse=True)
def registered():
    addon.register()
    yield
    addon.unregister()


def vrm_scene(spec: str, near: dict, far: dict):
    """Two semi-transparent VRM Add-on MToon quads of one VRM armature (``spec``): Near in front of
    Far, overlapping; ``near``/``far``: more AddonMToon settings."""
    scene = empty_scene(40, 30)
    scene.render.engine = "UNITY_PASSES"
    arm = bpy.data.armatures.new("Armature")
    vrm_addon.write_armature_spec_version(arm, spec)
    armature = bpy.data.objects.new("Armature", arm)
    scene.collection.objects.link(armature)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))  # MToon is lit (Lambert here)
    sun.rotation_euler = (1.2, 0.0, 0.3)
    sun.data.energy = 1.0  # colours below 1: the two blend orders differ
    scene.collection.objects.link(sun)
    for name, color, location, settings in (("Near", (0.9, 0.1, 0.1, 0.5), (-0.5, -1.0, 0.0), near),
                                            ("Far", (0.1, 0.2, 0.9, 0.5), (0.5, 1.0, 0.3), far)):
        mat = bpy.data.materials.new(name)
        vrm_addon.write_addon_mtoon(mat, AddonMToon(name=name, alpha_mode="BLEND", base_color_factor=color,
                                                    **settings))
        add_plane(name, 2.0, location, mat).parent = armature
    return scene


def _stored(mat, *path):
    group = mat.bl_system_properties_get()["vrm_addon_extension"]["mtoon1"]
    for key in path:
        group = group[key]
    return group


@pytest.mark.parametrize("spec,near,far,change,queue", [
    # VRM 1.0: Near at offset -1 → 2999, drawn before Far (3000) although in front. Near cannot go above
    # 3000 (clamp(offset, -9, 0)); Far can go before it: offset -2 → 3000 - 2 = 2998.
    ("1.0", {"render_queue_offset_number": -1}, {}, {"render_queue_offset_number": -2}, 2998),
    # VRM 0.x: renderQueue as stored: Near 2990, Far 3000 → Far 2989 (within 2951..3000).
    ("0.x", {"mtoon0_render_queue": 2990}, {"mtoon0_render_queue": 3000}, {"mtoon0_render_queue": 2989}, 2989),
])
def test_apply_advice_writes_the_vrm_setting_and_the_error_falls_as_measured(spec, near, far, change, queue):
    scene = vrm_scene(spec, near, far)
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.unity.sort_analyze() == {"FINISHED"}
    results = bpy.context.window_manager.unity_sort_results
    assert [(r.front, r.behind) for r in results.items] == [("Near", "Far")]
    advice = json.loads(results.items[0].change)
    assert advice == {"material": "Far", "vrm": change, "vrm_spec": spec}
    assert "VRM material 'Far'" in results.items[0].text and "0 inverted pixels" in results.items[0].text
    before = blendlib.analyze(scene)
    (item,) = before.advice
    assert item["inversions_before"] > 0 and item["inversions_after"] == 0
    assert item["differing_after"] < item["differing_before"] == before.differing
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.unity.sort_apply_advice() == {"FINISHED"}
    far_mat = bpy.data.materials["Far"]
    (key, value), = change.items()
    stored = _stored(far_mat, "extensions", "vrmc_materials_mtoon", key) if spec == "1.0" else _stored(far_mat, key)
    assert stored == value  # the add-on's own setting, which its exporter writes
    if spec == "1.0":  # the socket mirror the add-on 2.20.62 reads
        node = far_mat.node_tree.nodes[vrm_addon.OUTPUT_NODE]
        assert node.inputs["Render Queue Offset Number"].default_value == value
    assert not blendlib.blender.material_values(far_mat)["enabled"]  # the Unity settings stay off
    assert vrm_addon.derived_material(far_mat)[0].material.render_queue == queue
    after = blendlib.analyze(scene)
    assert after.inversions == [] and after.differing == item["differing_after"]


def test_a_self_overlap_is_advised_transparent_with_z_write():
    scene = vrm_scene("1.0", {}, {})
    # one object: a second, farther quad added to Near's mesh, so its triangles overlap in mesh order
    bpy.data.objects.remove(bpy.data.objects["Far"])
    near = bpy.data.objects["Near"]
    mesh = near.data
    import bmesh  # importable once bpy is

    bm = bmesh.new()
    bm.from_mesh(mesh)
    # the far quad, appended: drawn after the near one within the one draw call
    bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=1.0,
                          matrix=Matrix.Translation((0.5, 1.5, 0.3)) @ Matrix.Rotation(math.pi / 2, 4, "X"))
    bm.to_mesh(mesh)
    bm.free()
    result = blendlib.analyze(scene)
    (item,) = result.advice
    assert (item["front"], item["behind"]) == ("Near", "Near")
    assert item["change"] == {"material": "Near", "vrm": {"transparent_with_z_write": True}, "vrm_spec": "1.0"}
    assert item["inversions_after"] == 0
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.unity.sort_analyze() == {"FINISHED"}
        assert bpy.ops.unity.sort_apply_advice() == {"FINISHED"}
    # Transparent With Z-Write: 2501 + clamp(0, 0, 9), ZWrite On
    got = vrm_addon.derived_material(bpy.data.materials["Near"])[0].material
    assert got.render_queue == 2501 and got.passes[0].zwrite
    assert blendlib.analyze(scene).differing == item["differing_after"]


def test_apply_refuses_what_is_not_the_addons():
    scene = vrm_scene("1.0", {}, {})
    mat = bpy.data.materials["Near"]
    with pytest.raises(ValueError, match="no VRM setting 'queue_offset'"):
        vrm_addon.apply_settings(mat, {"queue_offset": 1})
    blendlib.blender.write_material(mat, enabled=True)
    with pytest.raises(ValueError, match="its Unity settings are on"):
        vrm_addon.apply_settings(mat, {"render_queue_offset_number": -1})
    with pytest.raises(ValueError, match="is not a VRM Add-on MToon material"):
        vrm_addon.apply_settings(bpy.data.materials.new("Plain"), {"render_queue_offset_number": -1})
    # with Unity settings on, the advice is a Unity queue offset (the settings that decide)
    assert "Near" not in vrm_addon.advice_settings() and "Far" in vrm_addon.advice_settings()
    assert scene is not None
