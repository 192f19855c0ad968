"""The core's fast paths must give the scalar reference's answer bit for bit.

Large, flat, untextured triangles take three shortcuts the small sweep cells never reach:
shading once per triangle (docs/pipeline.md §6), blending 8-bit buffers through a lookup
table per source colour (``merger.blend_lut``), and screen bands merged by two threads.
Each test renders a scene where the shortcut is taken (asserted), against the pure-Python
reference of tests/reference/scalar.py.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core import colorspace, merger, raster
from blendlib.core.merger import blending, ordering
from blendlib.core.pipeline import BAND_PIXELS as PRODUCTION_BAND_PIXELS  # read before the tests' override
from blendlib.core.scene import DrawScene
from blendlib.core.vertex import HALF, SUBPIXEL
from blendlib.core.vocabulary import (
    BlendFactor,
    BlendOp,
    ColorSpace,
    CompareFunction,
    Cull,
    Lighting,
    Material,
    Pass,
    Queue,
    TextureFilter,
    TextureWrap,
)
from tests.reference import scenes as sc
from tests.reference.scalar import render_reference

W, H = 40, 32  # each triangle of the full-frame quad covers 640 pixels: more than 256, so it is tabulated
CROSS = {BlendFactor.DstAlpha, BlendFactor.OneMinusDstAlpha, BlendFactor.SrcAlphaSaturate}


def _background(seed: int) -> object:
    """An opaque quad with one random texel per pixel: every destination code differs."""
    rng = np.random.default_rng(seed)
    px = rng.uniform(0, 1, size=(H, W, 4)).astype(np.float32)
    from blendlib.core.vocabulary import Texture

    mat = Material(name="Background", queue=Queue.Background, lighting=Lighting.Unlit,
                   main_tex=Texture(px, encoding="sRGB", name="bg"),
                   main_tex_filter=TextureFilter.Point, main_tex_wrap=TextureWrap.Clamp)
    return sc.renderer(sc.quad(0, 0, W, H, z=-1.0), mat, name="Background")


def _scene(p: Pass, color_space: ColorSpace, color=(0.8, 0.35, 0.6, 0.45), lighting=Lighting.Unlit) -> DrawScene:
    top = Material(name="Top", queue=Queue.Transparent, color=color, lighting=lighting, passes=(p,))
    return DrawScene(camera=sc.screen_camera(W, H), color_space=color_space, ambient=(0.3, 0.2, 0.1),
                     light=None, renderers=(_background(7), sc.renderer(sc.quad(0, 0, W, H, z=1.0), top, name="Top")))


def _assert_equal_with_table(scene: DrawScene, monkeypatch, expect_table: bool = True) -> None:
    calls = []
    original = merger.blend_lut

    def counting(buf, p, palette):
        calls.append(palette.shape[0])
        return original(buf, p, palette)

    monkeypatch.setattr(blending, "blend_lut", counting)
    merger.RECENT_TABLES.clear()  # tables kept from earlier renders would skip blend_lut
    frame = render_scene(scene)
    color, depth, stencil = render_reference(scene)
    assert bool(calls) == expect_table, f"lookup table used {len(calls)} times"
    np.testing.assert_array_equal(frame.color, color)
    np.testing.assert_array_equal(frame.depth, depth)
    np.testing.assert_array_equal(frame.stencil, stencil)


FACTOR_CASES = (
    [(f, BlendFactor.OneMinusSrcAlpha, BlendOp.Add) for f in BlendFactor]
    + [(BlendFactor.SrcAlpha, f, BlendOp.Add) for f in BlendFactor]
    + [(BlendFactor.SrcColor, BlendFactor.DstColor, op) for op in BlendOp]
)


@pytest.mark.parametrize("color_space", list(ColorSpace))
@pytest.mark.parametrize("src,dst,op", FACTOR_CASES, ids=lambda v: str(v))
def test_constant_colour_blending_equals_reference(src, dst, op, color_space, monkeypatch):
    """Every factor and op: the table path (or, for factors that read destination alpha, the
    per-fragment path) equals one-fragment-at-a-time blending."""
    p = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=src, dst_blend=dst, blend_op=op)
    eligible = src not in CROSS and dst not in CROSS
    _assert_equal_with_table(_scene(p, color_space), monkeypatch, expect_table=eligible)


@pytest.mark.parametrize("color_space", list(ColorSpace))
def test_separate_alpha_and_colour_mask_through_the_table(color_space, monkeypatch):
    p = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.OneMinusDstColor,
             dst_blend=BlendFactor.SrcAlpha, blend_op=BlendOp.RevSub, separate_alpha=True,
             src_blend_alpha=BlendFactor.DstAlpha, dst_blend_alpha=BlendFactor.One, blend_op_alpha=BlendOp.Max,
             color_mask=frozenset("RB"))
    _assert_equal_with_table(_scene(p, color_space), monkeypatch)


def test_blend_off_and_out_of_range_colour_through_the_table(monkeypatch):
    """Blend Off writes the clamped source; an HDR-ish colour (> 1, < 0) is clamped first."""
    _assert_equal_with_table(_scene(Pass(ztest=CompareFunction.Always), ColorSpace.Gamma,
                                    color=(1.7, -0.2, 0.5, 1.3)), monkeypatch)


def test_lambert_flat_triangles_shade_once_and_match(monkeypatch):
    """Flat normals and no texture: one shading per triangle, equal to per-fragment shading."""
    scene = _scene(Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
                        dst_blend=BlendFactor.OneMinusSrcAlpha), ColorSpace.Linear, lighting=Lighting.Lambert)
    scene = DrawScene(camera=scene.camera, renderers=scene.renderers, color_space=scene.color_space,
                      ambient=(0.3, 0.2, 0.1), light=sc.Light(direction=(0.3, -0.2, 0.9), color=(1, 0.9, 0.8),
                                                              energy=1.5))
    _assert_equal_with_table(scene, monkeypatch)


def test_hdr_never_uses_the_table(monkeypatch):
    p = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
             dst_blend=BlendFactor.OneMinusSrcAlpha)
    scene = _scene(p, ColorSpace.Linear)
    scene = DrawScene(camera=scene.camera, renderers=scene.renderers, color_space=scene.color_space, hdr=True)
    _assert_equal_with_table(scene, monkeypatch, expect_table=False)


def test_worker_bands_and_chunks_do_not_change_the_frame():
    """One worker, two worker bands and tiny chunks give identical buffers on a self-overlapping draw."""
    mesh = sc.uv_sphere(radius=1.0, segments=24, rings=16)
    p = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
             dst_blend=BlendFactor.OneMinusSrcAlpha)
    mat = Material(color=(0.2, 0.6, 0.9, 0.4), passes=(p,))
    scene = DrawScene(camera=sc.camera(96, 64, eye=(0, 0, 3.2)), renderers=(sc.renderer(mesh, mat),),
                      light=sc.Light(direction=(0.2, 0.5, 0.8)))
    frames = [render_scene(scene, workers=1), render_scene(scene, workers=2),
              render_scene(scene, workers=2, chunk_candidates=97)]
    for other in frames[1:]:
        np.testing.assert_array_equal(frames[0].color, other.color)
        np.testing.assert_array_equal(frames[0].depth, other.depth)
    color, _, _ = render_reference(scene)
    np.testing.assert_array_equal(frames[0].color, color)


def test_parallel_setup_and_spans_equal_serial():
    """A 160k-triangle sphere crossing the near plane: setup and span building split over two
    threads (and clipping in both halves) give the same buffers as one thread."""
    mesh = sc.uv_sphere(radius=1.0, segments=400, rings=200)
    split = 2 * (1 << 15)  # parts.run_parts splits from this many items on
    assert mesh.triangle_count > split and mesh.positions.shape[0] > split
    p = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
             dst_blend=BlendFactor.OneMinusSrcAlpha)
    mat = Material(color=(0.9, 0.5, 0.2, 0.3), passes=(p,))
    for eye in ((0.0, 0.0, 3.0), (0.3, 0.2, 1.02)):  # outside, then touching the surface: near-plane clipping
        scene = DrawScene(camera=sc.camera(120, 90, eye=eye), renderers=(sc.renderer(mesh, mat),),
                          light=sc.Light(direction=(0.2, 0.5, 0.8)))
        one, two = render_scene(scene, workers=1), render_scene(scene, workers=2)
        np.testing.assert_array_equal(one.color, two.color)
        np.testing.assert_array_equal(one.depth, two.depth)
        assert np.count_nonzero(one.color[..., 3] != 0.0) > 1000  # the clear alpha is 0


def test_equal_corner_values_are_not_interpolated():
    """docs/pipeline.md §6: equal corner values are the attribute itself. UV corners all at
    (0.75, 0.75) on a 4x4 Point-sampled texture sit exactly on a texel boundary (0.75*4 = 3):
    a weighted sum just below 0.75, as (w0*a + w1*a) + w2*a gives for about one fragment in
    eight, would sample texel 2 instead of 3."""
    from blendlib.core import raster
    from blendlib.core.vocabulary import Texture

    # The rule at the unit level, with weights whose sum differs from the corner value.
    rng = np.random.default_rng(1)
    w = rng.random((3, 400))
    w /= w.sum(axis=0)
    assert np.any((w[0] * 0.75 + w[1] * 0.75) + w[2] * 0.75 < 0.75)
    out = raster.interpolate_runs(w, np.full((1, 3, 2), 0.75), np.array([400]), np.array([True]))
    assert np.all(out == 0.75)

    texels = np.zeros((4, 4, 4), np.float32)
    texels[..., 1] = texels[..., 3] = 1.0  # green everywhere...
    texels[3, 3] = (1.0, 0.0, 0.0, 1.0)  # ...except texel (3, 3): red
    quad = sc.quad(-1.5, -1.5, 1.5, 1.5)
    # Unlit: flat UVs make the triangle constant (shaded once). Lambert with differing corner
    # normals: shaded per fragment, the UVs still flat. Both must sample texel (3, 3) only.
    for lighting, normals in ((Lighting.Unlit, None), (Lighting.Lambert, [[(0, 0, 1), (0.3, 0, 1), (0, 0.4, 1)]] * 2)):
        mat = Material(lighting=lighting, main_tex=Texture(texels, encoding="Data"),
                       main_tex_filter=TextureFilter.Point, main_tex_wrap=TextureWrap.Clamp,
                       passes=(Pass(cull=Cull.Off),))
        mesh = sc.make_mesh(quad.positions, quad.triangles, normals=normals, uvs=np.full((2, 3, 2), 0.75))
        scene = DrawScene(camera=sc.camera(48, 40, eye=(0.7, 0.4, 2.5)), renderers=(sc.renderer(mesh, mat),),
                          light=sc.Light(direction=(0.2, 0.3, 1.0)), ambient=(0.1, 0.1, 0.1))
        frame = render_scene(scene)
        covered = frame.depth < 1.0
        assert covered.sum() > 500
        assert np.all(frame.color[covered][:, 1] == 0.0) and np.all(frame.color[covered][:, 0] > 0.0), lighting
        color, _, _ = render_reference(scene)
        np.testing.assert_array_equal(frame.color, color)


def test_small_frames_render_in_one_thread_by_default(monkeypatch):
    """The default worker count follows the frame size; the result does not depend on it."""
    from blendlib.core import pipeline

    created = []
    real = pipeline.ThreadPoolExecutor

    def counting(*args, **kwargs):
        created.append(kwargs.get("max_workers"))
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline, "ThreadPoolExecutor", counting)
    cam = sc.screen_camera(64, 48)
    scene = sc.scene(cam, sc.renderer(sc.quad(4, 4, 60, 44), sc.unlit((1, 0, 0, 1))))
    small = render_scene(scene)
    assert created == []  # 64x48 < SMALL_FRAME_PIXELS: no thread pool
    monkeypatch.setattr(pipeline, "SMALL_FRAME_PIXELS", 64 * 48)
    big = render_scene(scene)
    assert created == [min(2, os.cpu_count() or 1)] if (os.cpu_count() or 1) > 1 else created == []
    assert np.array_equal(small.color, big.color) and np.array_equal(small.depth, big.depth)


def test_frame_output_division_equals_float64_rounding_for_every_code():
    """``FrameBuffers.output`` divides in float32: exhaustively the same as the float64 quotient
    rounded to float32 (the definition: colour ``q / 255``, depth ``d / (2**24 - 1)``)."""
    from blendlib.core.vertex import DEPTH_MAX
    from blendlib.core.vocabulary import ColorSpace

    buf = merger.FrameBuffers(256, 1, False, ColorSpace.Gamma, (0, 0, 0, 0))
    buf.color[:] = np.arange(256, dtype=np.uint8)[:, None]
    color, _, _ = buf.output()
    np.testing.assert_array_equal(color[0, :, 0], (np.arange(256) / 255.0).astype(np.float32))
    width = 1 << 12
    buf = merger.FrameBuffers(width, (DEPTH_MAX + 1) // width, False, ColorSpace.Gamma, (0, 0, 0, 0))
    buf.depth[:] = np.arange(DEPTH_MAX + 1, dtype=np.int64)
    _, depth, _ = buf.output()
    want = (np.arange(DEPTH_MAX + 1, dtype=np.int64) / float(DEPTH_MAX)).astype(np.float32)
    np.testing.assert_array_equal(depth[::-1].reshape(-1), want)


def _texel_palette_scene(lighting: Lighting, p: Pass, *, hdr: bool = False, cutoff: float = 0.0) -> DrawScene:
    """A 4x4 Point-filtered texture (repeated 3x, offset) over a cube seen at an angle: every face
    has a constant normal and varying UVs, so its colour is a function of (face normal, texel)."""
    from blendlib.core.vocabulary import Texture

    rng = np.random.default_rng(11)
    px = rng.uniform(0, 1, size=(4, 4, 4)).astype(np.float32)
    px[0, 0] = (0.5, 0.25, 0.75, 0.0)  # a transparent texel for the alpha test
    mat = Material(name="Checker", queue=Queue.Transparent, lighting=lighting, color=(0.9, 0.7, 1.0, 0.8),
                   main_tex=Texture(px, encoding="sRGB", name="checker"), main_tex_filter=TextureFilter.Point,
                   main_tex_wrap=TextureWrap.Repeat, main_tex_tiling=(3.0, 3.0), main_tex_offset=(0.1, -0.2),
                   cutoff=cutoff, passes=(p,))
    shape = sc.cube(2.0)
    face_uvs = [[(0, 0), (1, 0), (1, 1)], [(0, 0), (1, 1), (0, 1)]] * 6
    mesh = sc.make_mesh(shape.positions, shape.triangles, normals=shape.normals, uvs=face_uvs)
    cube = sc.renderer(mesh, mat, name="Cube", matrix=sc.translate(0.1, 0.0, 0.0))
    return DrawScene(camera=sc.camera(48, 40, eye=(2.5, 2.0, 4.0)), color_space=ColorSpace.Linear, hdr=hdr,
                     ambient=(0.3, 0.2, 0.1), renderers=(_background(3), cube),
                     light=sc.Light(direction=(0.3, -0.5, -0.8), color=(1, 0.9, 0.8), energy=1.5))


def _count_palettes(monkeypatch) -> list[int]:
    """The group count of every texel palette made from now on (``shade.texel_palette`` spied)."""
    from blendlib.core import shade

    palettes: list[int] = []
    original = shade.texel_palette

    def counting(material, texels, lights, color_space, normals, *colors):
        palettes.append(normals.shape[0])
        return original(material, texels, lights, color_space, normals, *colors)

    monkeypatch.setattr(shade, "texel_palette", counting)
    return palettes


@pytest.mark.parametrize("lighting", [Lighting.Unlit, Lighting.Lambert])
@pytest.mark.parametrize("hdr", [False, True])
@pytest.mark.parametrize("blend", [True, False])
def test_point_texture_palette_equals_reference(lighting, hdr, blend, monkeypatch):
    """Point-filtered triangles with a constant normal take colours from a palette shaded once
    per (normal, texel) (``shade.texel_palette``): equal to the scalar reference, blended through
    the table in LDR (Blend Off: one stored value per colour) and gathered in HDR, with an alpha
    test on the palette's alpha."""
    palettes = _count_palettes(monkeypatch)
    p = Pass(cull=Cull.Off, zwrite=False, blend=blend, src_blend=BlendFactor.SrcAlpha,
             dst_blend=BlendFactor.OneMinusSrcAlpha, alpha_test=True)
    scene = _texel_palette_scene(lighting, p, hdr=hdr, cutoff=0.3)
    frame = render_scene(scene, workers=1)
    color, depth, stencil = render_reference(scene)
    assert palettes, "the texel palette was not used"
    # Unlit: one group; Lambert: one per distinct face normal of the chunk (Cull Off: up to 6).
    assert max(palettes) == 1 if lighting is Lighting.Unlit else 2 <= max(palettes) <= 6
    np.testing.assert_array_equal(frame.color, color)
    np.testing.assert_array_equal(frame.depth, depth)
    np.testing.assert_array_equal(frame.stencil, stencil)


