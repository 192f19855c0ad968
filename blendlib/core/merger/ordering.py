"""Applying fragments in exact primitive order (docs/pipeline.md §8): stencil, depth, blending, colour mask.

A chunk of fragments arrives in draw order. Fragments alone on their pixel are
independent and applied at once. The rest are ranked within their pixel (0 = first
drawn) and applied layer by layer: layer k holds the k-th fragment of every such pixel,
so each layer touches distinct pixels and is one vectorised read-modify-write
(:func:`apply_layer`). The result equals applying the fragments one by one in order, as a
GPU does, with a loop over layers (the depth complexity of one draw call), never over
fragments or pixels. Layers are peeled while there are few; deeper ones are ranked with one
stable sort (:func:`layers_by_rank`, which the sorted reference uses too).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from ..gather import gather
from ..vocabulary import CompareFunction, Pass
from .blending import BlendTable, blend_fragments, find_table
from .buffers import PEEL_FREE, FrameBuffers, Outcome, compare, stencil_op

_CHANNEL_INDEX = {"R": 0, "G": 1, "B": 2, "A": 3}
#: ColorMask letters → the bits of their channel in a packed LDR pixel.
_MASK_BITS = {"R": 0x000000FF, "G": 0x0000FF00, "B": 0x00FF0000, "A": 0xFF000000}


def apply_layer(
    buf: FrameBuffers, p: Pass, pix: np.ndarray, depth: np.ndarray | None, rgba: np.ndarray | None,
    ids: np.ndarray | None = None, lut: BlendTable | None = None, outcome: np.ndarray | None = None,
) -> None:
    """Apply fragments on *distinct* pixels: stencil → depth → stencil op → depth write → blend → mask.

    ``pix`` (N,) int64, ``depth`` (N,) int64, ``rgba`` (N, 4) float64 shading-space colours.
    ``depth`` None: every fragment is known to pass the depth test (the caller proved it) and
    the pass does not write depth. With ``ids`` (N,) int32 and a :class:`BlendTable` ``lut``
    (built once per palette by the caller), fragments with ``ids >= 0`` take their stored codes from
    the table (their ``rgba`` rows are not read; ``rgba`` may be None when all are tabled).
    ``outcome`` (N,) int8, optional: receives each fragment's :class:`Outcome`.
    """
    if depth is None:
        passed = None
        if outcome is not None:
            outcome[:] = Outcome.WRITTEN
    else:
        passed = compare(p.ztest, depth, buf.depth[pix])
        if outcome is not None:
            outcome[:] = np.where(passed, Outcome.WRITTEN, Outcome.DEPTH)
    if p.stencil:
        s_old = buf.stencil[pix]
        rm, wm, ref = p.stencil_read_mask, p.stencil_write_mask, p.stencil_ref
        s_pass = compare(p.stencil_comp, np.int64(ref & rm), s_old.astype(np.int64) & rm)
        z_pass = s_pass if passed is None else passed & s_pass
        zfail = s_old if passed is None else stencil_op(p.stencil_zfail, s_old, ref)
        new = np.where(~s_pass, stencil_op(p.stencil_fail, s_old, ref),
                       np.where(z_pass, stencil_op(p.stencil_pass, s_old, ref), zfail))
        buf.stencil[pix] = ((s_old.astype(np.int64) & (~wm & 255)) | (new & wm)).astype(np.uint8)
        passed = z_pass
        if outcome is not None:
            outcome[~s_pass] = Outcome.STENCIL
    if passed is not None:
        if not passed.any():
            return
        if not passed.all():
            index = np.flatnonzero(passed)
            pix = gather(pix, index)
            depth = None if depth is None else gather(depth, index)
            rgba = None if rgba is None else gather(rgba, index, axis=0)
            ids = None if ids is None else gather(ids, index)
    if p.zwrite:
        buf.depth[pix] = depth
    if not p.color_mask:
        return
    packed = buf.packed()
    stored = packed[pix]
    if ids is not None:
        tabled = ids >= 0
        if tabled.all():
            result = lut.lookup(stored, ids)
        else:
            result = np.empty_like(stored)
            result[tabled] = lut.lookup(stored[tabled], ids[tabled])
            plain = ~tabled
            result[plain] = blend_fragments(buf, p, stored[plain], rgba[plain])
    else:
        result = blend_fragments(buf, p, stored, rgba)
    if len(p.color_mask) < 4:
        if buf.hdr:
            merged = result.view(np.float32).reshape(-1, 4)
            old = stored.view(np.float32).reshape(-1, 4)
            keep = [_CHANNEL_INDEX[c] for c in "RGBA" if c not in p.color_mask]
            merged[:, keep] = old[:, keep]
        else:
            bits = np.uint32(sum(_MASK_BITS[c] for c in p.color_mask))
            result = (stored & ~bits) | (result & bits)
    packed[pix] = result


#: At most this many layers of a chunk are peeled (one ``minimum.at`` each); the fragments
#: of deeper pixels that remain after them are ranked with one stable sort.
PEEL_LAYERS = 8


def layers_by_rank(order: np.ndarray, grouped: np.ndarray) -> list[np.ndarray]:
    """The layers of fragments grouped by pixel, each a set of distinct pixels.

    ``order`` (N,) int64: indices that group the fragments by pixel, each pixel's fragments in
    the order they are applied; ``grouped`` (N,) integer: the pixel of each, in that order
    (``pixel[order]``). A fragment's rank is its place within its pixel (0 = applied first);
    layer k holds the fragments of rank k, in the order of ``order``. Returns the L layers as
    (M_k,) int64 index arrays (views of one array), L the most fragments of any pixel.
    """
    n = grouped.size
    if n == 0:
        return []
    starts = np.ones(n, dtype=bool)
    starts[1:] = grouped[1:] != grouped[:-1]
    index = np.arange(n, dtype=np.int64)
    rank = index - np.maximum.accumulate(np.where(starts, index, 0))
    layers = int(rank.max()) + 1
    bounds = np.concatenate([[0], np.bincount(rank, minlength=layers).cumsum()])
    # A stable sort by rank keeps each layer in the order of ``order``; numpy sorts 16-bit keys
    # by radix, and any key type gives the same permutation.
    by_rank = order[np.argsort(rank.astype(np.uint16) if layers <= 1 << 16 else rank, kind="stable")]
    return [by_rank[bounds[k]:bounds[k + 1]] for k in range(layers)]


_NEARER_PASSES = (CompareFunction.Less, CompareFunction.LEqual)


def order_free_depth(p: Pass) -> bool:
    """Whether a pass only keeps the nearest (or farthest) depth per pixel: ZWrite On with
    ZTest Less, LEqual, Greater or GEqual, no colour written, no stencil. Its fragments can
    then be applied in any order (the merger takes a per-pixel minimum or maximum)."""
    return (not p.color_mask and not p.stencil and p.zwrite
            and p.ztest in (*_NEARER_PASSES, CompareFunction.Greater, CompareFunction.GEqual))


def merge(
    buf: FrameBuffers, p: Pass, pix: np.ndarray, depth: np.ndarray | None, rgba: np.ndarray | None,
    ids: np.ndarray | None = None, palette: np.ndarray | None = None, outcome: np.ndarray | None = None,
    disjoint: bool = False, tables: dict | None = None,
) -> int:
    """Apply a chunk of fragments (in draw order) exactly as one-by-one; returns the layer count
    (1 for a pass whose result does not depend on the order: :func:`order_free_depth`).

    Optional ``ids`` (N,) int32 / ``palette`` (K, 4) float64: fragments with ``ids >= 0``
    have the colour ``palette[ids]`` (constant over their triangle) and blend through a
    lookup table (:func:`.blending.blend_lut`); only valid when :func:`.blending.lut_eligible`.
    Optional ``outcome`` (N,) int8 receives each fragment's :class:`Outcome`.
    ``depth`` None: all fragments pass the depth test and the pass writes no depth (see
    :func:`apply_layer`). ``disjoint``: the caller knows the fragments hit distinct pixels.
    ``tables``: a dict the caller keeps for the chunks of one draw call (same pass and
    buffer kind): blend tables are built once per palette there instead of once per chunk
    (a :class:`.blending.BlendTables` when band workers share it); tables of earlier renders
    are taken from :data:`.blending.RECENT_TABLES` (:func:`.blending.find_table`).
    """
    n = pix.shape[0]
    if n == 0:
        return 0
    if outcome is None and depth is not None and order_free_depth(p):
        # Applied one by one, each fragment replaces the stored depth when nearer (farther):
        # the pixel ends with the minimum (maximum) of its stored and fragment depths.
        (np.minimum if p.ztest in _NEARER_PASSES else np.maximum).at(buf.depth, pix, depth)
        return 1
    lut = None if ids is None else find_table(buf, p, palette, n, tables)

    def layer(sel) -> None:
        if sel is None:
            apply_layer(buf, p, pix, depth, rgba, ids, lut, outcome)
            return
        codes = None if outcome is None else np.empty(sel.shape[0], dtype=np.int8)
        # np.take: fancy indexing of (N, 4) rows costs several times more.
        apply_layer(buf, p, gather(pix, sel), None if depth is None else gather(depth, sel),
                    None if rgba is None else gather(rgba, sel, axis=0),
                    None if ids is None else gather(ids, sel), lut, codes)
        if codes is not None:
            outcome[sel] = codes

    layers = 0
    for sel in primitive_layers(pix, disjoint, buf.peel_scratch()):
        layer(sel)
        layers += 1
    return layers


def primitive_layers(pix: np.ndarray, disjoint: bool = False,
                     scratch: np.ndarray | None = None) -> Iterator[np.ndarray | None]:
    """The layers of fragments at ``pix`` (N,) int64 (N > 0, in draw order) to apply one after
    another, each a set of distinct pixels in draw order: None for "all of them" when the pixels
    are distinct (``disjoint``: the caller knows), else index arrays — the first remaining
    fragment of every pixel, peeled while there are at most :data:`PEEL_LAYERS`, the rest then
    ranked by :func:`layers_by_rank`. Applying the layers in order applies every pixel's
    fragments in order.

    ``scratch``: an int64 array longer than ``pix.max()``, every entry :data:`.buffers.PEEL_FREE`
    (:meth:`.buffers.FrameBuffers.peel_scratch`), used and left so, even when the caller stops
    early; without it one is made for the chunk's range of pixels. The peel touches only the
    chunk's own pixels: no frame-sized count or table per chunk."""
    if disjoint:
        yield None
        return
    if scratch is None:
        lo = int(pix.min())
        pix = pix - lo
        scratch = np.full(int(pix.max()) + 1, PEEL_FREE, dtype=np.int64)
    remaining = np.arange(pix.shape[0], dtype=np.int64)
    where = pix
    for peeled in range(PEEL_LAYERS):
        # Layer k = the first remaining fragment of each pixel, found with an unbuffered minimum;
        # its entries are freed before the layer is handed out, so the table is clean whenever
        # the caller has it (an error in between frees them too).
        try:
            np.minimum.at(scratch, where, remaining)
            is_first = scratch[where] == remaining
        finally:
            scratch[where] = PEEL_FREE
        if peeled == 0 and is_first.all():
            yield None
            return
        yield remaining[is_first]
        remaining = remaining[~is_first]
        if not remaining.size:
            return
        where = pix[remaining]
    # Deeper than PEEL_LAYERS: rank what remains with one stable sort.
    order = remaining[np.argsort(where, kind="stable")]
    yield from layers_by_rank(order, pix[order])
