"""The frame driver: draw list → per draw call (vertex → raster → shade → output merger) → Frame.

Each draw call's rows are split into horizontal screen bands of about equal fragment
counts; one worker thread per band rasterises, shades and merges its band (numpy
releases the GIL in its array loops, so both CPU cores work). Bands own disjoint pixels
and each band is processed in draw order, so the result is exact.
"""

from __future__ import annotations

import functools
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, wait
from dataclasses import dataclass, field, replace

import numpy as np

from . import merger, raster, shade, vertex
from .drawlist import DrawCall, draw_calls
from .merger import FrameBuffers, merge
from .scene import DrawScene, SceneError, SceneMemo, validate_scene
from .vocabulary import ColorSpace, CompareFunction, Lighting, Material, Pass, TextureFilter

#: Candidate pixels per chunk. Small enough that a chunk's per-fragment arrays (1 MB each for
#: int64) stay in a core's cache while a chunk passes through the stages, large enough that the
#: per-chunk Python work stays small: on the 2-core machine 128k beat 1M by 10-35 % on S1, S4
#: and the example scenes, with S2 within 10 %; 32k lost on every scene.
CHUNK_CANDIDATES = 1 << 17
#: Frames with fewer pixels render in one thread by default: below this, handing screen bands to
#: a second thread costs more than it saves (the viewport's 240x135 first frames of the example
#: scenes took 12-59 ms in one thread against 21-86 ms in two; at 960x540 two threads win).
SMALL_FRAME_PIXELS = 1 << 18


class RenderCancelled(Exception):
    """Raised when ``should_cancel()`` returned True; no buffers are returned."""


@dataclass(eq=False)
class Frame:
    """A rendered frame. Row 0 is the top of the image.

    - ``color`` (H, W, 4) float32: the stored frame values (sRGB-encoded in Gamma
      mode and in Linear LDR; linear in Linear HDR).
    - ``depth`` (H, W) float32: window depth ``d / (2**24 - 1)``.
    - ``stencil`` (H, W) uint8.
    - ``warnings``: one line each (skipped triangles, empty meshes, missing images).
    - ``encoded``: whether ``color``'s rgb is sRGB-encoded (Gamma mode, and Linear LDR);
      False only for Linear HDR, whose buffer holds linear values.
    """

    color: np.ndarray
    depth: np.ndarray
    stencil: np.ndarray
    warnings: list[str] = field(default_factory=list)
    encoded: bool = True


@dataclass(frozen=True, eq=False)
class DrawState:
    """What one draw call needs beyond its triangles, decided once per draw call (the
    "derived state" of the call): the draw call, its material and pass, the texture's
    texels in shading space, the frame's lights, colour space, buffer kind and width."""

    call: DrawCall
    material: Material
    texels: np.ndarray | None
    lights: shade.Lights
    color_space: ColorSpace
    hdr: bool
    width: int
    #: An observer receives every fragment: source triangles are computed, and depth codes the
    #: merge does not need are computed when the observer reads them.
    observed: bool = False
    #: ``zbound`` (T,) int64 per setup triangle (:func:`raster.depth_upper_codes`) and ``zfloor``
    #: (H,) int64 the smallest depth code stored in each buffer row: rows whose bound is at or
    #: below (``Less``: below) the floor pass the depth test, so a pass without ZWrite needs no
    #: per-fragment depth there (a hierarchical-Z test per row, exact). None: not applicable.
    zbound: np.ndarray | None = None
    zfloor: np.ndarray | None = None

    @property
    def pass_state(self) -> Pass:
        return self.call.state

    def depth_needed(self, rows, start: int, stop: int) -> bool:
        """Whether the fragments of rows ``[start, stop)`` need their depth codes."""
        p = self.pass_state
        if p.zwrite:
            return True
        if p.ztest is CompareFunction.Always:
            return False
        if self.zbound is None or self.zfloor is None:
            return True
        bound = self.zbound[rows.tri[start:stop]]
        floor = self.zfloor[rows.y[start:stop]]
        trivial = bound < floor if p.ztest is CompareFunction.Less else bound <= floor
        return not bool(np.all(trivial))


@dataclass(eq=False)
class ShadedFragments:
    """A chunk of one draw call's fragments after shading, in primitive order.

    - ``pix`` (N,) int64: window pixel index ``y * W + x`` with y up (row 0 = bottom).
    - ``depth`` (N,) int64: 24-bit depth code after Offset. When the chunk provably passes the
      depth test of a pass without ZWrite (:meth:`DrawState.depth_needed`), the codes are only
      computed when an observer reads ``depth`` (``stored_depth`` None, ``depth_fn`` set), or
      never (no observer: ``depth`` None).
    - ``rgba`` (N, 4) float64: shader output in shading space (rows with ``ids >= 0`` unset),
      or None when every fragment has an id.
    - ``ids`` (N,) int32 or None, ``palette`` (K, 4) float64 or None: fragments with
      ``ids >= 0`` have the colour ``palette[ids]`` (shaded once per triangle).
    - ``triangle`` (N,) int64: the source mesh triangle (index in the renderer's mesh), computed
      when an observer reads it (``stored_triangle`` / ``triangle_fn``); None when not observed.
    - ``alive`` (N,) bool or None: passed the alpha test (None: the pass has no alpha test).
    - ``disjoint``: the fragments hit pairwise distinct pixels (one merge layer).
    """

    pix: np.ndarray
    stored_depth: np.ndarray | None
    rgba: np.ndarray
    ids: np.ndarray | None
    palette: np.ndarray | None
    stored_triangle: np.ndarray | None
    alive: np.ndarray | None
    disjoint: bool = False
    #: ``depth_fn(index)``: the deferred depth codes of fragments ``index`` (None: all).
    depth_fn: Callable[[np.ndarray | None], np.ndarray] | None = None
    #: ``triangle_fn(index)``: the source triangles of fragments ``index`` (None: all), deferred.
    triangle_fn: Callable[[np.ndarray | None], np.ndarray] | None = None
    #: ``colors_fn(index)``: the shader colours (M, 4) of fragments ``index`` (None: all), deferred
    #: (a pass that writes no colour, observed: colours only for the fragments an observer reads).
    colors_fn: Callable[[np.ndarray | None], np.ndarray] | None = None

    @property
    def triangle(self) -> np.ndarray | None:
        """(N,) int64 source mesh triangles, computed on first use when deferred (observed renders)."""
        if self.stored_triangle is None and self.triangle_fn is not None:
            self.stored_triangle, self.triangle_fn = self.triangle_fn(None), None
        return self.stored_triangle

    @property
    def count(self) -> int:
        return int(self.pix.shape[0])

    @property
    def depth(self) -> np.ndarray | None:
        """(N,) int64 depth codes, computed on first use when deferred (see the class doc)."""
        if self.stored_depth is None and self.depth_fn is not None:
            self.stored_depth, self.depth_fn = self.depth_fn(None), None
        return self.stored_depth

    def colors(self) -> np.ndarray:
        """(N, 4) float64 shader colours, table entries filled in."""
        if self.ids is None and self.rgba is None and self.colors_fn is not None:
            return self.colors_fn(None)
        if self.ids is None:
            return self.rgba
        if self.rgba is None:
            return self.palette[self.ids]
        out = self.rgba.copy()
        tabled = self.ids >= 0
        out[tabled] = self.palette[self.ids[tabled]]
        return out

    def span(self, lo: int, hi: int) -> ShadedFragments:
        """Fragments ``[lo, hi)`` as views, palette kept (a chunk without deferred values)."""
        def cut(a):
            return None if a is None else a[lo:hi]

        return ShadedFragments(cut(self.pix), cut(self.stored_depth), cut(self.rgba), cut(self.ids), self.palette,
                               cut(self.stored_triangle), cut(self.alive), self.disjoint)

    def select(self, keep: np.ndarray) -> ShadedFragments:
        """The fragments where ``keep`` (bool (N,) or indices) holds."""
        index = np.flatnonzero(keep) if keep.dtype == bool else keep

        def take(a):
            return None if a is None else np.take(a, index, axis=0)

        def deferred(stored, fn):
            # A deferred value of the selection asks for the selected fragments only (a pixel
            # history reads a handful of each chunk).
            if stored is not None or fn is None:
                return None
            return lambda sub: fn(index if sub is None else np.take(index, sub))

        depth_fn = deferred(self.stored_depth, self.depth_fn)
        triangle_fn = deferred(self.stored_triangle, self.triangle_fn)
        colors_fn = deferred(self.rgba if self.ids is None else self.ids, self.colors_fn)
        return ShadedFragments(take(self.pix), take(self.stored_depth), take(self.rgba), take(self.ids),
                               self.palette, take(self.stored_triangle), take(self.alive), self.disjoint, depth_fn,
                               triangle_fn, colors_fn)


