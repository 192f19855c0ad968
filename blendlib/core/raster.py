"""Raster stage (docs/pipeline.md §4–§6), vectorised numpy.

- :func:`coverage_rows`: the triangles a pass draws → per-row candidate spans.
- :func:`rasterize_rows`: a slice of those rows → :class:`Fragments` (exact integer
  top-left coverage), in draw order.
- :func:`interpolate`: fragments → 24-bit depth and perspective-correct weights.

Work is proportional to covered pixels plus rows (spans), not to bounding boxes.

One concern in one module, over 700 lines: the integer edge functions of §4, from the spans they
bound to the barycentrics and depth they give, with the bounds under which each step computes
them in float64 or int64 (2**53, 2**63) beside the arithmetic they guard; split, a bound would
live apart from the arithmetic whose exactness it proves.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .gather import gather
from .parts import PIECE, run_parts
from .vertex import DEPTH_MAX, HALF, SUBPIXEL, TriangleSetup

_SHIFT = SUBPIXEL.bit_length() - 1
assert SUBPIXEL == 1 << _SHIFT  # divisions by S are shifts
#: Span ends are found by float64 division below this numerator bound (exact there), else in int64.
FLOAT_DIVISION_LIMIT = 2**53
#: By an edge's side (sign of dy, plus one): what :func:`_spans` adds to its float64 bound on a
#: row's last pixel (dy > 0 bounds it: + 0) and subtracts it from for the first (dy < 0: 0 - q);
#: the infinities leave the other side as it is.
_UPPER_ADDEND = np.array([np.inf, np.inf, 0.0])
_LOWER_ADDEND = np.array([0.0, -np.inf, -np.inf])
#: By whether an MSAA sample's span on a row is empty (0) or not (1): what moves its first pixel
#: out of the row's hull (and is taken from its last).
_EMPTY_ADDEND = np.array([np.inf, 0.0])


@dataclass(eq=False)
class Rows:
    """Spans of a pass: one entry per (triangle, pixel row) with covered pixels, in draw order.

    ``tri`` (R,) int64 setup index; ``y`` (R,) int64 pixel row (from the bottom);
    ``x0`` (R,) int64 first covered column and ``length`` (R,) int64 covered pixels: the
    span ``[x0, x0 + length)`` is exactly the row's covered pixels (top-left rule applied
    in integers). ``c0``, ``c1``, ``dy0``, ``dy1`` (R,) int64: the row's edge functions
    ``E_k = c_k - dy_k*Px`` for the counter-clockwise edges b→c and c→a (the third is
    ``area - E_0 - E_1``); ``swap`` (R,) bool: the triangle was clockwise and its coverage
    order is (v0, v2, v1); ``area`` (R,) int64 |area2|.

    With MSAA (:func:`coverage_rows` with ``samples``) the span is the union of the samples'
    spans and ``sample_x0``, ``sample_x1`` (R, N) int64 hold each sample's own: sample ``s``
    of pixel ``x`` is covered exactly when ``sample_x0[s] <= x <= sample_x1[s]`` (empty when
    ``sample_x0 > sample_x1``); None without.
    """

    tri: np.ndarray
    y: np.ndarray
    x0: np.ndarray
    length: np.ndarray
    c0: np.ndarray
    c1: np.ndarray
    dy0: np.ndarray
    dy1: np.ndarray
    swap: np.ndarray
    area: np.ndarray
    sample_x0: np.ndarray | None = None
    sample_x1: np.ndarray | None = None

    @property
    def count(self) -> int:
        return int(self.tri.shape[0])

    def each_field(self, fn: Callable[[str, np.ndarray], np.ndarray]) -> Rows:
        """``Rows`` of ``fn(name, array)`` for every field (the MSAA fields stay None without MSAA)."""
        return Rows(**{name: None if (v := getattr(self, name)) is None else fn(name, v)
                       for name in self.__dataclass_fields__})

    def take(self, mask: np.ndarray) -> Rows:
        """The rows where ``mask`` is True, order kept."""
        # One index list, then a gather per field: boolean indexing of each field costs
        # several times more when the mask is irregular (small triangles).
        return self.take_rows(np.flatnonzero(mask))

    def take_rows(self, index: np.ndarray) -> Rows:
        """The rows at positions ``index`` (int), in that order."""
        return self.each_field(lambda _, v: v.take(index, axis=0))

    def split_bands(self, bands: int, height: int) -> list[Rows]:
        """Split into up to ``bands`` horizontal screen bands of about equal fragment counts.

        Bands cover disjoint pixel rows, so they can be merged independently and exactly.
        """
        if bands <= 1 or self.count == 0:
            return [self]
        cuts = band_cuts([self], bands, height)
        if cuts is None:
            return [self]
        return [part for part in self.split_at(cuts) if part.count]

    def split_at(self, cuts: np.ndarray) -> list[Rows]:
        """One :class:`Rows` per band of :func:`band_cuts` (band k: ``cuts[k-1] <= y < cuts[k]``),
        empty ones included, order kept within each."""
        return [self.band_of(cuts, k) for k in range(cuts.size + 1)]

    def band_of(self, cuts: np.ndarray, k: int) -> Rows:
        """Band ``k`` of :meth:`split_at` alone: the rows with ``cuts[k-1] <= y < cuts[k]`` (no
        lower bound for the first band, no upper bound for the last), order kept. Each band's
        worker takes its own (the renderer's threads split the rows at once, not one after
        the other on the calling thread)."""
        if k == 0:
            mask = self.y < cuts[0]
        elif k == cuts.size:
            mask = self.y >= cuts[-1]
        else:
            mask = self.y >= cuts[k - 1]
            mask &= self.y < cuts[k]
        return self.take(mask)


def join_rows(parts: list[Rows], tri_offsets=None) -> Rows:
    """The rows of ``parts`` one after another (their ``tri`` plus ``tri_offsets[k]`` when given)."""
    def joined(name: str, _) -> np.ndarray:
        if name == "tri" and tri_offsets is not None:
            return np.concatenate([r.tri + o for r, o in zip(parts, tri_offsets, strict=True)])
        return np.concatenate([getattr(r, name) for r in parts])

    return parts[0].each_field(joined)


def band_cuts(parts: list[Rows], bands: int, height: int) -> np.ndarray | None:
    """Row cuts (bands - 1,) int64 splitting the fragments of ``parts`` (rows of one or more
    draw calls) into ``bands`` screen bands of about equal counts; None when there are none."""
    per_y = np.zeros(height, dtype=np.float64)
    for rows in parts:
        if rows.count:
            per_y += np.bincount(rows.y, weights=rows.length, minlength=height)
    total = per_y.sum()
    if total == 0:
        return None
    return np.searchsorted(per_y.cumsum(), total * np.arange(1, bands) / bands, side="right")


def coverage_rows(
    setup: TriangleSetup, selected: np.ndarray, width: int, height: int, pool=None, parts: int = 1,
    band: tuple[int, int] | None = None, samples: np.ndarray | None = None,
) -> Rows:
    """Per-row spans of exactly the covered pixels of the selected triangles (docs/pipeline.md §4).

    ``selected`` is covered in contiguous pieces of at most ``PIECE`` triangles (their arrays
    stay in cache), on a thread ``pool`` when given, joined in order (rows stay in draw order).
    ``band`` (y0, y1): only pixel rows ``y0 <= y < y1``. ``samples`` (N, 2) int64 sample
    positions (:func:`.msaa.sample_offsets`; MSAA): each row's span is then the smallest one
    holding every pixel with a covered sample (:func:`_spans`).
    """
    results: dict[int, Rows] = {}

    def part(lo: int, hi: int) -> None:
        results[lo] = _coverage_rows(setup, selected[lo:hi], width, height, band, samples)

    run_parts(pool, parts, selected.size, part, piece=PIECE)
    if len(results) == 1:
        return next(iter(results.values()))
    return join_rows([results[k] for k in sorted(results)])


def coverage_rows_many(passes: list[tuple[TriangleSetup, np.ndarray]], width: int, height: int,
                       band: tuple[int, int] | None = None, samples: np.ndarray | None = None) -> list[Rows]:
    """:func:`coverage_rows` of several passes at once: (setup, selected triangles) each → its Rows.

    The spans of a triangle depend on that triangle alone, so the selected triangles of all
    passes are concatenated and covered in one pass of array operations (many small draw
    calls cost one set of array operations, not one each), then cut per pass. Passes that
    select the same triangles of the same setup (two passes of one material with one Cull)
    share one computation: their Rows hold the same arrays. ``samples``: as :func:`coverage_rows`'s.
    """
    unique: list[tuple[TriangleSetup, np.ndarray]] = []
    slot = []  # each pass's index in ``unique``
    for setup, selected in passes:
        for k, (other_setup, other_selected) in enumerate(unique):
            if other_setup is setup and np.array_equal(other_selected, selected):
                slot.append(k)
                break
        else:
            slot.append(len(unique))
            unique.append((setup, selected))
    if len(unique) < len(passes):
        computed = coverage_rows_many(unique, width, height, band, samples)
        out, given = [], set()
        for k in slot:  # a repeated pass gets its own Rows over the same arrays
            out.append(computed[k] if k not in given else Rows(**vars(computed[k])))
            given.add(k)
        return out
    if len(passes) == 1:
        return [_coverage_rows(passes[0][0], passes[0][1], width, height, band, samples)]
    counts = np.array([sel.size for _, sel in passes], dtype=np.int64)
    offsets = np.concatenate([[0], counts.cumsum()])
    gathered = [np.concatenate([getattr(setup, name).take(sel, axis=0) for setup, sel in passes])
                for name in ("X", "Y", "area2")]
    # Rows come out labelled with their position in the concatenation: ascending, so each
    # pass's rows are one contiguous range; the labels then become the pass's own triangles.
    labels = np.arange(int(offsets[-1]), dtype=np.int64)
    rows = _spans(*gathered, labels, width, height, band, samples)
    cuts = np.searchsorted(rows.tri, offsets)
    local = np.concatenate([sel for _, sel in passes]).astype(np.int64, copy=False)
    out = []
    for k in range(len(passes)):
        a, b = int(cuts[k]), int(cuts[k + 1])
        part = rows.each_field(lambda _, v, a=a, b=b: v[a:b])
        part.tri = local.take(part.tri)
        out.append(part)
    return out


def _coverage_rows(setup: TriangleSetup, selected: np.ndarray, width: int, height: int,
                   band: tuple[int, int] | None = None, samples: np.ndarray | None = None) -> Rows:
    """:func:`coverage_rows` for one contiguous part."""
    return _spans(setup.X.take(selected, axis=0), setup.Y.take(selected, axis=0),
                  setup.area2.take(selected), selected, width, height, band, samples)


def _spans(X: np.ndarray, Y: np.ndarray, area2: np.ndarray, selected: np.ndarray, width: int,
           height: int, band: tuple[int, int] | None = None, samples: np.ndarray | None = None) -> Rows:
    """The spans of triangles with snapped corners ``X``, ``Y`` (n, 3) int64 and twice their
    signed areas ``area2`` (n,) int64, labelled ``selected`` (n,) in the rows' ``tri``; within
    pixel rows ``band`` (y0, y1) when given, else all ``height`` rows.

    A pixel centre ``Px = x*S + S/2`` of row ``y`` is covered when every edge has
    ``E_k = c_k - dy_k*Px >= bias_k`` (bias 0 on top-left edges, else 1), i.e.
    ``dy_k*Px <= rhs_k`` with ``rhs_k = c_k - bias_k``. With ``q = (rhs_k - (S/2)*dy_k) //
    (S*|dy_k|)``, that is ``x <= q`` when ``dy_k > 0`` and ``x >= -q`` when ``dy_k < 0``
    (one exact floor division per edge); a horizontal edge keeps or empties the row.

    With ``samples`` (N, 2) int64 (MSAA sample positions from the pixel's lower-left corner),
    the same test runs at each sample position ``(x*S + ox, y*S + oy)`` and a row's span is the
    smallest holding every pixel with a covered sample (the union of the samples' spans: each
    end pixel has one; a pixel inside may have none, on thin slivers). ``c0``/``c1`` stay the
    edge functions along the row of pixel centres, where fragments are shaded.
    """
    # Bounding boxes first: they do not depend on the vertex order, and most small triangles hold
    # no pixel centre at all, so they are dropped before any per-edge work.
    x_min = np.minimum(np.minimum(X[:, 0], X[:, 1]), X[:, 2])
    x_max = np.maximum(np.maximum(X[:, 0], X[:, 1]), X[:, 2])
    y_min = np.minimum(np.minimum(Y[:, 0], Y[:, 1]), Y[:, 2])
    y_max = np.maximum(np.maximum(Y[:, 0], Y[:, 1]), Y[:, 2])
    # The pixels whose sample points (the centre without MSAA) can fall in the box: x*S + o in
    # [x_min, x_max] for an offset o between the smallest and largest sample offset.
    if samples is None:
        ox_lo = ox_hi = oy_lo = oy_hi = HALF
    else:
        ox_lo, oy_lo = (int(v) for v in samples.min(axis=0))
        ox_hi, oy_hi = (int(v) for v in samples.max(axis=0))
    # Floor and ceiling divisions by S = 2**SHIFT as arithmetic shifts (exact for negatives too).
    x_lo = np.maximum(-((ox_hi - x_min) >> _SHIFT), 0)
    x_hi = np.minimum((x_max - ox_lo) >> _SHIFT, width - 1)
    row_lo, row_hi = (0, height) if band is None else band
    y_lo = np.maximum(-((oy_hi - y_min) >> _SHIFT), row_lo)
    y_hi = np.minimum((y_max - oy_lo) >> _SHIFT, row_hi - 1)
    has = (x_lo <= x_hi) & (y_lo <= y_hi)
    if not has.all():
        index = np.flatnonzero(has)
        X, Y = X.take(index, axis=0), Y.take(index, axis=0)
        selected, area2, x_lo, x_hi, y_lo, y_hi, x_min, x_max, y_min, y_max = (
            gather(v, index) for v in (selected, area2, x_lo, x_hi, y_lo, y_hi, x_min, x_max, y_min, y_max))
    swap = area2 < 0
    # Counter-clockwise vertex order (a, b, c) = (v0, v1, v2), or (v0, v2, v1) when clockwise.
    ax, ay = X[:, 0], Y[:, 0]
    bx = np.where(swap, X[:, 2], X[:, 1])
    by = np.where(swap, Y[:, 2], Y[:, 1])
    cx = np.where(swap, X[:, 1], X[:, 2])
    cy = np.where(swap, Y[:, 1], Y[:, 2])
    nrows = y_hi - y_lo + 1
    total = int(nrows.sum())
    starts = nrows.cumsum() - nrows
    # Per-triangle values are expanded to rows through one row -> triangle index and gathers
    # (np.repeat copies run by run: slow with counts of one or two, the common case).
    of_row = np.arange(nrows.size, dtype=np.int64).repeat(nrows)

    def each(per_triangle: np.ndarray) -> np.ndarray:
        return gather(per_triangle, of_row)

    y = each(y_lo - starts)
    y += np.arange(total, dtype=np.int64)
    py = y * SUBPIXEL + HALF
    # The floor divisions below run in float64 when that is exact: a quotient of integers below
    # 2**53 in magnitude is correctly rounded, so it lands on the integer below it only when it
    # is that integer (its distance to any other is at least 1/|divisor|, the rounding error
    # less than that). |numerator| <= 6*L**2 + S*L + 1 for corners within L of the origin (the
    # corners of the triangles kept: the only ones whose rows are computed).
    reach = max(0, -int(x_min.min(initial=0)), int(x_max.max(initial=0)),
                -int(y_min.min(initial=0)), int(y_max.max(initial=0)))
    # A sample away from the centre adds dx*(oy - S/2) - dy*(ox - S/2): at most 2*S*L more.
    in_float = 6 * reach * reach + (1 if samples is None else 3) * SUBPIXEL * reach + 1 < FLOAT_DIVISION_LIMIT
    if samples is not None:
        return _sample_spans(ax, ay, bx, by, cx, cy, each(x_lo), each(x_hi), y, py, each, selected, swap, area2,
                             samples, in_float)
    # Edges p -> q: b->c (opposite a), c->a (opposite b), a->b (opposite c). Per row of edge k,
    # E = c - dy*Px with c = dx*Py + k; the test E >= bias is dy*Px <= c - bias, i.e. with
    # num = c - bias - (S/2)*dy: x <= num // (S*dy) for dy > 0, x >= -(num // (S*|dy|)) for
    # dy < 0, and for dy = 0 the row is kept when num >= 0. Per-triangle terms are summed once
    # per triangle (integer sums: the same values in any order) before they reach the rows.
    # In float64 the bounds stay floats to the end (each one an integer, exactly), and an edge's
    # bound reaches its side through an addend gathered per row: 0 where the edge bounds that
    # side, an infinity that leaves the side as it is where it does not (a masked minimum,
    # ``where=``, costs ten times a plain one over rows of mixed edges).
    if in_float:
        x0, x1 = each(x_lo.astype(np.float64)), each(x_hi.astype(np.float64))
    else:
        x0, x1 = each(x_lo), each(x_hi)
    c_rows, dy_t_all, empty_rows = [], [], []
    for edge, (xp, yp, xq, yq) in enumerate(((bx, by, cx, cy), (cx, cy, ax, ay), (ax, ay, bx, by))):
        dx_t, dy_t = xq - xp, yq - yp
        bias_t = ((dy_t > 0) | ((dy_t == 0) & (dx_t >= 0))).astype(np.int64)  # 0 on top-left edges
        k_t = dy_t * xp - dx_t * yp  # E = dx*(Py - yp) - dy*(Px - xp) = (dx*Py + k) - dy*Px
        num = each(dx_t) * py
        if edge < 2:  # the rows keep c for the barycentrics
            num += each(k_t)
            c_rows.append(num.copy())
            num += each(-(bias_t + HALF * dy_t))
        else:
            num += each(k_t - (bias_t + HALF * dy_t))
        den = each(SUBPIXEL * np.maximum(np.abs(dy_t), 1))
        if in_float:
            q = np.divide(num, den, dtype=np.float64)
            np.floor(q, out=q)
            upper, lower = _bound_addends(dy_t, each)
            upper += q
            np.minimum(x1, upper, out=x1)
            np.subtract(lower, q, out=q)
            np.maximum(x0, q, out=x0)
        else:
            q = num // den
            dy = each(dy_t)
            np.minimum(x1, q, out=x1, where=dy > 0)
            np.negative(q, out=q)
            np.maximum(x0, q, out=x0, where=dy < 0)
        flat_t = dy_t == 0
        if flat_t.any():  # horizontal edges: the row is empty when the pixel centre row fails them
            flat = np.flatnonzero(each(flat_t))
            empty_rows.append(flat[gather(num, flat) < 0])
        dy_t_all.append(dy_t)
    if in_float:
        x0, x1 = x0.astype(np.int64), x1.astype(np.int64)
    for empty in empty_rows:  # bounds only narrow a row: emptied after every edge is the same
        x1[empty] = x0[empty] - 1
    length = x1 - x0 + 1
    keep = np.flatnonzero(length > 0)
    if keep.size != length.size:  # rows without a covered pixel centre are dropped
        y, x0, length, c0, c1 = (gather(v, keep) for v in (y, x0, length, *c_rows))
        of_row = gather(of_row, keep)
    else:
        c0, c1 = c_rows
    return Rows(tri=each(selected), y=y, x0=x0, length=length, c0=c0, c1=c1, dy0=each(dy_t_all[0]),
                dy1=each(dy_t_all[1]), swap=each(swap), area=each(np.abs(area2)))


def _bound_addends(dy_t: np.ndarray, each: Callable[[np.ndarray], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Per row (``each`` expands per-triangle values to rows), an edge's float64 addends by the
    sign of its ``dy_t`` (n,) int64: (added to its bound on the last pixel, from which its bound
    on the first pixel is subtracted), :data:`_UPPER_ADDEND` and :data:`_LOWER_ADDEND`. The sign
    indexes the tables (np.where over mixed signs costs several gathers)."""
    side = np.sign(dy_t)
    side += 1  # 0, 1, 2 for dy < 0, = 0, > 0
    return each(gather(_UPPER_ADDEND, side)), each(gather(_LOWER_ADDEND, side))


def _sample_spans(ax, ay, bx, by, cx, cy, x_lo: np.ndarray, x_hi: np.ndarray, y: np.ndarray, py: np.ndarray,
                  each, selected: np.ndarray, swap: np.ndarray, area2: np.ndarray, samples: np.ndarray,
                  in_float: bool) -> Rows:
    """:func:`_spans` with MSAA sample positions ``samples`` (N, 2): the counter-clockwise
    corners (n,) of the kept triangles, the bounding-box columns ``x_lo``/``x_hi`` (R,), pixel
    rows ``y`` (R,) and their centres ``py`` (R,) in sub-pixels, ``each`` expanding per-triangle
    values to rows. Per edge and sample, the bound is the centre's test shifted by the sample's
    offset from the centre (``E`` there is ``E`` at the centre plus ``dx*(oy - S/2) - dy*(ox -
    S/2)``); a row's span is the union hull of its samples' spans."""
    # The bounds are computed in float64 when exact there (in_float: every numerator an integer
    # below 2**53, so sums and products of them are exact and a quotient floors correctly, see
    # _spans), else in int64; per edge, the row values are converted once. In float64 an edge's
    # bound reaches its side through addends, as in _spans (no masked minimum or maximum), and
    # a sample's empty span leaves the row's hull through infinities likewise.
    work = np.float64 if in_float else np.int64
    edges = []  # per edge: (upper, lower, horizontal rows or None, dx, dy, num at the centre, den), (R,) each
    c_rows, dy_rows = [], []
    for edge, (xp, yp, xq, yq) in enumerate(((bx, by, cx, cy), (cx, cy, ax, ay), (ax, ay, bx, by))):
        dx_t, dy_t = xq - xp, yq - yp
        bias_t = ((dy_t > 0) | ((dy_t == 0) & (dx_t >= 0))).astype(np.int64)
        k_t = dy_t * xp - dx_t * yp
        dy = each(dy_t)
        c = each(dx_t) * py + each(k_t)
        if edge < 2:
            c_rows.append(c)
            dy_rows.append(dy)
        flat = None if dy_t.all() else dy == 0
        den = each(SUBPIXEL * np.maximum(np.abs(dy_t), 1))
        if in_float:  # addends by side: 0 where the edge bounds it, an infinity where it does not
            upper, lower = _bound_addends(dy_t, each)
        else:  # masks: dy > 0 bounds the last pixel, dy < 0 the first
            upper, lower = dy > 0, dy < 0
        edges.append((upper, lower, flat, each(dx_t).astype(work), dy.astype(work),
                      (c - each(bias_t + HALF * dy_t)).astype(work), den.astype(work)))
    first_x, last_x = x_lo.astype(work), x_hi.astype(work)
    if in_float:
        lo = np.full(y.size, np.inf)
        hi = np.full(y.size, -np.inf)
    else:
        lo = np.full(y.size, np.iinfo(np.int64).max, dtype=np.int64)
        hi = np.full(y.size, np.iinfo(np.int64).min, dtype=np.int64)
    spans = np.empty((2, y.size, samples.shape[0]), dtype=np.int64)  # each sample's (x0, x1) per row
    for s, (ox, oy) in enumerate((samples - HALF).tolist()):
        x0, x1 = first_x.copy(), last_x.copy()
        for upper, lower, flat, dx, dy, num_centre, den in edges:
            num = dx * oy
            num -= dy * ox
            num += num_centre
            if in_float:
                q = num / den
                np.floor(q, out=q)
                bound = q + upper
                np.minimum(x1, bound, out=x1)
                np.subtract(lower, q, out=q)
                np.maximum(x0, q, out=x0)
            else:
                q = num // den
                np.minimum(x1, q, out=x1, where=upper)
                np.negative(q, out=q)
                np.maximum(x0, q, out=x0, where=lower)
            if flat is not None:  # horizontal edges: the sample row is empty when its points fail them
                empty = np.flatnonzero(flat & (num < 0))
                x1[empty] = x0[empty] - 1
        spans[0, :, s], spans[1, :, s] = x0, x1
        if in_float:
            covered = gather(_EMPTY_ADDEND, (x1 >= x0).astype(np.intp))  # 0 where covered, else inf
            x0 += covered
            np.minimum(lo, x0, out=lo)
            np.subtract(x1, covered, out=x1)
            np.maximum(hi, x1, out=hi)
        else:
            some = x1 >= x0
            np.minimum(lo, x0, out=lo, where=some)
            np.maximum(hi, x1, out=hi, where=some)
    keep = np.flatnonzero(hi >= lo)
    of_row = np.arange(y.size, dtype=np.int64)
    if keep.size != y.size:
        y, lo, hi, of_row = (gather(v, keep) for v in (y, lo, hi, of_row))
        c_rows = [gather(v, keep) for v in c_rows]
        dy_rows = [gather(v, keep) for v in dy_rows]
        spans = spans.take(keep, axis=1)
    if in_float:  # every kept row has a covered sample: finite bounds
        lo, hi = lo.astype(np.int64), hi.astype(np.int64)

    def per_row(per_triangle: np.ndarray) -> np.ndarray:
        return each(per_triangle).take(of_row)

    return Rows(tri=per_row(selected), y=y, x0=lo, length=hi - lo + 1, c0=c_rows[0], c1=c_rows[1],
                dy0=dy_rows[0], dy1=dy_rows[1], swap=per_row(swap), area=per_row(np.abs(area2)),
                sample_x0=spans[0], sample_x1=spans[1])


def row_chunks(rows: Rows, max_candidates: int) -> list[tuple[int, int]]:
    """Split rows into consecutive ranges of at most ``max_candidates`` candidates (at least one row)."""
    if rows.count == 0:
        return []
    ends = rows.length.cumsum()
    total = int(ends[-1])
    if total == 0:
        return []
    bounds = [0]
    while bounds[-1] < rows.count:
        start = bounds[-1]
        base = int(ends[start - 1]) if start else 0
        stop = int(np.searchsorted(ends, base + max_candidates, side="right"))
        bounds.append(max(stop, start + 1))
    return list(zip(bounds[:-1], bounds[1:], strict=True))


@dataclass(eq=False)
class Fragments:
    """Covered pixels of a chunk, in draw order (fragments of one triangle hit distinct pixels).

    ``pix`` (N,) int64 window pixel index ``y*W + x`` (y from the bottom);
    ``tri`` (N,) int64 setup triangle index; ``bary`` (3, N) float64 screen-space
    barycentrics in the triangle's own vertex order (channels first: each row contiguous),
    or None when not asked for (nothing of the chunk needs them).
    """

    pix: np.ndarray
    tri: np.ndarray
    bary: np.ndarray | None
    #: The chunk's rows: setup triangle (R,) int64 and covered pixels (R,) int64 of each.
    row_tri: np.ndarray | None = None
    row_length: np.ndarray | None = None

    @property
    def count(self) -> int:
        return int(self.pix.shape[0])

    def per_fragment(self, per_triangle: np.ndarray) -> np.ndarray:
        """A per-setup-triangle array (T,) → its value at every fragment (N,): expanded from the
        rows with ``repeat`` (sequential copies) when rows are long, else gathered."""
        if self.row_tri is None or self.row_tri.shape[0] * REPEAT_MIN_RUN > self.pix.shape[0]:
            # Rows of a few pixels: one gather is cheaper. Indexing, not np.take, which would
            # first copy a strided column (zw[:, k]) of every setup triangle to contiguous memory.
            return per_triangle[self.tri]
        return per_triangle[self.row_tri].repeat(self.row_length, axis=0)


#: Runs at least this long on average are expanded with ``np.repeat``, shorter ones by a gather
#: through a run index made once: a gather costs the same whatever the runs, repeat copies run
#: by run, so it wins from about this length on (docs/benchmark.md, "Why the constants are what
#: they are").
REPEAT_MIN_RUN = 16


def run_expander(counts: np.ndarray, n: int) -> Callable[[np.ndarray], np.ndarray]:
    """A function that expands per-run values (R, ...) to the ``n`` elements of runs of ``counts``
    (R,) int64 (along the first axis): ``repeat`` (sequential copies) when runs are long; for short
    runs (small triangles, rows of a few pixels; :data:`REPEAT_MIN_RUN`) one element -> run index
    once and a gather per expansion."""
    if counts.size * REPEAT_MIN_RUN > n:
        run = np.arange(counts.size, dtype=np.int64).repeat(counts)
        return lambda values: gather(values, run, axis=0)
    return lambda values: values.repeat(counts, axis=0)


#: Chunks of up to this many fragments give :func:`rasterize_rows`' edge functions from the
#: fragment's index in the chunk (products below 2**59), larger ones from its index in its row.
GLOBAL_INDEX_FRAGMENTS = 1 << 22


def _float_exact(a0: np.ndarray, a1: np.ndarray, s0: np.ndarray, s1: np.ndarray, area: np.ndarray,
                 last_step: int) -> bool:
    """Whether :func:`rasterize_rows`' edge functions ``E = a - s*step`` (rows' (R,) int64 ``a``,
    ``s``; steps 0..``last_step``), their doubled areas ``area`` (R,) int64 and every product and
    sum on the way — ``s*step``, ``area - E0`` and ``area - E0 - E1`` (a pixel centre outside the
    triangle, as an MSAA span's may be, has an E below 0) — stay below 2**53 in magnitude: then
    float64 computes them exactly."""
    if a0.size == 0:
        return True
    reach = max(int(np.abs(a0).max()), int(np.abs(a1).max()))
    slope = max(int(np.abs(s0).max()), int(np.abs(s1).max()))
    return 2 * (reach + slope * max(last_step, 0)) + int(area.max()) < FLOAT_DIVISION_LIMIT


def rasterize_rows(rows: Rows, start: int, stop: int, width: int, bary: bool = True) -> Fragments:
    """The covered pixels of rows ``[start, stop)`` with their barycentrics (docs/pipeline.md §4).

    ``bary`` False: only pixels and triangles (a chunk that needs neither depth nor weights).
    """
    length = rows.length[start:stop]
    n = int(length.sum())
    sl = slice(start, stop)
    # A fragment's pixel is its index in the chunk plus its row's (first pixel - first index).
    first = length.cumsum() - length
    each = run_expander(length, n)
    index = np.arange(n, dtype=np.int64)
    pix = each(rows.y[sl] * width + rows.x0[sl] - first)
    pix += index
    row_tri = rows.tri[sl]
    tri = each(row_tri)
    if not bary:
        return Fragments(pix=pix, tri=tri, bary=None, row_tri=row_tri, row_length=length)
    # The edge functions E = c - dy*Px at the pixel centres Px = S*x + HALF, x = index + (x0 -
    # first) of the row: E = (c - dy*P0) - (dy*S)*index with P0 = S*(x0 - first) + HALF per row,
    # the same integers (int64, exact) without a per-fragment x or Px. A chunk of more than
    # GLOBAL_INDEX_FRAGMENTS counts from each row's start instead (one more pass), so that no
    # product comes near 2**63 (|dy| < 2**28 within the guard band).
    if n <= GLOBAL_INDEX_FRAGMENTS:
        step = index
        p0 = rows.x0[sl] - first
    else:
        step = index - each(first)
        p0 = rows.x0[sl].copy()
    p0 *= SUBPIXEL
    p0 += HALF
    c0, dy0, c1, dy1, row_area = rows.c0[sl], rows.dy0[sl], rows.c1[sl], rows.dy1[sl], rows.area[sl]
    swap = rows.swap[sl]
    if swap.any():
        # A clockwise triangle's second weight is its third edge function (area - E0 - E1 =
        # (area - c0 - c1) - (-(dy0 + dy1))*Px): take that edge's row coefficients, so the
        # fragments need no swap of their own; the third weight (area - E0 - E1) is then E1.
        c1 = np.where(swap, row_area - c0 - c1, c1)
        dy1 = np.where(swap, -(dy0 + dy1), dy1)
    a0, a1 = c0 - dy0 * p0, c1 - dy1 * p0  # (R,) each edge's E at step 0 of its row's run
    s0, s1 = dy0 * SUBPIXEL, dy1 * SUBPIXEL  # (R,) what one pixel to the right takes from it
    last_step = n - 1 if n <= GLOBAL_INDEX_FRAGMENTS else int(length.max()) - 1
    # Every value below is an integer: in float64 when all stay under 2**53 in magnitude
    # (_float_exact), where float64 holds them exactly (the same E, converted as the int64
    # division converts them, with no int64 product per fragment and no mixed-type division),
    # else in int64.
    kind = np.float64 if _float_exact(a0, a1, s0, s1, row_area, last_step) else np.int64
    steps = step.astype(kind, copy=False)
    area = each(row_area.astype(kind, copy=False))
    ea = each(a0.astype(kind, copy=False))
    ea -= each(s0.astype(kind, copy=False)) * steps
    eb = each(a1.astype(kind, copy=False))
    eb -= each(s1.astype(kind, copy=False)) * steps
    ec = area - ea
    ec -= eb  # the three edge functions sum to the doubled area
    farea = area.astype(np.float64, copy=False)
    weights = np.empty((3, n), dtype=np.float64)
    np.divide(ea, farea, out=weights[0])
    np.divide(eb, farea, out=weights[1])
    np.divide(ec, farea, out=weights[2])
    return Fragments(pix=pix, tri=tri, bary=weights, row_tri=row_tri, row_length=length)


def row_end_fragments(rows: Rows, start: int, stop: int, width: int) -> Fragments:
    """The first and last covered pixel of each of rows ``[start, stop)`` (R rows, each holding
    one at least) as :class:`Fragments` with barycentrics: the R first pixels, then the R last
    ones (a row of one pixel gives it twice), each as :func:`rasterize_rows` gives it."""
    sl = slice(start, stop)
    ends = rows.each_field(lambda _, v: np.concatenate([v[sl], v[sl]]))
    count = stop - start
    ends.x0[count:] += ends.length[count:] - 1
    ends.length = np.ones(2 * count, dtype=np.int64)
    return rasterize_rows(ends, 0, 2 * count, width)


def depth_upper_codes(setup: TriangleSetup, offset_factor: float = 0.0, offset_units: float = 0.0) -> np.ndarray:
    """(T,) int64: a code no fragment of each setup triangle exceeds (its vertices' largest
    depth after Offset, plus one code for rounding: depth is a convex combination of them)."""
    zw = setup.zw
    z = np.maximum(np.maximum(zw[:, 0], zw[:, 1]), zw[:, 2])  # as max(axis=1), NaN included; no strided reduction
    if offset_factor != 0.0 or offset_units != 0.0:
        z = z + (float(offset_factor) * setup.slope() + float(offset_units) * 2.0**-24)
    z = np.minimum(np.maximum(z, 0.0), 1.0)
    z[np.isnan(z)] = 1.0  # no bound known: the farthest code (only proves Always-like cases)
    return np.floor(z * DEPTH_MAX + 0.5).astype(np.int64) + 1


def interpolate(
    setup: TriangleSetup, frags: Fragments, offset_factor: float = 0.0, offset_units: float = 0.0,
    weights: bool = True, depth: bool = True,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Depth and perspective-correct source-triangle weights of fragments (§5, §6).

    Returns ``depth`` (N,) int64 in 0..2**24-1 and ``weights`` (3, N) float64 (channels
    first) — the weights of the *source* mesh triangle's corners (clipping undone) — or
    None for either when not asked for (``depth`` / ``weights`` False).
    """
    t = frags.tri
    each = frags.per_fragment
    b0, b1, b2 = frags.bary
    codes = None
    if depth:
        # (b0*z0 + b1*z1) + b2*z2, clamped into [0, 1], floor(z*DEPTH_MAX + 0.5): each operation in
        # that order, made in place in the per-fragment arrays (each() gives new ones).
        zw = setup.zw
        z = each(zw[:, 0])
        z *= b0
        term = each(zw[:, 1])
        term *= b1
        z += term
        np.multiply(b2, each(zw[:, 2]), out=term)
        z += term
        del term
        if offset_factor != 0.0 or offset_units != 0.0:
            z += float(offset_factor) * each(setup.slope()) + float(offset_units) * 2.0**-24
        np.maximum(z, 0.0, out=z)
        np.minimum(z, 1.0, out=z)
        z *= DEPTH_MAX
        z += 0.5
        np.floor(z, out=z)
        codes = z.astype(np.int64)
    if not weights:
        return codes, None

    iw = setup.iw
    t0, t1, t2 = b0 * each(iw[:, 0]), b1 * each(iw[:, 1]), b2 * each(iw[:, 2])
    s = (t0 + t1) + t2
    p = np.empty((3, t.size), dtype=np.float64)  # channels first: each weight row contiguous
    np.divide(t0, s, out=p[0])
    np.divide(t1, s, out=p[1])
    np.divide(t2, s, out=p[2])
    if setup.weights is not None:
        clipped = each(setup.clipped)
        if clipped.any():
            w = setup.weights[t[clipped]]  # (M, 3 vertices, 3 source corners)
            pc = p[:, clipped]
            p[:, clipped] = ((pc[0][:, None] * w[:, 0] + pc[1][:, None] * w[:, 1]) + pc[2][:, None] * w[:, 2]).T
    return codes, p


def rows_disjoint(rows: Rows, start: int, stop: int, width: int) -> bool:
    """Whether rows ``[start, stop)`` cover pairwise distinct pixels (then a chunk's fragments
    form one layer and need no per-pixel counting). False also means "not checked": rows
    shorter than 16 pixels on average are left to the merger's count."""
    if stop - start <= 1:
        return True
    sl = slice(start, stop)
    if (stop - start) * 16 > int(rows.length[sl].sum()):
        return False  # short rows (small triangles): counting fragments per pixel is as cheap
    first = rows.y[sl] * width + rows.x0[sl]
    order = np.argsort(first, kind="stable")
    begin = first[order]
    end = begin + rows.length[sl][order]
    return bool((begin[1:] >= end[:-1]).all())


def flat_corners(corners: np.ndarray) -> np.ndarray:
    """(T,) bool: the three corner values of each triangle are equal (corners (T, 3, C))."""
    flat = corners[:, 0, 0] == corners[:, 1, 0]
    flat &= corners[:, 0, 0] == corners[:, 2, 0]
    for c in range(1, corners.shape[2]):
        flat &= corners[:, 0, c] == corners[:, 1, c]
        flat &= corners[:, 0, c] == corners[:, 2, c]
    return flat


def interpolate_runs(weights: np.ndarray, corners: np.ndarray, counts: np.ndarray, flat: np.ndarray,
                     channels_first: bool = False) -> np.ndarray:
    """Interpolate an attribute over fragments grouped in runs of one triangle each (§6).

    ``weights`` (3, N) float64; ``corners`` (K, 3, C) corner values of the K triangles;
    ``counts`` (K,) int64 fragments of each triangle, in order (sum N); ``flat`` (K,) bool:
    the triangle's corners are equal, so its fragments take the corner value. Returns
    (N, C) float64 ``(o0*a0 + o1*a1) + o2*a2`` per component, or (C, N) with
    ``channels_first`` (each component contiguous). Corner values are expanded with
    ``repeat`` (sequential copies) when runs are long, else gathered per fragment.
    """
    n = weights.shape[1]
    out = np.empty((corners.shape[2], n), dtype=np.float64)
    expand = run_expander(counts, n)
    if flat.all():  # every triangle's corners equal (a particle's colour): each fragment takes them
        for c in range(corners.shape[2]):
            out[c] = expand(corners[:, 0, c])
        return out if channels_first else np.ascontiguousarray(out.T)
    for c in range(corners.shape[2]):
        acc = out[c]
        np.multiply(weights[0], expand(corners[:, 0, c]), out=acc)
        acc += weights[1] * expand(corners[:, 1, c])
        acc += weights[2] * expand(corners[:, 2, c])
    if flat.any():
        keep = flat.repeat(counts)
        out[:, keep] = corners[flat, 0].repeat(counts[flat], axis=0).T
    return out if channels_first else np.ascontiguousarray(out.T)