def test_point_texture_palette_beside_fragments_shaded_one_by_one_equals_reference(monkeypatch):
    """A chunk whose flat faces take the texel palette while two faces with a normal varying
    from corner to corner are shaded fragment by fragment (their weights and coordinates taken
    out of the chunk's): equal to the scalar reference."""
    palettes = _count_palettes(monkeypatch)
    p = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
             dst_blend=BlendFactor.OneMinusSrcAlpha)
    scene = _texel_palette_scene(Lighting.Lambert, p)
    background, cube = scene.renderers
    normals = np.array(cube.mesh.normals, dtype=np.float32)
    normals[:4] += np.array([[0.3, -0.2, 0.1], [-0.25, 0.15, 0.05], [0.1, 0.3, -0.2]], dtype=np.float32)
    cube = replace(cube, mesh=replace(cube.mesh, normals=normals))
    scene = replace(scene, renderers=(background, cube))
    frame = render_scene(scene, workers=1)
    color, depth, stencil = render_reference(scene)
    assert palettes, "the texel palette was not used"
    np.testing.assert_array_equal(frame.color, color)
    np.testing.assert_array_equal(frame.depth, depth)


def test_texel_palette_is_left_when_the_texture_is_large(monkeypatch):
    """A texture with more texels than a quarter of the fragments it serves is shaded per fragment."""
    from blendlib.core import fragment, shade

    def refuse(*_args):
        raise AssertionError("texel palette used for a large texture")

    monkeypatch.setattr(shade, "texel_palette", refuse)
    scene = _texel_palette_scene(Lighting.Unlit, Pass())
    monkeypatch.setattr(fragment, "TEXEL_PALETTE_SHARE", 10_000)
    frame = render_scene(scene, workers=1)
    np.testing.assert_array_equal(frame.color, render_reference(scene)[0])


