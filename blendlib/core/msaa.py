"""Multisampling (docs/pipeline.md §10): sample patterns, per-sample coverage and depth,
AlphaToMask, sample fragments for the merger, and the resolve.

With ``DrawScene.msaa`` N > 1 the buffers hold N samples per pixel (sample ``s`` of window
pixel ``p`` at index ``p*N + s``). A draw call's rows are the pixels where at least one sample
is covered (:func:`.raster.coverage_rows` with ``samples``); each such pixel is one *pixel
fragment*, shaded once at the pixel centre, with a coverage mask (bit ``s`` = sample ``s``,
:func:`coverage_and_depth`) and a depth code per sample. The merger receives one *sample
fragment* per covered sample (:func:`sample_fragments`): each sample is a pixel of its own for
the depth and stencil tests, blending and primitive order, so the merger's layer machinery
applies unchanged. :func:`resolve_colors` averages the samples as llvmpipe's resolve does.
"""

from __future__ import annotations

import numpy as np

from .merger import FrameBuffers, Outcome, merge
from .vertex import DEPTH_MAX, HALF, SUBPIXEL, TriangleSetup
from .vocabulary import Pass

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
    X = np.take(setup.X, tri, axis=0)
    ax = X[:, 0]
    bx = np.where(swap, X[:, 2], X[:, 1])
    cx = np.where(swap, X[:, 1], X[:, 2])
    dx = (cx - bx, ax - cx, bx - ax)
    dy0, dy1 = rows.dy0[start:stop], rows.dy1[start:stop]
    dy = (dy0, dy1, -(dy0 + dy1))
    bias = tuple(((d_y > 0) | ((d_y == 0) & (d_x >= 0))).astype(np.int64) for d_x, d_y in zip(dx, dy, strict=True))
    return dx, dy, bias


