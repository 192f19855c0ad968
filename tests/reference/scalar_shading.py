"""The scalar reference's shading (docs/pipeline.md §7) and the outline vertex program (§1): the
fragment program (:class:`Shader`: the book's ForwardBase, a ForwardAdd draw's light, vertex colours,
mipmaps) and its helpers, one value at a time in plain Python floats (each sum and product in the
order the page writes it).

A module of its own so that tests/reference/scalar.py (the pipeline around it) stays readable; it
uses nothing of ``blendlib.core`` beyond the data classes and the vocabulary.
"""

from __future__ import annotations

import math
import struct

import numpy as np

from blendlib.core.scene import DrawScene
from blendlib.core.vocabulary import (
    ColorSpace,
    Lighting,
    LightType,
    OutlineFormula,
    OutlineMode,
    TextureFilter,
    TextureWrap,
    VertexColor,
)

S = 256
HALF = S // 2
EXP = 1.0 / 2.4


def to_list(m) -> list:
    """A numpy array (any float dtype) as nested lists of Python floats (float64)."""
    return np.asarray(m, dtype=np.float64).tolist()


def f32(x: float) -> float:
    """The float32 nearest to ``x`` (round to nearest even; overflow gives +-inf)."""
    try:
        return struct.unpack("<f", struct.pack("<f", x))[0]
    except OverflowError:
        return math.copysign(math.inf, x)


def encode(x: float) -> float:
    return x * 12.92 if x <= 0.0031308 else 1.055 * x**EXP - 0.055


def decode(x: float) -> float:
    return x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4


def nmin(a: float, b: float) -> float:
    """numpy's ``minimum``: NaN if either is NaN."""
    if a != a or b != b:
        return math.nan
    return a if a <= b else b


def nmax(a: float, b: float) -> float:
    """numpy's ``maximum``: NaN if either is NaN."""
    if a != a or b != b:
        return math.nan
    return a if a >= b else b


def div(a: float, b: float) -> float:
    """IEEE division (numpy semantics: x/0 is +-inf or nan instead of an exception)."""
    try:
        return a / b
    except ZeroDivisionError:
        if a != a or a == 0.0:
            return math.nan
        return math.copysign(math.inf, a) * math.copysign(1.0, b)


def length3(v) -> float:
    return math.sqrt((v[0] * v[0] + v[1] * v[1]) + v[2] * v[2])


def unit3(v) -> list:
    n = length3(v)
    if n == 0:
        return [0.0, 0.0, 0.0]
    return [div(v[0], n), div(v[1], n), div(v[2], n)]


def rows3(m, v, affine: bool) -> list:
    """``((m[i][0]*x + m[i][1]*y) + m[i][2]*z) (+ m[i][3])`` per row of ``m``."""
    out = []
    for row in m:
        x = (row[0] * v[0] + row[1] * v[1]) + row[2] * v[2]
        out.append(x + row[3] if affine else x)
    return out


def matmul4(a, b):
    return [[((a[i][0] * b[0][j] + a[i][1] * b[1][j]) + a[i][2] * b[2][j]) + a[i][3] * b[3][j] for j in range(4)]
            for i in range(4)]


def signed_cofactors(m) -> tuple[list, float]:
    """§1's normal matrix (cofactors of the upper 3x3, negated for a negative determinant) and det."""
    c = [[m[(i + 1) % 3][(j + 1) % 3] * m[(i + 2) % 3][(j + 2) % 3]
          - m[(i + 1) % 3][(j + 2) % 3] * m[(i + 2) % 3][(j + 1) % 3] for j in range(3)] for i in range(3)]
    det = (m[0][0] * c[0][0] + m[0][1] * c[0][1]) + m[0][2] * c[0][2]
    return (c if det >= 0 else [[-x for x in row] for row in c]), det


# ---------------------------------------------------------------- §1 outline vertex program


