"""docs/sorting.md advice: a checked change per inverted pair; the prepass for self-overlap, with its price.

Advice is computed on top of an analysis (blendlib.explain.advice.analyze_and_advise), never by it."""

from __future__ import annotations

import os
from dataclasses import replace

import numpy as np
import pytest

from blendlib.core.drawlist import draw_calls
from blendlib.core.vocabulary import Cull, Pass, Queue
from blendlib.explain import advice
from blendlib.explain.advice import analyze_and_advise, with_prepass, with_queue_offset
from blendlib.explain.sorted_reference import analyze, sort_error
from blendlib.runtime.forked import ForkedMap
from tests.explain.test_sorted_reference import BLEND, _two_quads, layered_scene, transparent
from tests.reference import scenes as sc
from tests.reference.random_scenes import seeded_scene


def _named(scene):
    return replace(scene, renderers=tuple(replace(r, material=replace(r.material, name="M" + r.name))
                                          for r in scene.renderers))


def test_queue_offset_advice_is_checked_by_rendering():
    scene = _named(_two_quads(False))
    assert analyze(scene).advice == []  # the analysis alone advises nothing
    result = analyze_and_advise(scene)
    assert len(result.advice) == 1
    item = result.advice[0]
    assert (item["front"], item["front_slot"], item["behind"], item["behind_slot"]) == ("Red", 0, "Blue", 0)
    assert item["change"] == {"material": "MRed", "queue_offset": 1}
    assert item["inversions_before"] == 48 and item["inversions_after"] == 0
    assert item["differing_before"] == 48 and item["differing_after"] == 0
    assert "Transparent+1" in item["text"] and "48 → 0" in item["text"]
    fixed = with_queue_offset(scene, "MRed", 1)
    assert [c.renderer.name for c in draw_calls(fixed)] == ["Blue", "Red"]
    again = analyze(fixed)
    assert again.inversions == [] and again.differing == 0


def test_a_shared_material_gets_a_sort_setting():
    result = analyze_and_advise(_two_quads(False))  # both quads use the material called "Material"
    item = result.advice[0]
    assert item["change"]["sort_mode"] == "CustomAxis" and item["inversions_after"] == 0
    assert item["differing_after"] == 0


def test_self_overlap_advice_is_the_prepass_with_its_price():
    cam = sc.camera(24, 24, eye=(0, 0, 4))
    ball = sc.renderer(sc.uv_sphere(1.0, 12, 8), sc.unlit((0.9, 0.6, 0.1, 0.4), queue=Queue.Transparent,
                                                           passes=[replace(BLEND, cull=Cull.Off)]), name="Ball")
    result = analyze_and_advise(sc.scene(cam, ball))
    [item] = result.advice
    assert item["front"] == item["behind"] == "Ball" and item["change"] is None
    assert item["technique"] == "depth prepass" and item["preset"] == "Alpha Blend ZWrite"
    assert item["inversions_before"] == result.inversions[0].pixels > 0 and item["inversions_after"] == 0
    assert item["differing_after"] > 0  # only the front layer shows
    assert "Sort Elements" in item["text"] and "front layer" in item["text"]
    assert np.all(result.inverted[result.inverted > 0] == 1)


def _full_measure(original, pairs):
    """What advice measured before it re-rendered only what a change can change: a whole new
    analysis of the changed scene, compared with the original sorted reference."""

    def measure(changed):
        after = analyze(changed)
        error = sort_error(after.frame.color, original.reference, original.hdr)
        return {pair: after.pair_pixels(*pair) for pair in pairs}, int(np.count_nonzero(error > original.step))

    return measure


def _candidates(scene, inv):
    if inv.self_overlap:
        return [with_prepass(scene, inv.front)]
    a = next(r for r in scene.renderers if (r.name, r.slot) == inv.front)
    b = next(r for r in scene.renderers if (r.name, r.slot) == inv.behind)
    return [changed for _, changed, _ in advice._pair_candidates(scene, a, b)]


