"""Chunk shading (docs/pipeline.md §5–§7): rows of one draw call → :class:`.records.ShadedFragments`.

A chunk of a call's covered rows is rasterised (:mod:`.raster`), interpolated and shaded
(:mod:`.shade`) and alpha-tested, taking the cheapest path that gives the per-fragment
arithmetic's result bit for bit:

- :func:`shade_chunk`: triangles whose shading inputs are constant are shaded once per
  triangle; Point-filtered textured triangles with a constant normal take their colour from a
  texel palette (one colour per normal and texel); the rest are shaded per fragment.
- :func:`shade_constant_chunk`: every fragment takes a colour known per triangle (fused
  constant-colour calls, :mod:`.fuse`), or no colour at all.
- :func:`shade_colourless_chunk`: a pass that writes no colour and has no alpha test (a depth
  prepass): pixels and depth only; observers read its colours lazily.

Every chunk shader is a :data:`ChunkShader`: rows ``[start, stop)`` of a call's
:class:`~.raster.Rows` over its setup, under its :class:`~.records.DrawState` → the chunk's
fragments in primitive order, or None when the rows cover no pixel.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from . import lights, mips, raster, shade
from .gather import gather, scatter_rows
from .merger import compare, table_pays
from .records import DrawState, ShadedFragments
from .vertex import TriangleSetup
from .vocabulary import ColorSpace, CompareFunction, Pass, TextureFilter

#: ``shade(setup, rows, start, stop, state)``: a chunk of a draw call's rows → its shaded fragments.
ChunkShader = Callable[[TriangleSetup, raster.Rows, int, int, DrawState], ShadedFragments | None]


#: A texel palette (one colour per normal and texel, :func:`shade.texel_palette`) replaces
#: per-fragment shading when it has at most this share of the fragments it serves.
TEXEL_PALETTE_SHARE = 4
#: Textures up to this many texels are examined for repeated texels (a palette entry each).
TEXEL_PALETTE_EXAMINE = 1 << 14


def _texel_groups(state: DrawState, candidates: np.ndarray, normals, colors,
                  counts) -> tuple[np.ndarray, np.ndarray | None, np.ndarray] | None:
    """Point-filtered triangles whose normal and vertex colour are constant: their colour is a
    function of (normal, vertex colour, texel). Returns ``(normals (G, 3), vertex colours (G, 4)
    or None, group (K,) int64 per triangle)`` when a palette of G * (distinct texels) colours is
    cheaper than shading the candidates' fragments, else None."""
    served = int(counts[candidates].sum())
    h, w = state.texels.shape[:2]
    # Finding the distinct texels of a large texture costs more than it can save unless even
    # its full size would pay: only small textures are examined for repeated texels.
    if h * w > TEXEL_PALETTE_EXAMINE and h * w * TEXEL_PALETTE_SHARE > served:
        return None
    texel_count = state.texels.distinct()[0].size
    if texel_count * TEXEL_PALETTE_SHARE > served:
        return None
    parts = [v[candidates, 0] for v in (normals, colors) if v is not None]
    if not parts:  # Unlit, no vertex colour: the colour depends on the texel alone
        return np.zeros((1, 3), dtype=np.float64), None, np.zeros(candidates.size, dtype=np.int64)
    corner = np.ascontiguousarray(np.concatenate(parts, axis=1))
    # Distinct by bytes, not value: -0.0 and 0.0 (or NaNs) stay apart, so each group's normal and
    # colour are bit for bit the ones its fragments would be shaded with.
    _, where, inverse = np.unique(corner.view(np.dtype((np.void, corner.itemsize * corner.shape[1]))).reshape(-1),
                                  return_index=True, return_inverse=True)
    if where.size * texel_count * TEXEL_PALETTE_SHARE > served:
        return None
    group = np.zeros(candidates.size, dtype=np.int64)
    group[candidates] = inverse.reshape(-1)
    chosen = corner[where]
    group_normals = chosen[:, :3] if normals is not None else np.zeros((where.size, 3), dtype=np.float64)
    group_colors = chosen[:, -4:] if colors is not None else None
    return group_normals, group_colors, group


