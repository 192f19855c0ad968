"""The pipeline's hooks for the explaining tools: draw calls, stop after draw K, resume from a
snapshot, and the per-fragment records an observer receives (with the test that discarded each)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core.drawlist import draw_calls, sort_distance
from blendlib.core.merger import Outcome
from blendlib.core.pipeline import FrameObserver
from blendlib.core.vocabulary import CompareFunction, Cull, Pass, Queue, StencilOp
from tests.reference import scenes as sc
from tests.reference.random_scenes import seeded_scene
from tests.reference.scalar import render_reference


class Recorder(FrameObserver):
    def __init__(self):
        self.lock = threading.Lock()
        self.calls, self.snapshots, self.triangles = [], {}, {}
        self.outcomes: dict[int, list[np.ndarray]] = {}
        self.pixels: dict[int, list[np.ndarray]] = {}

    def draw_begin(self, call, buffers):
        self.calls.append(call.index)

    def fragments(self, call, frags, outcome):
        with self.lock:
            self.outcomes.setdefault(call.index, []).append(outcome.copy())
            self.pixels.setdefault(call.index, []).append(frags.pix.copy())

    def draw_end(self, call, buffers, triangles):
        self.snapshots[call.index] = buffers.copy()
        self.triangles[call.index] = triangles

    def counts(self, index):
        out = np.concatenate(self.outcomes.get(index, [np.zeros(0, np.int8)]))
        return {o: int(np.count_nonzero(out == o)) for o in Outcome}


def _frame_equal(a, b):
    return (np.array_equal(a.color, b.color) and np.array_equal(a.depth, b.depth)
            and np.array_equal(a.stencil, b.stencil))


@pytest.mark.parametrize("seed", [3, 11, 27])
def test_until_draw_equals_the_scalar_reference_stopped_after_k_draws(seed):
    scene = seeded_scene(seed)
    n = len(draw_calls(scene))
    for k in sorted({0, 1, n // 2, n, n + 3}):
        frame = render_scene(scene, until_draw=k, workers=2)
        color, depth, stencil = render_reference(scene, max_calls=k)
        assert np.array_equal(frame.color, color), (seed, k)
        assert np.array_equal(frame.depth, depth) and np.array_equal(frame.stencil, stencil), (seed, k)


@pytest.mark.parametrize("seed", [5, 8])
def test_resume_from_a_snapshot_equals_the_whole_render(seed):
    scene = seeded_scene(seed)
    rec = Recorder()
    full = render_scene(scene, observer=rec, workers=2)
    assert _frame_equal(full, render_scene(scene, workers=2))  # observing changes nothing
    n = len(draw_calls(scene))
    assert rec.calls == list(range(1, n + 1))
    for k0 in (1, n // 2):
        resumed = render_scene(scene, resume=(rec.snapshots[k0], k0), workers=2)
        assert _frame_equal(resumed, full)
        part = render_scene(scene, resume=(rec.snapshots[k0], k0), until_draw=n - 1, workers=1)
        assert _frame_equal(part, render_scene(scene, until_draw=n - 1))


def test_negative_until_draw_is_an_error():
    with pytest.raises(ValueError, match="until_draw"):
        render_scene(seeded_scene(1), until_draw=-1)


def test_outcomes_name_the_test_that_discarded_each_fragment():
    cam = sc.screen_camera(8, 8)
    quad = sc.quad(0, 0, 8, 8, z=0.0)
    cutout = sc.unlit((1, 0, 0, 0.25), passes=[Pass(alpha_test=True)], cutoff=0.5)
    base = sc.unlit((0, 1, 0, 1), passes=[Pass(stencil=True, stencil_pass=StencilOp.Replace, stencil_ref=7)])
    masked = sc.unlit((0, 0, 1, 1), queue=Queue.Transparent,
                      passes=[Pass(ztest=CompareFunction.Less, name="behind"),
                              Pass(ztest=CompareFunction.Always, stencil=True, stencil_ref=7,
                                   stencil_comp=CompareFunction.NotEqual, name="stencil")])
    scene = sc.scene(cam, sc.renderer(quad, cutout, name="A"), sc.renderer(quad, base, name="B"),
                     sc.renderer(quad, masked, name="C"))
    rec = Recorder()
    frame = render_scene(scene, observer=rec)
    names = {c.index: (c.renderer.name, c.pass_index) for c in draw_calls(scene)}
    by_name = {names[i]: rec.counts(i) for i in names}
    assert by_name[("A", 0)][Outcome.ALPHA_TEST] == 64 and by_name[("A", 0)][Outcome.WRITTEN] == 0
    assert by_name[("B", 0)][Outcome.WRITTEN] == 64
    assert by_name[("C", 0)][Outcome.DEPTH] == 64  # same depth, ZTest Less
    assert by_name[("C", 1)][Outcome.STENCIL] == 64  # stencil 7 everywhere, Comp NotEqual 7
    assert np.all(frame.color[..., :3] == (0, 1, 0)) and np.all(frame.stencil == 7)
    assert set(rec.triangles.values()) == {2}


def test_draw_calls_are_numbered_with_euclidean_distance_and_culling_counts():
    cam = sc.camera(16, 16, eye=(0, 0, 5))
    cube = sc.cube(1.0)
    glass = sc.unlit((1, 1, 1, 0.5), queue=Queue.Transparent,
                     passes=[Pass(cull=Cull.Front, zwrite=False), Pass(cull=Cull.Back, zwrite=False)])
    near = sc.renderer(cube, glass, name="Near", matrix=sc.translate(0, 0, 2))
    far = sc.renderer(cube, glass, name="Far", matrix=sc.translate(3, 0, -1))
    scene = sc.scene(cam, near, far)
    calls = draw_calls(scene)
    assert [(c.index, c.renderer.name, c.pass_index) for c in calls] == [
        (1, "Far", 0), (2, "Far", 1), (3, "Near", 0), (4, "Near", 1)]
    assert calls[0].distance == pytest.approx(np.sqrt(3**2 + 6**2)) and calls[2].distance == pytest.approx(3.0)
    assert calls[0].distance == sort_distance(scene, far)
    rec = Recorder()
    render_scene(scene, observer=rec)
    # a cube seen from the front: 6 triangles face the camera side, 6 the back, per pass (some may be
    # edge-on in perspective and count as culled for both): back + front never exceed 12
    assert rec.triangles[1] + rec.triangles[2] <= 12 and rec.triangles[3] + rec.triangles[4] <= 12
    assert rec.triangles[2] >= 2 and rec.triangles[4] >= 2


class DepthRecorder(FrameObserver):
    """Keeps (pixel, depth) of every fragment and whether its depth arrived deferred."""

    def __init__(self):
        self.lock = threading.Lock()
        self.records: list[tuple[np.ndarray, np.ndarray]] = []
        self.deferred = 0

    def fragments(self, call, frags, outcome):
        with self.lock:
            self.deferred += frags.stored_depth is None
            self.records.append((frags.pix.copy(), frags.depth.copy()))

    def arrays(self):
        pix = np.concatenate([p for p, _ in self.records])
        depth = np.concatenate([d for _, d in self.records])
        order = np.lexsort((depth, pix))
        return pix[order], depth[order]


@pytest.mark.parametrize("offset", [(0.0, 0.0), (1.5, 4.0)])
def test_deferred_depth_of_a_provably_passing_pass_equals_the_computed_depth(offset):
    """A ZWrite Off pass over an empty depth buffer passes its LEqual test everywhere (the per-row
    hierarchical-Z bound), so the merge needs no depth; an observer reading ``depth`` gets the same
    codes as a pass that must compute them (ZWrite On), Offset included."""
    def scene(zwrite: bool):
        p = Pass(zwrite=zwrite, ztest=CompareFunction.LEqual, blend=True, cull=Cull.Off,
                 offset_factor=offset[0], offset_units=offset[1])
        tilt = np.eye(4)
        tilt[2, 0] = 0.3  # z grows with x: depth varies across the quad
        material = sc.unlit((0.2, 0.6, 0.9, 0.5), queue=Queue.Transparent, passes=(p,))
        return sc.scene(sc.camera(48, 40, eye=(0, 0, 6)),
                        sc.renderer(sc.quad(-2, -2, 2, 2, uv=False), material, matrix=tilt))

    deferred, computed = DepthRecorder(), DepthRecorder()
    render_scene(scene(False), observer=deferred, workers=1)
    render_scene(scene(True), observer=computed, workers=1)
    assert deferred.deferred > 0 and computed.deferred == 0
    got, want = deferred.arrays(), computed.arrays()
    assert got[0].size > 300
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert np.unique(got[1]).size > 10  # a tilted plane: depth varies across it


class SubsetDepthRecorder(DepthRecorder):
    """Reads the deferred depth of a scattered subset first (every 7th fragment, then a selection
    of that selection), then the whole chunk's, and keeps both."""

    def __init__(self):
        super().__init__()
        self.pairs: list[tuple[np.ndarray, np.ndarray]] = []

    def fragments(self, call, frags, outcome):
        pick = np.arange(3, frags.count, 7)
        sub = frags.select(pick)
        nested = sub.select(np.arange(0, sub.count, 2)).depth.copy()
        partial = sub.depth.copy()
        with self.lock:
            self.pairs.append((pick, partial, nested))
        super().fragments(call, frags, outcome)