def _two_pass_quad_scene():
    """Quad A in two passes, the second pushed farther by its Offset (its nearest fragment comes
    first), then quad B on the same plane at a depth between the two; and two quads C, D beside
    them in the wrong order, whose fixes leave A drawn before B: the pair (A, B) stays inverted."""
    cam = sc.screen_camera(128, 8)  # long rows: chunks the rasteriser knows are one layer
    a = sc.renderer(sc.quad(0, 0, 64, 8), sc.unlit((0.9, 0.1, 0.1, 0.5), queue=Queue.Transparent, name="MA",
                                                    passes=[BLEND, replace(BLEND, offset_units=1000.0)]), name="A")
    b = sc.renderer(sc.quad(0, 0, 64, 8), sc.unlit((0.1, 0.9, 0.1, 0.5), queue=Queue.Transparent, queue_offset=1,
                                                    name="MB", passes=[replace(BLEND, offset_units=500.0)]), name="B")
    c = sc.renderer(sc.quad(64, 0, 128, 8, z=1.0), sc.unlit((0.1, 0.1, 0.9, 0.5), queue=Queue.Transparent,
                                                            name="MC", passes=[BLEND]), name="C")
    d = sc.renderer(sc.quad(64, 0, 128, 8, z=-1.0), sc.unlit((0.9, 0.9, 0.1, 0.5), queue=Queue.Transparent,
                                                             queue_offset=1, name="MD", passes=[BLEND]), name="D")
    return sc.scene(cam, a, b, c, d)


def _opaque_reordered_scene():
    """Two transparent quads sharing a material in the wrong order (their fix: a sort setting),
    over four overlapping opaque quads whose sort points order them the same way under the
    CustomAxis and Perspective settings, and otherwise under the scene's own (orthographic); two of
    them at one depth, so their order decides the colour where they overlap."""
    scene = _two_quads(False)
    opaque = []
    for k, (centre, z) in enumerate([((48, 6, -2), -2.0), ((28, 6, -3), -2.0), ((68, 6, -1), -2.5),
                                     ((8, 6, -4), -3.0)]):
        r = sc.renderer(sc.quad(2 * k, 0, 2 * k + 8, 12, z=z), sc.unlit((0.2 * k, 0.5, 0.3, 1.0), name=f"O{k}"),
                        name=f"O{k}")
        opaque.append(replace(r, bounds_center=np.array(centre, dtype=np.float64)))
    return replace(scene, renderers=scene.renderers + tuple(opaque))


def _advice_scenes():
    yield "two-pass quad", _two_pass_quad_scene()
    yield "opaque reordered alike", _opaque_reordered_scene()
    for seed in range(10):
        yield f"layered {seed}", layered_scene(seed)
    for seed in (3, 11, 23, 31, 47):
        yield f"seeded {seed}", _named(transparent(seeded_scene(seed), every=1))
        yield f"seeded shared {seed}", transparent(seeded_scene(seed + 100), every=2)


@pytest.mark.parametrize("keep_step1", [True, False])
def test_measurements_equal_a_full_analysis_of_each_changed_scene(keep_step1):
    """Every candidate of every advised pair, on random scenes (stencil, ZWrite and ZTest
    variations, Cull Off, several passes, opaque and overlay queues): the inverted pixels of
    every advised pair and the differing pixels equal those of a full analysis of the changed
    scene, also where candidates that reorder the opaque queue alike resume from one drawing of it,
    and where a measurement takes chunks an earlier one shaded (:mod:`blendlib.core.shaded_cache`)."""
    checked = shared = taken = 0
    for name, scene in _advice_scenes():
        original = analyze(scene, keep_step1=keep_step1)
        pairs = [(inv.front, inv.behind) for inv in original.inversions[:5]]
        measurer = advice._Measurer(scene, original, pairs, None, None)
        full = _full_measure(original, pairs)
        candidates = [(inv, changed) for inv in original.inversions[:5] for changed in _candidates(scene, inv)]
        # Candidates that reorder the opaque queue alike resume from one drawing of it.
        measurer.expect([changed for _, changed in candidates])
        for inv, changed in candidates:
            assert measurer.measure(changed) == full(changed), (name, inv)
            checked += 1
        shared += len(measurer.prefix_step1)
        taken += measurer.shaded.hits
    assert checked > 40 and shared >= 1 and taken > 20


