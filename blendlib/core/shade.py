"""Shade stage: the book's ForwardBase fragment program (docs/pipeline.md §7), vectorised.

Scene-level constants (light, ambient, colours brought to shading space) are plain
Python floats computed once; per-fragment work is float64 numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import colorspace
from .gather import gather
from .lights import AddLight, light_terms
from .scene import DrawScene
from .vocabulary import ColorSpace, Lighting, Material, Pass, Texture, TextureFilter, TextureWrap, VertexColor


def gamma_color_to_shading(rgb, color_space: ColorSpace) -> tuple[float, ...]:
    """COLOR_GAMMA (sRGB-encoded) colour → shading space: as is in Gamma, decoded in Linear."""
    if color_space is ColorSpace.Linear:
        return tuple(colorspace.decode(float(c)) for c in rgb)
    return tuple(float(c) for c in rgb)


def linear_color_to_shading(rgb, color_space: ColorSpace) -> tuple[float, ...]:
    """Linear Blender colour → shading space: encoded in Gamma, as is in Linear."""
    if color_space is ColorSpace.Gamma:
        return tuple(colorspace.encode(float(c)) for c in rgb)
    return tuple(float(c) for c in rgb)


@dataclass(frozen=True)
class Lights:
    """Shading-space lighting constants of a draw call: the frame's ambient and main light
    (ForwardBase), or with ``add`` the one light of a ForwardAdd draw (:mod:`.lights`)."""

    ambient: tuple[float, float, float]
    light: tuple[float, float, float]
    direction: tuple[float, float, float]
    add: AddLight | None = None

    @property
    def positional(self) -> bool:
        """Whether Lambert shading reads the fragment's world position (a point or spot light)."""
        return self.add is not None and self.add.positional


@dataclass(frozen=True)
class OutlineColor:
    """A pass's own colour (MToon's outline, :attr:`.vocabulary.Pass.outline_color`) in shading
    space, and its lighting mix: the pass's fragments take ``rgb * lerp(1, lit, mix)``."""

    rgb: tuple[float, float, float]
    mix: float


def outline_color(p: Pass, color_space: ColorSpace) -> OutlineColor | None:
    """``p``'s outline colour brought to shading space (COLOR_GAMMA, as ``_Color``); None when the
    pass draws the material's lit colour."""
    if p.outline_color is None:
        return None
    return OutlineColor(gamma_color_to_shading(p.outline_color, color_space), float(p.outline_lighting_mix))


def frame_lights(scene: DrawScene) -> Lights:
    cs = scene.color_space
    if scene.ambient_is_linear:
        ambient = linear_color_to_shading(scene.ambient, cs)
    else:
        ambient = gamma_color_to_shading(scene.ambient, cs)
    if scene.light is None:
        return Lights(ambient=ambient, light=(0.0, 0.0, 0.0), direction=(0.0, 0.0, 0.0))
    lamp = linear_color_to_shading(scene.light.color, cs)
    energy = float(scene.light.energy)
    light = tuple(c * energy for c in lamp)
    lx, ly, lz = (float(v) for v in scene.light.direction)
    length = math.sqrt((lx * lx + ly * ly) + lz * lz)
    direction = (lx / length, ly / length, lz / length) if length > 0 else (0.0, 0.0, 0.0)
    return Lights(ambient=ambient, light=light, direction=direction)


