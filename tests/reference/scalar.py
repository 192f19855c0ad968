"""The scalar reference renderer: docs/pipeline.md in plain Python, one fragment at a time.

This is the specification written as code (README "How correctness is checked", reference 1). Every value is a
Python float (IEEE float64) or int; each sum is written in the evaluation order the
page prescribes, ``(a + b) + c``, so the vectorised core must match it bit for bit.
numpy is used only to read the input arrays (converted to Python numbers first) and
to build the output arrays at the very end. Fragments are processed in primitive
order, so the output merger sees them exactly as a GPU would.

    color, depth, stencil = render_reference(scene)

returns ``color`` (H, W, 4) float32, ``depth`` (H, W) float32 and ``stencil``
(H, W) uint8 with row 0 = the top of the image, like :class:`blendlib.core.pipeline.Frame`.
"""

from __future__ import annotations

import math
import struct

import numpy as np

from blendlib.core.scene import DrawScene, validate_scene
from blendlib.core.vocabulary import (
    LAST_OPAQUE_QUEUE,
    BlendFactor,
    BlendOp,
    ColorSpace,
    CompareFunction,
    Cull,
    Lighting,
    SortMode,
    StencilOp,
    TextureFilter,
    TextureWrap,
)

S = 256  # sub-pixel steps per pixel
HALF = S // 2
DMAX = 2**24 - 1
GUARD = 4.0
EXP = 1.0 / 2.4


# ---------------------------------------------------------------- small helpers


def f32(x: float) -> float:
    """The float32 nearest to ``x`` (round to nearest even; overflow gives +-inf)."""
    try:
        return struct.unpack("<f", struct.pack("<f", x))[0]
    except OverflowError:
        return math.copysign(math.inf, x)


def div(a: float, b: float) -> float:
    """IEEE division (numpy semantics: x/0 is +-inf or nan instead of an exception)."""
    try:
        return a / b
    except ZeroDivisionError:
        if a != a or a == 0.0:
            return math.nan
        return math.copysign(math.inf, a) * math.copysign(1.0, b)


def encode(x: float) -> float:
    return x * 12.92 if x <= 0.0031308 else 1.055 * x**EXP - 0.055


def decode(x: float) -> float:
    return x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4


def clamp01(x: float) -> float:
    return min(max(x, 0.0), 1.0)


def matmul4(a, b):
    return [
        [((a[i][0] * b[0][j] + a[i][1] * b[1][j]) + a[i][2] * b[2][j]) + a[i][3] * b[3][j] for j in range(4)]
        for i in range(4)
    ]


def to_list(m) -> list:
    """A numpy array (any float dtype) as nested lists of Python floats (float64)."""
    return np.asarray(m, dtype=np.float64).tolist()


def compare(func: CompareFunction, a: int, b: int) -> bool:
    """``a OP b`` (the incoming value on the left, as GL and the page write it)."""
    if func is CompareFunction.Never:
        return False
    if func is CompareFunction.Less:
        return a < b
    if func is CompareFunction.Greater:
        return a > b
    if func is CompareFunction.LEqual:
        return a <= b
    if func is CompareFunction.GEqual:
        return a >= b
    if func is CompareFunction.Equal:
        return a == b
    if func is CompareFunction.NotEqual:
        return a != b
    return True  # Always


def stencil_op(op: StencilOp, s: int, ref: int) -> int:
    if op is StencilOp.Keep:
        return s
    if op is StencilOp.Zero:
        return 0
    if op is StencilOp.Replace:
        return ref
    if op is StencilOp.IncrSat:
        return min(s + 1, 255)
    if op is StencilOp.DecrSat:
        return max(s - 1, 0)
    if op is StencilOp.Invert:
        return 255 - s
    if op is StencilOp.IncrWrap:
        return (s + 1) & 255
    return (s - 1) & 255  # DecrWrap


# ---------------------------------------------------------------- §0 draw list


