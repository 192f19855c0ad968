"""Vertex and clip stage (docs/pipeline.md §1–§3), vectorised numpy.

- :func:`setup_triangles`: a renderer's mesh → :class:`TriangleSetup` (clip-space
  transform, near/far/guard-band clipping, snapping to 1/256 pixel, areas). Done
  once per renderer and shared by its passes.
- :func:`cull_select`: the triangles a pass with a given ``Cull`` draws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .gather import gather
from .outline import outline_clip_many
from .parts import PIECE, run_parts
from .scene import Camera, Mesh, matmul4_many, normal_matrices
from .vocabulary import Cull, Pass

SUBPIXEL = 256
HALF = SUBPIXEL // 2
GUARD_BAND = 4.0
DEPTH_MAX = 2**24 - 1
_MAX_POLY = 3 + 6  # a triangle clipped by six planes has at most nine vertices
#: Per-vertex code bits: 0-5 outside clip plane k (§2 order), 6 non-finite, 7 no window position.
_NONFINITE_BIT, _NO_WINDOW_BIT = 6, 7
_PLANES_MASK = np.uint8(0x3F)
_NONFINITE_MASK = np.uint8(1 << _NONFINITE_BIT)


def _affine_rows(m: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray, rows: int,
                 out: np.ndarray | None = None) -> np.ndarray:
    """``((m[i,0]*x + m[i,1]*y) + m[i,2]*z) + m[i,3]`` for i < rows (m[i,3] omitted when m has 3
    columns) as a (rows, n) float64 array, written into ``out`` when given; ``m`` (rows, 3|4) of
    scalars, or (rows, 3|4, n) of per-element entries. Each row is built in place, operation
    by operation in that order (the same roundings as the expression)."""
    if out is None:
        out = np.empty((rows, np.shape(x)[0]), dtype=np.float64)
    term = np.empty(out.shape[1], dtype=np.float64)
    for i in range(rows):
        row = out[i]
        np.multiply(m[i, 0], x, out=row)
        row += np.multiply(m[i, 1], y, out=term)
        row += np.multiply(m[i, 2], z, out=term)
        if m.shape[1] == 4:
            row += m[i, 3]
    return out


@dataclass(eq=False)
class TriangleSetup:
    """Screen-space triangles of one renderer, after clipping, in draw order.

    n triangles; all arrays indexed by triangle:
    - ``X``, ``Y`` (n, 3) int64: snapped window positions in 1/256 pixel, y up.
    - ``zw`` (n, 3) float64 window depth; ``iw`` (n, 3) float64 ``1/w``.
    - ``area2`` (n,) int64 twice the signed area (> 0: counter-clockwise).
    - ``src`` (n,) int64: index of the mesh triangle it came from.
    - ``weights`` (n, 3, 3) float64 or None: original-triangle weights of each
      vertex for clipped triangles (row k = vertex k); None when nothing was clipped.
    - ``clipped`` (n,) bool.
    - ``front`` (n,) bool: the triangle shows its front side (False for zero area, which
      no cull mode draws).
    - ``object_normals`` (T, 3, 3) corner normals and ``normal_matrix`` (3, 3) (§1), or
      None when shading does not read normals; ``object_uvs`` (T, 3, 2) or None. World
      normals and float64 UVs are made on demand for the triangles that produce fragments
      (:meth:`world_normals_of`, :meth:`uvs_of`).
    - ``object_colors`` (T, 3, 4) float64 vertex colours in shading space, or None when shading
      does not read them (:meth:`colors_of`).
    - ``placement``: the mesh's (positions (V, 3), triangles (T, 3), matrix_world (4, 4)), from
      which :meth:`world_positions_of` makes world positions on demand (an outline's corners
      light as the mesh's own: its program moves only the clip position); ``world_corners``
      (T, 3, 3) float64 precomputed world positions instead (concatenated setups), or None.
    """

    X: np.ndarray
    Y: np.ndarray
    zw: np.ndarray
    iw: np.ndarray
    area2: np.ndarray
    src: np.ndarray
    weights: np.ndarray | None
    clipped: np.ndarray
    front: np.ndarray
    object_normals: np.ndarray | None
    normal_matrix: np.ndarray | None
    object_uvs: np.ndarray | None
    skipped_nonfinite: int = 0
    degenerate: int = 0
    _slope: np.ndarray | None = None
    _world_normal_corners: np.ndarray | None = None  # (T, 3, 3) float64, kept by world_normals_of
    object_colors: np.ndarray | None = None
    placement: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    world_corners: np.ndarray | None = None

    def world_positions_of(self, src: np.ndarray) -> np.ndarray:
        """World-space corner positions (K, 3, 3) float64 of source triangles ``src`` (K,): §1's
        ``((M[i][0]*x + M[i][1]*y) + M[i][2]*z) + M[i][3]``."""
        if self.world_corners is not None:
            return self.world_corners.take(src, axis=0)
        positions, triangles, matrix = self.placement
        # np.take gathers whole rows: many times faster than fancy indexing of (K, 3[, C]) arrays.
        corner_vertices = np.asarray(triangles).take(src, axis=0).reshape(-1)
        corners = np.asarray(positions, dtype=np.float64).take(corner_vertices, axis=0)  # (3K, 3)
        cols = np.ascontiguousarray(corners.T)
        out = _affine_rows(np.asarray(matrix, dtype=np.float64)[:3], cols[0], cols[1], cols[2], 3)
        return out.T.reshape(-1, 3, 3)

    def colors_of(self, src: np.ndarray) -> np.ndarray:
        """Shading-space corner vertex colours (K, 3, 4) float64 of source triangles ``src`` (K,)."""
        return self.object_colors.take(src, axis=0)

    def world_normals_of(self, src: np.ndarray) -> np.ndarray:
        """World-space corner normals (K, 3, 3) float64 of source triangles ``src`` (K,). A small
        mesh's are made for all its triangles at the first call and kept with the setup (the
        same per-corner sums): its passes' chunks, and the viewport's later frames through a
        kept setup, gather them instead of transforming their triangles' again."""
        if self.normal_matrix is not None and self.object_normals.shape[0] > KEPT_WORLD_NORMALS:
            return _world_normals(self.object_normals.take(src, axis=0), self.normal_matrix)
        return self.all_world_normals().take(src, axis=0)

    def all_world_normals(self) -> np.ndarray:
        """World-space corner normals (T, 3, 3) float64 of every source triangle: kept with the
        setup for a mesh of at most :data:`KEPT_WORLD_NORMALS` triangles (made at the first call)."""
        if self.normal_matrix is None:
            return self.object_normals
        if self._world_normal_corners is not None:
            return self._world_normal_corners
        corners = _world_normals(self.object_normals, self.normal_matrix)
        if self.object_normals.shape[0] > KEPT_WORLD_NORMALS:
            return corners
        # Kept contiguous (np.take of a strided view copies it whole first); threads of one setup
        # may both make it: the same values.
        self._world_normal_corners = np.ascontiguousarray(corners)
        return self._world_normal_corners

    def uvs_of(self, src: np.ndarray) -> np.ndarray:
        """Corner UVs (K, 3, 2) float64 of source triangles ``src`` (K,)."""
        return self.object_uvs.take(src, axis=0).astype(np.float64, copy=False)

    @property
    def count(self) -> int:
        return int(self.src.shape[0])

    def slope(self) -> np.ndarray:
        """(n,) float64 ``max(|dz/dx|, |dz/dy|)`` in window units (polygon offset, §5)."""
        if self._slope is None:
            x = self.X.astype(np.float64) / SUBPIXEL
            y = self.Y.astype(np.float64) / SUBPIXEL
            z = self.zw
            a = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
            with np.errstate(divide="ignore", invalid="ignore"):
                dzdx = ((z[:, 1] - z[:, 0]) * (y[:, 2] - y[:, 0]) - (z[:, 2] - z[:, 0]) * (y[:, 1] - y[:, 0])) / a
                dzdy = ((z[:, 2] - z[:, 0]) * (x[:, 1] - x[:, 0]) - (z[:, 1] - z[:, 0]) * (x[:, 2] - x[:, 0])) / a
            self._slope = np.maximum(np.abs(dzdx), np.abs(dzdy))
        return self._slope