def outline_clip(p, position, normal, M, V, P, factor: float | None = None) -> list:
    """Clip coordinates of one corner (object ``position``, ``normal``) under pass ``p``'s outline;
    ``factor`` the outline-width texture's at the corner (:func:`width_factor`; None: ×1)."""
    n = unit3(normal)
    width = float(p.outline_width)

    def times(w: float) -> float:
        return w if factor is None else w * factor
    mv = matmul4(V, M)
    mvp = matmul4(P, mv)
    old = p.outline_formula is OutlineFormula.MToon0x
    if p.outline_mode is OutlineMode.World:
        N, det = signed_cofactors(M)
        wn = rows3(N, n, affine=False)
        if old:
            scale = div(length3(wn), abs(det)) * times(0.01 * width)
            moved = [position[k] + scale * n[k] for k in range(3)]
            return rows3(mvp, moved, affine=True)
        u = unit3(wn)
        world = rows3(M[:3], position, affine=True)
        moved = [world[k] + u[k] * times(width) for k in range(3)]
        return rows3(matmul4(P, V), moved, affine=True)
    clip = rows3(mvp, position, affine=True)
    Nv, _ = signed_cofactors(mv)
    v = rows3(Nv, n, affine=False)
    cx, cy = rows3([P[0][:3], P[1][:3]], v, affine=False)
    cl = math.sqrt(cx * cx + cy * cy)
    if cl == 0:  # no direction on screen: no offset (the core adds a zero)
        return [clip[0] + 0.0, clip[1] + 0.0, clip[2], clip[3]]
    dx, dy = cx / cl, cy / cl
    w = clip[3]
    aspect = abs(P[0][0] / P[1][1])
    vz = div(v[2], length3(v))
    if old:
        reach = nmin(w, float(p.outline_max_distance))
        dx, dy = dx * reach, dy * reach
        dx *= aspect
        facing = 1.0 - abs(vz)
        k = times(0.01 * width)
        dx, dy = k * dx, k * dy
    else:
        reach = nmin(w, P[1][1]) * times(2.0 * width)
        dx, dy = dx * reach, dy * reach
        dx *= aspect
        facing = 1.0 - vz * vz
    facing = nmin(nmax(facing, 0.0), 1.0)
    return [clip[0] + dx * facing, clip[1] + dy * facing, clip[2], clip[3]]


def width_factor(material, uv: list, linear: bool) -> float | None:
    """The outline-width texture's red channel at mesh coordinates ``uv`` (after ``_MainTex``'s
    tiling and offset), level 0, Point or Bilinear, in shading space; None without a texture."""
    tex = material.outline_width_tex
    if tex is None:
        return None
    conv = convert_of(tex.encoding, linear)
    rows = [[[conv(t[0]), t[1], t[2], t[3]] for t in row] for row in to_list(np.asarray(tex.pixels, np.float32))]
    u = uv[0] * float(material.main_tex_tiling[0]) + float(material.main_tex_offset[0])
    v = uv[1] * float(material.main_tex_tiling[1]) + float(material.main_tex_offset[1])
    return sample_rows(rows, u, v, material.outline_width_tex_filter is TextureFilter.Point,
                       material.outline_width_tex_wrap is TextureWrap.Repeat)[0]


def convert_of(encoding: str, linear: bool):
    """A texel's colour channel → shading space (§7: sRGB decoded in Linear, Linear encoded in Gamma)."""
    if encoding == "sRGB":
        return decode if linear else (lambda c: c)
    if encoding == "Linear":
        return (lambda c: c) if linear else encode
    return lambda c: c


