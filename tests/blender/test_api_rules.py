"""The Python API's rules (README "Python API with Blender", blendlib/blender/render.py): what renders
or explains a scene's frame sees F12's evaluation unless given a depsgraph; ``until_draw`` is an
integer within the draw list; a scene may be named; ``render_view`` refuses matrices that cannot
show anything; results print short."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

import addon
import blendlib
from blendlib import blender
from blendlib.blender.render import CAPTURE_SLOT
from blendlib.core.scene import SceneError
from tests.support.blender_fixtures import add_cube, empty_scene, unlit_material


@pytest.fixture()
def rounded():
    """A cube with a Subdivision modifier at viewport level 0 and render level 2: the
    viewport shows 12 triangles, F12 renders 6 x 16 x 2 = 192 (a rounder, smaller silhouette)."""
    scene = empty_scene(40, 30)
    mat = unlit_material("Solid", (0.9, 0.3, 0.1, 1.0))
    cube = add_cube("Cube", 3.0, material=mat)
    mod = cube.modifiers.new("Subdivision", "SUBSURF")
    mod.levels, mod.render_levels = 0, 2
    return scene


def viewport_depsgraph():
    return bpy.context.evaluated_depsgraph_get()


def test_the_tools_that_explain_a_frame_see_f12s_geometry(rounded):
    """Before, draw_list and pixel_history (and the Frame Debugger's Capture, and render) used the
    viewport's evaluation: 12 triangles and another frame than F12's 192."""
    f12 = blender.render_final(rounded)
    assert np.array_equal(blendlib.render(rounded).color, f12.color)
    viewport = blendlib.render(rounded, depsgraph=viewport_depsgraph())
    changed = np.argwhere((viewport.color != f12.color).any(axis=2))
    assert len(changed) > 20  # the level-0 cube's corners
    [stats] = blendlib.draw_list(rounded)
    [shown] = blendlib.draw_list(rounded, depsgraph=viewport_depsgraph())
    assert (stats.call.renderer.mesh.triangles.shape[0], shown.call.renderer.mesh.triangles.shape[0]) == (192, 12)
    y, x = (int(v) for v in changed[0])
    covered_only_in_viewport = not (f12.color[y, x] != f12.color[0, 0]).any()
    history = blendlib.pixel_history(rounded, x, y)
    seen = blendlib.pixel_history(rounded, x, y, depsgraph=viewport_depsgraph())
    assert (len(history.fragments) == 0) == covered_only_in_viewport
    assert len(seen.fragments) != len(history.fragments)


def test_the_frame_debuggers_capture_sees_f12s_geometry(rounded):
    addon.register()
    try:
        assert bpy.ops.unity.frame_debugger_capture() == {"FINISHED"}
        from addon.frame_debugger.ops import current_capture

        cap = current_capture(rounded)
        assert cap.scene.renderers[0].mesh.triangles.shape[0] == 192
    finally:
        addon.unregister()


def test_until_draw_is_an_integer_within_the_draw_list(rounded):
    """Before, 1.5 was truncated to draw 1 and a number beyond the draw list gave the whole frame."""
    cleared = blendlib.render(rounded, until_draw=np.int64(0))
    assert (cleared.color == cleared.color[0, 0]).all()
    for bad in (1.5, True, "1"):
        with pytest.raises(TypeError, match="until_draw must be an integer"):
            blendlib.render(rounded, until_draw=bad)
    with pytest.raises(SceneError, match="until_draw 2 is beyond the last draw call: the frame has 1"):
        blendlib.render(rounded, until_draw=2)
    with pytest.raises(SceneError, match="until_draw must be 0 or more"):
        blendlib.render(rounded, until_draw=-1)


def test_a_scene_may_be_given_by_name(rounded):
    """Before, render_view("Scene", ...) raised AttributeError."""
    np.testing.assert_array_equal(blendlib.render(rounded.name).color, blendlib.render(rounded).color)
    view = np.eye(4)
    view[2, 3] = -8.0
    proj = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, -1.0, -0.2], [0, 0, -1.0, 0]])
    frame = blendlib.render_view(rounded.name, view, proj, 20, 10)
    assert frame.color.shape == (10, 20, 4)
    with pytest.raises(SceneError, match="no scene named 'Nope'"):
        blendlib.render("Nope")
    with pytest.raises(TypeError, match="scene must be a bpy.types.Scene, a scene's name or None, got int"):
        blendlib.render(42)


def test_render_view_refuses_matrices_that_show_nothing(rounded):
    """Before, a complex matrix was taken without its imaginary parts, and an all-zero projection
    drew a blank frame without a word."""
    view = np.eye(4)
    view[2, 3] = -8.0
    proj = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, -1.0, -0.2], [0, 0, -1.0, 0]])
    with pytest.raises(SceneError, match="view_matrix: must be a real 4x4 matrix, got complex values"):
        blendlib.render_view(rounded, view + 1j, proj, 20, 10)
    with pytest.raises(SceneError, match="projection_matrix is singular"):
        blendlib.render_view(rounded, view, np.zeros((4, 4)), 20, 10)
    flat = proj.copy()
    flat[1] = flat[0]  # two equal rows: every vertex on one line
    with pytest.raises(SceneError, match="projection_matrix is singular"):
        blendlib.render_view(rounded, view, flat, 20, 10)


def test_results_print_short(rounded):
    """Before, repr() of a DrawStats or an analysis printed whole meshes and image arrays."""
    [stats] = blendlib.draw_list(rounded)
    assert repr(stats) == (f"DrawStats(call=1, object='Cube', slot=0, pass=0, queue=2000, triangles={stats.triangles}, "
                           f"fragments={stats.fragments}, written={stats.written})")
    text = repr(blendlib.analyze(rounded, advice=False))
    assert text.startswith("Analysis(40x30, differing=0, max_error=0, inversions=0") and len(text) < 120


def test_the_users_render_result_is_kept(rounded):
    """render() runs Blender's render operator: it adds no image, and an F12 result stays active."""
    blender.render_final(rounded)
    assert [i for i in bpy.data.images if i.type == "RENDER_RESULT"] == []
    addon.register()
    try:
        rounded.render.engine = "UNITY_PASSES"
        assert bpy.ops.render.render() == {"FINISHED"}  # the user's F12
        [result] = [i for i in bpy.data.images if i.type == "RENDER_RESULT"]
        result.render_slots.active_index = 2
        slots = len(result.render_slots)
        for _ in range(2):
            blendlib.render(rounded)
            assert result.render_slots.active_index == 2 and len(result.render_slots) == slots + 1
        assert result.render_slots[slots].name == CAPTURE_SLOT
    finally:
        addon.unregister()
