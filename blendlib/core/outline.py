"""The outline vertex program (docs/pipeline.md §1, "Outline vertex program"): MToon's outline pass
pushes each vertex out along its normal before projection (SPEC §11.6; UniVRM's
``MToonCore.cginc`` ``CalculateOutlineVertexClipPosition`` for VRM 0.x and
``vrmc_materials_mtoon_geometry_vertex.hlsl`` ``MToon_GetOutlineVertex`` for VRM 1.0).

:func:`outline_clip` gives the clip coordinates of every triangle corner of a mesh for a pass
with an :class:`~.vocabulary.OutlineMode`; the vertex stage (:func:`.vertex.setup_renderers`) then
clips, snaps and rasterises them like any vertex. The program runs per corner, since a vertex's
corners may carry different normals (hard edges split the outline, as a GPU's split vertices do).
Every value is float64, each sum and product in the order written below, so the scalar reference
gives the same bits.

MToon's outline-width texture (:func:`width_factors`) multiplies the width per corner: MToon 0.x
``tex2Dlod(_OutlineWidthTexture, float4(TRANSFORM_TEX(v.texcoord, _MainTex), 0, 0)).r``
(``MToonCore.cginc`` ``CalculateOutlineVertexClipPosition``), MToon 1.0
``_OutlineWidth * UNITY_SAMPLE_TEX2D_LOD(_OutlineWidthTex, uv, 0).x`` with ``uv =
TRANSFORM_TEX(v.texcoord0, _MainTex)`` (``vrmc_materials_mtoon_geometry_vertex.hlsl``
``MToon_GetOutlineVertex_OutlineWidth``): the red channel at level 0, at the corner's ``_MainTex``
coordinates (both ignore the texture's own offset and scale), in shading space (a 0.x texture is
imported sRGB, decoded in Linear; 1.0's is linear data). With a factor ``f`` per corner, ``width``
below reads ``width * f`` where it is first multiplied: 0.x World ``(0.01 * width) * f``, 1.0 World
``width * f``, 0.x Screen ``k = (0.01 * width) * f``, 1.0 Screen ``(2 * width) * f``.

With ``n`` the corner's object normal normalised (``n / sqrt((x*x + y*y) + z*z)``, 0 for a zero
normal), ``N``/``det`` the sign-corrected cofactors of the object matrix (§1: ``N·n`` is ``|det|``
times ``M⁻ᵀ n``), ``MVP``/``VP`` the products of §1 and ``w`` the clip w of the corner's own position:

- MToon 0.x, World: in object space, ``p' = p + ((0.01 * width) * (len(N·n) / |det|)) * n``,
  ``clip = MVP · p'`` (``0.01 * _OutlineWidth * worldNormalLength * v.normal``).
- MToon 1.0, World: in world space, ``p' = M·p + (N·n / len(N·n)) * width``, ``clip = VP · p'``.
- Screen (both): ``clip = MVP · p``; the view normal ``v = Nv·n`` (``Nv`` the sign-corrected
  cofactors of ``MV``: the direction of ``IT_MV · n``); its clip xy
  ``c = ((P[i][0]*vx + P[i][1]*vy) + P[i][2]*vz)`` for i = 0, 1; ``d = c / sqrt(cx*cx + cy*cy)``
  (no offset when that length is 0); MToon 0.x: ``d *= min(w, _OutlineScaledMaxDistance)``,
  ``d.x *= aspect``, ``clip.xy += ((0.01 * width) * d) * saturate(1 - |vz / len(v)|)``;
  MToon 1.0: ``d *= (2 * width) * min(w, P[1][1])``, ``d.x *= aspect``,
  ``clip.xy += d * saturate(1 - (vz/len(v))²)``. ``aspect = |P[0][0] / P[1][1]|`` (MToon's
  ``nearUpperRight`` ratio ``tan(fovY/2) / tan(fovX/2)``, for a projection without lens shift).
"""

from __future__ import annotations

import numpy as np

from . import shade
from .scene import Camera, Mesh, matmul4_many, normal_matrices
from .vocabulary import ColorSpace, Material, OutlineFormula, OutlineMode, Pass, TextureFilter


def outline_key(p: Pass) -> tuple | None:
    """The pass's vertex program as a hashable key (None: the vertices as they are). Passes with
    equal keys share one vertex setup."""
    if p.outline_mode is OutlineMode.Off:
        return None
    return (p.outline_mode, p.outline_formula, float(p.outline_width), float(p.outline_max_distance))


def _rows(m: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray, affine: bool) -> list[np.ndarray]:
    """``((m[i,0]*x + m[i,1]*y) + m[i,2]*z) (+ m[i,3])`` for each row i of ``m``."""
    out = []
    for row in m:
        v = np.multiply(row[0], x)
        v += np.multiply(row[1], y)
        v += np.multiply(row[2], z)
        if affine:
            v += row[3]
        out.append(v)
    return out