def test_batched_bands_equal_per_draw_bands_and_reference(monkeypatch):
    """Without an observer, draw calls are prepared as batches (renderers in parallel when they
    hold enough triangles) and each worker draws its screen band of a whole batch with no wait
    between calls: the frame, depth, stencil and warnings equal one thread, per-draw bands (an
    observer that needs exact draw boundaries: one call a step) and the reference.
    Opaque ZWrite On draws between ZWrite Off ones make each band recompute its depth floor."""
    from blendlib.core import pipeline, prepare

    blend = dict(blend=True, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha)
    opaque = Material(name="Opaque", color=(0.3, 0.8, 0.4, 1.0), passes=(Pass(),))
    glass = Material(name="Glass", queue=Queue.Transparent, color=(0.9, 0.3, 0.2, 0.5),
                     passes=(Pass(zwrite=True, color_mask=""), Pass(zwrite=False, **blend)))
    thin = Material(name="Thin", queue=Queue.Transparent, color=(0.2, 0.4, 0.9, 0.35), lighting=Lighting.Unlit,
                    passes=(Pass(cull=Cull.Off, zwrite=False, **blend),))
    renderers = [sc.renderer(sc.uv_sphere(0.8, 20, 12), opaque, name="Ball", matrix=sc.translate(-0.9, 0.3, -0.5))]
    for k in range(4):
        renderers.append(sc.renderer(sc.uv_sphere(0.5, 16, 10), glass, name=f"Glass{k}",
                                     matrix=sc.translate(-1.2 + 0.8 * k, -0.4 + 0.25 * k, 0.2 * k)))
        renderers.append(sc.renderer(sc.quad(-2 + k, -1.5, -0.5 + k, 1.5, z=0.4 - 0.3 * k), thin, name=f"Sheet{k}"))
    degenerate = sc.make_mesh([(0, 0, 0), (1, 1, 0), (2, 2, 0)], [(0, 1, 2)])
    renderers.append(sc.renderer(degenerate, thin, name="Line"))
    scene = DrawScene(camera=sc.camera(120, 96, eye=(0.3, 0.4, 4.0)), renderers=tuple(renderers),
                      light=sc.Light(direction=(0.2, 0.5, 0.8)))
    batches = []
    original = pipeline.prepare_batch

    def counting(frame, runs):
        batches.append(sum(len(run) for run in runs))
        return original(frame, runs)

    monkeypatch.setattr(pipeline, "prepare_batch", counting)
    batched = render_scene(scene, workers=2)
    assert batches == [14]  # every draw call in one batch
    monkeypatch.setattr(prepare, "PARALLEL_PREPARE_TRIANGLES", 0)  # renderers prepared on the pool
    pool_prepared = render_scene(scene, workers=2)
    observed = render_scene(scene, workers=2, observer=pipeline.FrameObserver())
    one = render_scene(scene, workers=1, chunk_candidates=211)
    monkeypatch.setattr(pipeline, "BATCH_DRAWS", 1)
    unbatched = render_scene(scene, workers=2)
    color, depth, stencil = render_reference(scene)
    assert any("degenerate" in w for w in batched.warnings)
    for frame in (batched, pool_prepared, observed, one, unbatched):
        np.testing.assert_array_equal(frame.color, color)
        np.testing.assert_array_equal(frame.depth, depth)
        np.testing.assert_array_equal(frame.stencil, stencil)
        assert frame.warnings == batched.warnings


@pytest.mark.parametrize("size", [1, 7, 8, 18, 32])
@pytest.mark.parametrize("wrap", [TextureWrap.Repeat, TextureWrap.Clamp])
def test_integer_texel_wrap_equals_float_formulas(size, wrap):
    """``shade._wrap`` takes integer arithmetic when every index converts exactly: the same
    indices as the float formulas of §7 (``mod`` / clamp), for negative, large and power-of-two
    cases; arrays holding NaN or huge values take the float formulas themselves."""
    from blendlib.core import shade

    rng = np.random.default_rng(size)
    values = np.floor(rng.uniform(-3000.0, 3000.0, 4096))
    values[:6] = (-0.0, 0.0, -1.0, float(size), -float(size), 2.0**61)
    if wrap is TextureWrap.Repeat:
        expected = np.mod(values, float(size)).astype(np.int64)
    else:
        expected = np.minimum(np.maximum(values, 0.0), float(size - 1)).astype(np.int64)
    got = shade._wrap(values.copy(), size, wrap)
    assert got.dtype == np.int64
    np.testing.assert_array_equal(got, expected)
    assert got.min() >= 0 and got.max() <= size - 1
    huge = values.copy()
    huge[7] = 2.0**70  # beyond int64: the float formulas for the whole array
    with np.errstate(invalid="ignore"):
        if wrap is TextureWrap.Repeat:
            expected_huge = np.mod(huge, float(size)).astype(np.int64)
        else:
            expected_huge = np.minimum(np.maximum(huge, 0.0), float(size - 1)).astype(np.int64)
        np.testing.assert_array_equal(shade._wrap(huge, size, wrap), expected_huge)


def test_point_texel_index_of_non_finite_coordinates_is_texel_zero():
    from blendlib.core import shade

    texels = shade.Texels(np.random.default_rng(1).uniform(0, 1, (6, 10, 4)).astype(np.float32), None)
    u = np.array([0.05, np.nan, 0.55, np.inf, -0.25, 1.25])
    v = np.array([0.05, 0.5, np.nan, 0.5, -0.1, 2.5])
    got = shade.point_texel_index_of(texels, u, v, TextureWrap.Repeat)
    # floor(u*10) mod 10 + 10 * (floor(v*6) mod 6); any non-finite coordinate -> texel 0.
    np.testing.assert_array_equal(got, [0, 0, 0, 0, 5 * 10 + 7, 3 * 10 + 2])


def test_gather_equals_take_for_every_index_take_accepts():
    """``gather`` (mode "wrap") gives np.take's values for indices in -n..n-1, negative ones
    counting from the end, along an axis and into ``out`` alike."""
    from blendlib.core.gather import gather

    rng = np.random.default_rng(3)
    values = rng.uniform(-1.0, 1.0, (37, 4))
    index = rng.integers(-37, 37, 500)
    index[:2] = (-37, 36)
    np.testing.assert_array_equal(gather(values[:, 1], index), np.take(values[:, 1], index))
    np.testing.assert_array_equal(gather(values, index, axis=0), np.take(values, index, axis=0))
    out = np.empty(500, np.float64)
    assert gather(values.reshape(-1), index, out=out) is out
    np.testing.assert_array_equal(out, np.take(values.reshape(-1), index))


@pytest.mark.parametrize("columns", [3, 4])
def test_scatter_rows_equals_row_assignment(columns):
    """``scatter_rows`` writes whole rows where fancy assignment would, from rows given as a
    transposed view too, and leaves every other row as it was."""
    from blendlib.core.gather import scatter_rows

    rng = np.random.default_rng(columns)
    dest = rng.uniform(-1.0, 1.0, (50, columns))
    index = rng.permutation(50)[:23]
    rows = rng.uniform(-1.0, 1.0, (columns, 23)).T  # (23, C), not contiguous
    expected = dest.copy()
    expected[index] = rows
    scatter_rows(dest, index, rows)
    np.testing.assert_array_equal(dest.view(np.int64), expected.view(np.int64))


@pytest.mark.parametrize("columns", [3, 4])
def test_scatter_rows_of_one_row_equals_scalar_assignment(columns):
    """``scatter_rows`` of one zero row sets every indexed row to +0.0 bit for bit (a NaN or -0.0
    there included), as ``dest[index] = 0.0`` does, and leaves every other row as it was."""
    from blendlib.core.gather import scatter_rows

    rng = np.random.default_rng(10 + columns)
    dest = rng.uniform(-1.0, 1.0, (60, columns))
    dest[3] = np.nan
    dest[4] = -0.0
    index = np.concatenate([[3, 4], rng.permutation(np.arange(5, 60))[:20]])
    expected = dest.copy()
    expected[index] = 0.0
    scatter_rows(dest, index, np.zeros((1, columns)))
    np.testing.assert_array_equal(dest.view(np.int64), expected.view(np.int64))
    assert not np.signbit(dest[4]).any() and np.isnan(dest[5:]).sum() == 0


def _sprite_like(h: int, w: int, byte: bool, alpha: float = 0.2) -> np.ndarray:
    """(h, w, 4) float32: red and green white everywhere, blue varying (but along its first
    row), alpha ``alpha`` everywhere (0.2, or 0 as 8 bits hold it) — the uniform channels of a
    particle sprite, and two channels sharing one uniform value."""
    rng = np.random.default_rng(h * 100 + w)
    px = rng.uniform(0.0, 1.0, (h, w, 4)).astype(np.float32)
    if byte:
        px = (np.rint(px * 255.0) / np.float32(255.0)).astype(np.float32)
    px[..., 0] = 1.0
    px[..., 1] = 1.0
    px[..., 3] = np.float32(round(alpha * 255.0) / 255.0) if byte else np.float32(alpha)
    px[0, :, 2] = 0.6  # blue uniform along the first row only
    return px


