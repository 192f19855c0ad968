"""The sorted reference, sort errors, inversions and overdraw (docs/sorting.md), vectorised.

One observed render of the scene gives everything: the frame as drawn, the buffers after the
last draw of queue ≤ 2500 (step 1), every fragment of queues 2501–3999 that survived culling
and the alpha test (with whether the frame wrote it) and the per-pixel fragment counts.
Step 2 applies the kept fragments per pixel far to near — one stable sort by (pixel, depth
code descending) of the fragments in draw order, so ties keep draw order then primitive
order — layer by layer (layer k = the k-th fragment of every pixel, distinct pixels) with
:func:`blendlib.core.merger.apply_layer`, each layer's fragments grouped by draw call so each
goes through its own pass's stencil, depth test (against step 1's depth: nothing writes depth
in step 2), blending and ColorMask. Step 3 resumes the pipeline from those buffers for the
Overlay draws.

Memory is bounded by screen bands: fragments are stored compactly as they arrive (pixel,
depth code, draw call, colour key: 14 bytes, colours kept once per triangle where the
shader output is constant) in blocks of rows, and step 2 and the inversion count run one
band of blocks at a time.

Passes with ColorMask 0 write nothing in step 2 (no colour, no depth, no stencil): they are
left out of it and of the inversion counts.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np

from ..core.drawlist import DrawCall, draw_calls
from ..core.merger import BlendTable, FrameBuffers, Outcome, apply_layer, blend_lut, layers_by_rank
from ..core.pipeline import render_scene
from ..core.records import Frame, FrameObserver, RenderCancelled, ShadedFragments
from ..core.scene import DrawScene, validate_scene
from ..core.vertex import DEPTH_MAX
from ..core.vocabulary import LAST_OPAQUE_QUEUE, QUEUE_NUMBERS, Queue

#: Queues sorted per fragment in step 2: from the first transparent queue up to Overlay − 1.
FIRST_SORTED_QUEUE = LAST_OPAQUE_QUEUE + 1
LAST_SORTED_QUEUE = QUEUE_NUMBERS[Queue.Overlay] - 1
#: Rows per storage block (fragments are bucketed by block as they arrive).
BLOCK_ROWS = 32
#: Fragments per processing band (step 2 and inversions): bounds the sort's working memory.
BAND_FRAGMENTS = 6_000_000


def is_sorted_queue(queue: int) -> bool:
    """Whether a draw call of this queue is applied per fragment in step 2 (2501–3999)."""
    return FIRST_SORTED_QUEUE <= queue <= LAST_SORTED_QUEUE


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


class _Collector(FrameObserver):
    """Observes one render: step-1 snapshot, overdraw counts, the sorted-range fragments (compact)."""

    def __init__(self, calls: list[DrawCall], width: int, height: int) -> None:
        self.width, self.height = width, height
        n = width * height
        self.rasterised = np.zeros(n, dtype=np.uint32)
        self.written = np.zeros(n, dtype=np.uint32)
        self.sorted_calls = {c.index for c in calls if is_sorted_queue(c.queue) and c.state.color_mask}
        firsts = [c.index for c in calls if c.queue > LAST_OPAQUE_QUEUE]
        self.first_after_opaque = min(firsts) if firsts else None
        self.step1: FrameBuffers | None = None
        self.final: FrameBuffers | None = None
        self.lock = threading.Lock()
        self.block_pixels = BLOCK_ROWS * width
        self.blocks: list[list[tuple]] = [[] for _ in range((height + BLOCK_ROWS - 1) // BLOCK_ROWS)]
        self.block_counts = np.zeros(len(self.blocks), dtype=np.int64)
        self.palettes: dict[int, list[np.ndarray]] = {}  # call → palettes (constant triangle colours)
        self.palette_size: dict[int, int] = {}
        self.table: list[np.ndarray] = []  # float64 (K, 4) colours of the other fragments
        self.table_size = 0
        self.call_dtype = np.uint16 if len(calls) < 65535 else np.int32

    def draw_begin(self, call, buffers) -> None:
        if call.index == self.first_after_opaque:
            self.step1 = buffers.copy()

    def draw_end(self, call, buffers, triangles) -> None:
        self.final = buffers

    def fragments(self, call: DrawCall, frags: ShadedFragments, outcome: np.ndarray) -> None:
        pix = frags.pix
        lo, hi = int(pix.min()), int(pix.max())
        # Bands of the pipeline own disjoint row ranges, so these slices never overlap between threads.
        self.rasterised[lo:hi + 1] += np.bincount(pix - lo, minlength=hi - lo + 1).astype(np.uint32)
        wrote = outcome == Outcome.WRITTEN
        if wrote.any():
            wp = pix[wrote]
            self.written[lo:hi + 1] += np.bincount(wp - lo, minlength=hi - lo + 1).astype(np.uint32)
        if call.index not in self.sorted_calls:
            return
        if frags.alive is not None:
            frags = frags.select(frags.alive)
            wrote = wrote[outcome != Outcome.ALPHA_TEST]
            if frags.count == 0:
                return
        key = self._colour_keys(call.index, frags)
        pix32 = frags.pix.astype(np.int32)
        depth32 = frags.depth.astype(np.int32)
        block = frags.pix // self.block_pixels
        b0, b1 = int(block[0]), int(block.max())
        calls = np.full(frags.count, call.index, dtype=self.call_dtype)
        if b0 == b1 and int(block.min()) == b0:
            parts = [(b0, slice(None))]
        else:
            order = np.argsort((block - block.min()).astype(np.uint16), kind="stable")
            sb = block[order]
            cuts = np.flatnonzero(sb[1:] != sb[:-1]) + 1
            bounds = np.concatenate([[0], cuts, [sb.size]])
            parts = [(int(sb[a]), order[a:b]) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        pieces = [(b, (pix32[s], depth32[s], calls[s], key[s], wrote[s])) for b, s in parts]
        with self.lock:
            for b, piece in pieces:
                self.blocks[b].append(piece)
                self.block_counts[b] += piece[0].size

    def _colour_keys(self, index: int, frags: ShadedFragments) -> np.ndarray:
        """(N,) int32: ≥ 0 an entry of the call's palette, < 0 the table row ``-1 - key``."""
        n = frags.count
        key = np.empty(n, dtype=np.int32)
        if frags.ids is not None:
            tabled = frags.ids >= 0
            with self.lock:
                offset = self.palette_size.get(index, 0)
                self.palettes.setdefault(index, []).append(frags.palette)
                self.palette_size[index] = offset + frags.palette.shape[0]
            key[tabled] = frags.ids[tabled] + offset
            rest = np.flatnonzero(~tabled)
        else:
            rest = None
        if frags.rgba is None:  # every colour is a palette entry
            rows = np.empty((0, 4), dtype=np.float64)
        else:
            rows = frags.rgba if rest is None else frags.rgba[rest]
        if rows.shape[0]:
            # Consecutive fragments of a constant-colour triangle share one table row.
            new = np.ones(rows.shape[0], dtype=bool)
            new[1:] = (rows[1:] != rows[:-1]).any(axis=1)
            run = np.cumsum(new) - 1
            unique = rows[new]
            with self.lock:
                offset = self.table_size
                self.table.append(unique)
                self.table_size += unique.shape[0]
            codes = (-1 - (offset + run)).astype(np.int32)
            if rest is None:
                key[:] = codes
            else:
                key[rest] = codes
        return key

    def bands(self) -> list[list[int]]:
        """Consecutive blocks grouped into bands of at most about BAND_FRAGMENTS fragments."""
        out: list[list[int]] = []
        current: list[int] = []
        total = 0
        for b, count in enumerate(self.block_counts.tolist()):
            if count == 0:
                continue
            if current and total + count > BAND_FRAGMENTS:
                out.append(current)
                current, total = [], 0
            current.append(b)
            total += count
        if current:
            out.append(current)
        return out

    def take_band(self, blocks: list[int]) -> tuple[np.ndarray, ...]:
        """Concatenate (and free) the pieces of ``blocks``: pix, depth, call, key, written."""
        pieces = [p for b in blocks for p in self.blocks[b]]
        for b in blocks:
            self.blocks[b] = []
        pix, depth, call, key, written = (np.concatenate([p[k] for p in pieces]) for k in range(5))
        return pix.astype(np.int64), depth.astype(np.int64), call, key, written


