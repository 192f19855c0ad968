"""The sorted reference, sort errors, inversions and overdraw (docs/sorting.md), vectorised, in bounded memory.

One observed render of the scene gives everything: the frame as drawn, the buffers after the
last draw of queue ≤ 2500 (step 1), every fragment of queues 2501–3999 that survived culling
and the alpha test (with whether the frame wrote it) and the per-pixel fragment counts. The
fragments are kept compactly by blocks of rows (:mod:`.fragment_store`). Step 2 applies each
block's fragments per pixel far to near (where the frame kept one fragment at a pixel, the
frame's own colour is the reference's there, :func:`lone_fragments_as_frame`), ties in draw
order then primitive order, layer by layer (layer k = the k-th farthest fragment of every
pixel, distinct pixels), each through its own pass's stencil, depth test (against step 1's
depth: nothing writes depth in step 2), blending and ColorMask; the same block gives the
inverted renderer pairs (:mod:`.layering`). Step 3 resumes the pipeline from those buffers for
the Overlay draws.

**Memory** (docs/sorting.md "Cost"): the kept fragments stay within a budget (``memory``,
default :data:`FRAGMENT_BUDGET`, less when the machine has less to spare). When a frame's
fragments do not fit, the blocks that did are finished, and the rows above them are rendered
again, alone, for the next blocks: a few more partial renders instead of more memory. Beyond the
budget the analysis needs memory in proportion to the pixels (:func:`memory_bound`); a frame for
which even that is not available is refused before anything is rendered.

Passes with ColorMask 0 write nothing in step 2 (no colour, no depth, no stencil): they are
left out of it and of the inversion counts.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ..core.drawlist import DrawCall, draw_calls
from ..core.merger import FrameBuffers
from ..core.parts import run_parts
from ..core.pipeline import render_scene
from ..core.records import Frame, FrameObserver, RenderCancelled
from ..core.scene import DrawScene, SceneError, validate_scene
from . import layering
from .fragment_store import (
    FIRST_SORTED_QUEUE,
    LAST_SORTED_QUEUE,
    FragmentCollector,
    is_sorted_queue,
    opaque_order_calls,
    pixel_ranges,
)
from .progress import Progress

__all__ = ["FIRST_SORTED_QUEUE", "LAST_SORTED_QUEUE", "Analysis", "Inversion", "analyze", "is_sorted_queue",
           "memory_bound", "sort_error"]

#: Default budget of the kept fragments, bytes: about 90 million fragments (50 transparent
#: layers over 1920x1080 take 73 million) before the rows above are analysed by another pass.
FRAGMENT_BUDGET = 1 << 30
#: The smallest budget the analysis lowers itself to when memory is short (then it refuses).
SMALLEST_BUDGET = 64 << 20
#: A block holding more fragments than this is taken out of the store by ranges of its pixels.
TAKE_FRAGMENTS = 1 << 21
#: Fragments one thread sorts and applies at once (a range of a block's pixels): bounds the
#: working memory of step 2 and of the inversion count beside the kept fragments.
WORK_FRAGMENTS = 1 << 19
#: Fragments a unit of blocks holds at least when it may (:func:`unit_fragments`).
UNIT_FRAGMENTS = 1 << 16
#: Memory the analysis needs per pixel at most, bytes, with LDR and with HDR buffers: the
#: result (frame 21, reference 16, error 4, overdraw 8, inverted 2), the render's buffers and
#: their step-1 copy (13 each, HDR 25), the overdraw counts (8), and a resumed render's buffers
#: and frame when Overlay draws follow (measured: 72 and 95 at 3000x3000, budget and work included).
PIXEL_BYTES = 96
PIXEL_BYTES_HDR = 128
#: With advice: a pristine copy of the step-1 buffers, a changed frame, its buffers and error,
#: and the pairs' images (:class:`blendlib.explain.advice._PairWatch`); in 8-bit buffers the
#: analysed frame's codes (4) instead of a changed frame's arrays (21).
ADVICE_PIXEL_BYTES = 96
#: With MSAA, per pixel and sample beyond the first: the three sets of buffers above hold every
#: sample (colour 4, HDR 16, depth 4 and stencil 1 bytes each; :class:`.merger.FrameBuffers`);
#: with advice two more sets and the pairs' images per sample.
SAMPLE_BYTES = 27
SAMPLE_BYTES_HDR = 63
ADVICE_SAMPLE_BYTES = 48
#: The kept fragments' peak over the budget, per thread processing blocks: a block taken out of
#: the store (:data:`TAKE_FRAGMENTS` at most), sorted and applied by ranges of
#: :data:`WORK_FRAGMENTS` (bytes; measured up to 100 MB).
WORK_BYTES = 160 << 20


def processing_threads(workers: int | None) -> int:
    """Threads that process blocks: ``workers``, else two (or one on a one-core machine)."""
    return max(1, int(workers) if workers is not None else min(2, os.cpu_count() or 1))


def memory_bound(width: int, height: int, hdr: bool = False, budget: int = FRAGMENT_BUDGET,
                 advice: bool = False, threads: int = 2, samples: int = 1) -> int:
    """Bytes an analysis of a ``width`` x ``height`` frame may add to the process at most: per
    pixel :data:`PIXEL_BYTES` (HDR :data:`PIXEL_BYTES_HDR`; with ``advice`` also
    :data:`ADVICE_PIXEL_BYTES`) and with MSAA ``samples`` N per further sample
    :data:`SAMPLE_BYTES` (:data:`SAMPLE_BYTES_HDR`, :data:`ADVICE_SAMPLE_BYTES`), the fragment
    ``budget`` and :data:`WORK_BYTES` per processing thread. The budget holds unless a single
    block of rows (:data:`.fragment_store.BLOCK_PIXELS` samples) alone holds more than it:
    thousands of transparent layers on every pixel of it."""
    per_pixel = (PIXEL_BYTES_HDR if hdr else PIXEL_BYTES) + (ADVICE_PIXEL_BYTES if advice else 0)
    per_sample = (SAMPLE_BYTES_HDR if hdr else SAMPLE_BYTES) + (ADVICE_SAMPLE_BYTES if advice else 0)
    per_pixel += (int(samples) - 1) * per_sample
    return int(width) * int(height) * per_pixel + int(budget) + int(threads) * WORK_BYTES


def available_memory() -> int | None:
    """Bytes the system can still give this process (Linux ``MemAvailable``), None where unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def fragment_budget(width: int, height: int, hdr: bool, memory: int | None, memory_limit: int | None,
                    advice: bool = False, threads: int = 2, samples: int = 1) -> int:
    """The fragment budget of an analysis: ``memory`` when given, else :data:`FRAGMENT_BUDGET`
    or what ``memory_limit`` (default: :func:`available_memory`) leaves beside the rest of
    :func:`memory_bound`, at least :data:`SMALLEST_BUDGET`. Raises :class:`SceneError` (one
    line, the memory it would need) when the frame does not fit ``memory_limit`` even so."""
    limit = available_memory() if memory_limit is None else int(memory_limit)
    if memory is not None:
        budget = int(memory)
        if budget < 1:
            raise SceneError(f"analyze: the fragment memory must be positive, got {memory!r}")
    else:
        budget = FRAGMENT_BUDGET
        if limit is not None:
            spare = limit - memory_bound(width, height, hdr, 0, advice, threads, samples)
            budget = max(SMALLEST_BUDGET, min(FRAGMENT_BUDGET, spare))
    need = memory_bound(width, height, hdr, budget, advice, threads, samples)
    if limit is not None and need > limit:
        work = threads * WORK_BYTES
        raise SceneError(
            f"analyze: a {width}x{height} frame needs about {need / 2**30:.1f} GiB of memory "
            f"({(need - budget - work) / 2**30:.1f} GiB for its pixels, {(budget + work) / 2**30:.2f} GiB for "
            f"the transparent fragments) and {max(limit, 0) / 2**30:.1f} GiB is available; lower the resolution")
    return budget


