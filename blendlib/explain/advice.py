"""Advice for inverted renderer pairs (docs/sorting.md), each checked by rendering the scene with the change.

For a pair of different renderers (A drawn before B although A lies in front of B) the
candidates are: a render-queue offset that draws A after B (on A's material) or B before A
(on B's material), and a sort setting of the scene (``CustomAxis`` along the line from A's
sort point to B's, or the other built-in mode). Each candidate is measured; the one that
leaves the fewest inverted pixels of the pair (then the fewest differing pixels, measured
against the original sorted reference: the image the artist means) is advised.

A material whose state comes from settings of its own (``settings``: the VRM Add-on's MToon,
:class:`MaterialSettings`) is advised in their terms instead of a queue offset — its queue setting
within its clamp, a render mode that writes depth or tests alpha — and no scene sort setting is
proposed for its pairs (the application that draws the avatar sorts as Unity's default); each
change is measured the same way.

For a renderer that overlaps itself no queue or sort setting helps. The measured technique is
the depth prepass (preset "Alpha Blend ZWrite"): it removes the inversions, but it shows only
the front layer, so the frame still differs from the sorted reference — the technique's price,
reported as ``differing_after``. Splitting the mesh or sorting its triangles (Blender's Mesh ›
Sort Elements) are named too; they depend on the view and are not measured. A material with
settings of its own is advised its render modes instead (VRM: Transparent With Z-Write, Cutout).

**What a measurement re-renders** (:class:`_Measurer`): a candidate changes only the order of
the draw calls (queues, sort settings) or one renderer's passes (the prepass), so its frame is
the original's step-1 buffers (everything up to queue 2500, kept by the analysis) with the
draw calls from there on; only those are rendered, once per distinct draw list (a sort mode
shared by several pairs is rendered once; a draw list equal to the original's is not rendered
at all). A candidate that reorders the opaque queue resumes from them too when the analysis
proved that queue's order free (:attr:`.sorted_reference.Analysis.opaque_order_free`); else the
reordered queue is drawn (once for the candidates that share it). Only the band of rows where a
pixel can change is drawn (:meth:`_Measurer.band`): the boxes that the renderers it alters after
the opaque queue reached in the analysis, where the boxes of two renderers it orders otherwise
meet, and where those of each advised pair meet; elsewhere every pixel sees the same fragments
in the same order. The pairs' inversions are counted as that render goes
(:class:`_PairWatch`), and the differing pixels against the original reference, computed again
only where the colour changed. The numbers equal those of a full analysis of the changed scene
(tests/explain/test_advice.py checks it on random scenes and on scenes in strips). The distinct
draw lists may be measured two at a time, in this process and a forked copy of it
(``measure_map``, :class:`MeasureMap`: the explaining tools own no processes, their callers
pass :class:`blendlib.runtime.forked.ForkedMap`); the figures are the same.

One concern in one module, over 700 lines: the candidates and their measurement stay side by
side, because what a measurement may skip (the opaque queue, the rows outside its band) holds
only for the kinds of change the candidates make — a new kind of candidate must be checked
against :class:`_Measurer`'s assumptions in the same edit.

Advice sits on top of the analysis (:mod:`.sorted_reference` knows nothing of it):
:func:`analyze_and_advise` runs one and then the other, for the callers that want both
(``blendlib.analyze``, ``python -m blendlib analyze``, the add-on's Analyze button).
"""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any, Protocol

import numpy as np

from ..core import shade
from ..core.drawlist import DrawCall, draw_calls, sort_key_distance
from ..core.merger import FrameBuffers, Outcome
from ..core.pipeline import render_scene
from ..core.records import FrameObserver, RenderCancelled
from ..core.scene import DrawScene, Renderer, SceneMemo
from ..core.shaded_cache import ShadedCache
from ..core.vocabulary import LAST_OPAQUE_QUEUE, Cull, Material, SortMode, preset, queue_text
from .fragment_store import is_sorted_queue, union_box
from .progress import Progress
from .sorted_reference import ERROR_ROWS, Analysis, LastBuffers, analyze, largest_step, ldr_codes, sort_error

PREPASS_PRESET = "Alpha Blend ZWrite"
#: Share of the progress bar the analysis takes in :func:`analyze_and_advise`, per advised pair
#: the advice takes about as much as an analysis takes in all (a render or two per pair).
ADVICE_WEIGHT = 0.35

Key = tuple[str, int]

#: Measurements whose second longest draws at least this many fragments (about half a second of
#: one thread's work here) are shared between two processes from the first
#: (:class:`MeasureMap`'s ``at_once``): the first one alone would gain about a third of its time
#: from a second thread while the others wait (docs/benchmark.md, round twenty-seven).
AT_ONCE_FRAGMENTS = 2_000_000


class MaterialSettings(Protocol):
    """Where a material's Unity state comes from when that is not its Unity settings (e.g. the VRM
    Add-on's MToon: :class:`blendlib.formats.gltf.vrm_advice.VrmSettings`): the advice then proposes
    changes of those settings, so that a fix is written where it lives and survives export."""

    def options(self, old: Material, *, after: int | None = None, before: int | None = None
                ) -> list[tuple[dict[str, Any], Material, str]]:
        """Changes to try, each (the change as JSON, the Material then drawn, a sentence): ones that
        draw ``old`` after queue ``after`` / before queue ``before``, and ones that stop it sorting
        (e.g. writing depth); none asked (both None): those only (a self-overlap)."""
        ...