class Texels:
    """Texels in shading space, stored compactly; :meth:`fetch` gives exactly the float64 values
    that converting every texel would (docs/pipeline.md §7: conversion before filtering).

    - Byte images (at most 256 distinct float32 values, e.g. Blender's k/255): (h*w, 4) uint8
      codes and a float64 lookup table per channel kind (RGB converted, alpha as is): 1 byte a channel;
      small ones (up to :attr:`PLANE_TEXELS` texels) also decoded, channels first, on first fetch.
    - Other images that need no conversion: the float32 values (float64 of a float32 is exact).
    - Other images that need a conversion: float64 (as before).
    """

    #: Rows converted per step (bounds the temporaries of an 8192² texture to a few MB).
    ROWS = 256

    def __init__(self, pixels: np.ndarray, convert) -> None:
        h, w = pixels.shape[:2]
        self.shape = (h, w, 4)
        self.codes = self.lut_rgb = self.lut_alpha = self.values = None
        codes = np.empty((h, w, 4), np.uint8)
        lut32 = np.zeros(256, np.float32)
        exact = True
        for lo in range(0, h, self.ROWS):  # codes = round(v * 255); exact when the table gives v back
            block = pixels[lo:lo + self.ROWS]
            with np.errstate(invalid="ignore", over="ignore"):
                c = np.rint(np.clip(block, 0.0, 1.0) * np.float32(255.0))
            c = np.nan_to_num(c).astype(np.uint8)
            lut32[c.ravel()] = block.ravel()
            codes[lo:lo + self.ROWS] = c
        for lo in range(0, h, self.ROWS):
            block = pixels[lo:lo + self.ROWS]
            if not np.array_equal(lut32[codes[lo:lo + self.ROWS]], block):  # NaN never equals: not exact
                exact = False
                break
        if exact:
            self.codes = codes.reshape(h * w, 4)
            raw = lut32.astype(np.float64)
            self.lut_rgb = convert(raw) if convert is not None else raw
            self.lut_alpha = raw
            return
        del codes
        if convert is None:
            self.values = pixels.reshape(h * w, 4)
            return
        texels = pixels.astype(np.float64)
        texels[..., :3] = convert(texels[..., :3])
        self.values = texels.reshape(h * w, 4)

    def peak(self) -> float:
        """The largest magnitude of any texel's values (inf when one is not finite), computed once."""
        cached = getattr(self, "_peak", None)
        if cached is None:
            if self.codes is not None:
                tables = np.concatenate([self.lut_rgb, self.lut_alpha])
            else:
                tables = self.values
            with np.errstate(invalid="ignore"):
                cached = float(np.max(np.abs(tables), initial=0.0))
            if not np.isfinite(tables).all():
                cached = math.inf
            self._peak = cached
        return cached

    def distinct(self) -> tuple[np.ndarray, np.ndarray]:
        """The texture's distinct texels: ``(first (D,) int64`` flat index of one texel of each
        distinct value, ``of_texel (h*w,) int32`` each texel's entry in ``first``). Computed once."""
        cached = getattr(self, "_distinct", None)
        if cached is None:
            if self.codes is not None:
                keys = self.codes.view(np.uint32).reshape(-1)
            else:  # by bytes: values that differ only in sign of zero or NaN payload stay apart
                raw = np.ascontiguousarray(self.values)
                keys = raw.view(np.dtype((np.void, raw.itemsize * 4))).reshape(-1)
            _, first, of_texel = np.unique(keys, return_index=True, return_inverse=True)
            cached = self._distinct = (first.astype(np.int64), of_texel.reshape(-1).astype(np.int32))
        return cached

    def fetch(self, index: np.ndarray) -> np.ndarray:
        """Texels at flat indices ``index`` (N,) int64 (row * w + column, in 0..h*w-1) → (N, 4) float64
        (for byte images a transposed view of a channels-first array)."""
        return self.fetch_channels(index).T

    def fetch_channels(self, index: np.ndarray, channels: tuple[int, ...] = (0, 1, 2, 3)) -> np.ndarray:
        """:meth:`fetch` channels first: (C, N) float64 of ``channels`` (default all four), each
        channel's values contiguous for byte images (a transposed view for the others)."""
        if self.codes is None:
            values = self.values[index].astype(np.float64, copy=False).T
            return values if len(channels) == 4 else values[list(channels)]
        # Channels first (each channel's values contiguous): the shading reads one channel at a time.
        out = np.empty((len(channels), len(index)), np.float64)
        planes = self._planes()
        if planes is not None:  # one gather per channel from the decoded texture
            for row, k in enumerate(channels):
                gather(planes[k], index, out=out[row])
            return out
        # Whole texels gathered as one uint32 each (fancy indexing of (N, 4) rows is slower),
        # then one table per channel.
        c = self.codes.view(np.uint32).reshape(-1).take(index).view(np.uint8).reshape(-1, 4)
        luts = (self.lut_rgb, self.lut_rgb, self.lut_rgb, self.lut_alpha)
        for row, k in enumerate(channels):
            gather(luts[k], c[:, k], out=out[row])
        return out

    #: Byte images of up to this many texels are also kept decoded, channels first (8 MB at most).
    PLANE_TEXELS = 1 << 18

    def _planes(self) -> np.ndarray | None:
        """(4, h*w) float64: every texel's channels through the tables (the values :meth:`fetch`
        returns), made on first use for textures of at most :attr:`PLANE_TEXELS` texels."""
        planes = getattr(self, "_decoded", None)
        if planes is None and self.codes.shape[0] <= self.PLANE_TEXELS:
            planes = np.empty((4, self.codes.shape[0]), np.float64)
            for k, lut in enumerate((self.lut_rgb, self.lut_rgb, self.lut_rgb, self.lut_alpha)):
                gather(lut, self.codes[:, k], out=planes[k])
            self._decoded = planes
        return planes

    def uniform(self) -> tuple[float | None, ...]:
        """Per channel (four) the value every texel holds there, as :meth:`fetch` gives it
        (the same bits), or None where texels differ or hold NaN; computed once."""
        cached = getattr(self, "_uniform", None)
        if cached is None:
            found: list[float | None] = []
            for k in range(4):
                if self.codes is not None:
                    column = self.codes[:, k]
                    lut = self.lut_alpha if k == 3 else self.lut_rgb
                    value = float(lut[column[0]]) if (column == column[0]).all() else None
                else:
                    column = self.values[:, k]
                    bits = column.view(np.uint32 if column.dtype == np.float32 else np.uint64)
                    value = float(column[0]) if (bits == bits[0]).all() else None
                found.append(None if value is None or math.isnan(value) else value)
            cached = self._uniform = tuple(found)
        return cached

    #: Textures of up to this many texels also keep, per wrap mode, each texel's bilinear
    #: neighbourhood (:meth:`quads`: 128 bytes a texel, 2.1 MB for 128×128; four times the
    #: decoded texture, so larger ones, whose gathers miss the caches anyway, gather texels).
    QUAD_TEXELS = 1 << 14

    def quads(self, wrap: TextureWrap) -> np.ndarray | None:
        """(4, 4, (h+1)*(w+1)) float64, made on first use for textures of at most
        :attr:`QUAD_TEXELS` texels (None for larger ones): entries ``[k, m, (j+1)*(w+1) + i+1]``
        for m = 0..3 hold channel ``k`` of the four texels bilinear filtering blends with its
        corner at texel (j, i), for j in -1..h-1 and i in -1..w-1 — (j, i), (j, i+1), (j+1, i),
        (j+1, i+1), each index wrapped by ``wrap`` as :func:`sample` wraps it — so a sample
        gathers the four by one index, each from a contiguous row (four gathers of one value
        and contiguous arithmetic cost less than one gather of four and strided arithmetic)."""
        cache = self.__dict__.setdefault("_quads", {})
        table = cache.get(wrap)
        h, w = self.shape[:2]
        if table is None and h * w <= self.QUAD_TEXELS:
            if self.codes is not None:
                planes = self._planes()
                if planes is None:  # a byte image too large to keep decoded (only when PLANE_TEXELS < QUAD_TEXELS)
                    return None
            else:
                planes = self.values.T.astype(np.float64)
            rows = _wrap(np.arange(-1.0, h + 1.0), h, wrap) * w
            columns = _wrap(np.arange(-1.0, w + 1.0), w, wrap)
            texel = rows[:, None] + columns[None, :]  # (h+2, w+2): the texel at extended (j, i)
            corners = np.stack([texel[:-1, :-1], texel[:-1, 1:], texel[1:, :-1], texel[1:, 1:]], axis=-1)
            table = cache[wrap] = np.ascontiguousarray(planes[:, corners.reshape(-1, 4).T])
        return table