def _strips_scene(seed: int):
    """Pairs of transparent quads in horizontal strips of the frame, each pair drawn in the wrong
    order (the nearer first), some sharing a material, one writing depth in the Transparent queue,
    over an opaque depth-writing quad across two strips and a Cull Front quad seen from behind:
    fixes of one pair move renderers of a few strips only."""
    rng = np.random.default_rng(seed)
    cam = sc.screen_camera(40, 96)
    zwrite = replace(BLEND, zwrite=True)
    renderers = [sc.renderer(sc.quad(0, 14, 40, 46, z=-0.5), sc.unlit((0.2, 0.3, 0.4, 1), name="Floor"), name="Floor")]
    shared = sc.unlit((0.8, 0.8, 0.2, 0.5), queue=Queue.Transparent, queue_offset=1, name="Shared", passes=[BLEND])
    for k in range(4):
        y0 = 4 + 22 * k
        x = int(rng.integers(0, 12))
        near = sc.unlit(tuple(rng.uniform(0.1, 0.9, 3)) + (0.5,), queue=Queue.Transparent, name=f"Near{k}",
                        passes=[zwrite if k == 2 else BLEND])
        far = shared if k % 2 else sc.unlit(tuple(rng.uniform(0.1, 0.9, 3)) + (0.6,), queue=Queue.Transparent,
                                            queue_offset=1, name=f"Far{k}", passes=[BLEND])
        renderers.append(sc.renderer(sc.quad(x, y0, x + 24, y0 + 12, z=1.0), near, name=f"Near{k}"))
        renderers.append(sc.renderer(sc.quad(x + 6, y0 + 4, x + 30, y0 + 16, z=-1.0), far, name=f"Far{k}"))
    back = sc.unlit((0.9, 0.2, 0.2, 0.5), queue=Queue.Transparent, queue_offset=-1, name="Back",
                    passes=[replace(BLEND, cull=Cull.Front)])
    renderers.append(sc.renderer(sc.quad(30, 80, 10, 92, z=0.5), back, name="Back"))  # clockwise: its back
    return sc.scene(cam, *renderers)


@pytest.mark.parametrize("seed", [0, 1])
def test_measurements_in_bands_equal_a_full_analysis(monkeypatch, seed):
    """Fixes that move renderers of a few strips are measured in a band of the frame's rows; the
    figures equal those of a full analysis of each changed scene."""
    scene = _strips_scene(seed)
    original = analyze(scene, keep_step1=True)
    pairs = [(inv.front, inv.behind) for inv in original.inversions[:5]]
    assert len(pairs) >= 3
    measurer = advice._Measurer(scene, original, pairs[:1], None, None)
    bands = []
    band = advice._Measurer.band
    monkeypatch.setattr(advice._Measurer, "band", lambda self, *a: bands.append(band(self, *a)) or bands[-1])
    full = _full_measure(original, pairs[:1])
    checked = 0
    for inv in original.inversions[:5]:
        for changed in _candidates(scene, inv):
            assert measurer.measure(changed) == full(changed), inv
            checked += 1
    drawn = [b for b in bands if b is not None and b[0] < b[1]]
    assert checked >= 6 and len(drawn) >= 3
    assert sum(b[1] - b[0] <= 24 for b in drawn) >= 2  # a strip or two of the 96 rows


@pytest.mark.parametrize("seed", [0, 2, 5])
def test_advice_equals_advice_measured_by_full_analyses(monkeypatch, seed):
    scene = layered_scene(seed)
    fast = analyze_and_advise(scene)
    assert fast.advice

    def full(self, changed):
        return _full_measure(self.analysis, self.pairs)(changed)

    monkeypatch.setattr(advice._Measurer, "measure", full)
    slow = analyze_and_advise(scene)
    assert fast.advice == slow.advice


@pytest.mark.parametrize("pairs_checked", [True, False])
def test_a_reordering_of_renderers_that_never_meet_is_not_drawn_again(monkeypatch, pairs_checked):
    """A sort setting that fixes the pair (A, B) also swaps L and R, which share rows but never a
    pixel (their boxes do not meet): the band drawn is the pair's rows alone, and every candidate
    measures as a full analysis of its scene. With more pairs of renderers than it checks one by
    one, every renderer drawn at another place counts whole: L's and R's rows too."""
    if not pairs_checked:
        monkeypatch.setattr(advice._Measurer, "BAND_PAIRS", 0)
    cam = sc.screen_camera(40, 40)
    shared = sc.unlit((0.5, 0.5, 0.9, 0.5), queue=Queue.Transparent, passes=[BLEND], name="Shared")

    def quad(box, z, centre, name):
        x0, y0, x1, y1 = box
        return replace(sc.renderer(sc.quad(x0, y0, x1, y1, z=z), shared, name=name),
                       bounds_center=np.array(centre, dtype=np.float64))

    a = quad((0, 0, 20, 10), 1.0, (0, 0, -9), "A")  # in front, but its sort point is far: drawn first
    b = quad((5, 0, 25, 10), -1.0, (0, 0, 9), "B")
    left = quad((0, 20, 10, 30), 0.0, (0, 0, 0), "L")
    right = quad((25, 20, 35, 30), 0.5, (0, 0, 5), "R")
    scene = sc.scene(cam, a, b, left, right)
    original = analyze(scene, keep_step1=True)
    assert [(inv.front, inv.behind) for inv in original.inversions] == [(("A", 0), ("B", 0))]
    pairs = [(("A", 0), ("B", 0))]
    measurer = advice._Measurer(scene, original, pairs, None, None)
    full = _full_measure(original, pairs)
    names = lambda s: [c.renderer.name for c in draw_calls(s)]  # noqa: E731
    swapped = 0
    for changed in _candidates(scene, original.inversions[0]):
        assert measurer.measure(changed) == full(changed)
        order = names(changed)
        if order.index("L") > order.index("R"):  # drawn L then R before: swapped
            swapped += 1
            calls = draw_calls(changed)
            expected = (0, 10) if pairs_checked else (0, 30)
            assert measurer.band(advice._signature(changed, calls), calls, 40) == expected
    assert names(scene).index("L") < names(scene).index("R") and swapped >= 1


