"""The render engine and render_final with a Render Region, and no image after a failure."""

from __future__ import annotations

import os

import bpy
import numpy as np
import pytest

import addon
from addon.engine import render as engine
from blendlib import SceneError, blender
from blendlib.formats import images
from tests.support.blender_fixtures import add_cube, empty_scene, unlit_material

W, H = 40, 30
# Blender: region = border x size in float32, truncated; y counts from the bottom.
BORDER = (0.25, 0.6, 0.1, 0.5)
X0, X1, Y0, Y1 = 10, 24, 3, 15
ROWS, COLS = slice(H - Y1, H - Y0), slice(X0, X1)


@pytest.fixture(autouse=True)
def registered():
    addon.register()
    yield
    addon.unregister()


def scene_with_cubes():
    scene = empty_scene(W, H)
    scene.render.engine = "UNITY_PASSES"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    add_cube("Back", 2.0, (0.5, 2, 0.3), unlit_material("Red", (0.9, 0.1, 0.1, 1.0)))
    add_cube("Front", 1.0, (-0.6, 0, -0.4), unlit_material("Blue", (0.1, 0.2, 0.9, 1.0)))
    return scene


def set_region(scene, crop: bool) -> None:
    r = scene.render
    r.use_border, r.use_crop_to_border = True, crop
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = BORDER


def write_still(scene, path) -> np.ndarray:
    scene.render.filepath = str(path)
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}
    return images.load(path)


def test_region_pixels_match_the_full_render(tmp_path):
    scene = scene_with_cubes()
    full = write_still(scene, tmp_path / "full.exr")
    inside = full[ROWS, COLS]
    assert len(np.unique(inside.reshape(-1, 4), axis=0)) >= 3  # clear, red and blue inside the region

    set_region(scene, crop=True)
    cropped = write_still(scene, tmp_path / "crop.exr")
    assert cropped.shape == (Y1 - Y0, X1 - X0, 4)
    np.testing.assert_array_equal(cropped, inside)

    set_region(scene, crop=False)
    placed = write_still(scene, tmp_path / "nocrop.exr")
    assert placed.shape == (H, W, 4)
    np.testing.assert_array_equal(placed[ROWS, COLS], inside)
    outside = np.ones((H, W), bool)
    outside[ROWS, COLS] = False
    assert (placed[outside] == 0).all()


@pytest.mark.parametrize("crop", [True, False])
def test_render_final_writes_the_region_like_f12(tmp_path, crop):
    scene = scene_with_cubes()
    full = blender.render_final(scene)
    set_region(scene, crop)
    f12 = write_still(scene, tmp_path / "f12.exr")
    frame = blender.render_final(scene)
    if crop:
        assert frame.color.shape == (Y1 - Y0, X1 - X0, 4)
        np.testing.assert_array_equal(frame.color, full.color[ROWS, COLS])
        np.testing.assert_array_equal(frame.depth, full.depth[ROWS, COLS])
    else:
        assert frame.color.shape == (H, W, 4)
        np.testing.assert_array_equal(frame.color[ROWS, COLS], full.color[ROWS, COLS])
        outside = np.ones((H, W), bool)
        outside[ROWS, COLS] = False
        assert (frame.color[outside] == 0).all() and (frame.depth[outside] == 1).all()
    np.testing.assert_array_equal(blender.linear_rgba(frame, opaque=True)[..., :3], f12[..., :3])


def test_a_region_smaller_than_a_pixel_is_one_error():
    scene = scene_with_cubes()
    set_region(scene, crop=True)
    scene.render.border_max_x = scene.render.border_min_x
    with pytest.raises(SceneError, match="Render Region"):
        blender.render_final(scene)


def test_no_image_is_saved_after_a_failure_also_in_an_animation(tmp_path, monkeypatch):
    scene = scene_with_cubes()
    scene.render.image_settings.file_format = "PNG"

    def failing(frame):
        raise ValueError("result arrays failed")

    monkeypatch.setattr(engine, "result_arrays", failing)
    scene.render.filepath = str(tmp_path / "still.png")
    with pytest.raises(RuntimeError, match="result arrays failed"):
        bpy.ops.render.render(write_still=True)
    scene.frame_start, scene.frame_end = 1, 3
    scene.render.filepath = str(tmp_path / "anim_#")
    with pytest.raises(RuntimeError, match="result arrays failed"):
        bpy.ops.render.render(animation=True)
    assert os.listdir(tmp_path) == []


def test_render_final_restores_the_current_frame():
    scene = scene_with_cubes()
    scene.frame_set(3)
    blender.render_final(scene, frame=7)
    assert scene.frame_current == 3


def test_a_missing_image_is_warned_once(tmp_path):
    scene = scene_with_cubes()
    image = bpy.data.images.new("Missing", 4, 4)
    image.source = "FILE"
    image.filepath = str(tmp_path / "does_not_exist.png")
    bpy.data.materials["Red"].unity.main_tex = image
    frame = blender.render(scene)
    about = [w for w in frame.warnings if "Missing" in w]
    assert about == [f"image 'Missing': cannot read {image.filepath}; using magenta"]
    final = blender.render_final(scene)
    assert [w for w in final.warnings if "Missing" in w] == about