@pytest.mark.parametrize("wrap", [TextureWrap.Repeat, TextureWrap.Clamp])
@pytest.mark.parametrize("byte", [True, False], ids=["byte", "float"])
@pytest.mark.parametrize("quads", [True, False], ids=["quads", "texels"])
@pytest.mark.parametrize("alpha", [0.2, 0.0])
def test_bilinear_samples_equal_the_scalar_formula(wrap, byte, quads, alpha, monkeypatch):
    """Bilinear sampling (§7) through each texel's kept neighbourhood (``Texels.quads``) or four
    texel gathers, with uniform channels computed once (those of 1 and 0 filled): the same bits
    as the scalar reference's ``lo = t00*(1-au) + t01*au``, ``hi = t10*(1-au) + t11*au``,
    ``lo*(1-av) + hi*av`` for coordinates inside, on and far beyond the border (the corners'
    extended rows), non-finite ones, ones 2**52 texels away, a non-square texture and any subset
    of channels."""
    from blendlib.core import shade
    from tests.reference.scalar_shading import sample_rows

    if not quads:
        monkeypatch.setattr(shade.Texels, "QUAD_TEXELS", 0)
    h, w = 5, 12
    px = _sprite_like(h, w, byte, alpha)
    texels = shade.Texels(px, None)
    assert (texels.codes is not None) == byte
    assert texels.uniform() == (1.0, 1.0, None, float(px[0, 0, 3]))
    assert (texels.quads(wrap) is not None) == quads
    rng = np.random.default_rng(5)
    near = rng.uniform(-0.2, 1.2, (600, 2))
    border = np.array([[0.0, 0.0], [1.0, 1.0], [0.5 / w, 0.5 / h], [1.0 - 0.5 / w, 1.0 - 0.5 / h],
                       [-0.01, 0.5], [0.5, 1.01], [np.nan, 0.5], [0.5, np.inf], [-np.inf, -np.inf]])
    far = rng.uniform(-4000.0, 4000.0, (200, 2))
    tall = np.stack([rng.uniform(0.0, 1.0, 200), rng.uniform(1.0, 2.0, 200)], axis=1)  # rows past h, columns not past w
    huge = np.array([[2.0**55 / w + 0.3, 0.4], [0.2, -(2.0**56) / h]])
    T = [[[float(c) for c in px[j, i]] for i in range(w)] for j in range(h)]
    for uv in (near, border, tall, far, huge, np.concatenate([near, huge])):
        expected = np.array([sample_rows(T, u, v, False, wrap is TextureWrap.Repeat) for u, v in uv])
        for channels in ((0, 1, 2, 3), (2,), (3, 0), (1, 2), (2, 0, 1)):
            got = shade.sample(texels, uv, TextureFilter.Bilinear, wrap, channels)
            np.testing.assert_array_equal(got.view(np.int64), expected[:, list(channels)].view(np.int64))


@pytest.mark.parametrize("filt", [TextureFilter.Point, TextureFilter.Bilinear, TextureFilter.Trilinear])
@pytest.mark.parametrize("wrap", [TextureWrap.Repeat, TextureWrap.Clamp])
def test_identity_tiling_samples_the_mesh_uvs_as_the_formula_would(filt, wrap):
    """``shade.texture_uv`` with tiling (1, 1) and offset (0, 0) hands the mesh UVs on as they are,
    where ``u * 1 + 0`` would turn a -0.0 into +0.0: sampling (each filter and wrap, through
    the mip chain too) takes both zeros to the same bits, so the frame is the formula's. Another
    tiling or offset is applied."""
    from blendlib.core import mips, shade
    from blendlib.core.vocabulary import Material, Texture

    px = np.random.default_rng(3).uniform(0.0, 1.0, (8, 8, 4)).astype(np.float32)
    material = Material(main_tex=Texture(px, encoding="Linear", name="t"), main_tex_filter=filt, main_tex_wrap=wrap,
                        main_tex_mipmaps=True)
    texels = shade.texture_texels(material.main_tex, ColorSpace.Gamma)
    chain = mips.build_chain(texels)
    zeros = np.array([[-0.0, 0.3], [0.7, -0.0], [-0.0, -0.0], [0.0, 0.0], [-0.0, 1.0], [1e-300, -0.0]])
    assert shade.texture_uv(material, zeros) is zeros
    positive = zeros + 0.0  # what u * 1 + 0 gives: every -0.0 made +0.0
    assert np.signbit(zeros).any() and not np.signbit(positive).any()
    lod = np.array([0.0, 0.5, 1.2, 2.0, 0.0, 3.0])
    for sampled in (lambda uv: shade.sample(texels, uv, filt, wrap),
                    lambda uv: mips.sample_mipmapped(chain, uv, lod, filt, wrap)):
        np.testing.assert_array_equal(sampled(zeros).view(np.int64), sampled(positive).view(np.int64))
    moved = replace(material, main_tex_tiling=(2.0, 1.0), main_tex_offset=(0.0, 0.25))
    expected = np.stack([zeros[:, 0] * 2.0 + 0.0, zeros[:, 1] * 1.0 + 0.25], axis=1)
    np.testing.assert_array_equal(shade.texture_uv(moved, zeros), expected)


def test_a_bilinear_weight_and_its_complement_sum_to_exactly_one():
    """Why a channel of texels all 1 samples to exactly 1 (``shade.sample`` fills it): for a
    fraction ``a`` in [0, 1), ``(1 - a) + a`` rounds to 1 in float64, so ``lo = 1*(1-au) + 1*au``
    is 1 and ``lo*(1-av) + lo*av`` is 1 again. Checked on fractions near 0, 1/2 and 1 (where
    ``1 - a`` rounds) and a million random ones; a value like 0.7 does not stay exact."""
    rng = np.random.default_rng(11)
    tiny = 2.0 ** -np.arange(1, 80, dtype=np.float64)
    edges = np.concatenate([[0.0, 0.5, 0.25, 0.75], tiny, 0.5 - tiny[tiny < 0.5], np.nextafter(1.0, 0.0) - tiny[:60],
                            np.nextafter(np.float64(0.5), 0.0) - tiny[:60], [np.nextafter(1.0, 0.0)]])
    a = np.concatenate([edges[(edges >= 0.0) & (edges < 1.0)], rng.uniform(0.0, 1.0, 1_000_000),
                        rng.uniform(0.0, 2.0 ** -20, 100_000)])
    assert ((1.0 - a) + a == 1.0).all()
    assert (np.multiply(1.0 - a, 0.7) + np.multiply(a, 0.7) != 0.7).any()


@pytest.mark.parametrize("src, dst, op", FACTOR_CASES)
@pytest.mark.parametrize("color_space", [ColorSpace.Gamma, ColorSpace.Linear])
def test_per_fragment_blending_by_channel_equals_reference(src, dst, op, color_space, monkeypatch):
    """Varying colours (a bilinear texture with values beyond [0, 1]) blend one channel at a time
    (``blending._blend_ldr``): equal to the reference for every factor and op, in both spaces."""
    from blendlib.core.vocabulary import Texture

    p = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=src, dst_blend=dst, blend_op=op)
    scene = _scene(p, color_space)
    px = np.random.default_rng(5).uniform(-0.2, 1.3, size=(5, 7, 4)).astype(np.float32)
    top = Material(name="Top", queue=Queue.Transparent, color=(0.9, 0.8, 1.0, 0.7), lighting=Lighting.Unlit,
                   main_tex=Texture(px, encoding="Linear", name="noise"), main_tex_filter=TextureFilter.Bilinear,
                   passes=(p,))
    scene = DrawScene(camera=scene.camera, color_space=color_space, renderers=(
        scene.renderers[0], sc.renderer(sc.quad(0, 0, W, H, z=1.0), top, name="Top")))
    _assert_equal_with_table(scene, monkeypatch, expect_table=False)


def test_blend_results_stay_within_the_clamps_left_out():
    """``_blend_ldr`` leaves out the clamp to [0, 1] of a channel's result where ``_clamps`` says
    it cannot be needed: for every source and destination factor and op, over sources and
    destinations in [0, 1] (their edges and the floats next to them among them), no result falls
    below 0 where the low clamp is left out, nor above 1 where the high one is; and the codes
    equal those of the full quantisation. The common cases leave clamps out: ``SrcAlpha
    OneMinusSrcAlpha`` both, additive ``SrcAlpha One`` the low one, ``Blend Off`` both."""
    rng = np.random.default_rng(11)
    edges = np.array([0.0, 1.0, np.nextafter(1.0, 0.0), 5e-324, 0.5, np.nextafter(0.5, 1.0), 1 / 3, 2 / 3])
    grid = np.stack(np.meshgrid(edges, edges, edges, edges, indexing="ij"), axis=-1).reshape(-1, 4)
    s = np.concatenate([rng.uniform(0, 1, (20000, 4)), grid, grid[::-1]])
    d = np.concatenate([rng.uniform(0, 1, (20000, 4)), grid[::-1], grid])
    left_out = 0
    for src in BlendFactor:
        for dst in BlendFactor:
            for op in BlendOp:
                p = Pass(blend=True, src_blend=src, dst_blend=dst, blend_op=op)
                result = blending._blend_channels(p, list(s.T), list(d.T))
                for c in range(4):
                    low, high = blending._clamps(p, c)
                    v = np.broadcast_to(np.asarray(result[c], dtype=np.float64), (s.shape[0],))
                    assert low or np.all(v >= 0.0), (src, dst, op, c)
                    assert high or np.all(v <= 1.0), (src, dst, op, c)
                    codes = colorspace.unorm_codes_in_place(v.copy(), low, high)
                    assert np.array_equal(codes, colorspace.unorm_codes_in_place(v.copy())), (src, dst, op, c)
                    left_out += (not low) + (not high)
    assert left_out > 300
    assert blending._clamps(Pass(blend=True, src_blend=BlendFactor.SrcAlpha,
                                 dst_blend=BlendFactor.OneMinusSrcAlpha), 0) == (False, False)
    assert blending._clamps(Pass(blend=True, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.One), 0) == (
        False, True)
    assert blending._clamps(Pass(blend=True, src_blend=BlendFactor.One, dst_blend=BlendFactor.One,
                                 blend_op=BlendOp.Sub), 3) == (True, False)
    assert blending._clamps(Pass(), 0) == (False, False)


def test_large_textures_are_not_examined_for_repeated_texels(monkeypatch):
    """Finding the distinct texels of a texture larger than ``TEXEL_PALETTE_EXAMINE`` is skipped
    unless even its full size would pay (a 256x256 texture over a 48x40 frame): shaded per fragment."""
    from blendlib.core import shade
    from blendlib.core.vocabulary import Texture

    def refuse(self):
        raise AssertionError("distinct texels of a large texture computed")

    monkeypatch.setattr(shade.Texels, "distinct", refuse)
    px = np.random.default_rng(2).uniform(0, 1, size=(256, 256, 4)).astype(np.float32)
    mat = Material(name="Big", lighting=Lighting.Unlit, main_tex=Texture(px, encoding="sRGB", name="big"),
                   main_tex_filter=TextureFilter.Point, passes=(Pass(),))
    scene = DrawScene(camera=sc.screen_camera(48, 40), renderers=(sc.renderer(sc.quad(0, 0, 48, 40), mat),))
    frame = render_scene(scene, workers=1)
    np.testing.assert_array_equal(frame.color, render_reference(scene)[0])


