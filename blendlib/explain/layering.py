"""Per-pixel order of a block's kept fragments (:mod:`.fragment_store`): the far-to-near layers
of the sorted reference (step 2) and the renderer pairs the frame applied out of order.

A block's fragments come in the order the frame applied them at each pixel. Where the
frame allows it, the fragments alone at their pixel leave first (the frame's colour is the
reference's there). One stable sort by pixel (:func:`group_by_pixel`; a radix sort where a
unit's pixels fit 16 bits) groups the rest, each pixel's still in that order, and every
per-pixel array that follows is over the pixels holding them only. Then, for pixels of bounded
fragment totals at a time (:func:`pixel_ranges`):

- :func:`far_to_near_layers`: pixels with the same number of fragments ``c`` form one (n, c)
  matrix, sorted row by row by (depth code descending, applied order) — small sorts, no sort of
  the whole block — and layer k (the k-th farthest fragment of every pixel, distinct pixels) is
  column k of every matrix. :class:`ReferenceBlender` applies a layer through the output
  merger (:func:`blendlib.core.merger.apply_layer`) with each draw call's pass state, depth
  tested against step 1's depth and never written, constant colours through blend tables.
- :func:`inverted_pairs`: consecutive written fragments of one draw call at a pixel form a
  run; a pair (A, B) scores at a pixel when a fragment of A was applied before a farther one of
  B: inside a run iff two neighbours ascend in depth; between runs i < j iff run i's nearest
  fragment is nearer than run j's farthest. Pixels with the same number of runs ``c`` form
  (n, c) matrices compared at every offset t (columns i and i + t), skipping pixels that can
  have no pair at larger offsets.
"""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np

from ..core.drawlist import DrawCall
from ..core.gather import gather
from ..core.merger import FrameBuffers, apply_layer, find_table, lut_eligible, table_pays
from ..core.vertex import DEPTH_MAX
from .fragment_store import DEPTH_MASK, WRITTEN_BIT, Block

#: A blend table of a group of draw calls is used for at most this many palette colours (16 MB).
TABLE_COLORS = 4096
#: Pair keys are counted with a bincount below this many renderer pairs, else sorted.
BINCOUNT_PAIRS = 1 << 22
#: Inverted (pixel, pair) found are reduced to counts every this many.
TALLY_FLUSH = 1 << 20
#: Every this many offsets, pixels with no inverted pair left at larger offsets are dropped.
PRUNE_OFFSETS = 4


_FRAGMENT_ARRAYS = ("local", "depth_written", "call", "key")


