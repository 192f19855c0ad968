"""The kept fragments of the sorted reference (docs/sorting.md "Cost"): an observer that stores every
fragment of queues 2501–3999 compactly, by blocks of rows, within a memory budget.

A render hands its fragments over chunk by chunk (:class:`~blendlib.core.records.FrameObserver`);
:class:`FragmentCollector` keeps those of the sorted calls (queue 2501–3999, ColorMask not 0) that
survived the alpha test, split by **block** — a run of whole rows of at most
:data:`BLOCK_PIXELS` pixels, so a pixel within its block fits 16 bits — in the order they arrive,
which at each pixel is the order the frame applied them. Per fragment it keeps 12 bytes:

- ``local`` uint16: the pixel within its block (``pixel - block * block_pixels``);
- ``depth_written`` uint32: the 24-bit depth code, bit 31 set when the frame wrote the fragment;
- ``call`` uint16 (int32 beyond 65535 draw calls): the draw call;
- ``key`` int32: its colour — ``k >= 0`` entry ``k`` of the call's palette (constant-colour
  triangles, one entry per triangle colour, kept once per call), ``k < 0`` row ``-1 - k`` of its
  piece's colour table (per-fragment colours, consecutive equal colours stored once: 32 bytes).

**Budget.** The collector counts the bytes it holds (pieces, colour tables, palettes). Past
``budget`` it drops the highest stored block and stores no more fragments of the rows above it
(never the first block of the pass, so each pass makes progress): the blocks it keeps,
``[first_block, limit)``, are complete. The rows it dropped are collected by the next pass, a
render of those rows only (:func:`blendlib.core.pipeline.render_scene`'s ``band``).
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..core.drawlist import DrawCall, writes_depth_or_stencil
from ..core.gather import gather
from ..core.merger import FrameBuffers, Outcome
from ..core.records import FrameObserver, ShadedFragments
from ..core.vocabulary import LAST_OPAQUE_QUEUE, QUEUE_NUMBERS, BlendFactor, BlendOp, CompareFunction, Pass, Queue

#: Queues sorted per fragment in step 2: from the first transparent queue up to Overlay − 1.
FIRST_SORTED_QUEUE = LAST_OPAQUE_QUEUE + 1
LAST_SORTED_QUEUE = QUEUE_NUMBERS[Queue.Overlay] - 1
#: Pixels per storage block at most (whole rows; one row when a row is wider): a pixel's place in
#: its block fits 16 bits, and a block is the unit of storage, of eviction and of processing.
BLOCK_PIXELS = 1 << 15
#: Pixels of the blocks processed together as one unit at most (:meth:`FragmentCollector.units`).
UNIT_PIXELS = 1 << 20
#: Bytes kept per fragment (local pixel 2, depth and written 4, draw call 2, colour key 4).
FRAGMENT_BYTES = 12
#: Bytes of a colour (RGBA float64) in a palette or a colour table.
COLOR_BYTES = 32
#: Bit of ``depth_written`` that marks a fragment the frame wrote.
WRITTEN_BIT = np.uint32(1 << 31)
DEPTH_MASK = np.uint32((1 << 24) - 1)


def is_sorted_queue(queue: int) -> bool:
    """Whether a draw call of this queue is applied per fragment in step 2 (2501–3999)."""
    return FIRST_SORTED_QUEUE <= queue <= LAST_SORTED_QUEUE


#: Depth keys of opaque fragments kept at most to prove the opaque queue's order free
#: (:meth:`FragmentCollector.opaque_order_free`; 8 bytes each): past it the proof is given up.
ORDER_KEYS = 1 << 23


def writes_nearest(p: Pass, hdr: bool) -> bool:
    """Whether a pass leaves at each pixel what its nearest fragment carries, whatever the
    buffers held: ZWrite On, ZTest Less or LEqual, no stencil, and its colour the fragment's own —
    Blend Off, or in 8-bit buffers ``Blend One Zero`` with ``BlendOp Add`` (``s·1 + d·0`` is ``s``
    exactly for the finite ``d`` of a stored code; an HDR ``d`` may be infinite) — its alpha
    the same, or ``Max``/``Min`` of the fragment's and the stored one (:func:`alpha_extreme`).
    Opaque draw calls of such passes, with one ColorMask and one alpha operation, no two of which
    put a fragment at one pixel with one depth code, leave the same buffers in any order of the
    calls (:meth:`FragmentCollector.opaque_order_free`)."""
    if p.stencil or not p.zwrite or p.ztest not in (CompareFunction.Less, CompareFunction.LEqual):
        return False
    if not p.blend:
        return True
    source = (BlendFactor.One, BlendFactor.Zero, BlendOp.Add)
    return (not hdr and (p.src_blend, p.dst_blend, p.blend_op) == source
            and (tuple(p.alpha_factors) == source or alpha_extreme(p) is not None))


def alpha_extreme(p: Pass) -> BlendOp | None:
    """``Max`` or ``Min`` when a pass blends alpha by that operation (the stored alpha becomes
    the larger or smaller of the fragment's and its own, the factors unused), else None. Written
    any number of times in any order by fragments of one alpha ``A`` it ends as ``op(A, clear)``
    (in 8-bit codes too: a code read back and compared again gives itself)."""
    op = p.alpha_factors[2] if p.blend else None
    return op if op in (BlendOp.Max, BlendOp.Min) else None


def opaque_order_calls(calls: list[DrawCall], hdr: bool, samples: int) -> frozenset[int]:
    """The opaque draw calls (queue ≤ 2500) whose order :meth:`FragmentCollector.opaque_order_free`
    may prove free: all of them when there are two or more, one sample a pixel, every pass
    :func:`writes_nearest` and all share one ColorMask and one alpha operation; else none."""
    opaque = [c for c in calls if c.queue <= LAST_OPAQUE_QUEUE]
    if (samples != 1 or len(opaque) < 2 or len({(c.state.color_mask, alpha_extreme(c.state)) for c in opaque}) > 1
            or not all(writes_nearest(c.state, hdr) for c in opaque)):
        return frozenset()
    return frozenset(c.index for c in opaque)


def block_rows(width: int) -> int:
    """Rows per block for frames ``width`` pixels wide (at least one)."""
    return max(1, BLOCK_PIXELS // max(1, int(width)))


@dataclass(eq=False)
class Block:
    """The kept fragments of one block (the arrays as stored, module doc), in the order the frame
    applied them at each pixel.

    ``local`` (N,) uint16 (int32 in a unit of more than 65536 pixels); ``depth_written`` (N,)
    uint32 (:data:`DEPTH_MASK`, :data:`WRITTEN_BIT`);
    ``call`` (N,) uint16 or int32; ``key`` (N,) int32 colour keys, table rows renumbered into
    ``table`` (K, 4) float64 (row ``-1 - key`` for ``key < 0``). ``start``: the block's first
    window pixel (``pixel = start + local``)."""

    index: int
    start: int
    local: np.ndarray
    depth_written: np.ndarray
    call: np.ndarray
    key: np.ndarray
    table: np.ndarray

    @property
    def count(self) -> int:
        return int(self.local.shape[0])

    def depth(self, index=slice(None)) -> np.ndarray:
        """(M,) int64 depth codes of fragments ``index``."""
        return (self.depth_written[index] & DEPTH_MASK).astype(np.int64)

    def written(self, index=slice(None)) -> np.ndarray:
        """(M,) bool: the frame wrote fragments ``index``."""
        return self.depth_written[index] >= WRITTEN_BIT


class FragmentCollector(FrameObserver):
    """Observes one render: per-pixel overdraw counts and the step-1 buffers (``overdraw``:
    the first pass), and the sorted calls' fragments of blocks ``[first_block, limit)``
    within ``budget`` bytes (module doc).

    ``rasterised``, ``unwritten`` (H*W,) uint32 per window pixel: fragments rasterised, and
    those not written (with ``overdraw``); ``step1``:
    a copy of the buffers before the first draw call of a queue above 2500 (None when there is
    none, or without ``overdraw``).

    With MSAA (``samples`` N > 1) each sample is a pixel of its own for the sort (docs/sorting.md):
    a pixel fragment becomes one kept fragment per sample it reached (covered, past AlphaToMask,
    the alpha test passed) with that sample's depth code, at the *sample index* ``p*N + s`` —
    the pixels of a frame N times as wide, so blocks stay whole rows. The overdraw counts stay per
    window pixel and count pixel fragments (the draw list's ``fragments``): rasterised when a
    sample is covered, unwritten when no sample was written."""

    per_sample = True

    def __init__(self, calls: list[DrawCall], width: int, height: int, budget: int, *,
                 first_block: int = 0, overdraw: bool = True, samples: int = 1,
                 order_calls: frozenset[int] = frozenset()) -> None:
        self.samples = int(samples)
        self.width, self.height = int(width) * self.samples, int(height)  # width in samples
        self.rows_per_block = block_rows(self.width)
        self.block_pixels = self.rows_per_block * self.width
        self.block_count = (self.height + self.rows_per_block - 1) // self.rows_per_block
        self.first_block = int(first_block)
        self.limit = self.block_count
        self.budget = int(budget)
        self.overdraw = overdraw
        n = int(width) * self.height
        self.rasterised = np.zeros(n if overdraw else 0, dtype=np.uint32)
        self.unwritten = np.zeros(n if overdraw else 0, dtype=np.uint32)  # rasterised but not written
        self.sorted_calls = frozenset(c.index for c in calls if is_sorted_queue(c.queue) and c.state.color_mask)
        firsts = [c.index for c in calls if c.queue > LAST_OPAQUE_QUEUE]
        self.first_after_opaque = min(firsts) if firsts and overdraw else None
        #: Whether the step-1 snapshot shares the frame's depth and stencil arrays rather than
        #: copying them: no call from the first after the opaque queue on writes either
        #: (:func:`.drawlist.writes_depth_or_stencil`), so they stay step 1's to the end, and
        #: the reference replayed onto the snapshot writes no depth (:class:`.layering.ReferenceBlender`).
        self.step1_shares_depth = self.first_after_opaque is not None and not any(
            writes_depth_or_stencil(c) for c in calls if c.index >= self.first_after_opaque)
        self.step1: FrameBuffers | None = None
        self.final: FrameBuffers | None = None
        self.lock = threading.Lock()
        self.blocks: list[list[tuple]] = [[] for _ in range(self.block_count)]
        self.block_counts = np.zeros(self.block_count, dtype=np.int64)
        self.block_bytes = np.zeros(self.block_count, dtype=np.int64)
        self.palettes: dict[int, list[np.ndarray]] = {}  # call → its chunks' palettes, in order
        self.palette_size: dict[int, int] = {}
        self.palette_bytes = 0
        self.call_fragments: dict[int, int] = {}  # call → fragments kept (which blend tables pay)
        #: call → (y0, y1, x0, x1): the box of buffer rows (from the bottom) and columns, ends
        #: exclusive, its fragments reached, rasterised ones before any test (with ``overdraw``;
        #: what a fix moving the call can change).
        self.call_boxes: dict[int, tuple[int, int, int, int]] = {}
        self.bytes = 0  # held now: pieces, their tables and the palettes
        self.peak_bytes = 0
        self.call_dtype = np.uint16 if max((c.index for c in calls), default=0) < 65535 else np.int32
        #: ``order_calls``: opaque draw calls (:func:`opaque_order_calls`) whose fragments' (pixel,
        #: depth code) keys are kept, per call, for :meth:`opaque_order_free` (None once more than
        #: :data:`ORDER_KEYS` arrived).
        self.order_calls = order_calls
        self.order_keys: dict[int, list[np.ndarray]] | None = {} if self.order_calls else None
        self.order_count = 0
        #: The alpha values (clamped as the merger clamps them) the fragments of ``order_calls``
        #: that blend alpha by Max or Min carried: (lowest, highest), NaN when one was NaN.
        self.order_alpha: tuple[float, float] | None = None
        self._extreme_calls = frozenset(c.index for c in calls if c.index in self.order_calls
                                        and alpha_extreme(c.state) is not None)

    #: Draw calls are drawn in batches; only the step-1 snapshot needs the buffers exactly
    #: between two draw calls (:attr:`exact_before`).
    exact_boundaries = False

    @property
    def exact_before(self) -> frozenset[int]:
        return frozenset() if self.first_after_opaque is None else frozenset((self.first_after_opaque,))

    def reads_depth(self, call: DrawCall) -> bool:
        return call.index in self.sorted_calls or call.index in self.order_calls

    def reads_call(self, call: DrawCall) -> bool:
        return self.overdraw or call.index in self.sorted_calls

    def colors_read(self, call: DrawCall) -> bool:
        return call.index in self.sorted_calls  # the others' counts, depths and alpha only

    def draw_begin(self, call, buffers) -> None:
        if call.index == self.first_after_opaque:
            self.step1 = buffers.copy(colors_only=self.step1_shares_depth)

    def draw_end(self, call, buffers, triangles) -> None:
        if self.overdraw:
            self.final = buffers  # the frame's own buffers (its codes, for the sort error)

    def fragments(self, call: DrawCall, frags: ShadedFragments, outcome: np.ndarray) -> None:
        if self.overdraw and frags.pix.size:
            width = self.width // self.samples
            first, last = int(frags.pix.min()), int(frags.pix.max())
            box = (first // width, last // width + 1, first % width, last % width + 1)
            if box[1] - box[0] > 1:  # more than one row: the columns of every fragment
                columns = np.floor_divide(frags.pix, width)  # pix - (pix // width) * width: int64
                columns *= width  # remainder costs twice these three (a division by a constant is fast)
                np.subtract(frags.pix, columns, out=columns)
                box = (box[0], box[1], int(columns.min()), int(columns.max()) + 1)
            with self.lock:
                old = self.call_boxes.get(call.index)
                self.call_boxes[call.index] = box if old is None else union_box(old, box)
        if frags.coverage is not None:
            self._pixel_fragments(call, frags, outcome)
            return
        if call.index in self.order_calls:
            self._order_keys(call, frags, outcome)
        wrote = outcome == Outcome.WRITTEN
        all_written = bool(wrote.all())
        if self.overdraw:
            # Bands of the pipeline own disjoint rows, so threads never count the same pixels.
            _count(self.rasterised, frags.pix)
            if not all_written:
                _count(self.unwritten, frags.pix[~wrote])
        if call.index not in self.sorted_calls:
            return
        self._keep(call, frags, wrote, all_written)

    def _order_keys(self, call: DrawCall, frags: ShadedFragments, outcome: np.ndarray) -> None:
        """Keep ``pixel << 24 | depth code`` of the fragments of an opaque call that passed the
        alpha test (those discarded write nothing in any order)."""
        if self.order_keys is None:
            return
        pix, depth = frags.pix, frags.depth
        reached = outcome != Outcome.ALPHA_TEST
        every = bool(reached.all())
        if not every:
            pix, depth = pix[reached], depth[reached]
        keys = np.left_shift(pix, 24, dtype=np.int64)
        keys |= depth
        span = None
        if call.index in self._extreme_calls and keys.size:
            alpha = frags.colors()[:, 3]
            alpha = np.clip(alpha if every else alpha[reached], 0.0, 1.0)
            span = (alpha.min(), alpha.max())  # NaN when one is NaN
        with self.lock:
            if self.order_keys is None:
                return
            if span is not None:  # np.minimum / np.maximum keep a NaN
                old = self.order_alpha or span
                self.order_alpha = (float(np.minimum(old[0], span[0])), float(np.maximum(old[1], span[1])))
            self.order_count += keys.size
            if self.order_count > ORDER_KEYS:
                self.order_keys = None
                return
            self.order_keys.setdefault(call.index, []).append(keys)

    def opaque_order_free(self) -> bool:
        """Whether the opaque calls of ``order_calls`` leave the same buffers in any order: at no
        pixel do two of them put a fragment that passed the alpha test at the nearest depth code
        (the one ``step1`` holds: ZWrite On, Less or LEqual keep the nearest). Then that depth is
        one call's; every pass of :func:`writes_nearest` lets that call's first fragment there
        through and nothing of another call after it, whichever comes first, the call's own
        fragments keep their order, and the pixels written are those where it passes, in any
        order. Passes that blend alpha by Max or Min (:func:`alpha_extreme`) need one alpha value
        over all their fragments. False when no keys were kept (none asked for, more than
        :data:`ORDER_KEYS`) or there is no ``step1``. The keys are freed."""
        kept, self.order_keys = self.order_keys, None
        if kept is None or self.step1 is None:
            return False
        if self.order_alpha is not None and not self.order_alpha[0] == self.order_alpha[1]:  # NaN: not equal
            return False
        nearest = self.step1.depth
        owner = np.full(nearest.size, -1, dtype=np.int32)  # per pixel: a call with a fragment at the nearest depth
        for call, parts in kept.items():
            keys = np.concatenate(parts)
            pix = np.right_shift(keys, 24)
            at_nearest = np.take(nearest, pix) == (keys & np.int64(DEPTH_MASK))
            pix = pix[at_nearest]
            before = np.take(owner, pix)
            if np.any((before >= 0) & (before != call)):
                return False
            owner[pix] = call
        return True

    def _pixel_fragments(self, call: DrawCall, frags: ShadedFragments, outcome: np.ndarray) -> None:
        """MSAA pixel fragments (``outcome`` (M, N) per sample): the overdraw counts per pixel
        fragment, and one sample fragment per sample reached kept (class doc)."""
        covered = outcome != Outcome.NOT_COVERED
        if self.overdraw:
            rasterised = covered.any(axis=1)
            unwritten = rasterised & ~(outcome == Outcome.WRITTEN).any(axis=1)
            _count(self.rasterised, frags.pix[rasterised])
            if unwritten.any():
                _count(self.unwritten, frags.pix[unwritten])
        if call.index not in self.sorted_calls:
            return
        reached = covered & (outcome != Outcome.ALPHA_TEST) & (outcome != Outcome.ALPHA_TO_MASK)
        which, sample = np.nonzero(reached)  # fragment by fragment: each sample's own order kept
        if which.size == 0:
            return
        rgba = frags.rgba if frags.rgba is not None or frags.ids is not None else frags.colors()
        rgba = None if rgba is None else np.take(rgba, which, axis=0)
        ids = None if frags.ids is None else np.take(frags.ids, which)

        def depth_fn(index: np.ndarray | None) -> np.ndarray:  # read only for the blocks kept
            depth = frags.depth
            return depth[which, sample] if index is None else depth[which[index], sample[index]]

        per_sample = ShadedFragments(np.take(frags.pix, which) * self.samples + sample, None, rgba, ids,
                                     frags.palette, None, None, depth_fn=depth_fn)
        wrote = outcome[which, sample] == Outcome.WRITTEN
        self._keep(call, per_sample, wrote, bool(wrote.all()))

    def _keep(self, call: DrawCall, frags: ShadedFragments, wrote: np.ndarray, all_written: bool) -> None:
        """Store the fragments of a sorted call that passed the alpha test (module doc)."""
        if frags.alive is not None and not frags.alive.all():
            keep = frags.alive
            frags = frags.select(keep)
            wrote = wrote[keep]
            if frags.count == 0:
                return
        pix = frags.pix
        block = pix // self.block_pixels
        if not any(self.first_block <= int(b) < self.limit for b in (block[0], block[-1])):
            b_lo, b_hi = int(block.min()), int(block.max())
            if b_hi < self.first_block or b_lo >= self.limit:
                return  # rows another pass collects (depth codes not even computed)
        depth = frags.depth.astype(np.uint32)
        if all_written:
            depth |= WRITTEN_BIT
        elif wrote.any():
            depth[wrote] |= WRITTEN_BIT
        key = self._palette_keys(call.index, frags)
        order, spans = _pieces(block, self.first_block, self.limit)
        if not spans:
            return
        # The kept fragments in piece order, each array made once for the chunk (pieces are then
        # slices of it, copied so that an evicted block frees its memory).
        lo, hi = spans[0][1], spans[-1][2]
        index = None if order is None else order[lo:hi]

        def kept(a: np.ndarray) -> np.ndarray:
            return a[lo:hi] if index is None else gather(a, index, axis=0)

        local = np.empty(hi - lo, dtype=np.uint16)
        np.subtract(kept(pix), kept(block) * self.block_pixels, out=local, casting="unsafe")
        depth = kept(depth)
        keys = np.empty(hi - lo, dtype=np.int32) if key is None else kept(key)
        starts = np.array([a - lo for _b, a, _e in spans], dtype=np.int64)
        table_rows = table_bounds = None  # every piece's colour table, laid end to end
        if key is None or frags.rgba is not None:
            own = None if key is None else np.flatnonzero(keys < 0)  # fragments with their own colour
            if own is None or own.size:
                if own is None:
                    rows = kept(frags.rgba)
                else:
                    rows = gather(frags.rgba, (own + lo) if index is None else gather(index, own), axis=0)
                table_rows, codes, table_bounds = _color_tables(
                    rows, starts if own is None else np.searchsorted(own, starts))
                if own is None:
                    keys = codes
                else:
                    keys[own] = codes
        pieces = []
        for k, (b, a, e) in enumerate(spans):
            a -= lo
            e -= lo
            table = None
            if table_bounds is not None and table_bounds[k] < table_bounds[k + 1]:
                table = table_rows[table_bounds[k]:table_bounds[k + 1]].copy()
            piece = (local[a:e].copy(), depth[a:e].copy(), np.full(e - a, call.index, dtype=self.call_dtype),
                     keys[a:e].copy(), table)
            nbytes = (e - a) * FRAGMENT_BYTES + (0 if table is None else table.shape[0] * COLOR_BYTES)
            pieces.append((b, piece, e - a, nbytes))
        with self.lock:
            for b, piece, n, nbytes in pieces:
                if b >= self.limit:
                    continue
                self.blocks[b].append(piece)
                self.call_fragments[call.index] = self.call_fragments.get(call.index, 0) + n
                self.block_counts[b] += n
                self.block_bytes[b] += nbytes
                self.bytes += nbytes
            self.peak_bytes = max(self.peak_bytes, self.bytes)
            self._evict()

    def _evict(self) -> None:
        """Drop the highest stored blocks while over the budget, never the lowest that holds fragments
        (each pass makes progress). Under the lock."""
        if self.bytes <= self.budget:
            return
        held = np.flatnonzero(self.block_counts[self.first_block:self.limit])
        lowest = self.first_block + (int(held[0]) if held.size else 0)  # kept whatever its size
        while self.bytes > self.budget and self.limit - 1 > lowest:
            self.limit -= 1
            b = self.limit
            self.bytes -= int(self.block_bytes[b])
            self.blocks[b] = []
            self.block_counts[b] = 0
            self.block_bytes[b] = 0

    def _palette_keys(self, index: int, frags: ShadedFragments) -> np.ndarray | None:
        """(N,) int32 of a chunk: ``>= 0`` the entry of the call's palettes laid end to end,
        -1 where the fragment has its own colour (a row of ``frags.rgba``); None without a palette."""
        if frags.ids is None:
            return None
        count = frags.palette.shape[0]
        with self.lock:
            offset = self.palette_size.get(index, 0)
            self.palettes.setdefault(index, []).append(frags.palette)
            self.palette_size[index] = offset + count
            self.palette_bytes += count * COLOR_BYTES
            self.bytes += count * COLOR_BYTES
        if frags.rgba is None:  # every fragment has a palette entry
            return frags.ids + np.int32(offset)
        return np.where(frags.ids >= 0, frags.ids + np.int32(offset), np.int32(-1)).astype(np.int32)

    def units(self, most: int) -> list[list[int]]:
        """The blocks this pass completed that hold fragments, in order, as units processed
        together: consecutive blocks of at most :data:`UNIT_PIXELS` pixels in all holding at most
        ``most`` fragments (so many shallow blocks cost as few rounds of the per-unit work as
        deep ones)."""
        per_unit = max(1, UNIT_PIXELS // self.block_pixels)
        out: list[list[int]] = []
        total = 0
        for b in range(self.first_block, self.limit):
            count = int(self.block_counts[b])
            if not count:
                continue
            if (out and out[-1][-1] == b - 1 and len(out[-1]) < per_unit and total + count <= most):
                out[-1].append(b)
                total += count
            else:
                out.append([b])
                total = count
        return out

    def take(self, unit: list[int], most: int) -> Iterator[Block]:
        """The fragments of consecutive blocks ``unit`` (freed here; :meth:`units`) as
        :class:`Block` s of consecutive pixel ranges, each holding at most ``most`` fragments (a
        pixel alone may hold more): the working memory of a block stays bounded however deep
        its pixels are. A unit's pixels are numbered from its first block's first pixel."""
        pieces = []
        # A pixel of the unit in 16 bits while they suffice (a radix sort groups them), else 32.
        dtype = np.uint16 if len(unit) * self.block_pixels <= 65536 else np.int32
        with self.lock:
            for k, b in enumerate(unit):
                if k == 0 and dtype is np.uint16:
                    pieces += self.blocks[b]
                else:
                    shift = dtype(k * self.block_pixels)
                    pieces += [(p[0].astype(dtype, copy=False) + shift, *p[1:]) for p in self.blocks[b]]
                self.blocks[b] = []
                self.bytes -= int(self.block_bytes[b])
                self.block_bytes[b] = 0
        b = unit[0]
        if not pieces:
            return
        if sum(p[0].size for p in pieces) <= most:
            block = self._block(b, pieces)
            del pieces  # the block holds the fragments now, not the pieces too
            yield block
            return
        pixels = len(unit) * self.block_pixels
        counts = np.zeros(pixels, dtype=np.int64)
        for p in pieces:
            counts += np.bincount(p[0], minlength=pixels)
        for p0, p1 in pixel_ranges(counts, most):
            parts = []
            for local, dw, call, key, table in pieces:
                inside = (local >= p0) & (local < p1)
                if inside.any():
                    parts.append((local[inside], dw[inside], call[inside], key[inside], table))
            yield self._block(b, parts)

    def _block(self, b: int, pieces: list[tuple]) -> Block:
        """The pieces of block ``b`` (or of a range of its pixels) laid end to end."""
        local = np.concatenate([p[0] for p in pieces])
        dw = np.concatenate([p[1] for p in pieces])
        call = np.concatenate([p[2] for p in pieces])
        key = np.concatenate([p[3] for p in pieces])
        tables = [p[4] for p in pieces if p[4] is not None]
        if tables:
            # Renumber each piece's table rows into the block's table: keys -1 - (offset + row).
            offset = start = 0
            for p in pieces:
                n = p[0].size
                if p[4] is not None:
                    if offset:
                        seg = key[start:start + n]
                        seg[seg < 0] -= np.int32(offset)
                    offset += p[4].shape[0]
                start += n
            table = np.concatenate(tables)
        else:
            table = np.zeros((0, 4), dtype=np.float64)
        return Block(b, b * self.block_pixels, local, dw, call, key, table)

    def palette(self, index: int) -> np.ndarray:
        """(K, 4) float64: the call's palettes laid end to end (palette keys index it)."""
        parts = self.palettes.get(index)
        return np.concatenate(parts) if parts else np.zeros((0, 4), dtype=np.float64)

    def rows_of(self, b: int) -> tuple[int, int]:
        """Buffer rows ``[y0, y1)`` (from the bottom) of block ``b``."""
        return b * self.rows_per_block, min(self.height, (b + 1) * self.rows_per_block)


def pixel_ranges(counts: np.ndarray, most: int) -> list[tuple[int, int]]:
    """Consecutive pixel ranges ``[p0, p1)`` covering every pixel with fragments (``counts``
    (P,) per pixel), each holding at most ``most`` fragments (or one pixel that alone holds more)."""
    ends = np.cumsum(counts)
    total = int(ends[-1]) if ends.size else 0
    out = []
    p0, done = int(np.searchsorted(ends, 0, side="right")), 0
    while done < total:
        p1 = max(int(np.searchsorted(ends, done + most, side="right")), p0 + 1)
        out.append((p0, p1))
        done = int(ends[p1 - 1])
        p0 = p1
    return out


def union_box(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """The box (y0, y1, x0, x1) holding boxes ``a`` and ``b``."""
    return (min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), max(a[3], b[3]))


def _count(counts: np.ndarray, pix: np.ndarray) -> None:
    """``counts[p] += 1`` for every pixel ``p`` in ``pix`` (repeated pixels counted each time):
    numpy's unbuffered ``add.at``, which since numpy 1.25 beats both a gather and scatter of
    distinct pixels and a count over the chunk's range of pixels."""
    np.add.at(counts, pix, np.uint32(1))


#: A chunk falling into more runs of consecutive fragments of one block than this is split by sorting.
SPLIT_RUNS = 64


def _pieces(block: np.ndarray, first: int, limit: int) -> tuple[np.ndarray | None, list[tuple[int, int, int]]]:
    """The pieces of a chunk's fragments in blocks ``[first, limit)``, each block's in chunk order:
    ``(order, [(block, lo, hi), ...])``, piece k being fragments ``lo..hi`` of the chunk (``order``
    None: runs of consecutive fragments, when there are few) or of ``order`` (N,) int64 (the
    chunk's fragments stably sorted by block), in that order."""
    cuts = np.flatnonzero(block[1:] != block[:-1]) + 1
    if cuts.size < SPLIT_RUNS:
        bounds = [0, *cuts.tolist(), block.size]
        runs = [(int(block[a]), a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        return None, [(b, lo, hi) for b, lo, hi in runs if first <= b < limit]
    b_lo = int(block.min())
    order = np.argsort((block - b_lo).astype(np.uint16), kind="stable")  # radix; chunk order kept
    sorted_block = block[order]
    cuts = np.flatnonzero(sorted_block[1:] != sorted_block[:-1]) + 1
    bounds = [0, *cuts.tolist(), order.size]
    parts = [(int(sorted_block[a]), a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    return order, [(b, lo, hi) for b, lo, hi in parts if first <= b < limit]


def _color_tables(rows: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The colour tables of consecutive pieces of ``rows`` (R, 4) float64, piece k holding rows
    ``starts[k]..starts[k+1]`` (``starts`` (K,) int64 ascending, the last piece to R; a piece may
    be empty): each piece's distinct consecutive rows, and each row's code ``-1 - entry`` in its
    piece's table. Returns (the tables laid end to end (T, 4), codes (R,) int32, bounds (K+1,)
    int64: piece k's table is rows ``bounds[k]..bounds[k+1]``). Rows are compared as two complex
    numbers each (the same float comparisons, in two passes)."""
    new = np.ones(rows.shape[0], dtype=bool)
    if rows.shape[0] > 1:
        pairs = np.ascontiguousarray(rows).view(np.complex128)
        np.not_equal(pairs[1:, 0], pairs[:-1, 0], out=new[1:])
        new[1:] |= pairs[1:, 1] != pairs[:-1, 1]
    inside = starts < rows.shape[0]
    new[starts[inside]] = True  # a piece's first row opens its table
    count = np.cumsum(new, dtype=np.int32)  # entries so far, over all pieces
    bounds = np.empty(starts.size + 1, dtype=np.int64)
    bounds[:-1] = np.where(inside, count[np.minimum(starts, rows.shape[0] - 1)] - 1, count[-1] if count.size else 0)
    bounds[-1] = count[-1] if count.size else 0
    lengths = np.diff(np.append(starts, rows.shape[0]))
    codes = np.repeat(bounds[:-1].astype(np.int32), lengths)  # the table's start: -1 - (count - 1 - start)
    codes -= count
    return np.compress(new, rows, axis=0), codes, bounds
