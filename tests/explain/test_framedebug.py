"""The frame debugger (docs/framedebugger.md) against the scalar reference: draw statistics, pixel histories
replayed fragment by fragment, stepping through draws from snapshots."""

from __future__ import annotations

import functools
import json
from dataclasses import replace

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core.drawlist import draw_calls
from blendlib.core.scene import SceneError
from blendlib.core.vocabulary import BlendFactor, Cull, Pass, Queue, pass_state_text
from blendlib.explain import framedebug as fd
from tests.reference import scalar
from tests.reference import scenes as sc
from tests.reference.random_scenes import describe, seeded_scene

SEEDS = [0, 2, 4, 7, 9, 10, 11, 13, 21, 33]
DMAX = 2**24 - 1


def _all_pixels(scene):
    return [(x, y) for y in range(scene.camera.height) for x in range(scene.camera.width)]


def _reference(scene, max_calls=None):
    log = scalar.FragmentLog()
    frame = scalar.render_reference(scene, max_calls=max_calls, log=log)
    return frame, log


def _stored(buf, x, y):
    """The scalar buffers' pixel in frame units: (rgba float32 (4,), depth float32, stencil int)."""
    c = buf.color[y][x]
    rgba = np.array(c, dtype=np.float32) if buf.hdr else (np.array(c, dtype=np.int64) / 255.0).astype(np.float32)
    return rgba, np.float32(buf.depth[y][x] / DMAX), buf.stencil[y][x]


@pytest.mark.parametrize("seed", SEEDS)
def test_every_pixel_history_replays_through_the_scalar_reference_to_the_frame(seed):
    scene = seeded_scene(seed)
    w, h = scene.camera.width, scene.camera.height
    histories, frame = fd.pixel_histories(scene, _all_pixels(scene))
    (color, depth, stencil), log = _reference(scene)
    assert np.array_equal(frame.color, color) and np.array_equal(frame.depth, depth)
    ref_by_pixel: dict[tuple[int, int], list] = {}
    for rec in log.fragments:
        ref_by_pixel.setdefault((rec[1], rec[2]), []).append(rec)
    replay = scalar.Buffers(scene)
    calls = {c.index: c for c in draw_calls(scene)}
    total = 0
    for hist in histories:
        x, y = hist.x, hist.y
        wy = h - 1 - y  # window row (y up)
        ref = ref_by_pixel.get((x, wy), [])
        # the same fragments in the same order, with the same triangle, depth, colour and result
        got = [(f.call.index, f.triangle, f.depth_code, f.result) for f in hist.fragments]
        assert got == [(r[0], r[3], r[4], r[6]) for r in ref], (seed, x, y, describe(scene))
        for f, r in zip(hist.fragments, ref, strict=True):
            assert list(f.source) == list(r[5]), (seed, x, y)
        # replay: each fragment through the reference's own merger, from the cleared pixel
        rgba, d, s = _stored(replay, x, wy)
        assert np.array_equal(np.float32(hist.clear), rgba)
        for f in hist.fragments:
            assert np.array_equal(np.float32(f.before), rgba) and f.depth_before == d and f.stencil_before == s
            if f.result != "alpha_test":
                assert scalar.merge_fragment(x, wy, f.depth_code, list(f.source), calls[f.call.index].state,
                                             replay) == f.result
            rgba, d, s = _stored(replay, x, wy)
            assert np.array_equal(np.float32(f.after), rgba), (seed, x, y, f)
            assert f.depth_after == d and f.stencil_after == s, (seed, x, y, f)
            assert f.depth == np.float32(f.depth_code / DMAX)
        assert np.array_equal(rgba, frame.color[y, x]) and np.array_equal(np.float32(hist.final), rgba)
        assert d == frame.depth[y, x] and s == frame.stencil[y, x]
        # a triangle (even split by clipping) gives at most one fragment per pixel and draw
        keys = [(f.call.index, f.triangle) for f in hist.fragments]
        assert len(keys) == len(set(keys))
        total += len(hist.fragments)
    assert total == len(log.fragments) and len(histories) == w * h