@dataclass(frozen=True)
class Inversion:
    """Pixels where a fragment of ``front`` was applied before a farther fragment of ``behind``.

    ``front``/``behind``: (object name, material slot). The same renderer on both sides is a
    self-overlap (triangles of one draw, or passes of one material)."""

    front: tuple[str, int]
    behind: tuple[str, int]
    pixels: int

    @property
    def self_overlap(self) -> bool:
        return self.front == self.behind

    def as_json(self) -> dict:
        return {"front": self.front[0], "front_slot": self.front[1], "behind": self.behind[0],
                "behind_slot": self.behind[1], "pixels": self.pixels}


@dataclass(eq=False)
class Analysis:
    """What :func:`analyze` finds (images row 0 = top).

    - ``frame``: the frame as drawn (:class:`Frame`).
    - ``reference`` (H, W, 4) float32: the sorted reference in ``frame.color`` units.
    - ``error`` (H, W) float32: per pixel the largest |frame − reference| over RGBA, in 8-bit
      steps for LDR buffers (whole steps), absolute for HDR.
    - ``overdraw`` (H, W, 2) uint32: fragments rasterised, fragments written (every draw call).
    - ``inverted`` (H, W) uint16: renderer pairs (A, B) inverted at the pixel.
    - ``inversions``: :class:`Inversion` per pair, most pixels first.
    - ``advice``: list of advice dicts (docs/json.md), filled by
      :func:`blendlib.explain.advice.analyze_and_advise` (empty from :func:`analyze` alone).
    """

    frame: Frame
    reference: np.ndarray
    error: np.ndarray
    overdraw: np.ndarray
    inverted: np.ndarray
    inversions: list[Inversion]
    hdr: bool
    advice: list[dict] = field(default_factory=list)
    #: The buffers after the last draw call of queue ≤ 2500, kept for advice (``analyze(...,
    #: keep_step1=True)``), else None: a changed scene's frame resumes from them.
    step1: FrameBuffers | None = field(default=None, repr=False)
    #: Per draw call index, the box of buffer rows (from the bottom) and columns ``(y0, y1, x0,
    #: x1)``, ends exclusive, its rasterised fragments reached; calls that rasterised nothing are absent.
    call_boxes: dict[int, tuple[int, int, int, int]] = field(default_factory=dict, repr=False)
    #: With ``keep_step1``: whether the draw calls of queue ≤ 2500 leave ``step1`` in any order
    #: (:meth:`.fragment_store.FragmentCollector.opaque_order_free`): advice then resumes a
    #: reordered opaque queue from ``step1`` instead of drawing it. False when not proved.
    opaque_order_free: bool = field(default=False, repr=False)
    #: With ``keep_step1``, 8-bit buffers and one sample: the frame's stored colour codes (H*W, 4)
    #: uint8 (buffer rows from the bottom): advice finds a changed frame's changed pixels by them.
    final_codes: np.ndarray | None = field(default=None, repr=False)

    @property
    def step(self) -> float:
        """One step of the error scale: 1 (8-bit steps) for LDR, 1/255 for HDR."""
        return 1.0 / 255.0 if self.hdr else 1.0

    @property
    def differing(self) -> int:
        """Pixels whose error exceeds one step."""
        return int(np.count_nonzero(self.error > self.step))

    def pair_pixels(self, front: tuple[str, int], behind: tuple[str, int]) -> int:
        for inv in self.inversions:
            if inv.front == front and inv.behind == behind:
                return inv.pixels
        return 0

    def __repr__(self) -> str:  # the images are megabytes of numbers: their size and the summary
        h, w = self.error.shape[:2]
        return (f"Analysis({w}x{h}, differing={self.differing}, max_error={float(self.error.max(initial=0)):g}, "
                f"inversions={len(self.inversions)}, advice={len(self.advice)})")

    def summary(self) -> dict:
        """The JSON summary of docs/json.md (``advice`` included)."""
        return {
            "pixels": int(self.error.size),
            "differing": self.differing,
            "max_error": float(self.error.max()) if self.error.size else 0.0,
            "mean_error": float(self.error.mean(dtype=np.float64)) if self.error.size else 0.0,
            "error_unit": "absolute" if self.hdr else "8-bit steps",
            "inversions": [inv.as_json() for inv in self.inversions],
            "advice": list(self.advice),
        }


