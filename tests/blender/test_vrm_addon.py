"""Materials of the VRM Add-on for Blender, read without that add-on (SPEC §11.6, research-vrm §6).

``shared/corpus/vrm-addon/`` holds two ``.blend`` files saved by the add-on 2.20.61 and the ``.vrm``
files it exported from them; each ``.blend`` (Unity settings off, the add-on not installed) must give
every material the Unity state its own export gives (spec_version absent = VRM 0.x, 1 = VRM 1.0).
"""

from __future__ import annotations

import dataclasses

import bpy
import pytest

from blendlib import blender
from blendlib.blender import vrm_addon
from blendlib.core.vocabulary import Cull, OutlineMode
from blendlib.formats.gltf import SHADING_APPROXIMATION, import_file
from blendlib.formats.gltf.vrm_addon import AddonMToon
from tests.support.blender_fixtures import add_plane, empty_scene
from tests.support.gltf_docs import corpus_dir

CORPUS = corpus_dir()
needs_corpus = pytest.mark.skipif(CORPUS is None, reason="shared/corpus not found beside the repository")
MTOON_MATERIALS = ("Opaque", "Cutout", "Transparent", "TransparentWithZWrite")


@needs_corpus
@pytest.mark.parametrize("spec,version", [("vrm0", "0.x"), ("vrm1", "1.0")])
def test_each_blend_equals_its_own_export(spec, version):
    assert not hasattr(bpy.types.Material, "vrm_addon_extension")  # the add-on is not installed
    exported = {m.material.name: m for m in import_file(CORPUS / "vrm-addon" / f"mtoon1_2_20_61_{spec}.vrm").materials}
    blender.open_blend(CORPUS / "vrm-addon" / f"mtoon1_2_20_61_{spec}.blend")
    for name in MTOON_MATERIALS:
        mat = bpy.data.materials[name]
        assert not blender.material_values(mat)["enabled"]
        assert vrm_addon.spec_version(mat) == version
        imported, image, width, mtoon = vrm_addon.derived_material(mat)
        assert imported.material == exported[name].material, name
        # the outline-width texture (outline_width_multiply_texture): the image, read as the export's
        assert (width.name if width else None) == ("20.png" if name == "Transparent" else None)
        assert (imported.outline_width_tex is None) == (exported[name].outline_width_tex is None)
        assert imported.outline_width_encoding == exported[name].outline_width_encoding
        # the outline (mode, width, max distance, colour): the same program on the same pass, the same record
        outline = [p for p in imported.material.passes if p.outline_mode is not OutlineMode.Off]
        expected = {"Opaque": [OutlineMode.World], "Cutout": []}.get(name, [OutlineMode.Screen])
        assert [p.outline_mode for p in outline] == expected, name
        assert imported.extra["outline"] == exported[name].extra["outline"], name
        assert (image.name if image else None) == {"Opaque": "1.png", "Transparent": "16.png",
                                                   "TransparentWithZWrite": "3.png"}.get(name)
        assert mtoon.addon_version == (2, 20, 61)
    assert vrm_addon.addon_mtoon(bpy.data.materials["Dots Stroke"]) is None  # grease pencil: not MToon


@needs_corpus
def test_the_two_exports_of_the_same_materials_differ_as_research_found():
    """research-vrm §6.5: the 0.x and 1.0 exports of one material are not the same Unity state."""
    blender.open_blend(CORPUS / "vrm-addon" / "mtoon1_2_20_61_vrm0.blend")
    mtoon = {name: vrm_addon.addon_mtoon(bpy.data.materials[name]) for name in MTOON_MATERIALS}
    from blendlib.formats.gltf.vrm_addon import addon_material

    v0 = {n: addon_material(m, "0.x").material for n, m in mtoon.items()}
    v1 = {n: addon_material(m, "1.0").material for n, m in mtoon.items()}
    # Opaque: mtoon0_front_cull_mode → Cull Front in 0.x; doubleSided → Off in 1.0.
    assert (v0["Opaque"].passes[0].cull, v1["Opaque"].passes[0].cull) == (Cull.Front, Cull.Off)
    # Transparent: mtoon0_render_queue 2952 vs 3000 + clamp(8, -9, 0); TZW 2550 vs 2501 + 9.
    assert (v0["Transparent"].render_queue, v1["Transparent"].render_queue) == (2952, 3000)
    assert (v0["TransparentWithZWrite"].render_queue, v1["TransparentWithZWrite"].render_queue) == (2550, 2510)
    # Cutout: AlphaToMask 0 (not written by the 0.x exporter) vs On (MToon validator).
    assert (v0["Cutout"].passes[0].alpha_to_mask, v1["Cutout"].passes[0].alpha_to_mask) == (False, True)


@needs_corpus
def test_the_blend_renders_with_the_derived_state():
    blender.open_blend(CORPUS / "vrm-addon" / "mtoon1_2_20_61_vrm0.blend")
    scene = bpy.context.scene
    scene.render.resolution_percentage = 10
    draw = blender.build_draw_scene(scene)
    by_name = {r.material.name: r.material for r in draw.renderers}
    derived = vrm_addon.derived_material(bpy.data.materials["Transparent"])[0].material
    got = by_name["Transparent"]
    assert got.render_queue == 2952 and got.passes == derived.passes
    assert got.main_tex is not None and got.main_tex.name == "16.png"
    assert draw.warnings.count(SHADING_APPROXIMATION) == 1