def group_by_pixel(block: Block, pixels: int,
                   drop_lone: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Reorder ``block``'s arrays (in place of the block) so its fragments are grouped by pixel
    ascending, each pixel's in the order the frame applied them; ``pixels``: the block's size.
    With ``drop_lone`` the fragments alone at their pixel are removed first: there the frame
    applied one fragment onto step 1's buffers, as the reference does
    (:func:`.sorted_reference.lone_fragments_as_frame`).

    Every per-pixel array is over the pixels that hold fragments only (Q of them, ascending):
    returns (pixels (Q,) int64 their numbers within the block, counts (Q,) int64 fragments at
    each, starts (Q,) int64 the place of each one's first, lone (K,) int64 the numbers of the
    pixels whose lone fragment was removed)."""
    lone = np.zeros(0, dtype=np.int64)
    if drop_lone:
        many = np.bincount(block.local, minlength=pixels)[block.local] > 1
        if not many.all():
            lone = block.local[~many].astype(np.int64)
            for name in _FRAGMENT_ARRAYS:
                setattr(block, name, getattr(block, name)[many])
        del many
    order = np.argsort(block.local, kind="stable")  # 16-bit keys: radix sort; wider: runs merged
    for name in _FRAGMENT_ARRAYS:
        setattr(block, name, gather(getattr(block, name), order))
    del order
    local, n = block.local, block.local.size
    new = np.empty(n, dtype=bool)
    new[:1] = True
    np.not_equal(local[1:], local[:-1], out=new[1:])
    starts = np.flatnonzero(new)
    return np.take(local, starts).astype(np.int64), np.diff(starts, append=n), starts, lone


def _classes(counts: np.ndarray, smallest: int) -> list[tuple[int, np.ndarray]]:
    """(c, places (n,) int64 ascending) for each value ``c >= smallest`` present in ``counts``
    (P,) (non-negative integers: fragment counts per pixel, state groups per fragment), in
    ascending order of ``c``."""
    wanted = np.flatnonzero(counts >= smallest)
    if wanted.size == 0:
        return []
    values = counts[wanted]
    if values.size and int(values.max()) <= np.iinfo(np.uint16).max:
        values = values.astype(np.uint16)  # numpy's radix sort
    by_count = wanted[np.argsort(values, kind="stable")]
    sorted_values = counts[by_count]
    cuts = np.flatnonzero(sorted_values[1:] != sorted_values[:-1]) + 1
    bounds = [0, *cuts.tolist(), by_count.size]
    return [(int(sorted_values[a]), by_count[a:b]) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


def far_to_near_layers(counts: np.ndarray, starts: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, list[int]]:
    """The layers of pixels' fragments far to near, laid end to end: (fragment indices (M,)
    int64, layer bounds [0, b1, ..., M]). Layer k (distinct pixels) holds the k-th farthest
    fragment of every pixel with more than k, ties in applied order. ``counts``/``starts``
    (P,) int64: a range of pixels of a block grouped by :func:`group_by_pixel`, ``starts``
    relative to ``depth`` (M,) int64: the range's depth codes in that order."""
    columns: list[list[np.ndarray]] = []
    for c, rows in _classes(counts, 1):
        first = starts[rows][:, None]
        if c == 1:
            frag = first
        else:
            bits = (c - 1).bit_length()
            place = np.arange(c, dtype=np.int64)
            key = gather(depth, first + place)
            np.subtract(DEPTH_MAX, key, out=key)  # far first, then applied order
            key <<= bits
            key |= place
            key.sort(axis=1)
            key &= (1 << bits) - 1  # the place within the pixel
            frag = key
            frag += first
        frag = frag.T  # (c, n): layer k is row k
        while len(columns) < c:
            columns.append([])
        for k in range(c):
            columns[k].append(frag[k])
    sizes = [sum(part.size for part in parts) for parts in columns]
    order = np.concatenate([part for parts in columns for part in parts]) if columns else np.zeros(0, np.int64)
    return order, [0, *np.cumsum(sizes).tolist()]