class _Step2:
    """Applies a band's fragments far to near with their passes' state (no depth writes).

    Draw calls whose passes have the same state share one group: one blend table over their
    palettes laid end to end, so a layer costs one merge per distinct state, not one per draw
    call (a layer's fragments lie on distinct pixels, so the grouping cannot change the result).
    """

    def __init__(self, collector: _Collector, calls: dict[int, DrawCall], buf: FrameBuffers) -> None:
        self.c = collector
        self.buf = buf
        self.table = np.concatenate(collector.table) if collector.table else np.zeros((0, 4), np.float64)
        size = max(calls, default=0) + 1
        self.group_of_call = np.zeros(size, dtype=np.int64)
        self.base_of_call = np.zeros(size, dtype=np.int64)  # offset of the call's palette in its group's
        self.group_pass: list = []
        self.group_calls: list[list[int]] = []
        groups: dict = {}
        filled: list[int] = []
        for index in sorted(collector.sorted_calls):
            state = replace(calls[index].state, zwrite=False)
            g = groups.setdefault(state, len(groups))
            if g == len(self.group_pass):
                self.group_pass.append(state)
                self.group_calls.append([])
                filled.append(0)
            self.group_of_call[index] = g
            self.base_of_call[index] = filled[g]
            self.group_calls[g].append(index)
            filled[g] += collector.palette_size.get(index, 0)
        self.luts: dict[int, BlendTable] = {}
        self.lock = threading.Lock()

    def lut(self, group: int) -> BlendTable:
        with self.lock:  # bands run on two threads: build each table once
            if group not in self.luts:
                palette = np.concatenate([p for i in self.group_calls[group] for p in self.c.palettes.get(i, ())])
                self.luts[group] = BlendTable(blend_lut(self.buf, self.group_pass[group], palette))
            return self.luts[group]

    def apply_band(self, pix, depth, call, key, written) -> np.ndarray:
        """Apply a band (arrays in draw order, ``pix``/``depth`` int64); returns the pixels (sorted,
        unique) where the written fragments were not applied far to near (candidates for inversions)."""
        lo = int(pix.min())
        sort_key = ((pix - lo) << 24) | (DEPTH_MAX - depth)
        order = np.argsort(sort_key, kind="stable")  # far first; ties keep draw then primitive order
        del sort_key
        # In sorted order, a written fragment that arrived before its farther predecessor = an inversion.
        w = order[written[order]]
        wp = pix[w]
        descent = (wp[1:] == wp[:-1]) & (w[1:] < w[:-1])
        suspects = np.unique(wp[1:][descent])
        del w, wp, descent
        layers = layers_by_rank(order, pix[order])  # layer k: the k-th farthest fragment of each pixel
        del order
        for sel in layers:
            self.apply_layer(pix[sel], depth[sel], call[sel], key[sel])
        return suspects

    def apply_layer(self, pix, depth, call, key) -> None:
        group = self.group_of_call[call]
        first, last = int(group.min()), int(group.max())
        if first == last:
            groups = [(first, slice(None))]
        else:
            order = np.argsort(group, kind="stable")
            sg = group[order]
            cuts = np.flatnonzero(sg[1:] != sg[:-1]) + 1
            bounds = np.concatenate([[0], cuts, [sg.size]])
            groups = [(int(sg[a]), order[a:b]) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        for g, sel in groups:
            k = key[sel]
            n = k.size
            tabled = k >= 0
            rgba = np.empty((n, 4), dtype=np.float64)
            ids = lut = None
            if tabled.any():
                ids = np.where(tabled, k + self.base_of_call[call[sel]], -1).astype(np.int32)
                lut = self.lut(g)
                plain = ~tabled
                if plain.any():
                    rgba[plain] = self.table[-1 - k[plain].astype(np.int64)]
            else:
                rgba = self.table[-1 - k.astype(np.int64)]
            apply_layer(self.buf, self.group_pass[g], pix[sel], depth[sel], rgba, ids, lut)


def _band_inversions(pix, depth, call, written, renderer_of_call: np.ndarray, nrend: int) -> np.ndarray:
    """Unique keys ``(pixel * R + front) * R + behind`` of the pairs inverted in a band.

    Among the written fragments of a pixel in the order the frame applied them, (A, B) scores
    when a fragment of A precedes a farther (larger depth code) fragment of B. Consecutive
    fragments of one draw call form a run: inside a run that holds iff two neighbours ascend
    in depth; between runs iff the earlier run's nearest fragment is nearer than the later
    run's farthest. Only runs preceded by a nearer fragment are paired with their predecessors,
    so a well-sorted frame costs one pass.
    """
    w = np.flatnonzero(written)
    if w.size == 0:
        return np.zeros(0, dtype=np.int64)
    idx = w[np.argsort(pix[w], kind="stable")]
    p = pix[idx].astype(np.int64)
    d = depth[idx].astype(np.int64)
    c = call[idx]
    r = renderer_of_call[c].astype(np.int64)
    same_call = (p[1:] == p[:-1]) & (c[1:] == c[:-1])
    found = []
    ascent = np.flatnonzero(same_call & (d[:-1] < d[1:])) + 1
    if ascent.size:
        found.append((p[ascent] * nrend + r[ascent]) * nrend + r[ascent])
    run_start = np.ones(p.size, dtype=bool)
    run_start[1:] = ~same_call
    starts = np.flatnonzero(run_start)
    run_pix, run_r = p[starts], r[starts]
    run_min = np.minimum.reduceat(d, starts)
    run_max = np.maximum.reduceat(d, starts)
    seg_start = np.ones(starts.size, dtype=bool)
    seg_start[1:] = run_pix[1:] != run_pix[:-1]
    seg = np.cumsum(seg_start) - 1
    big = np.int64(1 << 25)  # > every depth code: a segmented running minimum by offsets
    inclusive = np.minimum.accumulate(run_min - seg * big) + seg * big
    before = np.full(starts.size, big, dtype=np.int64)
    before[1:] = np.where(seg_start[1:], big, inclusive[:-1])
    q = np.flatnonzero(before < run_max)
    t = 1
    while q.size:
        a = q - t
        ok = a >= 0
        ok[ok] = seg[a[ok]] == seg[q[ok]]
        q, a = q[ok], a[ok]
        hit = run_min[a] < run_max[q]
        if hit.any():
            found.append((run_pix[q[hit]] * nrend + run_r[a[hit]]) * nrend + run_r[q[hit]])
        t += 1
    if not found:
        return np.zeros(0, dtype=np.int64)
    return np.unique(np.concatenate(found))


def sort_error(frame_color: np.ndarray, reference: np.ndarray, hdr: bool) -> np.ndarray:
    """(H, W) float32: the largest absolute difference over RGBA (8-bit steps on the codes for LDR)."""
    if hdr:
        diff = np.abs(frame_color.astype(np.float64) - reference.astype(np.float64))
    else:
        diff = np.abs(np.rint(frame_color * np.float32(255)).astype(np.int16)
                      - np.rint(reference * np.float32(255)).astype(np.int16))
    return diff.max(axis=-1).astype(np.float32)


def analyze(
    scene: DrawScene,
    *,
    workers: int | None = None,
    progress: Callable[[float], None] | None = None,
    should_cancel: Callable[[], bool] | None = None,
) -> Analysis:
    """Render ``scene`` and its sorted reference; sort error, inversions, overdraw (docs/sorting.md).

    The result's ``advice`` is empty: advice is checked on top of an analysis
    (:func:`blendlib.explain.advice.analyze_and_advise`). Raises
    :class:`~blendlib.core.scene.SceneError` for input that cannot render,
    :class:`~blendlib.core.records.RenderCancelled` when cancelled.
    """
    validate_scene(scene)  # one-line SceneError before anything is allocated
    calls = draw_calls(scene)
    cam = scene.camera
    width, height = int(cam.width), int(cam.height)
    collector = _Collector(calls, width, height)
    frame = render_scene(scene, observer=collector, workers=workers, progress=progress,
                         should_cancel=should_cancel, calls=calls)
    n = width * height
    inverted = np.zeros(n, dtype=np.uint16)
    pair_counts: dict[int, int] = {}
    renderers = list(dict.fromkeys((c.renderer.name, c.renderer.slot) for c in calls))
    rend_index = {key: k for k, key in enumerate(renderers)}
    nrend = max(len(renderers), 1)
    renderer_of_call = np.zeros(len(calls) + 1, dtype=np.int64)
    for c in calls:
        renderer_of_call[c.index] = rend_index[(c.renderer.name, c.renderer.slot)]
    if not any(is_sorted_queue(c.queue) for c in calls):
        reference = frame.color.copy()
    else:
        buf = collector.step1
        by_index = {c.index: c for c in calls}
        step2 = _Step2(collector, by_index, buf)

        def band_inversions(blocks: list[int]) -> np.ndarray:
            """Step 2 of one band (its pixels are its own), then its inverted pairs' keys."""
            if should_cancel is not None and should_cancel():
                raise RenderCancelled("render cancelled")
            pix, depth, call, key, wrote = collector.take_band(blocks)
            suspects = step2.apply_band(pix, depth, call, key, wrote)
            del key
            if not suspects.size:
                return np.zeros(0, dtype=np.int64)
            lo = int(suspects[0])
            marked = np.zeros(int(suspects[-1]) - lo + 1, dtype=bool)
            marked[suspects - lo] = True
            inside = (pix >= lo) & (pix <= int(suspects[-1]))
            inside[inside] = marked[pix[inside] - lo]
            wrote &= inside
            return _band_inversions(pix, depth, call, wrote, renderer_of_call, nrend)

        # Bands own disjoint pixels: two at a time on the two cores (numpy releases the GIL),
        # at most ``threads`` bands' fragments in memory at once.
        threads = workers if workers is not None else min(2, os.cpu_count() or 1)
        with ThreadPoolExecutor(max_workers=max(1, threads)) as pool:
            for keys in pool.map(band_inversions, collector.bands()):
                if keys.size:
                    pixel = keys // (nrend * nrend)
                    np.add.at(inverted, pixel, 1)
                    pairs, counts = np.unique(keys % (nrend * nrend), return_counts=True)
                    for pair, count in zip(pairs.tolist(), counts.tolist(), strict=True):
                        pair_counts[pair] = pair_counts.get(pair, 0) + count
        last_sorted = max(c.index for c in calls if c.queue <= LAST_SORTED_QUEUE)
        if any(c.queue > LAST_SORTED_QUEUE for c in calls):
            reference = render_scene(scene, resume=(buf, last_sorted), workers=workers, calls=calls).color
        else:
            reference = buf.output()[0]
    overdraw = np.stack([collector.rasterised, collector.written], axis=-1).reshape(height, width, 2)[::-1].copy()
    inversions = [Inversion(renderers[pair // nrend], renderers[pair % nrend], count)
                  for pair, count in pair_counts.items()]
    inversions.sort(key=lambda inv: (-inv.pixels, inv.front, inv.behind))
    return Analysis(frame=frame, reference=reference, error=sort_error(frame.color, reference, scene.hdr),
                    overdraw=overdraw, inverted=inverted.reshape(height, width)[::-1].copy(),
                    inversions=inversions, hdr=bool(scene.hdr))