@pytest.mark.parametrize("seed", SEEDS)
def test_draw_list_counts_equal_the_scalar_reference(seed):
    scene = seeded_scene(seed)
    stats = fd.draw_list(scene)
    _, log = _reference(scene)
    counts = log.counts()
    assert [s.call.index for s in stats] == list(range(1, len(draw_calls(scene)) + 1))
    for s in stats:
        assert (s.fragments, s.written) == counts.get(s.call.index, (0, 0)), (seed, s)
        assert s.triangles == log.triangles.get(s.call.index, 0), (seed, s)
    assert sum(s.fragments for s in stats) > 0 or seed == 3


@pytest.mark.parametrize(("seed", "samples"), [(16, 1), (21, 1), (27, 1), (29, 1), (56, 1), (64, 1), (27, 4), (56, 4)])
def test_a_colourless_draw_list_counts_as_the_scalar_reference_and_names_the_real_passes(seed, samples):
    """The draw list renders every pass as ``ColorMask 0`` (its statistics never read a colour):
    on scenes with lights, vertex colours, mipmaps, outlines, alpha tests and stencil, with and
    without MSAA, its counts still equal the scalar reference's, and its draw calls are the
    scene's own, their colour masks and blend states intact."""
    scene = seeded_scene(seed, features=True, msaa=samples)
    stats = fd.draw_list(scene)
    _, log = _reference(scene)
    counts = log.counts()
    written = log.samples_written() if samples > 1 else {}
    calls = draw_calls(scene)
    assert [s.call.state for s in stats] == [c.state for c in calls]
    assert any(c.state.color_mask for c in calls) and any(c.light is not None for c in calls)
    for s in stats:
        assert (s.fragments, s.written) == counts.get(s.call.index, (0, 0)), (seed, samples, s, describe(scene))
        assert s.triangles == log.triangles.get(s.call.index, 0), (seed, s)
        if samples > 1:
            assert s.samples_written == written.get(s.call.index, 0), (seed, s)
    assert any(s.written for s, c in zip(stats, calls, strict=True) if c.state.alpha_test)  # alpha still tested


def test_draw_list_json_items_follow_spec():
    cam = sc.camera(16, 16, eye=(0, 0, 5))
    glass = sc.unlit((1, 1, 1, 0.5), queue=Queue.Transparent,
                     passes=[Pass(name="Back", cull=Cull.Front, zwrite=False),
                             Pass(name="Front", blend=True, src_blend=BlendFactor.SrcAlpha,
                                  dst_blend=BlendFactor.OneMinusSrcAlpha, zwrite=False)])
    floor = sc.unlit((0, 1, 0, 1), passes=())
    scene = sc.scene(cam, sc.renderer(sc.cube(1.0), glass, name="Glass"),
                     sc.renderer(sc.quad(-3, -3, 3, 3, z=-1.0), floor, name="Floor", slot=1))
    items = json.loads(json.dumps(fd.draw_list_json(fd.draw_list(scene))))
    assert [(i["index"], i["object"], i["pass"], i["pass_name"]) for i in items] == [
        (1, "Floor", 0, "Pass"), (2, "Glass", 0, "Back"), (3, "Glass", 1, "Front")]
    first = items[0]
    assert first["slot"] == 1 and first["queue"] == 2000 and first["material"] == floor.name
    assert first["state"] == pass_state_text(Pass()) == "Cull Back ZWrite On ZTest LEqual Blend Off"
    assert first["distance"] == pytest.approx(6.0) and first["triangles"] == 2
    assert first["fragments"] == first["written"] == 256  # the floor fills the 16x16 frame
    assert items[2]["state"] == "Cull Back ZWrite Off ZTest LEqual Blend SrcAlpha OneMinusSrcAlpha"
    assert items[1]["written"] == items[1]["fragments"] > 0  # back faces in front of the floor
    assert set(first) >= {"index", "object", "slot", "material", "pass", "pass_name", "queue", "distance", "state",
                          "triangles", "fragments", "written"}


