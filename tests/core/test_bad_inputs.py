"""Bad input to the core: skipped with a warning, or refused with a one-line SceneError."""

from __future__ import annotations

import time
import tracemalloc
import warnings

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core.scene import Camera, DrawScene, Mesh, SceneError
from blendlib.core.vocabulary import Cull, Lighting, Material, Pass, Texture, TextureFilter
from tests.reference import scenes as sc
from tests.reference.scalar import render_reference

RED = Material(color=(1, 0, 0, 1), lighting=Lighting.Unlit, passes=(Pass(cull=Cull.Off),))


def _render(scene):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # numpy noise on inf/nan inputs is not the point here
        return render_scene(scene)


def _same_as_reference(frame, scene):
    c, d, s = render_reference(scene)
    assert np.array_equal(frame.color, c) and np.array_equal(frame.depth, d) and np.array_equal(frame.stencil, s)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 1e300])
def test_non_finite_vertices_skipped_with_warning(bad):
    """A triangle with a NaN/inf vertex (or, 1e300 under a 1e10 scale, one whose clip coordinates
    overflow) is skipped and named in Frame.warnings; the good triangles of the same mesh render
    exactly as without it."""
    k = 1e-10 if bad == 1e300 else 1.0  # positions scaled down, matrix scales them back up
    pos = [(k * 1, k * 1, 0), (k * 7, k * 1, 0), (k * 7, k * 7, 0), (k * 1, k * 7, 0), (k * 4, bad, 0)]
    tri = [(0, 1, 2), (0, 4, 3), (0, 2, 3)]
    mesh = sc.make_mesh(np.nan_to_num(np.array(pos, float), nan=0, posinf=0, neginf=0), tri)
    mesh = Mesh(np.array(pos, dtype=np.float64), mesh.triangles, mesh.normals, None)
    matrix = sc.scale(1 / k, 1 / k, 1.0)
    r = sc.renderer(mesh, RED, name="Broken", matrix=matrix)
    r = type(r)(r.name, r.slot, r.mesh, r.matrix_world, r.material, np.array([4.0, 4.0, 0.0]))
    scene = sc.scene(sc.screen_camera(8, 8), r)
    frame = _render(scene)
    assert any("Broken" in w and "1" in w for w in frame.warnings), frame.warnings
    good = sc.make_mesh(np.array(pos[:4], float), [(0, 1, 2), (0, 2, 3)])
    frame_good = render_scene(sc.scene(sc.screen_camera(8, 8), sc.renderer(good, RED, name="Broken",
                                                                           matrix=matrix)))
    assert np.array_equal(frame.color, frame_good.color)
    assert np.array_equal(frame.depth, frame_good.depth)
    assert np.count_nonzero(frame.depth < 1) == 36
    _same_as_reference(frame, scene)


def test_non_finite_normals_and_uvs_do_not_crash():
    """A NaN normal or uv on a finite triangle: the frame renders (texel (0,0) for a non-finite uv)."""
    tex = Texture(np.array([[[0.2, 0.4, 0.6, 1.0], [0.9, 0.9, 0.9, 1.0]]], np.float32), encoding="Data")
    mat = Material(main_tex=tex, main_tex_filter=TextureFilter.Point, lighting=Lighting.Unlit,
                   passes=(Pass(cull=Cull.Off),))
    m = sc.quad(0, 0, 4, 4)
    uvs = np.array(m.uvs)
    uvs[:, :, :] = np.nan
    mesh = Mesh(m.positions, m.triangles, m.normals, uvs.astype(np.float32))
    scene = sc.scene(sc.screen_camera(4, 4), sc.renderer(mesh, mat))
    frame = render_scene(scene)
    assert np.allclose(frame.color[..., :3], np.float32(np.rint(np.array([0.2, 0.4, 0.6]) * 255) / 255))
    _same_as_reference(frame, scene)


def test_zero_area_triangles_draw_nothing():
    pos = [(1, 1, 0), (5, 5, 0), (3, 3, 0), (6, 2, 0), (6.001, 2.001, 0)]
    tri = [(0, 1, 2), (0, 0, 1), (3, 3, 3), (3, 4, 0)]  # collinear, repeated, a point, a sliver < 1/256
    scene = sc.scene(sc.screen_camera(8, 8), sc.renderer(sc.make_mesh(pos, tri), RED, name="Flat"))
    frame = _render(scene)
    assert np.all(frame.depth == 1.0) and np.all(frame.stencil == 0)
    assert np.all(frame.color == frame.color[0, 0])
    _same_as_reference(frame, scene)