def test_a_change_that_leaves_nothing_after_the_opaque_queue_measures_as_a_full_analysis():
    """A change that makes both renderers of the pair opaque (a VRM Cutout, say), expected twice:
    its opaque queue is drawn once and resumed from, with no draw call after it, so the frame
    is those buffers; the measurement equals a full analysis of the changed scene."""
    scene = _named(_two_quads(False))
    original = analyze(scene, keep_step1=True)
    pairs = [(inv.front, inv.behind) for inv in original.inversions]
    assert pairs == [(("Red", 0), ("Blue", 0))]
    opaque = replace(scene, renderers=tuple(replace(r, material=replace(r.material, queue=Queue.Geometry,
                                                                          passes=(Pass(),)))
                                            for r in scene.renderers))
    measurer = advice._Measurer(scene, original, pairs, None, None)
    measurer.expect([opaque, opaque])
    assert measurer.measure(opaque) == _full_measure(original, pairs)(opaque)
    assert measurer.prefix_step1  # drawn once, resumed from


class _SpyMap(ForkedMap):
    """A ForkedMap that notes which process measured each draw list and how many shared the machine."""

    def __call__(self, fn, items, should_cancel=None, on_done=None, at_once=False):
        self.at_once = at_once
        marked = super().__call__(lambda item, processes: (fn(item, processes), os.getpid(), processes),
                                  items, should_cancel, on_done, at_once)
        self.pids = [pid for _, pid, _ in marked]
        self.shares = [processes for _, _, processes in marked]
        return [result for result, _, _ in marked]


@pytest.mark.parametrize("seed", [0, 2])
def test_advice_measured_in_two_processes_equals_advice_measured_here(monkeypatch, seed):
    """The distinct draw lists measured in this process and a forked one give the same advice;
    those measured while both run draw with one thread."""
    scene = layered_scene(seed)
    here = analyze_and_advise(scene)
    threads = []  # the measuring renders of this process, their threads
    render = advice.render_scene

    def noted(*args, observer=None, workers=None, **kwargs):
        if isinstance(observer, advice._PairWatch):
            threads.append(workers)
        return render(*args, observer=observer, workers=workers, **kwargs)

    monkeypatch.setattr(advice, "render_scene", noted)
    spy = _SpyMap(2, min_work_s=0.0)
    shared = analyze_and_advise(scene, measure_map=spy)
    assert shared.advice == here.advice
    assert len(spy.pids) >= 3 and os.getpid() in spy.pids and len(set(spy.pids)) == 2
    assert spy.shares[0] == 1 and set(spy.shares[1:]) == {2}
    assert threads[0] is None  # the first one here, alone: the measurer's threads
    assert threads[1:] and set(threads[1:]) == {1}  # this process's others, while the child runs
    assert len(threads) < len(spy.pids)  # the child measured the rest


def test_measurements_band_fragments_are_the_analysed_frames_in_those_rows():
    """A measurement's work is estimated by the fragments the analysed frame rasterised in its
    band's rows (buffer rows from the bottom): in the strips scene rows 86–92 hold only the Back
    quad (20 × 6 pixels), rows 4–10 the first strip's near quad and two rows of its far one."""
    scene = _strips_scene(0)
    original = analyze(scene, keep_step1=True)
    measurer = advice._Measurer(scene, original, [], None, None)
    assert measurer.fragments_within(None) == 40 * 32 + 8 * 24 * 12 + 20 * 12
    assert measurer.fragments_within((86, 92)) == 20 * 6
    assert measurer.fragments_within((4, 10)) == 24 * 6 + 24 * 2
    assert measurer.fragments_within((0, 4)) == measurer.fragments_within((50, 50)) == 0