def texture_texels(texture: Texture, color_space: ColorSpace) -> Texels:
    """Texels converted to shading space before filtering (row 0 = v 0), stored compactly (:class:`Texels`)."""
    pixels = np.asarray(texture.pixels, dtype=np.float32)
    convert = None
    if texture.encoding == "sRGB" and color_space is ColorSpace.Linear:
        convert = colorspace.decode_array
    elif texture.encoding == "Linear" and color_space is ColorSpace.Gamma:
        convert = colorspace.encode_array
    return Texels(pixels, convert)


def _wrap(i: np.ndarray, size: int, wrap: TextureWrap) -> np.ndarray:
    """Float texel indices (integer-valued) → int64 indices in 0..size-1."""
    # Integer arithmetic gives the same indices whenever every value converts exactly (and is
    # several times faster than a float modulo); NaN or huge values take the float formulas.
    low, high = i.min(initial=0.0), i.max(initial=0.0)
    if 0.0 <= low and high <= size - 1:  # already in range (uv in [0, 1)): nothing to wrap
        return i.astype(np.int64)
    if -(2.0**62) < low and high < 2.0**62:
        k = i.astype(np.int64)
        if wrap is TextureWrap.Repeat:
            if size & (size - 1) == 0:  # a power of two: the low bits (two's complement)
                return np.bitwise_and(k, size - 1, out=k)
            return np.remainder(k, size, out=k)  # floor modulo, as the float np.mod
        return np.clip(k, 0, size - 1, out=k)
    if wrap is TextureWrap.Repeat:
        return np.mod(i, float(size)).astype(np.int64)
    return np.minimum(np.maximum(i, 0.0), float(size - 1)).astype(np.int64)