def distinct_colors(colors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(colors, axis=0, return_inverse=True)`` of (K, 4) float64 colours, byte for byte:
    without a sort when every row has the same bytes (an unlit or evenly lit mesh: the common
    case), else by one ``np.lexsort`` of the columns when every value is finite and none is -0.0
    (equal numbers are then equal bytes; np.unique's row sort costs 3-5x more on a few hundred)."""
    bits = np.ascontiguousarray(colors).view(np.int64)
    if not np.isfinite(colors).all() or (bits == _NEGATIVE_ZERO_BITS).any():
        return np.unique(colors, axis=0, return_inverse=True)
    if (bits == bits[:1]).all():
        return colors[:1], np.zeros(colors.shape[0], dtype=np.int64)
    order = np.lexsort(colors.T[::-1])  # by the first column, then the next: np.unique's row order
    ordered = bits.take(order, axis=0)
    first = np.ones(order.size, dtype=bool)
    first[1:] = (ordered[1:] != ordered[:-1]).any(axis=1)
    inverse = np.empty(order.size, dtype=np.int64)
    inverse[order] = first.cumsum() - 1
    return colors.take(order[first], axis=0), inverse


_NEGATIVE_ZERO_BITS = np.float64(-0.0).view(np.int64)


def alpha_test(rgba: np.ndarray | None, ids: np.ndarray | None, palette: np.ndarray | None,
               cutoff: float, comp: CompareFunction = CompareFunction.GEqual) -> np.ndarray:
    """(N,) bool: the fragments that survive the alpha test ``alpha <comp> _Cutoff``, their
    colours given as in :class:`ShadedFragments` (``rgba``, or ``palette[ids]`` where ``ids >= 0``).

    ``GEqual`` is the book's ``clip(alpha - _Cutoff)``: a fragment dies when the difference is
    negative (so a NaN alpha survives, as ``clip`` keeps it). The other comparisons are the
    legacy ``AlphaTest`` command's (Unity manual, "ShaderLab: legacy alpha testing"): a plain
    IEEE comparison of alpha with the cutoff; ``Always`` keeps every fragment, ``Never`` none.
    """
    if ids is None:
        alpha = rgba[:, 3]
    elif rgba is None:
        alpha = palette[:, 3].take(ids)
    else:
        alpha = np.where(ids >= 0, palette[np.maximum(ids, 0), 3], rgba[:, 3])
    return alpha_passes(alpha, cutoff, comp)


def alpha_passes(alpha: np.ndarray, cutoff: float, comp: CompareFunction = CompareFunction.GEqual) -> np.ndarray:
    """(N,) bool: :func:`alpha_test` of the fragments' alphas (N,) float64."""
    cutoff = float(cutoff)
    if comp is CompareFunction.GEqual:
        return ~(alpha - cutoff < 0)
    if comp is CompareFunction.Always or comp is CompareFunction.Never:
        return np.full(alpha.shape, comp is CompareFunction.Always, dtype=bool)
    return _ALPHA_COMPARISONS[comp](alpha, cutoff)


#: ``alpha <comp> cutoff`` for the comparisons other than GEqual, Always and Never.
_ALPHA_COMPARISONS = {
    CompareFunction.Greater: np.greater, CompareFunction.Less: np.less, CompareFunction.LEqual: np.less_equal,
    CompareFunction.Equal: np.equal, CompareFunction.NotEqual: np.not_equal,
}


#: Depth tests an early test may apply against the depth stored before a chunk: while the chunk's
#: fragments are merged one by one, the stored depth only moves towards the passing side (nearer for
#: Less/LEqual, farther for Greater/GEqual, unchanged for Equal or without ZWrite), so a fragment that
#: fails against the earlier value fails against the later one too.
_EARLY_TESTS = (CompareFunction.Less, CompareFunction.LEqual, CompareFunction.Greater, CompareFunction.GEqual,
                CompareFunction.Equal)


#: An early depth test drops a chunk's failing fragments when at least 1/EARLY_DROP_SHARE of them
#: fail: taking the others out costs about a sixth of what shading and merging a fragment costs.
EARLY_DROP_SHARE = 8


def early_depth_applies(p: Pass, samples: int, observed: bool) -> bool:
    """Whether fragments of pass ``p`` that fail its depth test against the depth stored when their
    chunk is shaded may be dropped before shading (an early depth test): they would fail when
    merged too (:data:`_EARLY_TESTS`; ``NotEqual`` only without ZWrite) and a failed depth test
    then changes nothing — not with stencil (its ZFail operation), MSAA (a depth per sample) or an
    observer told of every fragment and its outcome (``observed``; one that reads written fragments
    only, :meth:`.records.FrameObserver.reads_hidden`, is not)."""
    if samples != 1 or observed or p.stencil:
        return False
    return p.ztest in _EARLY_TESTS or (p.ztest is CompareFunction.NotEqual and not p.zwrite)


def _segment_sums(values: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """(K,) int64: the sums of ``values`` (N,) over consecutive segments of ``counts`` (K,) int64
    (sum N; zero-length segments sum to 0)."""
    running = np.zeros(values.size + 1, dtype=np.int64)
    values.cumsum(out=running[1:])
    return np.diff(running.take(counts.cumsum()), prepend=0)


def shade_chunk(setup, rows, start: int, stop: int, state: DrawState) -> ShadedFragments | None:
    """Raster + interpolate + shade + alpha test of rows [start, stop), in draw order.

    Triangles whose inputs to shading are constant (no texture or flat UVs, Unlit or flat
    normals: docs/pipeline.md §6) are shaded once per triangle; Point-filtered textured
    triangles with a constant normal take their colour from a palette shaded once per
    (normal, texel); the others are shaded once per fragment. Work per source triangle
    (runs, flatness, table ids) is done per row and expanded.
    """
    p, material, texels, outline = state.pass_state, state.material, state.texels, state.outline
    chunk_rows = stop - start  # rows of the chunk as the caller counts them (row_counts below)
    length = rows.length[start:stop]
    n = full = int(length.sum())
    if n == 0:
        return None
    # Rows come in triangle order: each source triangle's rows (so fragments) form one run.
    row_src = setup.src[rows.tri[start:stop]]
    first = np.ones(row_src.size, dtype=bool)
    first[1:] = row_src[1:] != row_src[:-1]
    run_of_row = first.cumsum() - 1
    tris = row_src[first]  # (K,) the source triangles of this chunk
    uvs = setup.uvs_of(tris) if texels is not None and setup.object_uvs is not None else None
    normals = setup.world_normals_of(tris) if setup.object_normals is not None else None
    colors = setup.colors_of(tris) if setup.object_colors is not None else None
    # World positions only for Lambert under a point or spot light (a ForwardAdd draw).
    positions = setup.world_positions_of(tris) if normals is not None and state.lights.positional else None
    flat = np.ones(tris.size, dtype=bool)  # shading inputs constant over the triangle (§6)
    uv_flat, normal_flat, color_flat, position_flat = (None if corners is None else raster.flat_corners(corners)
                                                       for corners in (uvs, normals, colors, positions))
    for corners_flat in (uv_flat, normal_flat, color_flat, position_flat):
        if corners_flat is not None:
            flat &= corners_flat
    any_varying = not bool(flat.all())
    of_row = None  # (P,) int64: each row's row in the chunk, when rows were cut (below)
    beyond = None  # (N,) bool, observed: fragments beyond the spans the light may reach (dark)
    reach_cut = False  # a render's rows cut to the light's reach: the dark left are too few to test for
    if state.dark_skip and positions is not None and n >= ROW_REACH_MIN_RUN * length.size:
        reach_cut = not state.observed
        # The parts of rows out of the ForwardAdd light's reach hold fragments _dark would call
        # dark. A render cuts them off before they are rasterised; observed, every fragment is
        # rasterised and told of, and the spans spare only the world positions and reach test of
        # those beyond them (whatever the stored alpha: the observed path merges them there).
        spans = _reached_spans(setup, rows, start, stop, state, positions, run_of_row,
                               [c for c in (normals, colors) if c is not None], saturated_only=not state.observed)
        if spans is not None and state.observed:
            beyond = _beyond_spans(rows.x0[start:stop], length, *spans)
        elif spans is not None:
            x0, x1 = spans
            reached = np.flatnonzero(x1 > x0)
            if reached.size == 0:
                return None
            rows = rows.take_rows(reached + start)
            rows.x0 = x0.take(reached)
            rows.length = x1.take(reached) - rows.x0
            of_row = reached
            start, stop, run_of_row = 0, rows.count, run_of_row.take(of_row)
            length = rows.length
            n = int(length.sum())
    want_depth = state.depth_needed(rows, start, stop)
    frags = raster.rasterize_rows(rows, start, stop, state.width, bary=want_depth or any_varying)
    depth = weights = None
    if frags.bary is not None:
        depth, weights = raster.interpolate(setup, frags, p.offset_factor, p.offset_units,
                                            weights=any_varying, depth=want_depth)
    if state.early_depth is not None and depth is not None:
        # Early depth test: what fails against the stored depth now fails when merged (see
        # early_depth_applies) and is dropped here, before its attributes are interpolated and shaded.
        passing = compare(p.ztest, depth, gather(state.early_depth, frags.pix))
        kept_count = int(np.count_nonzero(passing))
        # Dropping copies what is kept: it pays where a good share fails (else the merger drops them).
        if (n - kept_count) * EARLY_DROP_SHARE >= n:
            kept = np.flatnonzero(passing)
            if kept.size == 0:
                return None
            length = _segment_sums(passing, length)  # rows keep their order; some hold none now
            n = int(kept.size)
            frags = raster.Fragments(pix=gather(frags.pix, kept), tri=gather(frags.tri, kept),
                                     bary=gather(frags.bary, kept, axis=1), row_tri=frags.row_tri,
                                     row_length=length)
            depth = gather(depth, kept)
            weights = None if weights is None else gather(weights, kept, axis=1)
            beyond = None if beyond is None else gather(beyond, kept)
    # (K,) fragments per triangle (some none): rows come in triangle order, each triangle's one run.
    counts = (np.add.reduceat(length, np.flatnonzero(first)) if of_row is None
              else np.bincount(run_of_row, weights=length, minlength=tris.size).astype(np.int64))
    groups = None  # texel-palette groups (normals (G, 3), colours, group (K,)) and the triangles they serve
    if (any_varying and uvs is not None and material.main_tex_filter is TextureFilter.Point
            and state.mips is None and positions is None):
        candidates = ~uv_flat
        for constant in (normal_flat, color_flat):
            if constant is not None:
                candidates = candidates & constant
        if candidates.any():
            groups = _texel_groups(state, candidates, normals, colors, counts)
            tabled = candidates
    rgba = np.empty((n, 4), dtype=np.float64)
    palettes: list[np.ndarray] = []  # colours fragments take by id: per flat triangle, per texel
    ids = None  # (N,) int32 palette entry of each fragment, -1 for those shaded one by one
    tabled_count = 0  # fragments with an id
    row_flat = flat[run_of_row]
    dropped = None  # (N,) bool: fragments dropped before merging (out of a light's reach, alpha first)
    inert = None  # (N,) bool: observed fragments whose merge changes nothing (ShadedFragments.inert)
    constant = None if not any_varying else row_flat.repeat(length)

    def sample_at(uv: np.ndarray, lod: np.ndarray | None, channels: tuple[int, ...]) -> np.ndarray:
        """The texture's ``channels`` (M, C) at mesh coordinates ``uv`` (M, 2), through the mip
        chain with ``lod`` (M,) when given (as :func:`.shade.shade` samples without one)."""
        tex_uv = shade.texture_uv(material, uv)
        if lod is None:
            return shade.sample(texels, tex_uv, material.main_tex_filter, material.main_tex_wrap, channels)
        return mips.sample_mipmapped(state.mips, tex_uv, lod, material.main_tex_filter, material.main_tex_wrap,
                                     channels)

    def shade_at(uv: np.ndarray | None, normal: np.ndarray | None, color: np.ndarray | None,
                 position: np.ndarray | None, count: int, lod: np.ndarray | None = None,
                 alpha: np.ndarray | None = None) -> np.ndarray:
        """Colours (count, 4) of fragments; ``alpha`` (count,): the texture's alpha there, sampled
        already (the alpha test's): only red, green and blue are sampled again."""
        uv = np.zeros((count, 2), dtype=np.float64) if uv is None else uv
        normal = np.zeros((count, 3), dtype=np.float64) if normal is None else normal
        if lod is None and alpha is None:
            return shade.shade(material, texels, state.lights, state.color_space, uv, normal, color, position,
                               outline)
        if alpha is None:
            tex = sample_at(uv, lod, (0, 1, 2, 3))
        else:
            tex = np.empty((4, count), dtype=np.float64)  # channels first: rows copied whole
            tex[:3] = sample_at(uv, lod, (0, 1, 2)).T
            tex[3] = alpha
            tex = tex.T
        return shade.shade_texels(material, tex, state.lights, state.color_space, normal, color, position, outline,
                                  shade.sampled_ones(texels) if lod is None else None)

    def first_corner(corners: np.ndarray | None, index: np.ndarray) -> np.ndarray | None:
        return None if corners is None else corners[index, 0]

    if flat.any():
        # Constant inputs: a flat-UV triangle samples at level 0 with or without mipmaps (§7).
        const_tris = np.nonzero(flat)[0]
        const_colors = shade_at(first_corner(uvs, const_tris), first_corner(normals, const_tris),
                                first_corner(colors, const_tris), first_corner(positions, const_tris),
                                const_tris.size)
        # Triangles of one colour (an unlit mesh, a flat-lit plane) share one palette entry.
        const_colors, inverse = distinct_colors(const_colors)
        palettes.append(const_colors)
        slot = np.full(tris.size, -1, dtype=np.int32)
        slot[const_tris] = inverse.reshape(-1)
        ids = slot[run_of_row].repeat(length)
        tabled_count = n if not any_varying else int(counts[flat].sum())
    if any_varying:
        # Varying fragments are exactly those of the non-flat triangles: whole runs.
        every = not flat.any()  # e.g. a smooth mesh: no masked copies needed
        keep = slice(None) if every else ~flat
        at = slice(None) if every else np.flatnonzero(~constant)  # their places in the chunk
        # Columns by np.take: fancy indexing along the second axis costs several times more.
        w = weights if every else gather(weights, at, axis=1)
        # Channels first: each coordinate contiguous for the texel lookups (uv (2, M)).
        uv = None if uvs is None else raster.interpolate_runs(w, uvs[keep], counts[keep], uv_flat[keep],
                                                              channels_first=True)
        if groups is not None:
            palette_normals, palette_colors, group = groups
            first_texel, of_texel = texels.distinct()
            by_texel = tabled[keep].repeat(counts[keep])
            every_texel = bool(by_texel.all())
            u, v = (uv[0], uv[1]) if every_texel else (uv[0][by_texel], uv[1][by_texel])
            u, v = shade.texture_uv_of(material, u, v)
            texel = of_texel.take(shade.point_texel_index_of(texels, u, v, material.main_tex_wrap))
            base = (sum(part.shape[0] for part in palettes) + group * first_texel.size).astype(np.int32)  # (K,)
            texel += base[tabled].repeat(counts[tabled])
            tabled_count += int(counts[tabled].sum())
            places = np.arange(n)[at]  # of the non-flat fragments, in the chunk
            if ids is None and every and every_texel:
                ids = texel
            else:
                if ids is None:
                    ids = np.full(n, -1, dtype=np.int32)
                ids[places[by_texel]] = texel
            palettes.append(shade.texel_palette(material, texels, state.lights, state.color_space, palette_normals,
                                                palette_colors, outline))
            keep = ~flat & ~tabled
            shaded = np.flatnonzero(~by_texel)
            at = places[shaded]
            w = gather(w, shaded, axis=1)
            uv = gather(uv, shaded, axis=1)
        if w.shape[1]:
            def varying(corners: np.ndarray | None, corner_flat: np.ndarray | None) -> np.ndarray | None:
                return None if corners is None else raster.interpolate_runs(
                    w, corners[keep], counts[keep], corner_flat[keep], channels_first=True).T

            lod = None
            if state.mips is not None and uv is not None:  # one LOD per 2x2 quad (§7, "Mipmaps")
                lod = mips.sampling_lod(setup, frags.tri[at], frags.pix[at], state.width, material, texels.shape[:2])
            skip = None  # (M,) bool: fragments not shaded (dropped, or observed and only their alpha computed)
            position = lit_position = None  # (M, 3) world positions; (L, 3) those of the lit ones (below)
            known = None
            if beyond is not None:
                known = _known_dark(state, beyond[at], frags.pix[at])
            if known is not None:
                # Positions for the fragments within the spans alone (runs keep their order: a
                # triangle's fragments there stay one run), all of them lit: as after a render's
                # cut (reach_cut), only the rows' margins hold dark ones there, shaded and merged
                # as the reference does. ``skip`` holds at least 1/SPARSE_SKIP_SHARE of them
                # (_known_dark), so the sparse branch below, which would read every fragment's
                # position, is not taken: lit_position serves the lit.
                within = np.flatnonzero(~known)
                w_within = gather(w, within, axis=1)
                lit_position = position = raster.interpolate_runs(
                    w_within, positions[keep], _segment_sums(~known, counts[keep]), position_flat[keep],
                    channels_first=True).T
                skip = known
            else:
                position = varying(positions, position_flat)
                # After the cut, only the rows' margins (and rows the cut could not place) hold
                # dark fragments: shaded and merged as the reference does (colour 0 added: the
                # stored values stay), that costs less than finding them.
                if state.dark_skip and position is not None and not reach_cut:
                    skip = _dark(state, position, frags.pix[at], [c[keep] for c in (normals, colors) if c is not None])
            color = None  # the vertex colours, when interpolated for the alpha first
            tex_alpha = None  # (M,) the texture's alpha, when sampled for the alpha first
            if p.alpha_test and not state.observed and uv is not None:
                # Alpha first (it reads neither lighting nor the outline): fragments the alpha test
                # discards are not shaded further; an observer would be told of their colours.
                color = varying(colors, color_flat)
                tex_alpha = sample_at(uv.T, lod, (3,))[:, 0]
                alpha = shade.alpha_of(material, tex_alpha, None if color is None else color[:, 3], w.shape[1])
                discarded = ~alpha_passes(alpha, material.cutoff, p.alpha_test_comp)
                if discarded.any():
                    skip = discarded if skip is None else skip | discarded
            sparse = False
            if skip is not None:
                places = np.arange(n)[at]
                if not state.observed:  # observed, unlit fragments are merged and told of (rgb 0)
                    dropped = np.zeros(n, dtype=bool)
                    dropped[places[skip]] = True
                sparse = int(np.count_nonzero(skip)) * SPARSE_SKIP_SHARE < skip.size
            if skip is None or sparse:
                # Few to drop: all are shaded (a dropped fragment's colour is never read) rather
                # than the others gathered out and scattered back.
                shaded_rgba = shade_at(None if uv is None else uv.T, varying(normals, normal_flat),
                                       varying(colors, color_flat) if color is None else color, position,
                                       w.shape[1], lod, tex_alpha)
                if isinstance(at, slice):
                    rgba[at] = shaded_rgba
                else:
                    scatter_rows(rgba, at, shaded_rgba)
            else:  # unreached by a ForwardAdd light or discarded: dropped, never shaded
                lit = np.flatnonzero(~skip)
                run_counts = counts[keep]
                lit_counts = _segment_sums(~skip, run_counts)
                w_lit = gather(w, lit, axis=1)  # runs keep their order: a triangle's lit fragments stay one run

                def varying_lit(corners: np.ndarray | None, corner_flat: np.ndarray | None) -> np.ndarray | None:
                    return None if corners is None else raster.interpolate_runs(
                        w_lit, corners[keep], lit_counts, corner_flat[keep], channels_first=True).T

                unlit = places[skip]
                scatter_rows(rgba, unlit, _ZERO_RGBA)  # colour 0 (fused calls merge them so)
                if state.observed:  # told of: their alpha as shading computes it (it reads no light)
                    inert = np.zeros(n, dtype=bool)
                    # Inert where merging them changes nothing (DrawState.dark_skip); indexing, not
                    # np.take, of the strided alpha codes (see _dark).
                    saturated = None if state.dark_alpha is None else state.dark_alpha[frags.pix[unlit]] == 255
                    inert[unlit if saturated is None else unlit[saturated]] = True
                    dim = np.flatnonzero(skip)
                    dim_color = None if colors is None else raster.interpolate_runs(  # observed: no alpha first
                        gather(w, dim, axis=1), colors[keep][:, :, 3:], run_counts - lit_counts, color_flat[keep])[:, 0]
                    # A textured mesh without UVs samples at (0, 0), as shade_at does (lod is None then).
                    dim_alpha = None if texels is None else sample_at(
                        np.zeros((dim.size, 2), dtype=np.float64) if uv is None else gather(uv, dim, axis=1).T,
                        None if lod is None else gather(lod, dim), (3,))[:, 0]
                    rgba[unlit, 3] = shade.alpha_of(material, dim_alpha, dim_color, dim.size)
                # Colours and positions are views of channels-first arrays: gathered along those.
                scatter_rows(rgba, places[lit], shade_at(
                    None if uv is None else gather(uv, lit, axis=1).T, varying_lit(normals, normal_flat),
                    varying_lit(colors, color_flat) if color is None else gather(color.T, lit, axis=1).T,
                    lit_position if known is not None else None if position is None
                    else gather(position.T, lit, axis=1).T, lit.size,
                    None if lod is None else gather(lod, lit), None if tex_alpha is None else gather(tex_alpha, lit)))
    palette = None
    if palettes:
        palette = palettes[0] if len(palettes) == 1 else np.concatenate(palettes)
        # 8-bit blending of a constant colour is a function of the destination code: tabulate
        # it (256 rows per colour, one without Blend) when that is cheaper than blending every fragment.
        if table_pays(p, state.hdr, state.color_space is ColorSpace.Linear, palette, tabled_count):
            if tabled_count == n:
                rgba = None  # every colour comes from the palette
        else:
            if tabled_count == n:
                rgba = palette.take(ids, axis=0)
            else:
                tabled_at = ids >= 0
                rgba[tabled_at] = palette.take(ids[tabled_at], axis=0)
            ids = palette = None
    alive = alpha_test(rgba, ids, palette, material.cutoff, p.alpha_test_comp) if p.alpha_test else None
    if dropped is not None:
        alive = ~dropped if alive is None else alive & ~dropped
    triangle_fn = None
    if state.observed:  # source triangles only when an observer reads them (and only those it reads)
        def triangle_fn(index: np.ndarray | None) -> np.ndarray:
            if index is None:
                return row_src.repeat(length)
            return row_src.take(np.searchsorted(length.cumsum(), index, side="right"))
    disjoint = raster.rows_disjoint(rows, start, stop, state.width)
    depth_fn = None
    if depth is None and state.observed:
        def depth_fn(index: np.ndarray | None) -> np.ndarray:
            if index is None:
                with_bary = frags if frags.bary is not None else raster.rasterize_rows(rows, start, stop, state.width)
                return raster.interpolate(setup, with_bary, p.offset_factor, p.offset_units, weights=False)[0]
            # Rasterise only the rows holding fragments ``index``, then pick them out.
            ends = length.cumsum()
            row = np.searchsorted(ends, index, side="right")
            used, which = np.unique(row, return_inverse=True)
            sub = rows.take_rows(start + used)
            codes = raster.interpolate(setup, raster.rasterize_rows(sub, 0, sub.count, state.width),
                                       p.offset_factor, p.offset_units, weights=False)[0]
            sub_first = sub.length.cumsum() - sub.length
            return codes[sub_first[which.reshape(-1)] + (index - (ends - length)[row])]
    if of_row is not None:  # the counts of the chunk's rows, of which these are the parts kept
        length = np.bincount(of_row, weights=length, minlength=chunk_rows).astype(np.int64)
    return ShadedFragments(frags.pix, depth, rgba, ids, palette, None, alive, disjoint, depth_fn, triangle_fn,
                           row_counts=None if n == full else length, inert=inert)


#: The colour of fragments left unlit: one row, put at each of theirs (:func:`.gather.scatter_rows`).
_ZERO_RGBA = np.zeros((1, 4), dtype=np.float64)
#: Fragments dropped before merging (out of a ForwardAdd light's reach, discarded by the alpha
#: test) are left out of shading when they are at least 1/SPARSE_SKIP_SHARE of those shaded one
#: by one; fewer are shaded with the others and dropped after (gathering the others out and
#: their colours back costs more than shading a few more).
SPARSE_SKIP_SHARE = 8
#: Rows are cut to a ForwardAdd light's reach (:func:`_reached_spans`: two interpolated positions
#: and a quadratic per row) when they hold at least ROW_REACH_MIN_RUN fragments on average:
#: shorter ones cost about as much to cut as to shade.
ROW_REACH_MIN_RUN = 16
#: A row keeps this many pixels beyond each end of the part of it the light may reach: far above
#: the rounding of that part's ends.
REACH_PIXEL_MARGIN = 1.0


def _reached_spans(setup, rows, start: int, stop: int, state: DrawState, positions: np.ndarray,
                   run_of_row: np.ndarray, corners: list[np.ndarray], saturated_only: bool = True
                   ) -> tuple[np.ndarray, np.ndarray] | None:
    """Rows ``[start, stop)`` (R rows) cut to the part a ForwardAdd light may reach
    (:attr:`DrawState.dark_skip`): the new spans ``[x0, x1)`` (two (R,) int64 within each row's;
    ``x1 <= x0``: nothing kept), or None when nothing is cut. ``positions`` (K, 3, 3) float64: the
    world corners of the chunk's source triangles, ``run_of_row`` (R,) int64 each row's among
    them; ``corners``: their (K, 3, C) normals and colours, all finite and bounded or nothing is
    cut (as :func:`_dark`). Where ``dark_alpha`` is set and ``saturated_only`` (a render's cut: the
    parts cut off are dropped), a row is cut only where its stored alpha is 255 throughout the
    parts cut off, else kept whole.

    Along a row the screen barycentrics are affine in x, so a fragment's perspective-correct world
    position runs along the segment between those of the row's first and last pixels, ``A + t (B −
    A)`` with ``t = λ s_B / ((1 − λ) s_A + λ s_B)`` at the row's fraction ``λ`` of the way from its
    first pixel to its last and ``s`` the interpolated ``1/w`` at each end. The part of the segment
    within the light's reach (:func:`.lights.segments_reach`) maps back to ``λ = t s_A / (t s_A +
    (1 − t) s_B)`` (increasing in t), and the row keeps its pixels within
    :data:`REACH_PIXEL_MARGIN` of that part: the others hold only fragments
    :func:`.lights.dark_fragments` calls dark."""
    if not _bounded(corners):
        return None
    count = stop - start
    ends = raster.row_end_fragments(rows, start, stop, state.width)
    weights = raster.interpolate(setup, ends, weights=True, depth=False)[1]  # (3, 2R): first pixels, then last
    world = positions.take(np.concatenate([run_of_row, run_of_row]), axis=0)  # (2R, 3 corners, 3)
    # Interpolated as the fragments' positions are: each end a run of one fragment.
    at = raster.interpolate_runs(weights, world, np.ones(2 * count, dtype=np.int64), raster.flat_corners(world))
    scale = float(np.abs(positions).max(initial=0.0))
    t_lo, t_hi = lights.segments_reach(state.lights.add, at[:count], at[count:], scale)
    iw = setup.iw.take(ends.tri, axis=0)  # (2R, 3) 1/w at the triangle's vertices
    b = ends.bary
    s = b[0] * iw[:, 0]
    s += b[1] * iw[:, 1]
    s += b[2] * iw[:, 2]
    s_a, s_b = s[:count], s[count:]
    first = rows.x0[start:stop]
    stop_x = first + rows.length[start:stop]
    last = (rows.length[start:stop] - 1).astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        near, far = np.multiply(t_lo, s_a), np.multiply(t_hi, s_a)
        lam_lo = near / (near + (1.0 - t_lo) * s_b)
        lam_hi = far / (far + (1.0 - t_hi) * s_b)
        lo = np.ceil(first + lam_lo * last - REACH_PIXEL_MARGIN)
        hi = np.floor(first + lam_hi * last + REACH_PIXEL_MARGIN) + 1.0
    known = (s_a > 0.0) & (s_b > 0.0) & np.isfinite(s_a) & np.isfinite(s_b) & np.isfinite(lo) & np.isfinite(hi)
    x0 = np.where(known, np.clip(lo, first, stop_x), first).astype(np.int64)
    x1 = np.where(known, np.clip(hi, x0, stop_x), stop_x).astype(np.int64)
    empty = known & (t_lo > t_hi)
    x0[empty] = first[empty]
    x1[empty] = first[empty]
    cut = (x0 != first) | (x1 != stop_x)
    if not cut.any():
        return None
    if state.dark_alpha is not None and saturated_only:
        # Cut-off parts keep their stored colour; their alpha too only where it is 255 already.
        # Both sides of the cut rows in one test: they share the box the running count covers.
        some = np.flatnonzero(cut)
        side_x0 = np.concatenate([first[some], x1[some]])  # [first, x0) then [x1, stop)
        side_x1 = np.concatenate([x0[some], stop_x[some]])
        owner = np.concatenate([np.arange(some.size), np.arange(some.size)])
        sides = np.flatnonzero(side_x1 > side_x0)
        part = rows.take_rows(some[owner[sides]] + start)
        part.x0 = side_x0[sides]
        part.length = side_x1[sides] - part.x0
        unsaturated = _unsaturated(state.dark_alpha, state.width, part)
        keep = some[np.bincount(owner[sides], weights=unsaturated, minlength=some.size) > 0]
        x0[keep] = first[keep]
        x1[keep] = stop_x[keep]
    return x0, x1


def _beyond_spans(first: np.ndarray, length: np.ndarray, x0: np.ndarray, x1: np.ndarray) -> np.ndarray:
    """(N,) bool over the fragments of R rows (``first`` (R,) int64 each row's first column,
    ``length`` (R,) int64 its fragments, N in all, in row order): those outside the row's span
    ``[x0, x1)`` (two (R,) int64 within the row, ``x0 <= x1``; :func:`_reached_spans`)."""
    parts = np.empty((length.size, 3), dtype=np.int64)  # per row: before, within, after the span
    np.subtract(x0, first, out=parts[:, 0])
    np.subtract(x1, x0, out=parts[:, 1])
    np.subtract(first + length, x1, out=parts[:, 2])
    return np.tile(_BEYOND_PATTERN, length.size).repeat(parts.reshape(-1))


_BEYOND_PATTERN = np.array([True, False, True])


def _known_dark(state: DrawState, beyond: np.ndarray, pix: np.ndarray) -> np.ndarray | None:
    """(M,) bool: which of M observed fragments (``beyond`` (M,) bool: beyond the light's reached
    spans, ``pix`` (M,) int64 their pixels) :func:`_dark` would call dark without their positions:
    those beyond the spans (their attenuation is 0) at pixels whose colour the observer does not
    read. None when they are too few to pay for handling the others apart (then :func:`_dark`
    tests all, finding the same)."""
    known = beyond if state.colors_read is False else beyond & ~state.colors_read[pix]
    if int(np.count_nonzero(known)) * SPARSE_SKIP_SHARE < known.size:
        return None
    return known


def _unsaturated(alpha: np.ndarray, width: int, rows) -> np.ndarray:
    """(R,) bool: which of ``rows`` hold a pixel whose stored ``alpha`` (H*W,) uint8 is not 255.
    Over the rows' box, a running count of such pixels along each buffer row gives a span's in
    two reads, when the box is not much larger than the spans; else their pixels are read."""
    y, x0, x1 = rows.y, rows.x0, rows.x0 + rows.length
    y_lo, y_hi, x_lo, x_hi = int(y.min()), int(y.max()) + 1, int(x0.min()), int(x1.max())
    if (y_hi - y_lo) * (x_hi - x_lo) > 4 * int(rows.length.sum()):
        pix = raster.rasterize_rows(rows, 0, rows.count, width, bary=False).pix
        return _segment_sums(alpha[pix] != 255, rows.length) > 0  # not np.take: see _dark
    unset = alpha.reshape(-1, width)[y_lo:y_hi, x_lo:x_hi] != 255
    if not unset.any():  # the common case (an opaque base pass wrote 255 under the whole box)
        return np.zeros(rows.count, dtype=bool)
    running = np.zeros((y_hi - y_lo, x_hi - x_lo + 1), dtype=np.int32)
    unset.cumsum(axis=1, out=running[:, 1:])
    at = y - y_lo
    return running[at, x1 - x_lo] != running[at, x0 - x_lo]


def _dark(state: DrawState, position: np.ndarray, pix: np.ndarray, corners: list[np.ndarray]) -> np.ndarray | None:
    """(M,) bool: which of M fragments at world positions ``position`` (M, 3) float64 and pixels
    ``pix`` (M,) int64 a ForwardAdd light does not reach while their pass then changes nothing
    (:attr:`DrawState.dark_skip`); None when none is, or when a corner normal or colour of their
    triangles (``corners``: (K, 3, C) arrays) is not finite and bounded (their interpolated
    values, convex combinations of those, then might not give a colour of exactly 0)."""
    dark = lights.dark_fragments(state.lights.add, position[:, 0], position[:, 1], position[:, 2])
    if state.observed and state.colors_read is not False:  # lit where the observer reads the colour
        dark &= ~state.colors_read[pix]
    if state.dark_alpha is not None and not state.observed:  # observed: merged there (DrawState.dark_skip)
        # Indexing, not np.take: the alpha codes are a strided view of the colour buffer, which
        # np.take would first copy whole.
        dark &= state.dark_alpha[pix] == 255
    if not dark.any() or not _bounded(corners):
        return None
    return dark


def _bounded(corners: list[np.ndarray]) -> bool:
    """Whether every value of ``corners`` (normals, colours) is finite and at most
    :data:`.lights.DARK_SKIP_PEAK` in magnitude (then so are values interpolated from them)."""
    return all(bool((np.abs(values) <= lights.DARK_SKIP_PEAK).all()) for values in corners)


def shade_colourless_chunk(setup, rows, start: int, stop: int, state: DrawState) -> ShadedFragments | None:
    """:func:`shade_chunk` of a pass that writes no colour and has no alpha test: pixels and
    depth only (the merger reads no colour of such a pass). Observed, the colours, deferred
    depths and source triangles an observer reads come from :func:`shade_chunk` of the chunk,
    run only when read (a pixel history reads the chunks on its pixel; a draw list none)."""
    light = shade_constant_chunk(setup, rows, start, stop, state, None, None)
    if light is None or not state.observed:
        return light
    full: list[ShadedFragments] = []

    def part(index: np.ndarray | None) -> ShadedFragments:
        if not full:
            full.append(shade_chunk(setup, rows, start, stop, state))
        return full[0] if index is None else full[0].select(index)

    light.colors_fn = lambda index: part(index).colors()
    light.triangle_fn = lambda index: part(index).triangle
    if light.stored_depth is None:
        light.depth_fn = lambda index: part(index).depth
    return light


def shade_constant_chunk(setup, rows, start: int, stop: int, state: DrawState, color_id: np.ndarray | None,
                         palette: np.ndarray | None) -> ShadedFragments | None:
    """:func:`shade_chunk` of rows whose every fragment takes a constant colour:
    ``palette[color_id[tri]]`` for setup triangle ``tri`` (``color_id`` (T,) int32, ``palette``
    (K, 4) float64), or no colour at all when ``palette`` is None. Depth as there; no weights,
    no per-fragment shading."""
    p = state.pass_state
    length = rows.length[start:stop]
    n = int(length.sum())
    if n == 0:
        return None
    want_depth = state.depth_needed(rows, start, stop)
    frags = raster.rasterize_rows(rows, start, stop, state.width, bary=want_depth)
    depth = None
    if want_depth:
        depth = raster.interpolate(setup, frags, p.offset_factor, p.offset_units, weights=False)[0]
    disjoint = raster.rows_disjoint(rows, start, stop, state.width)
    if palette is None:
        return ShadedFragments(frags.pix, depth, None, None, None, None, None, disjoint)
    ids = raster.run_expander(length, n)(color_id.take(rows.tri[start:stop]))
    rgba, chunk_palette = None, palette
    if not table_pays(p, state.hdr, state.color_space is ColorSpace.Linear, palette, n):
        rgba, ids, chunk_palette = palette.take(ids, axis=0), None, None  # blended one by one
    return ShadedFragments(frags.pix, depth, rgba, ids, chunk_palette, None, None, disjoint)
