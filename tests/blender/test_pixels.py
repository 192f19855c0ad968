"""The one flip between the renderer's top-first frames and Blender's bottom-first buffers
(blendlib/blender/pixels.py), pinned on explicit arrays and through a real Blender image saved to
a file and read back by an independent reader."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from blendlib import Frame, write_image
from blendlib.blender.pixels import bottom_first
from blendlib.formats import images
from tests.support.blender_fixtures import empty_scene


def test_bottom_first_puts_the_last_row_first_and_keeps_rows_left_to_right():
    top_first = np.array([[0, 1, 2], [10, 11, 12]], dtype=np.int64)  # 2 rows, 3 columns: row 0 = top
    got = bottom_first(top_first)
    assert got.dtype == np.float32 and got.shape == (6, 1) and got.flags.c_contiguous
    np.testing.assert_array_equal(got[:, 0], [10, 11, 12, 0, 1, 2])
    rgba = np.arange(2 * 3 * 4, dtype=np.float64).reshape(2, 3, 4)
    got = bottom_first(rgba)
    assert got.shape == (6, 4) and got.dtype == np.float32
    np.testing.assert_array_equal(got[0], [12, 13, 14, 15])  # bottom-left pixel: row 1, column 0
    np.testing.assert_array_equal(got[3], [0, 1, 2, 3])  # top-left pixel follows the bottom row
    assert np.shares_memory(got, got.ravel())  # the flat buffer is a view
    np.testing.assert_array_equal(got.ravel()[:8], [12, 13, 14, 15, 16, 17, 18, 19])


def test_bottom_first_rejects_other_shapes():
    with pytest.raises(ValueError, match=r"\(H, W\) or \(H, W, C\)"):
        bottom_first(np.zeros(5, np.float32))


def test_a_blender_image_written_from_a_frame_saves_the_frame_upright(tmp_path):
    """An asymmetric 3x4 frame (one bright top-left corner, a ramp along x, rows differing in green)
    written to a bpy Image: Blender's first pixel is the frame's bottom-left, and the file Blender
    saves reads back (row 0 = top) as the frame itself."""
    empty_scene(4, 3)
    h, w = 3, 4
    color = np.zeros((h, w, 4), np.float32)
    color[..., 0] = np.arange(w, dtype=np.float32)[None, :] / 8  # red ramp: left to right
    color[..., 1] = np.arange(h, dtype=np.float32)[:, None] / 4  # green: top row 0, bottom row 0.5
    color[..., 3] = 1.0
    color[0, 0, 2] = 1.0  # blue: only the top-left pixel
    frame = Frame(color=color, depth=np.ones((h, w), np.float32), stencil=np.zeros((h, w), np.uint8))
    target = bpy.data.images.new("Upright", w, h, alpha=True, float_buffer=True)
    target.colorspace_settings.name = "Non-Color"  # saved as stored (set first: it regenerates the pixels)
    image = write_image(frame, "Upright", encoded=False)
    assert image == target  # write_image fills a float image of the frame's size in place
    pixels = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(pixels)
    np.testing.assert_array_equal(pixels[:4], [0.0, 0.5, 0.0, 1.0])  # Blender's (0, 0): bottom-left
    np.testing.assert_array_equal(pixels[-4:], [3 / 8, 0.0, 0.0, 1.0])  # Blender's last: top-right
    image.filepath_raw = str(tmp_path / "upright.exr")
    image.file_format = "OPEN_EXR"
    image.save()
    np.testing.assert_array_equal(images.load(tmp_path / "upright.exr"), color)
    bpy.data.images.remove(image)
