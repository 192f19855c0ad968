"""Mipmaps (docs/pipeline.md §7, "Mipmaps"): a texture's mip chain, the level of detail of each
fragment's 2×2 pixel quad, and sampling through the chain with the three filters.

- :func:`build_chain`: level 0 is the texture in shading space (:class:`.shade.Texels`); each
  further level is the 2×2 box average of the level above, ``float32((((a + b) + c) + d) * 0.25)``
  (an RGBA32F texture's values: the OpenGL reference uploads the same numbers), down to 1×1;
  optionally with Unity's "Mip Maps Preserve Coverage" (:func:`coverage_scale`).
- :func:`quad_lod`: the LOD per 2×2 quad from the texture coordinates' screen derivatives, as the
  GL specification defines it (§8.14) and llvmpipe evaluates it: from the quad's top-left pixel
  in window coordinates (x and y even, y up), ``ddx`` to the next pixel of its row and ``ddy`` to
  the next of its column, each texture coordinate evaluated from the triangle's plane at those
  pixel centres (covered or not: helper pixels), ``λ = 0.5 × log2(ρ²)`` with
  ``ρ² = max((du/dx·w)² + (dv/dx·h)², (du/dy·w)² + (dv/dy·h)²)``. llvmpipe replaces log2 by a
  piecewise-linear ``fast_log2`` (exact at powers of two): its LOD differs from this by up to 0.043.
- :func:`sampling_lod`: :func:`quad_lod` where the level depends on it; triangles whose every quad
  certainly samples level 0 (a bound on ρ² over the triangle's quads, :func:`_level_zero_runs`)
  take λ = −inf instead, which samples the same level: magnified textures skip the per-quad work.
- :func:`sample_mipmapped`: ``Point`` = GL_NEAREST_MIPMAP_NEAREST, ``Bilinear`` =
  GL_LINEAR_MIPMAP_NEAREST (the nearest level, sampled bilinearly), ``Trilinear`` =
  GL_LINEAR_MIPMAP_LINEAR (two levels blended by the LOD's fraction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import raster, shade
from .gather import gather
from .scene import CYCLIC_AFTER, CYCLIC_NEXT
from .vertex import HALF, SUBPIXEL, TriangleSetup
from .vocabulary import Material, TextureFilter, TextureWrap

#: Output rows of a level computed per step while building a chain (bounds the temporaries).
ROWS = 256
#: Preserve Coverage's search: the scale starts at 1 and is bisected within [0, 4], at most this
#: many evaluations (NVIDIA Texture Tools' ``scaleAlphaToCoverage`` constants).
COVERAGE_STEPS = 10


@dataclass(eq=False)
class MipChain:
    """A texture's levels in shading space: ``levels[0]`` the texture's own :class:`.shade.Texels`,
    ``levels[L]`` ``max(1, h >> L) × max(1, w >> L)`` texels, down to 1×1."""

    levels: list[shade.Texels]

    @property
    def last(self) -> int:
        """The last level's number (GL's q)."""
        return len(self.levels) - 1


def _downsample(rows, h: int, w: int) -> np.ndarray:
    """The next level (max(1, h//2), max(1, w//2), 4) float32 of a level of h × w texels whose rows
    ``[lo, hi)`` ``rows(lo, hi)`` gives as (hi - lo, w, 4) float64: each texel the box average
    ``(((T[r0][c0] + T[r0][c1]) + T[r1][c0]) + T[r1][c1]) * 0.25`` of rows r0 = 2j, r1 = 2j + 1 and
    columns c0 = 2i, c1 = 2i + 1 (a side of one texel repeats it; a last odd row or column of the
    larger level is left out)."""
    h2, w2 = max(1, h // 2), max(1, w // 2)
    out = np.empty((h2, w2, 4), dtype=np.float32)
    c0 = np.arange(w2) * 2
    c1 = c0 + 1 if w > 1 else c0
    for lo in range(0, h2, ROWS):
        hi = min(h2, lo + ROWS)
        block = rows(2 * lo, min(h, 2 * hi))  # the source rows of output rows [lo, hi)
        r0 = np.arange(hi - lo) * 2
        r1 = r0 + 1 if h > 1 else r0
        top, bottom = block[r0], block[r1]
        acc = top[:, c0] + top[:, c1]
        acc += bottom[:, c0]
        acc += bottom[:, c1]
        acc *= 0.25
        out[lo:hi] = acc
    return out


def _coverage_count(alpha: np.ndarray, scale: float, cutoff: float) -> int:
    """Texels whose ``min(max(alpha * scale, 0), 1) >= cutoff`` (alpha (N,) float64)."""
    a = np.multiply(alpha, scale)
    np.maximum(a, 0.0, out=a)
    np.minimum(a, 1.0, out=a)
    return int(np.count_nonzero(a >= cutoff))


def coverage_scale(alpha: np.ndarray, cutoff: float, target: tuple[int, int]) -> float:
    """Preserve Coverage's alpha scale of a level whose alpha is ``alpha`` (N,) float64: the scale
    ``s`` whose coverage (the share of texels with ``min(max(a·s, 0), 1) >= cutoff``, the test of
    ``clip(a - _Cutoff)``) is nearest level 0's, ``target`` = (covered, texels). Searched as NVIDIA
    Texture Tools does: ``s = 1``, then up to :data:`COVERAGE_STEPS` evaluations bisecting within
    [0, 4] (too little coverage: raise, too much: lower, equal: stop); of the scales evaluated, the
    one with the smallest coverage error, ties to the one nearest 1 (exact: counts compared over a
    common denominator)."""
    covered0, texels0 = target
    n = alpha.size
    low, high, s = 0.0, 4.0, 1.0
    best = None
    for _ in range(COVERAGE_STEPS):
        count = _coverage_count(alpha, s, cutoff)
        diff = count * texels0 - covered0 * n  # sign of (coverage - target), exactly
        key = (abs(diff), abs(s - 1.0))
        if best is None or key < best[0]:
            best = (key, s)
        if diff < 0:
            low = s
        elif diff > 0:
            high = s
        else:
            break
        s = (low + high) * 0.5
    return best[1]


def build_chain(base: shade.Texels, preserve_coverage: bool = False, cutoff: float = 0.5) -> MipChain:
    """The mip chain of a texture whose level 0 is ``base`` (module docstring). With
    ``preserve_coverage`` each level L >= 1 is built from the unscaled level above, then its alpha
    becomes ``float32(min(max(a * s, 0), 1))`` with ``s`` = :func:`coverage_scale` against level 0's
    coverage at ``cutoff``."""
    h, w = base.shape[:2]

    def base_rows(lo: int, hi: int) -> np.ndarray:
        return base.fetch(np.arange(lo * w, hi * w, dtype=np.int64)).reshape(hi - lo, w, 4)

    target = None
    if preserve_coverage:
        alpha0 = np.concatenate([base_rows(lo, min(h, lo + ROWS))[..., 3].reshape(-1) for lo in range(0, h, ROWS)])
        target = (_coverage_count(alpha0, 1.0, float(cutoff)), alpha0.size)
    levels = [base]
    rows, size = base_rows, (h, w)
    while size != (1, 1):
        values = _downsample(rows, *size)
        size = values.shape[:2]
        kept = values
        if target is not None:
            kept = values.copy()
            alpha = values[..., 3].astype(np.float64).reshape(-1)
            scaled = np.multiply(alpha, coverage_scale(alpha, float(cutoff), target))
            np.maximum(scaled, 0.0, out=scaled)
            np.minimum(scaled, 1.0, out=scaled)
            kept[..., 3] = scaled.reshape(size)
        levels.append(shade.Texels(kept, None))

        def rows(lo: int, hi: int, values=values) -> np.ndarray:  # the unscaled level feeds the next
            return values[lo:hi].astype(np.float64)
    return MipChain(levels)


def level_of(chain: MipChain, index: int) -> np.ndarray:
    """Level ``index``'s texels (h, w, 4) float64 in shading space (for tests and references)."""
    texels = chain.levels[index]
    h, w = texels.shape[:2]
    return texels.fetch(np.arange(h * w, dtype=np.int64)).reshape(h, w, 4)


def _texture_uvs_at(setup: TriangleSetup, tri: np.ndarray, corners: np.ndarray, flat: np.ndarray,
                    material: Material, x: np.ndarray, y: np.ndarray,
                    steps: tuple[tuple[int, int], ...]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Texture coordinates (u', v') (N,) float64 of setup triangles ``tri`` (N,) at the pixel
    centres ``(x + dx, y + dy)`` for each ``(dx, dy)`` of ``steps`` ((x, y) (N,) int64), covered or
    not: docs/pipeline.md §4's edge functions at the pixel centre divided by the doubled area (the
    sign taken to the numerator, as for a clockwise triangle's coverage order), §6's
    perspective-correct weights and interpolation (``flat`` triangles take their corner value),
    then ``_MainTex``'s tiling and offset. The edge functions of a step are the first point's plus
    integer multiples of the edge's extent (exact), the rest is evaluated per point."""
    # Rows of three by np.take: fancy indexing of (N, 3) rows costs several times more.
    X, Y = gather(setup.X, tri, axis=0), gather(setup.Y, tri, axis=0)
    area = gather(setup.area2, tri)
    sign = np.where(area < 0, -1, 1)
    farea = np.abs(area).astype(np.float64)
    px = x * SUBPIXEL + HALF
    py = y * SUBPIXEL + HALF
    edges = []  # per edge k (opposite vertex k, from vertex k+1 to vertex k+2): E at (x, y), dx, dy
    for k in range(3):
        p, q = (k + 1) % 3, (k + 2) % 3
        dx, dy = X[:, q] - X[:, p], Y[:, q] - Y[:, p]
        edges.append((dx * (py - Y[:, p]) - dy * (px - X[:, p]), dx, dy))
    iw = gather(setup.iw, tri, axis=0)
    clipped = None
    if setup.weights is not None:
        clipped = setup.clipped[tri]
        clipped = clipped if clipped.any() else None
        wts = None if clipped is None else setup.weights[tri[clipped]]  # (M, 3 vertices, 3 source corners)
    out = []
    for step_x, step_y in steps:
        bary = []
        for e, dx, dy in edges:
            # E(Px + S*step_x, Py + S*step_y) = E + dx*S*step_y - dy*S*step_x, in integers.
            at = e if step_x == 0 and step_y == 0 else e + (dx * (SUBPIXEL * step_y) - dy * (SUBPIXEL * step_x))
            bary.append(np.divide((at * sign).astype(np.float64), farea))
        t = [bary[k] * iw[:, k] for k in range(3)]
        s = (t[0] + t[1]) + t[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            o = [np.divide(t[k], s) for k in range(3)]
        if clipped is not None:
            oc = [v[clipped] for v in o]
            mixed = (oc[0][:, None] * wts[:, 0] + oc[1][:, None] * wts[:, 1]) + oc[2][:, None] * wts[:, 2]
            for k in range(3):
                o[k][clipped] = mixed[:, k]
        uv = []
        for c in range(2):
            a = np.multiply(o[0], corners[:, 0, c])
            a += o[1] * corners[:, 1, c]
            a += o[2] * corners[:, 2, c]
            a[flat] = corners[flat, 0, c]
            uv.append(a)
        out.append(shade.texture_uv_of(material, uv[0], uv[1]))
    return out


def quad_lod(setup: TriangleSetup, tri: np.ndarray, pix: np.ndarray, width: int, material: Material,
             size: tuple[int, int]) -> np.ndarray:
    """The LOD λ (N,) float64 of fragments of setup triangles ``tri`` (N,) int64 at window pixels
    ``pix`` (N,) int64 (``y * width + x``, y up) of a texture whose level 0 is ``size`` = (h, w)
    texels (module docstring; λ = −inf where the coordinates do not change, NaN where they are not
    finite)."""
    x, y = pix % width, pix // width
    return _quad_lod_runs(setup, tri, x & ~1, y & ~1, width, material, size)


def sampling_lod(setup: TriangleSetup, tri: np.ndarray, pix: np.ndarray, width: int, material: Material,
                 size: tuple[int, int]) -> np.ndarray:
    """:func:`quad_lod` where it decides the sampled level, −inf for the fragments of triangles
    whose every quad here certainly samples level 0 (:func:`_level_zero_runs`): the same level,
    so :func:`sample_mipmapped` gives the same samples (magnified textures skip the per-quad LOD)."""
    x, y = pix % width, pix // width
    x0, y0 = x & ~1, y & ~1
    if tri.size >= BOUND_MIN_FRAGMENTS:
        starts = np.flatnonzero(tri[1:] != tri[:-1]) + 1  # runs of one triangle
        starts = np.concatenate([np.zeros(1, dtype=np.int64), starts])
        proved = _level_zero_runs(setup, tri.take(starts), np.minimum.reduceat(x0, starts),
                                  np.maximum.reduceat(x0, starts), np.minimum.reduceat(y0, starts),
                                  np.maximum.reduceat(y0, starts), material, size)
        if proved.any():
            lod = np.full(tri.size, -np.inf, dtype=np.float64)
            if proved.all():
                return lod
            lengths = np.diff(np.append(starts, tri.size))
            rest = np.flatnonzero(~proved.repeat(lengths))
            lod[rest] = _quad_lod_runs(setup, tri[rest], x0[rest], y0[rest], width, material, size)
            return lod
    return _quad_lod_runs(setup, tri, x0, y0, width, material, size)


def _quad_lod_runs(setup: TriangleSetup, tri: np.ndarray, x0: np.ndarray, y0: np.ndarray, width: int,
                   material: Material, size: tuple[int, int]) -> np.ndarray:
    """:func:`_quad_lods` of fragments' (triangle, quad) pairs ``tri``, ``x0``, ``y0`` (N,) int64."""
    # Fragments of one triangle in one 2x2 quad share λ: a row's neighbours (x0, x0 + 1) come one
    # after the other, so each run of equal (triangle, quad) is computed once and expanded.
    first = np.ones(tri.size, dtype=bool)
    if tri.size > 1:
        same = tri[1:] == tri[:-1]
        same &= x0[1:] == x0[:-1]
        same &= y0[1:] == y0[:-1]
        first[1:] = ~same
    if not first.all():
        runs = first.cumsum() - 1
        at = np.flatnonzero(first)
        return _quad_lods(setup, tri[at], x0[at], y0[at], width, material, size)[runs]
    return _quad_lods(setup, tri, x0, y0, width, material, size)


#: Fewer fragments than this skip the per-triangle bound of :func:`_level_zero_runs`.
BOUND_MIN_FRAGMENTS = 256
#: The bound must stay within this share of the threshold: the rest covers rounding (see below).
BOUND_MARGIN = 0.9
#: Relative allowance for the rounding of the bound's own arithmetic (each term is a few products).
BOUND_ROUNDING = 1e-9
#: Texture coordinates times the texture size up to this keep the λ's own rounding negligible.
BOUND_MAGNITUDE = float(1 << 20)


def _level_zero_runs(setup: TriangleSetup, tri: np.ndarray, x_lo: np.ndarray, x_hi: np.ndarray,
                     y_lo: np.ndarray, y_hi: np.ndarray, material: Material,
                     size: tuple[int, int]) -> np.ndarray:
    """(R,) bool: runs of fragments, of setup triangles ``tri`` (R,) int64 whose quads' lower-left
    pixels lie within ``[x_lo, x_hi] × [y_lo, y_hi]`` ((R,) int64 each), that certainly sample
    level 0 (λ ≤ 0 for ``Trilinear``, λ ≤ 0.5 otherwise), so their λ need not be computed.

    A coordinate is ``u = N / D`` with N and D affine in the pixel centre P (§6: the edge
    functions weighted by 1/w, and by the corner values for N). A step e of one pixel then changes
    it by ``(Nₑ·D(P) − N(P)·Dₑ) / (D(P)·D(P + e))``: the numerator is affine in P (its terms in the
    step's own direction cancel), so its largest size over the box of the quads' pixels (the box
    grown by the quads' second row and column) is at a corner, and so is D's smallest value, which
    must be positive. The bound on ρ² that follows must stay under BOUND_MARGIN of the threshold
    after an allowance for its own rounding, and the coordinates must stay small enough
    (BOUND_MAGNITUDE) that the computed λ's rounding (relative 1e-15 of them) cannot cross it."""
    h, w = size
    trilinear = material.main_tex_filter is TextureFilter.Trilinear
    limit = BOUND_MARGIN * (1.0 if trilinear else 2.0)
    X = gather(setup.X, tri, axis=0).astype(np.float64)
    Y = gather(setup.Y, tri, axis=0).astype(np.float64)
    sign = np.where(gather(setup.area2, tri) < 0, -1.0, 1.0)
    iw = gather(setup.iw, tri, axis=0) * sign[:, None]
    corners = setup.uvs_of(setup.src[tri])  # (R, 3, 2)
    if setup.weights is not None:
        clipped = np.flatnonzero(setup.clipped[tri])
        if clipped.size:
            corners = corners.copy()
            corners[clipped] = np.einsum("rkj,rjc->rkc", setup.weights[tri[clipped]], corners[clipped])
    tiling = np.asarray(material.main_tex_tiling, dtype=np.float64)
    offset = np.asarray(material.main_tex_offset, dtype=np.float64)
    extent = np.array([w, h], dtype=np.float64)  # texels across u and v
    lo_x = x_lo.astype(np.float64) * SUBPIXEL + HALF
    hi_x = (x_hi + 1).astype(np.float64) * SUBPIXEL + HALF
    lo_y = y_lo.astype(np.float64) * SUBPIXEL + HALF
    hi_y = (y_hi + 1).astype(np.float64) * SUBPIXEL + HALF
    cx, cy = 0.5 * (lo_x + hi_x), 0.5 * (lo_y + hi_y)
    hx, hy = 0.5 * (hi_x - lo_x), 0.5 * (hi_y - lo_y)
    # Per edge k (columns; from vertex k+1 to vertex k+2): E_k(centre + d) = e0 + ea·dx + eb·dy,
    # each weighted by 1/w (D's terms); the three edges at once, (R, 3) each.
    xp, yp = X[:, CYCLIC_NEXT], Y[:, CYCLIC_NEXT]
    ex, ey = X[:, CYCLIC_AFTER] - xp, Y[:, CYCLIC_AFTER] - yp
    e0 = ex * (cy[:, None] - yp)
    e0 -= ey * (cx[:, None] - xp)
    e0 *= iw
    ea = -ey * iw
    eb = ex * iw
    d0, da, db = _edge_sum(e0), _edge_sum(ea), _edge_sum(eb)
    d0_abs, da_abs, db_abs = _edge_sum(np.abs(e0)), _edge_sum(np.abs(ea)), _edge_sum(np.abs(eb))
    d_min = d0 - np.abs(da) * hx - np.abs(db) * hy
    d_min -= BOUND_ROUNDING * (d0_abs + da_abs * hx + db_abs * hy)
    rho_x = np.zeros_like(cx)  # bounds on ρ² times d_min⁴, per step direction
    rho_y = np.zeros_like(cx)
    big = np.zeros(cx.size, dtype=bool)
    for c in range(2):
        value = np.ascontiguousarray(corners[:, :, c])  # (R, 3)
        texture = np.abs(value * tiling[c] + offset[c]) * extent[c]
        big |= texture.max(axis=1) > BOUND_MAGNITUDE
        # N's terms, as D's: the corner values weighted by the edges' terms.
        p0, pa, pb = e0 * value, ea * value, eb * value
        n0, na, nb = _edge_sum(p0), _edge_sum(pa), _edge_sum(pb)
        n0_abs, na_abs, nb_abs = _edge_sum(np.abs(p0)), _edge_sum(np.abs(pa)), _edge_sum(np.abs(pb))
        cross = np.abs(na * db - da * nb)
        cross_abs = na_abs * db_abs + da_abs * nb_abs
        along_x = np.abs(na * d0 - da * n0) + cross * hy
        along_x += BOUND_ROUNDING * (na_abs * d0_abs + da_abs * n0_abs + cross_abs * hy)
        along_y = np.abs(nb * d0 - db * n0) + cross * hx
        along_y += BOUND_ROUNDING * (nb_abs * d0_abs + db_abs * n0_abs + cross_abs * hx)
        scale = SUBPIXEL * abs(tiling[c]) * extent[c]  # a coordinate's step in texels
        rho_x += (along_x * scale) ** 2
        rho_y += (along_y * scale) ** 2
    with np.errstate(over="ignore", invalid="ignore"):
        rho = np.maximum(rho_x, rho_y)
        proved = rho <= limit * d_min ** 4
    proved &= np.isfinite(rho)  # (an overflow to inf on both sides would compare true)
    proved &= d_min > 0.0
    proved &= ~big
    return proved


def _edge_sum(terms: np.ndarray) -> np.ndarray:
    """(R,) float64: the sum of the three edges' terms (R, 3), edge after edge."""
    total = terms[:, 0] + terms[:, 1]
    total += terms[:, 2]
    return total


#: Fewer quads than this are computed as they come (finding the shared ones costs more).
SHARED_QUADS_MIN = 1024


def _quad_lods(setup: TriangleSetup, tri: np.ndarray, x0: np.ndarray, y0: np.ndarray, width: int,
               material: Material, size: tuple[int, int]) -> np.ndarray:
    """:func:`_quad_lod_at` of (triangle, quad) pairs ``tri``, ``x0``, ``y0`` (N,) int64, each
    pair computed once where it comes again: a quad's two rows come one after the other in a
    triangle's rows, so most quads come twice. Each quad records the last entry that wrote it
    (which one does not matter); an entry whose recorded one has its triangle takes that one's
    λ, the others are computed."""
    n = tri.size
    if n < SHARED_QUADS_MIN:
        return _quad_lod_at(setup, tri, x0, y0, material, size)
    quad = (y0 >> 1) * ((width + 1) >> 1) + (x0 >> 1)
    low = int(quad.min())
    quad -= low
    holder_of = np.empty(int(quad.max()) + 1, dtype=np.int64)  # only entries written here are read
    own = np.arange(n, dtype=np.int64)
    holder_of[quad] = own
    holder = holder_of[quad]
    shared = holder != own
    shared &= tri.take(holder) == tri
    if not shared.any():
        return _quad_lod_at(setup, tri, x0, y0, material, size)
    mine = np.flatnonzero(~shared)
    lod = np.empty(n, dtype=np.float64)
    lod[mine] = _quad_lod_at(setup, tri[mine], x0[mine], y0[mine], material, size)
    taken = np.flatnonzero(shared)
    lod[taken] = lod[holder[taken]]
    return lod


def _quad_lod_at(setup: TriangleSetup, tri: np.ndarray, x0: np.ndarray, y0: np.ndarray, material: Material,
                 size: tuple[int, int]) -> np.ndarray:
    """:func:`quad_lod` of the quads whose lower-left pixels are ``(x0, y0)`` (N,) int64 (even)."""
    h, w = size
    corners = setup.uvs_of(setup.src[tri])
    flat = raster.flat_corners(corners)
    (u00, v00), (u10, v10), (u01, v01) = _texture_uvs_at(setup, tri, corners, flat, material, x0, y0,
                                                         ((0, 0), (1, 0), (0, 1)))
    with np.errstate(invalid="ignore", over="ignore"):
        a = (u10 - u00) * w
        b = (v10 - v00) * h
        rx = a * a + b * b
        a = (u01 - u00) * w
        b = (v01 - v00) * h
        ry = a * a + b * b
        rho2 = np.maximum(rx, ry)
    return 0.5 * log2(rho2)


#: Whether numpy's float64 ``log2`` gave C's ``log2`` (``math.log2``) on a sample of this machine
#: (None: not checked yet). numpy builds with AVX-512 kernels (SVML) differ in the last bit.
_NUMPY_LOG2_IS_C: bool | None = None


def numpy_log2_is_c() -> bool:
    """Whether numpy's float64 ``log2`` equals C's on this machine: checked once, on 4,096
    values spread over 2**-57 .. 2**57 (about 1 ms)."""
    global _NUMPY_LOG2_IS_C
    if _NUMPY_LOG2_IS_C is None:
        sample = np.exp(np.linspace(-40.0, 40.0, 4096)) * 1.000000001
        _NUMPY_LOG2_IS_C = bool(np.array_equal(np.log2(sample), _c_log2(sample)))
    return _NUMPY_LOG2_IS_C


def _c_log2(values: np.ndarray) -> np.ndarray:
    """C's ``log2`` (N,) float64 of positive finite ``values`` (N,) float64, one ``math.log2`` each."""
    return np.fromiter(map(math.log2, values.tolist()), dtype=np.float64, count=values.size)


def log2(values: np.ndarray) -> np.ndarray:
    """C's ``log2`` (the scalar reference's ``math.log2``) of ``values`` (N,) float64, element by
    element, as a new (N,) float64 array: ``log2(0) = -inf``, ``log2(inf) = inf``, NaN for NaN and
    negatives. numpy's own where it equals C's on this machine (:func:`numpy_log2_is_c`); else
    numpy's for the special values and C's for the others, once per run of equal values (the
    quads of one triangle often share their ρ²)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.log2(values)
    if numpy_log2_is_c():
        return out
    at = np.flatnonzero(np.isfinite(out))  # finite, positive values: C's log2 is finite there too
    if at.size:
        finite = values.take(at)
        starts = np.flatnonzero(np.concatenate(([True], finite[1:] != finite[:-1])))
        counts = np.diff(np.append(starts, finite.size))
        out.reshape(-1)[at] = _c_log2(finite.take(starts)).repeat(counts)
    return out


def _sample_levels(chain: MipChain, uv: np.ndarray, level: np.ndarray, filt: TextureFilter, wrap: TextureWrap,
                   channels: tuple[int, ...]) -> np.ndarray:
    """Each fragment's texel sample (C, N) float64 (channels first) of ``channels`` at ``uv`` (N, 2)
    float64 in its level ``level`` (N,) int64."""
    present = np.flatnonzero(np.bincount(level))  # the levels in use (a count, not np.unique's sort)
    if present.size == 1:
        return _sample_at(chain.levels[int(present[0])], uv, filt, wrap, channels)
    out = np.empty((len(channels), uv.shape[0]), dtype=np.float64)
    for index in present.tolist():
        at = np.flatnonzero(level == index)
        out[:, at] = _sample_at(chain.levels[index], _coordinates_at(uv, at), filt, wrap, channels)
    return out


def _sample_at(texels: shade.Texels, uv: np.ndarray, filt: TextureFilter, wrap: TextureWrap,
               channels: tuple[int, ...]) -> np.ndarray:
    """:func:`.shade.sample` of one level at ``uv`` (N, 2) float64 as (C, N) float64: the sampler
    reads the coordinates as columns (contiguous ones from a channels-first pair's transposed
    view) and writes channels first."""
    return np.ascontiguousarray(shade.sample(texels, uv, filt, wrap, channels).T)


def _coordinates_at(uv: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Rows ``index`` (M,) of ``uv`` (N, 2), as the transposed view of a channels-first (2, M) pair."""
    out = np.empty((2, index.size), dtype=np.float64)
    gather(uv[:, 0], index, out=out[0])
    gather(uv[:, 1], index, out=out[1])
    return out.T


def sample_mipmapped(chain: MipChain, uv: np.ndarray, lod: np.ndarray, filt: TextureFilter,
                     wrap: TextureWrap, channels: tuple[int, ...] = (0, 1, 2, 3)) -> np.ndarray:
    """Sample (N, C) float64 of ``channels`` (default all four) at texture coordinates ``uv`` (N, 2)
    float64 (after tiling and offset) with LOD ``lod`` (N,) float64 (GL 4.5 §8.14.3; a NaN LOD
    samples level 0):

    - ``Point`` / ``Bilinear``: the nearest level ``d`` (0 unless λ > 0.5, then ``ceil(λ + 0.5) − 1``,
      at most the last), sampled with the nearest texel / bilinearly (§7);
    - ``Trilinear``: level 0 bilinearly unless λ > 0; then ``d = floor(λ)``: the last level alone
      when ``d`` reaches it, else ``t0 * (1 − f) + t1 * f`` of levels ``d`` and ``d + 1`` sampled
      bilinearly, ``f = λ − d``.

    The result is the transposed view of a channels-first (C, N) array: each channel contiguous.
    """
    last = chain.last
    level = np.zeros(uv.shape[0], dtype=np.int64)
    if filt is not TextureFilter.Trilinear:
        far = np.flatnonzero(lod > 0.5)
        level[far] = np.minimum(np.ceil(lod[far] + 0.5) - 1.0, float(last)).astype(np.int64)
        return _sample_levels(chain, uv, level, filt, wrap, channels).T
    minified = np.flatnonzero(lod > 0.0)
    floor = np.floor(lod[minified])
    level[minified] = np.minimum(floor, float(last)).astype(np.int64)
    out = _sample_levels(chain, uv, level, filt, wrap, channels)
    below = floor < last
    mixed = minified[below]
    if mixed.size:
        f = lod[mixed] - floor[below]
        g = 1.0 - f
        every = mixed.size == level.size  # (then mixed is 0..N-1)
        upper = _sample_levels(chain, uv if every else _coordinates_at(uv, mixed), level[mixed] + 1, filt, wrap,
                               channels)
        # t0 * (1 - f) + t1 * f per element, one channel at a time.
        lower = out if every else gather(out, mixed, axis=1)
        for c in range(lower.shape[0]):
            lower[c] *= g
            upper[c] *= f
            lower[c] += upper[c]
        if not every:
            out[:, mixed] = lower
    return out.T
