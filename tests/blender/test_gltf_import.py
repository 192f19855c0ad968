"""Importing .vrm/.glb/.gltf into Blender: Blender's glTF importer for the geometry, the Unity settings
of every material through the schema's writer, names and images kept, a camera framing the model."""

from __future__ import annotations

import dataclasses

import bpy
import numpy as np
import pytest
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

from blendlib import blender
from blendlib.blender import gltf_import, vrm_addon
from blendlib.core.vocabulary import Cull, Queue
from blendlib.formats.gltf import GltfError, import_file, read_document
from blendlib.formats.gltf.records import f32
from tests.support.blender_fixtures import add_plane, empty_scene
from tests.support.gltf_docs import corpus_dir, triangles_document, write_glb

CORPUS = corpus_dir()
needs_corpus = pytest.mark.skipif(CORPUS is None, reason="shared/corpus not found beside the repository")


def stored(material):
    """A Material as Blender stores it: float32 numbers, no texture pixels."""
    def rounded(value):
        if isinstance(value, float):
            return f32(value)
        if isinstance(value, tuple) and value and isinstance(value[0], float):
            return tuple(f32(v) for v in value)
        return value
    return dataclasses.replace(material, main_tex=None, **{
        f.name: rounded(getattr(material, f.name)) for f in dataclasses.fields(material)
        if f.name not in ("main_tex", "passes", "name")},
        passes=tuple(dataclasses.replace(p, offset_factor=f32(p.offset_factor), offset_units=f32(p.offset_units))
                     for p in material.passes))


#: The MToon materials of each file (VRM 0.x VRM/MToon, VRM 1.0 VRMC_materials_mtoon): they import as the
#: VRM Add-on's MToon settings; the others (glTF Standard, VRM/UnlitTransparentZWrite) as Unity settings.
MTOON = {"mtoon1_2_20_61_vrm0.vrm": {"Opaque", "Cutout", "Transparent", "TransparentWithZWrite"},
         "mtoon1_2_20_61_vrm1.vrm": {"Opaque", "Cutout", "Transparent", "TransparentWithZWrite"},
         "material.vrm": {"MToonUnversioned"}}


@needs_corpus
@pytest.mark.parametrize("file", ["mtoon1_2_20_61_vrm0.vrm", "mtoon1_2_20_61_vrm1.vrm", "material.vrm"])
def test_every_material_gets_the_state_unitys_importer_sets(file):
    path = CORPUS / "vrm-addon" / file
    expected = import_file(path)
    document = read_document(path)
    empty_scene()
    done = gltf_import.import_gltf(path)
    assert len(done.materials) == len(expected.materials)
    assert set(done.addon_materials) == MTOON[file] and not done.warnings
    for imported, mat in zip(expected.materials, done.materials, strict=True):
        assert mat.name == imported.material.name
        values = blender.material_values(mat)
        if mat.name in MTOON[file]:  # the add-on's settings, Unity settings off: the same state read back
            assert not values["enabled"] and values["main_tex"] is None
            derived, image, width, _ = vrm_addon.derived_material(mat)
            assert vrm_addon.spec_version(mat) == expected.vrm
            assert derived.material == imported.material, mat.name  # queue, passes, cull, blend, outline...
            assert (image is None) == (imported.main_tex is None) and (width is None) == (
                imported.outline_width_tex is None)
            if image is not None:
                assert image.name == document.image_name(document.texture_image(imported.main_tex))
            if width is not None:  # MToon's outline-width texture: an image no glTF material uses
                assert width.name == document.image_name(document.texture_image(imported.outline_width_tex))
                assert width.size[0] > 0 and width.has_data
                assert blender.material_from_blender(mat, with_texture=True).outline_width_tex.encoding == \
                    imported.outline_width_encoding
            continue
        assert values["enabled"]
        got = blender.material_from_blender(mat)
        assert got == dataclasses.replace(stored(imported.material), name=mat.name), mat.name
        image = values["main_tex"]
        if imported.main_tex is None:
            assert image is None
        else:  # the glTF image the texture names, with its name and pixels
            index = document.texture_image(imported.main_tex)
            assert image.name == document.image_name(index) and image.size[0] > 0 and image.has_data
        width = values["outline_width_tex"]  # MToon's outline-width texture: an image no glTF material uses
        if imported.outline_width_tex is None:
            assert width is None
        else:
            assert width.name == document.image_name(document.texture_image(imported.outline_width_tex))
            assert width.size[0] > 0 and width.has_data
            assert width.colorspace_settings.is_data == (imported.outline_width_encoding == "Data")
            assert blender.material_from_blender(mat, with_texture=True).outline_width_tex.encoding == \
                imported.outline_width_encoding


