"""Reference 1 (tests/reference/scalar.py): the vectorised core equals the scalar reference bit for bit.

``tests/reference/scalar.py`` is docs/pipeline.md written one fragment at a time in
plain Python. Random scenes (hypothesis) and every structured state sweep must give
*identical* colour, depth and stencil buffers (``np.array_equal``, no tolerance).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from blendlib import render_scene
from blendlib.core.vocabulary import BlendFactor, Material, Pass, Queue, SortMode, preset
from tests.reference import scenes as sc
from tests.reference.random_scenes import describe, scenes, seeded_scene
from tests.reference.scalar import draw_list, render_reference
from tests.reference.sweeps import SWEEPS

PROPERTY = settings(max_examples=120, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def assert_same(scene):
    """Core frame == scalar reference, bit for bit; the message names the first differing pixels.

    Two worker threads (screen bands), as large frames render: these small frames would otherwise
    render in one thread by default (``SMALL_FRAME_PIXELS``)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        frame = render_scene(scene, workers=2)
    color, depth, stencil = render_reference(scene)
    assert frame.color.dtype == np.float32 and frame.depth.dtype == np.float32 and frame.stencil.dtype == np.uint8
    assert frame.color.shape == color.shape and frame.depth.shape == depth.shape
    problems = []
    for name, ours, ref in (("color", frame.color, color), ("depth", frame.depth, depth),
                            ("stencil", frame.stencil, stencil)):
        if not np.array_equal(ours, ref):
            diff = ours != ref
            if diff.ndim == 3:
                diff = diff.any(axis=-1)
            ys, xs = np.nonzero(diff)
            where = ", ".join(f"(row {y}, col {x}): core {ours[y, x].tolist()} reference {ref[y, x].tolist()}"
                              for y, x in list(zip(ys, xs, strict=True))[:5])
            problems.append(f"{name}: {int(diff.sum())} pixels differ; {where}")
    assert not problems, "\n".join(problems) + "\n" + describe(scene)
    return frame


@PROPERTY
@given(scenes())
def test_random_scenes_equal_reference(scene):
    """Shared vertices: shared edges, duplicate / degenerate / coincident triangles, self-overlap."""
    assert_same(scene)


@settings(PROPERTY, max_examples=80)
@given(scenes(shared=False))
def test_random_scenes_distinct_triangles_equal_reference(scene):
    assert_same(scene)


@settings(PROPERTY, max_examples=100)
@given(scenes(features=True))
def test_random_scenes_with_lights_vertex_colours_mipmaps_and_outlines_equal_reference(scene):
    """SPEC §12's features and the outline vertex program: ForwardAdd draws per light (directional,
    point, spot), every LightMode, vertex colours Off / Multiply / Particle, mipmapped textures with
    every filter and Preserve Coverage, outlines in World and Screen mode of both MToon formulas."""
    assert_same(scene)


@pytest.mark.parametrize("seed", range(0, 240, 4))
def test_seeded_scenes_with_features_equal_reference(seed):
    assert_same(seeded_scene(seed, shared=False, features=True))


@pytest.mark.parametrize("seed", range(0, 400, 8))
def test_seeded_scenes_equal_reference(seed):
    """A fixed batch as well (stable across runs; the hypothesis tests explore new scenes)."""
    assert_same(seeded_scene(seed))


@pytest.mark.parametrize("name", list(SWEEPS))
def test_sweeps_equal_reference(name):
    """Every value of every pass state (see tests/reference/sweeps.py)."""
    assert_same(SWEEPS[name]())


def test_near_plane_crossing_is_clipped_not_dropped():
    """A big floor quad that runs under the camera: clipped at the near plane, its visible part drawn."""
    cam = sc.camera(24, 16, eye=(0, 1, 0), target=(0, 0.5, -5), near=0.5, far=30)
    floor = sc.make_mesh([(-5, 0, 5), (5, 0, 5), (5, 0, -20), (-5, 0, -20)], [(0, 1, 2), (0, 2, 3)],
                         uvs=[[(0, 0), (1, 0), (1, 1)], [(0, 0), (1, 1), (0, 1)]])
    scene = sc.scene(cam, sc.renderer(floor, sc.unlit((0.9, 0.5, 0.1, 1.0))))
    frame = assert_same(scene)
    assert np.count_nonzero(frame.depth < 1.0) > 24 * 3  # the floor fills the bottom rows


@pytest.mark.parametrize("mode", list(SortMode))
def test_sort_modes_equal_reference(mode):
    """Transparent renderers at different distances; every sort mode orders them as the reference."""
    q, passes = preset("Alpha Blend")
    rs = [sc.renderer(sc.quad(-1, -1, 1, 1), Material(name=f"m{k}", queue=q, passes=passes,
                                                      color=(k / 5, 1 - k / 5, 0.5, 0.5)),
                      name=f"obj{k}", matrix=sc.translate(k * 0.3 - 0.6, k * 0.1, -k * 0.7 + (k % 2) * 1.1))
          for k in range(5)]
    scene = sc.scene(sc.camera(16, 16, eye=(0.5, 0.8, 5)), *rs, sort_mode=mode, sort_axis=(0.3, -0.2, 1.0))
    assert_same(scene)


def test_draw_list_order_rules():
    """Reference draw order: queue ascending; opaque front to back; transparent back to front;
    ties by name, then slot."""
    cam = sc.camera(8, 8, eye=(0, 0, 10))
    opaque = Material(name="o")
    transparent = Material(name="t", queue=Queue.Transparent)
    overlay = Material(name="v", queue=Queue.Overlay, queue_offset=-1000)  # 3000: same queue as Transparent
    rs = [
        sc.renderer(sc.quad(0, 0, 1, 1), transparent, name="T_near", matrix=sc.translate(z=2)),
        sc.renderer(sc.quad(0, 0, 1, 1), transparent, name="T_far", matrix=sc.translate(z=-2)),
        sc.renderer(sc.quad(0, 0, 1, 1), opaque, name="O_far", matrix=sc.translate(z=-2)),
        sc.renderer(sc.quad(0, 0, 1, 1), opaque, name="O_near", matrix=sc.translate(z=2)),
        sc.renderer(sc.quad(0, 0, 1, 1), overlay, name="B_tie", slot=1),
        sc.renderer(sc.quad(0, 0, 1, 1), overlay, name="B_tie", slot=0),
        sc.renderer(sc.quad(0, 0, 1, 1), Material(name="bg", queue=Queue.Background), name="Z_bg"),
    ]
    scene = sc.scene(cam, *rs)
    order = [(r.name, r.slot) for r in draw_list(scene)]
    assert order == [("Z_bg", 0), ("O_near", 0), ("O_far", 0), ("T_far", 0), ("B_tie", 0), ("B_tie", 1),
                     ("T_near", 0)]


def test_multi_pass_and_default_pass():
    """An empty pass tuple draws one default pass; multi-pass materials draw in order."""
    cam = sc.screen_camera(8, 8)
    m0 = Material(color=(0.3, 0.6, 0.9, 1.0), passes=())
    m1 = Material(color=(0.3, 0.6, 0.9, 0.5), passes=(Pass(), Pass(blend=True, src_blend=BlendFactor.DstColor)))
    assert_same(sc.scene(cam, sc.renderer(sc.quad(1, 1, 7, 7), m0, name="a"),
                         sc.renderer(sc.quad(2, 0, 8, 5, z=0.5), m1, name="b")))
