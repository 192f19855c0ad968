"""MSAA and AlphaToMask (docs/pipeline.md §10, SPEC §12): the core equals the scalar reference bit
for bit at 2, 4 and 8 samples, coverage is watertight at every sample, AlphaToMask follows
llvmpipe's rule, and msaa 1 is the single-sampled pipeline unchanged.

The agreement with OpenGL (llvmpipe, 4x) is in tests/core/test_msaa_gl.py."""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from blendlib import render_scene
from blendlib.core import msaa
from blendlib.core.records import FrameObserver
from blendlib.core.scene import SceneError
from blendlib.core.vocabulary import (
    BlendFactor,
    CompareFunction,
    Cull,
    Lighting,
    Material,
    Pass,
    Queue,
    StencilOp,
    Texture,
    TextureFilter,
    TextureWrap,
)
from blendlib.explain import sorted_reference
from tests.reference import scalar
from tests.reference import scenes as sc
from tests.reference.random_scenes import describe, scenes, seeded_scene
from tests.reference.sweeps import SWEEPS

PROPERTY = settings(max_examples=100, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def assert_same(scene, **kw):
    """Core frame == scalar reference, bit for bit (colour resolved, depth and stencil of sample 0)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        frame = render_scene(scene, workers=2, **kw)
    color, depth, stencil = scalar.render_reference(scene)
    for name, ours, ref in (("color", frame.color, color), ("depth", frame.depth, depth),
                            ("stencil", frame.stencil, stencil)):
        diff = ours != ref
        if diff.ndim == 3:
            diff = diff.any(axis=-1)
        ys, xs = np.nonzero(diff)
        assert not diff.any(), (f"{name}: {int(diff.sum())} pixels differ, first (row, col) "
                                f"{list(zip(ys.tolist(), xs.tolist(), strict=True))[:5]}\n{describe(scene)}")
    return frame


# ------------------------------------------------------------------ the scalar reference


@PROPERTY
@given(scenes(msaa=0))
def test_random_msaa_scenes_equal_reference(scene):
    """2, 4 or 8 samples, AlphaToMask on some passes, every pass state (shared vertices: shared
    edges, duplicate and coincident triangles, self-overlap in one draw call)."""
    assert_same(scene)


@settings(PROPERTY, max_examples=60)
@given(scenes(shared=False, msaa=0))
def test_random_msaa_scenes_distinct_triangles_equal_reference(scene):
    assert_same(scene)


@pytest.mark.parametrize("samples", [2, 4, 8])
@pytest.mark.parametrize("seed", range(0, 60, 3))
def test_seeded_msaa_scenes_equal_reference_in_small_chunks(seed, samples):
    """A fixed batch, drawn in chunks of 7 candidates: a chunk boundary inside a triangle's rows
    and inside a fused call's rows (the fragments of a chunk stay one per candidate pixel)."""
    scene = seeded_scene(seed, msaa=samples)
    assert_same(scene)
    assert_same(scene, chunk_candidates=7)


@pytest.mark.parametrize("name", ["ztest", "stencil", "alpha_test", "offset", "cull", "colormask_linear_ldr",
                                  "texture_linear", "blend_plain_gamma_ldr", "blend_linear_hdr"])
def test_sweeps_at_4x_equal_reference(name):
    """The state sweeps (tests/reference/sweeps.py) under 4x MSAA, AlphaToMask on every pass (their
    quads' edges on pixel boundaries: every sample of a pixel is covered alike; AlphaToMask, per-sample
    depth and stencil decide)."""
    scene = SWEEPS[name]()
    scene = replace(scene, msaa=4, renderers=tuple(
        replace(r, material=replace(r.material, passes=tuple(replace(p, alpha_to_mask=True)
                                                             for p in r.material.draw_passes)))
        for r in scene.renderers))
    assert_same(scene)


def test_msaa_1_ignores_alpha_to_mask():
    """msaa 1: AlphaToMask has no effect (GL applies it only with sample buffers; the lead's
    decision): a frame with it on every pass equals the frame without."""
    for seed in range(12):
        scene = seeded_scene(seed, msaa=2)  # AlphaToMask on some passes
        single = replace(scene, msaa=1)
        plain = replace(single, renderers=tuple(
            replace(r, material=replace(r.material, passes=tuple(replace(p, alpha_to_mask=False)
                                                                 for p in r.material.draw_passes)))
            for r in single.renderers))
        a, b = render_scene(single), render_scene(plain)
        assert np.array_equal(a.color, b.color) and np.array_equal(a.depth, b.depth)
        assert_same(single)


def test_band_renders_of_msaa_frames_are_their_rows():
    scene = seeded_scene(5, msaa=4)
    whole = render_scene(scene)
    h = scene.camera.height
    part = render_scene(scene, band=(3, h - 2))
    assert np.array_equal(part.color, whole.color[2:h - 3]) and np.array_equal(part.stencil, whole.stencil[2:h - 3])


# ------------------------------------------------------------------ sample positions, AlphaToMask


def test_sample_positions_are_the_standard_patterns():
    """Direct3D's standard patterns (D3D11_STANDARD_MULTISAMPLE_PATTERN; Vulkan's standard sample
    locations), in 1/16 pixel from the pixel centre; here from the lower-left corner, y up, as GL's
    GL_SAMPLE_POSITION reports llvmpipe's 4x pattern."""
    from_centre = {
        2: [(4, 4), (-4, -4)],
        4: [(-2, -6), (6, -2), (-6, 2), (2, 6)],
        8: [(1, -3), (-1, 3), (5, 1), (-3, -5), (-5, 5), (-7, -1), (3, 7), (7, -7)],
    }
    for n, table in from_centre.items():
        assert (msaa.sample_offsets(n) == (np.array(table) + 8) * 16).all()
    assert (msaa.sample_offsets(1) == [[128, 128]]).all()
    with pytest.raises(ValueError):
        msaa.sample_offsets(3)


def test_alpha_to_mask_is_llvmpipes_rule():
    """lp_build_sample_alpha_to_coverage: sample s of N covered iff alpha > s/N (the raw alpha, no
    clamp): ceil(N*alpha) samples filled from sample 0."""
    alpha = np.array([-0.1, 0.0, 0.1, 0.25, 0.2500001, 0.5, 0.51, 0.75, 0.76, 1.0, 1.5])
    assert msaa.alpha_to_mask(alpha, 4).tolist() == [0, 0, 1, 1, 3, 3, 7, 7, 15, 15, 15]
    assert msaa.alpha_to_mask(alpha, 2).tolist() == [0, 0, 1, 1, 1, 1, 3, 3, 3, 3, 3]
    eighths = msaa.alpha_to_mask(np.arange(9) / 8 + 1e-9, 8)
    assert eighths.tolist() == [(1 << k) - 1 for k in range(1, 9)] + [255]


def _white_quad_scene(samples, x0, y0, x1, y1, alpha=1.0, alpha_to_mask=False, alpha_test=False, cutoff=0.5):
    """A white Unlit quad over black, Blend Off, in HDR: a pixel's resolved value is the share of
    its samples the quad wrote."""
    p = Pass(cull=Cull.Off, alpha_to_mask=alpha_to_mask, alpha_test=alpha_test)
    quad = sc.renderer(sc.quad(x0, y0, x1, y1), sc.unlit((1, 1, 1, alpha), passes=(p,), cutoff=cutoff))
    return sc.scene(sc.screen_camera(8, 8), quad, hdr=True, clear_color=(0, 0, 0, 0), msaa=samples)


@pytest.mark.parametrize("samples", [2, 4, 8])
def test_a_pixel_edge_covers_the_samples_on_its_side(samples):
    """A quad whose right edge is the vertical line x = 3 + 8.5/16 (window units): in column 3,
    exactly the samples left of it are covered (positions are whole 16ths: none on the line); its
    top edge y = 5 + 4.5/16 likewise in row 5 (y up: the samples below it)."""
    offsets = msaa.sample_offsets(samples) / 256
    frame = render_scene(_white_quad_scene(samples, 0.0, 0.0, 3 + 8.5 / 16, 5 + 4.5 / 16))
    h = 8
    left = np.mean(offsets[:, 0] < 8.5 / 16)
    low = np.mean(offsets[:, 1] < 4.5 / 16)
    corner = np.mean((offsets[:, 0] < 8.5 / 16) & (offsets[:, 1] < 4.5 / 16))
    assert frame.color[h - 1 - 2, 3, 0] == np.float32(left)  # window row 2: inside in y
    assert frame.color[h - 1 - 5, 1, 0] == np.float32(low)  # window row 5, column 1: inside in x
    assert frame.color[h - 1 - 5, 3, 0] == np.float32(corner)
    assert frame.color[h - 1 - 2, 1, 0] == 1.0 and frame.color[h - 1 - 2, 4, 0] == 0.0


@pytest.mark.parametrize("samples", [2, 4, 8])
def test_alpha_to_mask_writes_its_share_of_the_samples(samples):
    for alpha in (0.0, 0.2, 0.3, 0.5, 0.6, 0.9, 1.0):
        frame = render_scene(_white_quad_scene(samples, 0, 0, 8, 8, alpha, alpha_to_mask=True))
        expected = math.ceil(samples * alpha) / samples  # alpha > s/N for s < N*alpha
        assert np.all(frame.color[..., 0] == np.float32(expected)), (samples, alpha)
        # the written samples hold alpha, the others 0: their float32 sum in sample order, times 1/N
        total = np.float32(0.0)
        for _ in range(math.ceil(samples * alpha)):
            total += np.float32(alpha)
        assert np.all(frame.color[..., 3] == total * np.float32(1 / samples))


def test_alpha_test_discards_the_whole_pixel_before_alpha_to_mask():
    """clip(a - _Cutoff) runs once per pixel, before coverage: 0.3 < 0.5 writes no sample; 0.6
    passes and AlphaToMask then keeps 3 of 4 samples (0.6 > 0, 1/4, 2/4)."""
    dropped = render_scene(_white_quad_scene(4, 0, 0, 8, 8, 0.3, alpha_to_mask=True, alpha_test=True))
    kept = render_scene(_white_quad_scene(4, 0, 0, 8, 8, 0.6, alpha_to_mask=True, alpha_test=True))
    assert np.all(dropped.color == 0.0)
    assert np.all(kept.color[..., 0] == np.float32(0.75))


def test_shading_is_once_per_pixel_at_its_centre():
    """A pixel half covered by a quad whose texture changes at the quad's edge: every covered sample
    takes the colour at the pixel centre (outside the quad here: the texture coordinates there are
    extrapolated from the triangle's plane, and Clamp keeps the last texel), not at the sample."""
    px = np.zeros((1, 2, 4), np.float32)
    px[0, 0] = (1, 0, 0, 1)
    px[0, 1] = (0, 0, 1, 1)
    tex = Texture(px, encoding="Data", name="two")
    mat = sc.unlit((1, 1, 1, 1), passes=(Pass(cull=Cull.Off),), main_tex=tex, main_tex_filter=TextureFilter.Point,
                   main_tex_wrap=TextureWrap.Clamp)
    # u = 0..1 across x = 0..3.5: pixel 3's centre (x 3.5) is u = 1, the blue texel (clamped)
    scene = sc.scene(sc.screen_camera(8, 8), sc.renderer(sc.quad(0.0, 0.0, 3.5, 8.0), mat), hdr=True,
                     clear_color=(0, 0, 0, 0), msaa=4)
    frame = render_scene(scene)
    assert frame.color[4, 3].tolist() == [0.0, 0.0, 0.5, 0.5]  # two samples, blue (pixel centre)
    assert frame.color[4, 0].tolist() == [1.0, 0.0, 0.0, 1.0]


# ------------------------------------------------------------------ watertightness per sample


class _SampleCounter(FrameObserver):
    """Counts, per draw call, how often each sample of each pixel is covered."""

    exact_boundaries = False
    per_sample = True

    def __init__(self, pixels: int, samples: int):
        self.samples = samples
        self.counts: dict[int, np.ndarray] = {}
        self.pixels = pixels

    def fragments(self, call, frags, outcome):
        counts = self.counts.setdefault(call.index, np.zeros((self.pixels, self.samples), dtype=np.int64))
        covered = msaa.mask_bits(frags.coverage, self.samples)
        assert np.array_equal(covered, outcome != -1)
        np.add.at(counts, frags.pix, covered.astype(np.int64))


def _sample_counts(scene):
    """Per draw call (1, 2, ...): (H*W, N) coverage counts from the core and from the scalar reference."""
    n, w, h = scene.msaa, scene.camera.width, scene.camera.height
    observer = _SampleCounter(w * h, n)
    render_scene(scene, observer=observer)
    log = scalar.FragmentLog()
    scalar.render_reference(scene, log=log)
    ref: dict[int, np.ndarray] = {}
    for draw, x, y, _, _, _, _, coverage in log.fragments:
        c = ref.setdefault(draw, np.zeros((w * h, n), dtype=np.int64))
        c[y * w + x] += [(coverage >> s) & 1 for s in range(n)]
    return observer.counts, ref


def _counting(mesh, samples, cam, cull_passes=(Cull.Off, Cull.Back, Cull.Front)):
    passes = tuple(Pass(cull=c, zwrite=False, ztest=CompareFunction.Always, blend=True, src_blend=BlendFactor.One,
                        dst_blend=BlendFactor.One, stencil=True, stencil_pass=StencilOp.IncrWrap)
                   for c in cull_passes)
    return sc.scene(cam, sc.renderer(mesh, sc.unlit((0.125,) * 4, queue=Queue.Transparent, passes=passes)),
                    hdr=True, clear_color=(0, 0, 0, 0), msaa=samples)


@pytest.mark.parametrize("samples", [2, 4, 8])
@pytest.mark.parametrize("eye", [(2.2, 1.7, 3.0), (-3.1, 0.4, 1.3), (0.01, 0.02, 3.5)])
def test_closed_mesh_covers_every_sample_exactly_once_per_side(samples, eye):
    """A closed convex mesh: with Cull Off every sample inside the silhouette twice (front and back),
    none outside; Cull Back and Cull Front each exactly once where Cull Off had two."""
    scene = _counting(sc.uv_sphere(1.1, segments=13, rings=9), samples, sc.camera(32, 24, eye=eye, fov=45))
    core, ref = _sample_counts(scene)
    for draw in (1, 2, 3):
        assert np.array_equal(core[draw], ref[draw])
    off, back, front = core[1], core[2], core[3]
    assert set(np.unique(off)) == {0, 2}
    assert np.array_equal(back, off // 2) and np.array_equal(front, off // 2)
    assert ((off > 0).any(axis=1) & ~(off > 0).all(axis=1)).sum() > 10  # partly covered edge pixels


@pytest.mark.parametrize("samples", [2, 4, 8])
@pytest.mark.parametrize("seed", range(3))
def test_jittered_grid_covers_each_sample_of_its_rectangle_once(samples, seed):
    """A grid with jittered inner vertices and mixed windings, its boundary on pixel boundaries:
    each sample of the rectangle's pixels exactly once, none outside."""
    x0, y0, x1, y1 = 3.0, 2.0, 21.0, 15.0
    w, h = 24, 18
    mesh = sc.jittered_grid(np.random.default_rng(seed), x0, y0, x1, y1, 6)
    scene = _counting(mesh, samples, sc.screen_camera(w, h), (Cull.Off,))
    core, ref = _sample_counts(scene)
    assert np.array_equal(core[1], ref[1])
    expected = np.zeros((h, w), dtype=np.int64)
    expected[int(y0):int(y1), int(x0):int(x1)] = 1  # window rows (y up)
    assert np.array_equal(core[1], np.repeat(expected.reshape(-1, 1), samples, axis=1))


# ------------------------------------------------------------------ tools that read per pixel


def test_an_observer_of_pixel_fragments_is_refused_msaa_scenes_in_one_line():
    """The explain tools' observers read samples (analyze per sample: tests/explain/
    test_sorted_reference_msaa.py); one that reads pixel fragments only cannot watch MSAA."""
    scene = seeded_scene(1, msaa=4)
    with pytest.raises(SceneError, match=r"^FrameObserver reads pixel fragments only \(FrameObserver.per_sample\), "
                                         r"and the scene has MSAA 4: render it with msaa 1$"):
        render_scene(scene, observer=FrameObserver())
    render_scene(replace(scene, msaa=1), observer=FrameObserver())
    assert sorted_reference.analyze(scene).frame.color.shape == (scene.camera.height, scene.camera.width, 4)


@pytest.mark.parametrize("samples", [2, 4, 8])
@pytest.mark.parametrize("hdr", [False, True])
def test_blended_sphere_equals_reference(samples, hdr):
    """A small S1: a smooth Lambert sphere, Cull Off ZWrite Off alpha-blended over an opaque quad,
    then a second sphere pass with ZWrite On: pixels blended once while their samples agree
    (uniform), spread at triangle edges, joined again under fragments covering them, per sample
    under depth tests — equal to the scalar reference's sample-by-sample merge."""
    glass = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
                 dst_blend=BlendFactor.OneMinusSrcAlpha)
    solid = Pass(cull=Cull.Back, blend=True, src_blend=BlendFactor.One, dst_blend=BlendFactor.One)
    sphere = Material(color=(0.3, 0.6, 0.9, 0.5), queue=Queue.Transparent, passes=(glass, solid),
                      lighting=Lighting.Lambert)
    cam = sc.camera(40, 30, eye=(0.4, 0.9, 3.2), fov=50)
    back = sc.renderer(sc.quad(-3, -3, 3, 3, z=-1.5), sc.unlit((0.8, 0.2, 0.1, 1.0)), name="Back")
    scene = sc.scene(cam, back, sc.renderer(sc.uv_sphere(1.0, segments=18, rings=12), sphere, name="Sphere"),
                     hdr=hdr, msaa=samples)
    assert_same(scene)
    assert_same(scene, chunk_candidates=97)


@pytest.mark.parametrize("samples", [2, 4, 8])
@pytest.mark.parametrize("seed", range(1, 40, 4))
def test_seeded_msaa_scenes_with_lights_vertex_colours_mips_and_outlines_equal_reference(seed, samples):
    """SPEC §12 together: ForwardAdd lights, vertex colours, mipmaps (the quad LOD from the pixel
    centres, shading once per pixel) and outline vertex programs under MSAA with AlphaToMask."""
    assert_same(seeded_scene(seed, features=True, msaa=samples))
