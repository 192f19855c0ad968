"""The viewport's view maths (blendlib.blender.viewport), bpy-free: a view's matrices → Camera, and
the camera frame's rectangle in a region."""

from __future__ import annotations

import numpy as np
import pytest

from blendlib import SceneError
from blendlib.blender import viewport
from blendlib.blender.viewport import camera_from_matrices
from tests.reference.scenes import look_at, orthographic, perspective


def test_camera_from_matrices():
    view = look_at((3, -5, 2), (0, 0, 0), (0, 0, 1))
    persp = perspective(50, 4 / 3, 0.5, 40)
    cam = camera_from_matrices(view, persp, 40, 30)
    assert not cam.orthographic and (cam.width, cam.height) == (40, 30)
    np.testing.assert_allclose(cam.position, (3, -5, 2), atol=1e-12)  # the sort position
    ortho = camera_from_matrices(view.tolist(), orthographic(8, 6), 40, 30)
    assert ortho.orthographic
    for bad in (np.eye(3), [[1, 2], [3, 4]], "matrix", np.full((4, 4), np.nan)):
        with pytest.raises(SceneError, match="4x4"):
            camera_from_matrices(bad, persp, 40, 30)
    with pytest.raises(SceneError, match="integers"):
        camera_from_matrices(view, persp, 40.0, 30)
    with pytest.raises(SceneError, match="singular"):
        camera_from_matrices(np.zeros((4, 4)), persp, 40, 30)


def test_camera_frame_rect():
    # corners of a frame that the perspective maps to NDC x in [-0.5, 0.5], y in [-0.5, 0.5]
    corners = np.array([[0.5, 0.5, 0.0], [0.5, -0.5, 0.0], [-0.5, -0.5, 0.0], [-0.5, 0.5, 0.0]])
    assert viewport.camera_frame_rect(corners, np.eye(4), 200, 100) == (50, 25, 100, 50)
    shifted = np.eye(4)
    shifted[0, 3] = 0.5  # NDC x + 0.5: a quarter of the region to the right
    assert viewport.camera_frame_rect(corners, shifted, 200, 100) == (100, 25, 100, 50)
