"""SPEC §12's shading features and the outline vertex program (docs/pipeline.md §1 and §7): a
ForwardAdd draw's light, vertex colours, mipmaps, MToon's outline.

Expected values come from Unity's own texts (the shaders in shared/corpus, MToon's vertex programs
as UniVRM ships them, the GL specification) or are computed here from the formulas those texts
state; the core must equal the scalar reference bit for bit on structured sweeps
(tests/reference/feature_sweeps.py) and agree with OpenGL on llvmpipe (tests/reference/glref.py).
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core import colorspace, drawlist, lights, mips, outline, shade
from blendlib.core.scene import Camera, DrawScene, ForwardLight
from blendlib.core.vocabulary import (
    BlendFactor,
    ColorSpace,
    Cull,
    Lighting,
    LightMode,
    LightRenderMode,
    LightType,
    Material,
    OutlineFormula,
    OutlineMode,
    Pass,
    Texture,
    TextureFilter,
    TextureWrap,
    VertexColor,
)
from tests.reference import scenes as sc
from tests.reference.feature_sweeps import ADD, BASE, FEATURE_SWEEPS, mip_sweep
from tests.reference.glref import decode, render_gl
from tests.reference.random_scenes import seeded_scene
from tests.reference.scalar import render_reference

REPO = Path(__file__).resolve().parents[2]
CORPUS = REPO.parent / "shared" / "corpus"
if not CORPUS.is_dir():
    CORPUS = Path("/work/shared/corpus")
SHADERS = CORPUS / "unity-builtin-shaders-2019.4" / "DefaultResourcesExtra"


def _core(scene, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return render_scene(scene, **kw)


def _assert_equal_to_reference(scene):
    frame = _core(scene, workers=2)
    color, depth, stencil = render_reference(scene)
    bad = np.any(frame.color != color, axis=-1)
    assert not bad.any(), f"{int(bad.sum())} pixels differ, first at {np.argwhere(bad)[:3].tolist()}"
    assert np.array_equal(frame.depth, depth) and np.array_equal(frame.stencil, stencil)
    return frame


@pytest.mark.parametrize("name", list(FEATURE_SWEEPS))
def test_feature_sweeps_equal_reference(name):
    """Every value of the new enums: the core equals the scalar reference bit for bit."""
    frame = _assert_equal_to_reference(FEATURE_SWEEPS[name]())
    # Not an empty frame: a good part of the pixels is drawn over.
    cleared = np.all(frame.color == frame.color[0, 0], axis=-1).mean()
    assert cleared < 0.7


def test_feature_sweeps_render_alike_in_bands_chunks_and_one_thread():
    for name in ("lights_gamma", "mips_trilinear", "outline", "vertex_colors_linear"):
        scene = FEATURE_SWEEPS[name]()
        a = _core(scene, workers=1)
        b = _core(scene, workers=2, chunk_candidates=97)
        assert np.array_equal(a.color, b.color) and np.array_equal(a.depth, b.depth), name


# ------------------------------------------------------------------ lights


def test_falloff_is_unitys_built_in_one_and_equals_the_draw_lists():
    """Unity's LWRP: "attenuation = 1.0 / 1.0 + distanceToLightSqr * quadraticAttenuation" with
    quadraticAttenuation = 25 / range², faded linearly from 80 % of the range (r2 = 0.64) to 0."""
    r2 = np.array([0.0, 0.04, 0.25, 0.64, 0.8, 0.99, 1.0, 2.0])
    expected = np.array([1.0, 1 / (1 + 25 * 0.04), 1 / (1 + 25 * 0.25), 1 / (1 + 25 * 0.64),
                         1 / (1 + 25 * 0.8) * (0.2 / 0.36), 1 / (1 + 25 * 0.99) * (0.01 / 0.36), 0.0, 0.0])
    got = lights.falloff(r2)
    assert np.allclose(got, expected, rtol=1e-12, atol=0)
    assert got.tolist() == [drawlist.light_falloff(float(v)) for v in r2]


def _spot(angle=60.0) -> lights.AddLight:
    return lights.add_light(ForwardLight("S", LightType.Spot, position=(0, 0, 0), axis=(0, 0, 1), range=100.0,
                                         spot_angle=angle), ColorSpace.Linear)


def test_spot_cone_is_full_within_46_64_of_the_radius_and_zero_at_the_edge_and_behind():
    """Unity's ExtractInnerCone: tan(inner/2) = tan(outer/2) × (64 − 18) / 64; beyond it the
    default cookie falls to 0 at the cone's edge (linearly here), and ``lightCoord.z > 0``."""
    light = _spot(60.0)  # shines along −Z
    tan_half = math.tan(math.radians(30.0))
    z = np.full(6, 2.0)
    rho = np.array([0.0, 0.5, 46 / 64, 0.859375, 1.0, 1.2])  # radius shares at depth 2
    d2 = z * z + (rho * 2.0 * tan_half) ** 2
    cone = lights.spot_cone(light, z, d2)
    assert cone[:3].tolist() == [1.0, 1.0, 1.0]
    assert cone[3] == pytest.approx(0.5, abs=1e-12)  # halfway between 46/64 and 1
    assert cone[4] == pytest.approx(0.0, abs=1e-12) and cone[5] == 0.0
    assert lights.spot_cone(light, np.array([-1.0, 0.0]), np.array([1.0, 0.0])).tolist() == [0.0, 0.0]


def test_dark_fragments_are_exactly_those_the_light_terms_give_no_light():
    """Every fragment :func:`lights.dark_fragments` names has attenuation exactly 0 in
    :func:`lights.light_terms` (beyond the range, or outside a spot's cone or behind it), and it
    names most of them: all beyond the range and every one where the cone is 0."""
    rng = np.random.default_rng(5)
    p = rng.uniform(-6, 6, size=(20000, 3))
    for light in (lights.add_light(ForwardLight("P", LightType.Point, position=(0.5, -0.2, 0.3), range=3.0),
                                   ColorSpace.Gamma),
                  lights.add_light(ForwardLight("S", LightType.Spot, position=(0.2, 0.1, 1.0), axis=(0.2, -0.1, 1.0),
                                                range=5.0, spot_angle=50.0), ColorSpace.Linear)):
        dark = lights.dark_fragments(light, p[:, 0], p[:, 1], p[:, 2])
        atten = lights.light_terms(light, p[:, 0], p[:, 1], p[:, 2])[3]
        assert np.all(atten[dark] == 0.0) and 1000 < dark.sum()
        d2 = ((p - np.array(light.position)) ** 2).sum(axis=1)
        assert np.all(dark[d2 / light.range2 >= 1.0 + 1e-9])
        assert np.all(atten[~dark] > 0.0) if light.type is LightType.Point else np.all(dark[atten == 0.0])


def test_dark_fragments_are_skipped_only_where_they_change_nothing():
    """Out of a ForwardAdd light's reach a fragment's colour is 0; with ``BlendOp Add`` and
    destination factor ``One`` an 8-bit buffer keeps every stored code (checked for all 256 in
    Gamma and Linear), and alpha too unless the pass adds a source alpha to an unsaturated one."""
    from blendlib.core.merger import FrameBuffers, blend_fragments

    for color_space in (ColorSpace.Gamma, ColorSpace.Linear):
        buf = FrameBuffers(256, 1, False, color_space, (0, 0, 0, 1))
        codes = np.repeat(np.arange(256, dtype=np.uint8)[:, None], 4, axis=1)
        stored = codes.view(np.uint32).reshape(-1)
        for src in (BlendFactor.One, BlendFactor.SrcAlpha, BlendFactor.DstColor, BlendFactor.OneMinusSrcAlpha):
            p = Pass(blend=True, src_blend=src, dst_blend=BlendFactor.One, zwrite=False, color_mask=frozenset("RGB"))
            out = blend_fragments(buf, p, stored, np.zeros((256, 4)))
            assert np.array_equal(out, stored), (color_space, src)
    point = lights.add_light(ForwardLight("P", LightType.Point, position=(0, 0, 1), range=2.0), ColorSpace.Gamma)
    mat = Material(name="M")

    def applies(p, material=mat, light=point, peak=1.0, hdr=False, samples=1, observed=False):
        return lights.dark_skip_applies(p, material, light, peak, hdr, samples, observed)

    add = ADD  # Blend One One: alpha added too
    assert applies(add) == (True, True)  # where the stored alpha is 255 only
    assert applies(replace(add, color_mask=frozenset("RGB"))) == (True, False)
    assert applies(replace(add, separate_alpha=True, src_blend_alpha=BlendFactor.Zero,
                           dst_blend_alpha=BlendFactor.One)) == (True, False)
    never = [replace(add, dst_blend=BlendFactor.OneMinusSrcAlpha), replace(add, zwrite=True),
             replace(add, stencil=True), replace(add, outline_color=(1.0, 0.0, 0.0)),
             replace(add, separate_alpha=True, src_blend_alpha=BlendFactor.One, dst_blend_alpha=BlendFactor.Zero)]
    assert all(applies(p) == (False, False) for p in never)
    assert applies(add, hdr=True)[0] is False and applies(add, samples=4)[0] is False
    assert applies(add, observed=True)[0] is False and applies(add, peak=math.inf)[0] is False
    assert applies(add, material=replace(mat, color=(math.nan, 0, 0, 1)))[0] is False
    assert applies(add, material=replace(mat, lighting=Lighting.Unlit))[0] is False
    directional = lights.add_light(ForwardLight("D", LightType.Directional), ColorSpace.Gamma)
    assert applies(add, light=directional)[0] is False


