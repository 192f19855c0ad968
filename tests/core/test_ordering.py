"""Layers of a chunk (``merger.primitive_layers``): each pixel's fragments in draw order, one per
layer, however deep the chunk, and the peel's shared table left as it was found.

What a GPU does (docs/pipeline.md §8): fragments of one draw call reach a pixel in primitive
order. The expected layers here are written out from that rule, fragment by fragment."""

from __future__ import annotations

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core.merger import PEEL_LAYERS, primitive_layers
from blendlib.core.merger.buffers import PEEL_FREE, FrameBuffers
from blendlib.core.scene import DrawScene, Mesh
from blendlib.core.vocabulary import BlendFactor, ColorSpace, Cull, Lighting, Material, Pass, Queue
from tests.reference import scenes as sc
from tests.reference.scalar import render_reference


def _expected_layers(pix: np.ndarray) -> list[list[int]]:
    """Layer k: the k-th fragment (in draw order) of every pixel that has one, in draw order."""
    seen: dict[int, int] = {}
    layers: list[list[int]] = []
    for i, p in enumerate(pix.tolist()):
        k = seen.get(p, 0)
        seen[p] = k + 1
        if k == len(layers):
            layers.append([])
        layers[k].append(i)
    return layers


def _as_lists(layers, n: int) -> list[list[int]]:
    out = []
    for sel in layers:
        out.append(list(range(n)) if sel is None else sorted(np.asarray(sel).tolist()))
    return out


@pytest.mark.parametrize("depth", [1, 2, PEEL_LAYERS, PEEL_LAYERS + 1, 3 * PEEL_LAYERS])
@pytest.mark.parametrize("shared", [False, True])
def test_layers_hold_each_pixels_fragments_in_draw_order(depth, shared):
    rng = np.random.default_rng(depth)
    # 300 pixels; one of them (pixel 7) is reached `depth` times, the others up to that many.
    pix = np.concatenate([rng.integers(0, 300, size=400 * (depth > 1)), np.full(depth, 7),
                          np.arange(300, 600)]).astype(np.int64)
    rng.shuffle(pix)
    if depth == 1:
        pix = np.unique(pix)
        rng.shuffle(pix)
    scratch = np.full(1000, PEEL_FREE, dtype=np.int64) if shared else None
    expected = _expected_layers(pix)
    got = list(primitive_layers(pix, False, scratch))
    assert len(got) == len(expected) >= depth
    # Within a layer the pixels are distinct, and the layers' sets are the expected ones.
    for sel in got:
        chosen = pix if sel is None else pix[sel]
        assert np.unique(chosen).size == chosen.size
    assert [sorted(x) for x in expected] == _as_lists(got, pix.size)
    if depth == 1:
        assert got == [None]
    if shared:
        assert (scratch == PEEL_FREE).all()


def test_peeled_layers_keep_draw_order_and_an_early_stop_frees_the_table():
    pix = np.array([5, 3, 5, 9, 3, 5, 5], dtype=np.int64)
    scratch = np.full(16, PEEL_FREE, dtype=np.int64)
    layers = primitive_layers(pix, False, scratch)
    assert next(layers).tolist() == [0, 1, 3]  # the first fragment of pixels 5, 3 and 9
    assert next(layers).tolist() == [2, 4]
    layers.close()  # a caller that stops (a cancelled render) leaves the table clean
    assert (scratch == PEEL_FREE).all()
    assert list(primitive_layers(pix, True, scratch)) == [None]  # disjoint: the caller knows


def test_a_draw_call_deeper_than_the_peel_equals_the_reference():
    """Twenty stacked quads of one mesh, drawn in one call (Blend SrcAlpha OneMinusSrcAlpha,
    ZWrite Off, lit per fragment so no blend table is used): each pixel is blended twenty times
    in the mesh's triangle order, as the scalar reference does one fragment at a time."""
    w, h = 24, 20
    quads = [sc.quad(1 + k % 5, 1 + k % 4, w - 2 - k % 3, h - 1 - k % 6, z=0.1 * k) for k in range(20)]
    positions = np.concatenate([q.positions for q in quads])
    triangles = np.concatenate([q.triangles + 4 * k for k, q in enumerate(quads)])
    rng = np.random.default_rng(3)
    normals = rng.normal(size=(len(triangles), 3, 3)).astype(np.float32)  # varying: per-fragment light
    mesh = Mesh(positions, triangles, normals, np.concatenate([q.uvs for q in quads]))
    p = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
             dst_blend=BlendFactor.OneMinusSrcAlpha)
    mat = Material(name="Stack", queue=Queue.Transparent, lighting=Lighting.Lambert,
                   color=(0.9, 0.5, 0.2, 0.3), passes=(p,))
    scene = DrawScene(camera=sc.screen_camera(w, h), renderers=(sc.renderer(mesh, mat),),
                      light=sc.Light(direction=(0.2, 0.5, 0.8)))
    color, depth, _ = render_reference(scene)
    for workers in (1, 2):
        frame = render_scene(scene, workers=workers)
        np.testing.assert_array_equal(frame.color, color)
        np.testing.assert_array_equal(frame.depth, depth)


def test_the_peel_table_of_buffers_gone_is_the_next_buffers_own():
    """Buffers that no longer exist hand their peel table (every entry free again) to the next
    buffers of that size, which then fill none; buffers of another size make their own."""
    def made(width):
        return FrameBuffers(width, 3, False, ColorSpace.Gamma, (0, 0, 0, 1))

    first = made(5)
    table = first.peel_scratch()
    assert table.shape == (15,) and (table == PEEL_FREE).all()
    pix = np.array([4, 2, 4, 4], dtype=np.int64)
    for layer in primitive_layers(pix, False, table):  # used, and left free
        assert layer is not None
    del first
    assert made(5).peel_scratch() is table and (table == PEEL_FREE).all()
    other = made(6).peel_scratch()
    assert other is not table and other.shape == (18,)