def _renderer(scene: DrawScene, key: Key) -> Renderer:
    return next(r for r in scene.renderers if (r.name, r.slot) == key)


def with_queue_offset(scene: DrawScene, material: str, offset: int) -> DrawScene:
    """The scene with every renderer of material ``material`` at queue offset ``offset``."""
    return replace(scene, renderers=tuple(
        replace(r, material=replace(r.material, queue_offset=int(offset))) if r.material.name == material else r
        for r in scene.renderers))


def with_prepass(scene: DrawScene, key: Key) -> DrawScene:
    """The scene with renderer ``key``'s material given the depth-prepass preset's queue and passes."""
    queue, passes = preset(PREPASS_PRESET)
    return replace(scene, renderers=tuple(
        replace(r, material=replace(r.material, queue=queue, passes=passes)) if (r.name, r.slot) == key else r
        for r in scene.renderers))


def _label(key: Key) -> str:
    return f"'{key[0]}'" if key[1] == 0 else f"'{key[0]}' (slot {key[1]})"


def with_material(scene: DrawScene, material: Material) -> DrawScene:
    """The scene with every renderer of the material named ``material.name`` drawing ``material``."""
    return replace(scene, renderers=tuple(
        replace(r, material=material) if r.material.name == material.name else r for r in scene.renderers))


def _settings_candidates(scene: DrawScene, renderer: Renderer, source: MaterialSettings, purpose: str,
                         **wanted: int | None) -> list[tuple[dict, DrawScene, str]]:
    """A material's own settings (``source.options``) as candidates: change, changed scene, sentence
    (ending with ``purpose``, e.g. "so that 'A' draws after 'B'")."""
    return [(change, with_material(scene, material), f"{sentence} {purpose}".rstrip())
            for change, material, sentence in source.options(renderer.material, **wanted)]


def _pair_candidates(scene: DrawScene, a: Renderer, b: Renderer,
                     settings: Mapping[str, MaterialSettings] | None = None) -> list[tuple[dict, DrawScene, str]]:
    """(change, changed scene, sentence) for a pair: A is in front but drawn before B. A material
    in ``settings`` is changed through its own settings (e.g. VRM's), the others by a queue offset;
    a scene's sort setting is proposed only when neither material has settings of its own (a VRM
    application sorts as Unity's default: the avatar cannot carry a sort mode)."""
    out = []
    settings = settings or {}
    qa, qb = a.material.render_queue, b.material.render_queue
    own = a.material.name in settings or b.material.name in settings
    if a.material.name != b.material.name:
        after = f"so that {_label((a.name, a.slot))} draws after {_label((b.name, b.slot))}"
        before = f"so that {_label((b.name, b.slot))} draws before {_label((a.name, a.slot))}"
        target = qb + 1  # A after B
        if a.material.name in settings:
            out += _settings_candidates(scene, a, settings[a.material.name], after, after=qb)
        elif target <= 3999:
            offset = target - a.material.queue.number
            out.append(({"material": a.material.name, "queue_offset": offset},
                        with_queue_offset(scene, a.material.name, offset),
                        f"set material '{a.material.name}' to queue {queue_text(a.material.queue, offset)} "
                        f"({target}) {after}"))
        target = qa - 1  # B before A
        if b.material.name in settings:
            out += _settings_candidates(scene, b, settings[b.material.name], before, before=qa)
        elif target >= 2501:
            offset = target - b.material.queue.number
            out.append(({"material": b.material.name, "queue_offset": offset},
                        with_queue_offset(scene, b.material.name, offset),
                        f"set material '{b.material.name}' to queue {queue_text(b.material.queue, offset)} "
                        f"({target}) {before}"))
    if qa == qb and not own:
        axis = np.asarray(b.bounds_center, np.float64) - np.asarray(a.bounds_center, np.float64)
        length = float(np.linalg.norm(axis))
        if length > 0 and np.isfinite(length):
            axis = [round(float(v) / length, 4) for v in axis]
            if any(axis):
                changed = replace(scene, sort_mode=SortMode.CustomAxis, sort_axis=tuple(axis))
                if sort_key_distance(changed, b) > sort_key_distance(changed, a):
                    out.append(({"sort_mode": "CustomAxis", "sort_axis": axis}, changed,
                                f"sort transparent objects along the axis {tuple(axis)} (Sort Mode Custom Axis)"))
        for mode in (SortMode.Perspective, SortMode.Orthographic):
            if mode is not scene.sort_mode:
                out.append(({"sort_mode": mode.value}, replace(scene, sort_mode=mode),
                            f"set the scene's Sort Mode to {mode.value}"))
    return out