@pytest.mark.parametrize("color_space", [ColorSpace.Gamma, ColorSpace.Linear])
def test_light_sweeps_drop_unreached_fragments_and_equal_the_reference(color_space, monkeypatch):
    """The light sweep (a floor and a sphere under point and spot lights whose ranges end on the
    floor) drops fragments no light reaches — on the opaque floor, and on the transparent sphere
    only where its stored alpha is saturated — and still equals the scalar reference bit for bit."""
    from tests.reference.feature_sweeps import light_sweep

    dropped = _count_unlit(monkeypatch)
    _assert_equal_to_reference(light_sweep(color_space))
    assert dropped[("Floor", False)] > 500 and not any(name == "Unlit" for name, _ in dropped)
    dropped.clear()
    _core(light_sweep(color_space, hdr=True))
    assert not dropped  # HDR: alpha does not saturate, nothing is dropped


def test_segments_reach_leaves_out_only_dark_points():
    """A random sweep of segments under point lights and spots of several angles: every point
    outside the part of a segment ``segments_reach`` keeps (interpolated as fragments' positions
    are) is one ``dark_fragments`` calls dark; it keeps nothing of many segments, and only part
    of many others, among them ones inside the range sphere but off a spot's cone."""
    rng = np.random.default_rng(12)
    lamps = [lights.add_light(ForwardLight("P", LightType.Point, position=(0.5, -0.2, 1.0), range=1.5),
                              ColorSpace.Gamma)]
    lamps += [lights.add_light(ForwardLight("S", LightType.Spot, position=(-0.3, 0.4, 2.0), axis=(0.2, -0.3, 0.9),
                                            range=4.0, spot_angle=angle), ColorSpace.Gamma)
              for angle in (10.0, 45.0, 100.0, 170.0)]
    t = np.linspace(0.0, 1.0, 513)
    for light in lamps:
        a = rng.uniform(-4, 4, size=(3000, 3))
        b = a + rng.normal(0, 1.5, size=(3000, 3)) * rng.uniform(0, 1, size=(3000, 1)) ** 2
        lo, hi = lights.segments_reach(light, a, b, 4.0)
        assert np.all((lo >= 0.0) & (hi <= 1.0))
        empty = lo > hi
        assert empty.sum() > 300, (light.type, light.tan_half, empty.sum())
        assert (~empty & ((lo > 0.0) | (hi < 1.0))).sum() > 5  # cut, not only kept or dropped whole
        points = a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]
        left_out = (t[None, :] < lo[:, None]) | (t[None, :] > hi[:, None])
        flat = points[left_out]
        assert lights.dark_fragments(light, flat[:, 0], flat[:, 1], flat[:, 2]).all()
        # Segments across the axis half the range out hold lit points there: kept about their middle.
        mid = np.array(light.position) + 0.5 * math.sqrt(light.range2) * np.array(light.spot_axis)
        across = rng.normal(0, 1.0, size=(50, 3))
        mid_lo, mid_hi = lights.segments_reach(light, mid - across, mid + across, 4.0)
        assert np.all((mid_lo <= 0.5) & (mid_hi >= 0.5))
        if light.type is LightType.Spot and light.tan_half < 1.0:  # off the cone, within the range
            d2 = ((a - np.array(light.position)) ** 2).sum(axis=1)
            assert (empty & (d2 < 0.5 * light.range2)).sum() > 50
    # Kept whole: a segment through the lamp, and ones with a NaN or infinite end.
    spot = lamps[1]
    through = np.array([spot.position]) + np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    bad = np.array([[np.nan, 0.0, 0.0], [np.inf, 9.0, 9.0]])
    lo, hi = lights.segments_reach(spot, through[:1], through[1:], 4.0)
    assert lo[0] < 0.5 < hi[0]
    lo, hi = lights.segments_reach(spot, bad, bad + 20.0, 4.0)
    assert np.array_equal(lo, [0.0, 0.0]) and np.array_equal(hi, [1.0, 1.0])


def _reach_scene(color_space: ColorSpace) -> DrawScene:
    """A floor and a wall of two triangles each (rows of many pixels), opaque, and a transparent
    veil over part of them, under a point light and a narrow spot that light small parts of the
    floor, and a spot turned away from everything."""
    tex = Texture(np.random.default_rng(4).uniform(0.3, 1.0, (8, 8, 4)).astype(np.float32), name="tiles")
    floor = Material(name="Floor", color=(0.9, 0.85, 0.8, 1.0), main_tex=tex, passes=(BASE, ADD))
    wall = Material(name="Wall", color=(0.7, 0.8, 0.9, 1.0), passes=(BASE, ADD))
    from tests.reference.feature_sweeps import BLEND_ADD, BLEND_BASE

    veil = Material(name="Veil", queue=sc.Queue.Transparent, color=(0.6, 0.8, 1.0, 0.45),
                    passes=(BLEND_BASE, BLEND_ADD))
    rotate = np.array([[1, 0, 0, 0], [0, 0, -1, 2.0], [0, 1, 0, 0], [0, 0, 0, 1]], dtype=np.float64)
    important = LightRenderMode.Important
    lamps = (ForwardLight("Point", LightType.Point, position=(-1.0, -0.5, 0.4), color=(1.0, 0.6, 0.3),
                          intensity=2.0, range=1.2, render_mode=important),
             ForwardLight("Spot", LightType.Spot, position=(1.0, 0.5, 2.5), axis=(0.0, 0.0, 1.0), intensity=3.0,
                          range=4.0, spot_angle=25.0, render_mode=important),
             ForwardLight("Away", LightType.Spot, position=(0.0, -3.0, 1.0), axis=(0.0, 1.0, 0.0), intensity=3.0,
                          range=6.0, spot_angle=40.0, render_mode=important))
    renderers = (sc.renderer(sc.quad(-3, -3, 3, 3), floor, name="Floor"),
                 sc.renderer(sc.quad(-3, 0, 3, 2), wall, name="Wall", matrix=rotate),
                 sc.renderer(sc.quad(-2.5, -1.5, 0.5, 0.5, z=0.3), veil, name="Veil"))
    return DrawScene(camera=sc.camera(160, 120, eye=(0.0, -4.5, 3.0), target=(0.0, 0.0, 0.3), fov=60.0),
                     renderers=renderers, light=None, ambient=(0.1, 0.1, 0.1), color_space=color_space,
                     lights=lamps, pixel_light_count=3, clear_color=(0.0, 0.0, 0.0, 0.0))


@pytest.mark.parametrize("light", [
    ForwardLight("Point", LightType.Point, position=(0.6, 2.0, 0.6), range=1.2),
    ForwardLight("Spot", LightType.Spot, position=(-1.0, 3.0, 2.5), axis=(0.6, 0.0, 1.0), range=6.0,
                 spot_angle=50.0),
])
def test_reached_spans_keep_every_lit_fragment_and_little_more(light):
    """On a floor tilted sideways and seen at a grazing angle (depth varies strongly along each
    row), the spans ``_reached_spans`` keeps hold every fragment of a row that ``dark_fragments``
    does not call dark, and beyond the lit ones at most the pixel margin and one pixel at each end."""
    from types import SimpleNamespace

    from blendlib.core import fragment, raster, vertex

    width, height = 480, 270
    cam = sc.camera(width, height, eye=(0.0, -1.0, 0.35), target=(0.0, 6.0, 0.0), fov=70.0)
    tilt = math.radians(35.0)  # about the view's axis: rising to the right
    roll = np.array([[math.cos(tilt), 0.0, -math.sin(tilt), 0.0], [0.0, 1.0, 0.0, 0.0],
                     [math.sin(tilt), 0.0, math.cos(tilt), 0.0], [0.0, 0.0, 0.0, 1.0]])
    setup = vertex.setup_triangles(sc.quad(-8, -1, 8, 14), roll, cam)
    rows = raster.coverage_rows(setup, np.arange(setup.count), width, height)
    add = lights.add_light(light, ColorSpace.Linear)
    state = SimpleNamespace(width=width, lights=SimpleNamespace(add=add), dark_alpha=None)
    tris = setup.src[rows.tri]
    positions = setup.world_positions_of(np.arange(int(tris.max()) + 1))
    x0, x1 = fragment._reached_spans(setup, rows, 0, rows.count, state, positions, tris, [])
    # Every fragment's world position, interpolated as shading does.
    frags = raster.rasterize_rows(rows, 0, rows.count, width)
    weights = raster.interpolate(setup, frags, weights=True, depth=False)[1]
    world = raster.interpolate_runs(weights, np.take(positions, tris, axis=0), rows.length,
                                    raster.flat_corners(np.take(positions, tris, axis=0)))
    lit = ~lights.dark_fragments(add, world[:, 0], world[:, 1], world[:, 2])
    x = frags.pix % width
    row = np.repeat(np.arange(rows.count), rows.length)
    kept = (x >= x0[row]) & (x < x1[row])
    assert lit.sum() > 1000 and (~lit).sum() > 5000
    assert not np.any(lit & ~kept)
    lit_rows = np.flatnonzero(np.bincount(row, weights=lit, minlength=rows.count) > 0)
    first_lit = np.full(rows.count, width)
    np.minimum.at(first_lit, row[lit], x[lit])
    last_lit = np.full(rows.count, -1)
    np.maximum.at(last_lit, row[lit], x[lit])
    slack = int(fragment.REACH_PIXEL_MARGIN) + 1
    assert np.all(x0[lit_rows] >= first_lit[lit_rows] - slack)
    assert np.all(x1[lit_rows] <= last_lit[lit_rows] + 1 + slack)
    unlit_rows = np.setdiff1d(np.arange(rows.count), lit_rows)
    assert unlit_rows.size > 10 and np.all(x1[unlit_rows] - x0[unlit_rows] <= 2 * slack)


