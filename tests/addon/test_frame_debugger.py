"""The Unity Frame Debugger in Blender: registration, Capture and Pixel History operators run in
background through their execute path, the draw slider's image, the panel's draw code against
the recording layout of test_ui.py, and the Python API (render until_draw, draw_list, pixel_history)."""

from __future__ import annotations

from types import SimpleNamespace

import bpy
import numpy as np
import pytest

import addon
import blendlib
from blendlib import Frame, render_scene
from blendlib.blender import build_draw_scene, linear_rgba
from blendlib.blender import framedebug as bfd
from blendlib.explain import framedebug as fd
from tests.addon.recording import RecordingLayout, draw_panel
from tests.support.blender_fixtures import add_cube, add_plane, empty_scene, unlit_material


@pytest.fixture()
def scene():
    addon.register()
    scene = empty_scene(24, 16)
    wall = unlit_material("Wall", (0.9, 0.2, 0.1, 1.0))
    add_plane("Wall", 12.0, location=(0, 4, 0), material=wall)
    glass = unlit_material("Glass", (0.1, 0.4, 0.9, 0.5))
    with bpy.context.temp_override(material=glass):
        bpy.ops.unity.apply_preset(preset="Alpha Blend")
    glass.unity.passes[0].cull = "Off"
    add_cube("Cube", 2.0, material=glass)
    yield scene
    addon.unregister()


def _image_rgba():
    image = bpy.data.images[bfd.IMAGE_NAME]
    w, h = image.size
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(h, w, 4)[::-1]


def _shown(frame, buffer="COLOR", mask=None):
    rgba, encoded = bfd.buffer_rgba(frame, buffer, mask)
    return linear_rgba(Frame(rgba, frame.depth, frame.stencil, encoded=encoded))


def test_register_twice_and_unregister_removes_everything():
    addon.register()
    addon.register()
    assert hasattr(bpy.types.Scene, "unity_frame_debugger")
    for idname in ("UNITY_PT_frame_debugger", "UNITY_PT_frame_debugger_pixel", "UNITY_UL_frame_debugger_draws"):
        assert hasattr(bpy.types, idname), idname
    assert hasattr(bpy.ops.unity, "frame_debugger_capture") and hasattr(bpy.ops.unity, "frame_debugger_pixel")
    addon.unregister()
    addon.unregister()
    assert not hasattr(bpy.types.Scene, "unity_frame_debugger")
    assert not hasattr(bpy.types, "UNITY_PT_frame_debugger")


def test_capture_lists_draws_and_the_slider_shows_frames_after_each_draw(scene):
    settings = scene.unity_frame_debugger
    assert draw_panel(addon.frame_debugger.panel.UNITY_PT_frame_debugger, scene=scene)["operators"] == [
        "unity.frame_debugger_capture"]
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.unity.frame_debugger_capture() == {"FINISHED"}
    assert [(d.index, d.object, d.queue, d.pass_name) for d in settings.draws] == [
        (1, "Wall", 2000, "Pass"), (2, "Cube", 3000, "Pass")]
    assert settings.draws[1].state == "Cull Off ZWrite Off ZTest LEqual Blend SrcAlpha OneMinusSrcAlpha"
    assert settings.draws[0].written == 24 * 16 and settings.draws[1].triangles == 12
    assert settings.draw == 2
    draw = build_draw_scene(scene)
    full = render_scene(draw)
    assert np.array_equal(_image_rgba(), _shown(full))
    for k in (0, 1):
        settings.draw = k
        assert k == 0 or settings.active_draw == k - 1  # the list follows the slider
        expect = blendlib.render(scene, until_draw=k)  # the Python API stops there too
        assert np.array_equal(expect.color, render_scene(draw, until_draw=k).color)
        assert np.array_equal(_image_rgba(), _shown(expect)), k
    settings.active_draw = 1  # selecting a row moves the slider
    assert settings.draw == 2
    settings.buffer = "DEPTH"
    assert np.array_equal(_image_rgba(), _shown(full, "DEPTH"))
    settings.highlight = True
    _, mask = fd.FrameCapture.capture(draw).frame_after(2, highlight=True)
    assert mask.any() and not mask.all()
    assert np.array_equal(_image_rgba(), _shown(full, "DEPTH", mask))
    log = draw_panel(addon.frame_debugger.panel.UNITY_PT_frame_debugger, scene=scene)
    assert {"draws", "draw", "buffer", "highlight"} <= set(log["props"])
    assert any("Cull Off ZWrite Off" in text for text in log["labels"]), log["labels"]
    row = {"labels": [], "props": [], "operators": [], "menus": []}
    ul = SimpleNamespace(layout_type="DEFAULT")
    addon.frame_debugger.panel.UNITY_UL_frame_debugger_draws.draw_item(
        ul, None, RecordingLayout(row), settings, settings.draws[1], 0, settings, "active_draw")
    assert row["labels"] == ["2  3000  Cube  Pass", settings.draws[1].state]


def test_pixel_history_operator_with_coordinates(scene):
    settings = scene.unity_frame_debugger
    with bpy.context.temp_override(scene=scene):
        bpy.ops.unity.frame_debugger_capture()
        assert bpy.ops.unity.frame_debugger_pixel(x=12, y=8) == {"FINISHED"}
    expect = blendlib.pixel_history(scene, 12, 8)
    got = [(f.draw, f.object, f.triangle, f.polygon, f.result) for f in settings.fragments]
    assert got == [(f.call.index, f.call.renderer.name, f.triangle, f.polygon, f.result) for f in expect.fragments]
    assert [f.draw for f in settings.fragments] == [1, 2, 2]
    assert tuple(settings.fragments[-1].after) == pytest.approx(expect.final, abs=0)
    assert (settings.pixel_x, settings.pixel_y) == (12, 8) and "3 fragments" in settings.pixel_text
    log = draw_panel(addon.frame_debugger.panel.UNITY_PT_frame_debugger_pixel, scene=scene)
    assert {"pixel_x", "pixel_y", "fragments"} <= set(log["props"])
    assert log["operators"] == ["unity.frame_debugger_pixel"] * 2
    with bpy.context.temp_override(scene=scene), pytest.raises(RuntimeError, match="outside"):
        bpy.ops.unity.frame_debugger_pixel(x=24, y=0)
    assert len(settings.fragments) == 3  # unchanged


def test_capture_without_camera_reports_one_error(scene):
    scene.camera = None
    with bpy.context.temp_override(scene=scene), pytest.raises(RuntimeError, match="no camera"):
        bpy.ops.unity.frame_debugger_capture()
    assert len(scene.unity_frame_debugger.draws) == 0 and bfd.IMAGE_NAME not in bpy.data.images


def test_draw_list_api_matches_the_capture(scene):
    stats = blendlib.draw_list(scene)
    assert [s.to_json()["object"] for s in stats] == ["Wall", "Cube"]
    assert stats[1].fragments == stats[1].written > 0


def test_pixel_from_view_maps_image_coordinates():
    from addon.frame_debugger.ops import pixel_from_view

    assert pixel_from_view(0.0, 0.0, 24, 16) == (0, 15)  # bottom-left of the image = last row from the top
    assert pixel_from_view(0.999, 0.999, 24, 16) == (23, 0)
    assert pixel_from_view(0.5, 0.5, 24, 16) == (12, 7)
    assert pixel_from_view(1.0, 0.5, 24, 16) is None and pixel_from_view(-0.01, 0.5, 24, 16) is None
    assert pixel_from_view(float("nan"), 0.5, 24, 16) is None
