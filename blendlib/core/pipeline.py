"""The frame driver: draw list → batches of prepared draw calls → screen bands → Frame.

:func:`render_scene` only chains the stages. One loop (:func:`_draw_all`) walks the draw calls
in batches: each batch is prepared at once (:func:`.prepare.prepare_batch`: vertex setup,
coverage, derived state), fused where nothing observes the render (:mod:`.fuse`), and drawn
in steps — the whole batch, or one draw call at a time for an observer that needs the
buffers exactly between draw calls (timing each call). A step's rows are cut into horizontal
screen bands of about equal fragment counts; one worker thread per band draws its rows of every
call of the step in draw order, chunk by chunk (:mod:`.fragment` shading, then :mod:`.merger`),
and hands its rows to an observer's snapshots after the calls it names.
Bands own disjoint pixels and each sees its calls in order, so the result does not depend on
the split; numpy releases the GIL in its array loops, so both CPU cores work.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Hashable, Iterator, Mapping
from concurrent.futures import ThreadPoolExecutor, wait
from dataclasses import replace

import numpy as np

from . import fragment, msaa, raster, shade
from .drawlist import DrawCall, draw_calls, writes_depth_or_stencil
from .fuse import fuse_constant_calls, fuse_shared_shading
from .gather import gather
from .merger import FrameBuffers, Outcome, compare, lut_eligible, merge
from .prepare import FrameContext, Member, PreparedCall, placements_of, prepare_batch
from .records import DrawState, Frame, FrameObserver, RenderCancelled, ShadedFragments
from .scene import DrawScene, SceneError, SceneMemo, validate_scene
from .shaded_cache import ShadedCache, call_slots, state_key
from .vocabulary import ColorSpace, Lighting, TextureFilter

__all__ = ["Frame", "FrameObserver", "RenderCancelled", "render_scene"]

#: Candidate pixels per chunk. Small enough that a chunk's per-fragment arrays (1 MB each for
#: int64) stay in a core's cache while a chunk passes through the stages, large enough that the
#: per-chunk Python work stays small (docs/benchmark.md, "Why the constants are what they are").
CHUNK_CANDIDATES = 1 << 17
#: Frames with fewer pixels render in one thread by default: below this, handing screen bands to
#: a second thread costs more than it saves (the viewport's reduced first frames; docs/benchmark.md).
SMALL_FRAME_PIXELS = 1 << 18
#: Without an observer, consecutive draw calls are prepared (vertex setup and coverage, one
#: renderer per task) as a batch of up to this many source triangles and draw calls; then each
#: worker draws its screen band of the whole batch in draw order, with no wait between calls.
BATCH_TRIANGLES = 1 << 18
BATCH_DRAWS = 64
#: Frames of at least this many pixels draw every step in screen bands, one per worker (tests
#: lower it to draw every step in bands). Below it a step is drawn in bands only when its calls
#: are large: short array calls hold the GIL, which two threads then contend for, so bands of
#: many small calls or of cheap per-fragment work (palettes, constant colours, blend tables)
#: take longer than one thread (docs/benchmark.md, "Round five").
BAND_PIXELS = 1 << 23
#: Bands pay for a step whose calls hold this many candidate fragments each on average ...
BAND_CALL_FRAGMENTS = 1 << 18
#: ... or that holds at least BAND_SHADED_FRAGMENTS candidate fragments of per-fragment shading,
#: BAND_SHADED_CALL_FRAGMENTS on average in each call that shades per fragment.
BAND_SHADED_FRAGMENTS = 1 << 17
BAND_SHADED_CALL_FRAGMENTS = 1 << 15
#: Lit meshes of more triangles count as smooth (shaded per fragment) for that decision without
#: their normals being examined, which would cost a pass over them every frame.
SMOOTH_TRIANGLES = 1 << 15


def render_scene(
    scene: DrawScene,
    *,
    progress: Callable[[float], None] | None = None,
    should_cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    chunk_candidates: int = CHUNK_CANDIDATES,
    until_draw: int | None = None,
    resume: tuple[FrameBuffers, int] | None = None,
    observer: FrameObserver | None = None,
    band: tuple[int, int] | None = None,
    out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    memo: SceneMemo | None = None,
    calls: list[DrawCall] | None = None,
    output: bool = True,
    shaded_cache: ShadedCache | None = None,
    call_keys: Mapping[int, Hashable] | None = None,
) -> Frame:
    """Render a draw scene exactly as Unity's built-in pipeline would (docs/pipeline.md).

    ``progress(fraction)`` is called as draw calls complete (after each batch of them, see
    ``BATCH_TRIANGLES``; after each call with an observer that needs exact draw boundaries);
    ``should_cancel()`` is polled
    between draw calls and chunks, and a True answer raises :class:`RenderCancelled`.
    ``until_draw`` K: stop after draw call K (numbered from 1; 0 = the cleared frame).
    ``resume`` (buffers, K0): start from a copy of ``buffers`` as left after draw call K0
    (a snapshot taken by an observer's :meth:`FrameObserver.draw_end`), drawing K0+1 on.
    ``observer``: a :class:`FrameObserver` that receives every draw call and fragment.
    ``band`` (y0, y1): draw only buffer rows ``y0 <= y < y1`` (counted from the bottom) and
    return just those rows (the Frame's arrays are ``y1 - y0`` rows high, top row first): every
    pixel there equals the full render's, since pixels never depend on one another (one
    process's share of a frame split across processes, :mod:`blendlib.runtime.bandprocs`).
    An observer of a band render receives the band's fragments only, and buffers whose rows
    outside the band were never cleared (the sorted reference's later passes,
    :mod:`blendlib.explain.sorted_reference`). With ``resume`` too, the band's rows continue
    from the resumed buffers (the advice's re-measured fixes, :mod:`blendlib.explain.advice`).
    ``out``: (color, depth, stencil) arrays of the Frame's shapes and dtypes to write the
    result into (a band straight into its rows of a whole frame, or into shared memory).
    ``memo``: a :class:`~blendlib.core.scene.SceneMemo` shared by renders of scenes with the
    same renderers (the viewport's frames): renderers are checked and textures converted once.
    ``calls``: the scene's draw list, when the caller already has it
    (:func:`~blendlib.core.drawlist.draw_calls` of this very scene; the tools that explain a
    frame need it too).
    ``output=False``: the buffers are not converted into the Frame's arrays (its ``color``,
    ``depth`` and ``stencil`` are None): for an observer that reads them at its last ``draw_end``.
    ``shaded_cache`` with ``call_keys`` (call index → a key equal for calls that draw the same,
    whatever their place in the draw list): shaded chunks are taken from the cache where an
    earlier render given it shaded them in the same circumstances, and kept there
    (:mod:`.shaded_cache`; calls are then not fused); the frame is the same either way.
    Raises :class:`blendlib.core.scene.SceneError` (one line) for input that cannot render.
    """
    keep_setups = memo is not None  # a memo of this render alone would only hold setups to its end
    memo = SceneMemo() if memo is None else memo
    warnings = list(scene.warnings) + validate_scene(scene, memo)
    if until_draw is not None and int(until_draw) < 0:
        raise SceneError(f"until_draw must be 0 or more (got {until_draw})")
    cam = scene.camera
    width, height = int(cam.width), int(cam.height)
    if band is not None:
        band = (int(band[0]), int(band[1]))
        if not 0 <= band[0] < band[1] <= height:
            raise SceneError(f"band {band} is not a range of rows within 0..{height}")
    samples = int(scene.msaa)
    if samples > 1 and observer is not None and not observer.per_sample:
        raise SceneError(f"{type(observer).__name__} reads pixel fragments only (FrameObserver.per_sample), "
                         f"and the scene has MSAA {samples}: render it with msaa 1")
    cs = scene.color_space
    if resume is not None:
        if resume[0].samples != samples:
            raise SceneError(f"resume: buffers of {resume[0].samples} samples per pixel, the scene has {samples}")
    first = 0 if resume is None else int(resume[1])
    calls = draw_calls(scene) if calls is None else calls
    last = len(calls) if until_draw is None else min(int(until_draw), len(calls))
    todo = [c for c in calls if first < c.index <= last]
    if resume is not None:  # depth and stencil shared where no call writes them (read only)
        buf = resume[0].copy(band, colors_only=not any(writes_depth_or_stencil(c) for c in todo))
    else:
        clear = shade.gamma_color_to_shading(scene.clear_color[:3], cs) + (float(scene.clear_color[3]),)
        buf = FrameBuffers(width, height, scene.hdr, cs, clear, band, samples)
    lights = shade.frame_lights(scene)
    if workers is None:
        workers = 1 if width * height < SMALL_FRAME_PIXELS else min(2, os.cpu_count() or 1)
    pool = ThreadPoolExecutor(max_workers=workers) if workers > 1 else None
    frame = FrameContext(buf, cam, lights, cs, scene.hdr, chunk_candidates, pool, workers, threading.Event(),
                         observed=observer is not None and observer.reads_fragments, band=band, memo=memo,
                         keep_setups=keep_setups,
                         reads_depth=None if observer is None else observer.reads_depth,
                         reads_call=None if observer is None else observer.reads_call,
                         reads_hidden=None if observer is None else observer.reads_hidden,
                         colors_read=None if observer is None else observer.colors_read)
    if keep_setups:  # where the scene places each mesh: kept setups of other placements go
        frame.placements = placements_of(scene.renderers)
    if shaded_cache is not None and call_keys is not None:
        frame.shaded_cache = shaded_cache
        frame.shaded_slots = call_slots(shaded_cache, todo, call_keys,
                                        writes_depth_or_stencil,
                                        None if resume is None else resume[0])
    try:
        _draw_all(frame, todo, should_cancel, progress, observer)
        color, depth, stencil = buf.output(pool, workers, band, out) if output else (None, None, None)
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    warnings.extend(frame.warnings)
    degenerate = frame.degenerate
    if degenerate:
        total = sum(n for _, n in degenerate)
        names = sorted({name for name, _ in degenerate})
        shown = ", ".join(repr(n) for n in names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
        warnings.append(f"{total} degenerate (zero-area) triangles draw nothing, in {shown}")
    textures = (c.renderer.material.main_tex for c in calls)
    missing = {t.name for t in textures if t is not None and t.missing}
    warnings.extend(f"image {name!r}: file missing, drawn magenta" for name in sorted(missing))
    encoded = not (scene.hdr and cs is ColorSpace.Linear)
    return Frame(color=color, depth=depth, stencil=stencil, warnings=warnings, encoded=encoded)


# ---------------------------------------------------------------------------------------------
# The loop
# ---------------------------------------------------------------------------------------------


def _draw_all(frame: FrameContext, todo: list[DrawCall], should_cancel: Callable[[], bool] | None,
              progress: Callable[[float], None] | None, observer: FrameObserver | None) -> None:
    """Draw ``todo`` in order: batch by batch (:func:`_batches`), each prepared at once and
    drawn in steps (:func:`_steps`), the observer told of every call before and after its step.

    Without an observer that needs exact draw boundaries, a step is a whole batch: its calls'
    ``draw_begin`` come before it is drawn and ``draw_end`` after (with the buffers after the
    batch). With one, a batch is one renderer's passes (one vertex setup) and a step one call."""
    exact = observer is not None and observer.exact_boundaries
    cuts = frozenset() if observer is None else frozenset(observer.exact_before)
    floors = RowFloors(frame.buf)
    done = 0
    for runs in _batches(todo, exact, cuts):
        _check(should_cancel)
        prepared = prepare_batch(frame, runs)
        # An observer is told of each call's own fragments; a shaded cache keeps each call's own chunks.
        if observer is None and frame.shaded_cache is None:
            prepared = fuse_shared_shading(fuse_constant_calls(prepared, frame.memo), frame.memo)
        for calls, step in _steps([call for run in runs for call in run], prepared, exact):
            if observer is not None:
                for call in calls:
                    observer.draw_begin(call, frame.buf)
            marks = () if observer is None else sorted(
                s for s in observer.snapshot_after if calls[0].index <= s <= calls[-1].index)
            _draw_step(frame, step, floors, should_cancel, observer, marks)
            if frame.stop_flag.is_set():
                raise RenderCancelled("render cancelled")
            if observer is not None:
                reached = {pr.call.index: int(np.unique(pr.setup.src[pr.selected]).size) for pr in step}
                for call in calls:
                    observer.draw_end(call, frame.buf, reached.get(call.index, 0))
            done += len(calls)
            if progress is not None:
                progress(done / max(len(todo), 1))


def _renderer_runs(calls: list[DrawCall]) -> list[list[DrawCall]]:
    """Consecutive draw calls of one renderer (its passes), which share one vertex setup."""
    runs: list[list[DrawCall]] = []
    for call in calls:
        if runs and runs[-1][-1].renderer is call.renderer:
            runs[-1].append(call)
        else:
            runs.append([call])
    return runs


def _batches(calls: list[DrawCall], exact: bool = False,
             cuts: frozenset[int] = frozenset()) -> list[list[list[DrawCall]]]:
    """Renderer runs grouped into batches (a run is never split; at least one run a batch), of
    at most :data:`BATCH_TRIANGLES` and :data:`BATCH_DRAWS`; one run each when ``exact``; a
    run holding a call of ``cuts`` starts a batch."""
    batches: list[list[list[DrawCall]]] = []
    triangles = draws = 0
    for run in _renderer_runs(calls):
        count = int(run[0].renderer.mesh.triangle_count)
        if (batches and not exact and triangles + count <= BATCH_TRIANGLES
                and draws + len(run) <= BATCH_DRAWS and not any(c.index in cuts for c in run)):
            batches[-1].append(run)
            triangles += count
            draws += len(run)
        else:
            batches.append([run])
            triangles, draws = count, len(run)
    return batches


def _steps(calls: list[DrawCall], prepared: list[PreparedCall],
           exact: bool) -> list[tuple[list[DrawCall], list[PreparedCall]]]:
    """(draw calls, their prepared calls) drawn without a stop between: the whole batch, or with
    ``exact`` each call on its own (calls of renderers without triangles have none prepared)."""
    if not exact:
        return [(calls, prepared)]
    by_index = {pr.call.index: pr for pr in prepared}
    return [([call], [by_index[call.index]] if call.index in by_index else []) for call in calls]


def _check(should_cancel: Callable[[], bool] | None) -> None:
    """Raise :class:`RenderCancelled` when ``should_cancel()`` says so."""
    if should_cancel is not None and should_cancel():
        raise RenderCancelled("render cancelled")


def _draw_step(frame: FrameContext, step: list[PreparedCall], floors: RowFloors,
               should_cancel: Callable[[], bool] | None, observer: FrameObserver | None,
               marks: list[int] | tuple = ()) -> None:
    """Draw the prepared calls of a step: in one band here, or in screen bands cut at equal
    fragment counts of the whole step (:func:`_bands_pay`), one per worker, while this thread
    polls ``should_cancel``. ``marks``: the step's calls (indices, ascending) after which each
    band hands its rows to ``observer.snapshot_rows``."""
    lo, hi = frame.band or (0, frame.height)  # the rows drawn (a band render's own)
    cuts = None
    if frame.pool is not None and _bands_pay(frame, step):
        cuts = raster.band_cuts([pr.rows for pr in step], frame.workers, frame.height)
    if cuts is None:
        _draw_band(frame, [(pr, pr.rows) for pr in step], lo, hi, floors, observer,
                   lambda: _check(should_cancel), marks)
        return
    edges = [lo, *(int(c) for c in cuts), hi]
    futures = [frame.pool.submit(_draw_band_of, frame, step, cuts, k, edges[k],
                                 min(max(edges[k + 1], edges[k]), frame.height), floors, observer, marks)
               for k in range(cuts.size + 1)]
    _wait(futures, should_cancel, frame.stop_flag)


def _draw_band_of(frame: FrameContext, step: list[PreparedCall], cuts: np.ndarray, k: int, y0: int, y1: int,
                  floors: RowFloors, observer: FrameObserver | None, marks: list[int] | tuple) -> None:
    """:func:`_draw_band` of screen band ``k`` of ``cuts`` (rows ``[y0, y1)``), on a band worker:
    each worker takes its own rows of the step's calls (:meth:`.raster.Rows.band_of`)."""
    _draw_band(frame, [(pr, pr.rows.band_of(cuts, k)) for pr in step], y0, y1, floors, observer, _no_check, marks)


def _no_check() -> None:
    """Band workers poll the stop flag instead (set by the thread that polls ``should_cancel``)."""


def _wait(futures, should_cancel, stop_flag: threading.Event) -> None:
    """Wait for band workers, polling ``should_cancel`` from this (the calling) thread."""
    pending = set(futures)
    while pending:
        done, pending = wait(pending, timeout=0.05)
        for f in done:
            f.result()  # re-raise worker errors
        if should_cancel is not None and should_cancel():
            stop_flag.set()
            wait(pending)
            return


def _bands_pay(frame: FrameContext, step: list[PreparedCall]) -> bool:
    """Whether a step is drawn in screen bands on the pool (see :data:`BAND_PIXELS`)."""
    if frame.width * frame.height >= BAND_PIXELS:
        return True
    counts = [int(pr.rows.length.sum()) for pr in step]
    if sum(counts) >= BAND_CALL_FRAGMENTS * len(step):
        return True
    shaded = [count for pr, count in zip(step, counts, strict=True) if _shaded_per_fragment(pr)]
    return sum(shaded) >= max(BAND_SHADED_FRAGMENTS, BAND_SHADED_CALL_FRAGMENTS * len(shaded))


def _shaded_per_fragment(prepared: PreparedCall) -> bool:
    """Whether the call's fragments are shaded one by one (:func:`.fragment.shade_chunk`'s
    varying inputs: smooth normals under Lambert, or a filtered texture); not its flat
    triangles, texel palettes, constant colours or colourless passes."""
    if prepared.shade is not fragment.shade_chunk:
        return False
    material = prepared.state.material
    if material.main_tex is not None and (material.main_tex_filter is not TextureFilter.Point
                                          or material.main_tex_mipmaps):
        return True
    if prepared.setup.object_colors is not None:  # vertex colours: varying unless flat
        return True
    if material.lighting is Lighting.Unlit:
        return False
    if prepared.state.lights.positional:  # a point or spot light's direction varies
        return True
    calls = [prepared.call] if prepared.members is None else [m.state.call for m in prepared.members]
    for call in calls:
        normals = np.asarray(call.renderer.mesh.normals)
        if normals.shape[0] > SMOOTH_TRIANGLES:
            return True
        if not raster.flat_corners(normals).all():
            return True
    return False


# ---------------------------------------------------------------------------------------------
# One screen band
# ---------------------------------------------------------------------------------------------


class RowFloors:
    """Per buffer row, the smallest stored depth code: the ``zfloor`` of the hierarchical-Z
    shortcut (:meth:`.records.DrawState.depth_needed`), taken from the buffers when first needed
    and again only after a pass wrote depth in those rows.

    Screen bands own disjoint rows, so band workers read and refresh their own rows of the
    shared arrays without a lock; a band's floors stay valid from step to step until a pass
    that writes depth is drawn in it, wherever the cuts of later steps fall.
    """

    def __init__(self, buf: FrameBuffers) -> None:
        self.buf = buf
        self.floor = np.zeros(buf.height, dtype=np.int64)  # (H,) int64
        self.valid = np.zeros(buf.height, dtype=bool)  # (H,) bool: the row's floor is current

    def rows(self, y0: int, y1: int) -> np.ndarray:
        """The (H,) int64 floors, current in rows ``[y0, y1)`` (others as they are)."""
        stale = y0 + np.flatnonzero(~self.valid[y0:y1])
        if stale.size:
            if self.buf.samples == 1:
                self.floor[stale] = self.buf.depth.reshape(self.buf.height, self.buf.width)[stale].min(axis=1)
            else:  # every sample of the row's pixels (sample planes)
                depth = self.buf.depth.reshape(self.buf.samples, self.buf.height, self.buf.width)
                self.floor[stale] = depth[:, stale].min(axis=(0, 2))
            self.valid[stale] = True
        return self.floor

    def written(self, y0: int, y1: int) -> None:
        """A pass that writes depth was drawn in rows ``[y0, y1)``."""
        self.valid[y0:y1] = False


def _draw_band(frame: FrameContext, items: list[tuple[PreparedCall, raster.Rows]], y0: int, y1: int,
               floors: RowFloors, observer: FrameObserver | None, check: Callable[[], None],
               marks: list[int] | tuple = ()) -> None:
    """Draw screen band ``[y0, y1)`` of a step: ``items`` (prepared call, its rows in the band)
    in draw order, each with the band's depth floors; ``check()`` runs before each call (a
    cancellation check). After the calls of ``marks`` (indices, ascending; a call without
    triangles has no item) the band's rows go to ``observer.snapshot_rows``."""
    pending = list(marks)
    for prepared, rows in items:
        check()
        if frame.stop_flag.is_set():
            return
        while pending and pending[0] < prepared.call.index:
            observer.snapshot_rows(pending.pop(0), frame.buf, y0, y1)
        state = prepared.state
        if rows.count:
            if state.zbound is not None:
                state = replace(state, zfloor=floors.rows(y0, y1))
            if prepared.members is None:
                slot = frame.shaded_slots.get(prepared.call.index)  # kept only with a shaded cache
                _draw_chunks(frame, prepared, rows, state, observer, None if slot is None else (*slot, y0, y1))
            else:
                _draw_members(frame, prepared, rows, state)
        if state.pass_state.zwrite:
            floors.written(y0, y1)
    if frame.stop_flag.is_set():
        return
    for index in pending:
        observer.snapshot_rows(index, frame.buf, y0, y1)


def _shaded_chunks(frame: FrameContext, prepared: PreparedCall, rows: raster.Rows, state: DrawState,
                   watched: np.ndarray | None = None,
                   slot: tuple | None = None) -> Iterator[tuple[int, int, ShadedFragments, bool]]:
    """``rows`` of a prepared call in chunks of :attr:`FrameContext.chunk_candidates`, in draw
    order: (first row, end row, the chunk's shaded fragments, whether the observer is told of
    them) for each chunk holding any, until the render's stop flag is set. With ``watched``
    ((H,) bool buffer rows), a chunk in no watched row is shaded as an unobserved render shades
    it (``state.unobserved``). ``slot``: the key prefix of the call's chunks in the render's
    shaded cache (:mod:`.shaded_cache`), None when they are not kept."""
    plain = None if watched is None or state.unobserved is None else replace(state.unobserved, zfloor=state.zfloor)
    for a, b in raster.row_chunks(rows, frame.chunk_candidates):
        if frame.stop_flag.is_set():
            return
        seen = state.observed and (watched is None or bool(watched[rows.y[a:b]].any()))
        used = state if seen or plain is None else plain
        if used.samples == 1:
            used_key = None if slot is None else state_key(used)
            found, shaded = False, None
            if used_key is not None:
                key = (*slot, a, b, used_key)
                found, shaded = frame.shaded_cache.get(key)
            if not found:
                shaded = prepared.shade(prepared.setup, rows, a, b, used)
                if used_key is not None:
                    frame.shaded_cache.put(key, shaded)
        else:
            shaded = msaa.sampled_chunk(prepared.shade, prepared.setup, rows, a, b, used)
        if shaded is not None:
            yield a, b, shaded, seen


def _draw_chunks(frame: FrameContext, prepared: PreparedCall, rows: raster.Rows, state: DrawState,
                 observer: FrameObserver | None, slot: tuple | None = None) -> None:
    """Raster, shade and merge ``rows`` of one prepared call, chunk by chunk in draw order, with
    ``state`` (the call's, with the band's depth floors); the observer told of every fragment
    (of the chunks in its :attr:`.FrameObserver.watched_rows`)."""
    buf, p, tables = frame.buf, state.pass_state, prepared.tables
    if observer is not None and not state.observed:  # it reads no fragment, or none of this call's
        observer = None
    watched = None if observer is None else observer.watched_rows
    for _a, _b, shaded, seen in _shaded_chunks(frame, prepared, rows, state, watched, slot):
        merged = shaded if shaded.alive is None else shaded.select(shaded.alive)
        if observer is None or not seen:
            _merge(buf, p, merged, tables)
            continue
        if shaded.coverage is not None and not shaded.coverage.all():  # observers see covering fragments only
            shaded = shaded.select(shaded.coverage != 0)
            merged = shaded if shaded.alive is None else shaded.select(shaded.alive)
        per = () if shaded.coverage is None else (buf.samples,)  # with MSAA, an outcome per sample
        written = np.empty((merged.count, *per), dtype=np.int8)
        _merge(buf, p, merged, tables, written)
        if shaded.alive is None:
            outcome = written
        else:
            outcome = np.full((shaded.count, *per), Outcome.ALPHA_TEST, dtype=np.int8)
            if shaded.coverage is not None:  # samples the fragment does not cover
                outcome[~msaa.mask_bits(shaded.coverage, buf.samples)] = Outcome.NOT_COVERED
            outcome[shaded.alive] = written
        observer.fragments(state.call, shaded, outcome)


def _merge(buf: FrameBuffers, p, frags: ShadedFragments, tables, outcome: np.ndarray | None = None) -> None:
    """Merge a chunk's surviving fragments with pass ``p``: :func:`.merger.merge`, or per sample
    with MSAA (:func:`.msaa.merge_samples`); ``outcome`` as theirs. Inert fragments
    (:attr:`.records.ShadedFragments.inert`) are not merged: their outcome is the depth test's."""
    if frags.inert is not None and frags.inert.any():
        active = np.flatnonzero(~frags.inert)
        if active.size:
            codes = None if outcome is None else np.empty(active.size, dtype=np.int8)
            _merge(buf, p, frags.select(active), tables, codes)
            if outcome is not None:
                outcome[active] = codes
        if outcome is not None:
            idle = np.flatnonzero(frags.inert)
            if frags.stored_depth is None:  # the chunk passes the depth test (merge's depth None)
                outcome[idle] = Outcome.WRITTEN
            else:  # the pass writes no depth: the stored depth is as the others left it, and as before them
                passed = compare(p.ztest, gather(frags.stored_depth, idle), buf.depth[gather(frags.pix, idle)])
                outcome[idle] = np.where(passed, Outcome.WRITTEN, Outcome.DEPTH)
        return
    if frags.coverage is None:
        merge(buf, p, frags.pix, frags.stored_depth, frags.rgba, frags.ids, frags.palette, outcome=outcome,
              disjoint=frags.disjoint, tables=tables)
    else:
        msaa.merge_samples(buf, p, frags, tables, outcome)


def _draw_members(frame: FrameContext, prepared: PreparedCall, rows: raster.Rows, state: DrawState) -> None:
    """:func:`_draw_chunks` of calls with shared shading (:func:`.fuse.fuse_shared_shading`):
    each chunk is shaded once (``state``: how, with the band's depth floors); then each call's
    fragments, a contiguous run of the chunk (rows come in call order), pass its own alpha test
    and merge with its own pass, call after call."""
    members = prepared.members
    firsts = np.array([m.first for m in members], dtype=np.int64)
    for a, b, shaded, _seen in _shaded_chunks(frame, prepared, rows, state):
        member = np.searchsorted(firsts, rows.tri[a:b], side="right") - 1  # (R,) nondecreasing
        bounds = [0, *(np.flatnonzero(member[1:] != member[:-1]) + 1).tolist(), b - a]
        ends = (rows.length[a:b] if shaded.row_counts is None else shaded.row_counts).cumsum().tolist()
        for lo, hi in zip(bounds[:-1], bounds[1:], strict=False):
            f0, f1 = (ends[lo - 1] if lo else 0), ends[hi - 1]
            if f1 > f0:
                part = shaded.span(f0, f1)
                if not part.disjoint and len(bounds) > 2:  # the chunk's rows overlap; the call's may not
                    part.disjoint = raster.rows_disjoint(rows, a + lo, a + hi, frame.width)
                _merge_member(frame.buf, members[int(member[lo])], part)


def _merge_member(buf: FrameBuffers, member: Member, frags: ShadedFragments) -> None:
    """Alpha test and merge of one call's fragments shaded with others'."""
    p = member.state.pass_state
    if frags.ids is not None and not lut_eligible(p, buf.hdr):
        frags = replace(frags, rgba=frags.colors(), ids=None, palette=None)  # blended one by one
    if p.alpha_test:
        frags = frags.select(fragment.alpha_test(frags.rgba, frags.ids, frags.palette, member.state.material.cutoff,
                                                 p.alpha_test_comp))
    _merge(buf, p, frags, member.tables)