def test_renderers_set_up_together_equal_each_alone(monkeypatch):
    """Many small renderers get one vertex setup and one coverage pass for all of them; each
    renderer's triangles and each pass's spans equal those of its own setup: near-plane clipping,
    a mirroring matrix, non-finite and zero-area triangles, a mesh without triangles, float32 and
    int32 mesh arrays."""
    from blendlib.core import raster, vertex

    nan_mesh = sc.make_mesh([(0, 0, 0), (1, 0, 0), (0, 1, 0), (np.nan, 0, 0)], [(0, 1, 2), (0, 1, 3)])
    line = sc.make_mesh([(0, 0, 0), (1, 1, 0), (2, 2, 0)], [(0, 1, 2), (0, 1, 2)])
    sphere = sc.uv_sphere(0.9, 14, 9)
    small = sc.uv_sphere(0.4, 8, 6)
    small32 = sc.replace(small, positions=small.positions.astype(np.float32),
                         triangles=small.triangles.astype(np.int32))
    empty = sc.make_mesh(np.zeros((0, 3)), np.zeros((0, 3)))
    items = [
        vertex.SetupInput(sphere, sc.translate(0.2, 0.0, 1.6)),  # crosses the near plane (eye at z 2.5)
        vertex.SetupInput(sc.quad(-1, -1, 1, 1), sc.scale(-1.0, 1.0, 1.0), need_normals=False),  # mirrored
        vertex.SetupInput(nan_mesh, sc.translate(-0.5, 0.2, 0.0), need_uvs=False),
        vertex.SetupInput(empty, np.eye(4)),
        vertex.SetupInput(line, np.eye(4)),
        vertex.SetupInput(small32, sc.translate(0.6, -0.3, 0.5)),
        # Upright walls (normals across x and y): a zero z in their cross products, yet an area.
        vertex.SetupInput(sc.make_mesh([(0, 0, 0), (1, 0, 0), (0, 0, 1), (0, 1, 0)], [(0, 1, 2), (0, 2, 3)]),
                          sc.translate(-0.3, -0.2, 0.0)),
    ]
    camera = sc.camera(80, 60, eye=(0.0, 0.0, 2.5))
    together = vertex.setup_renderers(items, camera)
    alone = [vertex.setup_renderers([item], camera)[0] for item in items]
    for a, b in zip(together, alone, strict=True):
        for name in ("X", "Y", "zw", "iw", "area2", "src", "clipped", "front"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        assert (a.weights is None) == (b.weights is None)
        if a.weights is not None:
            np.testing.assert_array_equal(a.weights, b.weights)
        assert (a.skipped_nonfinite, a.degenerate) == (b.skipped_nonfinite, b.degenerate)
        assert (a.object_uvs is None) == (b.object_uvs is None)
        assert (a.object_normals is None) == (b.object_normals is None)
    # The cases above really happen.
    assert together[0].clipped.any() and together[0].weights is not None
    assert together[5].weights is None
    mirrored = together[1]
    assert mirrored.front.all() and (mirrored.area2 < 0).all()
    assert together[2].skipped_nonfinite == 1 and together[4].degenerate == 2 and together[3].count == 0
    assert together[6].degenerate == 0 and together[6].count == 2

    passes = [(setup, vertex.cull_select(setup, cull)) for setup in together for cull in (Cull.Back, Cull.Off)]
    many = raster.coverage_rows_many(passes, camera.width, camera.height)
    assert sum(r.count for r in many) > 200
    for (setup, selected), rows in zip(passes, many, strict=True):
        own = raster.coverage_rows(setup, selected, camera.width, camera.height)
        for name in raster.Rows.__dataclass_fields__:
            np.testing.assert_array_equal(getattr(rows, name), getattr(own, name), err_msg=name)

    # In pieces of a few vertices and triangles (vertex.PIECE: cache-sized pieces of big meshes),
    # run here one after another or on two threads: the same setups and spans.
    pool = ThreadPoolExecutor(max_workers=2)
    try:
        for piece, threads in ((7, None), (7, pool), (50, pool)):
            monkeypatch.setattr(vertex, "PIECE", piece)
            monkeypatch.setattr(raster, "PIECE", piece)
            pieced = vertex.setup_renderers(items, camera, pool=threads, parts=2 if threads else 1)
            for a, b in zip(pieced, together, strict=True):
                for name in ("X", "Y", "zw", "iw", "area2", "src", "clipped", "front"):
                    np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
                assert (a.skipped_nonfinite, a.degenerate) == (b.skipped_nonfinite, b.degenerate)
                assert (a.weights is None) == (b.weights is None)
                if a.weights is not None:
                    np.testing.assert_array_equal(a.weights, b.weights)
            for setup, selected in passes:
                whole = raster.coverage_rows(setup, selected, camera.width, camera.height)
                split = raster.coverage_rows(setup, selected, camera.width, camera.height, pool=threads,
                                             parts=2 if threads else 1)
                for name in raster.Rows.__dataclass_fields__:
                    np.testing.assert_array_equal(getattr(split, name), getattr(whole, name), err_msg=name)
    finally:
        pool.shutdown()


@pytest.mark.parametrize("rows", [
    [(0.2, 0.4, 0.6, 0.5)] * 5,
    [(0.2, 0.4, 0.6, 0.5)],
    [(0.2, 0.4, 0.6, 0.5), (0.2, 0.4, 0.6, 0.25), (0.2, 0.4, 0.6, 0.5)],
    [(0.0, 0.4, 0.6, 0.5), (-0.0, 0.4, 0.6, 0.5)],  # equal as numbers, not as bytes
    [(np.nan, 0.4, 0.6, 0.5)] * 3,
])
def test_distinct_colours_equal_numpy_unique(rows):
    """Flat triangles' colours are deduplicated without a sort when all are the same bytes; the
    result is np.unique's, byte for byte."""
    from blendlib.core.fragment import distinct_colors

    colors = np.array(rows, dtype=np.float64)
    got, inverse = distinct_colors(colors)
    want, want_inverse = np.unique(colors, axis=0, return_inverse=True)
    assert got.tobytes() == want.tobytes() and got.shape == want.shape
    np.testing.assert_array_equal(inverse.reshape(-1), want_inverse.reshape(-1))


@pytest.mark.parametrize("seed", range(6))
def test_distinct_colours_of_many_rows_equal_numpy_unique(seed):
    """Many colours, some repeated, some differing in one channel only, negative ones and, in
    some draws, a -0.0 or a NaN: np.unique's rows, order and inverse, byte for byte."""
    from blendlib.core.fragment import distinct_colors

    rng = np.random.default_rng(seed)
    base = rng.choice([-1.5, -0.25, 0.0, 0.25, 0.5, 2.0], size=(40, 4))
    colors = base[rng.integers(0, 40, size=300)].copy()
    if seed == 4:
        colors[7, 2] = -0.0
    if seed == 5:
        colors[9, 0] = np.nan
    got, inverse = distinct_colors(colors)
    want, want_inverse = np.unique(colors, axis=0, return_inverse=True)
    assert 10 < want.shape[0] < 300
    assert got.tobytes() == want.tobytes() and got.shape == want.shape
    np.testing.assert_array_equal(inverse.reshape(-1), want_inverse.reshape(-1))


def test_blend_tables_are_kept_across_renders_by_content(monkeypatch):
    """A second render takes its blend tables from merger.RECENT_TABLES (none is built) and is
    identical; a table is never reused for another colour space or pass: renders that
    alternate them, each with the other's tables kept, equal the reference."""
    built = []
    original = merger.BlendTable

    class Counting(original):
        def __init__(self, lut, pairs=False):
            built.append(lut.shape[0])
            super().__init__(lut, pairs)

    monkeypatch.setattr(blending, "BlendTable", Counting)
    merger.RECENT_TABLES.clear()
    over = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
                dst_blend=BlendFactor.OneMinusSrcAlpha)
    first = render_scene(_scene(over, ColorSpace.Gamma))
    assert built and len(merger.RECENT_TABLES) == len(built)
    count = len(built)
    again = render_scene(_scene(over, ColorSpace.Gamma))
    assert len(built) == count  # every table came from the kept ones
    np.testing.assert_array_equal(first.color, again.color)
    add = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.One, dst_blend=BlendFactor.One)
    # 0 and 1 are the same in both colour spaces: only the key's colour space tells these palettes apart.
    pure = (1.0, 0.0, 1.0, 0.45)
    for p, space in ((over, ColorSpace.Gamma), (over, ColorSpace.Linear), (add, ColorSpace.Linear),
                     (add, ColorSpace.Gamma), (over, ColorSpace.Gamma)):
        scene = _scene(p, space, color=pure)
        np.testing.assert_array_equal(render_scene(scene).color, render_reference(scene)[0])
    assert len(built) > count  # the other passes and colour space built their own tables


def test_recent_tables_drop_the_least_recently_used_past_their_budget():
    lut = np.zeros((1, 256, 4), dtype=np.uint8)
    size = merger.BlendTable(lut).nbytes  # four (256,) uint32 tables
    assert size == 4 * 256 * 4
    kept = merger.RecentTables(max_bytes=3 * size)
    for key in "abc":
        kept.put(key, merger.BlendTable(lut))
    assert kept.get("a") is not None  # now the most recently used
    kept.put("d", merger.BlendTable(lut))
    assert kept.get("b") is None and all(kept.get(k) is not None for k in "acd")
    assert kept.nbytes == 3 * size and len(kept) == 3
    kept.put("huge", merger.BlendTable(np.zeros((4, 256, 4), dtype=np.uint8)))  # larger than the budget
    assert kept.get("huge") is None and len(kept) == 3
    kept.clear()
    assert len(kept) == 0 and kept.nbytes == 0