#: Rows of the sort error computed at once (bounds its temporaries).
ERROR_ROWS = 256
#: :func:`reference_from_codes` converts a range of rows from the reference's codes when more
#: than one pixel in this many differs from the frame, else copies the frame's values and
#: replaces the pixels that differ (about 100 ns each against 2 ns a pixel for the conversion).
DIFFER_SHARE = 32


def reference_from_codes(frame_color: np.ndarray, frame: FrameBuffers, reference: FrameBuffers, pool=None,
                         parts: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(reference (H, W, 4) float32, :func:`sort_error` (H, W) float32) of two LDR buffers of one
    sample a pixel — the frame's, whose output is ``frame_color``, and the reference's — from their
    stored 8-bit codes: the frame's values where the codes agree, the reference's output and the
    largest code difference over RGBA (what ``rint(value * 255)`` recovers, every code checked by
    tests/explain) where they differ. ``pool`` / ``parts``: a thread pool to take row ranges on
    (the result does not depend on it)."""
    h, w = frame.height, frame.width
    out = np.empty_like(frame_color)
    error = np.empty((h, w), dtype=np.float32)
    mine, theirs = frame.packed(), reference.packed()
    out_pixels, error_pixels = out.reshape(-1, 4), error.reshape(-1)

    def rows(lo: int, hi: int) -> None:  # output rows [lo, hi): buffer rows [h - hi, h - lo)
        first, end = (h - hi) * w, (h - lo) * w
        differ = np.flatnonzero(mine[first:end] != theirs[first:end])
        error[lo:hi] = 0
        convert = differ.size * DIFFER_SHARE > end - first
        if convert:  # many differ: the reference's codes converted
            reference.output(band=(h - hi, h - lo), out=(out[lo:hi], None, None), color_only=True)
        else:  # few: the frame's values, those pixels replaced
            out[lo:hi] = frame_color[lo:hi]
        if not differ.size:
            return
        a = np.take(mine[first:end], differ).view(np.uint8).reshape(-1, 4)
        b = np.take(theirs[first:end], differ).view(np.uint8).reshape(-1, 4)
        at = differ // w  # buffer row h - hi + q is output row hi - 1 - q
        np.subtract(hi - 1, at, out=at)
        at *= w
        at += differ % w
        if not convert:
            out_pixels[at] = np.divide(b, np.float32(255), dtype=np.float32)  # as FrameBuffers.output
        steps = np.maximum(a, b)
        steps -= np.minimum(a, b)  # |a - b| without leaving 8 bits
        error_pixels[at] = largest_step(steps)

    run_parts(pool, parts, h, rows, min_part=64, piece=ERROR_ROWS)
    return out, error


def largest_step(steps: np.ndarray) -> np.ndarray:
    """(K,) the largest of each pixel's RGBA steps ``steps`` (K, 4), in their dtype: by columns (a
    reduction over the short axis costs more)."""
    return np.maximum(np.maximum(steps[:, 0], steps[:, 1]), np.maximum(steps[:, 2], steps[:, 3]))


def ldr_codes(values: np.ndarray) -> np.ndarray:
    """8-bit output values (float32, code / 255) → their codes as int16 (``rint(value · 255)``,
    exact for every code), as :func:`sort_error` compares them."""
    return np.rint(values * np.float32(255)).astype(np.int16)


def sort_error(frame_color: np.ndarray, reference: np.ndarray, hdr: bool, pool=None, parts: int = 1) -> np.ndarray:
    """(H, W) float32: the largest absolute difference over RGBA (8-bit steps on the codes for
    LDR); ``pool`` / ``parts``: a thread pool to take row ranges on."""
    out = np.empty(frame_color.shape[:2], dtype=np.float32)

    def rows(lo: int, hi: int) -> None:
        a, b = frame_color[lo:hi], reference[lo:hi]
        if hdr:
            diff = np.abs(a.astype(np.float64) - b.astype(np.float64))
        else:
            diff = np.abs(ldr_codes(a) - ldr_codes(b))
        out[lo:hi] = largest_step(diff.reshape(-1, 4)).reshape(hi - lo, -1)

    run_parts(pool, parts, out.shape[0], rows, min_part=ERROR_ROWS, piece=ERROR_ROWS)
    return out


def _overdraw_and_inverted(collector: FragmentCollector, inverted: np.ndarray, height: int, width: int,
                           pool=None, parts: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The analysis's per-pixel images, row 0 = top: overdraw (H, W, 2) uint32 (fragments
    rasterised, of them not written) from the collector's counts (whose ``unwritten`` becomes the
    written ones), and the inverted pairs ``inverted`` (H*W,) uint16 as (H, W); row ranges on ``pool``."""
    overdraw = np.empty((height, width, 2), dtype=np.uint32)
    flipped = np.empty((height, width), dtype=np.uint16)
    rasterised = collector.rasterised.reshape(height, width)
    unwritten = collector.unwritten.reshape(height, width)
    pixels = inverted.reshape(height, width)

    def rows(lo: int, hi: int) -> None:  # output rows [lo, hi): buffer rows [height - hi, height - lo)
        y0, y1 = height - hi, height - lo
        overdraw[lo:hi, :, 0] = rasterised[y0:y1][::-1]
        np.subtract(rasterised[y0:y1], unwritten[y0:y1], out=unwritten[y0:y1])
        overdraw[lo:hi, :, 1] = unwritten[y0:y1][::-1]
        flipped[lo:hi] = pixels[y0:y1][::-1]

    run_parts(pool, parts, height, rows, min_part=ERROR_ROWS, piece=ERROR_ROWS)
    return overdraw, flipped