def _length(x: np.ndarray, y: np.ndarray, z: np.ndarray | None = None) -> np.ndarray:
    s = np.multiply(x, x)
    s += np.multiply(y, y)
    if z is not None:
        s += np.multiply(z, z)
    return np.sqrt(s)


def _normalised(*v: np.ndarray) -> list[np.ndarray]:
    """``v / len(v)`` componentwise, 0 where the length is 0 (2 or 3 components)."""
    length = _length(*v)
    zero = length == 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        out = [np.divide(c, length) for c in v]
    if zero.any():
        for c in out:
            c[zero] = 0.0
    return out


def width_factors(mesh: Mesh, material: Material, color_space: ColorSpace,
                  texels: shade.Texels | None = None) -> np.ndarray | None:
    """(3T,) float64: the outline-width texture's red channel at every corner of ``mesh`` (corner k
    of triangle t at 3t + k; module docstring), sampled Point or Bilinear at level 0 (Trilinear's
    level 0 is Bilinear) with the texture's wrap; a mesh without UVs samples at (0, 0) after the
    offset. ``texels``: the texture already in ``color_space`` (None: converted here). None when
    ``material`` has no outline-width texture (×1)."""
    texture = material.outline_width_tex
    if texture is None:
        return None
    if texels is None:
        texels = shade.texture_texels(texture, color_space)
    t = mesh.triangle_count
    uv = np.zeros((3 * t, 2), dtype=np.float64) if mesh.uvs is None else \
        np.asarray(mesh.uvs, dtype=np.float64).reshape(-1, 2)
    point = material.outline_width_tex_filter is TextureFilter.Point
    sampled = shade.sample(texels, shade.texture_uv(material, uv),
                           TextureFilter.Point if point else TextureFilter.Bilinear, material.outline_width_tex_wrap)
    return np.ascontiguousarray(sampled[:, 0])


def _times(width: float, factors: np.ndarray | None) -> float | np.ndarray:
    """``width`` (a float), or ``width * factors`` per corner."""
    return width if factors is None else np.multiply(width, factors)


def outline_clip(mesh: Mesh, matrix_world: np.ndarray, camera: Camera, p: Pass,
                 factors: np.ndarray | None = None) -> np.ndarray:
    """Clip coordinates (4, 3T) float64 of every corner of ``mesh``'s T triangles (corner k of
    triangle t at column 3t + k) under pass ``p``'s outline program (module docstring); ``factors``
    (3T,) float64 the outline-width texture's per corner (:func:`width_factors`; None: x1)."""
    return outline_clip_many([(mesh, matrix_world, p, factors)], camera)[0]


def outline_clip_many(items: list[tuple[Mesh, np.ndarray, Pass, np.ndarray | None]],
                      camera: Camera) -> list[np.ndarray]:
    """:func:`outline_clip` of several (mesh, matrix_world, pass, factors) at once, one (4, 3T)
    array each, equal to its own call bit for bit.

    The program runs per corner, so the corners of every item of one mode and formula are
    concatenated and each step runs once for all of them (an avatar's outlined meshes cost one
    set of array operations, not one each). What differs per item (its matrices, width, maximum
    distance) becomes a per-corner array of that item's value: each element then meets the same
    IEEE operations, in the same order, as in the item's own call."""
    out: list[np.ndarray | None] = [None] * len(items)
    groups: dict[tuple, list[int]] = {}
    for k, (_mesh, _m, p, _f) in enumerate(items):
        groups.setdefault((p.outline_mode, p.outline_formula), []).append(k)
    view = np.asarray(camera.view_matrix, dtype=np.float64)
    proj = np.asarray(camera.projection, dtype=np.float64)
    for (mode, formula), members in groups.items():
        clip = _clip_group([items[k] for k in members], view, proj, mode, formula)
        at = 0
        for k in members:
            n = 3 * items[k][0].triangle_count
            out[k] = clip[:, at:at + n]
            at += n
    return out


def _per_corner(values: list, owner: np.ndarray | None) -> np.ndarray:
    """Per-item values (floats, or arrays of shape S) → each item's at every one of its corners
    (``owner`` (C,) int64: each corner's item): (C,) or (*S, C) float64, each row contiguous (one
    item, ``owner`` None: the value itself, broadcast as a scalar would be)."""
    if owner is None:
        return np.asarray(values[0], dtype=np.float64)
    stacked = np.asarray(values, dtype=np.float64)  # (I, *S)
    shape = stacked.shape[1:]
    return np.take(stacked.reshape(len(values), -1).T, owner, axis=1).reshape(*shape, owner.size)


