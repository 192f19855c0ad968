"""The bpy bridge: scene extraction (camera, meshes, lights, materials, textures) and rendering."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

from blendlib import blender, render, write_image
from blendlib.blender import extract
from blendlib.core import colorspace
from blendlib.core.scene import SceneError
from blendlib.core.vocabulary import Queue
from tests.support.blender_fixtures import (
    add_cube,
    add_mesh,
    add_plane,
    coverage,
    empty_scene,
    principled_material,
    snapshot,
)


@pytest.fixture(autouse=True)
def _unregistered():
    """These tests read the Unity settings without the add-on (stored ID properties)."""
    import addon

    addon.unregister()
    yield


def project(camera, point) -> np.ndarray:
    p = np.array([*point, 1.0])
    clip = camera.projection @ (camera.view_matrix @ p)
    return clip[:3] / clip[3]


@pytest.mark.parametrize("setup", ["persp", "aspect", "ortho", "shift"])
def test_camera_matches_world_to_camera_view(setup):
    scene = empty_scene(100, 76, percentage=50)
    cam = scene.camera
    cam.location = (1.5, -7.0, 2.0)
    cam.rotation_euler = (math.radians(80), math.radians(5), math.radians(10))
    if setup == "aspect":
        scene.render.pixel_aspect_x = 2.0
        scene.render.pixel_aspect_y = 1.0
    elif setup == "ortho":
        cam.data.type = "ORTHO"
        cam.data.ortho_scale = 9.0
    elif setup == "shift":
        cam.data.shift_x = 0.2
        cam.data.shift_y = -0.1
        cam.data.sensor_fit = "VERTICAL"
    draw = blender.build_draw_scene(scene)
    assert (draw.camera.width, draw.camera.height) == (50, 38)
    assert draw.camera.orthographic == (setup == "ortho")
    np.testing.assert_allclose(draw.camera.position, cam.matrix_world.translation, atol=1e-6)
    bpy.context.view_layer.update()
    for point in [(0, 0, 0), (1, 2, -1), (-2.5, 3, 1.5), (0.3, -1, 2.2)]:
        ndc = project(draw.camera, point)
        ref = world_to_camera_view(scene, cam, Vector(point))
        np.testing.assert_allclose(ndc[:2] * 0.5 + 0.5, ref[:2], atol=1e-6)
        assert -1 < ndc[2] < 1


def test_no_camera_is_a_scene_error():
    scene = empty_scene()
    scene.camera = None
    with pytest.raises(SceneError, match="no camera"):
        blender.build_draw_scene(scene)


def test_mesh_arrays_slots_and_loop_triangle_order():
    empty_scene()
    red, blue = bpy.data.materials.new("Red"), bpy.data.materials.new("Blue")
    obj = add_cube("Cube", material=red)
    obj.data.materials.append(blue)
    for i, poly in enumerate(obj.data.polygons):
        poly.material_index = 1 if i in (1, 4) else 0
    uv = obj.data.uv_layers.new(name="UV")
    for i, loop_uv in enumerate(uv.data):
        loop_uv.uv = (i * 0.01, 1 - i * 0.02)
    obj.rotation_euler = (0.3, 0.2, 0.1)
    draw = blender.build_draw_scene()
    rs = {r.slot: r for r in draw.renderers}
    assert sorted(rs) == [0, 1] and all(r.name == "Cube" for r in rs.values())
    assert rs[0].material.name == "Red" and rs[1].material.name == "Blue"
    mesh = obj.data
    mesh.calc_loop_triangles()
    tris = [lt for lt in mesh.loop_triangles]
    for slot in (0, 1):
        expected = [lt for lt in tris if mesh.polygons[lt.polygon_index].material_index == slot]
        r = rs[slot]
        assert r.mesh.triangles.tolist() == [list(lt.vertices) for lt in expected]
        np.testing.assert_allclose(r.mesh.uvs, [[uv.data[i].uv[:] for i in lt.loops] for lt in expected], atol=1e-7)
        np.testing.assert_allclose(r.mesh.normals,
                                   [[mesh.corner_normals[i].vector[:] for i in lt.loops] for lt in expected],
                                   atol=1e-7)
        np.testing.assert_allclose(r.matrix_world, np.array(obj.matrix_world), atol=1e-7)
    assert len(rs[0].mesh.triangles) == 8 and len(rs[1].mesh.triangles) == 4
    corners = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
    center = [(min(c[i] for c in corners) + max(c[i] for c in corners)) / 2 for i in range(3)]
    np.testing.assert_allclose(rs[0].bounds_center, center, atol=1e-6)


def test_empty_slot_uses_default_material_with_warning():
    empty_scene()
    obj = add_plane("Plane")
    obj.data.materials.append(None)
    draw = blender.build_draw_scene()
    assert [r.material.name for r in draw.renderers] == ["Default"]
    assert any("empty material slot" in w for w in draw.warnings)


def test_render_visibility_rules():
    scene = empty_scene()
    add_plane("Shown")
    add_plane("HiddenRender").hide_render = True
    add_plane("EyeHidden").hide_set(True)  # viewport-only: still renders
    coll = bpy.data.collections.new("Excluded")
    scene.collection.children.link(coll)
    add_mesh("InExcluded", [(0, 0, 0), (1, 0, 0), (0, 0, 1)], [(0, 1, 2)], collection=coll)
    bpy.context.view_layer.layer_collection.children["Excluded"].exclude = True
    coll2 = bpy.data.collections.new("NoRender")
    scene.collection.children.link(coll2)
    coll2.hide_render = True
    add_mesh("InNoRender", [(0, 0, 0), (1, 0, 0), (0, 0, 1)], [(0, 1, 2)], collection=coll2)
    names = sorted(r.name for r in blender.build_draw_scene().renderers)
    assert names == ["EyeHidden", "Shown"]


def test_main_light_is_strongest_sun_and_points_along_local_z():
    scene = empty_scene()
    for name, energy, color, rot in [("SunA", 2.0, (1, 1, 1), (0, 0, 0)), ("SunB", 4.0, (0.5, 1, 0.25), (0.5, 0, 0)),
                                     ("SunC", 3.0, (1, 1, 1), (0, 0, 0)), ("Point", 100.0, (1, 1, 1), (0, 0, 0))]:
        data = bpy.data.lights.new(name, "POINT" if name == "Point" else "SUN")
        data.energy = energy
        data.color = color
        obj = bpy.data.objects.new(name, data)
        obj.rotation_euler = rot
        scene.collection.objects.link(obj)
    bpy.data.objects["SunC"].hide_render = True
    draw = blender.build_draw_scene()
    # SunB: 4 * 1 = 4 beats SunA (2) ; SunC (3) is hidden; Point is not a Sun.
    assert draw.light.name == "SunB" and draw.light.energy == 4.0
    np.testing.assert_allclose(draw.light.color, (0.5, 1, 0.25))
    np.testing.assert_allclose(draw.light.direction, (0, -math.sin(0.5), math.cos(0.5)), atol=1e-6)
    bpy.data.objects["SunA"].data.energy = 4.0  # tie 4 == 4: the first name wins
    assert blender.build_draw_scene().light.name == "SunA"


def test_ambient_from_world_background_and_no_world():
    scene = empty_scene()
    assert blender.build_draw_scene().ambient == (0.0, 0.0, 0.0)  # no world: black
    world = bpy.data.worlds.new("World")
    scene.world = world
    tree = world.node_tree
    if tree is None:
        world.use_nodes = True
        tree = world.node_tree
    bg = next(n for n in tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Color"].default_value = (0.1, 0.2, 0.4, 1.0)
    bg.inputs["Strength"].default_value = 2.0
    draw = blender.build_draw_scene()
    np.testing.assert_allclose(draw.ambient, (0.2, 0.4, 0.8), atol=1e-6)
    assert draw.ambient_is_linear is True


def test_disabled_material_uses_principled_inputs_encoded():
    empty_scene()
    mat, bsdf = principled_material("P", (0.5, 0.2, 0.0, 1.0), 0.25)
    add_plane("Plane", material=mat)
    m = blender.build_draw_scene().renderers[0].material
    np.testing.assert_allclose(m.color, (colorspace.encode(0.5), colorspace.encode(0.2), 0.0, 0.25), atol=1e-6)
    assert m.queue is Queue.Geometry and len(m.draw_passes) == 1 and m.main_tex is None
    img = bpy.data.images.new("Tex", 2, 2)
    img.pixels.foreach_set(np.linspace(0, 1, 16, dtype=np.float32))
    node = mat.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = img
    mat.node_tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    m = blender.build_draw_scene().renderers[0].material
    assert m.color[:3] == (1.0, 1.0, 1.0) and m.main_tex.encoding == "sRGB"
    np.testing.assert_allclose(m.main_tex.pixels.ravel(), np.linspace(0, 1, 16), atol=1 / 255)


def test_texture_encodings_and_missing_file(tmp_path):
    empty_scene()
    ex = extract._Extractor(warnings := [])
    byte = bpy.data.images.new("Byte", 3, 2)
    px = np.random.default_rng(0).random(24).astype(np.float32)
    byte.pixels.foreach_set(px)
    t = ex.texture(byte)
    assert t.encoding == "sRGB" and t.pixels.shape == (2, 3, 4)
    np.testing.assert_allclose(t.pixels.ravel(), np.round(px * 255) / 255, atol=1e-6)  # row 0 = bottom
    flt = bpy.data.images.new("Float", 2, 2, float_buffer=True)
    flt.pixels.foreach_set(np.full(16, 2.5, np.float32))
    t = ex.texture(flt)
    assert t.encoding == "Linear" and float(t.pixels[0, 0, 0]) == 2.5
    data = bpy.data.images.new("Data", 2, 2)
    data.colorspace_settings.name = "Non-Color"
    assert ex.texture(data).encoding == "Data"
    missing = bpy.data.images.new("Missing", 4, 4)
    missing.source = "FILE"
    missing.filepath = str(tmp_path / "does_not_exist.png")
    t = ex.texture(missing)
    assert t.missing and t.pixels.shape == (1, 1, 4) and t.pixels[0, 0].tolist() == [1, 0, 1, 1]
    assert any("Missing" in w and "magenta" in w for w in warnings)


def test_negative_scale_keeps_the_front_side():
    empty_scene(48, 48)
    import addon
    from tests.support.blender_fixtures import unlit_material

    addon.register()
    try:
        mat = unlit_material("Front", (1, 0, 0, 1))
        plane = add_plane("Plane", 3.0, material=mat)
        base = render()
        plane.scale = (-1.0, 1.0, 1.0)
        mirrored = render()
        assert coverage(base) > 200
        assert coverage(mirrored) == coverage(base)
        mat.unity.passes.add().cull = "Front"
        assert coverage(render()) == 0  # the front is still the side the normal points to
    finally:
        addon.unregister()


def test_modifiers_and_text_render():
    empty_scene(64, 48)
    plane = add_plane("Plane", 1.0, location=(-2.5, 0, 0))
    one = render()
    mod = plane.modifiers.new("Array", "ARRAY")
    mod.count = 3
    mod.relative_offset_displace = (1.5, 0, 0)
    draw = blender.build_draw_scene()
    assert draw.renderers[0].mesh.triangle_count == 6
    three = render()
    assert coverage(three) > 2.5 * coverage(one) > 0
    bpy.data.objects.remove(plane)
    curve = bpy.data.curves.new("Text", "FONT")
    curve.body = "Hi"
    text = bpy.data.objects.new("Text", curve)
    text.rotation_euler = (math.pi / 2, 0, 0)
    text.location = (-1.0, 0, -0.5)
    bpy.context.scene.collection.objects.link(text)
    draw = blender.build_draw_scene()
    assert [r.name for r in draw.renderers] == ["Text"] and draw.renderers[0].mesh.triangle_count > 10
    assert coverage(render()) > 20


def test_render_leaves_scene_data_unchanged():
    scene = empty_scene()
    plane = add_plane("Plane", material=bpy.data.materials.new("M"))
    plane.modifiers.new("Sub", "SUBSURF")
    curve = bpy.data.curves.new("Text", "FONT")
    text = bpy.data.objects.new("Text", curve)
    scene.collection.objects.link(text)
    bpy.context.view_layer.update()  # Blender's own evaluation syncs matrix_world first
    before = snapshot()
    frame = render()
    write_image(frame, "Unity Render")
    after = snapshot()
    after.pop(("image", "Unity Render"))
    after["counts"] = before["counts"]  # the output image is the one allowed addition
    assert after == before
    assert len(bpy.data.images) == 1


def test_write_image_orientation_and_linear_values():
    empty_scene(8, 6)
    frame = render()
    frame.color[0, 0] = (1.0, 0.5, 0.0, 0.25)  # top-left pixel
    img = write_image(frame, "Out")
    assert tuple(img.size) == (8, 6) and img.is_float
    px = np.empty(8 * 6 * 4, np.float32)
    img.pixels.foreach_get(px)
    top_left = px.reshape(6, 8, 4)[5, 0]  # Blender's row 0 is the bottom
    # Stored (encoded, Gamma mode) 0.5 becomes linear 0.214041; alpha is kept.
    np.testing.assert_allclose(top_left, (1.0, 0.21404114, 0.0, 0.25), atol=1e-6)


def test_one_million_triangles_extract_with_the_fast_dtypes():
    """Extraction speed is measured by scripts/benchmark.py; here: a 1M-triangle mesh comes out
    whole, in the dtypes that keep ``foreach_get`` on its fast path."""
    empty_scene()
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=708, y_subdivisions=708, size=2)
    mesh = blender.build_draw_scene().renderers[0].mesh
    assert mesh.triangle_count == 2 * 708 * 708
    assert mesh.positions.dtype == np.float32 and mesh.positions.shape == (709 * 709, 3)
    assert mesh.normals.dtype == np.float32 and mesh.normals.shape == (2 * 708 * 708, 3, 3)
    np.testing.assert_allclose(mesh.normals[..., 2], 1.0, atol=1e-6)
    assert np.abs(mesh.positions[:, :2]).max() == 1.0


def test_render_size_rounds_down_like_blender():
    scene = empty_scene(101, 77, percentage=50)
    assert blender.render_size(scene) == (50, 38)


def test_geometry_nodes_instances_warn_once_per_cause():
    """An object whose geometry nodes turn everything into instances of a mesh with an empty
    material slot: no "empty mesh" for the instancer, one empty-slot warning for all instances."""
    empty_scene()
    tree = add_cube("Tree")
    tree.data.materials.append(None)  # one empty slot
    tree.hide_render = True  # only its instances render
    points = add_plane("Points", size=2.0)
    group = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    group.interface.new_socket(name="Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    group.interface.new_socket(name="Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes = group.nodes
    gin, gout = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    info, scatter = nodes.new("GeometryNodeObjectInfo"), nodes.new("GeometryNodeInstanceOnPoints")
    info.inputs["Object"].default_value = tree
    info.inputs["As Instance"].default_value = True
    group.links.new(gin.outputs["Geometry"], scatter.inputs["Points"])
    group.links.new(info.outputs["Geometry"], scatter.inputs["Instance"])
    group.links.new(scatter.outputs["Instances"], gout.inputs["Geometry"])
    points.modifiers.new("Scatter", "NODES").node_group = group
    frame = render()
    empty_slot = [w for w in frame.warnings if "empty material slot" in w]
    assert empty_slot == ["object 'Points/Tree' slot 0 (4 instances): empty material slot, using the default material"]
    assert not any("empty mesh" in w for w in frame.warnings), frame.warnings
    draw = blender.build_draw_scene()
    assert len(draw.renderers) == 4 and all(r.mesh.triangle_count == 12 for r in draw.renderers)