@pytest.mark.parametrize("color_space", [ColorSpace.Gamma, ColorSpace.Linear])
def test_row_parts_out_of_a_lights_reach_are_cut_and_equal_the_reference(color_space, monkeypatch):
    """The parts of long rows whose fragments a ForwardAdd light cannot reach are cut off before
    they are rasterised — on the opaque floor and wall; on the veil, whose pass adds alpha, only
    where the stored alpha is already 255 — and the frame equals the scalar reference."""
    from blendlib.core import fragment

    cut: dict[str, int] = {}
    kept_for_alpha: dict[str, int] = {}  # out of reach, but the stored alpha is not 255 throughout
    original = fragment._reached_spans

    def counting(setup, rows, start, stop, state, *args, **kwargs):
        def cut_off(spans):
            if spans is None:
                return 0
            return int(rows.length[start:stop].sum() - np.maximum(spans[1] - spans[0], 0).sum())

        out = original(setup, rows, start, stop, state, *args, **kwargs)
        anywhere = original(setup, rows, start, stop, replace(state, dark_alpha=None), *args, **kwargs)
        name = state.call.renderer.name
        cut[name] = cut.get(name, 0) + cut_off(out)
        kept_for_alpha[name] = kept_for_alpha.get(name, 0) + cut_off(anywhere) - cut_off(out)
        return out

    monkeypatch.setattr(fragment, "_reached_spans", counting)
    scene = _reach_scene(color_space)
    _assert_equal_to_reference(scene)
    assert cut["Floor"] > 10000 and cut["Wall"] > 5000, cut
    assert kept_for_alpha["Veil"] > 1000 and kept_for_alpha["Wall"] == 0, kept_for_alpha


def _capture_equal_to_reference(scene):
    """A frame debugger capture of ``scene`` whose per-draw counts and frame equal the scalar
    reference's."""
    from blendlib.explain import framedebug as fd
    from tests.reference.scalar import FragmentLog

    capture = fd.FrameCapture.capture(scene)
    log = FragmentLog()
    color, depth, _ = render_reference(scene, log=log)
    counts = log.counts()
    assert [(s.fragments, s.written) for s in capture.stats] == [counts.get(s.call.index, (0, 0))
                                                                 for s in capture.stats]
    assert np.array_equal(capture.frame.color, color) and np.array_equal(capture.frame.depth, depth)
    return capture


def _count_unlit(monkeypatch, tested: dict | None = None) -> dict[tuple[str, bool], int]:
    """Counts, by (renderer, whether the chunk is observed), the fragments left unlit: those
    ``fragment._dark`` calls dark, unobserved those ``fragment._reached_spans`` cuts off the
    rows (a render then tests none of the rest: its rows' margins shade as the reference does)
    and, observed, those ``fragment._known_dark`` calls dark beyond the light's reached spans
    without testing them. ``tested``, when given, counts likewise the fragments ``_dark`` tests."""
    from blendlib.core import fragment

    unlit: dict[tuple[str, bool], int] = {}
    original, known_dark, reached = fragment._dark, fragment._known_dark, fragment._reached_spans

    def spans(setup, rows, start, stop, state, *args, **kwargs):
        out = reached(setup, rows, start, stop, state, *args, **kwargs)
        if out is not None and not state.observed:
            key = (state.call.renderer.name, False)
            cut = int(rows.length[start:stop].sum()) - int(np.maximum(out[1] - out[0], 0).sum())
            unlit[key] = unlit.get(key, 0) + cut
        return out

    def dark(state, position, pix, corners):
        out = original(state, position, pix, corners)
        key = (state.call.renderer.name, state.observed)
        unlit[key] = unlit.get(key, 0) + (0 if out is None else int(out.sum()))
        if tested is not None:
            tested[key] = tested.get(key, 0) + int(pix.size)
        return out

    def known(state, beyond, pix):
        out = known_dark(state, beyond, pix)
        key = (state.call.renderer.name, state.observed)
        unlit[key] = unlit.get(key, 0) + (0 if out is None else int(out.sum()))
        return out

    monkeypatch.setattr(fragment, "_dark", dark)
    monkeypatch.setattr(fragment, "_known_dark", known)
    monkeypatch.setattr(fragment, "_reached_spans", spans)
    return unlit


@pytest.mark.parametrize("color_space,veil_colors", [(ColorSpace.Gamma, None), (ColorSpace.Linear, None),
                                                      (ColorSpace.Gamma, VertexColor.Multiply),
                                                      (ColorSpace.Linear, VertexColor.Particle)])
def test_a_draw_list_leaves_fragments_out_of_reach_unlit_and_counts_them_as_the_reference(color_space, veil_colors,
                                                                                          monkeypatch):
    """A capture reads no colour (``colors_read`` False): the fragments a ForwardAdd light does not
    reach are told of and merged with rgb 0 and their own alpha, their lighting not computed. The
    counts of every draw equal the scalar reference's and the frame equals it too — the veil's
    pass adds its source alpha to an unsaturated one, so a wrong alpha would show (with vertex
    colours on the veil: their interpolated alpha)."""

    unlit = _count_unlit(monkeypatch)
    scene = _reach_scene(color_space)
    if veil_colors is not None:
        *others, veil = scene.renderers
        mesh = veil.mesh
        colors = np.random.default_rng(5).uniform(0.2, 1.0, size=(2, 3, 4)).astype(np.float32)
        mesh = type(mesh)(mesh.positions, mesh.triangles, mesh.normals, mesh.uvs, colors=colors)
        veil = replace(veil, mesh=mesh, material=replace(veil.material, vertex_color=veil_colors))
        scene = replace(scene, renderers=(*others, veil))
    capture = _capture_equal_to_reference(scene)
    assert unlit[("Floor", True)] > 10000 and unlit[("Wall", True)] > 5000 and unlit[("Veil", True)] > 1000, unlit
    # The veil's alpha is what its pass adds: the fragments left unlit there change the stored alpha.
    veil = [s for s in capture.stats
            if s.call.renderer.name == "Veil" and s.call.state.light_mode is LightMode.ForwardAdd]
    assert veil and all(s.written > 1000 for s in veil)


def test_a_draw_list_does_not_merge_unreached_fragments_that_change_nothing(monkeypatch):
    """Under a capture (no colour read) the fragments of an opaque floor's ForwardAdd draws that
    its lights do not reach add rgb 0; where the stored alpha is saturated (the plank's, then the
    floor's once an earlier ForwardAdd draw filled it: its texture's alpha is below 1) they change
    nothing, are told of with the outcome of the depth test alone and never reach the merger. The
    plank, in front of part of the floor and drawn before it, makes some of them fail that test.
    Each draw's counts and the frame equal the scalar reference's; without the shortcut the merger
    would see every fragment told of."""
    from blendlib.core import pipeline

    scene = _reach_scene(ColorSpace.Gamma)
    floor = scene.renderers[0]
    plank = sc.renderer(sc.quad(-2.0, -2.6, 0.0, -1.8, z=0.6), Material(name="Plank", color=(0.3, 0.3, 0.3, 1.0),
                                                                         passes=(BASE,)), name="Plank")
    scene = replace(scene, renderers=(floor, plank))
    unlit = _count_unlit(monkeypatch)
    merged = [0]
    original = pipeline.merge

    def counting_merge(buf, p, pix, *args, **kwargs):
        merged[0] += int(pix.shape[0])
        return original(buf, p, pix, *args, **kwargs)

    monkeypatch.setattr(pipeline, "merge", counting_merge)
    capture = _capture_equal_to_reference(scene)
    told = sum(s.fragments for s in capture.stats)
    assert unlit[("Floor", True)] > 20000
    assert merged[0] < told - 15000, (merged[0], told, unlit)
    adds = [s for s in capture.stats if s.call.renderer.name == "Floor" and s.call.light is not None]
    assert len(adds) == 3 and all(s.fragments > s.written > 0 for s in adds)  # the plank hides some
    assert capture.stats[0].call.renderer.name == "Plank"  # nearer: drawn first (opaque, front to back)


@pytest.mark.parametrize("color_space", [ColorSpace.Gamma, ColorSpace.Linear])
def test_a_capture_tests_the_reach_only_of_fragments_within_the_reached_spans(color_space, monkeypatch):
    """Observed, every fragment of a ForwardAdd draw is rasterised and told of, but the world
    positions are computed only for fragments within the row spans the light may reach
    (:func:`fragment._reached_spans`, which a render uses to cut its rows): those beyond are dark
    by that function's guarantee. Within them only the rows' margins hold dark fragments, so none
    is tested for reach (``_dark``): they are lit, which gives rgb 0 there, and merged as the
    reference merges them. On the floor and wall most are beyond; on the veil, whose pass adds
    alpha to an unsaturated one, they are merged with rgb 0 all the same. Each draw's counts and
    the frame equal the scalar reference's; in round nineteen the fragments within the spans
    were tested, and before that every fragment told of."""
    tested: dict[tuple[str, bool], int] = {}
    unlit = _count_unlit(monkeypatch, tested)
    capture = _capture_equal_to_reference(_reach_scene(color_space))
    for name in ("Floor", "Wall", "Veil"):
        told = sum(s.fragments for s in capture.stats
                   if s.call.renderer.name == name and s.call.state.light_mode is LightMode.ForwardAdd)
        assert unlit[(name, True)] > told // 4, (name, told, unlit)
        assert tested.get((name, True), 0) == 0, (name, told, tested, unlit)


def test_unreached_fragments_of_a_textured_mesh_without_uvs_keep_the_texels_alpha(monkeypatch):
    """A mesh without UVs samples its texture at (0, 0) (§7): under a capture, the alpha of its
    fragments left unlit includes that texel's alpha (the floor's pass adds it to an unsaturated
    one), and the counts and frame equal the scalar reference."""

    unlit = _count_unlit(monkeypatch)
    scene = _reach_scene(ColorSpace.Gamma)
    floor, *others = scene.renderers
    mesh = floor.mesh
    bare = type(mesh)(mesh.positions, mesh.triangles, mesh.normals, None)
    pixels = np.random.default_rng(6).uniform(0.3, 1.0, (8, 8, 4)).astype(np.float32)
    pixels[..., 3] = 0.1  # far from saturating under the floor's three additive passes
    faint = replace(floor.material, main_tex=Texture(pixels, name="faint"))
    scene = replace(scene, renderers=(replace(floor, mesh=bare, material=faint), *others))
    _capture_equal_to_reference(scene)
    assert unlit[("Floor", True)] > 10000, unlit