def draw_list(scene: DrawScene) -> list:
    """Renderers in draw order: key (queue, signed distance, name, slot)."""
    cam = scene.camera
    p = [float(v) for v in cam.position]
    mode = scene.sort_mode
    if mode is SortMode.Default:
        mode = SortMode.Orthographic if cam.orthographic else SortMode.Perspective
    if mode is SortMode.Orthographic:
        axis = [float(v) for v in cam.forward]
    elif mode is SortMode.CustomAxis:
        a = [float(v) for v in scene.sort_axis]
        length = math.sqrt((a[0] * a[0] + a[1] * a[1]) + a[2] * a[2])
        axis = [a[0] / length, a[1] / length, a[2] / length]
    else:
        axis = None

    def key(r):
        c = [float(v) for v in r.bounds_center]
        dx, dy, dz = c[0] - p[0], c[1] - p[1], c[2] - p[2]
        if axis is None:
            d = (dx * dx + dy * dy) + dz * dz
        else:
            d = (dx * axis[0] + dy * axis[1]) + dz * axis[2]
        queue = r.material.render_queue
        return (queue, d if queue <= LAST_OPAQUE_QUEUE else -d, r.name, r.slot)

    return sorted(scene.renderers, key=key)


# ---------------------------------------------------------------- §2 clipping


def clip_triangle(verts: list) -> list:
    """Clip one triangle; each vertex is a list ``[x, y, z, w, B0, B1, B2]``. Returns triangles."""

    def planes(v):
        x, y, z, w = v[0], v[1], v[2], v[3]
        gw = GUARD * w
        return (z + w, w - z, gw - x, gw + x, gw - y, gw + y)

    dists = [planes(v) for v in verts]
    if all(d >= 0 for dv in dists for d in dv):
        return [verts]
    for k in range(6):
        if all(dv[k] < 0 for dv in dists):
            return []
    poly = verts
    for k in range(6):
        out = []
        n = len(poly)
        for i in range(n):
            a, b = poly[i], poly[(i + 1) % n]
            da, db = planes(a)[k], planes(b)[k]
            if da >= 0:
                out.append(a)
            if (da >= 0) != (db >= 0):
                t = da / (da - db)
                out.append([va + t * (vb - va) for va, vb in zip(a, b, strict=True)])
        poly = out
        if len(poly) < 3:
            return []
    return [[poly[0], poly[j], poly[j + 1]] for j in range(1, len(poly) - 1)]


# ---------------------------------------------------------------- §7 shading helpers


class Shader:
    """The material's fragment program in shading space."""

    def __init__(self, scene: DrawScene, material):
        linear = scene.color_space is ColorSpace.Linear
        self.linear = linear

        def from_gamma(c):  # COLOR_GAMMA colour
            return decode(c) if linear else c

        def from_linear(c):  # linear Blender colour
            return c if linear else encode(c)

        self.color = [from_gamma(float(c)) for c in material.color[:3]] + [float(material.color[3])]
        self.tiling = [float(v) for v in material.main_tex_tiling]
        self.offset = [float(v) for v in material.main_tex_offset]
        self.alpha_scale = float(material.alpha_scale)
        self.cutoff = float(material.cutoff)
        self.lambert = material.lighting is Lighting.Lambert
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
        tex = material.main_tex
        self.tex = None
        if tex is not None:
            rows = to_list(np.asarray(tex.pixels, dtype=np.float32))
            if tex.encoding == "sRGB":
                conv = decode if linear else (lambda c: c)
            elif tex.encoding == "Linear":
                conv = (lambda c: c) if linear else encode
            else:
                conv = lambda c: c  # noqa: E731
            self.tex = [[[conv(t[0]), conv(t[1]), conv(t[2]), t[3]] for t in row] for row in rows]
            self.th = len(rows)
            self.tw = len(rows[0])

    def wrap(self, i: int, n: int) -> int:
        return i % n if self.repeat else min(max(i, 0), n - 1)

    def sample(self, u: float, v: float) -> list:
        if self.tex is None:
            return [1.0, 1.0, 1.0, 1.0]
        T, w, h = self.tex, self.tw, self.th
        if not (math.isfinite(u) and math.isfinite(v)):
            return list(T[0][0])
        if self.point:
            i = self.wrap(math.floor(u * w), w)
            j = self.wrap(math.floor(v * h), h)
            return list(T[j][i])
        fu = u * w - 0.5
        fv = v * h - 0.5
        i0 = math.floor(fu)
        j0 = math.floor(fv)
        au = fu - i0
        av = fv - j0
        i1, j1 = self.wrap(i0 + 1, w), self.wrap(j0 + 1, h)
        i0, j0 = self.wrap(i0, w), self.wrap(j0, h)
        out = []
        for c in range(4):
            lo = T[j0][i0][c] * (1 - au) + T[j0][i1][c] * au
            hi = T[j1][i0][c] * (1 - au) + T[j1][i1][c] * au
            out.append(lo * (1 - av) + hi * av)
        return out

    def shade(self, uv: list, nw: list) -> list:
        """rgba of the fragment in shading space (before clamping)."""
        u = uv[0] * self.tiling[0] + self.offset[0]
        v = uv[1] * self.tiling[1] + self.offset[1]
        tex = self.sample(u, v)
        albedo = [tex[c] * self.color[c] for c in range(3)]
        alpha = (tex[3] * self.color[3]) * self.alpha_scale
        if not self.lambert:
            return albedo + [alpha]
        n = normalise(nw)
        l = self.ldir
        ndl = max(0.0, (n[0] * l[0] + n[1] * l[1]) + n[2] * l[2])
        rgb = [self.ambient[c] * albedo[c] + (self.light[c] * albedo[c]) * ndl for c in range(3)]
        return rgb + [alpha]


