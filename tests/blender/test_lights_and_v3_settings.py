"""Schema version 3 (SPEC §12): Blender lights as Unity forward lights (``Light.unity``, derived values),
the new material, pass and scene settings, and version-2 settings reading as they rendered."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

import addon
from blendlib import blender
from blendlib.blender import migration
from blendlib.core.scene import SceneError
from blendlib.core.vocabulary import CompareFunction, LightMode, LightRenderMode, LightType, TextureFilter, VertexColor
from tests.support.blender_fixtures import add_plane, empty_scene


def _light(name: str, kind: str, location=(0.0, 0.0, 0.0), energy: float = 1000.0):
    data = bpy.data.lights.new(name, kind)
    data.energy = energy
    obj = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    return obj


@pytest.fixture
def registered():
    was = hasattr(bpy.types.Material, "unity")
    if not was:
        addon.register()
    yield
    if not was:
        addon.unregister()


def test_derived_values_follow_the_blender_light():
    empty_scene()
    point = _light("Point", "POINT", energy=1000.0).data
    # Power in W / 4π (Blender's glTF exporter) / π (glTFast for the built-in pipeline).
    assert blender.derived_light_values(point)["intensity"] == pytest.approx(1000 / (4 * math.pi ** 2))
    assert blender.derived_light_values(point)["range"] == 10.0  # a new Unity light's range
    point.use_custom_distance, point.cutoff_distance = True, 7.5
    assert blender.derived_light_values(point)["range"] == 7.5
    spot = _light("Spot", "SPOT").data
    spot.spot_size = math.radians(60.0)
    assert blender.derived_light_values(spot)["spot_angle"] == pytest.approx(60.0)
    sun = _light("Sun", "SUN", energy=3.0).data
    assert blender.derived_light_values(sun)["intensity"] == 3.0  # the main light's convention


def test_stored_values_replace_the_derived_ones_when_asked():
    empty_scene()
    spot = _light("Spot", "SPOT").data
    blender.write_light_settings(spot, use_blender_values=False, intensity=2.5, range=4.0, spot_angle=40.0,
                                 render_mode="Important")
    values = blender.unity_light_values(spot)
    assert (values["intensity"], values["range"], values["spot_angle"], values["render_mode"]) == \
        (2.5, 4.0, 40.0, "Important")
    with pytest.raises(ValueError):
        blender.write_light_settings(spot, render_mode="Sometimes")


def test_extraction_keeps_the_brightest_sun_as_main_light_and_the_rest_as_forward_lights():
    empty_scene()
    add_plane("Plane")
    _light("Sun.A", "SUN", energy=2.0)
    _light("Sun.B", "SUN", energy=5.0).rotation_euler = (0.0, math.pi / 2, 0.0)
    _light("Lamp", "POINT", location=(1.0, -2.0, 3.0))
    spot = _light("Cone", "SPOT", location=(0.0, -1.0, 0.0))
    spot.rotation_euler = (math.pi / 2, 0.0, 0.0)  # local +Z turned to -Y: the spot shines along +Y
    _light("Panel", "AREA")
    draw = blender.build_draw_scene(bpy.context.scene)
    assert draw.light.name == "Sun.B" and draw.light.energy == 5.0
    np.testing.assert_allclose(draw.light.direction, (1.0, 0.0, 0.0), atol=1e-6)
    assert [(f.name, f.type) for f in draw.lights] == [
        ("Cone", LightType.Spot), ("Lamp", LightType.Point), ("Sun.A", LightType.Directional)]
    cone, lamp = draw.lights[0], draw.lights[1]
    assert lamp.position == pytest.approx((1.0, -2.0, 3.0))
    np.testing.assert_allclose(cone.axis, (0.0, -1.0, 0.0), atol=1e-6)
    assert cone.spot_angle == pytest.approx(45.0)  # Blender's default Spot Size
    assert all(f.render_mode is LightRenderMode.Auto for f in draw.lights)
    assert draw.pixel_light_count == 4 and draw.msaa == 1


def test_version_2_settings_read_with_defaults_that_draw_as_before():
    empty_scene()
    mat = bpy.data.materials.new("Old")
    store = mat.bl_system_properties_get(do_create=True)
    store["unity"] = {"enabled": 1, "queue": 3, "main_tex_filter": 1, "schema_version": 2,
                      "passes": [{"alpha_test": 1, "zwrite": 0}]}
    values = blender.material_values(mat)
    assert values["main_tex_filter"] == "Point" and values["main_tex_mipmaps"] is False
    assert values["vertex_color"] == "Off" and values["tint_color"] == pytest.approx((0.5, 0.5, 0.5, 0.5))
    p = blender.pass_from_values(values["passes"][0])
    assert p.alpha_test and p.alpha_test_comp is CompareFunction.GEqual and p.light_mode is LightMode.ForwardBase
    assert not p.alpha_to_mask
    m = blender.material_from_blender(mat)
    assert m.main_tex_filter is TextureFilter.Point and m.vertex_color is VertexColor.Off
    settings = blender.scene_settings(bpy.context.scene)
    assert settings["msaa"] == 1 and settings["pixel_light_count"] == 4
    assert migration.migrate_material({"schema_version": 2, "queue": 3}) == {"schema_version": 4, "queue": 3}


def test_msaa_takes_only_unitys_sample_counts(registered):
    scene = empty_scene()
    for bad in (3, 0, 16):
        with pytest.raises(ValueError):
            blender.write_scene_settings(scene, msaa=bad)
    blender.write_scene_settings(scene, msaa=8)
    assert scene.unity.msaa == 8
    scene.unity.msaa = 3  # the panel's slider between two counts snaps down
    assert scene.unity.msaa == 2
    scene.unity.msaa = 7
    assert scene.unity.msaa == 4


def test_an_msaa_count_stored_without_the_add_on_is_checked_at_render():
    scene = empty_scene()
    add_plane("Plane")
    scene.bl_system_properties_get(do_create=True)["unity"] = {"msaa": 3, "schema_version": 3}
    draw = blender.build_draw_scene(scene)
    from blendlib.core.scene import validate_scene

    with pytest.raises(SceneError, match="MSAA must be 1, 2, 4 or 8"):
        validate_scene(draw)


def test_new_material_settings_round_trip_through_the_writers(registered):
    empty_scene()
    mat = bpy.data.materials.new("Particles")
    blender.write_material(mat, enabled=True, main_tex_filter="Trilinear", main_tex_mipmaps=True,
                           main_tex_preserve_coverage=True, vertex_color="Particle", tint_color=(0.2, 0.4, 0.6, 0.8),
                           passes=[{"light_mode": "ForwardAdd", "alpha_to_mask": True, "alpha_test": True,
                                    "alpha_test_comp": "Greater"}])
    m = blender.material_from_blender(mat)
    assert m.main_tex_filter is TextureFilter.Trilinear and m.main_tex_mipmaps and m.main_tex_preserve_coverage
    assert m.vertex_color is VertexColor.Particle
    assert m.tint_color == pytest.approx((0.2, 0.4, 0.6, 0.8))
    p = m.passes[0]
    assert p.light_mode is LightMode.ForwardAdd and p.alpha_to_mask and p.alpha_test_comp is CompareFunction.Greater
    assert mat.unity.passes[0].light_mode == "ForwardAdd"