def test_colors_read_may_be_a_numpy_bool(monkeypatch):
    """An observer's ``colors_read`` answered with numpy's booleans means what True and False do."""
    from blendlib.core.records import FrameObserver

    class Counting(FrameObserver):
        exact_boundaries = False

        def __init__(self, answer):
            self.answer, self.count = answer, 0

        def colors_read(self, call):
            return self.answer

        def fragments(self, call, frags, outcome):
            self.count += frags.count

    unlit = _count_unlit(monkeypatch)
    scene = _reach_scene(ColorSpace.Gamma)
    plain = _core(scene)
    for answer, dark in ((np.False_, True), (np.True_, False)):
        unlit.clear()
        observer = Counting(answer)
        frame = _core(scene, observer=observer)
        assert np.array_equal(frame.color, plain.color) and observer.count > 0
        assert (unlit.get(("Floor", True), 0) > 10000) == dark, (answer, unlit)


def test_a_pixel_history_lights_its_own_pixels_and_draws_other_rows_unobserved(monkeypatch):
    """A pixel history reads the colours at its pixels only: there every fragment keeps its exact
    colour (as the scalar reference shades it), elsewhere in the chunks it is told of a fragment
    out of a light's reach is left unlit, and chunks in none of its rows are drawn as an
    unobserved render draws them (their unlit fragments dropped)."""
    from blendlib.explain import framedebug as fd
    from tests.reference.scalar import FragmentLog

    unlit = _count_unlit(monkeypatch)
    monkeypatch.setattr(fd, "render_scene", functools.partial(render_scene, chunk_candidates=400))  # many chunks
    scene = _reach_scene(ColorSpace.Linear)
    pixels = [(20, 100), (80, 110), (150, 100), (60, 70)]
    histories, frame = fd.pixel_histories(scene, pixels)
    log = FragmentLog()
    color, _, _ = render_reference(scene, log=log)
    assert np.array_equal(frame.color, color)
    height = scene.camera.height
    for history in histories:
        ref = [r for r in log.fragments if (r[1], r[2]) == (history.x, height - 1 - history.y)]
        assert [(f.call.index, f.triangle, f.depth_code, f.result) for f in history.fragments] == [
            (r[0], r[3], r[4], r[6]) for r in ref]
        assert [list(f.source) for f in history.fragments] == [list(r[5]) for r in ref]
    adds = [f for h in histories for f in h.fragments if f.call.state.light_mode is LightMode.ForwardAdd]
    assert sum(1 for f in adds if not any(f.source[:3])) >= 3  # pixels out of a light's reach among them
    assert unlit.get(("Floor", True), 0) > 2000 and unlit.get(("Floor", False), 0) > 2000, unlit


def _plane_scene(pass_list, light=None, lights_=(), lighting=Lighting.Lambert, color_space=ColorSpace.Gamma,
                 color=(0.5, 0.6, 0.7, 0.8), hdr=True):
    """A 4 x 4 quad facing a camera 4 units away (Gamma HDR: colours as authored, nothing clamped)."""
    mat = Material(name="Plane", color=color, lighting=lighting, passes=tuple(pass_list))
    cam = sc.camera(32, 32, eye=(0, 0, 4), fov=40.0)
    return DrawScene(camera=cam, renderers=(sc.renderer(sc.quad(-2, -2, 2, 2), mat, name="Plane"),), light=light,
                     ambient=(0.0, 0.0, 0.0), color_space=color_space, hdr=hdr, lights=tuple(lights_),
                     clear_color=(0, 0, 0, 0))


def test_forward_add_point_light_is_albedo_times_light_times_ndl_times_falloff():
    """The book's ForwardAdd (chapter 9): ``_LightColor0.rgb × albedo × max(0, N·L) × atten``, no
    ambient; blended ``One One`` over a black base pass (no main light, no ambient)."""
    point = ForwardLight("P", LightType.Point, position=(0.0, 0.0, 1.0), color=(1.0, 0.5, 0.25), intensity=2.0,
                         range=4.0, render_mode=LightRenderMode.Important)
    frame = _core(_plane_scene((BASE, ADD), lights_=(point,)))
    # Pixel (16, 16)'s centre is at the plane point (x, y) below (camera at z = 4, 40° field of view).
    half = math.tan(math.radians(20.0)) * 4.0
    x = (16.5 / 32 * 2 - 1) * half
    y = -(16.5 / 32 * 2 - 1) * half  # row 16 from the top
    d = np.array([x, y, 0.0]) - np.array([0.0, 0.0, 1.0])
    ndl = -d[2] / np.linalg.norm(d)
    atten = lights.falloff(np.array([d @ d / 16.0]))[0]
    lamp = np.array([colorspace.encode(c) for c in (1.0, 0.5, 0.25)])  # Gamma: encoded, then × intensity
    expected = np.array([0.5, 0.6, 0.7]) * lamp * 2.0 * ndl * atten
    assert np.allclose(frame.color[16, 16, :3], expected, rtol=1e-6)
    assert frame.color[16, 16, 3] == pytest.approx(1.6)  # the material's alpha, added by Blend One One


def test_forward_add_draws_add_up_per_light_and_unlit_outputs_its_albedo():
    """One ForwardAdd draw per light (Important lights), blended One One; an Unlit material's
    ForwardAdd draw outputs its albedo like any pass (SPEC: Unlit ignores lights)."""
    sun = ForwardLight("Sun2", LightType.Directional, axis=(0, 0, 1), color=(1, 1, 1), intensity=0.5,
                       render_mode=LightRenderMode.Important)
    sun3 = replace(sun, name="Sun3", intensity=0.25)
    lit = _core(_plane_scene((BASE, ADD), lights_=(sun, sun3)))
    assert np.allclose(lit.color[16, 16, :3], np.array([0.5, 0.6, 0.7]) * 0.75, rtol=1e-6)
    unlit = _core(_plane_scene((BASE, ADD), lights_=(sun, sun3), lighting=Lighting.Unlit))
    assert np.allclose(unlit.color[16, 16, :3], np.array([0.5, 0.6, 0.7]) * 3, rtol=1e-6)


def test_gamma_mode_encodes_the_light_colour_before_the_intensity():
    sun = ForwardLight("Sun2", LightType.Directional, axis=(0, 0, 1), color=(0.2, 0.2, 0.2), intensity=1.5,
                       render_mode=LightRenderMode.Important)
    add = lights.add_light(sun, ColorSpace.Gamma)
    assert add.color[0] == pytest.approx((1.055 * 0.2 ** (1 / 2.4) - 0.055) * 1.5)
    assert lights.add_light(sun, ColorSpace.Linear).color[0] == pytest.approx(0.3)


# ------------------------------------------------------------------ vertex colours


def test_particle_mode_is_the_legacy_particle_shaders_line():
    """``Particle Add.shader`` line 79: ``fixed4 col = 2.0f * i.color * _TintColor * tex2D(_MainTex,
    i.texcoord);`` — rgb and alpha alike."""
    text = (SHADERS / "Particle Add.shader").read_text()
    assert "fixed4 col = 2.0f * i.color * _TintColor * tex2D(_MainTex, i.texcoord);" in text.splitlines()[78]
    vc = np.array([[0.5, 0.25, 1.0, 0.5]])
    tex = np.array([[0.8, 0.6, 0.4, 0.9]])
    mat = Material(vertex_color=VertexColor.Particle, tint_color=(0.5, 0.4, 0.3, 0.5), lighting=Lighting.Unlit,
                   color=(0.1, 0.1, 0.1, 0.1), alpha_scale=0.5)
    got = shade.shade_texels(mat, tex, shade.Lights((0, 0, 0), (0, 0, 0), (0, 0, 0)), ColorSpace.Gamma,
                             np.zeros((1, 3)), vc)
    assert np.allclose(got, 2.0 * vc * np.array([0.5, 0.4, 0.3, 0.5]) * tex)  # _Color, _AlphaScale unused


def test_multiply_mode_is_sprites_and_ui_texture_times_colour():
    """UI-Default: ``(tex2D(_MainTex, IN.texcoord) + _TextureSampleAdd) * IN.color`` with
    ``OUT.color = v.color * _Color``: albedo and alpha × the vertex colour."""
    assert "* IN.color" in (SHADERS / "UI" / "UI-Default.shader").read_text()
    vc = np.array([[0.5, 0.25, 1.0, 0.5]])
    tex = np.array([[0.8, 0.6, 0.4, 0.9]])
    mat = Material(vertex_color=VertexColor.Multiply, lighting=Lighting.Unlit, color=(0.5, 1.0, 0.5, 0.8))
    got = shade.shade_texels(mat, tex, shade.Lights((0, 0, 0), (0, 0, 0), (0, 0, 0)), ColorSpace.Gamma,
                             np.zeros((1, 3)), vc)
    assert np.allclose(got, tex * np.array([0.5, 1.0, 0.5, 0.8]) * vc)


def test_vertex_colours_convert_as_textures_do():
    """A byte colour attribute holds sRGB-encoded values (decoded in Linear mode), a float one
    linear values (encoded in Gamma mode); alpha never changes."""
    colors = np.full((2, 3, 4), 0.5, np.float32)
    quad = sc.quad(0, 0, 4, 4)
    for encoding, space, expected in (("sRGB", ColorSpace.Gamma, 0.5), ("sRGB", ColorSpace.Linear, 0.2140411),
                                      ("Linear", ColorSpace.Linear, 0.5), ("Linear", ColorSpace.Gamma, 0.7353570)):
        mesh = replace(quad, colors=colors, color_encoding=encoding)
        mat = Material(vertex_color=VertexColor.Multiply, lighting=Lighting.Unlit)
        scene = DrawScene(camera=sc.screen_camera(4, 4), renderers=(sc.renderer(mesh, mat),), color_space=space,
                          hdr=True)
        frame = _core(scene)
        assert frame.color[1, 1, 0] == pytest.approx(expected, abs=1e-6), (encoding, space)
        assert frame.color[1, 1, 3] == 0.5