def normalise(v: list) -> list:
    length = math.sqrt((v[0] * v[0] + v[1] * v[1]) + v[2] * v[2])
    if length == 0:
        return [0.0, 0.0, 0.0]
    return [v[0] / length, v[1] / length, v[2] / length]


# ---------------------------------------------------------------- §8 blending


def factor(f: BlendFactor, c: int, src: list, dst: list) -> float:
    """Blend factor ``f`` for channel ``c`` (0..2 rgb, 3 alpha)."""
    sa, da = src[3], dst[3]
    if f is BlendFactor.One:
        return 1.0
    if f is BlendFactor.Zero:
        return 0.0
    if f is BlendFactor.SrcColor:
        return src[c]
    if f is BlendFactor.SrcAlpha:
        return sa
    if f is BlendFactor.DstColor:
        return dst[c]
    if f is BlendFactor.DstAlpha:
        return da
    if f is BlendFactor.OneMinusSrcColor:
        return 1 - src[c]
    if f is BlendFactor.OneMinusSrcAlpha:
        return 1 - sa
    if f is BlendFactor.OneMinusDstColor:
        return 1 - dst[c]
    if f is BlendFactor.OneMinusDstAlpha:
        return 1 - da
    # SrcAlphaSaturate
    return 1.0 if c == 3 else min(sa, 1 - da)


def blend_channel(op: BlendOp, s: float, d: float, fs: float, fd: float) -> float:
    if op is BlendOp.Add:
        return s * fs + d * fd
    if op is BlendOp.Sub:
        return s * fs - d * fd
    if op is BlendOp.RevSub:
        return d * fd - s * fs
    if op is BlendOp.Min:
        return min(s, d)
    return max(s, d)