def unit_fragments(collector: FragmentCollector, threads: int) -> int:
    """Fragments of the blocks processed together at most: :data:`WORK_FRAGMENTS`, fewer so
    that each thread has two units, at least :data:`UNIT_FRAGMENTS` (smaller units cost the
    per-unit work more often than they share it)."""
    total = int(collector.block_counts[collector.first_block:collector.limit].sum())
    return max(UNIT_FRAGMENTS, min(WORK_FRAGMENTS, total // (2 * threads)))


class LastBuffers(FrameObserver):
    """Keeps the buffers a render leaves at its last ``draw_end`` (with ``until_draw``, after that
    call), None when it drew no call; reads no fragment, so the calls are drawn as unobserved."""

    exact_boundaries = False
    reads_fragments = False
    per_sample = True  # reads the buffers only

    def __init__(self) -> None:
        self.buffers: FrameBuffers | None = None

    def draw_end(self, call, buffers, triangles) -> None:
        self.buffers = buffers


def lone_fragments_as_frame(calls: list[DrawCall], samples: int) -> bool:
    """Whether the reference may take the frame's colour at each pixel where the frame kept one
    fragment of queues 2501–3999 (:func:`.layering.group_by_pixel`): one sample a pixel, no Overlay
    draw after them (the frame's final colour would hold theirs, and they read the depth the
    transparent passes wrote), and no draw call of those queues that
    the collector does not keep writes anything (a ``ColorMask 0`` pass with ZWrite or stencil).
    There the frame applied that one fragment onto step 1's buffers with its own pass, as the
    reference does; its depth write changes no colour."""
    if samples != 1 or any(c.queue > LAST_SORTED_QUEUE for c in calls):
        return False
    return all(c.state.color_mask or (not c.state.zwrite and not c.state.stencil)
               for c in calls if is_sorted_queue(c.queue))


class _Blocks:
    """Step 2 and the inversion count of the blocks each pass keeps, by units of consecutive
    blocks (:func:`unit_fragments`), a unit on each of ``threads`` threads (numpy releases the GIL;
    units own disjoint pixels), at most ``threads`` units taken out of the store at once."""

    def __init__(self, calls: list[DrawCall], renderer_of_call: np.ndarray, renderers: int,
                 threads: int, should_cancel: Callable[[], bool] | None,
                 lone_from: FrameBuffers | None = None) -> None:
        self.by_index = {c.index: c for c in calls}
        #: The frame's final buffers when a pixel's lone fragment takes the frame's colour
        #: (:func:`lone_fragments_as_frame`), else None.
        self.lone_from = lone_from
        self.renderer_of_call = renderer_of_call
        self.renderers = renderers
        sorted_per_renderer = np.bincount(
            [renderer_of_call[c.index] for c in calls if is_sorted_queue(c.queue) and c.state.color_mask],
            minlength=renderers)
        # One sorted draw call per renderer: each (pixel, front, behind) is found once.
        self.exact_keys = bool(np.all(sorted_per_renderer <= 1))
        self.threads = threads
        self.should_cancel = should_cancel
        self.rows_finished = 0

    def run(self, collector: FragmentCollector, buf: FrameBuffers):
        """Yield (first window pixel, pixels (K,) int64 from it with inverted pairs, their
        counts (K,) int64, pair ids, their pixels) of each block ``collector`` kept, its
        reference rows applied onto ``buf``."""
        palettes = {index: collector.palette(index) for index in collector.palettes}
        blender = layering.ReferenceBlender(buf, self.by_index, collector.sorted_calls, palettes,
                                            dict(collector.call_fragments))
        self.rows_finished = 0

        def one(unit: list[int]):
            parts = []
            for block in collector.take(unit, TAKE_FRAGMENTS):
                if self.should_cancel is not None and self.should_cancel():
                    raise RenderCancelled("render cancelled")
                parts.append(self._block(block, len(unit) * collector.block_pixels, blender))  # unit's pixels
            joined = [np.concatenate(p) if p else np.zeros(0, np.int64) for p in zip(*parts, strict=True)]
            return unit[-1], (unit[0] * collector.block_pixels, *(joined or [np.zeros(0, np.int64)] * 4))

        with ThreadPoolExecutor(max_workers=self.threads) as pool:
            for b, out in pool.map(one, collector.units(unit_fragments(collector, self.threads))):
                self.rows_finished = collector.rows_of(b)[1] - collector.rows_of(collector.first_block)[0]
                yield out

    def _block(self, block, block_pixels: int, blender: layering.ReferenceBlender):
        """Step 2 and the inverted pairs of a :class:`.fragment_store.Block` (a unit, or a range of
        its pixels; ``block_pixels``: the unit's pixels): (its pixels with inverted pairs (K,)
        int64, their counts (K,) int64, pair ids, their pixels)."""
        pixels, counts, starts, lone = layering.group_by_pixel(block, block_pixels, self.lone_from is not None)
        if lone.size:
            lone += block.start
            blender.keep_frame(lone, self.lone_from)
        del lone
        group, ids = blender.colour_ids(block)
        inverted, inverted_at, pair_ids, pair_pixels = [], [], [], []
        for p0, p1 in pixel_ranges(counts, WORK_FRAGMENTS):
            f0, f1 = int(starts[p0]), int(starts[p1 - 1] + counts[p1 - 1])
            order, bounds = layering.far_to_near_layers(counts[p0:p1], starts[p0:p1] - f0, block.depth(slice(f0, f1)))
            blender.apply(block, group, ids, order, bounds, f0)
            del order
            per_pixel, found, tally = layering.block_inversions(block, f0, f1, counts[p0:p1], self.renderer_of_call,
                                                                self.renderers, self.exact_keys)
            some = np.flatnonzero(per_pixel)
            inverted_at.append(pixels[p0 + some])
            inverted.append(per_pixel[some])
            pair_ids.append(found)
            pair_pixels.append(tally)
        return tuple(np.concatenate(p) if p else np.zeros(0, dtype=np.int64)
                     for p in (inverted_at, inverted, pair_ids, pair_pixels))


def analyze(
    scene: DrawScene,
    *,
    workers: int | None = None,
    progress: Callable[[float], None] | None = None,
    should_cancel: Callable[[], bool] | None = None,
    memory: int | None = None,
    memory_limit: int | None = None,
    keep_step1: bool = False,
) -> Analysis:
    """Render ``scene`` and its sorted reference; sort error, inversions, overdraw (docs/sorting.md).

    ``memory``: the budget of kept fragments in bytes (default :data:`FRAGMENT_BUDGET`, lowered
    to what ``memory_limit`` leaves); ``memory_limit``: the bytes the analysis may use (default:
    what the system has available), see :func:`memory_bound`. ``keep_step1``: keep a copy of the
    step-1 buffers in the result (advice resumes from them). ``progress(fraction)`` and
    ``should_cancel()`` as for :func:`~blendlib.core.pipeline.render_scene`, over every phase.

    The result's ``advice`` is empty: advice is checked on top of an analysis
    (:func:`blendlib.explain.advice.analyze_and_advise`). Raises
    :class:`~blendlib.core.scene.SceneError` for input that cannot render or a frame too large
    for the memory (before anything is rendered), :class:`~blendlib.core.records.RenderCancelled`
    when cancelled.
    """
    validate_scene(scene)  # one-line SceneError before anything is allocated
    calls = draw_calls(scene)
    cam = scene.camera
    width, height = int(cam.width), int(cam.height)
    threads = processing_threads(workers)
    budget = fragment_budget(width, height, bool(scene.hdr), memory, memory_limit, keep_step1, threads,
                             int(scene.msaa))
    bar = Progress(progress)
    renderers = list(dict.fromkeys((c.renderer.name, c.renderer.slot) for c in calls))
    rend_index = {key: k for k, key in enumerate(renderers)}
    nrend = max(len(renderers), 1)
    renderer_of_call = np.zeros(len(calls) + 1, dtype=np.int64)
    for c in calls:
        renderer_of_call[c.index] = rend_index[(c.renderer.name, c.renderer.slot)]
    samples = int(scene.msaa)
    # Advice may reorder the opaque calls: is their order free?
    order_calls = opaque_order_calls(calls, bool(scene.hdr), samples) if keep_step1 else frozenset()
    collector = counts = FragmentCollector(calls, width, height, budget, samples=samples, order_calls=order_calls)
    call_boxes = collector.call_boxes
    frame = render_scene(scene, observer=collector, workers=workers, progress=bar.part(0.0, 0.4),
                         should_cancel=should_cancel, calls=calls)
    opaque_order_free = collector.opaque_order_free()
    inverted = np.zeros(width * height, dtype=np.uint16)
    pair_counts: dict[int, int] = {}
    step1 = error = reference = buf = None
    if not any(is_sorted_queue(c.queue) for c in calls):
        reference = frame.color.copy()
        error = np.zeros((height, width), dtype=np.float32)
    else:
        buf = collector.step1
        step1 = buf.copy(colors_only=collector.step1_shares_depth) if keep_step1 else None  # depth unwritten: shared
        blocks = _Blocks(calls, renderer_of_call, nrend, threads, should_cancel,
                         counts.final if lone_fragments_as_frame(calls, samples) else None)
        while True:
            rows_before = collector.rows_of(collector.first_block)[0]
            for start, at, per_pixel, ids, tally in blocks.run(collector, buf):
                at += start
                if samples > 1:  # per sample index: a pixel's most inverted sample
                    pixels, which = np.unique(at // samples, return_inverse=True)
                    most = np.zeros(pixels.size, dtype=np.int64)
                    np.maximum.at(most, which, per_pixel)
                    inverted[pixels] = most
                else:
                    inverted[at] = per_pixel
                for pair, count in zip(ids.tolist(), tally.tolist(), strict=True):
                    pair_counts[pair] = pair_counts.get(pair, 0) + count
                bar(0.4 + 0.55 * (rows_before + blocks.rows_finished) / height)
            if collector.limit >= collector.block_count:
                break
            # The rows above the blocks kept: another pass renders them alone and keeps what fits.
            first = collector.limit
            collector = FragmentCollector(calls, width, height, budget, first_block=first, overdraw=False,
                                          samples=samples)
            render_scene(scene, observer=collector, workers=workers, should_cancel=should_cancel, calls=calls,
                         band=(collector.rows_of(first)[0], height))
        bar(0.95)
        last_sorted = max(c.index for c in calls if c.queue <= LAST_SORTED_QUEUE)
        overlay = any(c.queue > LAST_SORTED_QUEUE for c in calls)
        if overlay and (scene.hdr or samples > 1):
            reference = render_scene(scene, resume=(buf, last_sorted), workers=workers, calls=calls,
                                     should_cancel=should_cancel).color
            buf = None
        elif overlay:  # the Overlay draws' codes, compared
            last = LastBuffers()
            render_scene(scene, resume=(buf, last_sorted), workers=workers, calls=calls,
                         should_cancel=should_cancel, observer=last, output=False)
            buf = last.buffers  # the reference's buffers after the Overlay draws
    final_codes = None
    if keep_step1 and not scene.hdr and samples == 1 and counts.final is not None:
        final_codes = counts.final.color  # the frame's own buffers: not written again
    # The passes over whole frames that remain: row ranges on both threads (numpy releases the GIL).
    with ThreadPoolExecutor(max_workers=threads) if threads > 1 else contextlib.nullcontext() as pool:
        if buf is not None:  # the reference's buffers, not output yet
            if scene.hdr or samples > 1:  # HDR values; MSAA: the samples resolved as the frame's
                reference = buf.output(pool, threads, color_only=True)[0]
            else:  # 8-bit codes, compared
                reference, error = reference_from_codes(frame.color, counts.final, buf, pool, threads)
            buf = None
        overdraw, flipped = _overdraw_and_inverted(counts, inverted, height, width, pool, threads)
        if error is None:
            error = sort_error(frame.color, reference, scene.hdr, pool, threads)
    del counts, collector
    inversions = [Inversion(renderers[pair // nrend], renderers[pair % nrend], count)
                  for pair, count in pair_counts.items()]
    inversions.sort(key=lambda inv: (-inv.pixels, inv.front, inv.behind))
    bar(1.0)
    return Analysis(frame=frame, reference=reference, error=error, overdraw=overdraw, inverted=flipped,
                    inversions=inversions, hdr=bool(scene.hdr), step1=step1, call_boxes=call_boxes,
                    opaque_order_free=opaque_order_free, final_codes=final_codes)
