"""Watertightness: a pixel on an edge shared by two triangles is covered exactly once (docs/pipeline.md §4).

Counting set-ups: HDR Additive of a constant 1/8 (exact in float32, so n coverages
give exactly n/8) and a stencil ``IncrWrap`` counter. A closed convex mesh seen from
outside covers every pixel of its silhouette exactly twice with Cull Off (one front,
one back face) and exactly once with Cull Back or Cull Front. A flat fan around a
shared vertex and a jittered grid whose outer boundary lies on pixel boundaries
cover every pixel of their outline exactly once. Checked on the core and on the
scalar reference.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core.vocabulary import BlendFactor, CompareFunction, Cull, Lighting, Material, Pass, Queue, StencilOp
from tests.reference import scenes as sc
from tests.reference.scalar import render_reference


def _core(scene):
    f = render_scene(scene)
    return f.color, f.depth, f.stencil


IMPLS = {"core": _core, "reference": render_reference}
impl = pytest.fixture(params=list(IMPLS))(lambda request: IMPLS[request.param])


def _counter(cull: Cull) -> Material:
    p = Pass(cull=cull, zwrite=False, ztest=CompareFunction.Always, blend=True, src_blend=BlendFactor.One,
             dst_blend=BlendFactor.One,
             stencil=True, stencil_comp=CompareFunction.Always, stencil_pass=StencilOp.IncrWrap)
    return Material(color=(0.125, 0.125, 0.125, 0.125), queue=Queue.Transparent, passes=(p,),
                    lighting=Lighting.Unlit)


def _count(impl, cam, mesh, cull, matrix=None):
    scene = sc.scene(cam, sc.renderer(mesh, _counter(cull), matrix=matrix), hdr=True, clear_color=(0, 0, 0, 0))
    color, _, stencil = impl(scene)
    counts = color[..., 0] * 8
    assert np.all(counts == np.round(counts)), "a pixel got a fraction of a coverage"
    counts = counts.astype(int)
    assert np.array_equal(counts, stencil.astype(int)), "blend count and stencil count disagree"
    assert np.all(color[..., 0] == color[..., 3])
    return counts


VIEWS = [(2.2, 1.7, 3.0), (-3.1, 0.4, 1.3), (0.3, -2.9, 2.2), (0.01, 0.02, 3.5)]
CLOSED = {
    "cube": lambda: sc.cube(1.7),
    "sphere": lambda: sc.uv_sphere(1.1, segments=13, rings=9),
    "sphere_fine": lambda: sc.uv_sphere(1.1, segments=24, rings=16),
}


@pytest.mark.parametrize("shape", list(CLOSED))
@pytest.mark.parametrize("eye", VIEWS)
def test_closed_convex_mesh_counts(impl, shape, eye):
    cam = sc.camera(40, 32, eye=eye, fov=45)
    mesh = CLOSED[shape]()
    off = _count(impl, cam, mesh, Cull.Off)
    back = _count(impl, cam, mesh, Cull.Back)
    front = _count(impl, cam, mesh, Cull.Front)
    silhouette = off > 0
    assert silhouette.sum() > 150
    assert set(np.unique(off)) <= {0, 2}, f"Cull Off counts {np.unique(off, return_counts=True)}"
    assert np.array_equal(back, silhouette.astype(int)), "front faces: gap or double coverage"
    assert np.array_equal(front, silhouette.astype(int)), "back faces: gap or double coverage"


def test_mirrored_closed_mesh_counts(impl):
    """Negative scale: faces keep their sides (Cull Back still shows the outside exactly once)."""
    cam = sc.camera(32, 32, eye=(2.0, 1.5, 3.0))
    mesh = sc.uv_sphere(1.0, segments=11, rings=7)
    matrix = sc.scale(-1.0, 1.0, 1.0)
    off = _count(impl, cam, mesh, Cull.Off, matrix)
    back = _count(impl, cam, mesh, Cull.Back, matrix)
    assert set(np.unique(off)) == {0, 2}
    assert np.array_equal(back, (off > 0).astype(int))


@pytest.mark.parametrize("count", [5, 7, 16, 33])
def test_fan_around_a_vertex(impl, count):
    """A flat disc of triangles sharing the centre vertex: every covered pixel exactly once, including
    the pixels on the spokes and at the centre; the covered area is close to the disc's."""
    cam = sc.screen_camera(32, 32)
    mesh = sc.fan(center=(16.0, 16.0, 0.0), radius=12.3, count=count, phase=0.37)
    counts = _count(impl, cam, mesh, Cull.Off)
    assert set(np.unique(counts)) == {0, 1}
    polygon_area = 0.5 * count * 12.3**2 * math.sin(2 * math.pi / count)
    assert abs(counts.sum() - polygon_area) < 4 * 12.3 * 2  # within a perimeter's worth of pixels


def test_fan_centre_on_pixel_centre(impl):
    """The shared vertex exactly on a pixel centre and spokes through pixel centres (E == 0 cases)."""
    cam = sc.screen_camera(16, 16)
    mesh = sc.fan(center=(8.5, 8.5, 0.0), radius=6.0, count=8, phase=0.0)
    counts = _count(impl, cam, mesh, Cull.Off)
    assert set(np.unique(counts)) == {0, 1}
    assert counts[16 - 1 - 8, 8] == 1  # the centre pixel (row 0 = top)


@pytest.mark.parametrize("seed", range(4))
def test_jittered_grid_covers_its_rectangle_once(impl, seed):
    """A grid mesh with randomly jittered inner vertices and its boundary on pixel boundaries: exactly
    the pixels of the rectangle, each once, whatever the triangle orientation."""
    x0, y0, x1, y1 = 3.0, 2.0, 27.0, 21.0
    mesh = sc.jittered_grid(np.random.default_rng(seed), x0, y0, x1, y1, 7)  # mixed windings: Cull Off
    cam = sc.screen_camera(32, 24)
    counts = _count(impl, cam, mesh, Cull.Off)
    expected = np.zeros((24, 32), int)
    expected[24 - int(y1):24 - int(y0), int(x0):int(x1)] = 1
    assert np.array_equal(counts, expected)


def test_grid_in_perspective(impl):
    """The same grid seen by a tilted perspective camera: no pixel covered twice, no hole inside."""
    n = 9
    xs = np.linspace(-1.5, 1.5, n)
    pos = np.array([(x, y, 0.0) for y in xs for x in xs])
    rng = np.random.default_rng(7)
    inner = (np.abs(pos[:, 0]) < 1.5) & (np.abs(pos[:, 1]) < 1.5)
    pos[inner, :2] += rng.uniform(-0.12, 0.12, size=(inner.sum(), 2))
    tri = []
    for j in range(n - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i
            tri += [(a, b, c), (a, c, d)]
    cam = sc.camera(40, 30, eye=(0.7, -2.0, 2.4))
    counts = _count(impl, cam, sc.make_mesh(pos, tri), Cull.Off)
    assert set(np.unique(counts)) == {0, 1}
    # no hole: every row's covered pixels form one contiguous run
    for row in counts:
        idx = np.nonzero(row)[0]
        if len(idx):
            assert idx[-1] - idx[0] + 1 == len(idx)