class Buffers:
    """Colour (LDR codes or HDR float32 values), depth (ints) and stencil (ints), window rows (y up)."""

    def __init__(self, scene: DrawScene):
        cam = scene.camera
        self.W, self.H = int(cam.width), int(cam.height)
        self.hdr = bool(scene.hdr)
        self.linear = scene.color_space is ColorSpace.Linear
        clear = [float(c) for c in scene.clear_color]
        if self.linear:
            clear = [decode(c) for c in clear[:3]] + [clear[3]]
        stored = self.store(clear)
        self.color = [[list(stored) for _ in range(self.W)] for _ in range(self.H)]
        self.depth = [[DMAX] * self.W for _ in range(self.H)]
        self.stencil = [[0] * self.W for _ in range(self.H)]
        self.collect: list | None = None  # sorted reference: fragments kept instead of merged

    def store(self, rgba: list) -> list:
        """Shading-space rgba → the stored representation (§8 'write')."""
        if self.hdr:
            return [f32(v) for v in rgba]
        out = []
        for c, v in enumerate(rgba):
            v = clamp01(v)
            if self.linear and c < 3:
                v = encode(v)
            out.append(math.floor(v * 255 + 0.5))
        return out

    def load(self, stored: list) -> list:
        """Stored representation → destination value in shading space."""
        if self.hdr:
            return list(stored)
        out = []
        for c, q in enumerate(stored):
            v = q / 255
            if self.linear and c < 3:
                v = decode(v)
            out.append(v)
        return out

    def write_color(self, x: int, y: int, p, src: list) -> None:
        if not self.hdr:
            src = [clamp01(v) for v in src]
        old = self.color[y][x]
        if p.blend:
            dst = self.load(old)
            sfa, dfa, opa = p.alpha_factors
            result = []
            for c in range(4):
                sf, df, op = (p.src_blend, p.dst_blend, p.blend_op) if c < 3 else (sfa, dfa, opa)
                result.append(blend_channel(op, src[c], dst[c], factor(sf, c, src, dst), factor(df, c, src, dst)))
        else:
            result = src
        new = self.store(result)
        mask = p.color_mask
        self.color[y][x] = [new[c] if ch in mask else old[c] for c, ch in enumerate("RGBA")]

    def arrays(self):
        if self.hdr:
            color = np.array(self.color, dtype=np.float32)
        else:
            color = (np.array(self.color, dtype=np.int64) / 255.0).astype(np.float32)
        depth = (np.array(self.depth, dtype=np.int64) / DMAX).astype(np.float32)
        stencil = np.array(self.stencil, dtype=np.uint8)
        return color[::-1].copy(), depth[::-1].copy(), stencil[::-1].copy()


# ---------------------------------------------------------------- the frame


class FragmentLog:
    """What :func:`render_reference` did, for the frame debugger's tests.

    ``fragments``: one tuple per rasterised fragment, in the order applied:
    ``(draw, x, y, triangle, depth_code, rgba, result)`` with ``draw`` the 1-based draw call,
    ``y`` the window row (0 = bottom), ``triangle`` the index in the renderer's mesh, ``rgba``
    the shader's output (shading space) and ``result`` one of ``written``, ``alpha_test``,
    ``stencil``, ``depth``. ``triangles``: per draw call, the source triangles drawn (some
    clipped piece neither culled nor of zero area).
    """

    def __init__(self) -> None:
        self.fragments: list[tuple] = []
        self.triangles: dict[int, int] = {}

    def counts(self) -> dict[int, tuple[int, int]]:
        """Per draw call: (fragments rasterised, fragments written)."""
        out: dict[int, list[int]] = {}
        for draw, *_, result in self.fragments:
            c = out.setdefault(draw, [0, 0])
            c[0] += 1
            c[1] += result == "written"
        return {k: (v[0], v[1]) for k, v in out.items()}


def render_reference(scene: DrawScene, warnings: list | None = None, max_calls: int | None = None,
                     log: FragmentLog | None = None):
    """Render ``scene`` fragment by fragment; returns ``(color, depth, stencil)`` (row 0 = top).

    Warnings (skipped triangles, empty meshes) are appended to ``warnings`` when given;
    ``max_calls`` stops after that many draw calls (for locating a disagreement);
    ``log`` (a :class:`FragmentLog`) receives every fragment and the triangles per draw.
    """
    found = validate_scene(scene)
    if warnings is not None:
        warnings.extend(found)
    buf = Buffers(scene)
    cam = scene.camera
    V, P = to_list(cam.view_matrix), to_list(cam.projection)
    budget = [math.inf if max_calls is None else max_calls, 0]  # draws left, draws done
    for r in draw_list(scene):
        draw_renderer(scene, r, V, P, buf, warnings, budget, log)
    return buf.arrays()


