"""``blendlib.render_view``: a scene through any view's matrices (the viewport's Rendered shading).

Checked against F12 through a camera with the same matrices (bit-identical), against the
OpenGL reference for free views (perspective and orthographic, no camera needed), and for
leaving the scene as it was.
"""

from __future__ import annotations

import dataclasses
import math

import bpy
import numpy as np
import pytest
from mathutils import Matrix

import addon
from blendlib import blender, render_view
from blendlib.blender import viewport
from blendlib.core.scene import SceneError
from tests.reference.scenes import look_at, orthographic, perspective
from tests.support import goldens
from tests.support.blender_fixtures import add_cube, empty_scene, snapshot, unlit_material


@pytest.fixture(autouse=True)
def registered():
    addon.register()
    yield
    addon.unregister()


def glass_scene(width=40, height=30):
    scene = empty_scene(width, height)
    add_cube("Back", 2.0, (0.5, 2, 0.3), unlit_material("Red", (0.9, 0.1, 0.1, 1.0)))
    glass = unlit_material("Glass", (0.2, 0.6, 1.0, 0.5))
    with bpy.context.temp_override(material=glass):
        bpy.ops.unity.apply_preset(preset="Alpha Blend Both Sided")
    add_cube("Glass", 2.0, (-0.5, 0, 0), glass)
    cam = scene.camera
    cam.location = (2.0, -7.0, 1.5)
    cam.rotation_euler = (math.radians(80), 0.0, math.radians(12))
    return scene


def camera_matrices(scene):
    cam = scene.camera
    depsgraph = bpy.context.evaluated_depsgraph_get()
    w, h = blender.render_size(scene)
    proj = cam.calc_matrix_camera(depsgraph, x=w, y=h, scale_x=1.0, scale_y=1.0)
    return cam.matrix_world.inverted(), proj, w, h


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_render_view_equals_f12_through_the_camera(kind):
    scene = glass_scene()
    if kind == "ORTHO":
        scene.camera.data.type = "ORTHO"
        scene.camera.data.ortho_scale = 6.0
    view, proj, w, h = camera_matrices(scene)
    f12 = blender.render_final(scene)
    before = snapshot()
    got = render_view(scene, view, proj, w, h)
    assert snapshot() == before
    np.testing.assert_array_equal(got.color, f12.color)
    np.testing.assert_array_equal(got.depth, f12.depth)
    np.testing.assert_array_equal(got.stencil, f12.stencil)
    assert len(np.unique(got.color.reshape(-1, 4), axis=0)) >= 3  # clear, red, glass over red ...
    # numpy arrays and nested lists are the same view
    again = render_view(scene, np.array(view), [list(r) for r in proj], w, h)
    np.testing.assert_array_equal(again.color, f12.color)


def test_ortho_projection_sorts_orthographically():
    """Default sort mode follows the projection: bottom row (0, 0, 0, 1) → orthographic."""
    scene = glass_scene()
    scene.camera.data.type = "ORTHO"
    view, proj, w, h = camera_matrices(scene)
    assert viewport.is_orthographic(np.array(proj))
    template = viewport.extract_template(scene)
    assert viewport.camera_from_matrices(view, proj, w, h).orthographic
    assert not viewport.camera_from_matrices(view, perspective(50, w / h), w, h).orthographic
    assert template.camera is viewport.PLACEHOLDER_CAMERA


def test_free_view_without_camera_and_scene_unchanged():
    scene = glass_scene(48, 36)
    bpy.data.objects.remove(scene.camera)
    assert scene.camera is None
    with pytest.raises(SceneError, match="no camera"):
        blender.render(scene)
    frame_before, res_before = scene.frame_current, (scene.render.resolution_x, scene.render.resolution_y)
    bpy.context.view_layer.update()  # the new objects' matrix_world, before the snapshot
    before = snapshot()
    view = Matrix([list(r) for r in look_at((4, -6, 3), (0, 0, 0), (0, 0, 1))])
    got = render_view(scene, view, perspective(45, 64 / 40, 0.1, 50), 64, 40)
    assert got.color.shape == (40, 64, 4)
    assert snapshot() == before
    assert scene.camera is None and scene.frame_current == frame_before
    assert (scene.render.resolution_x, scene.render.resolution_y) == res_before
    clear = got.color[0, 0]
    assert np.any(np.abs(got.color - clear) > 1e-6, axis=2).mean() > 0.1  # the cubes are in view


def test_viewport_visibility():
    """Objects show as the viewport shows them: hidden in the viewport → not drawn, even though
    F12 would draw them; disabled for renders only → drawn."""
    scene = glass_scene()
    view, proj, w, h = camera_matrices(scene)
    full = render_view(scene, view, proj, w, h)
    bpy.data.objects["Glass"].hide_set(True)
    hidden = render_view(scene, view, proj, w, h)
    assert not np.array_equal(hidden.color, full.color)
    bpy.data.objects["Glass"].hide_set(False)
    bpy.data.objects["Glass"].hide_render = True
    np.testing.assert_array_equal(render_view(scene, view, proj, w, h).color, full.color)


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_render_view_agrees_with_opengl_reference(projection):
    """A free view of an example scene against the OpenGL reference, as the example-scene GL test
    checks (llvmpipe rounds each blended layer: within one step on 99 % of pixels)."""
    from tests.reference.glref import render_gl

    goldens.ensure_addon()
    bpy.ops.wm.open_mainfile(filepath=str(goldens.BLEND_DIR / "two_sided.blend"), load_ui=False)
    scene = bpy.context.scene
    w, h = 160, 100
    view = look_at((3.0, -6.0, 2.5), (0, 0, 0), (0, 0, 1))
    proj = perspective(50, w / h, 0.1, 100) if projection == "perspective" else orthographic(6.4, 4.0, 0.1, 100)
    frame = render_view(scene, view, proj, w, h)
    draw = dataclasses.replace(viewport.extract_template(scene),
                               camera=viewport.camera_from_matrices(view, proj, w, h))
    gl_color, _, _ = render_gl(draw)
    gl = np.rint(np.asarray(gl_color, np.float64) * 255).astype(np.int64)
    ours = np.rint(frame.color.astype(np.float64) * 255).astype(np.int64)
    diff = np.abs(gl - ours).max(axis=2)
    assert (diff <= 1).mean() >= 0.99, f"{(diff > 1).sum()} pixels off by more than one step"
    assert (diff > 3).mean() <= 0.002
    assert np.any(ours != ours[0, 0], axis=2).mean() > 0.1  # the scene is in view