def coverage_and_depth(setup: TriangleSetup, rows, start: int, stop: int, width: int, samples: int,
                       depth: bool, offset_factor: float = 0.0, offset_units: float = 0.0,
                       index: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Coverage masks and per-sample depth codes of the candidate pixels of rows ``[start, stop)``
    (in the order :func:`.raster.rasterize_rows` gives them), or of candidates ``index`` (K,) of
    them only.

    Sample ``s`` at ``(x*S + ox_s, y*S + oy_s)`` is covered when every edge function there is
    ``> 0``, or ``== 0`` on a top-left edge (docs/pipeline.md §4); ``E_k`` at the sample is
    ``E_k`` at the pixel centre plus ``dx_k*(oy_s - S/2) - dy_k*(ox_s - S/2)``, all in integers.
    Depth at a sample: ``b_k = E_k / A`` (the screen barycentrics there) in §5's formula, Offset
    included. Returns ``mask`` (M,) uint8 (bit s: sample s covered; 0 for a candidate whose
    samples are all outside) and, with ``depth``, ``codes`` (M, N) int64 (those of samples not
    covered are computed but meaningless), else None.
    """
    length = rows.length[start:stop]
    first = np.cumsum(length) - length
    if index is None:
        n = int(length.sum())
        row = np.repeat(np.arange(length.size, dtype=np.int64), length)
        at = np.arange(n, dtype=np.int64) - np.take(first, row)
    else:
        row = np.searchsorted(np.cumsum(length), index, side="right")
        at = index - np.take(first, row)
    sl = slice(start, stop)
    x = np.take(rows.x0[sl], row) + at
    px = x * SUBPIXEL + HALF
    e0 = np.take(rows.c0[sl], row) - np.take(rows.dy0[sl], row) * px
    e1 = np.take(rows.c1[sl], row) - np.take(rows.dy1[sl], row) * px
    area = np.take(rows.area[sl], row)
    dx, dy, bias = _row_edges(setup, rows, start, stop)
    offsets = sample_offsets(samples) - HALF  # (N, 2) from the pixel centre
    mask = np.zeros(row.size, dtype=np.uint8)
    codes = np.empty((row.size, samples), dtype=np.int64) if depth else None
    if depth:
        zw = setup.zw
        tri = np.take(rows.tri[sl], row)
        swap = np.take(rows.swap[sl], row)
        z0, z1, z2 = (np.take(zw[:, k], tri) for k in range(3))
        farea = area.astype(np.float64)
        slope = None
        if offset_factor != 0.0 or offset_units != 0.0:
            slope = float(offset_factor) * np.take(setup.slope(), tri) + float(offset_units) * 2.0**-24
    for s, (ox, oy) in enumerate(offsets.tolist()):
        # The edge functions at the sample: the centre's plus a per-row step.
        ea = e0 + np.take(dx[0] * oy - dy[0] * ox, row)
        eb = e1 + np.take(dx[1] * oy - dy[1] * ox, row)
        ec = area - ea - eb
        covered = (ea >= np.take(bias[0], row)) & (eb >= np.take(bias[1], row)) & (ec >= np.take(bias[2], row))
        mask |= covered.astype(np.uint8) << np.uint8(s)
        if depth:
            # Barycentrics in the triangle's own vertex order (a clockwise triangle was covered
            # as (v0, v2, v1)), as raster.rasterize_rows maps them.
            b0 = ea / farea
            b1 = np.where(swap, ec, eb) / farea
            b2 = np.where(swap, eb, ec) / farea
            z = (b0 * z0 + b1 * z1) + b2 * z2
            if slope is not None:
                z = z + slope
            z = np.minimum(np.maximum(z, 0.0), 1.0)
            codes[:, s] = np.floor(z * DEPTH_MAX + 0.5).astype(np.int64)
    return mask, codes


def mask_bits(mask: np.ndarray, samples: int) -> np.ndarray:
    """(M, N) bool: bit ``s`` of each coverage mask (M,) uint8."""
    return ((mask[:, None] >> np.arange(samples, dtype=np.uint8)) & np.uint8(1)).astype(bool)


def sampled_chunk(shader, setup: TriangleSetup, rows, start: int, stop: int, state):
    """A chunk of a draw call under MSAA: the call's own chunk shader ``shader``
    (:data:`.fragment.ChunkShader`) shades the candidate pixels of rows ``[start, stop)`` (the
    union of the samples' spans) once each at the pixel centre — also where the centre itself
    lies outside the triangle, the attributes then extrapolated from its plane, as llvmpipe
    shades — and alpha-tests them; here each gets its coverage mask and, when the depth test
    or write needs it, a depth code per sample (:func:`coverage_and_depth`). Returns the
    chunk's :class:`.records.ShadedFragments` with ``coverage`` and (M, N) ``depth``, or None;
    its fragments stay one per candidate pixel of the rows (the calls of a fused chunk are cut
    by row), those covering no sample (inside thin slivers) with mask 0: they merge nothing."""
    shaded = shader(setup, rows, start, stop, state)  # state.depth_needed is False: no centre depth
    if shaded is None:
        return None
    p = state.pass_state
    want = state.sample_depth_needed(rows, start, stop)
    mask, codes = coverage_and_depth(setup, rows, start, stop, state.width, state.samples, want,
                                     p.offset_factor, p.offset_units)
    shaded.coverage = mask
    shaded.stored_depth = codes
    shaded.depth_fn = None
    if codes is None and state.observed:  # an observer reads the depth of a chunk that needs none
        def depth_fn(index):
            return coverage_and_depth(setup, rows, start, stop, state.width, state.samples, True, p.offset_factor,
                                      p.offset_units, index=index)[1]

        shaded.depth_fn = depth_fn
    return shaded


def merge_samples(buf: FrameBuffers, p: Pass, frags, tables=None, outcome: np.ndarray | None = None) -> None:
    """Apply MSAA pixel fragments ``frags`` (:class:`.records.ShadedFragments` with ``coverage``,
    alpha test done) of pass ``p``: AlphaToMask narrows each coverage mask (:func:`alpha_to_mask`),
    then every covered sample is one fragment for the merger (:func:`.merger.merge`) at its
    sample's place in the buffers (``pix*N + s``) with its own depth and its pixel fragment's
    colour — pixel fragments in order, their samples in ascending order, so primitive order
    holds per sample. ``outcome`` (M, N) int8, optional: receives each sample's
    :class:`.merger.Outcome` (``NOT_COVERED`` and ``ALPHA_TO_MASK`` included)."""
    n = buf.samples
    mask = frags.coverage
    if p.alpha_to_mask:
        mask = mask & alpha_to_mask(frags.colors()[:, 3], n)
    if outcome is not None:
        covered = mask_bits(frags.coverage, n)
        outcome[:] = np.where(covered, Outcome.ALPHA_TO_MASK, Outcome.NOT_COVERED)
    which, sample = np.nonzero(mask_bits(mask, n))
    if which.size == 0:
        return
    index = np.take(frags.pix, which) * n + sample
    depth = None if frags.stored_depth is None else frags.stored_depth[which, sample]
    rgba = None if frags.rgba is None else np.take(frags.rgba, which, axis=0)
    ids = None if frags.ids is None else np.take(frags.ids, which)
    written = None if outcome is None else np.empty(which.size, dtype=np.int8)
    merge(buf, p, index, depth, rgba, ids, frags.palette, outcome=written, disjoint=frags.disjoint, tables=tables)
    if outcome is not None:
        outcome[which, sample] = written
