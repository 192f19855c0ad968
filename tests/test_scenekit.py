"""scripts/scenekit.py, the scene-building helpers of the example scenes and the benchmark: cameras
and Suns point where they are told, objects turn by degrees, materials store the Unity settings
given and show their _Color decoded to linear."""

from __future__ import annotations

import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blendlib import blender  # noqa: E402
from scripts import scenekit  # noqa: E402  (imports bpy)


def _evaluate() -> None:
    """Evaluate the scene so that matrix_world follows location and rotation."""
    bpy.context.view_layer.update()


def _axis(obj, local) -> np.ndarray:
    """The world direction of one of ``obj``'s local axes, unit length."""
    v = np.array(obj.matrix_world.to_3x3()) @ np.array(local, dtype=np.float64)
    return v / np.linalg.norm(v)


def test_camera_looks_at_its_target_with_y_up():
    scene = scenekit.empty_file()
    cam = scenekit.add_camera(scene, (3.0, -4.0, 2.0), target=(0.0, 0.0, 0.0))
    _evaluate()
    assert scene.camera is cam and cam.name in scene.collection.objects
    assert (cam.data.clip_start, cam.data.clip_end) == pytest.approx((0.1, 100.0))
    assert cam.data.type == "PERSP"
    # A camera looks down its local -Z: towards the target, from its location.
    np.testing.assert_allclose(_axis(cam, (0, 0, -1)), np.array([-3.0, 4.0, -2.0]) / math.sqrt(29), atol=1e-6)
    assert _axis(cam, (0, 1, 0))[2] > 0  # its up axis leans to world +Z


def test_camera_by_rotation_and_orthographic():
    scene = scenekit.empty_file()
    cam = scenekit.add_camera(scene, (0.0, -10.0, 0.0), rotation=(math.pi / 2, 0.0, 0.0), clip=(0.5, 50.0),
                              lens=35.0, ortho_scale=16.0)
    _evaluate()
    np.testing.assert_allclose(_axis(cam, (0, 0, -1)), [0.0, 1.0, 0.0], atol=1e-6)  # looks along +Y
    assert (cam.data.type, cam.data.ortho_scale, cam.data.lens) == ("ORTHO", 16.0, 35.0)
    assert (cam.data.clip_start, cam.data.clip_end) == pytest.approx((0.5, 50.0))


def test_sun_shines_from_the_direction_it_points_its_z_axis_to():
    scene = scenekit.empty_file()
    direction = np.array([-0.35, -0.75, 0.55])
    sun = scenekit.add_sun(scene, energy=0.8, rotation=scenekit.pointing(direction, "Z"), location=(0.0, -6.0, 5.0))
    _evaluate()
    assert sun.data.type == "SUN" and sun.data.energy == pytest.approx(0.8)
    assert tuple(sun.location) == (0.0, -6.0, 5.0) and sun.name in scene.collection.objects
    np.testing.assert_allclose(_axis(sun, (0, 0, 1)), direction / np.linalg.norm(direction), atol=1e-6)


def test_objects_turn_by_degrees_and_meshes_keep_faces_and_uvs():
    scene = scenekit.empty_file()
    quad = scenekit.mesh("Quad", [(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)], [(0, 1, 2, 3)],
                         uvs=[((0, 0), (1, 0), (1, 1), (0, 1))], smooth=True)
    assert (len(quad.vertices), len(quad.polygons), len(quad.loops)) == (4, 1, 4)
    assert quad.polygons[0].use_smooth
    assert [tuple(quad.uv_layers["UVMap"].data[i].uv) for i in range(4)] == [(0, 0), (1, 0), (1, 1), (0, 1)]
    ob = scenekit.add_object(scene.collection, "Quad", quad, location=(1, 2, 3), rotation=(90, 0, -45),
                             scale=(2, 1, 1))
    assert ob.name in scene.collection.objects and ob.data is quad
    assert tuple(ob.rotation_euler) == pytest.approx((math.pi / 2, 0.0, -math.pi / 4))
    assert tuple(ob.location) == (1, 2, 3) and tuple(ob.scale) == (2, 1, 1)


def test_unity_material_stores_the_settings_and_shows_color_decoded():
    scenekit.empty_file()
    mat = scenekit.unity_material("Glass", queue="Transparent", color=(0.5, 0.25, 1.0, 0.25), lighting="Unlit",
                                  passes=[dict(scenekit.ALPHA_BLEND, cull="Off")])
    m = blender.material_from_blender(mat)
    assert (m.queue.value, m.color, m.lighting.value) == ("Transparent", pytest.approx((0.5, 0.25, 1.0, 0.25)),
                                                          "Unlit")
    (p,) = m.passes
    assert (p.blend, p.zwrite, p.src_blend.value, p.dst_blend.value, p.cull.value) == (
        True, False, "SrcAlpha", "OneMinusSrcAlpha", "Off")

    # The viewport colour: the sRGB decoding of _Color (IEC 61966-2-1), alpha as given.
    def decode(c):
        return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4

    assert tuple(mat.diffuse_color) == pytest.approx((decode(0.5), decode(0.25), 1.0, 0.25), abs=1e-6)
    assert decode(0.5) == pytest.approx(0.21404, abs=1e-5)


def test_set_resolution():
    scene = scenekit.empty_file()
    scene.render.resolution_percentage = 50
    scenekit.set_resolution(scene, 320, 180)
    assert (scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage) == (320, 180, 100)