@needs_corpus
def test_node_mirrors_of_a_2_20_61_file_read_like_its_id_properties():
    """From 2.20.62 the sockets and the texture's nodes hold the values: in the 2.20.61 files they mirror the
    ID properties (except ``Outline Width Mode``, which 2.20.61 leaves at 0), so reading them with the
    newer rule gives the same settings."""
    blender.open_blend(CORPUS / "vrm-addon" / "mtoon1_2_20_61_vrm1.blend")
    for name in MTOON_MATERIALS:
        mat = bpy.data.materials[name]
        old = vrm_addon.addon_mtoon(mat)
        mat["vrm_addon_extension"]["mtoon1"]["addon_version"] = [2, 20, 62]
        mat.bl_system_properties_get()["vrm_addon_extension"]["mtoon1"]["addon_version"] = [2, 20, 62]
        new = vrm_addon.addon_mtoon(mat)
        assert new.sources["mtoon"] == "node group sockets (add-on 2.20.62 and later)"
        assert dataclasses.replace(new, outline_width_mode=old.outline_width_mode, addon_version=old.addon_version,
                                   sources=old.sources) == old, name


def _addon_material(**settings):
    empty_scene()
    mat = bpy.data.materials.new("M")
    vrm_addon.write_addon_mtoon(mat, AddonMToon(name="M", **settings))
    return mat


def test_written_settings_read_back_and_render():
    mat = _addon_material(alpha_mode="BLEND", transparent_with_z_write=True, render_queue_offset_number=4,
                          double_sided=True, base_color_factor=(0.5, 0.25, 1.0, 0.6))
    arm = bpy.data.armatures.new("Armature")
    vrm_addon.write_armature_spec_version(arm, "1.0")
    armature = bpy.data.objects.new("Armature", arm)
    bpy.context.scene.collection.objects.link(armature)
    plane = add_plane("Plane", material=mat)
    plane.parent = armature
    mtoon = vrm_addon.addon_mtoon(mat)
    assert (mtoon.alpha_mode, mtoon.transparent_with_z_write, mtoon.render_queue_offset_number) == ("BLEND", True, 4)
    assert mtoon.base_color_factor == pytest.approx((0.5, 0.25, 1.0, 0.6))
    assert vrm_addon.spec_version(mat) == "1.0"
    draw = blender.build_draw_scene(bpy.context.scene)
    (renderer,) = draw.renderers
    # VRM 1.0 TransparentWithZWrite: 2501 + clamp(4, 0, 9); double sided: Cull Off.
    assert renderer.material.render_queue == 2505 and renderer.material.passes[0].cull is Cull.Off
    vrm_addon.write_armature_spec_version(arm, "0.x")
    assert vrm_addon.spec_version(mat) == "0.x"
    # VRM 0.x: mtoon0_render_queue (default 2000) as stored, Cull Off from not use_backface_culling.
    assert vrm_addon.derived_material(mat)[0].material.render_queue == 2000
    assert vrm_addon.summary(mat).startswith("VRM Add-on MToon: Transparent With Z-Write → queue 2000, Cull Off, "
                                             "ZWrite On, Blend SrcAlpha OneMinusSrcAlpha")


def test_version_rules_for_the_alpha_mode():
    mat = _addon_material(alpha_mode="MASK", alpha_cutoff=0.3)
    assert vrm_addon.addon_mtoon(mat).alpha_mode == "MASK"  # 2.20.61: the Alpha Mode socket
    group = mat.bl_system_properties_get()["vrm_addon_extension"]["mtoon1"]
    group["addon_version"] = [2, 20, 50]
    # Before 2.20.55: material.blend_method, which Blender 4.2+ reads as HASHED or BLEND for every
    # material (research-vrm §6.1): the add-on's own migration then makes it BLEND too.
    old = vrm_addon.addon_mtoon(mat)
    assert mat.blend_method in ("HASHED", "BLEND") and old.alpha_mode == "BLEND"
    assert old.alpha_cutoff == pytest.approx(mat.alpha_threshold)


def test_materials_that_are_not_the_addons():
    mat = _addon_material()
    mat.bl_system_properties_get()["vrm_addon_extension"]["mtoon1"]["enabled"] = 0
    assert vrm_addon.derived_material(mat) is None
    mat2 = _addon_material()
    mat2.node_tree.nodes.remove(mat2.node_tree.nodes[vrm_addon.OUTPUT_NODE])
    assert vrm_addon.addon_mtoon(mat2) is None  # no output group: the add-on does not treat it as MToon either
    plain = bpy.data.materials.new("Plain")
    assert vrm_addon.summary(plain) is None
    # With Unity settings on, those win: the VRM Add-on's state is not used.
    mat3 = _addon_material(alpha_mode="BLEND")
    blender.write_material(mat3, enabled=True)
    assert blender.material_from_blender(mat3).render_queue == 2000