def test_no_colour_attribute_is_white():
    mat = Material(vertex_color=VertexColor.Multiply, lighting=Lighting.Unlit, color=(0.3, 0.4, 0.5, 0.6))
    plain = replace(mat, vertex_color=VertexColor.Off)
    for m in (mat, plain):
        scene = DrawScene(camera=sc.screen_camera(4, 4), renderers=(sc.renderer(sc.quad(0, 0, 4, 4), m),), hdr=True)
        assert np.allclose(_core(scene).color[1, 1], (0.3, 0.4, 0.5, 0.6))


# ------------------------------------------------------------------ mipmaps


def _texels(px) -> shade.Texels:
    return shade.texture_texels(Texture(np.asarray(px, np.float32), encoding="Data"), ColorSpace.Gamma)


def test_mip_chain_is_2x2_box_averages_down_to_1x1_with_odd_sides_floored():
    rng = np.random.default_rng(0)
    px = rng.uniform(0, 1, (5, 8, 4)).astype(np.float32)
    chain = mips.build_chain(_texels(px))
    assert [level.shape[:2] for level in chain.levels] == [(5, 8), (2, 4), (1, 2), (1, 1)]
    level1 = mips.level_of(chain, 1)
    expected = px[:4].astype(np.float64).reshape(2, 2, 4, 2, 4).mean(axis=(1, 3))  # the odd last row left out
    assert np.allclose(level1, expected, atol=1e-7)
    top = mips.level_of(chain, 3)[0, 0]
    assert np.allclose(top, mips.level_of(chain, 2)[0].mean(axis=0), atol=1e-7)


def test_preserve_coverage_keeps_each_levels_alpha_tested_coverage():
    """"Mip Maps Preserve Coverage": each level's alpha scaled so its coverage at the cutoff equals
    level 0's, where the plain box filter loses it (mostly faint texels, a few opaque: foliage)."""
    rng = np.random.default_rng(5)
    px = np.ones((32, 32, 4), np.float32)
    px[..., 3] = rng.uniform(0, 1, (32, 32)) ** 3
    cutoff = 0.5
    plain = mips.build_chain(_texels(px))
    kept = mips.build_chain(_texels(px), preserve_coverage=True, cutoff=cutoff)
    base = (px[..., 3] >= cutoff).mean()
    for index in (1, 2, 3):
        lost = (mips.level_of(plain, index)[..., 3] >= cutoff).mean()
        held = (mips.level_of(kept, index)[..., 3] >= cutoff).mean()
        texels = mips.level_of(kept, index)[..., 3].size
        assert lost < base / 2 < held
        assert abs(held - base) <= 1.0 / texels + 1e-12, index  # as near as one texel allows
    assert np.array_equal(mips.level_of(kept, 1)[..., :3], mips.level_of(plain, 1)[..., :3])


def test_coverage_scale_bisects_as_nvidia_texture_tools():
    """s = 1, then bisection within [0, 4]: alphas i/63 (i < 64) at cutoff 0.5 reach a quarter
    covered at s = 0.65625 (1 → 0.5 → 0.75 → 0.625 → 0.6875 → 0.65625, exact there)."""
    alpha = np.arange(64) / 63.0
    s = mips.coverage_scale(alpha, 0.5, (16, 64))
    assert s == 0.65625
    assert int(np.count_nonzero(np.minimum(alpha * s, 1.0) >= 0.5)) == 16


def _uv_plane_scene(texels_per_pixel: float, filt=TextureFilter.Trilinear, size=64, frame=32):
    """A screen-filling quad whose uv covers ``texels_per_pixel`` texels of a ``size`` texture per pixel."""
    px = np.zeros((size, size, 4), np.float32)
    px[..., 3] = 1.0
    mat = Material(main_tex=Texture(px, encoding="Data"), main_tex_mipmaps=True, main_tex_filter=filt,
                   lighting=Lighting.Unlit, main_tex_tiling=(texels_per_pixel * frame / size,) * 2)
    return DrawScene(camera=sc.screen_camera(frame, frame), renderers=(sc.renderer(sc.quad(0, 0, frame, frame), mat),))


def test_quad_lod_is_log2_of_texels_per_pixel():
    """GL 4.5 §8.14: λ = log2 ρ with ρ the texels a pixel step covers: 4 texels a pixel → λ = 2,
    for every pixel of each 2x2 quad, helper pixels included (edges of the triangle)."""
    from blendlib.core import raster, vertex

    for tpp, lod in ((4.0, 2.0), (1.0, 0.0), (0.5, -1.0), (2.0 ** 1.5, 1.5)):
        scene = _uv_plane_scene(tpp)
        r = scene.renderers[0]
        setup = vertex.setup_triangles(r.mesh, r.matrix_world, scene.camera)
        rows = raster.coverage_rows(setup, vertex.cull_select(setup, Cull.Back), 32, 32)
        frags = raster.rasterize_rows(rows, 0, rows.count, 32)
        got = mips.quad_lod(setup, frags.tri, frags.pix, 32, r.material, (64, 64))
        assert np.allclose(got, lod, atol=1e-12), (tpp, np.unique(got))


def test_quad_lod_evaluates_the_triangle_plane_which_gives_each_fragment_its_own_coordinates():
    """The LOD's texture coordinates at any pixel centre come from the triangle's plane (helper
    pixels included); at a fragment's own pixel they are exactly its interpolated coordinates (§6)."""
    from blendlib.core import raster, vertex

    scene = mip_sweep(TextureFilter.Trilinear)
    r = scene.renderers[0]
    setup = vertex.setup_triangles(r.mesh, r.matrix_world, scene.camera)
    rows = raster.coverage_rows(setup, vertex.cull_select(setup, Cull.Back), 120, 80)
    frags = raster.rasterize_rows(rows, 0, rows.count, 120)
    _, weights = raster.interpolate(setup, frags)
    corners = setup.uvs_of(setup.src[frags.tri])
    uv = [(weights[0] * corners[:, 0, c] + weights[1] * corners[:, 1, c]) + weights[2] * corners[:, 2, c]
          for c in range(2)]
    expected = shade.texture_uv_of(r.material, uv[0], uv[1])
    x, y = frags.pix % 120, frags.pix // 120
    flat = np.zeros(frags.count, bool)
    # At the pixel itself, and one step right of (above) the pixel to its left (below): the same bits.
    for (u, v) in mips._texture_uvs_at(setup, frags.tri, corners, flat, r.material, x, y, ((0, 0),)) + [
            mips._texture_uvs_at(setup, frags.tri, corners, flat, r.material, x - 1, y, ((1, 0),))[0],
            mips._texture_uvs_at(setup, frags.tri, corners, flat, r.material, x, y - 1, ((0, 1),))[0]]:
        assert np.array_equal(u, expected[0]) and np.array_equal(v, expected[1])


def test_quad_lod_computes_a_quad_met_again_once_and_gives_every_fragment_its_quads_value(monkeypatch):
    """A quad's two rows come one after the other in a triangle's rows: its λ is computed once
    (with the quads of other triangles apart) and every fragment gets exactly the λ of its own
    (triangle, quad), as the reference computes it per fragment."""
    from blendlib.core import raster, vertex

    scene = mip_sweep(TextureFilter.Trilinear)
    r = scene.renderers[0]
    setup = vertex.setup_triangles(r.mesh, r.matrix_world, scene.camera)
    rows = raster.coverage_rows(setup, vertex.cull_select(setup, Cull.Back), 120, 80)
    frags = raster.rasterize_rows(rows, 0, rows.count, 120)
    x, y = frags.pix % 120, frags.pix // 120
    expected = mips._quad_lod_at(setup, frags.tri, x & ~1, y & ~1, r.material, (64, 64))
    computed = []
    real = mips._quad_lod_at
    monkeypatch.setattr(mips, "_quad_lod_at", lambda setup, tri, *a: computed.append(tri.size) or real(setup, tri, *a))
    got = mips.quad_lod(setup, frags.tri, frags.pix, 120, r.material, (64, 64))
    np.testing.assert_array_equal(got, expected)
    quads = np.unique(np.stack([frags.tri, x & ~1, y & ~1]), axis=1).shape[1]
    assert frags.count > 2 * mips.SHARED_QUADS_MIN  # about two fragments a run: quads are shared
    assert quads <= sum(computed) <= quads + quads // 8, (quads, computed, frags.count)


def _lod_threshold(filt: TextureFilter) -> float:
    """The largest λ that samples level 0 (GL 4.5 §8.14.3): 0 for LINEAR_MIPMAP_LINEAR (λ > 0
    minifies), 0.5 for the nearest-level filters (level ceil(λ + ½) − 1 from λ > ½)."""
    return 0.0 if filt is TextureFilter.Trilinear else 0.5


def _fragments_of(scene, r):
    from blendlib.core import raster, vertex

    w, h = scene.camera.width, scene.camera.height
    setup = vertex.setup_triangles(r.mesh, r.matrix_world, scene.camera)
    rows = raster.coverage_rows(setup, vertex.cull_select(setup, Cull.Off), w, h)
    return setup, raster.rasterize_rows(rows, 0, rows.count, w)


def _assert_skips_only_level_zero(setup, frags, width, material, size):
    """``sampling_lod`` equals ``quad_lod`` but where it gives −inf, and there ``quad_lod`` samples
    level 0; returns the number of fragments it skipped."""
    exact = mips.quad_lod(setup, frags.tri, frags.pix, width, material, size)
    got = mips.sampling_lod(setup, frags.tri, frags.pix, width, material, size)
    same = (got == exact) | (np.isnan(got) & np.isnan(exact))
    skipped = ~same
    assert np.all(got[skipped] == -np.inf)
    worst = exact[skipped].max(initial=-np.inf)
    assert worst <= _lod_threshold(material.main_tex_filter), worst
    return int(skipped.sum()), exact