@pytest.mark.parametrize("threshold", [0, 10**9])
def test_measurements_go_longest_first_and_long_ones_at_once(monkeypatch, threshold):
    """The distinct draw lists go to the map longest first (by their bands' fragments); when the
    second longest has AT_ONCE_FRAGMENTS or more they are shared from the first, each drawn with
    one thread in two processes; the advice is the same."""
    scene = _strips_scene(0)
    here = analyze_and_advise(scene, max_advice=1)
    monkeypatch.setattr(advice, "AT_ONCE_FRAGMENTS", threshold)
    items = []

    class Spy(_SpyMap):
        def __call__(self, fn, todo, *args, **kwargs):
            items.extend(todo)
            return super().__call__(fn, todo, *args, **kwargs)

    spy = Spy(2, min_work_s=0.0)
    assert analyze_and_advise(scene, max_advice=1, measure_map=spy).advice == here.advice
    original = analyze(scene, keep_step1=True)
    measurer = advice._Measurer(scene, original, [(i.front, i.behind) for i in original.inversions[:1]], None, None)
    work = [measurer.fragments_within(measurer._band_of(changed)) for changed in items]
    assert len(items) >= 2 and len(set(work)) >= 2
    assert work == sorted(work, reverse=True)
    assert spy.at_once is (threshold == 0)
    assert (set(spy.shares) == {2}) if threshold == 0 else (spy.shares[0] == 1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_pair_watch_counts_as_fragments_applied_one_by_one(seed):
    """Chunks of three renderers' fragments, most sharing pixels within a chunk and between
    chunks, some not written: the watch's inverted pixels per pair (a self-overlap among them)
    equal those found fragment by fragment in draw order, and a band's offset is honoured."""
    from types import SimpleNamespace

    from blendlib.core.merger import Outcome

    rng = np.random.default_rng(seed)
    keys = [("A", 0), ("B", 0), ("C", 1)]
    pairs = [(("A", 0), ("B", 0)), (("B", 0), ("B", 0)), (("C", 1), ("A", 0)), (("A", 0), ("C", 1))]
    calls = [SimpleNamespace(index=k + 1, queue=3000, state=SimpleNamespace(color_mask="RGBA"),
                             renderer=SimpleNamespace(name=name, slot=slot)) for k, (name, slot) in enumerate(keys)]
    pixels, first = 120, 100
    watch = advice._PairWatch(pairs, calls, pixels, first=first)
    nearest = {key: [1 << 30] * pixels for key in keys}
    expected = {pair: set() for pair in pairs}
    for _ in range(30):
        call = calls[int(rng.integers(0, 3))]
        key = (call.renderer.name, call.renderer.slot)
        n = int(rng.integers(1, 200))
        pix = rng.integers(0, pixels, n).astype(np.int64) + first
        disjoint = bool(rng.integers(0, 4) == 0)
        if disjoint:
            pix = rng.permutation(pixels)[:min(n, pixels)].astype(np.int64) + first
        depth = rng.integers(0, 50, pix.size).astype(np.int64)
        outcome = np.where(rng.random(pix.size) < 0.8, Outcome.WRITTEN, Outcome.DEPTH).astype(np.int8)
        watch.fragments(call, SimpleNamespace(coverage=None, pix=pix, depth=depth, disjoint=disjoint), outcome)
        for p, d, o in zip((pix - first).tolist(), depth.tolist(), outcome.tolist(), strict=True):
            if o != Outcome.WRITTEN:
                continue
            for front, behind in pairs:
                if behind == key and nearest[front][p] < d:
                    expected[(front, behind)].add(p)
            nearest[key][p] = min(nearest[key][p], d)
    counts = watch.counts()
    assert counts == {pair: len(found) for pair, found in expected.items()}
    assert all(counts.values())


def test_differing_pixels_from_codes_equal_those_from_colours():
    """A changed 8-bit frame's differing pixels counted from its stored codes equal those
    counted from its colours (code / 255 in float32, as FrameBuffers.output makes them), at
    random codes near the reference's (errors of 0 to 3 steps) and far from them."""
    scene = _strips_scene(1)
    original = analyze(scene, keep_step1=True)
    measurer = advice._Measurer(scene, original, [], None, None)
    rng = np.random.default_rng(3)
    at = rng.choice(original.error.size, 2000, replace=False)
    near = np.rint(original.reference.reshape(-1, 4)[at] * 255) + rng.integers(-3, 4, (at.size, 4))
    codes = np.clip(near, 0, 255).astype(np.uint8)
    codes[::7] = rng.integers(0, 256, (codes[::7].shape[0], 4))
    colors = np.divide(codes, np.float32(255.0), dtype=np.float32)
    counted = measurer._differing_at(codes, at)
    assert counted == measurer._differing_at(colors, at)
    assert counted != measurer.differing_before  # the codes do change which pixels differ