class _PairWatch(FrameObserver):
    """Counts, as a render goes, the pixels where each watched pair (A, B) is inverted: a written
    fragment of A applied before a farther written fragment of B (draw calls of queues 2501–3999
    that write colour, as the analysis counts them).

    Per front renderer A: ``nearest[A]`` (P,) int32, the smallest depth code of A's written
    fragments applied so far at each watched pixel (``pixels`` P from window pixel ``first``: a
    band's rows, or the frame; ``NONE`` before any); per pair a (P,) bool image of its inverted
    pixels. A fragment of B inverts the pair where ``nearest[A]`` is below its depth
    (fragments of one chunk of A itself: those before it in the chunk count too). Screen bands
    own disjoint pixels, so threads never touch the same entries.

    With MSAA (``samples`` N > 1) the images are per sample index ``p*N + s`` and a written sample
    is a fragment of its own, as the analysis counts inversions (docs/sorting.md)."""

    exact_boundaries = False  # only fragments are read
    per_sample = True
    NONE = np.int32(1 << 30)

    def __init__(self, pairs: list[tuple[Key, Key]], calls: list[DrawCall], pixels: int, samples: int = 1,
                 first: int = 0) -> None:
        self.pairs = pairs
        self.samples = int(samples)
        self.first = int(first)  # the first window pixel watched: a band's images hold its rows alone
        self.buffers: FrameBuffers | None = None
        pixels *= self.samples
        fronts = sorted({front for front, _ in pairs})
        self.nearest = {front: np.full(pixels, self.NONE, dtype=np.int32) for front in fronts}
        self.inverted = {pair: np.zeros(pixels, dtype=bool) for pair in pairs}
        watched = {key for pair in pairs for key in pair}
        self.watched = {c.index: (c.renderer.name, c.renderer.slot) for c in calls
                        if is_sorted_queue(c.queue) and c.state.color_mask
                        and (c.renderer.name, c.renderer.slot) in watched}
        self.lock = threading.Lock()

    def reads_depth(self, call: DrawCall) -> bool:
        return call.index in self.watched

    def reads_call(self, call: DrawCall) -> bool:
        return call.index in self.watched

    def reads_hidden(self, call: DrawCall) -> bool:
        return False  # written fragments only

    def colors_read(self, call: DrawCall) -> bool:
        return False  # their depths and outcomes only

    def fragments(self, call, frags, outcome) -> None:
        key = self.watched.get(call.index)
        if key is None:
            return
        written = outcome == Outcome.WRITTEN
        if not written.any():
            return
        if frags.coverage is not None:  # MSAA: each written sample at its sample index
            which, sample = np.nonzero(written)
            pix = (np.take(frags.pix, which) - self.first) * self.samples + sample
            depth = frags.depth[which, sample].astype(np.int32)
        elif written.all():
            pix = frags.pix - self.first if self.first else frags.pix
            depth = frags.depth.astype(np.int32)
        else:  # np.take: boolean and fancy indexing cost more
            kept = np.flatnonzero(written)
            pix = frags.pix.take(kept)
            if self.first:
                pix -= self.first
            depth = frags.depth.take(kept).astype(np.int32)
        if frags.disjoint:
            running = None  # one fragment per pixel in this chunk
        else:  # in pixel order, each fragment's nearest of the chunk at its pixel up to it, itself included
            order = np.argsort(pix, kind="stable")
            pix, depth = pix.take(order), depth.take(order)
            # Pixel p's fragments less p·2³¹: every earlier pixel's values lie above, so one running
            # minimum over the chunk restarts at each pixel (depth codes are below 2³⁰).
            shift = np.left_shift(pix, 31)
            running = np.subtract(depth, shift)
            np.minimum.accumulate(running, out=running)
            running += shift
        near = self.nearest.get(key)
        own = None
        if near is not None:  # the key's nearest at each fragment's pixel before this chunk...
            own = near.take(pix)
            if running is not None:  # ...and in it, up to the fragment itself: below its depth
                np.minimum(own, running, out=own)  # exactly when an earlier one's is
        for (front, behind), hit in self.inverted.items():
            if behind == key:
                nearest = own if front == key else self.nearest[front].take(pix)
                hit[pix.compress(nearest < depth)] = True
        if near is not None:
            if running is None:
                near[pix] = np.minimum(own, depth)
            else:  # each pixel's last fragment holds the nearest there
                last = np.append(np.flatnonzero(pix[1:] != pix[:-1]), pix.size - 1)
                near[pix.take(last)] = own.take(last)

    def draw_end(self, call, buffers, triangles) -> None:
        self.buffers = buffers  # after the last call: the changed frame's buffers

    def counts(self) -> dict[tuple[Key, Key], int]:
        return {pair: int(np.count_nonzero(hit)) for pair, hit in self.inverted.items()}


def _signature(scene: DrawScene, calls: list[DrawCall]) -> tuple:
    """What a draw list draws, call by call: the renderer (its place in the scene), pass, its
    state, light, and its material's cutoff and colour. Candidates change only queues, sort
    settings and one material's passes, cutoff and colour (a render mode of its own settings), so
    equal signatures mean equal frames."""
    place = {id(r): k for k, r in enumerate(scene.renderers)}
    lights = {id(light): k for k, light in enumerate(scene.lights)}
    return tuple((place[id(c.renderer)], c.pass_index, c.state, None if c.light is None else lights[id(c.light)],
                  c.renderer.material.cutoff, c.renderer.material.color) for c in calls)


def _coverage_key(call: DrawCall) -> tuple:
    """What of a draw call decides which pixels its fragments reach: its pass's cull and outline
    program, and its material's outline-width texture (by identity: candidates keep it or not)."""
    state, material = call.state, call.renderer.material
    return (state.cull, state.outline_mode, state.outline_width, state.outline_formula, state.outline_max_distance,
            id(material.outline_width_tex), material.outline_width_tex_filter, material.outline_width_tex_wrap)


def _covered_within(key: tuple, before: set) -> bool:
    """Whether a pass with coverage ``key`` reaches only pixels that passes of coverage ``before``
    reached: the same, or the same outline with Cull Off before (it reaches every side)."""
    return key in before or (Cull.Off, *key[1:]) in before


