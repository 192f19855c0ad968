"""The "Unity Passes" render engine (addon/engine/render.py): F12 stills and animations equal
blendlib.render, render_final's modifier levels, the result's passes, errors and cancel."""

from __future__ import annotations

import os

import bpy
import numpy as np
import pytest

import addon
import blendlib
from addon.engine.render import result_arrays
from blendlib import blender, render
from blendlib.core import colorspace
from blendlib.formats import images
from blendlib.runtime import bandprocs
from tests.support.blender_fixtures import add_cube, add_plane, empty_scene, unlit_material


@pytest.fixture(autouse=True)
def registered():
    addon.register()
    yield
    addon.unregister()


def glass_scene(color_space="Gamma", hdr=False):
    scene = empty_scene(40, 30)
    scene.render.engine = "UNITY_PASSES"
    scene.unity.color_space = color_space
    scene.unity.hdr = hdr
    add_cube("Back", 2.0, (0.5, 2, 0.3), unlit_material("Red", (0.9, 0.1, 0.1, 1.0)))
    glass = unlit_material("Glass", (0.2, 0.6, 1.0, 0.5))
    with bpy.context.temp_override(material=glass):
        bpy.ops.unity.apply_preset(preset="Alpha Blend Both Sided")
    add_cube("Glass", 2.0, (-0.5, 0, 0), glass)
    return scene


@pytest.mark.parametrize("color_space,hdr", [("Gamma", False), ("Linear", False), ("Linear", True)])
def test_engine_write_still_equals_blendlib_render(tmp_path, color_space, hdr):
    scene = glass_scene(color_space, hdr)
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = str(tmp_path / "still.png")
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}
    frame = render(scene)
    png = images.load(tmp_path / "still.png")
    expected = blender.linear_rgba(frame, opaque=True)
    # 8-bit file of Combined under the Standard view: the stored 8-bit values, alpha 255.
    want = images.to_uint8(frame.color[..., :3]) if not hdr else \
        images.to_uint8(np.where(expected[..., :3] <= 0.0031308, expected[..., :3] * 12.92,
                                  1.055 * np.maximum(expected[..., :3], 0) ** (1 / 2.4) - 0.055))
    got = images.to_uint8(png[..., :3])
    assert np.abs(got.astype(int) - want.astype(int)).max() <= (0 if not hdr else 1)
    assert (png[..., 3] == 1.0).all()
    assert len(np.unique(got.reshape(-1, 3), axis=0)) >= 3  # clear, red, glass: not an empty frame
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(tmp_path / "still.exr")
    bpy.ops.render.render(write_still=True)
    np.testing.assert_array_equal(images.load(tmp_path / "still.exr"), expected)


def test_large_f12_frames_are_drawn_in_two_bands_and_equal_one_render(tmp_path):
    """F12 of a frame of MIN_PIXELS or more goes through the final renderer's helper process
    (two bands) and writes the very frame one render_scene draws; unregistering ends the helper."""
    scene = glass_scene()
    scene.render.resolution_x, scene.render.resolution_y = 640, 360
    assert 640 * 360 >= bandprocs.MIN_PIXELS
    bands = bandprocs.final_renderer()
    assert bands.wait_ready(30.0), bands.failure
    before = bands.split_frames
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(tmp_path / "bands.exr")
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}
    assert bands.split_frames == before + 1
    expected = blendlib.render_scene(blender.draw_scene(scene))
    np.testing.assert_array_equal(images.load(tmp_path / "bands.exr"), blender.linear_rgba(expected, opaque=True))
    helper = bands._helper.proc
    addon.unregister()
    assert bands._closed and helper.wait(timeout=30.0) == 0


def test_render_final_uses_modifier_render_levels_like_f12(tmp_path):
    """A Subdivision modifier at viewport level 0 and render level 3: render_final (and so the
    CLI and render()) sees the render-level mesh exactly as F12 does; render() given the
    viewport's depsgraph sees the viewport one."""
    scene = glass_scene()
    glass = bpy.data.objects["Glass"]
    mod = glass.modifiers.new("Subdivision", "SUBSURF")
    mod.levels, mod.render_levels = 0, 3
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = str(tmp_path / "f12.png")
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}
    f12 = images.to_uint8(images.load(tmp_path / "f12.png")[..., :3])
    final = blender.render_final(scene)
    viewport = render(scene, depsgraph=bpy.context.evaluated_depsgraph_get())
    assert scene.render.engine == "UNITY_PASSES"  # restored after render_final
    np.testing.assert_array_equal(images.to_uint8(final.color[..., :3]), f12)
    changed = np.any(final.color != viewport.color, axis=2).sum()
    assert changed > 20, "the rounded (render-level) cube must differ from the level-0 cube"


def test_engine_result_passes():
    glass_scene("Linear")
    frame = render()
    assert frame.encoded  # Linear LDR stores sRGB-encoded codes
    arrays = result_arrays(frame)
    h, w = frame.depth.shape
    np.testing.assert_array_equal(arrays["Depth"].reshape(h, w)[::-1], frame.depth)
    np.testing.assert_array_equal(arrays["UnityAlpha"].reshape(h, w)[::-1], frame.color[..., 3])
    assert frame.depth.min() < 1.0 and frame.color[..., 3].min() == 0.0  # clear alpha 0 around the cubes
    combined = arrays["Combined"].reshape(h, w, 4)[::-1]
    assert (combined[..., 3] == 1).all()
    np.testing.assert_allclose(combined[..., :3], colorspace.decode_fast(frame.color[..., :3]), atol=1e-6)


def test_engine_errors_are_reports_and_write_nothing(tmp_path):
    scene = glass_scene()
    scene.camera = None
    scene.render.filepath = str(tmp_path / "nocam.png")
    with pytest.raises(RuntimeError, match="no camera"):
        bpy.ops.render.render(write_still=True)
    assert not (tmp_path / "nocam.png").exists()


def test_engine_cancel_writes_nothing(tmp_path, monkeypatch):
    scene = glass_scene()
    scene.render.filepath = str(tmp_path / "cancel.png")
    calls = []
    original = blendlib.blender.render_frame

    def cancelling(draw, progress=None, should_cancel=None):
        calls.append(should_cancel)
        return original(draw, progress=progress, should_cancel=lambda: True)

    monkeypatch.setattr(blendlib.blender, "render_frame", cancelling)
    with pytest.raises(RuntimeError, match="cancelled"):
        bpy.ops.render.render(write_still=True)
    assert calls and callable(calls[0])  # the engine passes its test_break
    assert not os.listdir(tmp_path)


def test_engine_animation_renders_each_frame(tmp_path):
    scene = glass_scene()
    glass = bpy.data.objects["Glass"]
    scene.frame_start, scene.frame_end = 1, 2
    glass.location = (-3, 0, 0)
    glass.keyframe_insert("location", frame=1)
    glass.location = (3, 0, 0)
    glass.keyframe_insert("location", frame=2)
    scene.render.filepath = str(tmp_path / "anim_#")
    scene.render.image_settings.file_format = "PNG"
    bpy.ops.render.render(animation=True)
    a, b = images.load(tmp_path / "anim_1.png"), images.load(tmp_path / "anim_2.png")
    assert a.shape == b.shape == (30, 40, 4) and not np.array_equal(a, b)


def test_plane_renders_with_disabled_material_lambert():
    empty_scene(16, 16)
    add_plane("Plane", 10.0)
    frame = render()
    assert np.allclose(frame.color, frame.color[0, 0])  # the plane fills the frame
    assert not np.allclose(frame.color[0, 0], blender.scene_settings(bpy.context.scene)["clear_color"], atol=1e-3)