def test_deferred_depth_of_a_selection_computes_only_its_rows():
    """``select(...).depth`` of deferred fragments rasterises only the rows holding them (a pixel
    history reads a few fragments of each chunk): the same codes as the whole chunk's depth."""
    p = Pass(zwrite=False, ztest=CompareFunction.LEqual, blend=True, cull=Cull.Off)
    tilt = np.eye(4)
    tilt[2, 0] = 0.3
    material = sc.unlit((0.2, 0.6, 0.9, 0.5), queue=Queue.Transparent, passes=(p,))
    scene = sc.scene(sc.camera(48, 40, eye=(0, 0, 6)), sc.renderer(sc.quad(-2, -2, 2, 2, uv=False), material,
                                                                  matrix=tilt))
    rec = SubsetDepthRecorder()
    render_scene(scene, observer=rec, workers=1, chunk_candidates=211)
    assert rec.deferred > 1 and len(rec.pairs) == len(rec.records)
    checked = 0
    for (pick, partial, nested), (_, whole) in zip(rec.pairs, rec.records, strict=True):
        np.testing.assert_array_equal(partial, whole[pick])
        np.testing.assert_array_equal(nested, whole[pick][::2])
        checked += pick.size
    assert checked > 50


class TriangleRecorder(FrameObserver):
    """Reads the source triangles of every 5th fragment through a selection, then of all."""

    def __init__(self):
        self.lock = threading.Lock()
        self.pairs = []

    def fragments(self, call, frags, outcome):
        pick = np.arange(1, frags.count, 5)
        partial = frags.select(pick).triangle.copy()
        with self.lock:
            self.pairs.append((pick, partial, frags.triangle.copy(), frags.pix.copy()))