def test_history_within_one_draw_is_primitive_order_and_json_is_exact():
    """A Cull Off blended mesh: its triangles blend at a pixel in mesh order, and the JSON reads
    back to the frame's float32 values exactly."""
    cam = sc.screen_camera(4, 4)
    far_first = sc.make_mesh([(0, 0, -0.5), (4, 0, -0.5), (0, 4, -0.5), (0, 0, 0.5), (4, 0, 0.5), (0, 4, 0.5)],
                             [(0, 1, 2), (3, 5, 4)])  # second triangle is a back face
    mat = sc.unlit((0.8, 0.3, 0.1, 0.4), queue=Queue.Transparent,
                   passes=[Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
                                dst_blend=BlendFactor.OneMinusSrcAlpha)])
    scene = sc.scene(cam, sc.renderer(far_first, mat, name="Knot"))
    hist = fd.pixel_history(scene, 0, 3)  # bottom-left pixel (row 3 from the top)
    assert [f.triangle for f in hist.fragments] == [0, 1] and [f.result for f in hist.fragments] == ["written"] * 2
    assert hist.fragments[0].polygon is None
    assert hist.fragments[0].before == hist.clear and hist.fragments[1].before == hist.fragments[0].after
    data = json.loads(json.dumps(hist.to_json()))
    frame = render_scene(scene)
    assert np.array_equal(np.float32(data["final"]), frame.color[3, 0])
    assert np.array_equal(np.float32(data["fragments"][-1]["after"]), frame.color[3, 0])
    assert np.float32(data["fragments"][0]["depth"]) == np.float32(hist.fragments[0].depth_code / DMAX)
    assert set(data["fragments"][0]) >= {
        "draw", "object", "slot", "pass", "triangle", "polygon", "depth", "source", "before", "after",
        "depth_before", "depth_after", "stencil_before", "stencil_after", "result"}
    assert (data["x"], data["y"], data["fragments"][0]["object"]) == (0, 3, "Knot")


def test_mesh_names_triangles_by_loop_triangle_and_polygon():
    cam = sc.screen_camera(4, 4)
    mesh = sc.quad(0, 0, 4, 4)
    named = replace(mesh, polygons=np.array([7, 7]), loop_triangles=np.array([10, 11]))
    scene = sc.scene(cam, sc.renderer(named, sc.unlit((1, 0, 0, 1)), name="Quad"))
    hist = fd.pixel_history(scene, 1, 1)
    assert [(f.triangle, f.polygon) for f in hist.fragments] in ([(10, 7)], [(11, 7)])