def point_texel_index(texels: Texels, uv: np.ndarray, wrap: TextureWrap) -> np.ndarray:
    """Point filtering's texel: flat indices (N,) int64 (row * w + column) of the texels that
    :func:`sample` with ``TextureFilter.Point`` fetches at uv (N, 2) float64 (§7)."""
    return point_texel_index_of(texels, uv[:, 0], uv[:, 1], wrap)


def point_texel_index_of(texels: Texels, u: np.ndarray, v: np.ndarray, wrap: TextureWrap) -> np.ndarray:
    """:func:`point_texel_index` of texture coordinates given as two (N,) float64 arrays."""
    h, w = texels.shape[:2]
    finite = np.isfinite(u)
    finite &= np.isfinite(v)
    with np.errstate(invalid="ignore", over="ignore"):
        i = np.floor(np.multiply(u, w))
        j = np.floor(np.multiply(v, h))
    if not finite.all():
        i[~finite] = 0.0
        j[~finite] = 0.0
    index = _wrap(j, h, wrap)
    index *= w
    index += _wrap(i, w, wrap)
    return index


def sample(texels: Texels, uv: np.ndarray, filt: TextureFilter, wrap: TextureWrap,
           channels: tuple[int, ...] = (0, 1, 2, 3)) -> np.ndarray:
    """Sample texels at uv (N, 2) float64 → (N, C) float64 of ``channels`` (default all four; each
    channel's values the same bits whichever others are asked for) (§7; non-finite uv → texel (0, 0))."""
    if filt is TextureFilter.Point:
        return texels.fetch_channels(point_texel_index(texels, uv, wrap), channels).T
    h, w = texels.shape[:2]
    u, v = uv[:, 0], uv[:, 1]
    with np.errstate(invalid="ignore", over="ignore"):
        fu = np.multiply(u, w)
        fu -= 0.5
        fv = np.multiply(v, h)
        fv -= 0.5
        i0, j0 = np.floor(fu), np.floor(fv)
        # The corners' extremes: finite only when every coordinate is (a NaN or an infinity
        # carries through the floor into min or max), which spares a finiteness pass.
        bounds = (i0.min(initial=0.0), i0.max(initial=0.0), j0.min(initial=0.0), j0.max(initial=0.0))
        every_finite = all(math.isfinite(b) for b in bounds) or bool((np.isfinite(u) & np.isfinite(v)).all())
        if every_finite:
            au, av = np.subtract(fu, i0, out=fu), np.subtract(fv, j0, out=fv)
        else:
            finite = np.isfinite(u)
            finite &= np.isfinite(v)
            i0 = np.where(finite, i0, 0.0)
            j0 = np.where(finite, j0, 0.0)
            au = np.where(finite, fu - i0, 0.0)
            av = np.where(finite, fv - j0, 0.0)
            bounds = None
    bu, bv = 1.0 - au, 1.0 - av
    out = np.empty((len(channels), u.size), np.float64)
    scratch = np.empty(u.size, np.float64)
    # Per element the same operations in the same order as lo = t00*(1-au) + t01*au,
    # hi = t10*(1-au) + t11*au, lo*(1-av) + hi*av, one channel at a time.
    uniform = texels.uniform()
    varying: list[tuple[int, int]] = []  # (row of out, channel) of channels whose texels differ
    made: dict[str, int] = {}  # a uniform value's bits → the row that holds its samples
    for row, k in enumerate(channels):
        c = uniform[k]
        if c is None:
            varying.append((row, k))
        elif c == 1.0 or c == 0.0:
            # Exactly c at every fragment: (1 - au) + au rounds to 1 for au in [0, 1] (1 - au is
            # exact from 1/2 up, else off by at most 2**-54, which the sum's rounding absorbs), so
            # lo = c*(1-au) + c*au = c and lo*(1-av) + lo*av = c; 0 times a finite weight is 0.
            out[row] = c
        elif c.hex() in made:  # the same value in another channel: the same samples
            out[row] = out[made[c.hex()]]
        else:  # t00 = t01 = t10 = t11 = c, so hi = lo: each operation once
            made[c.hex()] = row
            lo = np.multiply(bu, c, out=out[row])
            lo += np.multiply(au, c, out=scratch)
            np.multiply(lo, av, out=scratch)
            lo *= bv
            lo += scratch
    if not varying:
        return out.T
    quads = texels.quads(wrap)
    corner = None if quads is None else _quad_index(i0, j0, h, w, wrap, bounds)
    if corner is not None:  # per channel, the four neighbours by one index from their own rows
        four = np.empty((4, u.size), np.float64)
        for row, k in varying:
            t00, t01, t10, t11 = (gather(quads[k, m], corner, out=four[m]) for m in range(4))
            lo = np.multiply(t00, bu, out=out[row])
            lo += np.multiply(t01, au, out=scratch)
            hi = np.multiply(t10, bu, out=t10)
            hi += np.multiply(t11, au, out=scratch)
            lo *= bv
            lo += np.multiply(hi, av, out=hi)
        return out.T
    i1, j1 = _wrap(i0 + 1.0, w, wrap), _wrap(j0 + 1.0, h, wrap)
    i0, j0 = _wrap(i0, w, wrap), _wrap(j0, h, wrap)
    j0 *= w
    j1 *= w
    fetched = tuple(k for _row, k in varying)
    t00, t01, t10, t11 = (texels.fetch_channels(j + i, fetched) for j, i in ((j0, i0), (j0, i1), (j1, i0), (j1, i1)))
    for at, (row, _k) in enumerate(varying):
        lo = np.multiply(t00[at], bu, out=out[row])
        lo += np.multiply(t01[at], au, out=scratch)
        hi = np.multiply(t10[at], bu, out=t10[at])
        hi += np.multiply(t11[at], au, out=scratch)
        lo *= bv
        lo += np.multiply(hi, av, out=hi)
    return out.T


