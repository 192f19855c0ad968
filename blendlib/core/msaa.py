"""Multisampling (docs/pipeline.md §10): sample patterns, per-sample coverage and depth,
AlphaToMask, sample fragments for the merger, and the resolve.

With ``DrawScene.msaa`` N > 1 the buffers hold N samples per pixel (sample ``s`` of window
pixel ``p`` at index ``p*N + s``). A draw call's rows are the pixels where at least one sample
is covered (:func:`.raster.coverage_rows` with ``samples``); each such pixel is one *pixel
fragment*, shaded once at the pixel centre, with a coverage mask (bit ``s`` = sample ``s``,
:func:`coverage`) and a depth code per sample. The merger receives one *sample
fragment* per covered sample (:func:`sample_fragments`): each sample is a pixel of its own for
the depth and stencil tests, blending and primitive order, so the merger's layer machinery
applies unchanged. :func:`resolve_colors` averages the samples as llvmpipe's resolve does.
"""

from __future__ import annotations

import numpy as np

from . import raster
from .merger import FrameBuffers, Outcome, apply_layer, find_table, order_free_depth, primitive_layers
from .vertex import DEPTH_MAX, HALF, SUBPIXEL, TriangleSetup
from .vocabulary import CompareFunction, Pass

#: The standard sample positions (Direct3D's and Vulkan's, Mesa's ``u_sample_positions.c``)
#: in 1/16 pixel from the pixel's lower-left corner, x right and y up in window coordinates
#: (llvmpipe's 4x pattern exactly as ``glGetMultisamplefv(GL_SAMPLE_POSITION)`` reports it; the
#: same numbers as D3D's tables, which count y down from the top: the pattern seen in an image
#: is D3D's mirrored vertically). Sample ``s`` is bit ``s`` of a coverage mask.
SAMPLE_POSITIONS_16 = {
    1: ((8, 8),),
    2: ((12, 12), (4, 4)),
    4: ((6, 2), (14, 6), (2, 10), (10, 14)),
    8: ((9, 5), (7, 11), (13, 9), (5, 3), (3, 13), (1, 7), (11, 15), (15, 1)),
}