class ReferenceBlender:
    """Applies far-to-near layers onto the step-1 buffers with each fragment's pass (no depth writes).

    Draw calls whose passes have the same state share a group: one blend table over their
    palettes laid end to end, so a layer costs one merge per distinct state, not one per draw
    call (a layer's fragments lie on distinct pixels, so the grouping cannot change the result).
    ``palettes``: draw call → its (K, 4) float64 palette; ``fragments``: draw call → fragments
    kept (which blend table pays).

    With MSAA the fragments' pixels are sample indices ``p*N + s``
    (:class:`.fragment_store.FragmentCollector`), applied to sample ``s``'s plane of pixel ``p``;
    the buffers' uniform pixels (:attr:`.merger.FrameBuffers.uniform`) are spread first, so every
    sample holds its own colour."""

    def __init__(self, buf: FrameBuffers, calls: dict[int, DrawCall], sorted_calls,
                 palettes: dict[int, np.ndarray], fragments: dict[int, int]) -> None:
        self.buf = buf
        if buf.uniform is not None and buf.uniform.any():
            buf.spread(np.flatnonzero(buf.uniform))
        size = max(calls, default=0) + 1
        self.group_of_call = np.zeros(size, dtype=np.int64)
        self.base_of_call = np.zeros(size, dtype=np.int64)  # offset of the call's palette in its group's
        self.group_pass: list = []
        group_palettes: list[list[np.ndarray]] = []
        group_fragments: list[int] = []
        groups: dict = {}
        for index in sorted(sorted_calls):
            state = replace(calls[index].state, zwrite=False)
            g = groups.setdefault(state, len(groups))
            if g == len(self.group_pass):
                self.group_pass.append(state)
                group_palettes.append([])
                group_fragments.append(0)
            palette = palettes.get(index)
            self.group_of_call[index] = g
            self.base_of_call[index] = sum(p.shape[0] for p in group_palettes[g])
            if palette is not None and palette.shape[0]:
                group_palettes[g].append(palette)
            group_fragments[g] += fragments.get(index, 0)
        self.palettes = [np.concatenate(p) if p else np.zeros((0, 4), dtype=np.float64) for p in group_palettes]
        self.fragments = group_fragments
        self.tables: dict[int, object] = {}
        self.lock = threading.Lock()

    def _table(self, g: int):
        """The group's blend table, or None when its palette is blended colour by colour."""
        with self.lock:  # blocks run on two threads: each table is found once
            if g not in self.tables:
                p, palette, buf = self.group_pass[g], self.palettes[g], self.buf
                use = (lut_eligible(p, buf.hdr) and 0 < palette.shape[0] <= TABLE_COLORS
                       and table_pays(p, buf.hdr, buf.linear, palette, self.fragments[g]))
                # Channel tables (fragments=0: 4 KB per colour) stay in cache for a group's many
                # colours; the pair form (512 KB per colour) pays for one colour per chunk, not here.
                self.tables[g] = find_table(buf, p, palette, 0) if use else None
            return self.tables[g]

    def keep_frame(self, pixels: np.ndarray, frame: FrameBuffers) -> None:
        """Set the colour of ``pixels`` (K,) int64 to the ``frame``'s own (one sample a pixel):
        pixels where the frame applied a lone fragment onto step 1 (:func:`group_by_pixel`)."""
        self.buf.packed()[pixels] = np.take(frame.packed(), pixels)  # whole pixels, not rows of four

    def colour_ids(self, block: Block) -> tuple[np.ndarray | None, np.ndarray]:
        """(group (N,) int64 or None when there is one, ids (N,) int32) of a block's fragments:
        the state group of each, and its entry in the group's palette (``ids >= 0``) or its own
        colour, row ``-1 - id`` of ``block.table``."""
        group = None if len(self.group_pass) == 1 else self.group_of_call[block.call]
        ids = block.key + self.base_of_call[block.call].astype(np.int32)
        own = block.key < 0
        if own.any():
            ids[own] = block.key[own]
        return group, ids

    #: With at most this many state groups a layer is split by one comparison per group.
    GROUPS_BY_PASS = 8

    def apply(self, block: Block, group: np.ndarray | None, ids: np.ndarray, order: np.ndarray,
              bounds: list[int], offset: int) -> None:
        """Apply layers (:func:`far_to_near_layers`: fragment indices ``order`` of a range starting
        at fragment ``offset`` of ``block``, layer by layer between ``bounds``) in order;
        ``group``/``ids``: :meth:`colour_ids` of the block."""
        order = order + offset
        pix = block.local[order].astype(np.int64)
        pix += block.start
        n = self.buf.samples
        if n > 1:  # sample index p*N + s → sample s's plane
            pix = (pix % n) * self.buf.plane + pix // n
        depth = block.depth(order)
        fid = ids[order]
        rgba = None
        own = fid < 0
        if own.all():  # per-fragment colours: rows of the block's table
            rgba = gather(block.table, -1 - fid, axis=0)
        elif own.any():
            rgba = np.empty((order.size, 4), dtype=np.float64)
            rgba[own] = gather(block.table, -1 - fid[own], axis=0)
        grp = None if group is None else group[order]
        groups = len(self.group_pass)
        for k in range(len(bounds) - 1):
            a, b = bounds[k], bounds[k + 1]
            if grp is None:
                self._apply(0, pix[a:b], depth[a:b], fid[a:b], None if rgba is None else rgba[a:b])
                continue
            # The layer's fragments by group, each group's in layer order (its pixels are distinct
            # anyway): a pass per group where groups are few, else one stable sort (_classes).
            if groups <= self.GROUPS_BY_PASS:
                parts = [(g, np.flatnonzero(grp[a:b] == g)) for g in range(groups)]
            else:
                parts = _classes(grp[a:b], 0)
            for g, part in parts:
                if not part.size:
                    continue
                part = part + a
                self._apply(g, gather(pix, part), gather(depth, part), gather(fid, part),
                            None if rgba is None else gather(rgba, part, axis=0))

    def _apply(self, g: int, pix: np.ndarray, depth: np.ndarray, fid: np.ndarray, rgba: np.ndarray | None) -> None:
        """Fragments of one group on distinct pixels: ``fid`` (M,) int32 palette entries or -1
        (then their ``rgba`` row)."""
        own = None if rgba is None else fid < 0
        table = None if own is not None and own.all() else self._table(g)
        if table is None and (own is None or not own.all()):
            palette = self.palettes[g]
            if own is None:
                rgba = np.take(palette, fid, axis=0)
            else:
                rgba = rgba.copy()
                rgba[~own] = np.take(palette, fid[~own], axis=0)
        apply_layer(self.buf, self.group_pass[g], pix, depth, rgba, None if table is None else fid, table)