def test_degenerate_triangles_summarised_in_one_warning():
    """Zero-area triangles in two objects: one warning line with the total and the names."""
    pos = [(1, 1, 0), (5, 5, 0), (3, 3, 0), (1, 5, 0), (4, 5, 0), (1, 8, 0)]
    tri = [(0, 1, 2), (0, 0, 1), (3, 4, 5)]  # collinear, repeated vertex, and one good triangle
    scene = sc.scene(sc.screen_camera(8, 8), sc.renderer(sc.make_mesh(pos, tri), RED, name="Flat A"),
                     sc.renderer(sc.make_mesh(pos, tri[:1]), RED, name="Flat B"))
    frame = _render(scene)
    lines = [w for w in frame.warnings if "degenerate" in w]
    assert lines == ["3 degenerate (zero-area) triangles draw nothing, in 'Flat A', 'Flat B'"], frame.warnings
    assert np.count_nonzero(frame.depth < 1) > 0  # the good triangle still renders
    _same_as_reference(frame, scene)


def test_empty_mesh_warns_and_renders_clear():
    empty = Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3, 3), np.float32))
    scene = sc.scene(sc.screen_camera(6, 4), sc.renderer(empty, RED, name="Empty"),
                     clear_color=(0.1, 0.2, 0.3, 0.4))
    frame = _render(scene)
    assert any("Empty" in w and "empty" in w.lower() for w in frame.warnings), frame.warnings
    assert np.array_equal(frame.color[0, 0], np.float32(np.floor(np.array([0.1, 0.2, 0.3, 0.4]) * 255 + 0.5) / 255))
    assert np.all(frame.depth == 1.0)
    _same_as_reference(frame, scene)


def test_no_renderers_renders_clear():
    frame = _render(DrawScene(camera=sc.screen_camera(3, 2)))
    assert frame.color.shape == (2, 3, 4) and frame.depth.shape == (2, 3) and frame.stencil.shape == (2, 3)


def test_everything_behind_the_camera():
    cam = sc.camera(8, 8, eye=(0, 0, 5))
    scene = sc.scene(cam, sc.renderer(sc.cube(1.0), RED, matrix=sc.translate(z=9)))
    frame = _render(scene)
    assert np.all(frame.depth == 1.0)
    _same_as_reference(frame, scene)


@pytest.mark.parametrize("shape", [(0, 0, 4), (0, 3, 4), (3, 0, 4), (2, 2, 3), (4, 4)])
def test_texture_of_size_zero_or_bad_shape_raises(shape):
    with pytest.raises(ValueError):
        Texture(np.zeros(shape, np.float32))


@pytest.mark.parametrize("size", [(100_000, 100_000), (65537, 1), (1, 70000), (20000, 20000)])
def test_absurd_resolution_refused_before_allocating(size):
    w, h = size
    cam = Camera(np.eye(4), sc.perspective(50, 1.0), w, h)
    scene = sc.scene(cam, sc.renderer(sc.cube(), RED))
    tracemalloc.start()
    t = time.perf_counter()
    try:
        with pytest.raises(SceneError) as info:
            render_scene(scene)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert time.perf_counter() - t < 1.0
    assert peak < 50 * 2**20, f"allocated {peak / 2**20:.0f} MiB before refusing"
    message = str(info.value)
    assert "\n" not in message and "resolution" in message


@pytest.mark.parametrize("size", [(0, 8), (8, 0), (-1, 4)])
def test_empty_resolution_refused(size):
    cam = Camera(np.eye(4), sc.perspective(50, 1.0), *size)
    with pytest.raises(SceneError) as info:
        render_scene(DrawScene(camera=cam))
    assert "\n" not in str(info.value)


def test_non_finite_matrices_refused():
    bad = np.eye(4)
    bad[0, 3] = np.nan
    with pytest.raises(SceneError):
        render_scene(sc.scene(sc.screen_camera(4, 4), sc.renderer(sc.cube(), RED, matrix=bad)))
    cam = Camera(bad, sc.perspective(50, 1.0), 4, 4)
    with pytest.raises(SceneError):
        render_scene(DrawScene(camera=cam))


def test_out_of_range_indices_refused():
    mesh = Mesh(np.zeros((3, 3)), np.array([[0, 1, 3]]), np.zeros((1, 3, 3), np.float32))
    with pytest.raises(SceneError) as info:
        render_scene(sc.scene(sc.screen_camera(4, 4), sc.renderer(mesh, RED, name="Idx")))
    assert "Idx" in str(info.value) and "\n" not in str(info.value)