@pytest.mark.parametrize("filt", list(TextureFilter))
def test_sampling_lod_skips_the_triangles_that_sample_level_zero_and_samples_the_same(filt):
    """Near strips of a receding plane (texels magnified throughout) take λ = −inf, the rest their
    own λ; every fragment samples the same texels through the chain."""
    scene = mip_sweep(filt, strips=16, tiling=(0.5, 3.0))
    r = scene.renderers[0]
    setup, frags = _fragments_of(scene, r)
    size = (32, 32)
    skipped, exact = _assert_skips_only_level_zero(setup, frags, scene.camera.width, r.material, size)
    level_zero = int((exact <= _lod_threshold(filt)).sum())
    # Most of the level-0 fragments are skipped, and minified ones remain.
    assert skipped >= level_zero // 2 and skipped > 0, (skipped, level_zero)
    assert level_zero < frags.count
    chain = mips.build_chain(_texels(np.asarray(r.material.main_tex.pixels, np.float64)))
    uv = np.random.default_rng(5).uniform(-2, 2, (frags.count, 2))
    got = mips.sampling_lod(setup, frags.tri, frags.pix, scene.camera.width, r.material, size)
    np.testing.assert_array_equal(mips.sample_mipmapped(chain, uv, got, filt, TextureWrap.Repeat),
                                  mips.sample_mipmapped(chain, uv, exact, filt, TextureWrap.Repeat))


@pytest.mark.parametrize("seed", range(12))
def test_sampling_lod_bound_holds_under_perspective_clipping_and_tiling(seed):
    """Random triangles, some through the near plane (clipped) and some seen edge-on, random UVs,
    tilings (negative too), offsets and texture sizes, each filter: a triangle skipped by the bound
    never has a quad that would sample past level 0."""
    rng = np.random.default_rng(seed)
    skipped_total = 0
    for filt in TextureFilter:
        count = 24
        centre = rng.uniform([-1.5, -1.0, -6.0], [1.5, 1.0, 3.5], (count, 1, 3))
        positions = (centre + rng.normal(0.0, rng.uniform(0.05, 1.5, (count, 1, 1)), (count, 3, 3))).reshape(-1, 3)
        uvs = rng.uniform(-1.0, 1.0, (count, 3, 2)) * rng.uniform(0.01, 1.0, (count, 1, 1))
        mesh = sc.make_mesh(positions, np.arange(3 * count).reshape(count, 3), uvs=uvs)
        tiling = tuple((rng.choice([-1.0, 1.0]) * 2.0 ** rng.uniform(-3, 3)).item() for _ in range(2))
        material = Material(main_tex_filter=filt, main_tex_mipmaps=True, main_tex_tiling=tiling,
                            main_tex_offset=tuple(rng.uniform(-5, 5, 2).tolist()))
        scene = DrawScene(camera=sc.camera(96, 64, eye=(0, 0, 4), near=0.5), renderers=(sc.renderer(mesh, material),))
        setup, frags = _fragments_of(scene, scene.renderers[0])
        size = (int(2 ** rng.integers(0, 9)), int(2 ** rng.integers(0, 9)))
        with np.errstate(all="ignore"):
            skipped, _ = _assert_skips_only_level_zero(setup, frags, 96, material, size)
        skipped_total += skipped
    assert skipped_total > 0


def test_trilinear_blends_two_levels_by_the_lod_fraction():
    """GL_LINEAR_MIPMAP_LINEAR: (1 − f)·level d + f·level d+1 with d = floor λ, f = λ − d; the
    nearest-level filters take level ceil(λ + ½) − 1."""
    rng = np.random.default_rng(3)
    chain = mips.build_chain(_texels(rng.uniform(0, 1, (8, 8, 4))))
    uv = np.array([[0.5, 0.5]] * 4)
    level = [shade.sample(chain.levels[k], uv[:1], TextureFilter.Bilinear, TextureWrap.Repeat)[0] for k in range(4)]
    lod = np.array([-1.0, 0.25, 1.75, 9.0])
    tri = mips.sample_mipmapped(chain, uv, lod, TextureFilter.Trilinear, TextureWrap.Repeat)
    assert np.allclose(tri[0], level[0]) and np.allclose(tri[3], level[3])
    assert np.allclose(tri[1], 0.75 * level[0] + 0.25 * level[1])
    assert np.allclose(tri[2], 0.25 * level[1] + 0.75 * level[2])
    near = mips.sample_mipmapped(chain, uv, lod, TextureFilter.Bilinear, TextureWrap.Repeat)
    assert np.allclose(near[1], level[0]) and np.allclose(near[2], level[2]) and np.allclose(near[3], level[3])


def test_distant_texels_average_with_mipmaps_and_alias_without():
    """Without mipmaps a minified texture aliases to single texels; with them distant pixels tend
    to the texture's average (why Unity imports mipmaps)."""
    scene = mip_sweep(TextureFilter.Trilinear)
    alone = replace(scene, renderers=scene.renderers[:1])
    plain = replace(alone, renderers=(replace(alone.renderers[0], material=replace(
        alone.renderers[0].material, main_tex_mipmaps=False)),))
    spread = []
    for s in (alone, plain):
        far = _core(s).color[25:40, :, 0]  # rows towards the horizon
        spread.append(far[far > 0].std())
    assert spread[0] < spread[1] / 2


@pytest.mark.parametrize("numpy_path", [None, False])
def test_lod_log2_is_c_log2(numpy_path, monkeypatch):
    """The LOD's log2 (docs/pipeline.md §7) is C's, element by element, so that the core equals the
    scalar reference bit for bit on every machine: numpy's own where it agrees with C's (checked
    once per process), else C's per run of equal values (numpy builds with AVX-512 SVML kernels
    differ in the last bit). ``numpy_path`` False forces the second path on any machine."""
    from blendlib.core import mips

    if numpy_path is not None:
        monkeypatch.setattr(mips, "_NUMPY_LOG2_IS_C", numpy_path)
    x = np.exp(np.random.default_rng(1).uniform(-40, 40, 20000))
    x[100:140] = x[99]  # a run of equal values (one triangle's quads)
    x[200:204] = [0.0, np.inf, np.nan, 5e-324]  # the scalar reference's special cases, and a subnormal
    expected = [-math.inf if v == 0.0 else math.inf if v == math.inf else math.nan if v != v else math.log2(v)
                for v in x.tolist()]
    np.testing.assert_array_equal(mips.log2(x), np.array(expected))
    assert np.isnan(mips.log2(np.array([-1.0, -np.inf]))).all()


# ------------------------------------------------------------------ outline vertex program


def _screen_cam(width=64, height=48) -> Camera:
    return sc.camera(width, height, eye=(0, 0, 3), fov=50.0)


def _outline_scene(p: Pass, matrix=None, width=64, height=48):
    mesh = sc.quad(-0.5, -0.5, 0.5, 0.5)
    mat = Material(lighting=Lighting.Unlit, color=(1, 1, 1, 1), passes=(p,))
    return DrawScene(camera=_screen_cam(width, height), renderers=(sc.renderer(mesh, mat, matrix=matrix),),
                     clear_color=(0, 0, 0, 0))


def test_world_outline_moves_corners_along_the_normal_by_the_width():
    """MToon 0.x World: ``0.01 * _OutlineWidth * worldNormalLength * v.normal`` in object space
    (centimetres for a unit-scale object); MToon 1.0: ``outlineWidthFactor`` metres along the world
    normal. A quad facing the camera moves towards it: its clip w falls by exactly that distance."""
    mesh = sc.quad(-0.5, -0.5, 0.5, 0.5)
    cam = _screen_cam()
    # 0.x: worldNormalLength = |M⁻ᵀ n| undoes a uniform scale: 0.01 × width metres at any size.
    for formula, width, metres, matrix in ((OutlineFormula.MToon0x, 10.0, 0.1, np.eye(4)),
                                           (OutlineFormula.MToon0x, 10.0, 0.1, sc.scale(2, 2, 2)),
                                           (OutlineFormula.MToon10, 0.1, 0.1, sc.scale(2, 2, 2))):
        p = Pass(outline_mode=OutlineMode.World, outline_formula=formula, outline_width=width)
        clip = outline.outline_clip(mesh, matrix, cam, p)
        plain = outline.outline_clip(mesh, matrix, cam, replace(p, outline_width=0.0))
        assert np.allclose(plain[3] - clip[3], metres), formula  # camera at z=3 looks down −Z: w = 3 − z


def test_screen_outline_grows_by_a_share_of_the_screen_height():
    """MToon 1.0 Screen: ``2 * outlineWidthFactor * min(w, P[1][1])`` in clip space, x by the aspect:
    while w <= P[1][1], the silhouette moves by ``outlineWidthFactor`` × the screen height in pixels
    on both axes (0.x: ``0.01 * _OutlineWidth * min(w, _OutlineScaledMaxDistance)`` / 2 of it)."""
    mesh = sc.quad(-0.5, -0.5, 0.5, 0.5)
    normals = np.zeros((2, 3, 3), np.float32)
    normals[..., 0] = 1.0  # pointing along +x: the offset is along the screen's x
    mesh = replace(mesh, normals=normals)
    cam = sc.camera(64, 48, eye=(0, 0, 1.2), fov=100.0)  # P[1][1] = cot(50°) < w: capped
    p = Pass(outline_mode=OutlineMode.Screen, outline_formula=OutlineFormula.MToon10, outline_width=0.05)
    clip = outline.outline_clip(mesh, np.eye(4), cam, p)
    plain = outline.outline_clip(mesh, np.eye(4), cam, replace(p, outline_width=0.0))
    p11 = cam.projection[1, 1]
    w = plain[3]
    expected = 2 * 0.05 * np.minimum(w, p11) * (48 / 64)
    assert np.allclose(clip[0] - plain[0], expected) and np.allclose(clip[1], plain[1])
    old = replace(p, outline_formula=OutlineFormula.MToon0x, outline_width=5.0, outline_max_distance=1.0)
    clip = outline.outline_clip(mesh, np.eye(4), cam, old)
    assert np.allclose(clip[0] - plain[0], 0.01 * 5.0 * np.minimum(w, 1.0) * (48 / 64))