def _source_count(setup: TriangleSetup) -> int:
    """How many source triangles ``setup.src`` numbers: its corner arrays' length, else max + 1."""
    for corners in (setup.object_uvs, setup.object_normals, setup.object_colors, setup.world_corners):
        if corners is not None:
            return int(corners.shape[0])
    return int(setup.src.max()) + 1 if setup.count else 0


def concatenate_setups(setups: list[TriangleSetup], positions: bool = False) -> TriangleSetup:
    """The triangles of ``setups`` (all with normals or none, all with UVs or none, all with
    vertex colours or none) as one setup, in order: several draw calls drawn as one (pipeline's
    fused calls).

    Source triangles are renumbered past the setups before them, so ``src`` stays distinct
    between setups and indexes the concatenated corner arrays. World normals are computed here
    for every source triangle (each setup has its own normal matrix; the arithmetic per
    triangle is the same, so the values are equal bit for bit), and ``normal_matrix`` is None;
    so are world positions when ``positions`` (shading reads them: a point or spot light).
    """
    counts = [_source_count(s) for s in setups]
    offsets = np.cumsum([0, *counts[:-1]]).astype(np.int64)

    def cat(name: str) -> np.ndarray:
        return np.concatenate([getattr(s, name) for s in setups])

    weights = None
    if any(s.weights is not None for s in setups):
        # Only rows of clipped triangles are read (raster.interpolate): zeros elsewhere.
        weights = np.concatenate([np.zeros((s.count, 3, 3), dtype=np.float64) if s.weights is None
                                  else s.weights for s in setups])
    normals = uvs = None
    if setups[0].object_normals is not None:
        normals = np.concatenate([s.all_world_normals() for s in setups])
    if setups[0].object_uvs is not None:
        uvs = cat("object_uvs")
    colors = cat("object_colors") if setups[0].object_colors is not None else None
    world = None
    if positions:
        world = np.concatenate([s.world_positions_of(np.arange(n)) for s, n in zip(setups, counts, strict=True)])
    return TriangleSetup(X=cat("X"), Y=cat("Y"), zw=cat("zw"), iw=cat("iw"), area2=cat("area2"),
                         src=np.concatenate([s.src + o for s, o in zip(setups, offsets, strict=True)]),
                         weights=weights, clipped=cat("clipped"), front=cat("front"), object_normals=normals,
                         normal_matrix=None, object_uvs=uvs, object_colors=colors, world_corners=world)