def sample_rows(T: list, u: float, v: float, point: bool, repeat: bool) -> list:
    """Sample one level (rows of texels) at texture coordinates (u, v), Point or Bilinear (§7)."""
    def wrap(i: int, n: int) -> int:
        return i % n if repeat else min(max(i, 0), n - 1)

    w, h = len(T[0]), len(T)
    if not (math.isfinite(u) and math.isfinite(v)):
        return list(T[0][0])
    if point:
        return list(T[wrap(math.floor(v * h), h)][wrap(math.floor(u * w), w)])
    fu = u * w - 0.5
    fv = v * h - 0.5
    i0 = math.floor(fu)
    j0 = math.floor(fv)
    au = fu - i0
    av = fv - j0
    i1, j1 = wrap(i0 + 1, w), wrap(j0 + 1, h)
    i0, j0 = wrap(i0, w), wrap(j0, h)
    out = []
    for c in range(4):
        lo = T[j0][i0][c] * (1 - au) + T[j0][i1][c] * au
        hi = T[j1][i0][c] * (1 - au) + T[j1][i1][c] * au
        out.append(lo * (1 - av) + hi * av)
    return out


# ---------------------------------------------------------------- §7 a ForwardAdd draw's light


class AddLight:
    """A ForwardAdd draw's light in shading space."""

    def __init__(self, light, linear: bool):
        lamp = [float(c) if linear else encode(float(c)) for c in light.color]
        intensity = float(light.intensity)
        self.color = [c * intensity for c in lamp]
        self.type = light.type
        self.direction = unit3([float(c) for c in light.axis])
        self.position = [float(c) for c in light.position]
        self.axis = [-c for c in self.direction]
        r = float(light.range)
        self.range2 = r * r
        self.tan_half = math.tan(math.radians(float(light.spot_angle)) / 2.0)


def falloff(r2: float) -> float:
    if r2 >= 1.0:
        return 0.0
    return (1.0 / (r2 * 25.0 + 1.0)) * nmin(1.0, (1.0 - r2) / (1.0 - 0.64))


def light_terms(light: AddLight, pos: list) -> tuple[list, float]:
    """(unit vector towards the light, attenuation) at world position ``pos``."""
    if light.type is LightType.Directional:
        return light.direction, 1.0
    d = [pos[k] - light.position[k] for k in range(3)]
    d2 = (d[0] * d[0] + d[1] * d[1]) + d[2] * d[2]
    length = math.sqrt(d2) if d2 == d2 else math.nan
    to_light = [0.0, 0.0, 0.0] if length == 0 else [div(-d[k], length) for k in range(3)]
    atten = falloff(div(d2, light.range2))
    if light.type is LightType.Spot:
        z = (d[0] * light.axis[0] + d[1] * light.axis[1]) + d[2] * light.axis[2]
        if z > 0:
            q2 = nmax(d2 - z * z, 0.0)
            rho = div(math.sqrt(q2) if q2 == q2 else math.nan, z * light.tan_half)
            cone = nmin(nmax((1.0 - rho) / (18.0 / 64.0), 0.0), 1.0)
        else:
            cone = 0.0
        atten = cone * atten
    return to_light, atten


# ---------------------------------------------------------------- §7 mipmaps