def _by_place(signature: tuple) -> dict[int, list]:
    """A signature's entries (:func:`_signature`) per renderer place, in order."""
    out: dict[int, list] = {}
    for entry in signature:
        out.setdefault(entry[0], []).append(entry[1:])
    return out


def _altered_places(old: tuple, new: tuple) -> set[int]:
    """Renderer places whose own calls differ between two draw-list signatures: in state, light,
    material values, number or order."""
    a, b = _by_place(old), _by_place(new)
    return {k for k in a.keys() | b.keys() if a.get(k) != b.get(k)}


def _positions(signature: tuple) -> dict[int, list[int]]:
    """Per renderer place, the places of its calls in a signature's order."""
    out: dict[int, list[int]] = {}
    for at, entry in enumerate(signature):
        out.setdefault(entry[0], []).append(at)
    return out


def _interleaving(xs: list[int], ys: list[int]) -> tuple[bool, ...]:
    """The order of two renderers' calls at places ``xs`` and ``ys``: True for each of the first's."""
    return tuple(first for _, first in sorted([(at, True) for at in xs] + [(at, False) for at in ys]))


def _overlap(a: tuple[int, int, int, int] | None, b: tuple[int, int, int, int] | None) -> tuple[int, int] | None:
    """The rows ``(y0, y1)`` of the intersection of two boxes ``(y0, y1, x0, x1)``, None when it is
    empty or either box is None."""
    if a is None or b is None:
        return None
    y0, y1 = max(a[0], b[0]), min(a[1], b[1])
    return (y0, y1) if y0 < y1 and max(a[2], b[2]) < min(a[3], b[3]) else None


class MeasureMap(Protocol):
    """Runs the advice's measurements, ``[fn(item, processes) for item in items]``, perhaps
    several at once in processes of their own (:class:`blendlib.runtime.forked.ForkedMap`),
    ``processes`` telling each item how many share the machine while it runs; the results must
    be the same as in order here. ``processes`` (attribute): at most how many share the items."""

    processes: int

    def __call__(self, fn: Callable[[Any, int], Any], items: list,
                 should_cancel: Callable[[], bool] | None = None,
                 on_done: Callable[[int], None] | None = None, at_once: bool = False) -> list:
        """``at_once``: the items are long (two or more of at least :data:`AT_ONCE_FRAGMENTS`),
        longest first: share them from the first rather than time one alone first."""