def sample_offsets(samples: int) -> np.ndarray:
    """(N, 2) int64: the sample positions of an N-sample pixel in sub-pixel steps (1/256 pixel)
    from its lower-left corner, (x, y) with y up; N = 1 is the pixel centre."""
    if samples not in SAMPLE_POSITIONS_16:
        raise ValueError(f"MSAA must be 1, 2, 4 or 8 samples, got {samples!r}")
    return np.array(SAMPLE_POSITIONS_16[samples], dtype=np.int64) * (SUBPIXEL // 16)


def alpha_to_mask(alpha: np.ndarray, samples: int) -> np.ndarray:
    """(M,) uint8 AlphaToMask coverage of shader alphas ``alpha`` (M,) float64: sample ``s`` of
    N is covered when ``alpha > s/N`` — ceil(N*alpha) samples, from sample 0 up — llvmpipe's rule
    (``lp_build_sample_alpha_to_coverage``: the raw shader alpha, no clamp, no dither)."""
    mask = np.zeros(alpha.shape[0], dtype=np.uint8)
    for s in range(samples):
        mask |= (alpha > s / samples).astype(np.uint8) << np.uint8(s)
    return mask


def _row_edges(setup: TriangleSetup, rows, start: int, stop: int) -> tuple:
    """Per row of ``rows[start:stop]``: the x steps ``dx`` of the counter-clockwise edges b→c and
    c→a (the third edge's step is minus their sum) and each edge's top-left bias (0 on a top-left
    edge, else 1: docs/pipeline.md §4): ((dx0, dx1, dx2), (dy0, dy1, dy2), (bias0, bias1, bias2)),
    each (R,) int64."""
    tri = rows.tri[start:stop]
    swap = rows.swap[start:stop]
    X = setup.X.take(tri, axis=0)
    ax = X[:, 0]
    bx = np.where(swap, X[:, 2], X[:, 1])
    cx = np.where(swap, X[:, 1], X[:, 2])
    dx = (cx - bx, ax - cx, bx - ax)
    dy0, dy1 = rows.dy0[start:stop], rows.dy1[start:stop]
    dy = (dy0, dy1, -(dy0 + dy1))
    bias = tuple(((d_y > 0) | ((d_y == 0) & (d_x >= 0))).astype(np.int64) for d_x, d_y in zip(dx, dy, strict=True))
    return dx, dy, bias


def _fragment_rows(rows, start: int, stop: int, index: np.ndarray | None):
    """The candidates of rows ``[start, stop)`` (all, or those at positions ``index``): their x
    (K,) int64 and a function expanding per-row values (R, ...) of the slice to them."""
    length = rows.length[start:stop]
    first = length.cumsum() - length
    if index is None:
        n = int(length.sum())
        expand = raster.run_expander(length, n)
        x = np.arange(n, dtype=np.int64)
        x += expand(rows.x0[start:stop] - first)
        return x, expand
    row = np.searchsorted(length.cumsum(), index, side="right")
    return (rows.x0[start:stop] - first).take(row) + index, lambda values: values.take(row, axis=0)


def _masks(x: np.ndarray, x0: np.ndarray, x1: np.ndarray, samples: int) -> np.ndarray:
    """(K,) uint8: bit s set where ``x0[:, s] <= x <= x1[:, s]`` (x (K,), x0/x1 (K, N))."""
    covered = (x[:, None] >= x0) & (x[:, None] <= x1)
    return np.packbits(covered, axis=1, bitorder="little").reshape(-1)  # N <= 8: one byte


def coverage(rows, start: int, stop: int, samples: int, index: np.ndarray | None = None) -> np.ndarray:
    """(M,) uint8 coverage masks of the candidate pixels of MSAA rows ``[start, stop)`` (in the
    order :func:`.raster.rasterize_rows` gives them), or of candidates ``index`` (K,) of them only.

    Sample ``s`` at ``(x*S + ox_s, y*S + oy_s)`` is covered when every edge function there is
    ``> 0``, or ``== 0`` on a top-left edge (docs/pipeline.md §4): exactly when x lies in the
    sample's own span of the row (:attr:`.raster.Rows.sample_x0`/``sample_x1``, found by the
    rasteriser's exact integer division at the sample's position). Pixels inside every sample's
    span (the most of a large triangle's) are fully covered; only the others are compared
    sample by sample. 0: the candidate covers no sample (inside a thin sliver)."""
    sl = slice(start, stop)
    x, expand = _fragment_rows(rows, start, stop, index)
    x0, x1 = rows.sample_x0[sl], rows.sample_x1[sl]
    if index is not None:
        return _masks(x, expand(x0), expand(x1), samples)
    inner = (x < expand(x0.max(axis=1))) | (x > expand(x1.min(axis=1)))  # not inside every sample's span
    mask = np.full(x.size, (1 << samples) - 1, dtype=np.uint8)
    edge = np.flatnonzero(inner)
    if edge.size:
        row = np.searchsorted(rows.length[sl].cumsum(), edge, side="right")
        mask[edge] = _masks(x.take(edge), x0.take(row, axis=0), x1.take(row, axis=0), samples)
    return mask


def sample_depth(setup: TriangleSetup, rows, start: int, stop: int, samples: int, offset_factor: float = 0.0,
                 offset_units: float = 0.0, index: np.ndarray | None = None) -> np.ndarray:
    """(M, N) int64 depth codes at every sample of the candidate pixels of MSAA rows ``[start,
    stop)`` (or of candidates ``index`` of them): §5's formula with the screen barycentrics at
    the sample, ``b_k = E_k / A``, where ``E_k`` there is ``E_k`` at the pixel centre plus
    ``dx_k*(oy_s - S/2) - dy_k*(ox_s - S/2)`` (integers), Offset included. The codes of samples
    a candidate does not cover are computed too, and meaningless."""
    sl = slice(start, stop)
    x, expand = _fragment_rows(rows, start, stop, index)
    px = x * SUBPIXEL + HALF
    dx, dy, _ = _row_edges(setup, rows, start, stop)
    ox, oy = (sample_offsets(samples) - HALF).T  # (N,) each, from the pixel centre
    ea = (expand(rows.c0[sl]) - expand(rows.dy0[sl]) * px)[:, None] + expand(dx[0][:, None] * oy - dy[0][:, None] * ox)
    eb = (expand(rows.c1[sl]) - expand(rows.dy1[sl]) * px)[:, None] + expand(dx[1][:, None] * oy - dy[1][:, None] * ox)
    area = expand(rows.area[sl])[:, None]
    ec = area - ea - eb
    farea = area.astype(np.float64)
    tri = expand(rows.tri[sl])
    swap = expand(rows.swap[sl])[:, None]
    zw = setup.zw
    z0, z1, z2 = (zw[:, k].take(tri)[:, None] for k in range(3))
    # Barycentrics in the triangle's own vertex order (a clockwise triangle was covered as
    # (v0, v2, v1)), as raster.rasterize_rows maps them.
    z = (ea / farea) * z0
    z += (np.where(swap, ec, eb) / farea) * z1
    z += (np.where(swap, eb, ec) / farea) * z2
    if offset_factor != 0.0 or offset_units != 0.0:
        z += (float(offset_factor) * setup.slope().take(tri) + float(offset_units) * 2.0**-24)[:, None]
    np.maximum(z, 0.0, out=z)
    np.minimum(z, 1.0, out=z)
    z *= DEPTH_MAX
    z += 0.5
    return np.floor(z, out=z).astype(np.int64)


#: The lowest set bit of each nonzero 8-bit coverage mask (entry 0 unused).
_LOWEST_BIT = np.array([0] + [(m & -m).bit_length() - 1 for m in range(1, 256)], dtype=np.int64)


def mask_bits(mask: np.ndarray, samples: int) -> np.ndarray:
    """(M, N) bool: bit ``s`` of each coverage mask (M,) uint8."""
    return ((mask[:, None] >> np.arange(samples, dtype=np.uint8)) & np.uint8(1)).astype(bool)


def sampled_chunk(shader, setup: TriangleSetup, rows, start: int, stop: int, state):
    """A chunk of a draw call under MSAA: the call's own chunk shader ``shader``
    (:data:`.fragment.ChunkShader`) shades the candidate pixels of rows ``[start, stop)`` (the
    union of the samples' spans) once each at the pixel centre — also where the centre itself
    lies outside the triangle, the attributes then extrapolated from its plane, as llvmpipe
    shades — and alpha-tests them; here each gets its coverage mask and, when the depth test
    or write needs it, a depth code per sample (:func:`coverage`, :func:`sample_depth`). Returns the
    chunk's :class:`.records.ShadedFragments` with ``coverage`` and (M, N) ``depth``, or None;
    its fragments stay one per candidate pixel of the rows (the calls of a fused chunk are cut
    by row), those covering no sample (inside thin slivers) with mask 0: they merge nothing."""
    shaded = shader(setup, rows, start, stop, state)  # state.depth_needed is False: no centre depth
    if shaded is None:
        return None
    p, n = state.pass_state, state.samples
    shaded.coverage = coverage(rows, start, stop, n)
    shaded.stored_depth = shaded.depth_fn = None
    if state.sample_depth_needed(rows, start, stop):
        shaded.stored_depth = sample_depth(setup, rows, start, stop, n, p.offset_factor, p.offset_units)
    elif state.observed:  # an observer reads the depth of a chunk that needs none
        shaded.depth_fn = lambda index: sample_depth(setup, rows, start, stop, n, p.offset_factor, p.offset_units,
                                                     index=index)
    return shaded


def merge_samples(buf: FrameBuffers, p: Pass, frags, tables=None, outcome: np.ndarray | None = None) -> None:
    """Apply MSAA pixel fragments ``frags`` (:class:`.records.ShadedFragments` with ``coverage``,
    alpha test done) of pass ``p``: AlphaToMask narrows each coverage mask (:func:`alpha_to_mask`),
    then every covered sample is one fragment for the merger at its sample's place in the buffers
    (``s*H*W + pix``: its sample plane) with its own depth and its pixel fragment's colour.

    Primitive order per sample: the pixel fragments are cut into layers of distinct pixels
    (:func:`.merger.primitive_layers`, draw order kept) and each layer is applied sample plane by
    sample plane (:func:`.merger.apply_layer`) — a layer's samples are distinct, and every
    sample sees its fragments in draw order. A fragment that covers every sample of a uniform
    pixel (:attr:`.merger.FrameBuffers.uniform`) in a pass whose samples all pass alike (no
    depth test needed, no stencil) gives every sample the same result: it is applied to plane 0
    alone and the pixel stays uniform. ``outcome`` (M, N) int8, optional: receives each sample's
    :class:`.merger.Outcome` (``NOT_COVERED`` and ``ALPHA_TO_MASK`` included)."""
    n, plane = buf.samples, buf.plane
    full = (1 << n) - 1
    mask = frags.coverage
    if p.alpha_to_mask:
        mask = mask & alpha_to_mask(frags.colors()[:, 3], n)
    if outcome is not None:
        outcome[:] = np.where(mask_bits(frags.coverage, n), Outcome.ALPHA_TO_MASK, Outcome.NOT_COVERED)
    if frags.count == 0:
        return
    pix, depth, rgba, ids = frags.pix, frags.stored_depth, frags.rgba, frags.ids

    def subset(sel: np.ndarray | None, keep: np.ndarray) -> np.ndarray:
        return np.flatnonzero(keep) if sel is None else sel[keep]

    def apply(frag: np.ndarray | None, sample, every_sample: bool = False) -> None:
        """Fragments ``frag`` (None: all) to their samples ``sample`` (an int: one plane, or (K,)
        each its own): one layer of distinct samples (``every_sample``: the outcome of each is
        that of all its samples)."""
        target = pix if frag is None else pix.take(frag)
        target = target + sample * plane
        codes = None if outcome is None else np.empty(target.size, dtype=np.int8)
        if frag is None:
            apply_layer(buf, p, target, None if depth is None else depth[:, sample], rgba, ids, lut, codes)
        else:
            apply_layer(buf, p, target, None if depth is None else depth[frag, sample],
                        None if rgba is None else rgba.take(frag, axis=0),
                        None if ids is None else ids.take(frag), lut, codes)
        if outcome is not None:
            at = slice(None) if frag is None else frag
            if every_sample:
                outcome[at] = codes[:, None]
            else:
                outcome[at, sample] = codes

    def per_sample(idx: np.ndarray | None) -> None:
        """Fragments ``idx`` (None: all; distinct pixels), each to its covered samples, all in one
        layer: their uniform pixels are spread first; those covering every sample may leave their
        pixel uniform again."""
        ipix = pix if idx is None else pix.take(idx)
        imask = mask if idx is None else mask.take(idx)
        spread = buf.uniform[ipix] & (imask != 0)
        if spread.any():
            buf.spread(ipix[spread])
        which, sample = np.nonzero(mask_bits(imask, n))  # fragment by fragment, samples ascending
        if which.size:
            apply(which if idx is None else idx.take(which), sample)
        covers = imask == full
        if covers.any():
            buf.rejoin(ipix[covers])

    def partial_once(idx: np.ndarray) -> None:
        """Fragments ``idx`` (distinct uniform pixels, some samples covered, a pass whose samples
        all pass alike): every covered sample gets the same result, so each is blended once, at
        its lowest covered sample, and the result copied to its other covered samples."""
        ipix, imask = pix.take(idx), mask.take(idx)
        buf.spread(ipix)
        lowest = _LOWEST_BIT[imask]
        apply(idx, lowest)
        packed = buf.packed()
        result = packed[lowest * plane + ipix]
        for s in range(n):
            copy = (((imask >> np.uint8(s)) & np.uint8(1)) != 0) & (lowest != s)
            if copy.any():
                packed[s * plane + ipix[copy]] = result[copy]
                if outcome is not None:
                    outcome[idx[copy], s] = outcome[idx[copy], lowest[copy]]

    if outcome is None and depth is not None and order_free_depth(p):
        # Applied one by one, each fragment keeps the nearer (farther) depth: a per-sample extreme.
        extreme = np.minimum if p.ztest in (CompareFunction.Less, CompareFunction.LEqual) else np.maximum
        for s in range(n):
            has = ((mask >> np.uint8(s)) & np.uint8(1)) != 0
            extreme.at(buf.depth, pix[has] + s * plane, depth[has, s])
        return
    lut = None if ids is None else find_table(buf, p, frags.palette, frags.count * n, tables)
    alike = depth is None and not p.stencil  # every covered sample passes: its result depends on its colour alone
    for sel in primitive_layers(pix, frags.disjoint, buf.peel_scratch()):
        if not alike:
            per_sample(sel)
            continue
        lpix = pix if sel is None else pix.take(sel)
        lmask = mask if sel is None else mask.take(sel)
        uniform = buf.uniform[lpix]
        once = (lmask == full) & uniform
        if once.all():
            apply(sel, 0, every_sample=True)
            continue
        if once.any():
            apply(subset(sel, once), 0, every_sample=True)
        part = uniform & ~once & (lmask != 0)
        if part.any():
            partial_once(subset(sel, part))
        rest = ~uniform
        if rest.any():
            per_sample(subset(sel, rest))