def test_outlines_of_several_meshes_at_once_equal_the_scalar_program_corner_by_corner():
    """The vertex stage runs every outlined renderer's program in one set of array operations
    (``outline_clip_many``): each corner must still get the bits of its own program, with its own
    matrix (mirrored ones included), width, maximum distance and width texture, whatever mode and
    formula the others have. Expected values: the scalar reference's ``outline_clip``, corner by corner."""
    from tests.reference import scalar_shading as sh

    cam = sc.camera(64, 48, eye=(0.3, 0.8, 3.0), fov=55.0)
    meshes = (sc.uv_sphere(0.6, 8, 5), sc.cube(0.8), sc.quad(-0.5, -0.5, 0.5, 0.5))
    matrices = (np.eye(4), sc.translate(0.4, -0.2, 0.1) @ sc.scale(1.5, 0.7, 1.2), sc.scale(-1.0, 1.0, 2.0))
    rng = np.random.default_rng(7)
    items = []
    for k, mode in enumerate((OutlineMode.World, OutlineMode.Screen) * 3):
        for formula in (OutlineFormula.MToon0x, OutlineFormula.MToon10):
            mesh, matrix = meshes[k % 3], matrices[(k + int(formula is OutlineFormula.MToon10)) % 3]
            p = Pass(outline_mode=mode, outline_formula=formula, outline_width=0.004 * (k + 1) * (3 if k % 2 else 1),
                     outline_max_distance=0.5 + k)
            factors = rng.random(3 * mesh.triangle_count) if k % 3 == 1 else None
            items.append((mesh, matrix, p, factors))
    clips = outline.outline_clip_many(items, cam)
    V, P = cam.view_matrix.tolist(), cam.projection.tolist()
    for (mesh, matrix, p, factors), clip in zip(items, clips, strict=True):
        positions = np.asarray(mesh.positions, dtype=np.float64)
        normals = np.asarray(mesh.normals, dtype=np.float64).reshape(-1, 3)
        corners = np.asarray(mesh.triangles).reshape(-1)
        expected = [sh.outline_clip(p, positions[v].tolist(), normals[c].tolist(), matrix.tolist(), V, P,
                                    None if factors is None else float(factors[c]))
                    for c, v in enumerate(corners)]
        assert clip.shape == (4, corners.size)
        assert np.array_equal(clip.T, np.array(expected)), (p.outline_mode, p.outline_formula)
    # The same corners one renderer at a time give the same bits.
    for item, clip in zip(items, clips, strict=True):
        assert np.array_equal(outline.outline_clip(item[0], item[1], cam, item[2], item[3]), clip)


def test_outline_off_is_the_plain_vertex_stage_and_a_pass_like_any():
    base = Pass()
    ring = Pass(name="Outline", cull=Cull.Front, outline_mode=OutlineMode.World, outline_width=0.5,
                outline_formula=OutlineFormula.MToon10)
    scene = _outline_scene(base)
    assert np.array_equal(_core(scene).color, _core(_outline_scene(replace(base, outline_width=3.0))).color)
    two = replace(scene, renderers=(replace(scene.renderers[0], material=Material(
        lighting=Lighting.Unlit, passes=(base, replace(ring, cull=Cull.Off)))),))
    calls = drawlist.draw_calls(two)
    assert [c.state.name for c in calls] == ["Pass", "Outline"]
    from blendlib.explain import framedebug

    stats = framedebug.draw_list(two)
    assert stats[1].fragments > stats[0].fragments  # the pushed-out quad covers more pixels


def _outline_codes(color, outline_color, mix, blend=False, clear=(0, 0, 0, 0), color_space=ColorSpace.Gamma):
    """The 8-bit codes at the centre of a quad drawn by one MToon outline pass (Unlit ``color``)."""
    p = Pass(name="Outline", cull=Cull.Off, outline_mode=OutlineMode.World, outline_formula=OutlineFormula.MToon10,
             outline_width=0.0, outline_color=outline_color, outline_lighting_mix=mix)
    if blend:
        p = replace(p, blend=True, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha, zwrite=False)
    scene = _outline_scene(p)
    scene = replace(scene, clear_color=clear, color_space=color_space, renderers=(replace(
        scene.renderers[0], material=replace(scene.renderers[0].material, color=color)),))
    frame = _core(scene)
    assert np.array_equal(frame.color, render_reference(scene)[0])
    return np.round(frame.color[24, 32] * 255).astype(int).tolist()


def test_outline_colour_is_mtoons_outline_colour_mixed_with_the_lit_colour():
    """MToon 0.x (MToonCore.cginc): ``MTOON_OUTLINE_COLOR_FIXED``: ``col = _OutlineColor``;
    ``MTOON_OUTLINE_COLOR_MIXED``: ``col = _OutlineColor * lerp(1, col, _OutlineLightingMix)``; MToon 1.0
    (vrmc_materials_mtoon_lighting_mtoon.hlsl): ``outlineCol = _OutlineColor.rgb * lerp(1, baseCol,
    _OutlineLightingMix)``, alpha ``input.alpha`` (the base pass's). Codes by hand from those formulas."""
    lit = (0.8, 0.6, 1.0, 1.0)
    # Fixed (mix 0): exactly the outline colour, whatever the lit colour.
    assert _outline_codes(lit, (1.0, 0.0, 0.0), 0.0) == [255, 0, 0, 255]
    # Mix 1: the product (0.5 * 0.8, 1.0 * 0.6, 0.2 * 1.0) = (0.4, 0.6, 0.2) → 102, 153, 51.
    assert _outline_codes(lit, (0.5, 1.0, 0.2), 1.0) == [102, 153, 51, 255]
    # Mix 0.5: outline * (1 + 0.5 * (lit - 1)) = (0.5 * 0.9, 1.0 * 0.8, 0.2 * 1.0) = (0.45, 0.8, 0.2).
    assert _outline_codes(lit, (0.5, 1.0, 0.2), 0.5) == [115, 204, 51, 255]
    # Alpha is the base pass's: _Color.a 0.4 blends the red outline over a blue background.
    assert _outline_codes((0.8, 0.4, 1.0, 0.4), (1.0, 0.0, 0.0), 0.0, blend=True, clear=(0, 0, 1, 1)) == [
        round(0.4 * 255), 0, round(0.6 * 255), round((0.4 * 0.4 + 0.6 * 1.0) * 255)]  # alpha blends too
    # Linear colour space: _OutlineColor is a gamma colour (decoded, then encoded when stored).
    assert _outline_codes(lit, (0.5, 1.0, 0.2), 0.0, color_space=ColorSpace.Linear) == [128, 255, 51, 255]
    # No outline colour: the lit colour, as every other pass.
    assert _outline_codes(lit, None, 0.0) == [204, 153, 255, 255]


def test_outline_width_texture_multiplies_the_width_per_vertex():
    """MToon: ``width × tex2Dlod(_OutlineWidthTexture, TRANSFORM_TEX(uv, _MainTex)).r``. A sphere whose
    left half (u < 0.5) samples red 0 and right half red 1 (Point): no outline ring on the left, a
    ring of ``outlineWidthFactor`` metres on the right (MToon 1.0 World); 0.x's texture is sRGB:
    in Linear red 0.5 (code 128) decodes to 0.2158, in Gamma stays 0.502."""
    from tests.reference.feature_sweeps import planar_uvs

    sphere = planar_uvs(sc.uv_sphere(0.5, 48, 24), 0.5)
    pixels = np.ones((1, 2, 4), np.float32)
    pixels[0, 0, 0] = 0.0

    def ring(texture_pixels, encoding="Data", formula=OutlineFormula.MToon10, width=0.1, color_space=ColorSpace.Gamma):
        line = Pass(name="Outline", cull=Cull.Front, outline_mode=OutlineMode.World, outline_formula=formula,
                    outline_width=width, outline_color=(0.0, 1.0, 0.0))
        mat = Material(lighting=Lighting.Unlit, color=(1, 0, 0, 1), passes=(Pass(name="Base"), line),
                       outline_width_tex=Texture(texture_pixels, encoding=encoding),
                       outline_width_tex_filter=TextureFilter.Point, outline_width_tex_wrap=TextureWrap.Clamp)
        scene = DrawScene(camera=sc.camera(200, 100, eye=(0, 0, 5), fov=30.0), clear_color=(0, 0, 0, 1),
                          renderers=(sc.renderer(sphere, mat),), color_space=color_space)
        frame = _core(scene)
        assert np.array_equal(frame.color, render_reference(scene)[0])
        green = (frame.color[50, :, 1] > 0.5) & (frame.color[50, :, 0] < 0.5)
        columns = np.flatnonzero(green)
        return columns, frame

    columns, frame = ring(pixels)
    red = np.flatnonzero(frame.color[50, :, 0] > 0.5)
    assert columns.size and columns.min() > red.max()  # only right of the sphere
    # The ring: the sphere's silhouette grown from 0.5 to 0.6 m at 5 m, fov 30°: tan(asin(r / 5)) × 50 /
    # tan(15°) pixels from the centre, each side.
    def edge(r):
        return 100 + math.tan(math.asin(r / 5)) / math.tan(math.radians(15)) * 50
    assert abs(columns.max() + 1 - edge(0.6)) < 1.0 and abs(columns.min() - edge(0.5)) < 1.5
    # 0.x, sRGB texture, red code 128 on the right: ×0.5020 in Gamma, ×0.2158 in Linear (decoded).
    half = pixels.copy()
    half[0, 1, 0] = 128 / 255
    for color_space, factor in ((ColorSpace.Gamma, 128 / 255), (ColorSpace.Linear, colorspace.decode(128 / 255))):
        columns, _ = ring(half, "sRGB", OutlineFormula.MToon0x, width=10.0, color_space=color_space)
        assert abs(columns.max() + 1 - edge(0.5 + 0.1 * factor)) < 1.0, color_space