def test_a_history_is_told_only_of_chunks_in_its_pixels_rows(monkeypatch):
    """Chunks of fragments in rows without an asked pixel merge unobserved: the observer is told of
    chunks in the pixels' rows only, and the histories equal those told of every chunk."""
    seen_rows = []
    original = fd._PixelObserver.fragments

    def fragments(self, call, frags, outcome):
        seen_rows.append(np.unique(frags.pix // 96))
        return original(self, call, frags, outcome)

    monkeypatch.setattr(fd._PixelObserver, "fragments", fragments)
    monkeypatch.setattr(fd, "render_scene", functools.partial(render_scene, chunk_candidates=200))  # many chunks
    mesh = sc.uv_sphere(radius=1.0, segments=24, rings=16)
    p = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
             dst_blend=BlendFactor.OneMinusSrcAlpha)
    scene = sc.scene(sc.camera(96, 64, eye=(0, 0, 3.2)),
                     sc.renderer(mesh, sc.Material(color=(0.2, 0.6, 0.9, 0.4), queue=Queue.Transparent, passes=(p,))))
    pixels = [(40, 20), (50, 41)]
    histories, _ = fd.pixel_histories(scene, pixels)
    rows = {64 - 1 - y for _, y in pixels}
    assert seen_rows and all(rows & set(r.tolist()) for r in seen_rows)
    told = len(seen_rows)

    class TellEverything(fd._PixelObserver):
        def __init__(self, *args):
            super().__init__(*args)
            self.watched_rows = None

    monkeypatch.setattr(fd, "_PixelObserver", TellEverything)
    seen_rows.clear()
    every, _ = fd.pixel_histories(scene, pixels)
    assert len(seen_rows) > told  # told of every chunk this time
    assert [h.to_json() for h in histories] == [h.to_json() for h in every]
    assert all(h.fragments for h in histories)



@pytest.mark.parametrize(("seed", "samples"), [(8, 1), (15, 1), (17, 1), (21, 1), (23, 1), (9, 4), (15, 4)])
def test_one_pixel_s_history_renders_its_row_and_equals_the_whole_frame_s(seed, samples, monkeypatch):
    """``pixel_history`` renders only the pixel's row (a band of one row, y counted from the
    bottom), and every pixel's history (mipmapped textures, stencil, MSAA coverage included)
    equals the one ``pixel_histories`` takes from a render of the whole frame, its final colour
    the whole frame's pixel."""
    scene = seeded_scene(seed, features=True, msaa=samples)
    w, h = scene.camera.width, scene.camera.height
    every, frame = fd.pixel_histories(scene, _all_pixels(scene))
    bands = []

    def banded(*args, band=None, **kwargs):
        bands.append(band)
        return render_scene(*args, band=band, **kwargs)

    monkeypatch.setattr(fd, "render_scene", banded)
    for whole in every:
        one = fd.pixel_history(scene, whole.x, whole.y)
        assert one.to_json() == whole.to_json(), (seed, samples, whole.x, whole.y, describe(scene))
        assert one.final == tuple(float(v) for v in frame.color[whole.y, whole.x])
    assert bands == [(h - 1 - y, h - y) for y in range(h) for _ in range(w)]
    assert sum(len(x.fragments) for x in every) > w * h // 4  # the frame is well covered

def test_empty_history_and_bad_pixels():
    scene = seeded_scene(3)  # draws nothing
    hist = fd.pixel_history(scene, 0, 0)
    assert hist.fragments == [] and hist.final == hist.clear
    for x, y in [(-1, 0), (0, -1), (scene.camera.width, 0), (0, scene.camera.height)]:
        with pytest.raises(SceneError, match="outside"):
            fd.pixel_history(scene, x, y)


def test_float32_json_is_the_shortest_text_of_the_float32():
    for v in [0.1, 1 / 3, 0.5019608, 1e-8, 123456.789, 0.0]:
        text = json.dumps(fd.float32_json(v))
        assert np.float32(json.loads(text)) == np.float32(v)
        assert len(text) <= len(repr(float(np.float32(v))))
    assert json.dumps(fd.float32_json(0.1)) == "0.1"


@pytest.mark.parametrize("seed", [0, 9, 10])
def test_stepping_from_snapshots_equals_the_reference_stopped_after_k_draws(seed):
    scene = seeded_scene(seed)
    n = len(draw_calls(scene))
    per = fd.snapshot_bytes(scene.camera.width, scene.camera.height, scene.hdr)
    cap = fd.FrameCapture.capture(scene, memory=2 * per)  # at most 2 snapshots: replay several draws
    assert cap.interval == -(-n // 2) and len(cap.snapshots) <= 2 and cap.snapshot_memory <= 2 * per
    _, log = _reference(scene)
    for k in range(n + 2):
        frame, mask = cap.frame_after(k, highlight=True)
        color, depth, stencil = scalar.render_reference(scene, max_calls=k)
        assert np.array_equal(frame.color, color) and np.array_equal(frame.depth, depth), (seed, k)
        assert np.array_equal(frame.stencil, stencil), (seed, k)
        expect = np.zeros((scene.camera.height, scene.camera.width), dtype=bool)
        for draw, x, wy, *_ in log.fragments:
            if draw == min(k, n):  # past the last draw: the whole frame, the last draw marked
                expect[scene.camera.height - 1 - wy, x] = True
        assert np.array_equal(mask, expect), (seed, k)
        plain, none = cap.frame_after(k)
        assert none is None and np.array_equal(plain.color, frame.color)
    with pytest.raises(SceneError):
        cap.frame_after(-1)


def test_snapshots_taken_band_by_band_share_unchanged_rows(monkeypatch):
    """A frame large enough for two screen bands: the capture draws its calls in batches and each
    band hands its rows to the snapshot after the marked draws (no stop between draw calls).
    Stepping to every draw equals a render stopped there (itself checked against the scalar
    reference in tests/core/test_observer.py), and snapshots after draws that reach a few rows
    copy only those rows."""
    from blendlib.core import pipeline
    from blendlib.explain import snapshots

    taken = []
    original_take = snapshots.RowSnapshots.take

    def take(self, index, previous, buffers, y0, y1):
        taken.append((index, y0, y1))
        return original_take(self, index, previous, buffers, y0, y1)

    monkeypatch.setattr(snapshots.RowSnapshots, "take", take)
    exact_steps = []
    original_steps = pipeline._steps
    monkeypatch.setattr(pipeline, "_steps", lambda calls, prepared, exact: exact_steps.append(exact)
                        or original_steps(calls, prepared, exact))
    w, h = 1000, 640  # 640k pixels: drawn in bands (pipeline.BAND_PIXELS)
    blend = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
                 dst_blend=BlendFactor.OneMinusSrcAlpha)
    renderers = [sc.renderer(sc.quad(-9, -6, 9, 6, z=-2.0), sc.unlit((0.2, 0.3, 0.4, 1.0)), name="Back")]
    for k in range(6):  # small spheres, each in a few rows of its own
        mat = sc.Material(name=f"Glass{k}", queue=Queue.Transparent, color=(0.9, 0.2 * k, 0.5, 0.4), passes=(blend,))
        renderers.append(sc.renderer(sc.uv_sphere(0.35, 12, 8), mat, name=f"Ball{k}",
                                     matrix=sc.translate(-2.5 + k, -1.6 + 0.64 * k, 0.0)))
    scene = sc.scene(sc.camera(w, h, eye=(0, 0, 6)), *renderers)
    n = len(draw_calls(scene))
    per = fd.snapshot_bytes(w, h, scene.hdr)
    cap = fd.FrameCapture.capture(scene, workers=2)
    assert cap.interval == 1 and len(cap.snapshots) == n - 1
    assert exact_steps and not any(exact_steps)  # batches, not one call a step
    assert any(0 < y1 - y0 < h for _, y0, y1 in taken)  # rows handed over band by band
    for index in cap.snapshots:  # each snapshot's bands cover every row
        bands = sorted((y0, y1) for i, y0, y1 in taken if i == index)
        assert bands[0][0] == 0 and bands[-1][1] == h
        assert all(a[1] == b[0] for a, b in zip(bands, bands[1:], strict=False))
    # The first snapshot is whole; the spheres after it reach about 60 of the 640 rows each.
    assert per <= cap.snapshot_memory < per + (n - 2) * per // 4
    for k in range(n + 1):
        stepped, _ = cap.frame_after(k)
        stopped = render_scene(scene, until_draw=k, workers=1)
        for name in ("color", "depth", "stencil"):
            assert np.array_equal(getattr(stepped, name), getattr(stopped, name)), (k, name)


def test_snapshot_bound_at_1080p():
    """The stated bound: S2 at 1080p keeps its snapshots within SNAPSHOT_MEMORY (well under 2 GB)."""
    per = fd.snapshot_bytes(1920, 1080, False)
    assert per == 1920 * 1080 * 9 and fd.SNAPSHOT_MEMORY // per == 28
    assert fd.SNAPSHOT_MEMORY // fd.snapshot_bytes(1920, 1080, True) == 12


def test_colourless_prepass_is_shaded_only_where_a_history_reads_it(monkeypatch):
    """A ``ZWrite On, ColorMask 0`` prepass of a self-overlapping lit mesh: the draw list and the
    pixel histories (colours, depths, triangles of the prepass fragments) equal those of renders
    that shade every prepass fragment, while the draw list shades none of them and a history
    only the chunks on its pixel."""
    from blendlib.core import fragment, prepare

    knot = sc.Material(name="Knot", queue=Queue.Transparent, color=(0.7, 0.5, 0.9, 0.5),
                       passes=(Pass(cull=Cull.Off, color_mask=frozenset()),
                               Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
                                    dst_blend=BlendFactor.OneMinusSrcAlpha)))
    scene = sc.scene(sc.camera(64, 48, eye=(0.3, 0.5, 3.0)),
                     sc.renderer(sc.uv_sphere(0.9, 16, 10), knot, name="Knot", matrix=sc.scale(1.0, 0.5, 1.3)))
    shaded = []
    original = fragment.shade_chunk

    def counting(setup, rows, start, stop, state):
        shaded.append(state.call.pass_index)
        return original(setup, rows, start, stop, state)

    monkeypatch.setattr(fragment, "shade_chunk", counting)
    lean = fd.draw_list(scene, workers=2)
    assert 0 not in shaded  # the draw list read no prepass colour
    pixels = [(32, 24), (20, 30), (40, 18)]
    histories = [fd.pixel_history(scene, x, y).to_json() for x, y in pixels]
    assert any(f["pass"] == 0 for h in histories for f in h["fragments"])
    monkeypatch.setattr(prepare, "chunk_shading", lambda p: original)  # every pass shaded in full
    assert [s.to_json() for s in lean] == [s.to_json() for s in fd.draw_list(scene, workers=2)]
    assert histories == [fd.pixel_history(scene, x, y).to_json() for x, y in pixels]