@pytest.mark.parametrize("hdr", [False, True])
def test_frame_output_split_over_threads_equals_one_thread(hdr):
    """The frame's conversion to float32 (flipped to row 0 = top) in row ranges on a pool equals
    the one-thread conversion, for an odd height and both buffer kinds."""
    from concurrent.futures import ThreadPoolExecutor

    buf = merger.FrameBuffers(37, 301, hdr, ColorSpace.Linear, (0.1, 0.2, 0.3, 1.0))
    rng = np.random.default_rng(5)
    if hdr:
        buf.color[:] = rng.uniform(-2, 5, size=buf.color.shape).astype(np.float32)
    else:
        buf.color[:] = rng.integers(0, 256, size=buf.color.shape, dtype=np.uint8)
    buf.depth[:] = rng.integers(0, 2**24, size=buf.depth.shape)
    buf.stencil[:] = rng.integers(0, 256, size=buf.stencil.shape, dtype=np.uint8)
    one = buf.output()
    with ThreadPoolExecutor(2) as pool:
        split = buf.output(pool, 2)
    for a, b in zip(one, split, strict=True):
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
    np.testing.assert_array_equal(one[1][0], (buf.depth.reshape(301, 37)[-1] / (2**24 - 1)).astype(np.float32))


@pytest.mark.parametrize("samples", [1, 4, 8])
@pytest.mark.parametrize("reach", [1 << 12, 1 << 22])
def test_span_ends_by_float_division_equal_integer_division(reach, samples, monkeypatch):
    """Span ends come from a float64 floor division when that is exact (numerators below
    2**53): equal, field by field, to the int64 division path on random triangles whose
    corners lie up to ``reach`` subpixels away (far outside a 40x32 frame: guard-band sized),
    with horizontal, vertical and near-degenerate edges and both windings; with MSAA, each
    sample's span and the rows' hulls of them too."""
    from blendlib.core import msaa, raster

    rng = np.random.default_rng(int(reach).bit_length())
    n = 4000
    X = rng.integers(-reach, reach, size=(n, 3), dtype=np.int64)
    Y = rng.integers(-reach, reach, size=(n, 3), dtype=np.int64)
    X[: n // 4] = rng.integers(-4 * 256, 44 * 256, size=(n // 4, 3))  # small ones near the frame
    Y[: n // 4] = rng.integers(-4 * 256, 36 * 256, size=(n // 4, 3))
    Y[n // 4: n // 3, 1] = Y[n // 4: n // 3, 0]  # horizontal edges
    X[n // 3: n // 2, 2] = X[n // 3: n // 2, 0]  # vertical edges
    X[n // 2: n // 2 + 200, 1] = X[n // 2: n // 2 + 200, 0] + 1  # nearly degenerate
    area2 = (X[:, 1] - X[:, 0]) * (Y[:, 2] - Y[:, 0]) - (X[:, 2] - X[:, 0]) * (Y[:, 1] - Y[:, 0])
    keep = area2 != 0
    X, Y, area2 = X[keep], Y[keep], area2[keep]
    labels = np.arange(area2.size, dtype=np.int64)
    offsets = None if samples == 1 else msaa.sample_offsets(samples)
    fast = raster._spans(X, Y, area2, labels, W, H, samples=offsets)
    monkeypatch.setattr(raster, "FLOAT_DIVISION_LIMIT", 0)
    exact = raster._spans(X, Y, area2, labels, W, H, samples=offsets)
    assert fast.count > 1000 and int(fast.length.sum()) > 10000 and fast.swap.any() and not fast.swap.all()
    if offsets is not None:  # some rows' samples are not all covered (or none of a pixel's)
        assert (fast.sample_x0 > fast.sample_x1).any() and (fast.sample_x0 != fast.x0[:, None]).any()
    for name in raster.Rows.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(fast, name), getattr(exact, name), err_msg=name)


def test_matrices_of_many_renderers_equal_written_out_sums():
    """The batched 4x4 products and cofactors of the vertex stage equal the written-out
    Python-float sums of docs/pipeline.md §1 (mirroring matrices included)."""
    from blendlib.core import vertex

    rng = np.random.default_rng(11)
    worlds = rng.normal(size=(9, 4, 4))
    worlds[:, 3] = (0.0, 0.0, 0.0, 1.0)
    worlds[4, :3, 0] *= -1.0  # negative determinant
    view = rng.normal(size=(4, 4))

    def written(a, b):
        return [[((a[i][0] * b[0][j] + a[i][1] * b[1][j]) + a[i][2] * b[2][j]) + a[i][3] * b[3][j]
                 for j in range(4)] for i in range(4)]

    many = vertex.matmul4_many(view, worlds)
    nmats, dets = vertex.normal_matrices(worlds)
    assert (dets < 0).sum() >= 1 and (dets > 0).sum() >= 1
    for k, w in enumerate(worlds.tolist()):
        assert many[k].tolist() == written(view.tolist(), w)
        m = [row[:3] for row in w[:3]]
        c = [[m[(i + 1) % 3][(j + 1) % 3] * m[(i + 2) % 3][(j + 2) % 3]
              - m[(i + 1) % 3][(j + 2) % 3] * m[(i + 2) % 3][(j + 1) % 3] for j in range(3)] for i in range(3)]
        det = (m[0][0] * c[0][0] + m[0][1] * c[0][1]) + m[0][2] * c[0][2]
        assert dets[k] == det
        assert nmats[k].tolist() == ([[-v for v in row] for row in c] if det < 0 else c)


@pytest.mark.parametrize("ztest", [CompareFunction.LEqual, CompareFunction.Less, CompareFunction.GEqual,
                                   CompareFunction.Greater, CompareFunction.Equal])
def test_colourless_passes_skip_shading_and_take_extreme_depths(ztest, monkeypatch):
    """A ``ZWrite On, ColorMask 0`` prepass of a self-overlapping lit, textured mesh, then its
    blended pass: the prepass's fragments are not shaded, and with ZTest Less/LEqual/Greater/
    GEqual (no stencil) its depth is the per-pixel minimum/maximum, applied in any order. A
    colourless pass with a stencil op, and one with ZTest Equal, take the ordered path. The
    frame equals the reference, one thread and two, observed, and with every pass shaded in full."""
    from blendlib.core import fragment, pipeline, prepare
    from blendlib.core.vocabulary import StencilOp, Texture

    texture = Texture(np.random.default_rng(5).uniform(0, 1, (8, 8, 4)).astype(np.float32), name="t")
    blend = dict(blend=True, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha)
    knot = Material(name="Knot", queue=Queue.Transparent, color=(0.9, 0.8, 0.7, 0.6), main_tex=texture,
                    main_tex_filter=TextureFilter.Point,
                    passes=(Pass(cull=Cull.Off, zwrite=True, ztest=ztest, color_mask=frozenset()),
                            Pass(cull=Cull.Off, zwrite=False, **blend)))
    stamp = Material(name="Stamp", queue=Queue.Transparent, color=(0.2, 0.5, 0.9, 0.5), lighting=Lighting.Unlit,
                     passes=(Pass(zwrite=True, color_mask=frozenset(), stencil=True, stencil_ref=2,
                                  stencil_pass=StencilOp.Replace),
                             Pass(zwrite=False, stencil=True, stencil_ref=2, stencil_comp=CompareFunction.Equal,
                                  **blend)))
    floor = Material(name="Floor", color=(0.4, 0.4, 0.4, 1.0), passes=(Pass(),))
    scene = DrawScene(camera=sc.camera(96, 80, eye=(0.4, 0.9, 3.5)), light=sc.Light(direction=(0.3, 0.6, 0.7)),
                      renderers=(sc.renderer(sc.quad(-3, -3, 3, 3, z=-1.2), floor, name="Floor"),
                                 sc.renderer(sc.uv_sphere(0.9, 18, 12), knot, name="Knot",
                                             matrix=sc.scale(1.0, 0.6, 1.4)),
                                 sc.renderer(sc.fan((0.3, -0.2, 0.5), 0.8, 7), stamp, name="Stamp")))
    colourless, order_free = [], []
    shade_original, free_original = fragment.shade_colourless_chunk, ordering.order_free_depth

    def counting_shade(*args):
        colourless.append(1)
        return shade_original(*args)

    def counting_free(p):
        free = free_original(p)
        order_free.append(free)
        return free

    monkeypatch.setattr(fragment, "shade_colourless_chunk", counting_shade)
    monkeypatch.setattr(ordering, "order_free_depth", counting_free)
    frames = [render_scene(scene, workers=1), render_scene(scene, workers=2, chunk_candidates=301),
              render_scene(scene, workers=2, observer=pipeline.FrameObserver())]
    assert colourless  # both prepasses skip shading
    assert any(order_free) == (ztest is not CompareFunction.Equal)
    assert not all(order_free)  # the stencil prepass is merged in order
    colourless.clear()
    monkeypatch.setattr(prepare, "chunk_shading", lambda p: fragment.shade_chunk)  # every pass shaded in full
    frames.append(render_scene(scene, workers=2))
    assert not colourless
    color, depth, stencil = render_reference(scene)
    assert (stencil == 2).sum() > 50
    for frame in frames:
        np.testing.assert_array_equal(frame.color, color)
        np.testing.assert_array_equal(frame.depth, depth)
        np.testing.assert_array_equal(frame.stencil, stencil)


def test_passes_selecting_the_same_triangles_share_their_coverage(monkeypatch):
    """Two passes of one material with one Cull cover the same pixels: their rows are computed
    once (batched coverage and per-renderer preparation alike) and equal each pass's own."""
    from blendlib.core import pipeline, prepare, raster, vertex

    camera = sc.camera(80, 60, eye=(0.0, 0.0, 2.5))
    a, b = vertex.setup_renderers([vertex.SetupInput(sc.uv_sphere(0.9, 14, 9), np.eye(4)),
                                   vertex.SetupInput(sc.quad(-1, -1, 1, 1), sc.translate(0.3, 0.0, 0.2))], camera)
    passes = [(a, vertex.cull_select(a, Cull.Back)), (b, vertex.cull_select(b, Cull.Off)),
              (a, vertex.cull_select(a, Cull.Back)), (a, vertex.cull_select(a, Cull.Front)),
              (b, vertex.cull_select(b, Cull.Off))]
    spans = []
    original = raster._spans
    monkeypatch.setattr(raster, "_spans", lambda *args: spans.append(args[0].shape[0]) or original(*args))
    many = raster.coverage_rows_many(passes, camera.width, camera.height)
    assert len(spans) == 1 and spans[0] == sum(sel.size for _, sel in passes[:2]) + passes[3][1].size
    assert many[2].tri is many[0].tri and many[4].y is many[1].y and many[3].tri is not many[0].tri
    for (setup, selected), rows in zip(passes, many, strict=True):
        own = original(np.take(setup.X, selected, axis=0), np.take(setup.Y, selected, axis=0),
                       np.take(setup.area2, selected), selected, camera.width, camera.height)
        for name in raster.Rows.__dataclass_fields__:
            np.testing.assert_array_equal(getattr(rows, name), getattr(own, name), err_msg=name)

    covered = []
    coverage = raster.coverage_rows
    monkeypatch.setattr(raster, "coverage_rows", lambda *args, **kw: covered.append(1) or coverage(*args, **kw))
    monkeypatch.setattr(prepare, "PARALLEL_PREPARE_TRIANGLES", 0)  # per-renderer preparation
    glass = Material(name="Glass", queue=Queue.Transparent, color=(0.9, 0.3, 0.2, 0.5),
                     passes=(Pass(zwrite=True, color_mask=frozenset()),
                             Pass(zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
                                  dst_blend=BlendFactor.OneMinusSrcAlpha),
                             Pass(cull=Cull.Front, zwrite=False, blend=True, src_blend=BlendFactor.One,
                                  dst_blend=BlendFactor.One)))
    scene = DrawScene(camera=camera, renderers=(sc.renderer(sc.uv_sphere(0.9, 14, 9), glass, name="Glass"),
                                                sc.renderer(sc.uv_sphere(0.5, 10, 7), glass, name="Small",
                                                            matrix=sc.translate(0.4, 0.2, 0.6))),
                      light=sc.Light(direction=(0.2, 0.5, 0.8)))
    color, depth, stencil = render_reference(scene)
    for observer in (None, pipeline.FrameObserver()):
        covered.clear()
        frame = render_scene(scene, workers=2, observer=observer)
        assert len(covered) == 4  # two Culls of two renderers, not six passes
        np.testing.assert_array_equal(frame.color, color)
        np.testing.assert_array_equal(frame.depth, depth)
        np.testing.assert_array_equal(frame.stencil, stencil)


def test_small_frames_blend_through_tables_kept_from_larger_ones(monkeypatch):
    """A frame too small for building a blend table (fewer fragments than table rows) uses a
    table an earlier, larger render of the same palette kept (a viewport's reduced frame after
    its full one), in either of its forms: the frame equals the reference and the same frame
    drawn without kept tables."""
    from dataclasses import replace

    lookups = []
    original = merger.BlendTable.lookup

    def counting(self, stored, ids):
        lookups.append(ids.size)
        return original(self, stored, ids)

    monkeypatch.setattr(merger.BlendTable, "lookup", counting)
    built = []
    table_class = merger.BlendTable

    class Counting(table_class):
        def __init__(self, lut, pairs=False):
            built.append(pairs)
            super().__init__(lut, pairs)

    monkeypatch.setattr(blending, "BlendTable", Counting)
    # The large frame's 1280 fragments of the top colour get a table of channel pairs; the small
    # frame's 63 would ask for the other form, which the kept table stands in for.
    monkeypatch.setattr(blending, "PAIR_TABLE_FRAGMENTS", 512)
    over = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
                dst_blend=BlendFactor.OneMinusSrcAlpha)
    big = _scene(over, ColorSpace.Linear)
    small = replace(big, camera=sc.screen_camera(9, 7))  # 63 pixels, fewer than a table's 256 rows
    merger.RECENT_TABLES.clear()
    fresh = render_scene(small)
    assert not lookups
    render_scene(big)
    assert built == [True]
    lookups.clear()
    kept = render_scene(small)
    assert lookups and built == [True]  # the top quad's colour blended through the kept table
    color, depth, stencil = render_reference(small)
    for frame in (fresh, kept):
        np.testing.assert_array_equal(frame.color, color)
        np.testing.assert_array_equal(frame.depth, depth)


def test_small_frames_use_bands_only_for_fragments_shaded_one_by_one(monkeypatch):
    """Below BAND_PIXELS, a batch is drawn in screen bands only when its calls are large: many
    candidate fragments a call, or enough fragments shaded one by one (smooth Lambert, filtered
    textures) with many in each call that shades so. Cheap per-fragment work (flat or constant
    colours, texel palettes) and many small calls run faster in one thread than two contending
    for the GIL. Either way the frame equals one thread's."""
    from blendlib.core import pipeline, raster

    monkeypatch.setattr(pipeline, "BAND_PIXELS", PRODUCTION_BAND_PIXELS)
    cuts = []
    original = raster.band_cuts
    monkeypatch.setattr(raster, "band_cuts", lambda *args: cuts.append(1) or original(*args))
    smooth = Material(name="Smooth", color=(0.8, 0.6, 0.4, 1.0), passes=(Pass(),))
    flat = sc.unlit((0.3, 0.7, 0.2, 1.0), name="Flat")
    camera = sc.camera(600, 400, eye=(0.0, 0.0, 1.5))  # 240k pixels, below BAND_PIXELS, the ball filling them
    for material, banded in ((flat, False), (smooth, True)):
        scene = DrawScene(camera=camera, light=sc.Light(direction=(0.2, 0.5, 0.8)),
                          renderers=(sc.renderer(sc.uv_sphere(0.9, 24, 16), material, name="Ball"),))
        cuts.clear()
        two = render_scene(scene, workers=2)
        assert bool(cuts) == banded
        one = render_scene(scene, workers=1)
        np.testing.assert_array_equal(two.color, one.color)
        np.testing.assert_array_equal(two.depth, one.depth)
    # Twenty small smooth balls of their own colours (not fused): as many fragments shaded one by
    # one, but few in each call.
    balls = tuple(sc.renderer(sc.uv_sphere(0.2, 24, 16), replace(smooth, name=f"Smooth{k}",
                                                                 color=(0.8, 0.6, 0.02 * k, 1.0)),
                              name=f"Ball{k}", matrix=sc.translate(-0.9 + 0.45 * (k % 5), -0.6 + 0.4 * (k // 5), 0.0))
                  for k in range(20))
    scene = DrawScene(camera=camera, light=sc.Light(direction=(0.2, 0.5, 0.8)), renderers=balls)
    steps = []
    original_step = pipeline._draw_step
    monkeypatch.setattr(pipeline, "_draw_step", lambda frame, step, *args: steps.append(
        [int(pr.rows.length.sum()) for pr in step]) or original_step(frame, step, *args))
    cuts.clear()
    render_scene(scene, workers=2)
    shaded = sum(sum(counts) for counts in steps)
    assert not cuts and shaded >= pipeline.BAND_SHADED_FRAGMENTS
    assert shaded < pipeline.BAND_SHADED_CALL_FRAGMENTS * sum(len(counts) for counts in steps)
    # A flat ball filling a larger frame: a call of many fragments, drawn in bands.
    big = sc.camera(1000, 560, eye=(0.0, 0.0, 1.2))
    cuts.clear()
    render_scene(DrawScene(camera=big, renderers=(sc.renderer(sc.uv_sphere(0.9, 24, 16), flat),)), workers=2)
    assert cuts and steps[-1][0] >= pipeline.BAND_CALL_FRAGMENTS
    monkeypatch.setattr(pipeline, "BAND_PIXELS", 600 * 400)  # a frame this large: bands whatever the work
    cuts.clear()
    render_scene(DrawScene(camera=camera, renderers=(sc.renderer(sc.uv_sphere(0.9, 24, 16), flat),)), workers=2)
    assert cuts


def _early_scene(ztest: CompareFunction, zwrite: bool, stencil: bool = False, msaa: int = 1) -> DrawScene:
    """A back plane (drawn first, ZWrite On), then one call under test whose single mesh holds, in
    this order: a nearer quad over the middle, a quad at exactly the back plane's depth, and a
    farther one — Lambert shaded (normals interpolated), so every fragment is shaded one by one."""
    back = Material(name="Back", queue=Queue.Geometry, color=(0.2, 0.4, 0.9, 1.0), passes=(Pass(),))
    p = Pass(ztest=ztest, zwrite=zwrite, stencil=stencil, stencil_comp=CompareFunction.Always,
             stencil_ref=3)
    tested = Material(name="Tested", queue=Queue.Geometry, queue_offset=1, color=(0.9, 0.5, 0.1, 1.0), passes=(p,))
    parts = [sc.quad(-0.6, -0.6, 0.6, 0.6, z=0.5), sc.quad(-2, -2, 2, 2, z=0.0), sc.quad(-1.5, -1, 1.5, 1, z=-0.5)]
    mesh = sc.make_mesh(np.concatenate([m.positions for m in parts]),
                        np.concatenate([m.triangles + 4 * k for k, m in enumerate(parts)]))
    return DrawScene(camera=sc.camera(W, H, eye=(0.0, 0.3, 4.0)), light=sc.Light(direction=(0.3, 0.5, 0.8)),
                     msaa=msaa, renderers=(sc.renderer(sc.quad(-2, -2, 2, 2, z=0.0), back, name="Back"),
                                           sc.renderer(mesh, tested, name="Tested")))


@pytest.mark.parametrize("zwrite", [True, False])
@pytest.mark.parametrize("ztest", [f for f in CompareFunction if f is not CompareFunction.Never])  # not ShaderLab's
def test_early_depth_test_drops_failing_fragments_and_equals_reference(ztest, zwrite, monkeypatch):
    """Fragments failing the depth test against the depth stored when their chunk is shaded are
    dropped before shading where that cannot change the frame: every test but Always and (with
    ZWrite) NotEqual — there a nearer fragment of the same call may write a depth that the
    next one, equal to the old, then passes. The frame equals the scalar reference either way."""
    from blendlib.core import fragment

    dropped = []
    original = fragment.compare

    def counting(func, a, b):
        out = original(func, a, b)
        dropped.append(int(out.size - np.count_nonzero(out)))
        return out

    monkeypatch.setattr(fragment, "compare", counting)
    scene = _early_scene(ztest, zwrite)
    frame = render_scene(scene, workers=2)
    color, depth, stencil = render_reference(scene)
    np.testing.assert_array_equal(frame.color, color)
    np.testing.assert_array_equal(frame.depth, depth)
    early = ztest in (CompareFunction.Less, CompareFunction.LEqual, CompareFunction.Greater, CompareFunction.GEqual,
                      CompareFunction.Equal) or (ztest is CompareFunction.NotEqual and not zwrite)
    assert (sum(dropped) > 100) == early, (ztest, zwrite, dropped)
    # Never where the merge must see every fragment: stencil (ZFail), MSAA, observers.
    assert not fragment.early_depth_applies(Pass(ztest=ztest, zwrite=zwrite, stencil=True), 1, False)
    assert not fragment.early_depth_applies(Pass(ztest=ztest, zwrite=zwrite), 4, False)
    assert not fragment.early_depth_applies(Pass(ztest=ztest, zwrite=zwrite), 1, True)


def test_early_depth_test_is_off_with_stencil_and_msaa(monkeypatch):
    """With stencil (a failed depth test runs the ZFail operation) and MSAA the fragments reach the
    merger; the frames equal the scalar reference."""
    from blendlib.core import fragment

    decided = []
    original = fragment.early_depth_applies
    monkeypatch.setattr(fragment, "early_depth_applies",
                        lambda p, samples, observed: decided.append((p.stencil, samples,
                                                                     original(p, samples, observed))) or decided[-1][2])
    for scene in (_early_scene(CompareFunction.LEqual, True, stencil=True),
                  _early_scene(CompareFunction.LEqual, True, msaa=4)):
        frame = render_scene(scene, workers=1)
        color, depth, stencil = render_reference(scene)
        np.testing.assert_array_equal(frame.color, color)
        np.testing.assert_array_equal(frame.stencil, stencil)
    assert sorted(decided) == [(False, 1, True), (False, 4, False), (False, 4, False), (True, 1, False)]


def test_segment_sums_count_empty_segments_as_zero():
    from blendlib.core.fragment import _segment_sums

    values = np.array([True, False, True, True, False, True])
    counts = np.array([0, 2, 0, 3, 1, 0], dtype=np.int64)
    np.testing.assert_array_equal(_segment_sums(values, counts), [0, 1, 0, 2, 1, 0])


def _rows_at_random(seed: int, count: int, width: int) -> raster.Rows:
    """Rows of random spans and edge coefficients of guard-band size (|dy| up to 2**27, the
    extent of the guard band in subpixels), some clockwise, some of one pixel."""
    rng = np.random.default_rng(seed)
    length = rng.integers(1, 40, count).astype(np.int64)
    length[rng.random(count) < 0.3] = 1
    x0 = rng.integers(0, width - 40, count).astype(np.int64)
    big = lambda: rng.integers(-(2**27), 2**27, count).astype(np.int64)  # noqa: E731
    return raster.Rows(tri=rng.integers(0, 50, count).astype(np.int64), y=rng.integers(0, 300, count).astype(np.int64),
                       x0=x0, length=length, c0=big() * 3000, c1=big() * 3000, dy0=big(), dy1=big(),
                       swap=rng.random(count) < 0.5, area=rng.integers(1, 2**50, count).astype(np.int64))


def _barycentrics_pixel_by_pixel(rows: raster.Rows, width: int) -> tuple[np.ndarray, np.ndarray]:
    """docs/pipeline.md §4 written out per fragment: pixels and (3, N) weights, E_k = c_k - dy_k*Px
    at Px = x*S + HALF, the third edge area - E0 - E1, a clockwise row's second and third swapped."""
    pix, weights = [], []
    for r in range(rows.count):
        x = rows.x0[r] + np.arange(rows.length[r], dtype=np.int64)
        px = x * SUBPIXEL + HALF
        ea = rows.c0[r] - rows.dy0[r] * px
        eb = rows.c1[r] - rows.dy1[r] * px
        ec = rows.area[r] - ea - eb
        if rows.swap[r]:
            eb, ec = ec, eb
        pix.append(rows.y[r] * width + x)
        weights.append(np.stack([e / np.float64(rows.area[r]) for e in (ea, eb, ec)]))
    return np.concatenate(pix), np.concatenate(weights, axis=1)


@pytest.mark.parametrize("arithmetic", ["float64", "int64"])
@pytest.mark.parametrize("global_index", [True, False])
@pytest.mark.parametrize("seed", [0, 1])
def test_rasterized_barycentrics_equal_the_per_pixel_formula(arithmetic, global_index, seed, monkeypatch):
    # Row coefficients stand in for the per-fragment x, Px and swap; chunks past
    # GLOBAL_INDEX_FRAGMENTS count from each row's start. The edge functions are made in float64
    # where that is exact (these rows' values are: below 2**53), else in int64. All give the
    # formula's bits.
    if not global_index:
        monkeypatch.setattr(raster, "GLOBAL_INDEX_FRAGMENTS", 0)
    width = 1000
    rows = _rows_at_random(seed, 400, width)
    assert raster._float_exact(rows.c0, rows.c1, rows.dy0 * SUBPIXEL, rows.dy1 * SUBPIXEL, rows.area, 0)
    if arithmetic == "int64":
        monkeypatch.setattr(raster, "FLOAT_DIVISION_LIMIT", 0)
    pix, weights = _barycentrics_pixel_by_pixel(rows, width)
    for start, stop in ((0, rows.count), (37, 250), (5, 6)):
        first = int(rows.length[:start].sum())
        n = int(rows.length[start:stop].sum())
        frags = raster.rasterize_rows(rows, start, stop, width)
        np.testing.assert_array_equal(frags.pix, pix[first:first + n])
        assert frags.bary.view(np.uint64).tolist() == weights[:, first:first + n].view(np.uint64).tolist()


def test_rasterized_barycentrics_of_edge_functions_past_float64_s_integers_are_made_in_int64(monkeypatch):
    # Slopes of 2**42 subpixels a pixel over thousands of pixels: s*step passes 2**53, where
    # float64 no longer holds every integer. The bound sends these rows to int64, which gives the
    # formula's bits; made in float64 anyway, they would not be.
    width = 1000
    rows = _rows_at_random(3, 400, width)
    rng = np.random.default_rng(4)
    rows.dy0 = rng.integers(-(2**34), 2**34, rows.count).astype(np.int64)
    rows.c0 = rng.integers(-(2**50), 2**50, rows.count).astype(np.int64)
    rows.area = rng.integers(2**50, 2**52, rows.count).astype(np.int64)
    pix, weights = _barycentrics_pixel_by_pixel(rows, width)
    frags = raster.rasterize_rows(rows, 0, rows.count, width)
    np.testing.assert_array_equal(frags.pix, pix)
    assert frags.bary.view(np.uint64).tolist() == weights.view(np.uint64).tolist()
    monkeypatch.setattr(raster, "_float_exact", lambda *args: True)
    assert not np.array_equal(raster.rasterize_rows(rows, 0, rows.count, width).bary, weights)


def test_kept_world_normals_equal_the_normals_of_each_chunk_s_triangles(monkeypatch):
    """A small mesh's world-space corner normals are made once for all its triangles and kept with
    its setup; each call's gather equals §1's sums over that call's triangles alone, bit for bit,
    as does a large mesh's (not kept), under a non-uniform and a mirroring matrix."""
    from blendlib.core import vertex

    sphere = sc.uv_sphere(0.9, 14, 9)
    camera = sc.camera(80, 60, eye=(0.0, 0.0, 2.5))
    matrix = sc.translate(0.2, -0.1, 0.3) @ sc.scale(-1.3, 0.7, 1.1)
    rng = np.random.default_rng(5)
    subsets = [rng.choice(sphere.triangles.shape[0], size=k, replace=False) for k in (1, 17, 60)]

    def expected(setup, src):
        """§1: ``(N[i][0]*x + N[i][1]*y) + N[i][2]*z`` per corner, with the setup's normal matrix."""
        corners = np.asarray(setup.object_normals, dtype=np.float64)[src]
        n = setup.normal_matrix
        return np.stack([(n[i, 0] * corners[..., 0] + n[i, 1] * corners[..., 1]) + n[i, 2] * corners[..., 2]
                         for i in range(3)], axis=-1)

    for kept in (True, False):
        if not kept:
            monkeypatch.setattr(vertex, "KEPT_WORLD_NORMALS", 10)
        (setup,) = vertex.setup_renderers([vertex.SetupInput(sphere, matrix)], camera)
        assert setup.normal_matrix is not None and np.linalg.det(setup.normal_matrix) != 0
        for src in subsets:
            got = setup.world_normals_of(src)
            assert got.shape == (src.size, 3, 3)
            np.testing.assert_array_equal(got, expected(setup, src))
        assert (setup._world_normal_corners is not None) == kept