def _quad_index(i0: np.ndarray, j0: np.ndarray, h: int, w: int, wrap: TextureWrap,
                bounds: tuple[float, float, float, float] | None = None) -> np.ndarray | None:
    """Rows of :meth:`Texels.quads` for bilinear corners at float texel indices ``i0``, ``j0`` (N,)
    (integer-valued) → (N,) int64; None when an index is 2**52 or more from the texture (there
    ``i0 + 1.0`` rounds and :func:`sample` wraps it as it falls). ``bounds``: ``(i0.min(),
    i0.max(), j0.min(), j0.max())`` (each with ``initial=0.0``) when known."""
    span = 2.0 ** 52
    if bounds is None:
        bounds = (i0.min(initial=0.0), i0.max(initial=0.0), j0.min(initial=0.0), j0.max(initial=0.0))
    low, high = min(bounds[0], bounds[2]), max(bounds[1], bounds[3])
    if not (-span < low and high < span):
        return None
    if -1.0 <= low and high <= min(h, w) - 1.0:  # every corner's texels inside or on the border
        # (j0 + 1) * (w + 1) + (i0 + 1) in float64: integers far below 2**53, so exact.
        row = np.multiply(j0, float(w + 1))
        row += i0
        row += float(w + 2)
        return row.astype(np.int64)
    row, column = _extended(j0, h, wrap), _extended(i0, w, wrap)
    row += 1
    row *= w + 1
    row += column
    row += 1
    return row


def _extended(i: np.ndarray, size: int, wrap: TextureWrap) -> np.ndarray:
    """Float texel indices (integer-valued, under 2**52 in magnitude) → int64 in -1..size-1 with
    the same wrapped pair (i, i + 1) as :func:`_wrap` gives: Repeat keeps i modulo ``size``,
    Clamp holds i in -1..size-1 (below, both clamp to 0; above, both to size - 1)."""
    k = i.astype(np.int64)
    if wrap is TextureWrap.Repeat:
        if size & (size - 1) == 0:
            return np.bitwise_and(k, size - 1, out=k)
        return np.remainder(k, size, out=k)
    return np.clip(k, -1, size - 1, out=k)


