"""Extraction of vertex colours (SPEC §12: the active colour attribute, byte or float, point or
corner, white when absent) and the outline vertex program's pass settings (issue 28), in Blender."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from blendlib import blender, render
from blendlib.core.vocabulary import OutlineFormula, OutlineMode, Pass, VertexColor
from tests.support.blender_fixtures import add_plane, empty_scene, unlit_material


def _plane_with(material, data_type: str | None, domain: str = "CORNER", values=None):
    obj = add_plane("Plane", size=4.0, material=material)
    mesh = obj.data
    if data_type is not None:
        attribute = mesh.color_attributes.new("Col", data_type, domain)
        n = len(attribute.data)
        values = np.asarray(values if values is not None else np.linspace(0, 1, n * 4), np.float32).reshape(n, 4)
        attribute.data.foreach_set("color_srgb" if data_type == "BYTE_COLOR" else "color", values.reshape(-1))
        mesh.color_attributes.active_color = attribute
    return obj


def _renderer():
    (r,) = blender.build_draw_scene(bpy.context.scene).renderers
    return r


@pytest.mark.parametrize("domain", ["CORNER", "POINT"])
def test_byte_colours_are_read_as_their_encoded_values_per_corner(domain):
    empty_scene()
    values = np.array([[k / 255, (k + 1) / 255, (k + 2) / 255, 1.0] for k in (10, 60, 120, 200)], np.float32)
    _plane_with(unlit_material("M", vertex_color="Multiply"), "BYTE_COLOR", domain, values)
    r = _renderer()
    assert r.mesh.color_encoding == "sRGB" and r.mesh.colors.shape == (2, 3, 4)
    corner_vert = np.asarray(r.mesh.triangles)  # a point colour follows its vertex; the plane's loops are 0..3
    np.testing.assert_array_equal(r.mesh.colors, values[corner_vert])


def test_float_colours_are_linear_and_absent_colours_are_white():
    empty_scene()
    values = np.array([[0.1, 0.2, 0.3, 0.4]] * 4, np.float32)
    obj = _plane_with(unlit_material("M", vertex_color="Multiply", color=(1, 1, 1, 1)), "FLOAT_COLOR", "POINT",
                      values)
    r = _renderer()
    assert r.mesh.color_encoding == "Linear"
    np.testing.assert_array_equal(r.mesh.colors, np.broadcast_to(values[0], (2, 3, 4)))
    blender.write_scene_settings(bpy.context.scene, color_space="Linear", hdr=True)
    frame = render()
    assert frame.color[24, 32, 0] == pytest.approx(0.1, abs=1e-6)  # Linear mode: the float value as is
    assert frame.color[24, 32, 3] == pytest.approx(0.4, abs=1e-6)
    obj.data.color_attributes.remove(obj.data.color_attributes["Col"])
    assert _renderer().mesh.colors is None  # white
    assert np.allclose(render().color[24, 32], (1, 1, 1, 1))


def test_colours_are_read_only_for_materials_that_use_them():
    empty_scene()
    _plane_with(unlit_material("M"), "BYTE_COLOR")
    assert _renderer().mesh.colors is None
    assert _renderer().material.vertex_color is VertexColor.Off


def test_outline_settings_round_trip_and_render():
    empty_scene()
    outline = Pass(name="Outline", outline_mode=OutlineMode.Screen, outline_width=2.5,
                   outline_formula=OutlineFormula.MToon10, outline_max_distance=3.0)
    mat = unlit_material("Toon", passes=[Pass(name="Base"), outline])
    add_plane("Plane", material=mat)
    got = blender.material_from_blender(mat).passes[1]
    assert (got.outline_mode, got.outline_width, got.outline_formula, got.outline_max_distance) == \
        (OutlineMode.Screen, 2.5, OutlineFormula.MToon10, 3.0)
    assert blender.material_from_blender(mat).passes[0].outline_mode is OutlineMode.Off


def test_outline_colour_round_trips_and_an_older_group_has_none():
    """Schema version 4 appends the outline colour: written and read back (float32 as Blender stores
    it); a version-3 pass group without it reads as no outline colour (the lit colour, as before)."""
    from blendlib.blender import material_values

    empty_scene()
    outline = Pass(name="Outline", outline_mode=OutlineMode.World, outline_width=0.5,
                   outline_color=(1.0, 0.25, 0.0), outline_lighting_mix=0.5)
    mat = unlit_material("Toon", passes=[Pass(name="Base"), outline])
    got = blender.material_from_blender(mat).passes
    assert got[1].outline_color == (1.0, 0.25, 0.0) and got[1].outline_lighting_mix == 0.5
    assert got[0].outline_color is None
    stored = material_values(mat)["passes"]
    assert [p["outline_colored"] for p in stored] == [False, True]
    # A file saved before version 4: the group stores version 3 and none of the three names.
    group = mat.bl_system_properties_get()["unity"]
    if "schema_version" in group:
        group["schema_version"] = 3
    for item in group["passes"]:
        for name in ("outline_colored", "outline_color", "outline_lighting_mix"):
            if name in item:
                del item[name]
    old = blender.material_from_blender(mat).passes
    assert [p.outline_color for p in old] == [None, None] and old[1].outline_width == 0.5