class FrameObserver:
    """Receives the records of a render as it happens (frame debugger, sorted reference, overdraw).

    :meth:`fragments` is called from band worker threads (each band owns distinct pixels;
    within a band, chunks come in primitive order): implementations must be thread-safe.
    The base class ignores everything.
    """

    #: Whether :meth:`draw_begin` / :meth:`draw_end` must see the buffers exactly as they are
    #: between two draw calls (snapshots). False lets the renderer draw calls in batches, as
    #: without an observer: ``draw_begin`` of a batch's calls comes before it is drawn and
    #: ``draw_end`` after (with the buffers after the whole batch); fragments keep their order.
    exact_boundaries = True

    def draw_begin(self, call: DrawCall, buffers: FrameBuffers) -> None:
        """Before draw call ``call`` (``buffers`` as left by the draw calls before it when
        :attr:`exact_boundaries`; else as left by the batch before it)."""

    def fragments(self, call: DrawCall, frags: ShadedFragments, outcome: np.ndarray) -> None:
        """Every fragment rasterised in a chunk, with its :class:`merger.Outcome` (N,) int8."""

    def draw_end(self, call: DrawCall, buffers: FrameBuffers, triangles: int) -> None:
        """After draw call ``call``; ``triangles``: the call's source triangles that reach the
        rasteriser (neither culled nor degenerate nor entirely clipped away)."""


#: A texel palette (one colour per normal and texel, :func:`shade.texel_palette`) replaces
#: per-fragment shading when it has at most this share of the fragments it serves.
TEXEL_PALETTE_SHARE = 4
#: Textures up to this many texels are examined for repeated texels (a palette entry each).
TEXEL_PALETTE_EXAMINE = 1 << 14


def _texel_groups(state: DrawState, candidates: np.ndarray, normals, counts) -> tuple[np.ndarray, np.ndarray] | None:
    """Point-filtered triangles whose normal is constant: their colour is a function of
    (normal, texel). Returns ``(normals (G, 3), group (K,) int64 per triangle)`` when a palette
    of G * (distinct texels) colours is cheaper than shading the candidates' fragments, else None."""
    served = int(counts[candidates].sum())
    h, w = state.texels.shape[:2]
    # Finding the distinct texels of a large texture costs more than it can save unless even
    # its full size would pay: only small textures are examined for repeated texels.
    if h * w > TEXEL_PALETTE_EXAMINE and h * w * TEXEL_PALETTE_SHARE > served:
        return None
    texel_count = state.texels.distinct()[0].size
    if texel_count * TEXEL_PALETTE_SHARE > served:
        return None
    if normals is None:  # Unlit: the colour depends on the texel alone
        return np.zeros((1, 3), dtype=np.float64), np.zeros(candidates.size, dtype=np.int64)
    corner = np.ascontiguousarray(normals[candidates, 0])
    # Distinct by bytes, not value: -0.0 and 0.0 (or NaNs) stay apart, so each group's normal is
    # bit for bit the one its fragments would be shaded with.
    _, where, inverse = np.unique(corner.view(np.dtype((np.void, corner.itemsize * 3))).reshape(-1),
                                  return_index=True, return_inverse=True)
    if where.size * texel_count * TEXEL_PALETTE_SHARE > served:
        return None
    group = np.zeros(candidates.size, dtype=np.int64)
    group[candidates] = inverse.reshape(-1)
    return corner[where], group