def draw_renderer(scene, r, V, P, buf: Buffers, warnings, budget, log: FragmentLog | None = None) -> None:
    M = to_list(r.matrix_world)
    MVP = matmul4(P, matmul4(V, M))
    m = [row[:3] for row in M[:3]]
    C = [
        [
            m[(i + 1) % 3][(j + 1) % 3] * m[(i + 2) % 3][(j + 2) % 3]
            - m[(i + 1) % 3][(j + 2) % 3] * m[(i + 2) % 3][(j + 1) % 3]
            for j in range(3)
        ]
        for i in range(3)
    ]
    det = (m[0][0] * C[0][0] + m[0][1] * C[0][1]) + m[0][2] * C[0][2]
    N = C if det >= 0 else [[-c for c in row] for row in C]
    mirrored = det < 0

    positions = to_list(r.mesh.positions)
    triangles = np.asarray(r.mesh.triangles).tolist()
    normals = to_list(r.mesh.normals)
    uvs = to_list(r.mesh.uvs) if r.mesh.uvs is not None else None

    def clip_of(vtx):
        x, y, z = vtx
        return [((MVP[i][0] * x + MVP[i][1] * y) + MVP[i][2] * z) + MVP[i][3] for i in range(4)]

    # Vertex stage once per renderer: the same for every pass.
    prims = []  # per source triangle: (clipped triangles, uv corners, normal corners)
    skipped = 0
    for t, tri in enumerate(triangles):
        clips = [clip_of(positions[k]) for k in tri]
        if not all(math.isfinite(c) for v in clips for c in v):
            skipped += 1
            continue
        nws = [[(N[i][0] * n[0] + N[i][1] * n[1]) + N[i][2] * n[2] for i in range(3)] for n in normals[t]]
        uv = uvs[t] if uvs is not None else [[0.0, 0.0]] * 3
        unit = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0])
        verts = [clips[k] + list(unit[k]) for k in range(3)]
        prims.append((t, clip_triangle(verts), uv, nws))
    if skipped and warnings is not None:
        warnings.append(f"object {r.name!r} slot {r.slot}: {skipped} non-finite triangle(s) skipped")

    shader = Shader(scene, r.material)
    for p in r.material.draw_passes:
        if budget[0] <= 0:
            return
        budget[0] -= 1
        budget[1] += 1
        where = None if log is None else [budget[1], 0]
        drawn = 0
        for t, tris, uv, nws in prims:
            if where is not None:
                where[1] = t
            hit = False
            for tri in tris:
                hit = raster_triangle(tri, uv, nws, mirrored, p, shader, buf, log, where) or hit
            drawn += hit
        if log is not None:
            log.triangles[budget[1]] = drawn