def texture_uv_of(material: Material, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`texture_uv` of mesh coordinates given as two (N,) float64 arrays."""
    tu, tv = (float(x) for x in material.main_tex_tiling)
    ou, ov = (float(x) for x in material.main_tex_offset)
    up = np.multiply(u, tu)
    up += ou
    vp = np.multiply(v, tv)
    vp += ov
    return up, vp


def texture_uv(material: Material, uv: np.ndarray) -> np.ndarray:
    """Mesh uv (N, 2) float64 → texture coordinates after ``_MainTex``'s tiling and offset, for
    sampling (:func:`sample`, :func:`.mips.sample_mipmapped`). Tiling (1, 1) and offset (0, 0)
    give ``uv`` itself: ``u * 1 + 0`` is ``u`` but for a -0.0 made +0.0, and sampling takes
    both zeros to the same texels and weights (their products with a size, floors and integer
    conversions are equal)."""
    if tuple(material.main_tex_tiling) == (1.0, 1.0) and tuple(material.main_tex_offset) == (0.0, 0.0):
        return uv
    uvp = np.empty_like(uv)
    uvp[:, 0], uvp[:, 1] = texture_uv_of(material, uv[:, 0], uv[:, 1])
    return uvp


def shading_key(material: Material) -> tuple:
    """What of ``material`` :func:`shade` reads (its texture aside), numbers by their bytes:
    materials with equal keys give a fragment the same colour bit for bit (-0.0 and 0.0 apart)."""
    numbers = np.array([*material.color, *material.main_tex_tiling, *material.main_tex_offset,
                        material.alpha_scale, *material.tint_color], dtype=np.float64)
    return (material.lighting, material.main_tex_filter, material.main_tex_wrap, material.vertex_color,
            numbers.tobytes())


def shade(
    material: Material,
    texels: Texels | None,
    lights: Lights,
    color_space: ColorSpace,
    uv: np.ndarray,
    normal: np.ndarray,
    color: np.ndarray | None = None,
    position: np.ndarray | None = None,
    outline: OutlineColor | None = None,
) -> np.ndarray:
    """Fragment colours (N, 4) float64 in shading space, straight alpha.

    ``uv`` (N, 2) float64 interpolated mesh UVs; ``normal`` (N, 3) float64 interpolated
    (unnormalised) world normals; ``texels`` (:class:`Texels`) from :func:`texture_texels`, sampled
    at the base level (a mipmapped texture's levels are sampled by :mod:`.mips`); ``color``,
    ``position`` and ``outline``: as :func:`shade_texels`.
    """
    tex = ones = None
    if texels is not None:
        tex = sample(texels, texture_uv(material, uv), material.main_tex_filter, material.main_tex_wrap)
        ones = sampled_ones(texels)
    return shade_texels(material, tex, lights, color_space, normal, color, position, outline, ones)


def sampled_ones(texels: Texels) -> tuple[bool, ...]:
    """Per channel (four), whether :func:`sample` gives exactly 1.0 there at every coordinate:
    every texel holds 1 (a fill, see :func:`sample`; Point fetches the texel)."""
    return tuple(c == 1.0 for c in texels.uniform())


def texel_palette(
    material: Material, texels: Texels, lights: Lights, color_space: ColorSpace, normals: np.ndarray,
    colors: np.ndarray | None = None, outline: OutlineColor | None = None,
) -> np.ndarray:
    """Point filtering's colours for every (group, distinct texel): (G * D, 4) float64, row
    ``g * D + of_texel[t]`` (:meth:`Texels.distinct`) = what :func:`shade` gives a fragment with
    normal ``normals[g]`` (G, 3) float64 and vertex colour ``colors[g]`` (G, 4) float64 (None: no
    vertex colour) whose :func:`point_texel_index` is ``t`` (the same arithmetic per element, so
    equal bit for bit)."""
    first, _ = texels.distinct()
    tex = np.tile(texels.fetch(first), (normals.shape[0], 1))
    color = None if colors is None else colors.repeat(first.size, axis=0)
    return shade_texels(material, tex, lights, color_space, normals.repeat(first.size, axis=0), color,
                        outline=outline)


def _unit_normals(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n = normal / sqrt((x*x + y*y) + z*z)`` per fragment (0 for a zero normal), as three (N,)
    float64 arrays (the columns of ``normal`` (N, 3); a channels-first normal passed as its
    transposed view gives contiguous ones)."""
    nx, ny, nz = (normal[:, k] for k in range(3))
    length = nx * nx
    scratch = ny * ny
    length += scratch
    np.multiply(nz, nz, out=scratch)
    length += scratch
    np.sqrt(length, out=length)
    if (length > 0).all():
        return tuple(np.divide(v, length) for v in (nx, ny, nz))
    safe = length > 0  # a zero normal shades as n = 0
    divisor = np.where(safe, length, 1.0)
    out = tuple(np.divide(v, divisor) for v in (nx, ny, nz))
    for v in out:
        v[~safe] = 0.0
    return out


def shade_texels(
    material: Material, tex: np.ndarray | None, lights: Lights, color_space: ColorSpace, normal: np.ndarray,
    color: np.ndarray | None = None, position: np.ndarray | None = None, outline: OutlineColor | None = None,
    ones: tuple[bool, ...] | None = None,
) -> np.ndarray:
    """The fragment program after the texture fetch: ``tex`` (N, 4) float64 sampled texels
    (None: no texture), ``normal`` (N, 3) float64, ``color`` (N, 4) float64 the interpolated
    vertex colour in shading space (None: white), ``position`` (N, 3) float64 the interpolated
    world position (read only for a point or spot light's ForwardAdd draw), ``outline`` the pass's
    outline colour (:func:`outline_color`; None: none) → colours (N, 4) float64, straight alpha
    (docs/pipeline.md §7).

    Per fragment, the albedo and alpha by ``vertex_color``: ``Off``: ``albedo = tex.rgb *
    color.rgb``, ``alpha = (tex.a * color.a) * _AlphaScale``; ``Multiply``: those × ``i.color``
    (``albedo * vc.rgb``, ``alpha * vc.a``); ``Particle``: ``((2 * vc) * _TintColor) * tex`` for rgb
    and alpha (``_Color`` and ``_AlphaScale`` unused, as the particle shaders have neither). Then
    Lambert with ``n = normal / sqrt((x*x + y*y) + z*z)`` (0 for a zero normal) and ``ndl =
    max(0, (n.x*l.x + n.y*l.y) + n.z*l.z)``: ``rgb = ambient*albedo + (light*albedo)*ndl``, or for
    a ForwardAdd draw (``lights.add``) ``rgb = ((light*albedo)*ndl)*atten`` (:mod:`.lights`). Lighting
    is computed one channel at a time on contiguous arrays, each operation as written (the same
    rounding). With ``outline`` (MToon's outline pass) the lit rgb becomes ``outline.rgb[c] * (1 +
    mix * (lit - 1))`` (HLSL's ``lerp(1, lit, mix)``); alpha stays.

    ``ones``: per channel (four), whether ``tex`` holds exactly 1.0 there in every row (a white
    or opaque texture's channel, :func:`sample`): its products are left out (x * 1.0 is x, bit
    for bit), as for no texture.
    """
    out = _lit(material, tex, lights, color_space, normal, color, position, ones)
    if outline is not None:
        for c in range(3):
            v = out[:, c]
            v -= 1.0
            v *= outline.mix
            v += 1.0
            v *= outline.rgb[c]
    return out


def alpha_of(material: Material, tex_alpha: np.ndarray | None, color_alpha: np.ndarray | None, n: int,
             out: np.ndarray | None = None) -> np.ndarray:
    """The fragments' alpha (n,) float64 (:func:`shade_texels`: it reads neither lighting nor the
    outline): ``tex_alpha`` (n,) the sampled texels' alpha (None: no texture), ``color_alpha``
    (n,) the interpolated vertex colours' (None: white). Particle: ``((2 * vc.a) * _TintColor.a) *
    tex.a``; else ``(tex.a * _Color.a) * _AlphaScale``, times ``vc.a`` with ``Multiply``.
    ``out``: an (n,) float64 array (a view) to write them into, returned. The products are
    made in a contiguous array and written once into a strided ``out`` (a column of (n, 4)
    colours): a product into a strided view costs half as much again."""
    if out is None:
        out = np.empty(n, dtype=np.float64)
    work = out if out.flags.c_contiguous else np.empty(n, dtype=np.float64)
    if material.vertex_color is VertexColor.Particle:
        tint = float(material.tint_color[3])
        if color_alpha is None:
            work[...] = 2.0 * tint
        else:
            np.multiply(color_alpha, 2.0, out=work)
            work *= tint
        if tex_alpha is not None:
            work *= tex_alpha
    else:
        if tex_alpha is None:
            # tex = (1, 1, 1, 1): 1.0 * c == c exactly, so alpha is the material's.
            work[...] = float(material.color[3]) * float(material.alpha_scale)
        else:
            np.multiply(tex_alpha, float(material.color[3]), out=work)
            work *= float(material.alpha_scale)
        if material.vertex_color is VertexColor.Multiply and color_alpha is not None:
            work *= color_alpha
    if work is not out:
        out[...] = work
    return out


def _lit(
    material: Material, tex: np.ndarray | None, lights: Lights, color_space: ColorSpace, normal: np.ndarray,
    color: np.ndarray | None, position: np.ndarray | None, ones: tuple[bool, ...] | None = None,
) -> np.ndarray:
    """:func:`shade_texels` before the outline colour."""
    n = normal.shape[0]
    mode = material.vertex_color
    out = np.empty((n, 4), dtype=np.float64)
    # A channel of exactly 1.0 multiplies nothing: read as no texture there.
    texture = [None if tex is None or (ones is not None and ones[c]) else tex[:, c] for c in range(4)]
    untextured = all(t is None for t in texture[:3])
    alpha_of(material, texture[3], None if color is None else color[:, 3], n, out=out[:, 3])
    constant = None  # the albedo (3,) as Python floats when it is the same for every fragment
    if mode is VertexColor.Particle:
        tint = gamma_color_to_shading(material.tint_color[:3], color_space) + (float(material.tint_color[3]),)
        if color is None and untextured:
            constant = tuple(2.0 * tint[c] for c in range(3))

        def base(c: int) -> np.ndarray:  # (2 * i.color) * _TintColor, white when there is no colour
            if color is None:
                return np.full(n, 2.0 * tint[c], dtype=np.float64)
            v = np.multiply(color[:, c], 2.0)
            v *= tint[c]
            return v

        def albedo(c: int) -> np.ndarray:
            v = base(c)
            if texture[c] is not None:
                v *= texture[c]
            return v
    else:
        col = gamma_color_to_shading(material.color[:3], color_space) + (float(material.color[3]),)
        tinted = mode is VertexColor.Multiply and color is not None
        if untextured and not tinted:
            constant = tuple(float(col[c]) for c in range(3))

        def albedo(c: int) -> np.ndarray:
            v = np.full(n, col[c], dtype=np.float64) if texture[c] is None else np.multiply(texture[c], col[c])
            if tinted:
                v *= color[:, c]
            return v

    if material.lighting is Lighting.Unlit:
        for c in range(3):
            out[:, c] = albedo(c) if constant is None else constant[c]
        return out
    nx, ny, nz = _unit_normals(normal)
    add = lights.add
    atten = None
    if add is None:
        lx, ly, lz = lights.direction
        light = lights.light
    elif add.positional:
        lx, ly, lz, atten = light_terms(add, position[:, 0], position[:, 1], position[:, 2])
        light = add.color
    else:
        (lx, ly, lz), light = add.direction, add.color
    ndl = np.multiply(nx, lx, out=nx)
    ndl += np.multiply(ny, ly, out=ny)
    ndl += np.multiply(nz, lz, out=nz)
    np.maximum(0.0, ndl, out=ndl)
    for c in range(3):
        if constant is not None:
            # The same operations on one albedo for all: (light*albedo)*ndl (+ ambient*albedo),
            # each product of two doubles rounded as the per-fragment one is; the last one
            # writes the colour's column (ny: free scratch by now).
            lit = float(constant[c]) * float(light[c])
            if add is None:
                np.add(np.multiply(ndl, lit, out=ny), float(constant[c]) * float(lights.ambient[c]), out=out[:, c])
            elif atten is not None:
                np.multiply(np.multiply(ndl, lit, out=ny), atten, out=out[:, c])
            else:
                np.multiply(ndl, lit, out=out[:, c])
            continue
        a = albedo(c)
        if add is None:
            term = np.multiply(a, lights.ambient[c])
            np.multiply(a, light[c], out=a)
            a *= ndl
            term += a
        else:
            term = np.multiply(a, light[c], out=a)
            term *= ndl
            if atten is not None:
                term *= atten
        out[:, c] = term
    return out