def _distinct_colors(colors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(colors, axis=0, return_inverse=True)`` of (K, 4) float64 colours, without its
    sort when every row has the same bytes (an unlit or evenly lit mesh: the common case)."""
    bits = np.ascontiguousarray(colors).view(np.int64)
    if np.isfinite(colors).all() and (bits == bits[:1]).all():
        return colors[:1], np.zeros(colors.shape[0], dtype=np.int64)
    return np.unique(colors, axis=0, return_inverse=True)


def _alpha_test(rgba: np.ndarray | None, ids: np.ndarray | None, palette: np.ndarray | None,
                cutoff: float) -> np.ndarray:
    """(N,) bool: the fragments that survive ``clip(alpha - _Cutoff)``, their colours given as
    in :class:`ShadedFragments` (``rgba``, or ``palette[ids]`` where ``ids >= 0``)."""
    if ids is None:
        alpha = rgba[:, 3]
    elif rgba is None:
        alpha = np.take(palette[:, 3], ids)
    else:
        alpha = np.where(ids >= 0, palette[np.maximum(ids, 0), 3], rgba[:, 3])
    return ~(alpha - float(cutoff) < 0)


def _shade_chunk(setup, rows, start: int, stop: int, state: DrawState) -> ShadedFragments | None:
    """Raster + interpolate + shade + alpha test of rows [start, stop), in draw order.

    Triangles whose inputs to shading are constant (no texture or flat UVs, Unlit or flat
    normals: docs/pipeline.md §6) are shaded once per triangle; Point-filtered textured
    triangles with a constant normal take their colour from a palette shaded once per
    (normal, texel); the others are shaded once per fragment. Work per source triangle
    (runs, flatness, table ids) is done per row and expanded.
    """
    p, material, texels = state.pass_state, state.material, state.texels
    length = rows.length[start:stop]
    n = int(length.sum())
    if n == 0:
        return None
    # Rows come in triangle order: each source triangle's rows (so fragments) form one run.
    row_src = setup.src[rows.tri[start:stop]]
    first = np.ones(row_src.size, dtype=bool)
    first[1:] = row_src[1:] != row_src[:-1]
    run_of_row = np.cumsum(first) - 1
    tris = row_src[first]  # (K,) the source triangles of this chunk
    uvs = setup.uvs_of(tris) if texels is not None and setup.object_uvs is not None else None
    normals = setup.world_normals_of(tris) if setup.object_normals is not None else None
    flat = np.ones(tris.size, dtype=bool)  # shading inputs constant over the triangle (§6)
    uv_flat = normal_flat = None
    if uvs is not None:
        uv_flat = raster.flat_corners(uvs)
        flat &= uv_flat
    if normals is not None:
        normal_flat = raster.flat_corners(normals)
        flat &= normal_flat
    any_varying = not bool(np.all(flat))
    counts = np.add.reduceat(length, np.flatnonzero(first))  # (K,) fragments per triangle
    groups = None  # texel-palette groups (normals (G, 3), group (K,)) and the triangles they serve
    if any_varying and uvs is not None and material.main_tex_filter is TextureFilter.Point:
        candidates = ~uv_flat if normal_flat is None else ~uv_flat & normal_flat
        if np.any(candidates):
            groups = _texel_groups(state, candidates, normals, counts)
            tabled = candidates
    want_depth = state.depth_needed(rows, start, stop)
    frags = raster.rasterize_rows(rows, start, stop, state.width, bary=want_depth or any_varying)
    depth = weights = None
    if frags.bary is not None:
        depth, weights = raster.interpolate(setup, frags, p.offset_factor, p.offset_units,
                                            weights=any_varying, depth=want_depth)
    rgba = np.empty((n, 4), dtype=np.float64)
    palettes: list[np.ndarray] = []  # colours fragments take by id: per flat triangle, per texel
    ids = None  # (N,) int32 palette entry of each fragment, -1 for those shaded one by one
    tabled_count = 0  # fragments with an id
    row_flat = flat[run_of_row]
    constant = None if not any_varying else np.repeat(row_flat, length)

    def shade_at(uv: np.ndarray | None, normal: np.ndarray | None, count: int) -> np.ndarray:
        uv = np.zeros((count, 2), dtype=np.float64) if uv is None else uv
        normal = np.zeros((count, 3), dtype=np.float64) if normal is None else normal
        return shade.shade(material, texels, state.lights, state.color_space, uv, normal)

    if np.any(flat):
        const_tris = np.nonzero(flat)[0]
        colors = shade_at(None if uvs is None else uvs[const_tris, 0],
                          None if normals is None else normals[const_tris, 0], const_tris.size)
        # Triangles of one colour (an unlit mesh, a flat-lit plane) share one palette entry.
        colors, inverse = _distinct_colors(colors)
        palettes.append(colors)
        slot = np.full(tris.size, -1, dtype=np.int32)
        slot[const_tris] = inverse.reshape(-1)
        ids = np.repeat(slot[run_of_row], length)
        tabled_count = n if not any_varying else int(counts[flat].sum())
    if any_varying:
        # Varying fragments are exactly those of the non-flat triangles: whole runs.
        every = not np.any(flat)  # e.g. a smooth mesh: no masked copies needed
        keep = slice(None) if every else ~flat
        at = slice(None) if every else np.flatnonzero(~constant)  # their places in the chunk
        w = weights if every else weights[:, ~constant]
        # Channels first: each coordinate contiguous for the texel lookups (uv (2, M)).
        uv = None if uvs is None else raster.interpolate_runs(w, uvs[keep], counts[keep], uv_flat[keep],
                                                              channels_first=True)
        if groups is not None:
            palette_normals, group = groups
            first_texel, of_texel = texels.distinct()
            by_texel = np.repeat(tabled[keep], counts[keep])
            every_texel = bool(by_texel.all())
            u, v = (uv[0], uv[1]) if every_texel else (uv[0][by_texel], uv[1][by_texel])
            u, v = shade.texture_uv_of(material, u, v)
            texel = np.take(of_texel, shade.point_texel_index_of(texels, u, v, material.main_tex_wrap))
            base = (sum(part.shape[0] for part in palettes) + group * first_texel.size).astype(np.int32)  # (K,)
            texel += np.repeat(base[tabled], counts[tabled])
            tabled_count += int(counts[tabled].sum())
            places = np.arange(n)[at]  # of the non-flat fragments, in the chunk
            if ids is None and every and every_texel:
                ids = texel
            else:
                if ids is None:
                    ids = np.full(n, -1, dtype=np.int32)
                ids[places[by_texel]] = texel
            palettes.append(shade.texel_palette(material, texels, state.lights, state.color_space, palette_normals))
            keep = ~flat & ~tabled
            shaded = ~by_texel
            at = places[shaded]
            w = w[:, shaded]
            uv = uv[:, shaded]
        if w.shape[1]:
            normal = None if normals is None else raster.interpolate_runs(
                w, normals[keep], counts[keep], normal_flat[keep], channels_first=True).T
            rgba[at] = shade_at(None if uv is None else uv.T, normal, w.shape[1])
    palette = None
    if palettes:
        palette = palettes[0] if len(palettes) == 1 else np.concatenate(palettes)
        # 8-bit blending of a constant colour is a function of the destination code: tabulate
        # it (256 rows per colour, one without Blend) when that is cheaper than blending every fragment.
        if merger.table_pays(p, state.hdr, state.color_space is ColorSpace.Linear, palette, tabled_count):
            if tabled_count == n:
                rgba = None  # every colour comes from the palette
        else:
            if tabled_count == n:
                rgba = np.take(palette, ids, axis=0)
            else:
                tabled_at = ids >= 0
                rgba[tabled_at] = np.take(palette, ids[tabled_at], axis=0)
            ids = palette = None
    alive = _alpha_test(rgba, ids, palette, material.cutoff) if p.alpha_test else None
    triangle_fn = None
    if state.observed:  # source triangles only when an observer reads them (and only those it reads)
        def triangle_fn(index: np.ndarray | None) -> np.ndarray:
            if index is None:
                return np.repeat(row_src, length)
            return np.take(row_src, np.searchsorted(np.cumsum(length), index, side="right"))
    disjoint = raster.rows_disjoint(rows, start, stop, state.width)
    depth_fn = None
    if depth is None and state.observed:
        def depth_fn(index: np.ndarray | None) -> np.ndarray:
            if index is None:
                with_bary = frags if frags.bary is not None else raster.rasterize_rows(rows, start, stop, state.width)
                return raster.interpolate(setup, with_bary, p.offset_factor, p.offset_units, weights=False)[0]
            # Rasterise only the rows holding fragments ``index``, then pick them out.
            ends = np.cumsum(length)
            row = np.searchsorted(ends, index, side="right")
            used, which = np.unique(row, return_inverse=True)
            sub = rows.take_rows(start + used)
            codes = raster.interpolate(setup, raster.rasterize_rows(sub, 0, sub.count, state.width),
                                       p.offset_factor, p.offset_units, weights=False)[0]
            sub_first = np.cumsum(sub.length) - sub.length
            return codes[sub_first[which.reshape(-1)] + (index - (ends - length)[row])]
    return ShadedFragments(frags.pix, depth, rgba, ids, palette, None, alive, disjoint, depth_fn, triangle_fn)


def _draw_band(buf, setup, rows, chunk_candidates: int, state: DrawState, stop_flag, observer,
               tables: dict | None = None, shade_chunk: Callable = _shade_chunk) -> None:
    """Raster, shade and merge one screen band of a draw call, chunk by chunk in draw order.
    ``tables``: the draw call's blend tables (:class:`merger.BlendTables`), shared by its bands;
    ``shade_chunk``: how a chunk is shaded."""
    p = state.pass_state
    if tables is None:
        tables = {}  # blend tables of this band's palettes, shared by its chunks
    for a, b in raster.row_chunks(rows, chunk_candidates):
        if stop_flag.is_set():
            return
        shaded = shade_chunk(setup, rows, a, b, state)
        if shaded is None:
            continue
        merged = shaded if shaded.alive is None else shaded.select(shaded.alive)
        if observer is None:
            merge(buf, p, merged.pix, merged.stored_depth, merged.rgba, merged.ids, merged.palette,
                  disjoint=merged.disjoint, tables=tables)
            continue
        outcome = np.full(shaded.count, merger.Outcome.ALPHA_TEST, dtype=np.int8)
        written = np.empty(merged.count, dtype=np.int8)
        merge(buf, p, merged.pix, merged.stored_depth, merged.rgba, merged.ids, merged.palette, outcome=written,
              disjoint=merged.disjoint, tables=tables)
        if shaded.alive is None:
            outcome = written
        else:
            outcome[shaded.alive] = written
        observer.fragments(state.call, shaded, outcome)


def _draw_shared_band(buf, prepared: _Prepared, rows, chunk_candidates: int, state: DrawState, stop_flag) -> None:
    """:func:`_draw_band` of calls with shared shading (:func:`_fuse_shared_shading`): each
    chunk is shaded once (``state``: how, with the band's depth floors); then each call's
    fragments, a contiguous run of the chunk (rows come in call order), pass its own alpha test
    and merge with its own pass, call after call."""
    members = prepared.members
    firsts = np.array([m.first for m in members], dtype=np.int64)
    for a, b in raster.row_chunks(rows, chunk_candidates):
        if stop_flag.is_set():
            return
        shaded = prepared.shade(prepared.setup, rows, a, b, state)
        if shaded is None:
            continue
        member = np.searchsorted(firsts, rows.tri[a:b], side="right") - 1  # (R,) nondecreasing
        bounds = [0, *(np.flatnonzero(member[1:] != member[:-1]) + 1).tolist(), b - a]
        ends = np.cumsum(rows.length[a:b]).tolist()
        for lo, hi in zip(bounds[:-1], bounds[1:], strict=False):
            f0, f1 = (ends[lo - 1] if lo else 0), ends[hi - 1]
            if f1 > f0:
                part = shaded.span(f0, f1)
                if not part.disjoint and len(bounds) > 2:  # the chunk's rows overlap; the call's may not
                    part.disjoint = raster.rows_disjoint(rows, a + lo, a + hi, buf.width)
                _merge_member(buf, members[int(member[lo])], part)


def _merge_member(buf, member: _Member, frags: ShadedFragments) -> None:
    """Alpha test and merge of one call's fragments shaded with others'."""
    p = member.state.pass_state
    if frags.ids is not None and not merger.lut_eligible(p, buf.hdr):
        frags = replace(frags, rgba=frags.colors(), ids=None, palette=None)  # blended one by one
    if p.alpha_test:
        frags = frags.select(_alpha_test(frags.rgba, frags.ids, frags.palette, member.state.material.cutoff))
    merge(buf, p, frags.pix, frags.stored_depth, frags.rgba, frags.ids, frags.palette, disjoint=frags.disjoint,
          tables=member.tables)


def _wait(futures, should_cancel, stop_flag) -> None:
    """Wait for band workers, polling ``should_cancel`` from this (the calling) thread."""
    pending = set(futures)
    while pending:
        done, pending = wait(pending, timeout=0.05)
        for f in done:
            f.result()  # re-raise worker errors
        if should_cancel is not None and should_cancel():
            stop_flag.set()
            wait(pending)
            return


@dataclass(eq=False)
class _FrameContext:
    """What the draw calls of one render share: buffers, camera, lights, pool, caches, notes."""

    buf: FrameBuffers
    camera: object
    lights: shade.Lights
    color_space: ColorSpace
    hdr: bool
    chunk_candidates: int
    pool: ThreadPoolExecutor | None
    workers: int
    stop_flag: threading.Event
    observed: bool = False
    #: Buffer rows ``[y0, y1)`` (y from the bottom) this render draws, or None for all
    #: (:func:`render_scene`'s ``band``: one process's share of a frame, :mod:`blendlib.core.bandprocs`).
    band: tuple[int, int] | None = None
    #: Converted textures and (small renderers') setups, kept across renders when render_scene
    #: is given a memo.
    memo: SceneMemo = field(default_factory=SceneMemo)
    #: Whether setups go into the memo (it outlives this render: render_scene was given one).
    keep_setups: bool = False
    warnings: list[str] = field(default_factory=list)
    degenerate: list[tuple[str, int]] = field(default_factory=list)  # (object, zero-area triangles)

    @property
    def width(self) -> int:
        return self.buf.width

    @property
    def height(self) -> int:
        return self.buf.height

    @functools.cached_property
    def camera_key(self) -> tuple:
        """What a kept vertex setup is for: the camera's matrices and size (:func:`_setups`)."""
        return _camera_key(self.camera)

    def record(self, notes: list[str], degenerate: tuple[str, int] | None) -> None:
        """What :func:`_setup` found about a renderer, for the frame's warnings (in draw order)."""
        self.warnings.extend(notes)
        if degenerate is not None:
            self.degenerate.append(degenerate)

    def texels_of(self, material: Material):
        """The material's texture in shading space, converted once per memo (main thread only)."""
        texture, color_space = material.main_tex, self.color_space
        if texture is None:
            return None
        return self.memo.lookup(("texels", color_space), texture, lambda: shade.texture_texels(texture, color_space))


@dataclass(eq=False)
class _Prepared:
    """A draw call ready to draw: its renderer's triangle setup, the triangles its Cull keeps,
    their covered rows and its :class:`DrawState` (``zfloor`` filled in by whoever draws it)."""

    call: DrawCall
    setup: object
    selected: np.ndarray
    rows: raster.Rows
    state: DrawState
    #: Blend tables of the call's palettes, built once and shared by the bands that draw it.
    tables: merger.BlendTables = field(default_factory=merger.BlendTables)
    #: Raster + interpolate + shade of a chunk of rows (:func:`_shade_chunk`, or a specialised
    #: one: :func:`_skip_unused_shading`, :func:`_fuse_constant_calls`).
    shade: Callable = _shade_chunk
    #: Calls shaded together and merged one by one (:func:`_fuse_shared_shading`), or None:
    #: ``state`` is then only how the chunks are shaded.
    members: list[_Member] | None = None


@dataclass(eq=False)
class _Member:
    """One draw call of a :class:`_Prepared` with shared shading: its own state (pass,
    cutoff), blend tables, and first triangle in the shared setup."""

    state: DrawState
    tables: merger.BlendTables
    first: int


def _setup_input(renderer) -> vertex.SetupInput:
    """What the vertex setup of ``renderer`` needs: normals only for lit shading, UVs only with a texture."""
    material = renderer.material
    return vertex.SetupInput(renderer.mesh, renderer.matrix_world, need_normals=material.lighting is not Lighting.Unlit,
                             need_uvs=material.main_tex is not None)


def _setup_notes(renderer, setup) -> tuple[list[str], tuple[str, int] | None]:
    """What to tell the user about a renderer's setup: skipped triangles, zero-area ones."""
    notes = []
    if setup.skipped_nonfinite:
        label = f"object {renderer.name!r} slot {renderer.slot}"
        notes.append(f"{label}: skipped {setup.skipped_nonfinite} triangles with non-finite vertices")
    return notes, ((renderer.name, setup.degenerate) if setup.degenerate else None)


#: A memo keeps the vertex setup of renderers of at most this many triangles per camera (and,
#: for whole frames, their passes' coverage rows): the viewport's next frame through the same
#: view redraws the renderers a change left alone without setting them up again (a moved
#: object, an edited material). Bigger meshes are set up again: their setup is a small part of
#: their frame, and keeping it would hold 100+ bytes a triangle.
MEMO_SETUP_TRIANGLES = 1 << 17
#: Cameras per renderer whose setups a memo keeps: the viewport's reduced and full frame sizes.
MEMO_CAMERAS = 2
#: At most this many triangles' setups (over all renderers and cameras) in one memo: about
#: 120-200 bytes each, so some 300 MB; renderers beyond it are set up every frame.
MEMO_SETUP_BUDGET = 1 << 21


@dataclass(eq=False)
class _Geometry:
    """A renderer's triangle setup through one camera and, in whole frames, its passes' rows
    by Cull ((selected triangles, rows)), kept in a memo (:data:`MEMO_SETUP_TRIANGLES`)."""

    setup: object
    rows: dict = field(default_factory=dict)


def _camera_key(camera) -> tuple:
    return (np.asarray(camera.view_matrix, dtype=np.float64).tobytes(),
            np.asarray(camera.projection, dtype=np.float64).tobytes(), int(camera.width), int(camera.height))


def _kept_geometry(frame: _FrameContext, renderer) -> dict | None:
    """The memo's geometry of ``renderer`` by camera key, or None when it is not kept (too big,
    or the memo is this render's own: keeping every setup to the end would raise its peak)."""
    if not frame.keep_setups or renderer.mesh.triangle_count > MEMO_SETUP_TRIANGLES:
        return None
    return frame.memo.lookup("geometry", renderer, dict)


def _setups(frame: _FrameContext, renderers: list, pool=None, parts: int = 1) -> list[_Geometry]:
    """The geometry of each of ``renderers`` through the frame's camera: kept ones from the memo,
    the others set up together (:func:`vertex.setup_renderers`: each equals its own setup) and
    kept for the next frame."""
    key = frame.camera_key
    kept = [_kept_geometry(frame, r) for r in renderers]
    out = [None if k is None else k.get(key) for k in kept]
    todo = [i for i, g in enumerate(out) if g is None]
    if todo:
        made = vertex.setup_renderers([_setup_input(renderers[i]) for i in todo], frame.camera, pool=pool,
                                      parts=parts)
        held = None  # triangles whose setups the memo holds (counted once something is to be kept)
        for i, setup in zip(todo, made, strict=True):
            out[i] = _Geometry(setup)
            if kept[i] is None:
                continue
            if held is None:
                held = sum(r.mesh.triangle_count * len(d) for r, d in frame.memo.entries("geometry"))
            triangles = renderers[i].mesh.triangle_count
            if len(kept[i]) >= MEMO_CAMERAS:  # the oldest camera goes
                kept[i].pop(next(iter(kept[i])))
                held -= triangles
            if held + triangles <= MEMO_SETUP_BUDGET:
                kept[i][key] = out[i]
                held += triangles
    if frame.band is not None:  # a band's rows are its own (the cut moves frame to frame): not kept
        out = [_Geometry(g.setup) for g in out]
    return out


def _setup(frame: _FrameContext, renderer, pool, parts: int) -> tuple[_Geometry, list[str], tuple[str, int] | None]:
    """Vertex setup of one renderer (shared by its passes) and what to tell the user about it."""
    geometry = _setups(frame, [renderer], pool, parts)[0]
    return (geometry, *_setup_notes(renderer, geometry.setup))


def _draw_state(frame: _FrameContext, call: DrawCall, setup, texels,
                selected: np.ndarray | None = None) -> tuple[DrawState, np.ndarray]:
    """A draw call's derived state and the triangles its Cull keeps (``selected`` when known)."""
    p = call.state
    zbound = None
    if not p.zwrite and p.ztest in (CompareFunction.Less, CompareFunction.LEqual):
        zbound = raster.depth_upper_codes(setup, p.offset_factor, p.offset_units)
    state = DrawState(call, call.renderer.material, texels, frame.lights, frame.color_space, frame.hdr,
                      frame.width, observed=frame.observed, zbound=zbound)
    return state, vertex.cull_select(setup, p.cull) if selected is None else selected


def _prepare(frame: _FrameContext, call: DrawCall, geometry: _Geometry, texels, pool, parts: int) -> _Prepared:
    """Cull, coverage and derived state of one draw call. Passes of a renderer with one Cull
    cover the same pixels: their rows are computed once (``geometry.rows``; in a memo across
    frames when the frame is whole)."""
    setup, cull = geometry.setup, call.state.cull
    known = geometry.rows.get(cull)
    state, selected = _draw_state(frame, call, setup, texels, selected=None if known is None else known[0])
    if known is not None:
        return _Prepared(call, setup, selected, raster.Rows(**vars(known[1])), state)
    rows = raster.coverage_rows(setup, selected, frame.width, frame.height, pool=pool, parts=parts, band=frame.band)
    geometry.rows[cull] = (selected, rows)
    return _Prepared(call, setup, selected, rows, state)


def _prepare_together(frame: _FrameContext, runs: list[list[DrawCall]], texels) -> list[_Prepared]:
    """Prepare many small renderers' draw calls with one vertex setup and one coverage pass for
    all of them (per-call array work on a few hundred triangles is mostly fixed cost)."""
    geometries = _setups(frame, [run[0].renderer for run in runs])
    items = []  # (call, geometry, state, selected, kept rows or None)
    for run, geometry, run_texels in zip(runs, geometries, texels, strict=True):
        frame.record(*_setup_notes(run[0].renderer, geometry.setup))
        for call, tex in zip(run, run_texels, strict=True):
            known = geometry.rows.get(call.state.cull)
            state, selected = _draw_state(frame, call, geometry.setup, tex,
                                          selected=None if known is None else known[0])
            items.append((call, geometry, state, selected, None if known is None else known[1]))
    todo = [k for k, item in enumerate(items) if item[4] is None]
    made = raster.coverage_rows_many([(items[k][1].setup, items[k][3]) for k in todo], frame.width,
                                     frame.height, frame.band) if todo else []
    rows = [item[4] for item in items]
    for k, r in zip(todo, made, strict=True):
        rows[k] = r
        call, geometry, _, selected, _ = items[k]
        geometry.rows.setdefault(call.state.cull, (selected, r))
    return [_Prepared(call, geometry.setup, selected, r if kept is None else raster.Rows(**vars(r)), state)
            for (call, geometry, state, selected, kept), r in zip(items, rows, strict=True)]


#: Consecutive draw calls of one constant colour each are fused (drawn as one) in groups of at
#: most this many triangles: a few hundred triangles cost about 1 ms a call in fixed array-call
#: overhead; big meshes gain nothing and would be copied.
FUSE_TRIANGLES = 1 << 15
#: Draw calls with shared shading are fused in groups of at most this many fragments (about a
#: chunk): beyond that the fixed cost saved is small beside the work, and a chunk holding rows of
#: several large calls loses their proof of distinct pixels (S2's planes ran 3x slower fused).
FUSE_FRAGMENTS = 1 << 17


def _constant_color(prepared: _Prepared, memo: SceneMemo | None = None) -> np.ndarray | None:
    """(4,) float64: the colour the shader gives every fragment of the call, when that does not
    depend on the fragment (Unlit, no texture, no alpha test); else None. Kept in ``memo`` per
    material and colour space (Unlit reads no light)."""
    state = prepared.state
    material = state.material
    if prepared.shade is not _shade_chunk:  # already specialised (a colourless pass)
        return None
    if material.lighting is not Lighting.Unlit or state.texels is not None or state.pass_state.alpha_test:
        return None

    def compute() -> np.ndarray:  # what _shade_chunk's flat path computes for each of the call's triangles
        return shade.shade(material, None, state.lights, state.color_space, np.zeros((1, 2), dtype=np.float64),
                           np.zeros((1, 3), dtype=np.float64))[0]

    return compute() if memo is None else memo.lookup(("constant colour", state.color_space), material, compute)


def _fuse_constant_calls(prepared: list[_Prepared], memo: SceneMemo | None = None) -> list[_Prepared]:
    """Consecutive draw calls with one pass state whose fragments each take their call's
    constant colour (:func:`_constant_color`: text labels, unlit props) drawn as one call.

    Their setups and rows are concatenated in draw order and each fragment gets its call's
    colour from a palette, so the merger applies exactly the fragments the calls would apply
    one after another, in the same order (a pixel's fragments of several calls are layers of
    one chunk, as overlapping triangles of one call are). Saves the per-call fixed cost.
    ``memo``: where the calls' colours are kept across renders.
    """
    out: list[_Prepared] = []
    group: list[tuple[_Prepared, np.ndarray]] = []
    triangles = 0

    def flush() -> None:
        if len(group) > 1:
            out.append(_fused(group))
        else:
            out.extend(pr for pr, _ in group)
        group.clear()

    for pr in prepared:
        color = _constant_color(pr, memo) if pr.setup.count <= FUSE_TRIANGLES else None
        if color is None:
            flush()
            out.append(pr)
            triangles = 0
            continue
        if group and (pr.state.pass_state != group[0][0].state.pass_state
                      or triangles + pr.setup.count > FUSE_TRIANGLES):
            flush()
            triangles = 0
        group.append((pr, color))
        triangles += pr.setup.count
    flush()
    return out


def _concatenated(group: list[_Prepared]) -> tuple[object, raster.Rows, np.ndarray, np.ndarray]:
    """The setups, rows and Cull-kept triangles of ``group``'s calls in order, as one call's:
    (setup, rows, selected, each call's first triangle (G,) int64 in the setup)."""
    setup = vertex.concatenate_setups([pr.setup for pr in group])
    counts = np.array([pr.setup.count for pr in group], dtype=np.int64)
    offsets = np.cumsum(counts) - counts
    rows = raster.Rows(**{name: np.concatenate([getattr(pr.rows, name) + offset if name == "tri"
                                                else getattr(pr.rows, name)
                                                for pr, offset in zip(group, offsets, strict=True)])
                          for name in raster.Rows.__dataclass_fields__})
    selected = np.concatenate([pr.selected + o for pr, o in zip(group, offsets, strict=True)])
    return setup, rows, selected, offsets


def _fused(group: list[tuple[_Prepared, np.ndarray]]) -> _Prepared:
    """One :class:`_Prepared` drawing ``group``'s calls (prepared call, its colour) in order."""
    setup, rows, selected, _ = _concatenated([pr for pr, _ in group])
    counts = np.array([pr.setup.count for pr, _ in group], dtype=np.int64)
    # Palette entries by bytes (as _shade_chunk's flat path keeps -0.0 and NaN colours apart).
    entries: dict[bytes, int] = {}
    for _, color in group:
        entries.setdefault(color.tobytes(), len(entries))
    palette = np.array([np.frombuffer(b, dtype=np.float64) for b in entries], dtype=np.float64)
    color_id = np.repeat(np.array([entries[c.tobytes()] for _, c in group], dtype=np.int32), counts)
    first = group[0][0]
    zbounds = [pr.state.zbound for pr, _ in group]
    zbound = None if any(z is None for z in zbounds) else np.concatenate(zbounds)
    state = replace(first.state, zbound=zbound)

    def shade_chunk(setup, rows, start: int, stop: int, state: DrawState) -> ShadedFragments | None:
        return _shade_constant_chunk(setup, rows, start, stop, state, color_id, palette)

    return _Prepared(first.call, setup, selected, rows, state, shade=shade_chunk)


def _shading_key(prepared: _Prepared, memo: SceneMemo | None = None) -> tuple | None:
    """Calls with equal keys shade every fragment alike and interpolate depth alike: the same
    texels and :func:`shade.shading_key`, the same Offset, setups with the same corner arrays.
    None: the call is not fused (specialised shading, or a big mesh that would be copied).
    ``memo``: where materials' keys are kept across renders."""
    if prepared.shade is not _shade_chunk or prepared.setup.count > FUSE_TRIANGLES:
        return None
    state, setup = prepared.state, prepared.setup
    p = state.pass_state
    material = state.material
    key = shade.shading_key(material) if memo is None else memo.lookup("shading key", material,
                                                                         lambda: shade.shading_key(material))
    return (id(state.texels), key, float(p.offset_factor), float(p.offset_units),
            setup.object_normals is None, setup.object_uvs is None)


def _fuse_shared_shading(prepared: list[_Prepared], memo: SceneMemo | None = None) -> list[_Prepared]:
    """Consecutive draw calls with one :func:`_shading_key` (the same material but for its
    pass and cutoff: blend-mode swatches, alpha-test cutoffs, a small mesh's passes) drawn
    as one: raster, interpolation and shading of their concatenated triangles once per chunk,
    then each call's fragments (a contiguous run of the chunk; calls in draw order) pass its
    own alpha test and merge with its own pass (:func:`_draw_shared_band`). Saves the per-call
    fixed cost of those stages (about 1 ms a call on the 2-core machine). ``memo``: as
    :func:`_shading_key`'s."""
    out: list[_Prepared] = []
    group: list[_Prepared] = []
    key = None
    triangles = fragments = 0

    def flush() -> None:
        out.append(_shared(group) if len(group) > 1 else group[0])
        group.clear()

    for pr in prepared:
        count = int(pr.rows.length.sum())
        k = _shading_key(pr, memo) if count <= FUSE_FRAGMENTS else None
        if group and (k is None or k != key or triangles + pr.setup.count > FUSE_TRIANGLES
                      or fragments + count > FUSE_FRAGMENTS):
            flush()
        if k is None:
            out.append(pr)
            continue
        if not group:
            key, triangles, fragments = k, 0, 0
        group.append(pr)
        triangles += pr.setup.count
        fragments += count
    if group:
        flush()
    return out


def _shared(group: list[_Prepared]) -> _Prepared:
    """One :class:`_Prepared` shading ``group``'s calls together; ``members`` draws each."""
    setup, rows, selected, firsts = _concatenated(group)
    passes = [pr.state.pass_state for pr in group]
    depth = any(p.zwrite or p.ztest is not CompareFunction.Always for p in passes)
    # The pass _shade_chunk sees: depth when any call reads or writes it, no alpha test (each
    # call tests its own cutoff), the first call's blend state for the palette decision (calls
    # whose pass cannot use tables resolve it). When every call has a depth bound (no ZWrite,
    # ZTest Less or LEqual), rows proven to pass under the stricter of their tests need none.
    zbound, ztest = None, CompareFunction.LEqual if depth else CompareFunction.Always
    if all(pr.state.zbound is not None for pr in group):
        zbound = np.concatenate([pr.state.zbound for pr in group])
        ztest = CompareFunction.Less if any(p.ztest is CompareFunction.Less for p in passes) else ztest
    shading_pass = replace(passes[0], alpha_test=False, zwrite=any(p.zwrite for p in passes), ztest=ztest)
    first = group[0]
    state = replace(first.state, call=replace(first.call, state=shading_pass), zbound=zbound)
    members = [_Member(pr.state, pr.tables, int(f)) for pr, f in zip(group, firsts, strict=True)]
    return _Prepared(first.call, setup, selected, rows, state, members=members)


def _skip_unused_shading(prepared: list[_Prepared]) -> list[_Prepared]:
    """Draw calls whose pass writes no colour and has no alpha test (a depth prepass,
    ``ColorMask 0``) get fragments without colours: only depth and stencil reach the buffers."""
    for pr in prepared:
        p = pr.state.pass_state
        if not p.color_mask and not p.alpha_test:
            pr.shade = _shade_colourless_chunk
    return prepared


def _shade_colourless_chunk(setup, rows, start: int, stop: int, state: DrawState) -> ShadedFragments | None:
    """:func:`_shade_chunk` of a pass that writes no colour and has no alpha test: pixels and
    depth only (the merger reads no colour of such a pass). Observed, the colours, deferred
    depths and source triangles an observer reads come from :func:`_shade_chunk` of the chunk,
    run only when read (a pixel history reads the chunks on its pixel; a draw list none)."""
    light = _shade_constant_chunk(setup, rows, start, stop, state, None, None)
    if light is None or not state.observed:
        return light
    full: list[ShadedFragments] = []

    def part(index: np.ndarray | None) -> ShadedFragments:
        if not full:
            full.append(_shade_chunk(setup, rows, start, stop, state))
        return full[0] if index is None else full[0].select(index)

    light.colors_fn = lambda index: part(index).colors()
    light.triangle_fn = lambda index: part(index).triangle
    if light.stored_depth is None:
        light.depth_fn = lambda index: part(index).depth
    return light


def _shade_constant_chunk(setup, rows, start: int, stop: int, state: DrawState, color_id: np.ndarray | None,
                          palette: np.ndarray | None) -> ShadedFragments | None:
    """:func:`_shade_chunk` of rows whose every fragment takes a constant colour:
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
    ids = raster.run_expander(length, n)(np.take(color_id, rows.tri[start:stop]))
    rgba, chunk_palette = None, palette
    if not merger.table_pays(p, state.hdr, state.color_space is ColorSpace.Linear, palette, n):
        rgba, ids, chunk_palette = np.take(palette, ids, axis=0), None, None  # blended one by one
    return ShadedFragments(frags.pix, depth, rgba, ids, chunk_palette, None, None, disjoint)


def _renderer_runs(calls: list[DrawCall]) -> list[list[DrawCall]]:
    """Consecutive draw calls of one renderer (its passes), which share one vertex setup."""
    runs: list[list[DrawCall]] = []
    for call in calls:
        if runs and runs[-1][-1].renderer is call.renderer:
            runs[-1].append(call)
        else:
            runs.append([call])
    return runs


#: Without an observer, consecutive draw calls are prepared (vertex setup and coverage, one
#: renderer per task) as a batch of up to this many source triangles and draw calls; then each
#: worker draws its screen band of the whole batch in draw order, with no wait between calls.
BATCH_TRIANGLES = 1 << 18
BATCH_DRAWS = 64
#: Below this many triangles a batch's renderers are prepared in the calling thread: their
#: many small array operations hold the GIL, so a second thread only adds contention.
PARALLEL_PREPARE_TRIANGLES = 1 << 15


def _batches(calls: list[DrawCall]) -> list[list[list[DrawCall]]]:
    """Renderer runs grouped into batches (a run is never split; at least one run a batch)."""
    batches: list[list[list[DrawCall]]] = []
    triangles = draws = 0
    for run in _renderer_runs(calls):
        count = int(run[0].renderer.mesh.triangle_count)
        if batches and triangles + count <= BATCH_TRIANGLES and draws + len(run) <= BATCH_DRAWS:
            batches[-1].append(run)
            triangles += count
            draws += len(run)
        else:
            batches.append([run])
            triangles, draws = count, len(run)
    return batches


def _prepare_batch(frame: _FrameContext, runs: list[list[DrawCall]]) -> list[_Prepared]:
    """Prepare a batch's draw calls in draw order: renderers in parallel on the pool, or one
    renderer with its per-vertex and per-triangle work split over the pool."""
    runs = [run for run in runs if run[0].renderer.mesh.triangle_count > 0]
    texels = [[frame.texels_of(call.renderer.material) for call in run] for run in runs]

    def prepare_run(k: int, pool, parts: int):
        geometry, notes, degenerate = _setup(frame, runs[k][0].renderer, pool, parts)
        return notes, degenerate, [_prepare(frame, call, geometry, tex, pool, parts)
                                   for call, tex in zip(runs[k], texels[k], strict=True)]

    triangles = sum(int(run[0].renderer.mesh.triangle_count) for run in runs)
    if len(runs) > 1 and triangles < PARALLEL_PREPARE_TRIANGLES:
        return _prepare_together(frame, runs, texels)
    if frame.pool is None or len(runs) <= 1:
        results = [prepare_run(k, frame.pool, frame.workers) for k in range(len(runs))]
    else:
        results = list(frame.pool.map(lambda k: prepare_run(k, None, 1), range(len(runs))))
    prepared: list[_Prepared] = []
    for notes, degenerate, items in results:
        frame.record(notes, degenerate)
        prepared.extend(items)
    return prepared


#: Frames of at least this many pixels draw every batch in screen bands, one per worker. In
#: smaller frames (a 960x540 viewport) bands pay only for fragments shaded one by one: the
#: cheap per-fragment work of palettes, constant colours and blend tables is mostly array calls
#: holding the GIL, which two threads contend for (960x540 example scenes: 6 of 9 ran 8-23 %
#: faster in one thread, the smooth-lit one 25-30 % faster in two; at 1280x720, two won on 6 of 9).
BAND_PIXELS = 600_000
#: ... unless the batch holds at least this many candidate fragments of per-fragment shading.
BAND_SHADED_FRAGMENTS = 1 << 17


def _bands_pay(frame: _FrameContext, prepared: list[_Prepared]) -> bool:
    """Whether a batch is drawn in screen bands on the pool (see :data:`BAND_PIXELS`)."""
    if frame.width * frame.height >= BAND_PIXELS:
        return True
    shaded = sum(int(pr.rows.length.sum()) for pr in prepared if _shaded_per_fragment(pr))
    return shaded >= BAND_SHADED_FRAGMENTS


def _shaded_per_fragment(prepared: _Prepared) -> bool:
    """Whether the call's fragments are shaded one by one (:func:`_shade_chunk`'s varying
    inputs: smooth normals under Lambert, or a filtered texture); not its flat triangles,
    texel palettes, constant colours or colourless passes."""
    if prepared.shade is not _shade_chunk:
        return False
    material = prepared.state.material
    if material.main_tex is not None and material.main_tex_filter is not TextureFilter.Point:
        return True
    if material.lighting is Lighting.Unlit:
        return False
    calls = [prepared.call] if prepared.members is None else [m.state.call for m in prepared.members]
    for call in calls:
        normals = np.asarray(call.renderer.mesh.normals)
        if normals.shape[0] > FUSE_TRIANGLES:
            return True  # a large lit mesh is taken as smooth rather than examined every frame
        if not raster.flat_corners(normals).all():
            return True
    return False


def _band_floor(buf: FrameBuffers, y0: int, y1: int) -> np.ndarray:
    """(H,) int64: the smallest stored depth code of each buffer row in ``[y0, y1)`` (others 0)."""
    floor = np.zeros(buf.height, dtype=np.int64)
    floor[y0:y1] = buf.depth.reshape(buf.height, buf.width)[y0:y1].min(axis=1)
    return floor


def _draw_batch_band(frame: _FrameContext, items, y0: int, y1: int, between: Callable[[], None],
                     observer: FrameObserver | None = None) -> None:
    """Draw one screen band ``[y0, y1)`` of a batch: ``items`` (prepared call, its rows in the
    band) in draw order; ``between()`` runs before each call (a cancellation check)."""
    zfloor = None  # the band's smallest stored depth per row, valid until a pass writes depth
    for prepared, rows in items:
        between()
        if frame.stop_flag.is_set():
            return
        state = prepared.state
        if state.zbound is not None and rows.count:
            if zfloor is None:
                zfloor = _band_floor(frame.buf, y0, y1)
            state = replace(state, zfloor=zfloor)
        if rows.count and prepared.members is not None:
            _draw_shared_band(frame.buf, prepared, rows, frame.chunk_candidates, state, frame.stop_flag)
        elif rows.count:
            _draw_band(frame.buf, prepared.setup, rows, frame.chunk_candidates, state, frame.stop_flag, observer,
                       prepared.tables, prepared.shade)
        if state.pass_state.zwrite:
            zfloor = None


def _render_batched(frame: _FrameContext, todo, cancelled, should_cancel, progress,
                    observer: FrameObserver | None = None) -> None:
    """Draw calls batch by batch; within a batch the workers' screen bands (cut at equal
    fragment counts of the whole batch) proceed independently. An ``observer`` here does not
    need exact draw boundaries (:attr:`FrameObserver.exact_boundaries`)."""
    done = 0
    for runs in _batches(todo):
        cancelled()
        prepared = _prepare_batch(frame, runs)
        prepared = _skip_unused_shading(prepared)
        if observer is None:  # an observer is told of each call's own fragments
            prepared = _fuse_shared_shading(_fuse_constant_calls(prepared, frame.memo), frame.memo)
        calls = [call for run in runs for call in run]
        if observer is not None:
            for call in calls:
                observer.draw_begin(call, frame.buf)
        cuts = None
        if frame.pool is not None and _bands_pay(frame, prepared):
            cuts = raster.band_cuts([pr.rows for pr in prepared], frame.workers, frame.height)
        lo, hi = frame.band or (0, frame.height)  # the rows drawn (a band render's own)
        if cuts is None:
            _draw_batch_band(frame, [(pr, pr.rows) for pr in prepared], lo, hi, cancelled, observer)
        else:
            splits = [pr.rows.split_at(cuts) for pr in prepared]
            edges = [lo, *(int(c) for c in cuts), hi]
            futures = [frame.pool.submit(_draw_batch_band, frame, [(pr, split[k]) for pr, split in
                                                                   zip(prepared, splits, strict=True)],
                                         edges[k], min(max(edges[k + 1], edges[k]), frame.height), _no_check,
                                         observer)
                       for k in range(cuts.size + 1)]
            _wait(futures, should_cancel, frame.stop_flag)
        if frame.stop_flag.is_set():
            raise RenderCancelled("render cancelled")
        if observer is not None:
            reached = {pr.call.index: int(np.unique(pr.setup.src[pr.selected]).size) for pr in prepared}
            for call in calls:
                observer.draw_end(call, frame.buf, reached.get(call.index, 0))
        done += len(calls)
        if progress is not None:
            progress(done / max(len(todo), 1))


def _no_check() -> None:
    """Band workers poll the stop flag instead (set by the thread that polls ``should_cancel``)."""


def _render_observed(frame: _FrameContext, todo, cancelled, should_cancel, progress, observer) -> None:
    """Draw calls one at a time, each split into screen bands, with the observer told of every
    draw call (buffers before and after) and fragment."""
    buf, pool, workers = frame.buf, frame.pool, frame.workers
    geometry = setup_of = None
    zfloor_rows = None  # per buffer row, the smallest stored depth code (while no pass writes depth)
    for done, call in enumerate(todo, start=1):
        cancelled()
        renderer = call.renderer
        observer.draw_begin(call, buf)
        if renderer.mesh.triangle_count == 0:
            observer.draw_end(call, buf, 0)
            continue
        if setup_of is not renderer:  # one vertex setup per renderer, shared by its passes
            setup_of = renderer
            geometry, notes, degenerate = _setup(frame, renderer, pool, workers)
            frame.record(notes, degenerate)
        prepared = _prepare(frame, call, geometry, frame.texels_of(renderer.material), pool, workers)
        setup = prepared.setup
        state = prepared.state
        if state.zbound is not None:
            if zfloor_rows is None:  # recomputed only after a pass wrote depth
                zfloor_rows = _band_floor(buf, 0, buf.height)
            state = replace(state, zfloor=zfloor_rows)
        if call.state.zwrite:
            zfloor_rows = None
        rows = prepared.rows
        bands = rows.split_bands(workers, buf.height) if pool is not None else [rows]
        if len(bands) == 1:
            _draw_band(buf, setup, bands[0], frame.chunk_candidates, state, frame.stop_flag, observer)
        else:
            futures = [pool.submit(_draw_band, buf, setup, band, frame.chunk_candidates, state, frame.stop_flag,
                                   observer) for band in bands]
            _wait(futures, should_cancel, frame.stop_flag)
        if frame.stop_flag.is_set():
            raise RenderCancelled("render cancelled")
        observer.draw_end(call, buf, int(np.unique(setup.src[prepared.selected]).size))
        if progress is not None:
            progress(done / max(len(todo), 1))


def render_scene(
    scene: DrawScene,
    *,
    progress: Callable[[float], None] | None = None,
    should_cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    chunk_candidates: int = CHUNK_CANDIDATES,
    until_draw: int | None = None,
    resume: tuple[FrameBuffers, int] | None = None,
    observer: FrameObserver | None = None,
    band: tuple[int, int] | None = None,
    out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    memo: SceneMemo | None = None,
) -> Frame:
    """Render a draw scene exactly as Unity's built-in pipeline would (docs/pipeline.md).

    ``progress(fraction)`` is called as draw calls complete (after each batch of them, see
    ``BATCH_TRIANGLES``; after each call with an observer that needs exact draw boundaries);
    ``should_cancel()`` is polled
    between draw calls and chunks, and a True answer raises :class:`RenderCancelled`.
    ``until_draw`` K: stop after draw call K (numbered from 1; 0 = the cleared frame).
    ``resume`` (buffers, K0): start from a copy of ``buffers`` as left after draw call K0
    (a snapshot taken by an observer's :meth:`FrameObserver.draw_end`), drawing K0+1 on.
    ``observer``: a :class:`FrameObserver` that receives every draw call and fragment.
    ``band`` (y0, y1): draw only buffer rows ``y0 <= y < y1`` (counted from the bottom) and
    return just those rows (the Frame's arrays are ``y1 - y0`` rows high, top row first): every
    pixel there equals the full render's, since pixels never depend on one another (one
    process's share of a frame split across processes, :mod:`blendlib.core.bandprocs`).
    ``out``: (color, depth, stencil) arrays of the Frame's shapes and dtypes to write the
    result into (a band straight into its rows of a whole frame, or into shared memory).
    ``memo``: a :class:`~blendlib.core.scene.SceneMemo` shared by renders of scenes with the
    same renderers (the viewport's frames): renderers are checked and textures converted once.
    Raises :class:`blendlib.core.scene.SceneError` (one line) for input that cannot render.
    """
    keep_setups = memo is not None  # a memo of this render alone would only hold setups to its end
    memo = SceneMemo() if memo is None else memo
    warnings = list(scene.warnings) + validate_scene(scene, memo)
    if until_draw is not None and int(until_draw) < 0:
        raise SceneError(f"until_draw must be 0 or more (got {until_draw})")
    cam = scene.camera
    width, height = int(cam.width), int(cam.height)
    if band is not None:
        band = (int(band[0]), int(band[1]))
        if not 0 <= band[0] < band[1] <= height:
            raise SceneError(f"band {band} is not a range of rows within 0..{height}")
        if observer is not None or resume is not None:
            raise SceneError("a band render takes no observer and resumes nothing")
    cs = scene.color_space
    if resume is not None:
        buf, first = resume[0].copy(), int(resume[1])
    else:
        clear = shade.gamma_color_to_shading(scene.clear_color[:3], cs) + (float(scene.clear_color[3]),)
        buf, first = FrameBuffers(width, height, scene.hdr, cs, clear, band), 0
    lights = shade.frame_lights(scene)
    try:
        calls = draw_calls(scene)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    last = len(calls) if until_draw is None else min(int(until_draw), len(calls))
    todo = [c for c in calls if first < c.index <= last]
    if workers is None:
        workers = 1 if width * height < SMALL_FRAME_PIXELS else min(2, os.cpu_count() or 1)
    stop_flag = threading.Event()
    pool = ThreadPoolExecutor(max_workers=workers) if workers > 1 else None
    frame = _FrameContext(buf, cam, lights, cs, scene.hdr, chunk_candidates, pool, workers, stop_flag,
                          observed=observer is not None, band=band, memo=memo, keep_setups=keep_setups)

    def cancelled() -> None:
        if should_cancel is not None and should_cancel():
            raise RenderCancelled("render cancelled")

    try:
        if observer is None or not observer.exact_boundaries:
            _render_batched(frame, todo, cancelled, should_cancel, progress, observer)
        else:
            _render_observed(frame, todo, cancelled, should_cancel, progress, observer)
        color, depth, stencil = buf.output(pool, workers, band, out)
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    warnings.extend(frame.warnings)
    degenerate = frame.degenerate
    if degenerate:
        total = sum(n for _, n in degenerate)
        names = sorted({name for name, _ in degenerate})
        shown = ", ".join(repr(n) for n in names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
        warnings.append(f"{total} degenerate (zero-area) triangles draw nothing, in {shown}")
    textures = (c.renderer.material.main_tex for c in calls)
    missing = {t.name for t in textures if t is not None and t.missing}
    warnings.extend(f"image {name!r}: file missing, drawn magenta" for name in sorted(missing))
    encoded = not (scene.hdr and cs is ColorSpace.Linear)
    return Frame(color=color, depth=depth, stencil=stencil, warnings=warnings, encoded=encoded)