class _Measurer:
    """Measures changed scenes against an analysis (module doc): per distinct draw list, the
    inverted pixels of every pair advised and the pixels differing from the original reference."""

    def __init__(self, scene: DrawScene, analysis: Analysis, pairs: list[tuple[Key, Key]], workers: int | None,
                 should_cancel: Callable[[], bool] | None) -> None:
        self.scene, self.analysis, self.pairs = scene, analysis, pairs
        self.workers, self.should_cancel = workers, should_cancel
        self.calls = draw_calls(scene)
        self.signature = _signature(scene, self.calls)
        self.opaque = self._opaque_prefix(self.signature, self.calls)
        self.cache: dict[tuple, tuple[dict, int]] = {}
        self._step1 = analysis.step1
        self.differing_before = analysis.differing  # a count over the whole frame: once
        # Per renderer place (the signature's first field), the box of rows and columns its
        # calls' fragments reached and how they were covered.
        self.place_boxes: dict[int, tuple[int, int, int, int]] = {}
        self.place_coverage: dict[int, set] = {}
        for (k, *_), c in zip(self.signature, self.calls, strict=True):
            self.place_coverage.setdefault(k, set()).add(_coverage_key(c))
            box = analysis.call_boxes.get(c.index)
            if box is not None:
                self.place_boxes[k] = union_box(self.place_boxes.get(k, box), box)
        of_key = {(r.name, r.slot): k for k, r in enumerate(scene.renderers)}
        self.pair_places = [(of_key[front], of_key[behind]) for front, behind in pairs
                            if front in of_key and behind in of_key]
        #: Opaque prefixes other than the analysed one, by how many candidates draw each
        #: (:meth:`expect`), and the buffers after those drawn by more than one.
        self.prefix_counts: dict[tuple, int] = {}
        self.prefix_step1: dict[tuple, FrameBuffers] = {}
        self._opaque_counts: Counter | None = None
        self._row_fragments: np.ndarray | None = None  # fragments_within's cumulated rows
        self._draw_lists: dict[int, tuple[DrawScene, list[DrawCall], tuple, tuple, bool]] = {}
        #: Renderers checked, textures converted and vertex setups made once for every measurement:
        #: the changed scenes share the renderers a change leaves alone, and the camera.
        self.memo = SceneMemo()
        #: The chunks the measurements shade, kept for the next ones: a fix that reorders draw
        #: calls draws the same calls, and most of them in the same circumstances.
        self.shaded = ShadedCache()

    def expect(self, scenes: list[DrawScene]) -> None:
        """Note the changed scenes about to be measured: a reordered opaque queue that several of
        them share (sort settings reorder it, SPEC: one distance for both) is drawn once, and each
        of them resumes from its buffers."""
        for changed in scenes:
            _, _, prefix, kept = self._draw_list(changed)
            if not kept:
                self.prefix_counts[prefix] = self.prefix_counts.get(prefix, 0) + 1

    def _draw_list(self, changed: DrawScene) -> tuple[list[DrawCall], tuple, tuple, bool]:
        """A changed scene's draw calls, their signature, its opaque queue's signature
        (:meth:`_opaque_prefix`) and whether that queue leaves the analysed step-1 buffers
        (:meth:`_opaque_kept`), made once per scene object."""
        hit = self._draw_lists.get(id(changed))
        if hit is None or hit[0] is not changed:
            calls = draw_calls(changed)
            signature = _signature(changed, calls)
            prefix = self._opaque_prefix(signature, calls)
            hit = self._draw_lists[id(changed)] = (changed, calls, signature, prefix,  # keeps the scene alive
                                                   self._opaque_kept(prefix))
        return hit[1:]

    @staticmethod
    def _opaque_prefix(signature: tuple, calls: list[DrawCall]) -> tuple:
        return tuple(s for s, c in zip(signature, calls, strict=True) if c.queue <= LAST_OPAQUE_QUEUE)

    def _opaque_kept(self, prefix: tuple) -> bool:
        """Whether a changed scene's opaque queue (``prefix``, its signature) leaves the analysed
        step-1 buffers: the same calls in the same order, or in another where the analysis proved
        their order free (:attr:`.sorted_reference.Analysis.opaque_order_free`)."""
        if prefix == self.opaque:
            return True
        if not self.analysis.opaque_order_free:
            return False
        if self._opaque_counts is None:
            self._opaque_counts = Counter(self.opaque)
        return Counter(prefix) == self._opaque_counts

    def step1(self) -> FrameBuffers:
        """The buffers after the last draw call of queue ≤ 2500 (the analysis's, else rendered)."""
        if self._step1 is None:
            self._step1 = self._opaque_drawn(self.scene, self.calls)
        return self._step1

    def _opaque_drawn(self, scene: DrawScene, calls: list[DrawCall]) -> FrameBuffers:
        """``scene``'s buffers after its last draw call of queue ≤ 2500 (``calls``: its draw list)."""
        snapshot = LastBuffers()
        render_scene(scene, until_draw=_last_opaque(calls), observer=snapshot, workers=self.workers,
                     should_cancel=self.should_cancel, calls=calls, output=False, memo=self.memo)
        return snapshot.buffers if snapshot.buffers is not None else _cleared(scene)

    def _band_of(self, changed: DrawScene) -> tuple[int, int] | None:
        """:meth:`band` of a changed scene, its opaque queue as :meth:`measure` resumes it."""
        calls, signature, prefix, kept = self._draw_list(changed)
        return self.band(signature, calls, int(changed.camera.height), len(prefix) if kept else 0)

    def fragments_within(self, band: tuple[int, int] | None) -> int:
        """The fragments the analysed frame rasterised in a band's rows (None: the frame): about
        what a measurement there draws, and so what it costs."""
        if self._row_fragments is None:  # per image row (top first), cumulated from the bottom row
            per_row = self.analysis.overdraw[::-1, :, 0].sum(axis=1, dtype=np.int64)
            self._row_fragments = np.concatenate(([0], np.cumsum(per_row)))
        y0, y1 = (0, self._row_fragments.size - 1) if band is None else band
        return int(self._row_fragments[max(y1, y0)] - self._row_fragments[y0])

    def measure(self, changed: DrawScene, workers: int | None = None) -> tuple[dict[tuple[Key, Key], int], int]:
        """(inverted pixels per advised pair, pixels differing from the original reference);
        ``workers``: the render's threads (default the measurer's)."""
        if self.should_cancel is not None and self.should_cancel():
            raise RenderCancelled("render cancelled")
        calls, signature, prefix, kept = self._draw_list(changed)
        if signature == self.signature:
            return self.as_analysed()
        if signature in self.cache:
            return self.cache[signature]
        width, height = int(changed.camera.width), int(changed.camera.height)
        band = self._band_of(changed)
        if band is not None and band[0] >= band[1]:  # nothing it moves is drawn: the frame as analysed
            self.cache[signature] = self.as_analysed()
            return self.cache[signature]
        rows = (0, height) if band is None else band
        watch = _PairWatch(self.pairs, calls, width * (rows[1] - rows[0]), int(changed.msaa), rows[0] * width)
        resume = self._resume(changed, calls, prefix, kept)
        codes = self.analysis.final_codes is not None  # the changed pixels found by their codes
        frame = render_scene(changed, resume=resume, observer=watch, workers=workers or self.workers,
                             should_cancel=self.should_cancel, calls=calls, band=band, output=not codes,
                             memo=self.memo, shaded_cache=self.shaded,
                             call_keys={c.index: entry for c, entry in zip(calls, signature, strict=True)})
        if codes:  # with no draw call after the resumed ones, the frame is the resumed buffers
            buffers = watch.buffers if watch.buffers is not None else resume[0]
            differing = self.differing_codes(buffers.color, rows)
        else:
            differing = self.differing(frame.color, 0 if band is None else height - band[1])
        result = watch.counts(), differing
        self.cache[signature] = result
        return result

    def _resume(self, changed: DrawScene, calls: list[DrawCall], prefix: tuple,
                kept: bool) -> tuple[FrameBuffers, int] | None:
        """Where a changed scene's render resumes (``render_scene``'s ``resume``): the analysed
        step-1 buffers when its opaque queue ``prefix`` leaves them (``kept``), the buffers of
        a reordered opaque queue that several candidates share (drawn once), else None (drawn
        from the start)."""
        last = _last_opaque(calls)
        if not last:
            return None
        if kept:
            return self.step1(), last
        if self.prefix_counts.get(prefix, 0) > 1:
            if prefix not in self.prefix_step1:
                self.prefix_step1[prefix] = self._opaque_drawn(changed, calls)
            return self.prefix_step1[prefix], last
        return None

    def measure_all(self, scenes: list[DrawScene], measure_map: MeasureMap | None,
                    progress: Callable[[float], None] | None = None) -> None:
        """Measure the distinct draw lists of ``scenes`` that need a render through
        ``measure_map`` (:class:`MeasureMap`; None: one after the other as they are asked for),
        their results cached for :meth:`measure`. The opaque queues several of them share are
        drawn first, here, so no process draws one twice; a measurement that shares the
        machine with another process draws with one thread. They go to the map longest first
        (by :meth:`fragments_within` their bands), shared at once when the second longest has
        :data:`AT_ONCE_FRAGMENTS` or more. ``progress``: the fraction of them measured."""
        if measure_map is None or measure_map.processes < 2:
            return
        todo: dict[tuple, DrawScene] = {}
        for changed in scenes:
            signature = self._draw_list(changed)[1]
            if signature != self.signature and signature not in self.cache:
                todo.setdefault(signature, changed)
        if len(todo) < 2:
            return
        for changed in todo.values():  # the buffers they resume from, drawn here before they split
            calls, _, prefix, kept = self._draw_list(changed)
            self._resume(changed, calls, prefix, kept)
        work = {signature: self.fragments_within(self._band_of(changed)) for signature, changed in todo.items()}
        todo = dict(sorted(todo.items(), key=lambda item: -work[item[0]]))  # stable: ties keep their order
        at_once = sorted(work.values())[-2] >= AT_ONCE_FRAGMENTS
        results = measure_map(lambda changed, processes: self.measure(changed, 1 if processes > 1 else None),
                              list(todo.values()), self.should_cancel,
                              None if progress is None else (lambda n: progress(n / len(todo))), at_once=at_once)
        self.cache.update(zip(todo, results, strict=True))

    def as_analysed(self) -> tuple[dict[tuple[Key, Key], int], int]:
        """The measurement of a frame equal to the analysed one: the analysis's own figures."""
        return {pair: self.analysis.pair_pixels(*pair) for pair in self.pairs}, self.differing_before

    #: Bands of at least this share of the frame's rows are drawn whole (the band saves little).
    WHOLE_SHARE = 0.9
    #: Renderers, and pairs of them whose boxes meet, that :meth:`band` checks pair by pair at most;
    #: beyond, every renderer drawn at another place in the order counts whole (one of each
    #: pair drawn in another order is).
    BAND_PLACES = 1024
    BAND_PAIRS = 4096

    def band(self, signature: tuple, calls: list[DrawCall], height: int, kept: int = 0) -> tuple[int, int] | None:
        """The buffer rows a changed scene's frame can differ in from the analysed one, with every
        advised pair's inverted pixels: ``(y0, y1)`` (empty when y0 >= y1), or None for the whole
        frame. A pixel's colour and each pair's inversion there depend only on the calls whose
        fragments reach it, in their order. So it can change only within the box of a renderer
        whose own calls the change alters (:func:`_altered_places`), or where the boxes of two
        renderers whose calls it orders otherwise meet (at a pixel only one of them reaches,
        their order decides nothing); and an advised pair can be inverted only where the boxes of
        its renderers meet. ``kept``: the length of the changed scene's opaque queue when it
        leaves the analysed step-1 buffers (:meth:`_opaque_kept`; 0: not known to), so only the
        calls after it can change a pixel. None when an altered renderer may cover pixels it did
        not reach before (a cull or outline of its own it did not draw with)."""
        old, new = (self.signature[len(self.opaque):] if kept else self.signature), signature[kept:]
        altered = _altered_places(old, new)
        for (k, *_), c in zip(signature, calls, strict=True):
            if k in altered and not _covered_within(_coverage_key(c), self.place_coverage.get(k, set())):
                return None
        boxes = self.place_boxes
        rows = [boxes[k][:2] for k in altered if k in boxes]
        rows += [r for a, b in self.pair_places if (r := _overlap(boxes.get(a), boxes.get(b))) is not None]
        rows += self._reordered_rows(old, new, altered)
        if not rows:
            return (0, 0)
        y0, y1 = min(r[0] for r in rows), max(r[1] for r in rows)
        return None if (y1 - y0) >= self.WHOLE_SHARE * height else (y0, y1)

    def _reordered_rows(self, old: tuple, new: tuple, altered: set[int]) -> list[tuple[int, int]]:
        """The rows where the boxes of two renderers (neither ``altered``) meet that the new
        signature draws in another order than the old one."""
        before, after = _positions(old), _positions(new)
        drawn = sorted(k for k in after if k in self.place_boxes and k not in altered)
        box = np.array([self.place_boxes[k] for k in drawn], dtype=np.int64).reshape(-1, 4)
        if len(drawn) <= self.BAND_PLACES:
            y0 = np.maximum(box[:, None, 0], box[None, :, 0])
            y1 = np.minimum(box[:, None, 1], box[None, :, 1])
            meet = np.triu((y0 < y1) & (np.maximum(box[:, None, 2], box[None, :, 2])
                                         < np.minimum(box[:, None, 3], box[None, :, 3])), 1)
            first, second = np.nonzero(meet)
            if first.size <= self.BAND_PAIRS:
                return [(int(y0[i, j]), int(y1[i, j])) for i, j in zip(first.tolist(), second.tolist(), strict=True)
                        if _interleaving(before[drawn[i]], before[drawn[j]])
                        != _interleaving(after[drawn[i]], after[drawn[j]])]
        return [self.place_boxes[k][:2] for k in drawn if before.get(k) != after[k]]

    def differing_codes(self, codes: np.ndarray, rows: tuple[int, int]) -> int:
        """:meth:`differing` of a changed 8-bit frame from its buffers' colour codes ``codes``
        (H*W, 4) uint8 (buffer rows from the bottom; rows ``[y0, y1)`` drawn, the others the
        analysed frame's): the pixels whose codes differ from the analysed frame's, their colours
        made as the frame's are (code / 255 in float32)."""
        original = self.analysis
        width = original.frame.color.shape[1]
        y0, y1 = rows
        new = codes.view(np.uint32).reshape(-1)[y0 * width:y1 * width]
        old = original.final_codes.view(np.uint32).reshape(-1)[y0 * width:y1 * width]
        changed = np.flatnonzero(new != old) + y0 * width  # buffer pixels
        if changed.size == 0:
            return self.differing_before
        height = original.frame.color.shape[0]
        # sort_error takes the codes back from the colours (rint(code / 255 · 255) is the code,
        # for every code): the codes themselves, with the reference's taken as it takes them.
        return self._differing_at(np.take(codes, changed, axis=0), (height - 1 - changed // width) * width
                                  + changed % width)

    def _differing_at(self, color: np.ndarray, at: np.ndarray) -> int:
        """The differing pixels of the analysed frame with the colours ``color`` (K, 4) float32
        at pixels ``at`` (K,) (top row first) instead of its own; for 8-bit frames ``color``
        may be the stored codes (K, 4) uint8 instead (their steps against the reference's
        ``rint(value · 255)``, as :func:`.sorted_reference.sort_error` counts them)."""
        original = self.analysis
        reference = np.take(original.reference.reshape(-1, 4), at, axis=0)
        now = 0
        for k in range(0, at.size, ERROR_PIXELS):
            if color.dtype == np.uint8:
                theirs = ldr_codes(reference[k:k + ERROR_PIXELS])
                theirs -= color[k:k + ERROR_PIXELS]
                piece = largest_step(np.abs(theirs, out=theirs))
            else:  # each piece as one row: as (K, 1) pixels, sort_error would take them 256 rows at a time
                piece = sort_error(color[None, k:k + ERROR_PIXELS], reference[None, k:k + ERROR_PIXELS],
                                   original.hdr)
            now += int(np.count_nonzero(piece > original.step))
        before = original.error.reshape(-1)[at]
        return self.differing_before - int(np.count_nonzero(before > original.step)) + now

    def differing(self, color: np.ndarray, top: int = 0) -> int:
        """Pixels of a changed scene's frame whose sort error exceeds one step, given its rows
        ``[top, top + h)`` (counted from the top) as ``color`` (h, W, 4) float32, the other rows
        being the analysed frame's. A fix changes the frame only where its renderers draw: the
        error is computed again only at pixels whose colour differs (by bits) from the analysed
        frame, the others keep theirs."""
        original = self.analysis
        width = color.shape[1]
        # A pixel's four float32 as two uint64: two comparisons a pixel instead of a reduction over four.
        bits = np.ascontiguousarray(color).view(np.uint64)
        analysed = np.ascontiguousarray(original.frame.color[top:top + color.shape[0]]).view(np.uint64)
        changed = []
        for y in range(0, color.shape[0], ERROR_ROWS):  # bounds the temporaries of a large frame
            a, b = bits[y:y + ERROR_ROWS], analysed[y:y + ERROR_ROWS]
            rows = a[..., 0] != b[..., 0]
            rows |= a[..., 1] != b[..., 1]
            changed.append(np.flatnonzero(rows) + y * width)
        changed = np.concatenate(changed)
        if changed.size == 0:
            return self.differing_before
        return self._differing_at(np.take(color.reshape(-1, 4), changed, axis=0), changed + top * width)


#: Changed pixels whose sort error :meth:`_Measurer.differing` computes in one piece (bounds the
#: temporaries as ``sort_error``'s row ranges do on a frame: 256 rows of 1024 pixels).
ERROR_PIXELS = ERROR_ROWS * 1024


def _last_opaque(calls: list[DrawCall]) -> int:
    """The index of the last draw call of queue ≤ 2500 (0: none)."""
    return max((c.index for c in calls if c.queue <= LAST_OPAQUE_QUEUE), default=0)


def _cleared(scene: DrawScene) -> FrameBuffers:
    """The cleared buffers of ``scene``'s frame (a step 1 with nothing drawn)."""
    clear = shade.gamma_color_to_shading(scene.clear_color[:3], scene.color_space) + (float(scene.clear_color[3]),)
    return FrameBuffers(int(scene.camera.width), int(scene.camera.height), scene.hdr, scene.color_space, clear,
                        samples=int(scene.msaa))


def advise(scene: DrawScene, analysis: Analysis, limit: int = 5, workers: int | None = None, *,
           progress: Callable[[float], None] | None = None,
           should_cancel: Callable[[], bool] | None = None,
           settings: Mapping[str, MaterialSettings] | None = None,
           measure_map: MeasureMap | None = None) -> list[dict]:
    """Advice items for the ``limit`` largest inversion pairs (fields of docs/json.md), each checked.
    ``progress``/``should_cancel`` as for :func:`~.sorted_reference.analyze`; ``settings``: per
    material name, the settings its state comes from (:class:`MaterialSettings`; a material there
    is advised in their terms, a self-overlap by its settings that write depth or test alpha);
    ``measure_map``: runs the candidates' distinct measurements (:class:`MeasureMap`; None: one
    after the other here, each with ``workers`` threads)."""
    settings = settings or {}
    bar = Progress(progress)
    inversions = analysis.inversions[:limit]
    plans = []
    for inv in inversions:
        front = _renderer(scene, inv.front)
        if inv.self_overlap and front.material.name in settings:
            plans.append((inv, _settings_candidates(scene, front, settings[front.material.name], "")))
        elif inv.self_overlap:
            plans.append((inv, [(None, with_prepass(scene, inv.front), None)]))
        else:
            plans.append((inv, _pair_candidates(scene, front, _renderer(scene, inv.behind), settings)))
    measurer = _Measurer(scene, analysis, [(inv.front, inv.behind) for inv in inversions], workers, should_cancel)
    changed_scenes = [changed for _, candidates in plans for _, changed, _ in candidates]
    measurer.expect(changed_scenes)
    total = max(1, sum(len(candidates) for _, candidates in plans))
    measurer.measure_all(changed_scenes, measure_map, progress=bar.part(0.0, 0.95))
    done = 0
    items = []
    before_differing = measurer.differing_before
    for inv, candidates in plans:
        base = {**inv.as_json(), "inversions_before": inv.pixels, "differing_before": before_differing}
        base.pop("pixels")
        pair = (inv.front, inv.behind)
        best = None
        for change, changed, sentence in candidates:
            pixels, differing = measurer.measure(changed)
            done += 1
            bar(done / total)
            score = (pixels[pair], differing)
            if best is None or score < best[0]:
                best = (score, change, sentence)
        if inv.self_overlap and best is not None and best[1] is not None:  # a setting of its own
            (pairs, differing), change, sentence = best
            price = ("; what lies behind its nearer layers is hidden, so more of the frame differs from the "
                     "sorted reference" if differing > before_differing else "")
            items.append({**base, "change": change, "inversions_after": pairs, "differing_after": differing,
                          "text": (f"{_label(inv.front)} overlaps itself on {inv.pixels} pixels: {sentence} "
                                   f"(checked: {inv.pixels} → {pairs} inverted pixels, {before_differing} → "
                                   f"{differing} differing{price})")})
            continue
        if inv.self_overlap:
            (pairs, differing), _, _ = best
            items.append({**base, "change": None, "technique": "depth prepass", "preset": PREPASS_PRESET,
                          "inversions_after": pairs, "differing_after": differing,
                          "text": (f"{_label(inv.front)} overlaps itself on {inv.pixels} pixels: a depth prepass "
                                   f"(preset '{PREPASS_PRESET}') leaves {pairs} inverted but shows only the front "
                                   f"layer (then {differing} pixels of the frame differ from the sorted reference, "
                                   f"{before_differing} before); or split "
                                   "the mesh into parts that sort by distance, or order its triangles back to "
                                   "front (Mesh > Sort Elements)")})
            continue
        if best is None:
            items.append({**base, "change": None, "inversions_after": inv.pixels,
                          "differing_after": before_differing,
                          "text": (f"{_label(inv.front)} is in front of {_label(inv.behind)} on {inv.pixels} "
                                   "pixels but drawn first; they share a material and a queue: give one of "
                                   "them its own material and queue offset")})
            continue
        (pairs, differing), change, sentence = best
        items.append({**base, "change": change, "inversions_after": pairs, "differing_after": differing,
                      "text": (f"{_label(inv.front)} is in front of {_label(inv.behind)} on {inv.pixels} pixels "
                               f"but drawn first: {sentence} (checked: {inv.pixels} → {pairs} inverted pixels, "
                               f"{before_differing} → {differing} differing)")})
    bar(1.0)
    return items


def analyze_and_advise(
    scene: DrawScene,
    *,
    max_advice: int = 5,
    workers: int | None = None,
    progress: Callable[[float], None] | None = None,
    should_cancel: Callable[[], bool] | None = None,
    settings: Mapping[str, MaterialSettings] | None = None,
    measure_map: MeasureMap | None = None,
    **kwargs,
) -> Analysis:
    """:func:`~.sorted_reference.analyze` of ``scene``, its ``advice`` filled with a checked fix
    for each of the ``max_advice`` largest inversion pairs (:func:`advise`; 0: none). One
    ``progress`` fraction runs over both; ``settings`` and ``measure_map`` as for :func:`advise`.
    Other keyword arguments go to ``analyze`` (``memory``, ``memory_limit``). Raises as
    ``analyze`` does."""
    bar = Progress(progress)
    share = 1.0 if max_advice <= 0 else 1.0 / (1.0 + ADVICE_WEIGHT * max_advice)
    analysis = analyze(scene, workers=workers, progress=bar.part(0.0, share), should_cancel=should_cancel,
                       keep_step1=max_advice > 0, **kwargs)
    if max_advice > 0 and analysis.inversions:
        analysis.advice = advise(scene, analysis, limit=max_advice, workers=workers, progress=bar.part(share, 1.0),
                                 should_cancel=should_cancel, settings=settings, measure_map=measure_map)
    analysis.step1 = None  # the advice's: not part of the result
    bar(1.0)
    return analysis