def raster_triangle(tri, uv, nws, mirrored: bool, p, shader: Shader, buf: Buffers,
                    log: FragmentLog | None = None, where: list | None = None) -> bool:
    """Rasterise one (clipped) triangle; returns whether it was drawn (not culled, not zero-area)."""
    W, H = buf.W, buf.H
    # §3 viewport and snapping
    win = []
    for v in tri:
        x, y, z, w = v[0], v[1], v[2], v[3]
        iw = div(1.0, w)
        xn, yn, zn = x * iw, y * iw, z * iw
        xw = (xn * 0.5 + 0.5) * W
        yw = (yn * 0.5 + 0.5) * H
        zw = zn * 0.5 + 0.5
        win.append((math.floor(xw * S + 0.5), math.floor(yw * S + 0.5), zw, iw, v[4:7]))
    (X0, Y0, _, _, _), (X1, Y1, _, _, _), (X2, Y2, _, _, _) = win
    # §4 setup and culling
    area2 = (X1 - X0) * (Y2 - Y0) - (X2 - X0) * (Y1 - Y0)
    if area2 == 0:
        return False
    front = (area2 > 0) != mirrored
    if (p.cull is Cull.Back and not front) or (p.cull is Cull.Front and front):
        return False
    order = (0, 1, 2) if area2 > 0 else (0, 2, 1)
    a, b, c = (win[k] for k in order)
    Xa, Ya, Xb, Yb, Xc, Yc = a[0], a[1], b[0], b[1], c[0], c[1]
    A = float(abs(area2))

    def top_left(dx, dy):
        return dy < 0 or (dy == 0 and dx < 0)

    tl_a = top_left(Xc - Xb, Yc - Yb)
    tl_b = top_left(Xa - Xc, Ya - Yc)
    tl_c = top_left(Xb - Xa, Yb - Ya)

    # §5 polygon offset (per triangle)
    zws = [win[k][2] for k in range(3)]
    bias = 0.0
    use_offset = p.offset_factor != 0 or p.offset_units != 0
    if use_offset:
        x0, y0 = X0 / S, Y0 / S
        x1, y1 = X1 / S, Y1 / S
        x2, y2 = X2 / S, Y2 / S
        fa = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        dzdx = ((zws[1] - zws[0]) * (y2 - y0) - (zws[2] - zws[0]) * (y1 - y0)) / fa
        dzdy = ((zws[2] - zws[0]) * (x1 - x0) - (zws[1] - zws[0]) * (x2 - x0)) / fa
        bias = float(p.offset_factor) * max(abs(dzdx), abs(dzdy)) + float(p.offset_units) * 2**-24

    xs = (X0, X1, X2)
    ys = (Y0, Y1, Y2)
    xlo = max(0, (min(xs) - HALF) // S)
    xhi = min(W - 1, (max(xs) - HALF) // S + 1)
    ylo = max(0, (min(ys) - HALF) // S)
    yhi = min(H - 1, (max(ys) - HALF) // S + 1)
    for py in range(ylo, yhi + 1):
        Py = py * S + HALF
        for px in range(xlo, xhi + 1):
            Px = px * S + HALF
            Ea = (Xc - Xb) * (Py - Yb) - (Yc - Yb) * (Px - Xb)
            Eb = (Xa - Xc) * (Py - Yc) - (Ya - Yc) * (Px - Xc)
            Ec = (Xb - Xa) * (Py - Ya) - (Yb - Ya) * (Px - Xa)
            if not ((Ea > 0 or (Ea == 0 and tl_a)) and (Eb > 0 or (Eb == 0 and tl_b))
                    and (Ec > 0 or (Ec == 0 and tl_c))):
                continue
            ba, bb, bc = float(Ea) / A, float(Eb) / A, float(Ec) / A
            if area2 > 0:
                bw = (ba, bb, bc)
            else:  # order (v0, v2, v1): a = v0, b = v2, c = v1
                bw = (ba, bc, bb)
            fragment(px, py, bw, win, zws, bias, use_offset, uv, nws, p, shader, buf, log, where)
    return True


def lerp3(o: list, corners: list, n: int) -> list:
    """docs/pipeline.md §6: ``(o0*a0 + o1*a1) + o2*a2``, or the corner value when all three are equal."""
    if list(corners[0]) == list(corners[1]) == list(corners[2]):
        return [float(corners[0][c]) for c in range(n)]
    return [(o[0] * corners[0][c] + o[1] * corners[1][c]) + o[2] * corners[2][c] for c in range(n)]


def fragment(px, py, bw, win, zws, bias, use_offset, uv, nws, p, shader: Shader, buf: Buffers,
             log: FragmentLog | None = None, where: list | None = None) -> None:
    b0, b1, b2 = bw
    # §5 depth
    z = (b0 * zws[0] + b1 * zws[1]) + b2 * zws[2]
    if use_offset:
        z = z + bias
    z = min(max(z, 0.0), 1.0)
    d = math.floor(z * DMAX + 0.5)
    # §6 perspective-correct interpolation
    t = [bw[k] * win[k][3] for k in range(3)]
    s = (t[0] + t[1]) + t[2]
    pk = [div(tk, s) for tk in t]
    B = [win[k][4] for k in range(3)]
    o = [(pk[0] * B[0][j] + pk[1] * B[1][j]) + pk[2] * B[2][j] for j in range(3)]
    uvf = lerp3(o, uv, 2)
    nwf = lerp3(o, nws, 3)
    # §7 shading and alpha test
    rgba = shader.shade(uvf, nwf)
    if p.alpha_test and not alpha_survives(rgba[3], shader.cutoff, p.alpha_test_comp):
        result = "alpha_test"
    elif buf.collect is not None:  # sorted reference, step 2: kept for the per-pixel sort
        if p.color_mask:
            buf.collect.append((py, px, d, len(buf.collect), rgba, p))
        return
    else:
        result = merge_fragment(px, py, d, rgba, p, buf)
    if log is not None:
        log.fragments.append((where[0], px, py, where[1], d, rgba, result))


def alpha_survives(alpha: float, cutoff: float, comp: CompareFunction) -> bool:
    """``alpha <comp> cutoff``, one fragment: GEqual is ``clip(alpha - cutoff)`` (dies when the
    difference is negative), the others the legacy ``AlphaTest`` comparison of the two values."""
    if comp is CompareFunction.GEqual:
        return not alpha - cutoff < 0
    return {
        CompareFunction.Greater: alpha > cutoff, CompareFunction.Less: alpha < cutoff,
        CompareFunction.LEqual: alpha <= cutoff, CompareFunction.Equal: alpha == cutoff,
        CompareFunction.NotEqual: alpha != cutoff, CompareFunction.Always: True, CompareFunction.Never: False,
    }[comp]


def merge_fragment(px: int, py: int, d: int, rgba: list, p, buf: Buffers) -> str:
    """§8 output merger for one fragment at window pixel (px, py) with depth code ``d``;
    returns ``written`` or the test that discarded it (``stencil``, ``depth``)."""
    s_old = buf.stencil[py][px]
    if p.stencil:
        ref, rm, wm = p.stencil_ref, p.stencil_read_mask, p.stencil_write_mask

        def apply(op):
            buf.stencil[py][px] = (s_old & ~wm & 255) | (stencil_op(op, s_old, ref) & wm)

        if not compare(p.stencil_comp, ref & rm, s_old & rm):
            apply(p.stencil_fail)
            return "stencil"
    if not compare(p.ztest, d, buf.depth[py][px]):
        if p.stencil:
            apply(p.stencil_zfail)
        return "depth"
    if p.stencil:
        apply(p.stencil_pass)
    if p.zwrite:
        buf.depth[py][px] = d
    buf.write_color(px, py, p, rgba)
    return "written"


# ---------------------------------------------------------------- docs/sorting.md sorted reference


def render_sorted_reference(scene: DrawScene):
    """docs/sorting.md's sorted reference, one fragment at a time; returns ``(color, depth, stencil)``.

    Queues up to 2500 draw as usual; every fragment of queues 2501..3999 that survives culling
    and the alpha test (passes with ColorMask 0 left out: they write nothing) is kept, then
    the kept fragments are merged pixel by pixel far to near (larger depth code first; ties in
    draw order, then primitive order) with their pass state and no depth writes; Overlay
    (4000 and up) draws last as usual.
    """
    from dataclasses import replace

    validate_scene(scene)
    buf = Buffers(scene)
    cam = scene.camera
    V, P = to_list(cam.view_matrix), to_list(cam.projection)
    budget = [math.inf, 0]
    renderers = draw_list(scene)
    sorted_range = [r for r in renderers if LAST_OPAQUE_QUEUE < r.material.render_queue < 4000]
    for r in renderers:
        if r.material.render_queue <= LAST_OPAQUE_QUEUE:
            draw_renderer(scene, r, V, P, buf, None, budget)
    buf.collect = []
    for r in sorted_range:
        draw_renderer(scene, r, V, P, buf, None, budget)
    kept, buf.collect = buf.collect, None
    kept.sort(key=lambda f: (f[0], f[1], -f[2], f[3]))  # pixel, far first, then arrival order
    for py, px, d, _, rgba, p in kept:
        merge_fragment(px, py, d, rgba, replace(p, zwrite=False), buf)
    for r in renderers:
        if r.material.render_queue >= 4000:
            draw_renderer(scene, r, V, P, buf, None, budget)
    return buf.arrays()