@needs_corpus
def test_names_that_exist_already_are_deduped_but_each_material_gets_its_own_settings():
    empty_scene()
    existing = bpy.data.materials.new("Transparent")  # what Blender's dedupe turns the import into Transparent.001
    existing_material = blender.material_from_blender(existing)
    done = gltf_import.import_gltf(CORPUS / "vrm-addon" / "mtoon1_2_20_61_vrm0.vrm")
    names = [m.name for m in done.materials]
    assert names == ["Opaque", "Cutout", "Transparent.001", "TransparentWithZWrite"]
    assert blender.material_from_blender(done.materials[2]).render_queue == 2952
    assert blender.material_from_blender(existing) == existing_material  # untouched: renders as before
    assert not blender.material_values(existing)["enabled"]


@needs_corpus
def test_a_camera_frames_the_model_and_a_sun_lights_it():
    scene = empty_scene(96, 128)
    bpy.data.objects.remove(scene.camera)
    done = gltf_import.import_gltf(CORPUS / "vrm-addon" / "mtoon1_2_20_61_vrm1.vrm")
    assert scene.camera is done.camera and done.sun is not None
    depsgraph = bpy.context.evaluated_depsgraph_get()
    meshes = [obj.evaluated_get(depsgraph) for obj in done.objects if obj.type == "MESH"]
    points = [world_to_camera_view(scene, scene.camera, obj.matrix_world @ Vector(corner))
              for obj in meshes for corner in obj.bound_box]
    xs, ys = [p.x for p in points], [p.y for p in points]
    assert 0 <= min(xs) and max(xs) <= 1 and 0 <= min(ys) and max(ys) <= 1  # all inside the frame
    assert max(max(xs) - min(xs), max(ys) - min(ys)) > 0.7  # and filling most of it
    # VRM 1.0 faces glTF +Z, Blender's −Y: the camera looks along +Y from in front.
    direction = scene.camera.matrix_world.to_3x3() @ Vector((0, 0, -1))
    assert direction.y > 0.99


def test_a_glb_made_by_blenders_own_exporter_imports_as_unigltf(tmp_path):
    """Plain glTF: Blender's exporter writes an opaque and a blended Principled material; UniGLTF makes them
    Standard (2000, One Zero) and Standard Fade (3000, SrcAlpha OneMinusSrcAlpha, ZWrite Off), Cull Back
    whatever doubleSided says."""
    import addon_utils

    empty_scene()
    solid = bpy.data.materials.new("Solid")
    glass = bpy.data.materials.new("Glass")
    bsdf = glass.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Alpha"].default_value = 0.4
    glass.surface_render_method = "BLENDED"
    glass.use_backface_culling = False  # exported as doubleSided: true
    add_plane("A", material=solid, location=(-1.5, 0, 0))
    add_plane("B", material=glass, location=(1.5, 0, 0))
    addon_utils.enable("io_scene_gltf2", default_set=False)
    path = tmp_path / "scene.glb"
    bpy.ops.export_scene.gltf(filepath=str(path), export_format="GLB", export_cameras=False, export_lights=False)
    materials = {m.material.name: m for m in import_file(path).materials}
    assert materials["Solid"].importer == "glTF Standard"
    assert materials["Solid"].material.render_queue == 2000
    fade = materials["Glass"].material
    assert fade.queue is Queue.Transparent and fade.queue_offset == 0
    forward = fade.passes[0]
    assert (forward.src_blend.value, forward.dst_blend.value, forward.zwrite, forward.cull) == (
        "SrcAlpha", "OneMinusSrcAlpha", False, Cull.Back)
    assert fade.color[3] == pytest.approx(0.4)
    assert any("doubleSided is ignored" in w for w in materials["Glass"].warnings)
    empty_scene()
    done = gltf_import.import_gltf(path)
    assert blender.material_from_blender(done.materials[1]).render_queue == 3000


def test_a_bad_file_changes_nothing(tmp_path):
    empty_scene()
    before = (len(bpy.data.objects), len(bpy.data.materials), len(bpy.data.images), len(bpy.data.meshes))
    doc = triangles_document([{"name": "M", "pbrMetallicRoughness": {"baseColorTexture": {"index": 3}}}], textures=1)
    with pytest.raises(GltfError, match="baseColorTexture.index 3 is out of range"):
        gltf_import.import_gltf(write_glb(tmp_path / "bad.vrm", doc))
    path = write_glb(tmp_path / "cut.vrm", triangles_document([{"name": "M"}]))
    path.write_bytes(path.read_bytes()[:-10])
    with pytest.raises(GltfError, match="truncated"):
        gltf_import.import_gltf(path)
    assert (len(bpy.data.objects), len(bpy.data.materials), len(bpy.data.images), len(bpy.data.meshes)) == before