def block_inversions(block: Block, f0: int, f1: int, counts: np.ndarray, renderer_of_call: np.ndarray,
                     renderers: int, exact_keys: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`inverted_pairs` of the written fragments ``[f0, f1)`` of a block grouped by
    :func:`group_by_pixel`: the fragments of a range of its occupied pixels, ``counts`` (P,) per
    pixel (pixels numbered by their place in the range)."""
    pixel = np.repeat(np.arange(counts.size, dtype=np.int64), counts)
    dw = block.depth_written[f0:f1]
    call = block.call[f0:f1]
    written = dw >= WRITTEN_BIT
    if not written.all():
        pixel, call, dw = pixel[written], call[written], dw[written]
    return inverted_pairs(pixel, call, (dw & DEPTH_MASK).astype(np.int32), counts.size, renderer_of_call,
                          renderers, exact_keys)


class _PairTally:
    """Inverted (pixel, pair) found once each: counts per pixel and per pair id (``front * R + behind``),
    the found ones reduced to counts every :data:`TALLY_FLUSH` (bounded memory however many)."""

    def __init__(self, pixels: int, per_pair: int) -> None:
        self.per_pair = per_pair
        self.per_pixel = np.zeros(pixels, dtype=np.int64)
        self.counts = np.zeros(per_pair, dtype=np.int64) if per_pair <= BINCOUNT_PAIRS else None
        self.sparse: dict[int, int] = {}
        self.found: list[tuple[np.ndarray, np.ndarray]] = []
        self.held = 0

    def add(self, pixel: np.ndarray, pair: np.ndarray) -> None:
        self.found.append((pixel, pair))
        self.held += pixel.size
        if self.held >= TALLY_FLUSH:
            self._flush()

    def _flush(self) -> None:
        if not self.found:
            return
        self.per_pixel += np.bincount(np.concatenate([f[0] for f in self.found]), minlength=self.per_pixel.size)
        pair = np.concatenate([f[1] for f in self.found])
        self.found, self.held = [], 0
        if self.counts is not None:
            self.counts += np.bincount(pair, minlength=self.per_pair)
        else:
            ids, counts = np.unique(pair, return_counts=True)
            for k, n in zip(ids.tolist(), counts.tolist(), strict=True):
                self.sparse[k] = self.sparse.get(k, 0) + n

    def result(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self._flush()
        if self.counts is not None:
            ids = np.flatnonzero(self.counts)
            return self.per_pixel, ids, self.counts[ids]
        ids = np.array(sorted(self.sparse), dtype=np.int64)
        return self.per_pixel, ids, np.array([self.sparse[k] for k in ids.tolist()], dtype=np.int64)


def inverted_pairs(p: np.ndarray, c: np.ndarray, d: np.ndarray, pixels: int, renderer_of_call: np.ndarray,
                   renderers: int, exact_keys: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The inverted renderer pairs at pixels (module doc).

    ``p`` (M,) int64 pixel in ``[0, pixels)``, grouped ascending; ``c`` (M,) draw call indices,
    ``d`` (M,) depth codes: the written fragments, each pixel's in the order the frame applied
    them. ``renderer_of_call`` (calls + 1,) int64; ``renderers``: R. ``exact_keys``: no renderer
    has two sorted draw calls, so each (pixel, front, behind) is found once (else duplicates are
    removed). Returns (pairs inverted per pixel (pixels,) int64; distinct pair ids
    ``front * R + behind`` (K,) int64; the pixels of each (K,) int64)."""
    per_pair = renderers * renderers
    found = _PairTally(pixels, per_pair)
    if p.size == 0:
        return found.result()
    keys: list[np.ndarray] = []  # pixel * R² + pair, to be made distinct (not exact_keys)

    def add(pixel: np.ndarray, pair: np.ndarray) -> None:
        if exact_keys:
            found.add(pixel, pair)
            return
        keys.append(pixel * per_pair + pair)
        if len(keys) > 1 and sum(k.size for k in keys) >= TALLY_FLUSH:
            keys[:] = [np.unique(np.concatenate(keys))]  # the distinct ones so far

    r = renderer_of_call[c]
    same_call = (p[1:] == p[:-1]) & (c[1:] == c[:-1])
    ascent = np.flatnonzero(same_call & (d[:-1] < d[1:])) + 1
    if ascent.size:  # inside a run: (A, A), once per pixel and run
        first = np.ones(ascent.size, dtype=bool)
        first[1:] = (p[ascent[1:]] != p[ascent[:-1]]) | (c[ascent[1:]] != c[ascent[:-1]])
        ascent = ascent[first]
        add(p[ascent], r[ascent] * (renderers + 1))
    # 24-bit codes as int32: half the bytes for the comparisons.
    if not same_call.any():  # every run one fragment
        run_min = run_max = d.astype(np.int32, copy=False)
        run_ren, run_pix = r, p
    else:
        run_start = np.ones(p.size, dtype=bool)
        run_start[1:] = ~same_call
        starts = np.flatnonzero(run_start)
        run_min = np.minimum.reduceat(d, starts).astype(np.int32)
        run_max = np.maximum.reduceat(d, starts).astype(np.int32)
        run_ren, run_pix = r[starts], p[starts]
    run_counts = np.bincount(run_pix, minlength=pixels)
    run_first = np.cumsum(run_counts) - run_counts
    for n_runs, rows in _classes(run_counts, 2):
        # (c, n): column = pixel, row = its runs in applied order; offsets compare whole rows.
        place = run_first[rows][None, :] + np.arange(n_runs, dtype=np.int64)[:, None]
        rmin, rmax = run_min[place], run_max[place]
        # Run j pairs with an earlier run only if some earlier run is nearer than j's farthest.
        reach = np.minimum.accumulate(rmin, axis=0)
        live = (reach[:-1] < rmax[1:]).any(axis=0)
        if not live.any():
            continue
        if not live.all():  # np.compress keeps the (c, n) arrays C-contiguous, unlike [:, live]
            rows, place = rows[live], np.compress(live, place, axis=1)
            rmin, rmax, reach = (np.compress(live, a, axis=1) for a in (rmin, rmax, reach))
        ren = run_ren[place]
        for t in range(1, n_runs):
            if t % PRUNE_OFFSETS == 0:  # drop pixels with no pair left at offsets >= t
                live = (reach[:-t] < rmax[t:]).any(axis=0)
                if not live.any():
                    break
                if not live.all():
                    rows = rows[live]
                    rmin, rmax, reach, ren = (np.compress(live, a, axis=1) for a in (rmin, rmax, reach, ren))
            hit = np.flatnonzero(rmin[:-t] < rmax[t:])  # flat over (c - t, n)
            if hit.size:
                n = rows.size
                flat = ren.reshape(-1)
                add(rows[hit % n], flat[hit] * renderers + flat[hit + t * n])  # front * R + behind
    if keys:
        distinct = np.unique(np.concatenate(keys))
        pixel = distinct // per_pair
        found.add(pixel, distinct - pixel * per_pair)
    return found.result()