def test_deferred_source_triangles_of_a_selection_equal_the_whole_chunks():
    """Observed fragments carry their source triangles on demand; a selection computes only its
    own. Both agree, and each fragment's triangle covers its pixel (a 7-triangle fan)."""
    p = Pass(zwrite=False, blend=True, cull=Cull.Off)
    material = sc.unlit((0.2, 0.6, 0.9, 0.5), queue=Queue.Transparent, passes=(p,))
    scene = sc.scene(sc.camera(48, 40, eye=(0, 0, 3)), sc.renderer(sc.fan(radius=1.0, count=7), material))
    rec = TriangleRecorder()
    render_scene(scene, observer=rec, workers=1, chunk_candidates=97)
    assert len(rec.pairs) > 3
    seen = set()
    for pick, partial, whole, _pix in rec.pairs:
        np.testing.assert_array_equal(partial, whole[pick])
        assert whole.min() >= 0 and whole.max() < 7
        seen.update(np.unique(whole).tolist())
    assert seen == set(range(7))


def test_an_observer_of_draw_boundaries_only_is_told_of_no_fragment():
    """``reads_fragments = False`` (a clock): draw boundaries come call by call, with the buffers
    exactly between calls, and no fragment is reported; the frame is the plain render's."""

    class Clock(Recorder):
        reads_fragments = False

    scene = seeded_scene(11)
    clock = Clock()
    frame = render_scene(scene, observer=clock, workers=2)
    assert clock.calls == [c.index for c in draw_calls(scene)] and not clock.outcomes
    plain = render_scene(scene, workers=2)
    assert _frame_equal(frame, plain)
    for k in (1, len(clock.calls) // 2):
        stopped = render_scene(scene, until_draw=k, workers=1)
        snap = clock.snapshots[k]
        color, depth, stencil = snap.output()
        assert np.array_equal(color, stopped.color) and np.array_equal(depth, stopped.depth)
        assert np.array_equal(stencil, stopped.stencil)


def test_an_observer_of_some_calls_is_told_of_theirs_alone_and_the_others_draw_as_unobserved(monkeypatch):
    """``reads_call``: the fragments of the calls an observer reads are reported with the same
    outcomes as when it reads every call; the others are not reported and draw as an unobserved
    render draws them (an early depth test drops their hidden fragments before shading). The frame
    is the plain render's."""
    from blendlib.core import fragment

    scene = seeded_scene(27)
    calls = draw_calls(scene)
    read = {c.index for c in calls[1::2]}

    class Some(Recorder):
        def reads_call(self, call):
            return call.index in read

    every, some = Recorder(), Some()
    render_scene(scene, observer=every, workers=2)
    plain = render_scene(scene, workers=2)
    observed = []
    original = fragment.shade_chunk
    monkeypatch.setattr(fragment, "shade_chunk", lambda setup, rows, a, b, state: observed.append(
        (state.call.index, state.observed, state.early_depth is not None)) or original(setup, rows, a, b, state))
    frame = render_scene(scene, observer=some, workers=2)
    assert _frame_equal(frame, plain)
    assert set(some.outcomes) == read & set(every.outcomes) and read & set(every.outcomes)
    for index in some.outcomes:
        assert some.counts(index) == every.counts(index)
    assert all(flag == (index in read) for index, flag, _ in observed)
    assert any(early for index, _, early in observed if index not in read)
    assert not any(early for index, _, early in observed if index in read)


def _written_pixels(recorder, index):
    pix = np.concatenate(recorder.pixels.get(index, [np.zeros(0, np.int64)]))
    out = np.concatenate(recorder.outcomes.get(index, [np.zeros(0, np.int8)]))
    return pix[out == Outcome.WRITTEN]


def test_an_observer_of_written_fragments_lets_the_calls_it_reads_test_depth_early(monkeypatch):
    """``reads_hidden`` False (it reads written fragments only): the calls it reads still drop the
    fragments that fail the depth test against the depth stored when their chunk is shaded (the
    early depth test), unreported; it is told of every written fragment, at the same pixels and in
    the same order, as an observer of every fragment is. The frame is the plain render's."""
    from blendlib.core import fragment

    monkeypatch.setattr(fragment, "EARLY_DROP_SHARE", 1 << 30)  # drop whatever fails, however few
    scene = seeded_scene(27)

    class Written(Recorder):
        def reads_hidden(self, call):
            return False

    every, written = Recorder(), Written()
    plain = render_scene(scene, workers=2)
    render_scene(scene, observer=every, workers=1)
    frame = render_scene(scene, observer=written, workers=1)
    assert _frame_equal(frame, plain)
    dropped = 0
    for index in every.outcomes:
        e, w = every.counts(index), written.counts(index)
        assert w[Outcome.WRITTEN] == e[Outcome.WRITTEN] and w[Outcome.STENCIL] == e[Outcome.STENCIL]
        assert w[Outcome.DEPTH] <= e[Outcome.DEPTH] and w[Outcome.ALPHA_TEST] <= e[Outcome.ALPHA_TEST]
        dropped += e[Outcome.DEPTH] - w[Outcome.DEPTH]

        assert np.array_equal(_written_pixels(written, index), _written_pixels(every, index)), index
    assert dropped > 0


def test_a_render_without_output_leaves_the_buffers_to_the_observer():
    """``output=False``: the Frame's arrays are not made; the buffers the observer is handed after
    the last draw call hold the frame a plain render outputs."""
    scene = seeded_scene(5)

    class Last(FrameObserver):
        per_sample = True
        buffers = None

        def draw_end(self, call, buffers, triangles):
            self.buffers = buffers

    last = Last()
    frame = render_scene(scene, observer=last, output=False)
    assert frame.color is None and frame.depth is None and frame.stencil is None
    plain = render_scene(scene)
    color, depth, stencil = last.buffers.output()
    assert np.array_equal(color, plain.color) and np.array_equal(depth, plain.depth)
    assert np.array_equal(stencil, plain.stencil)