def _widths(base: list[float], factors: list[np.ndarray | None], owner: np.ndarray | None) -> float | np.ndarray:
    """``_times(base[i], factors[i])`` of every item, per corner (one item: as it gives it)."""
    if owner is None:
        return _times(base[0], factors[0])
    if all(f is None for f in factors):
        return _per_corner(base, owner)
    counts = np.bincount(owner, minlength=len(base))
    return np.concatenate([np.full(int(n), b) if f is None else _times(b, f)
                           for b, f, n in zip(base, factors, counts, strict=True)])


def _clip_group(items: list[tuple[Mesh, np.ndarray, Pass, np.ndarray | None]], view: np.ndarray,
                proj: np.ndarray, mode: OutlineMode, formula: OutlineFormula) -> np.ndarray:
    """Clip coordinates (4, C) float64 of the corners of ``items`` (one mode and formula), items
    one after another (module docstring)."""
    counts = np.array([3 * mesh.triangle_count for mesh, _m, _p, _f in items], dtype=np.int64)
    owner = None if len(items) == 1 else np.arange(len(items), dtype=np.int64).repeat(counts)
    pos = np.concatenate([np.asarray(mesh.positions, dtype=np.float64)[np.asarray(mesh.triangles, dtype=np.int64)
                                                                         .reshape(-1)] for mesh, _m, _p, _f in items])
    px, py, pz = (np.ascontiguousarray(pos[:, k]) for k in range(3))
    normal = np.concatenate([np.asarray(mesh.normals, dtype=np.float64).reshape(-1, 3) for mesh, _m, _p, _f in items])
    nx, ny, nz = _normalised(*(np.ascontiguousarray(normal[:, k]) for k in range(3)))
    ms = np.array([np.asarray(m, dtype=np.float64) for _mesh, m, _p, _f in items]).reshape(-1, 4, 4)
    widths = [float(p.outline_width) for _mesh, _m, p, _f in items]
    factors = [f for _mesh, _m, _p, f in items]
    mvs = matmul4_many(view, ms)
    mvp = _per_corner(list(matmul4_many(proj, mvs)), owner)
    old = formula is OutlineFormula.MToon0x
    if mode is OutlineMode.World:
        nmats, dets = normal_matrices(ms)
        wx, wy, wz = _rows(_per_corner(list(nmats), owner), nx, ny, nz, affine=False)
        if old:
            scale = _length(wx, wy, wz)
            scale /= _per_corner([abs(float(det)) for det in dets], owner)
            scale *= _widths([0.01 * w for w in widths], factors, owner)
            px, py, pz = (np.add(a, np.multiply(scale, b)) for a, b in ((px, nx), (py, ny), (pz, nz)))
            return np.array(_rows(mvp, px, py, pz, affine=True))
        ux, uy, uz = _normalised(wx, wy, wz)
        world = _rows(_per_corner([m[:3] for m in ms], owner), px, py, pz, affine=True)
        moved = [np.add(a, np.multiply(b, _widths(widths, factors, owner)))
                 for a, b in zip(world, (ux, uy, uz), strict=True)]
        return np.array(_rows(matmul4_many(proj, view[None])[0], *moved, affine=True))
    clip = np.array(_rows(mvp, px, py, pz, affine=True))
    vmat = _per_corner(list(normal_matrices(mvs)[0]), owner)
    vx, vy, vz = _rows(vmat, nx, ny, nz, affine=False)
    cx, cy = _rows(proj[:2, :3], vx, vy, vz, affine=False)
    length = _length(cx, cy)
    dx, dy = _normalised(cx, cy)
    w = clip[3]
    aspect = abs(float(proj[0, 0]) / float(proj[1, 1]))
    with np.errstate(divide="ignore", invalid="ignore"):
        view_z = np.divide(vz, _length(vx, vy, vz))
    if old:
        reach = np.minimum(w, _per_corner([float(p.outline_max_distance) for _mesh, _m, p, _f in items], owner))
        dx *= reach
        dy *= reach
        dx *= aspect
        facing = np.subtract(1.0, np.abs(view_z))
        k = _widths([0.01 * width for width in widths], factors, owner)
        dx, dy = np.multiply(k, dx), np.multiply(k, dy)
    else:
        reach = np.minimum(w, float(proj[1, 1]))
        reach *= _widths([2.0 * width for width in widths], factors, owner)
        dx *= reach
        dy *= reach
        dx *= aspect
        facing = np.subtract(1.0, np.multiply(view_z, view_z))
    np.maximum(facing, 0.0, out=facing)
    np.minimum(facing, 1.0, out=facing)
    dx *= facing
    dy *= facing
    none = length == 0.0
    if none.any():
        dx[none] = 0.0
        dy[none] = 0.0
    clip[0] += dx
    clip[1] += dy
    return clip