def test_outline_colour_out_of_range_is_a_one_line_error():
    from blendlib.core.scene import SceneError, validate_scene

    for bad, words in ((dict(outline_color=(math.nan, 0.0, 0.0)), "outline colour"),
                       (dict(outline_color=(-0.5, 0.0, 0.0)), "outline colour"),
                       (dict(outline_color=(1.0, 0.0, 0.0), outline_lighting_mix=1.5), "outline lighting mix")):
        with pytest.raises(SceneError, match=words) as info:
            validate_scene(_outline_scene(Pass(**bad)))
        assert "\n" not in str(info.value)


def test_forward_add_passes_count_per_light_in_the_scalar_reference_too():
    sun = ForwardLight("A", LightType.Directional, render_mode=LightRenderMode.Important)
    scene = _plane_scene((BASE, ADD, Pass(light_mode=LightMode.ShadowCaster)), lights_=(sun, replace(sun, name="B")))
    assert len(drawlist.draw_calls(scene)) == 3
    _assert_equal_to_reference(scene)


# ------------------------------------------------------------------ agreement with OpenGL (llvmpipe)

STEP = 1 / 255 + 1e-6


@functools.cache
def _gl_sweep(name: str):
    return render_gl(_gl_scene(name))


def _gl_scene(name: str) -> DrawScene:
    """The sweep as checked against GL: the mip sweeps without their plane that has no mipmaps (a
    minified texture aliases: float32 and float64 texture coordinates pick other texels there)."""
    scene = FEATURE_SWEEPS[name]()
    if name.startswith("mips"):
        scene = replace(scene, renderers=tuple(r for r in scene.renderers if r.material.main_tex_mipmaps))
    return scene


def _within(ours: np.ndarray, gl: np.ndarray, steps: float, scene: DrawScene) -> np.ndarray:
    """Per pixel: every channel within ``steps`` 8-bit steps; in Linear LDR also within 5/255 linear
    (llvmpipe's sRGB blending, tests/core/test_gl_reference.py's module docstring)."""
    ok = np.all(np.abs(ours.astype(np.float64) - gl) <= steps * STEP, axis=-1)
    if scene.color_space is ColorSpace.Linear and not scene.hdr:
        ok |= np.abs(decode(ours[..., :3]) - decode(gl[..., :3])).max(axis=-1) <= 5 / 255
    return ok


@pytest.mark.parametrize("name", list(FEATURE_SWEEPS))
def test_feature_sweeps_agree_with_gl(name):
    """Lights, vertex colours and outlines: ≥ 99.5 % of pixels within one 8-bit step (measured 99.7 %
    (lights, Gamma LDR) to 100 %); mipmapped frames: ≥ 99 % within three steps (measured 99.6 %
    Trilinear, 99.99 % Point, 100 % Bilinear): llvmpipe's LOD is 0.5 × fast_log2(ρ²), a piecewise-
    linear log2 up to 0.043 below the GL specification's, which moves Trilinear's level weights by
    up to 4 %. Stencil equal."""
    scene = _gl_scene(name)
    frame = _core(scene)
    gl = _gl_sweep(name)
    mipmapped = name.startswith("mips")
    ok = _within(frame.color, gl[0], 3 if mipmapped else 1, scene)
    share = ok.mean()
    print(f"\n{name}: {share:.4%} within {3 if mipmapped else 1} step(s)")
    assert share >= (0.99 if mipmapped else 0.995), f"{name}: {(~ok).sum()} pixels off"
    assert np.array_equal(frame.stencil, gl[2])


@pytest.mark.parametrize("first", range(0, 80, 20))
def test_random_feature_scenes_agree_with_gl(first):
    """Random scenes with lights, vertex colours, mipmaps and outlines (20 seeds a case, 80 in all;
    measured over the 80: 99.97 % of pixels of the scenes without mipmaps within one step, 99.99 %
    of those with mipmaps within three): scenes without mipmaps ≥ 99.5 % within one step, with
    mipmaps ≥ 99 % within three, stencil equal."""
    counts = {False: [0, 0], True: [0, 0]}  # mipmapped → [pixels, agreeing]
    for s in range(first, first + 20):
        scene = seeded_scene(s, shared=False, features=True)
        mipmapped = any(r.material.main_tex_mipmaps and r.material.main_tex is not None for r in scene.renderers)
        ours, gl = _core(scene), render_gl(scene)
        ok = _within(ours.color, gl[0], 3 if mipmapped else 1, scene) & (ours.stencil == gl[2])
        counts[mipmapped][0] += ok.size
        counts[mipmapped][1] += int(ok.sum())
    for mipmapped, limit in ((False, 0.995), (True, 0.99)):
        pixels, agreeing = counts[mipmapped]
        assert pixels == 0 or agreeing / pixels >= limit, (mipmapped, agreeing / pixels)


def test_draw_list_and_pixel_history_name_the_light_of_each_forward_add_draw():
    """docs/json.md: ``light`` is the light a ForwardAdd draw is for, null for the other draws."""
    from blendlib.explain import framedebug

    sun = ForwardLight("Rim", LightType.Directional, axis=(0, 0, 1), render_mode=LightRenderMode.Important)
    point = ForwardLight("Bulb", LightType.Point, position=(0, 0, 1), range=5.0, render_mode=LightRenderMode.Important)
    scene = _plane_scene((BASE, ADD), lights_=(sun, point))
    items = framedebug.draw_list_json(framedebug.draw_list(scene))
    # By importance (drawlist.pixel_lights): the sun's 1 before the bulb's 1 × falloff(1/25) = 0.5.
    assert [(i["pass_name"], i["light"]) for i in items] == [("Base", None), ("Add", "Rim"), ("Add", "Bulb")]
    history = framedebug.pixel_history(scene, 16, 16).to_json()
    assert [(f["pass_name"], f["light"], f["result"]) for f in history["fragments"]] == [
        ("Base", None, "written"), ("Add", "Rim", "written"), ("Add", "Bulb", "written")]


@pytest.mark.parametrize("apart", [False, True])  # spans filling their box (running counts), or far apart
def test_rows_holding_an_unsaturated_alpha_are_found_span_by_span(apart, monkeypatch):
    """:func:`fragment._unsaturated` says of each span whether one of its pixels' stored alpha is
    not 255, as reading every pixel of it does: by running counts over a compact box, by the
    spans' pixels when they lie far apart."""
    from blendlib.core import fragment, raster

    width, height = 64, 48
    rng = np.random.default_rng(int(apart))
    alpha = np.where(rng.random(width * height) < 0.05, rng.integers(0, 255, width * height), 255).astype(np.uint8)
    count = 40
    y = np.sort(rng.integers(0, 2, count) * 40 if apart else rng.integers(10, 16, count))
    x0 = rng.integers(0, 2, count) * (width - 9) if apart else rng.integers(20, 28, count)
    length = rng.integers(1, 9, count)
    zeros = np.zeros(count, dtype=np.int64)
    rows = raster.Rows(tri=zeros, y=y.astype(np.int64), x0=x0.astype(np.int64), length=length.astype(np.int64),
                       c0=zeros, c1=zeros, dy0=zeros, dy1=zeros, swap=zeros.astype(bool), area=zeros + 1)
    plane = alpha.reshape(height, width)
    expected = np.array([(plane[yy, xx:xx + n] != 255).any() for yy, xx, n in zip(y, x0, length, strict=True)])
    assert expected.any() and not expected.all()
    rasterised = []
    real = raster.rasterize_rows
    monkeypatch.setattr(raster, "rasterize_rows", lambda *a, **k: rasterised.append(1) or real(*a, **k))
    assert np.array_equal(fragment._unsaturated(alpha, width, rows), expected)
    assert bool(rasterised) == apart


@pytest.mark.parametrize("color_space", [ColorSpace.Gamma, ColorSpace.Linear])
@pytest.mark.parametrize("filt", [TextureFilter.Point, TextureFilter.Bilinear])
def test_texture_channels_of_exactly_one_shade_as_the_reference(color_space, filt, monkeypatch):
    """A white texture with a varying alpha (a particle sprite) and a varying one that is opaque:
    their channels of 1.0 sample to exactly 1 and ``shade.shade`` leaves their products out
    (``ones``). Every vertex colour mode, lighting and encoding of the vertex colour sweep, drawn
    with either texture: the frame equals the scalar reference's bit for bit."""
    from tests.reference.feature_sweeps import vertex_color_sweep

    rng = np.random.default_rng(31)
    sprite = rng.uniform(0.1, 1.0, size=(4, 4, 4)).astype(np.float32)
    sprite[..., :3] = 1.0
    opaque = rng.uniform(0.1, 1.0, size=(4, 4, 4)).astype(np.float32)
    opaque[..., 3] = 1.0
    textures = [Texture(sprite, encoding="sRGB", name="sprite"), Texture(opaque, encoding="sRGB", name="opaque")]
    scene = vertex_color_sweep(color_space)
    renderers = []
    for k, r in enumerate(scene.renderers):
        if r.material.main_tex is not None:
            r = replace(r, material=replace(r.material, main_tex=textures[k % 2], main_tex_filter=filt))
        renderers.append(r)
    seen = []
    real = shade.shade_texels
    monkeypatch.setattr(shade, "shade_texels", lambda *a, **k: seen.append(a[8] if len(a) > 8 else k.get("ones"))
                        or real(*a, **k))
    _assert_equal_to_reference(replace(scene, renderers=tuple(renderers)))
    assert {(True, True, True, False), (False, False, False, True)} <= set(seen)