def _plane_distance(v: np.ndarray, plane: int, guard: np.ndarray | None = None) -> np.ndarray:
    """Signed distance of clip-space vertices ``v[..., 0:4]`` to clip plane ``plane`` (§2 order);
    ``guard``: ``GUARD_BAND * w`` when the caller has it (the four guard-band planes share it)."""
    x, y, z, w = v[..., 0], v[..., 1], v[..., 2], v[..., 3]
    if plane == 0:
        return z + w
    if plane == 1:
        return w - z
    g = GUARD_BAND * w if guard is None else guard
    if plane == 2:
        return g - x
    if plane == 3:
        return g + x
    return g - y if plane == 4 else g + y


def _clip_polygons(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sutherland–Hodgman over the six planes for m triangles carrying 7 values per vertex.

    ``tri`` (m, 3, 7) float64 (x, y, z, w, B0, B1, B2) → polygons (m, 9, 7), counts (m,).
    """
    m = tri.shape[0]
    poly = np.zeros((m, _MAX_POLY, 7), dtype=np.float64)
    poly[:, :3] = tri
    count = np.full(m, 3, dtype=np.int64)
    slots = np.arange(_MAX_POLY)
    for plane in range(6):
        d = _plane_distance(poly, plane)  # (m, K)
        valid = slots[None, :] < count[:, None]
        nxt = np.where(slots[None, :] + 1 < count[:, None], slots[None, :] + 1, 0)
        b = np.take_along_axis(poly, nxt[:, :, None], axis=1)
        db = np.take_along_axis(d, nxt, axis=1)
        a_in = d >= 0
        b_in = db >= 0
        emit_a = valid & a_in
        emit_i = valid & (a_in != b_in)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            t = d / (d - db)  # only used where the edge crosses the plane; nan elsewhere is masked out
            inter = poly + t[:, :, None] * (b - poly)
        cand = np.empty((m, 2 * _MAX_POLY, 7), dtype=np.float64)
        cand[:, 0::2] = poly
        cand[:, 1::2] = inter
        flags = np.empty((m, 2 * _MAX_POLY), dtype=bool)
        flags[:, 0::2] = emit_a
        flags[:, 1::2] = emit_i
        pos = flags.cumsum(axis=1) - 1
        count = flags.sum(axis=1)
        if (count > _MAX_POLY).any():  # cannot happen for convex input; guard against float surprises
            raise AssertionError("clipped polygon exceeds nine vertices")
        out = np.zeros_like(poly)
        rows, cols = np.nonzero(flags)
        out[rows, pos[rows, cols]] = cand[rows, cols]
        poly = out
    return poly, count


def _to_window(clip: np.ndarray, camera: Camera) -> tuple[np.ndarray, ...]:
    """Clip coordinates (..., 4) → X, Y (int64 1/256 px), zw, iw (float64), finite mask."""
    x, y, z, w = clip[..., 0], clip[..., 1], clip[..., 2], clip[..., 3]
    # In place, operation by operation: xw = (x * iw * 0.5 + 0.5) * W, fx = floor(xw * S + 0.5), ...
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        iw = np.divide(1.0, w)

        def window(v: np.ndarray, size: int) -> np.ndarray:
            f = np.multiply(v, iw)
            f *= 0.5
            f += 0.5
            f *= size
            f *= SUBPIXEL
            f += 0.5
            return np.floor(f, out=f)

        fx = window(x, camera.width)
        fy = window(y, camera.height)
        zw = np.multiply(z, iw)
        zw *= 0.5
        zw += 0.5
    # Beyond 2**62 (far outside the guard band: such vertices are clipped) int64 cannot hold it.
    finite = np.abs(fx) < 2.0**62
    finite &= np.abs(fy) < 2.0**62
    finite &= np.isfinite(zw)
    finite &= np.isfinite(iw)
    if not finite.all():
        fx[~finite] = 0.0
        fy[~finite] = 0.0
    return fx.astype(np.int64), fy.astype(np.int64), zw, iw, finite


#: Meshes of up to this many triangles keep their world-space corner normals with their setup
#: (:meth:`TriangleSetup.world_normals_of`; 72 bytes a triangle).
KEPT_WORLD_NORMALS = 1 << 14


def _world_normals(normals: np.ndarray, nmat: np.ndarray) -> np.ndarray:
    """Corner normals (T, 3, 3) → world space with the explicit sums of §1, float64 (T, 3, 3)."""
    t = normals.shape[0]
    cols = np.ascontiguousarray(np.asarray(normals, dtype=np.float64).reshape(t * 3, 3).T)  # (3, 3T)
    out = _affine_rows(nmat, cols[0], cols[1], cols[2], 3)  # (3, 3T) components first: contiguous writes
    return out.T.reshape(t, 3, 3)  # a (T, 3, 3) view


@dataclass(frozen=True, eq=False)
class SetupInput:
    """One renderer for :func:`setup_renderers`: its mesh, object → world matrix (4, 4), whether
    shading reads normals (Lambert) and UVs (a texture), its vertex colours in shading space
    ((T, 3, 4) float64, or None when shading does not read them) and the pass whose outline
    vertex program moves its corners (:func:`.outline.outline_clip`; None: the vertices as they are)."""

    mesh: Mesh
    matrix_world: np.ndarray
    need_normals: bool = True
    need_uvs: bool = True
    colors: np.ndarray | None = None
    program: Pass | None = None
    #: The program's outline-width factor per corner ((3T,) float64, :func:`.outline.width_factors`;
    #: None: ×1).
    width_factors: np.ndarray | None = None


def setup_triangles(
    mesh: Mesh, matrix_world: np.ndarray, camera: Camera, need_normals: bool = True, need_uvs: bool = True,
    pool=None, parts: int = 1, colors: np.ndarray | None = None, program: Pass | None = None,
) -> TriangleSetup:
    """Vertex stage, clipping, viewport and snapping for one renderer (docs/pipeline.md §1–§4).

    ``need_normals`` / ``need_uvs``: whether shading reads them (Lambert; a texture).
    Attributes not needed are left out (``object_normals`` / ``object_uvs`` None).
    ``pool`` / ``parts``: a thread pool to split per-vertex and per-triangle work over.
    ``colors``, ``program``: as :class:`SetupInput`'s.
    """
    return setup_renderers([SetupInput(mesh, matrix_world, need_normals, need_uvs, colors, program)], camera,
                           pool, parts)[0]


def setup_renderers(items: list[SetupInput], camera: Camera, pool=None, parts: int = 1) -> list[TriangleSetup]:
    """:func:`setup_triangles` of several renderers at once, one :class:`TriangleSetup` each.

    Every step is per vertex or per triangle, so the renderers' vertices and triangles are
    concatenated and each step runs once for all of them (many small meshes cost one pass
    of array operations, not one per mesh); the results are then cut per renderer. Each
    renderer's setup equals its own :func:`setup_triangles` bit for bit.
    """
    worlds = np.array([np.asarray(item.matrix_world, dtype=np.float64) for item in items]).reshape(-1, 4, 4)
    mvps = matmul4_many(camera.projection, matmul4_many(camera.view_matrix, worlds))
    nmats, dets = normal_matrices(worlds)
    # A vertex program (an outline) moves each corner on its own: its renderer's vertices are its
    # corners (3t + k), their clip coordinates the program's (overwriting the plain transform).
    vertices = [np.asarray(item.mesh.positions) if item.program is None
                else np.asarray(item.mesh.positions)[np.asarray(item.mesh.triangles).reshape(-1)] for item in items]
    triangles = [np.asarray(item.mesh.triangles) if item.program is None
                 else np.arange(3 * item.mesh.triangle_count, dtype=np.int64).reshape(-1, 3) for item in items]
    v_counts = np.array([v.shape[0] for v in vertices], dtype=np.int64)
    t_counts = np.array([t.shape[0] for t in triangles], dtype=np.int64)
    v_offsets = np.concatenate([[0], v_counts.cumsum()])
    t_offsets = np.concatenate([[0], t_counts.cumsum()])
    v_count, t_count = int(v_offsets[-1]), int(t_offsets[-1])
    programmed = [k for k, item in enumerate(items) if item.program is not None]
    clips = outline_clip_many([(items[k].mesh, items[k].matrix_world, items[k].program, items[k].width_factors)
                               for k in programmed], camera)
    programs = [(int(v_offsets[k]), int(v_offsets[k + 1]), clip) for k, clip in zip(programmed, clips, strict=True)]

    # Per-vertex work first (V <= 3T), gathered per corner afterwards. Coordinates are kept
    # channels first ((3, V) positions, (4, V) clip coordinates): every column contiguous.
    # The positions are converted while copied, range by range in the vertex parts below (one
    # pass, no float64 temporary, on the pool's threads).
    pos_columns = np.empty((3, v_count), dtype=np.float64)
    # Vertex indices per triangle (T, 3): the mesh's own array (its integer dtype) for one
    # renderer, made int64 range by range where read (on the pool's threads: a million
    # triangles' conversion costs milliseconds); offset per renderer for several.
    if len(items) == 1:
        tris = np.asarray(triangles[0])
    else:
        tris = np.empty((t_count, 3), dtype=np.int64)
        for k, t in enumerate(triangles):
            np.add(t, v_offsets[k], out=tris[t_offsets[k]:t_offsets[k + 1]], dtype=np.int64)
    clip_v = np.empty((4, v_count), dtype=np.float64)
    finite_v = np.empty(v_count, dtype=bool)
    outcode_v = np.empty(v_count, dtype=np.uint8)
    Xv = np.empty(v_count, dtype=np.int64)
    Yv = np.empty(v_count, dtype=np.int64)
    zwv = np.empty(v_count, dtype=np.float64)
    iwv = np.empty(v_count, dtype=np.float64)
    okv = np.empty(v_count, dtype=bool)

    # Many renderers: each vertex's matrix entries (16, V), so that the affine rows are one set
    # of array operations for all of them (the same products and sums as _affine_rows).
    entries = None if len(items) == 1 else mvps.reshape(-1, 16).T.repeat(v_counts, axis=1).reshape(4, 4, -1)

    def vertex_part(lo: int, hi: int) -> None:
        for k in range(int(np.searchsorted(v_offsets, lo, side="right")) - 1, len(vertices)):
            a, b = max(lo, int(v_offsets[k])), min(hi, int(v_offsets[k + 1]))
            if a >= hi:
                break
            if a < b:
                pos_columns[:, a:b] = vertices[k][a - v_offsets[k]:b - v_offsets[k]].T
        p = pos_columns[:, lo:hi]
        m = mvps[0] if entries is None else entries[:, :, lo:hi]
        _affine_rows(m, p[0], p[1], p[2], 4, out=clip_v[:, lo:hi])
        for a, b, clip in programs:
            if a < hi and lo < b:
                clip_v[:, max(a, lo):min(b, hi)] = clip[:, max(a, lo) - a:min(b, hi) - a]
        cv = clip_v[:, lo:hi].T  # (n, 4) view with contiguous columns
        finite = np.isfinite(clip_v[0, lo:hi])
        for k in range(1, 4):
            finite &= np.isfinite(clip_v[k, lo:hi])
        finite_v[lo:hi] = finite
        code = np.zeros(hi - lo, dtype=np.uint8)
        guard = GUARD_BAND * clip_v[3, lo:hi]
        for k in range(6):
            code |= np.less(_plane_distance(cv, k, guard), 0).view(np.uint8) << np.uint8(k)
        Xv[lo:hi], Yv[lo:hi], zwv[lo:hi], iwv[lo:hi], okv[lo:hi] = _to_window(cv, camera)
        # Bits 6 and 7 carry "not finite" and "no window position", so one gather per corner
        # answers every per-triangle question below.
        code |= (~finite_v[lo:hi]).astype(np.uint8) << np.uint8(_NONFINITE_BIT)
        code |= (~okv[lo:hi]).astype(np.uint8) << np.uint8(_NO_WINDOW_BIT)
        outcode_v[lo:hi] = code

    run_parts(pool, parts, v_count, vertex_part, piece=PIECE)

    keep_whole = np.empty(t_count, dtype=bool)
    to_clip = np.empty(t_count, dtype=bool)
    finite = np.empty(t_count, dtype=bool)
    degenerate_t = np.empty(t_count, dtype=bool)

    def triangle_part(lo: int, hi: int) -> None:
        # Per corner, contiguous int64: gathers through a strided index array (a column of the
        # (T, 3) array) cost markedly more on large meshes.
        a, b, c = (tris[lo:hi, k].astype(np.int64) for k in range(3))
        ca, cb, cc = outcode_v.take(a), outcode_v.take(b), outcode_v.take(c)
        out_or = ca | cb | cc
        out_and = ca & cb & cc
        ok = (out_or & _NONFINITE_MASK) == 0
        planes_or = out_or & _PLANES_MASK
        finite[lo:hi] = ok
        keep_whole[lo:hi] = out_or == 0  # finite, inside every plane, with window positions
        to_clip[lo:hi] = ok & (planes_or != 0) & ((out_and & _PLANES_MASK) == 0)
        # Object-space degenerate triangles (zero area) are reported; they draw nothing. The
        # cross product of the edges e1 = b - a, e2 = c - a is zero when each component is: its
        # z component (from x and y) first, the other two only for the triangles where that one
        # is zero (few), so the corners' z are gathered for those alone.
        pa = [pos_columns[k].take(a) for k in range(2)]
        e1 = [pos_columns[k].take(b) - pa[k] for k in range(2)]
        e2 = [pos_columns[k].take(c) - pa[k] for k in range(2)]
        with np.errstate(over="ignore", invalid="ignore"):
            flat = (e1[0] * e2[1] - e1[1] * e2[0]) == 0
            flat &= ok
            degenerate = degenerate_t[lo:hi]
            degenerate[:] = False
            some = np.flatnonzero(flat)
            if some.size:
                f, g = [v.take(some) for v in e1], [v.take(some) for v in e2]
                z = pos_columns[2]
                za = z.take(a.take(some))
                f.append(z.take(b.take(some)) - za)
                g.append(z.take(c.take(some)) - za)
                degenerate[some] = ((f[1] * g[2] - f[2] * g[1]) == 0) & ((f[2] * g[0] - f[0] * g[2]) == 0)

    run_parts(pool, parts, t_count, triangle_part, piece=PIECE)

    # Unclipped triangles: window coordinates per vertex, gathered per corner.
    if keep_whole.all():
        whole, tw = np.arange(t_count, dtype=np.int64), tris
    else:
        whole = np.nonzero(keep_whole)[0]
        tw = tris[whole]
    X = np.empty(tw.shape, dtype=np.int64)
    Y = np.empty(tw.shape, dtype=np.int64)
    zw = np.empty(tw.shape, dtype=np.float64)
    iw = np.empty(tw.shape, dtype=np.float64)

    def gather_part(lo: int, hi: int) -> None:
        t = tw[lo:hi].astype(np.int64, copy=False)  # vertex indices, checked in range by the scene's validation
        gather(Xv, t, out=X[lo:hi])
        gather(Yv, t, out=Y[lo:hi])
        gather(zwv, t, out=zw[lo:hi])
        gather(iwv, t, out=iw[lo:hi])

    run_parts(pool, parts, tw.shape[0], gather_part, piece=PIECE)
    parts_list = [(whole, X, Y, zw, iw, None)]

    clip_idx = np.nonzero(to_clip)[0]
    if clip_idx.size:
        carried = np.zeros((clip_idx.size, 3, 7), dtype=np.float64)
        carried[:, :, :4] = clip_v.T[tris[clip_idx]]
        carried[:, :, 4:] = np.eye(3)[None]
        poly, count = _clip_polygons(carried)
        fan_src, fan_verts = [], []
        for j in range(1, _MAX_POLY - 1):  # fan triangles (v0, vj, vj+1), at most seven per polygon
            has = count >= j + 2
            if not has.any():
                break
            rows = np.nonzero(has)[0]
            fan_src.append(np.stack([rows, np.full(rows.size, j)], axis=1))
            fan_verts.append(np.stack([poly[rows, 0], poly[rows, j], poly[rows, j + 1]], axis=1))
        if fan_src:
            fs = np.concatenate(fan_src)
            fv = np.concatenate(fan_verts)
            order = np.lexsort((fs[:, 1], fs[:, 0]))  # by polygon, then fan position
            fs, fv = fs[order], fv[order]
            cX, cY, czw, ciw, cok = _to_window(fv[:, :, :4], camera)
            cgood = cok.all(axis=1)
            parts_list.append(
                (clip_idx[fs[cgood, 0]], cX[cgood], cY[cgood], czw[cgood], ciw[cgood], fv[cgood, :, 4:]))

    weights = None
    if len(parts_list) == 1:  # nothing clipped: already in draw order
        src = whole.astype(np.int64, copy=False)
        clipped = np.zeros(src.size, dtype=bool)
    else:
        src = np.concatenate([q[0] for q in parts_list]).astype(np.int64)
        order = np.argsort(src, kind="stable")
        src = src[order]
        X = np.concatenate([q[1] for q in parts_list])[order]
        Y = np.concatenate([q[2] for q in parts_list])[order]
        zw = np.concatenate([q[3] for q in parts_list])[order]
        iw = np.concatenate([q[4] for q in parts_list])[order]
        clipped = np.concatenate([np.zeros(whole.size, bool)] + [np.ones(q[0].size, bool) for q in parts_list[1:]])
        clipped = clipped[order]
        weights = np.concatenate(
            [np.broadcast_to(np.eye(3), (whole.size, 3, 3))] + [q[5] for q in parts_list[1:]])
        weights = np.ascontiguousarray(weights[order])

    # Setup triangles are in source order, so each renderer's are one contiguous range.
    cuts = np.searchsorted(src, t_offsets) if len(items) > 1 else np.array([0, src.size], dtype=np.int64)
    area2 = np.empty(src.size, dtype=np.int64)
    front = np.empty(src.size, dtype=bool)
    mirrored = [det < 0 for det in dets]

    def area_part(lo: int, hi: int) -> None:
        x, y = X[lo:hi], Y[lo:hi]
        a2 = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
        area2[lo:hi] = a2
        # Zero-area triangles stay in the arrays (no copies) but are neither front nor back;
        # a mirroring matrix (negative determinant) turns clockwise triangles to the front.
        np.greater(a2, 0, out=front[lo:hi])
        for k, flip in enumerate(mirrored):
            a, b = max(lo, int(cuts[k])), min(hi, int(cuts[k + 1]))
            if flip and a < b:
                np.less(area2[a:b], 0, out=front[a:b])

    run_parts(pool, parts, src.size, area_part, piece=PIECE)
    if len(items) == 1:
        skipped = [t_count - int(np.count_nonzero(finite))]
        degenerate = [int(np.count_nonzero(degenerate_t))]
    else:
        owner = np.arange(len(items)).repeat(t_counts)
        skipped = (t_counts - np.bincount(owner[finite], minlength=len(items))).tolist()
        degenerate = np.bincount(owner[degenerate_t], minlength=len(items)).tolist()
    setups = []
    for k, item in enumerate(items):
        a, b = int(cuts[k]), int(cuts[k + 1])
        mesh, n = item.mesh, int(t_counts[k])
        part_clipped = clipped[a:b]
        setups.append(TriangleSetup(
            X=X[a:b], Y=Y[a:b], zw=zw[a:b], iw=iw[a:b], area2=area2[a:b],
            src=src[a:b] - t_offsets[k] if k else src[a:b],
            weights=weights[a:b] if weights is not None and part_clipped.any() else None,
            clipped=part_clipped, front=front[a:b],
            object_normals=np.asarray(mesh.normals).reshape(n, 3, 3) if item.need_normals else None,
            normal_matrix=nmats[k],
            object_uvs=np.asarray(mesh.uvs).reshape(n, 3, 2) if item.need_uvs and mesh.uvs is not None else None,
            skipped_nonfinite=int(skipped[k]), degenerate=int(degenerate[k]), object_colors=item.colors,
            placement=(mesh.positions, mesh.triangles, worlds[k]),
        ))
    return setups


def cull_select(setup: TriangleSetup, cull: Cull) -> np.ndarray:
    """Indices (int64) of the setup's triangles that a pass with ``cull`` draws, in draw order."""
    if cull is Cull.Off:
        keep = setup.area2 != 0
    elif cull is Cull.Back:
        keep = setup.front
    else:
        keep = ~setup.front & (setup.area2 != 0)
    return np.nonzero(keep)[0].astype(np.int64)
