"""The engine's viewport (view_update / view_draw) headless, with the gpu drawing replaced.

A stand-in region and RegionView3D carry the matrices Blender would give; the drawing
function records what it was asked to draw.
"""

from __future__ import annotations

import math
import threading
from types import SimpleNamespace

import bpy
import numpy as np
import pytest
from mathutils import Matrix

import addon
from addon.engine import render as engine
from addon.engine import viewport
from blendlib import blender, render_view
from tests.reference.scenes import look_at, perspective
from tests.support.blender_fixtures import add_cube, empty_scene, unlit_material

WAIT = 60.0


@pytest.fixture(autouse=True)
def registered():
    addon.register()
    yield
    addon.unregister()


class FakeEngine:
    def __init__(self):
        self.stats = []

    def update_stats(self, a, b):
        self.stats.append(b)


class Drawn:
    def __init__(self):
        self.calls = []

    def __call__(self, engine, scene, pixels, size, rect):
        self.calls.append((pixels.copy(), size, rect))


def scene_with_cubes():
    scene = empty_scene(40, 30)
    scene.render.engine = "UNITY_PASSES"
    add_cube("Back", 2.0, (0.5, 2, 0.3), unlit_material("Red", (0.9, 0.1, 0.1, 1.0)))
    add_cube("Front", 1.0, (-0.5, 0, 0), unlit_material("Blue", (0.1, 0.2, 0.9, 1.0)))
    return scene


def region(width, height, view, window, perspective_kind="PERSP"):
    view, window = Matrix([list(r) for r in view]), Matrix([list(r) for r in window])
    data = SimpleNamespace(view_perspective=perspective_kind, view_matrix=view, window_matrix=window,
                           perspective_matrix=window @ view)
    return SimpleNamespace(region=SimpleNamespace(width=width, height=height), region_data=data)


def test_engine_has_viewport_methods():
    cls = engine.UnityPassesRenderEngine
    assert callable(cls.view_update) and callable(cls.view_draw)


def test_free_view_reduced_then_full_and_equal_to_render_view():
    scene = scene_with_cubes()
    redraws = []
    session = viewport.ViewportSession(lambda: redraws.append(1))
    # the worker waits for the test's first draw to return, so "nothing ready yet" cannot race
    # with a fast first frame; the scheduler's own renderer still draws every frame
    first_draw_returned = threading.Event()
    own_render = session.scheduler._render

    def gated_render(scene, **kwargs):
        assert first_draw_returned.wait(WAIT)
        return own_render(scene, **kwargs)

    session.scheduler._render = gated_render
    drawn, fake = Drawn(), FakeEngine()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    view, proj = look_at((3, -7, 2), (0, 0, 0), (0, 0, 1)), perspective(50, 200 / 150, 0.1, 100)
    ctx = region(200, 150, view, proj)
    try:
        session.update(depsgraph)
        assert session.draw(fake, ctx, depsgraph, draw=drawn) is False  # submitted; nothing ready yet
        first_draw_returned.set()
        assert session.scheduler.wait_idle(WAIT)
        assert len(redraws) == 2  # reduced frame, then full: a redraw after each
        assert session.draw(fake, ctx, depsgraph, draw=drawn) is True
        pixels, size, rect = drawn.calls[-1]
        assert size == (200, 150) and rect == (0, 0, 200, 150)
        expected = render_view(scene, view, proj, 200, 150)
        np.testing.assert_array_equal(pixels, viewport.display_pixels(expected))
        # F12's Combined pass and the viewport get the same linear values (alpha 1)
        from addon.engine.render import result_arrays

        np.testing.assert_array_equal(pixels.reshape(-1, 4), result_arrays(expected)["Combined"])
        # same view, same scene: nothing new is rendered
        session.draw(fake, ctx, depsgraph, draw=drawn)
        assert not session.scheduler.busy and len(redraws) == 2
        # the view changes (orbit): new work
        ctx2 = region(200, 150, look_at((-3, -7, 2), (0, 0, 0), (0, 0, 1)), proj)
        session.draw(fake, ctx2, depsgraph, draw=drawn)
        assert session.scheduler.wait_idle(WAIT) and len(redraws) == 4
        # the scene changes (view_update): new work, and the frame shows the change
        before = {r.name: r for r in session.template.renderers}
        bpy.data.objects["Front"].location.x += 1.0
        depsgraph = bpy.context.evaluated_depsgraph_get()
        session.update(depsgraph)
        # what did not change is the previous template's very objects (memos carry over)
        after = {r.name: r for r in session.template.renderers}
        assert after["Back"] is before["Back"]
        assert after["Front"] is not before["Front"]
        assert after["Front"].mesh is before["Front"].mesh and after["Front"].material is before["Front"].material
        session.draw(fake, ctx2, depsgraph, draw=drawn)
        assert session.scheduler.wait_idle(WAIT) and len(redraws) == 6
        session.draw(fake, ctx2, depsgraph, draw=drawn)
        moved = render_view(scene, look_at((-3, -7, 2), (0, 0, 0), (0, 0, 1)), proj, 200, 150)
        np.testing.assert_array_equal(drawn.calls[-1][0], viewport.display_pixels(moved))
    finally:
        first_draw_returned.set()
        session.close()
    assert fake.stats == []


def test_camera_view_renders_the_camera_frame_only():
    scene = scene_with_cubes()
    cam = scene.camera
    cam.rotation_euler = (math.radians(85), 0.0, math.radians(5))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    proj = cam.calc_matrix_camera(depsgraph, x=40, y=30, scale_x=1.0, scale_y=1.0)
    view = cam.matrix_world.inverted()
    # a viewport through the camera, zoomed out so the frame covers the middle half of the region
    window = Matrix.Diagonal((0.5, 0.5, 1.0, 1.0)) @ proj
    ctx = region(240, 180, view, window, "CAMERA")
    request = blender.viewport.region_view(scene, depsgraph, ctx.region, ctx.region_data)
    assert (request.x, request.y, request.width, request.height) == (60, 45, 120, 90)
    drawn = Drawn()
    session = viewport.ViewportSession(lambda: None)
    try:
        session.update(depsgraph)
        session.draw(FakeEngine(), ctx, depsgraph, draw=drawn)
        assert session.scheduler.wait_idle(WAIT)
        session.draw(FakeEngine(), ctx, depsgraph, draw=drawn)
    finally:
        session.close()
    pixels, size, rect = drawn.calls[-1]
    assert size == (120, 90) and rect == (60, 45, 120, 90)
    expected = render_view(scene, view, proj, 120, 90)  # F12's projection at the frame's size
    np.testing.assert_array_equal(pixels, viewport.display_pixels(expected))


def test_scene_errors_are_shown_not_raised():
    scene = scene_with_cubes()
    blender.write_scene_settings(scene, sort_mode="CustomAxis", sort_axis=(0.0, 0.0, 0.0))  # cannot sort
    depsgraph = bpy.context.evaluated_depsgraph_get()
    ctx = region(64, 48, look_at((3, -7, 2), (0, 0, 0), (0, 0, 1)), perspective(50, 4 / 3))
    fake = FakeEngine()
    session = viewport.ViewportSession(lambda: None)
    try:
        session.update(depsgraph)
        session.draw(fake, ctx, depsgraph, draw=Drawn())
        assert session.scheduler.wait_idle(WAIT)
        assert session.draw(fake, ctx, depsgraph, draw=Drawn()) is False
    finally:
        session.close()
    assert fake.stats and "Unity Passes:" in fake.stats[-1] and "sort_axis" in fake.stats[-1]
    assert scene.camera is not None