def test_textures_become_main_tex_with_their_pixels(tmp_path):
    doc = triangles_document([{"name": "T", "alphaMode": "MASK", "alphaCutoff": 0.25,
                               "extensions": {"KHR_materials_unlit": {}},
                               "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
                             textures=1, samplers=[{"magFilter": 9728, "minFilter": 9728}])
    empty_scene()
    done = gltf_import.import_gltf(write_glb(tmp_path / "t.glb", doc))
    (mat,) = done.materials
    image = blender.material_values(mat)["main_tex"]
    assert image.name == "tex0.png" and image.size[:] == (2, 2)
    pixels = np.array(image.pixels[:], np.float32).reshape(2, 2, 4)
    # the PNG's top row (red, green@128) is Blender's row 1 (row 0 = bottom)
    assert np.allclose(pixels[1, 0], (1, 0, 0, 1)) and pixels[1, 1, 3] == pytest.approx(128 / 255)
    material = blender.material_from_blender(mat)
    assert (material.main_tex_filter.value, material.cutoff, material.lighting.value) == ("Point", 0.25, "Unlit")


def test_a_gltf_with_external_buffer_and_image_files(tmp_path):
    """The importer reads a renamed copy of the file from a temporary folder: relative URIs (with a
    space, percent-encoded) still find the files beside the original."""
    import base64
    import json

    doc = triangles_document([{"name": "Ext", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
                             textures=1)
    folder = tmp_path / "my model"
    folder.mkdir()
    (folder / "geo data.bin").write_bytes(doc.pop("__buffer__"))
    doc["buffers"][0]["uri"] = "geo%20data.bin"
    png = base64.b64decode(doc["images"][0]["uri"].split(",", 1)[1])
    (folder / "tex 0.png").write_bytes(png)
    doc["images"][0] = {"uri": "tex%200.png"}
    (folder / "model.gltf").write_text(json.dumps(doc))
    empty_scene()
    done = gltf_import.import_gltf(folder / "model.gltf")
    (mat,) = done.materials
    image = blender.material_values(mat)["main_tex"]
    assert image.name == "tex 0.png" and image.size[:] == (2, 2) and image.has_data
    assert len([o for o in done.objects if o.type == "MESH"]) == 1


def test_a_file_blenders_importer_rejects_is_one_line_and_leaves_nothing(tmp_path):
    doc = triangles_document([{"name": "A"}, {"name": "B"}])
    doc["accessors"][3]["bufferView"] = 99  # the second mesh's positions: no such buffer view
    empty_scene()
    before = {key: len(getattr(bpy.data, key)) for key in gltf_import._CREATED}
    with pytest.raises(GltfError, match=r"bad.glb: Blender's glTF importer failed: IndexError: list index") as info:
        gltf_import.import_gltf(write_glb(tmp_path / "bad.glb", doc))
    assert "\n" not in str(info.value)
    assert {key: len(getattr(bpy.data, key)) for key in gltf_import._CREATED} == before


def test_an_mtoon_material_the_vrm_addon_cannot_state_keeps_unity_settings(tmp_path):
    """VRM 0.x ``_OutlineCullMode`` 0 (Cull Off on the outline): the add-on's exporter always writes 1,
    so its settings cannot give this state: the material keeps Unity settings, with a warning; a plain
    VRM/MToon material of the same file gets the add-on's settings and the file's spec version."""
    entry = {"shader": "VRM/MToon", "floatProperties": {"_OutlineWidthMode": 1, "_OutlineCullMode": 0},
             "keywordMap": {"MTOON_OUTLINE_WIDTH_WORLD": True, "MTOON_OUTLINE_COLOR_FIXED": True}}
    doc = triangles_document([{"name": "Odd"}, {"name": "Plain"}])
    doc["extensions"] = {"VRM": {"materialProperties": [entry, {"shader": "VRM/MToon"}]}}
    path = write_glb(tmp_path / "odd.vrm", doc)
    empty_scene()
    done = gltf_import.import_gltf(path)
    odd, plain = done.materials
    assert blender.material_values(odd)["enabled"] and vrm_addon.derived_material(odd) is None
    assert done.addon_materials == ("Plain",) and len(done.warnings) == 1
    assert "'Odd'" in done.warnings[0] and "keeps Unity settings" in done.warnings[0]
    assert blender.material_from_blender(odd).passes[1].cull is Cull.Off
    assert not blender.material_values(plain)["enabled"] and vrm_addon.spec_version(plain) == "0.x"
    assert vrm_addon.derived_material(plain)[0].material == import_file(path).materials[1].material