def build_mips(level0: list, preserve: bool, cutoff: float) -> list:
    """The chain [level 0, level 1, ...], each level rows (h) of texels (w) of 4 floats."""
    levels = [level0]
    target = None
    if preserve:
        alphas = [t[3] for row in level0 for t in row]
        target = (_covered(alphas, 1.0, cutoff), len(alphas))
    source = level0
    while len(source) > 1 or len(source[0]) > 1:
        h, w = len(source), len(source[0])
        h2, w2 = max(1, h // 2), max(1, w // 2)
        level = []
        for j in range(h2):
            r0, r1 = 2 * j, (2 * j + 1 if h > 1 else 2 * j)
            row = []
            for i in range(w2):
                c0, c1 = 2 * i, (2 * i + 1 if w > 1 else 2 * i)
                row.append([f32((((source[r0][c0][k] + source[r0][c1][k]) + source[r1][c0][k]) + source[r1][c1][k])
                                * 0.25) for k in range(4)])
            level.append(row)
        kept = level
        if target is not None:
            alphas = [t[3] for row in level for t in row]
            s = coverage_scale(alphas, cutoff, target)
            kept = [[t[:3] + [f32(nmin(nmax(t[3] * s, 0.0), 1.0))] for t in row] for row in level]
        levels.append(kept)
        source = level
    return levels


def _covered(alphas: list, s: float, cutoff: float) -> int:
    return sum(1 for a in alphas if nmin(nmax(a * s, 0.0), 1.0) >= cutoff)


def coverage_scale(alphas: list, cutoff: float, target: tuple[int, int]) -> float:
    covered0, n0 = target
    n = len(alphas)
    low, high, s = 0.0, 4.0, 1.0
    best = None
    for _ in range(10):
        diff = _covered(alphas, s, cutoff) * n0 - covered0 * n
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


def log2_lod(rho2: float) -> float:
    if rho2 != rho2:
        return math.nan
    if rho2 == 0.0:
        return -math.inf
    if rho2 == math.inf:
        return math.inf
    return 0.5 * math.log2(rho2)


def mip_sample(levels: list, sample_level, u: float, v: float, lod: float, filt: TextureFilter) -> list:
    """Sample through the chain; ``sample_level(level, u, v)`` samples one level with the filter."""
    last = len(levels) - 1
    if filt is not TextureFilter.Trilinear:
        level = 0
        if lod > 0.5:
            level = int(min(math.ceil(lod + 0.5) - 1.0, float(last)))
        return sample_level(levels[level], u, v)
    if not lod > 0.0:
        return sample_level(levels[0], u, v)
    d = math.floor(lod) if lod != math.inf else math.inf
    if d >= last:
        return sample_level(levels[last], u, v)
    f = lod - d
    t0 = sample_level(levels[int(d)], u, v)
    t1 = sample_level(levels[int(d) + 1], u, v)
    return [t0[k] * (1.0 - f) + t1[k] * f for k in range(4)]


# ---------------------------------------------------------------- §7 the fragment program


class Shader:
    """The material's fragment program in shading space (docs/pipeline.md §7); :meth:`for_light` sets
    the light of a ForwardAdd draw."""

    def __init__(self, scene: DrawScene, material):
        linear = scene.color_space is ColorSpace.Linear
        self.linear = linear

        def from_gamma(c):  # COLOR_GAMMA colour
            return decode(c) if linear else c

        def from_linear(c):  # linear Blender colour
            return c if linear else encode(c)

        self.from_gamma = from_gamma
        self.color = [from_gamma(float(c)) for c in material.color[:3]] + [float(material.color[3])]
        self.tint = [from_gamma(float(c)) for c in material.tint_color[:3]] + [float(material.tint_color[3])]
        self.vertex_color = material.vertex_color
        self.tiling = [float(v) for v in material.main_tex_tiling]
        self.offset = [float(v) for v in material.main_tex_offset]
        self.alpha_scale = float(material.alpha_scale)
        self.cutoff = float(material.cutoff)
        self.lambert = material.lighting is Lighting.Lambert
        self.filter = material.main_tex_filter
        self.point = material.main_tex_filter is TextureFilter.Point
        self.repeat = material.main_tex_wrap is TextureWrap.Repeat
        amb = [float(c) for c in scene.ambient]
        self.ambient = [from_linear(c) if scene.ambient_is_linear else from_gamma(c) for c in amb]
        if scene.light is None:
            self.light = [0.0, 0.0, 0.0]
            self.ldir = [0.0, 0.0, 0.0]
        else:
            energy = float(scene.light.energy)
            self.light = [from_linear(float(c)) * energy for c in scene.light.color]
            self.ldir = normalise([float(v) for v in scene.light.direction])
        self.add = None  # a ForwardAdd draw's light (scalar_shading.AddLight)
        self.outline = None  # the pass's outline colour (shading space) and lighting mix
        tex = material.main_tex
        self.tex = None
        self.mips = None
        if tex is not None:
            rows = to_list(np.asarray(tex.pixels, dtype=np.float32))
            conv = convert_of(tex.encoding, linear)
            self.tex = [[[conv(t[0]), conv(t[1]), conv(t[2]), t[3]] for t in row] for row in rows]
            self.th = len(rows)
            self.tw = len(rows[0])
            if material.main_tex_mipmaps:
                self.mips = build_mips(self.tex, material.main_tex_preserve_coverage, self.cutoff)

    def for_light(self, light, linear: bool) -> Shader:
        """This program with the light of a ForwardAdd draw (None: the frame's main light)."""
        self.add = None if light is None else AddLight(light, linear)
        return self

    def for_pass(self, p) -> Shader:
        """This program with pass ``p``'s outline colour (MToon's outline: None, the lit colour)."""
        self.outline = None
        if p.outline_color is not None:
            self.outline = ([self.from_gamma(float(c)) for c in p.outline_color], float(p.outline_lighting_mix))
        return self

    def sample(self, u: float, v: float) -> list:
        if self.tex is None:
            return [1.0, 1.0, 1.0, 1.0]
        return self.sample_level(self.tex, u, v)

    def sample_level(self, T: list, u: float, v: float) -> list:
        """Sample one level (rows of texels) at texture coordinates (u, v) with the filter (§7)."""
        return sample_rows(T, u, v, self.point, self.repeat)

    def texture_uv(self, uv: list) -> tuple[float, float]:
        return uv[0] * self.tiling[0] + self.offset[0], uv[1] * self.tiling[1] + self.offset[1]

    def shade(self, uv: list, nw: list, vc: list | None = None, pos: list | None = None,
              lod: float | None = None) -> list:
        """rgba of the fragment in shading space (before clamping); ``vc`` the vertex colour in
        shading space (None: white), ``pos`` the world position, ``lod`` the quad's LOD (mipmaps).
        An outline pass's colour replaces the lit rgb: ``outline * lerp(1, lit, mix)``, HLSL's
        ``lerp(a, b, t) = a + t * (b - a)``."""
        rgba = self.lit(uv, nw, vc, pos, lod)
        if self.outline is None:
            return rgba
        color, mix = self.outline
        return [color[c] * (1.0 + mix * (rgba[c] - 1.0)) for c in range(3)] + [rgba[3]]

    def lit(self, uv: list, nw: list, vc: list | None, pos: list | None, lod: float | None) -> list:
        """:meth:`shade` before the outline colour."""
        u, v = self.texture_uv(uv)
        if self.mips is not None and lod is not None:
            tex = mip_sample(self.mips, self.sample_level, u, v, lod, self.filter)
        else:
            tex = self.sample(u, v)
        if self.vertex_color is VertexColor.Particle:
            c = [1.0, 1.0, 1.0, 1.0] if vc is None else vc
            rgba = [((2.0 * c[k]) * self.tint[k]) * tex[k] for k in range(4)]
            albedo, alpha = rgba[:3], rgba[3]
        else:
            albedo = [tex[c] * self.color[c] for c in range(3)]
            alpha = (tex[3] * self.color[3]) * self.alpha_scale
            if self.vertex_color is VertexColor.Multiply and vc is not None:
                albedo = [albedo[c] * vc[c] for c in range(3)]
                alpha = alpha * vc[3]
        if not self.lambert:
            return albedo + [alpha]
        n = normalise(nw)
        if self.add is None:
            l = self.ldir
            ndl = nmax(0.0, (n[0] * l[0] + n[1] * l[1]) + n[2] * l[2])
            rgb = [self.ambient[c] * albedo[c] + (self.light[c] * albedo[c]) * ndl for c in range(3)]
            return rgb + [alpha]
        l, atten = light_terms(self.add, pos)
        ndl = nmax(0.0, (n[0] * l[0] + n[1] * l[1]) + n[2] * l[2])
        rgb = [((self.add.color[c] * albedo[c]) * ndl) * atten for c in range(3)]
        return rgb + [alpha]


def normalise(v: list) -> list:
    length = math.sqrt((v[0] * v[0] + v[1] * v[1]) + v[2] * v[2])
    if length == 0:
        return [0.0, 0.0, 0.0]
    return [v[0] / length, v[1] / length, v[2] / length]
