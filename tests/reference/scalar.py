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

import numpy as np

from blendlib.core.drawlist import pixel_lights
from blendlib.core.scene import DrawScene, validate_scene
from blendlib.core.vocabulary import (
    LAST_OPAQUE_QUEUE,
    ONCE,
    PER_LIGHT,
    BlendFactor,
    BlendOp,
    ColorSpace,
    CompareFunction,
    Cull,
    OutlineMode,
    Pass,
    SortMode,
    StencilOp,
    VertexColor,
    pass_draws,
)

from . import scalar_shading as sh
from .scalar_shading import Shader, decode, div, encode, f32, to_list  # noqa: F401  (the reference's helpers)

S = 256  # sub-pixel steps per pixel
HALF = S // 2
DMAX = 2**24 - 1
GUARD = 4.0


# ---------------------------------------------------------------- small helpers










def clamp01(x: float) -> float:
    return min(max(x, 0.0), 1.0)


def matmul4(a, b):
    return [
        [((a[i][0] * b[0][j] + a[i][1] * b[1][j]) + a[i][2] * b[2][j]) + a[i][3] * b[3][j] for j in range(4)]
        for i in range(4)
    ]




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
    """Colour (LDR codes or HDR float32 values), depth (ints) and stencil (ints), window rows (y up).

    ``color[y][x]``, ``depth[y][x]``, ``stencil[y][x]``: the pixel; with MSAA (``samples`` N > 1)
    a list of its N samples (docs/pipeline.md §10), resolved by :meth:`arrays`."""

    def __init__(self, scene: DrawScene):
        cam = scene.camera
        self.W, self.H = int(cam.width), int(cam.height)
        self.hdr = bool(scene.hdr)
        self.linear = scene.color_space is ColorSpace.Linear
        self.samples = int(scene.msaa)
        clear = [float(c) for c in scene.clear_color]
        if self.linear:
            clear = [decode(c) for c in clear[:3]] + [clear[3]]
        stored = self.store(clear)
        n = self.samples

        def cell(value):
            return value() if n == 1 else [value() for _ in range(n)]

        self.color = [[cell(lambda: list(stored)) for _ in range(self.W)] for _ in range(self.H)]
        self.depth = [[cell(lambda: DMAX) for _ in range(self.W)] for _ in range(self.H)]
        self.stencil = [[cell(lambda: 0) for _ in range(self.W)] for _ in range(self.H)]
        self.collect: list | None = None  # sorted reference: fragments kept instead of merged

    def get(self, grid: list, x: int, y: int, s: int):
        """Sample ``s`` of pixel (x, y) of ``grid`` (the pixel itself without MSAA)."""
        return grid[y][x] if self.samples == 1 else grid[y][x][s]

    def put(self, grid: list, x: int, y: int, s: int, value) -> None:
        if self.samples == 1:
            grid[y][x] = value
        else:
            grid[y][x][s] = value

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

    def write_color(self, x: int, y: int, p, src: list, s: int = 0) -> None:
        if not self.hdr:
            src = [clamp01(v) for v in src]
        old = self.get(self.color, x, y, s)
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
        self.put(self.color, x, y, s, [new[c] if ch in mask else old[c] for c, ch in enumerate("RGBA")])

    def resolved(self, x: int, y: int) -> list:
        """The stored pixel (x, y); with MSAA its samples resolved (docs/pipeline.md §10): a
        float32 sum from 0 in sample order times float32(1/N) — LDR of ``float32(q) * float32(1/255)``
        (Linear rgb: of ``float32(decode(q/255))``), rounded half to even after ``* 255`` (Linear
        rgb: encoded exactly) — numpy float32 scalars doing the float32 arithmetic."""
        if self.samples == 1:
            return self.color[y][x]
        f = np.float32
        out = []
        for c in range(4):
            acc = f(0.0)
            for sample in self.color[y][x]:
                q = sample[c]
                if self.hdr:
                    v = f(q)
                elif self.linear and c < 3:
                    v = f(decode(q / 255))
                else:
                    v = f(q) * f(1.0 / 255.0)
                acc = acc + v
            avg = acc * f(1.0 / self.samples)
            if self.hdr:
                out.append(float(avg))
            elif self.linear and c < 3:
                out.append(math.floor(encode(clamp01(float(avg))) * 255 + 0.5))
            else:
                out.append(round(float(avg * f(255.0))))  # round half to even
        return out

    def arrays(self):
        """(color, depth, stencil) row 0 = top; with MSAA the resolved colour and sample 0's depth
        and stencil (what GL's blit of a multisampled depth-stencil buffer keeps)."""
        pixels = [[self.resolved(x, y) for x in range(self.W)] for y in range(self.H)]
        if self.hdr:
            color = np.array(pixels, dtype=np.float32)
        else:
            color = (np.array(pixels, dtype=np.int64) / 255.0).astype(np.float32)
        depth = [[self.get(self.depth, x, y, 0) for x in range(self.W)] for y in range(self.H)]
        stencil = [[self.get(self.stencil, x, y, 0) for x in range(self.W)] for y in range(self.H)]
        depth = (np.array(depth, dtype=np.int64) / DMAX).astype(np.float32)
        stencil = np.array(stencil, dtype=np.uint8)
        return color[::-1].copy(), depth[::-1].copy(), stencil[::-1].copy()


# ---------------------------------------------------------------- the frame


class FragmentLog:
    """What :func:`render_reference` did, for the frame debugger's tests.

    ``fragments``: one tuple per rasterised fragment, in the order applied:
    ``(draw, x, y, triangle, depth_code, rgba, result)`` with ``draw`` the 1-based draw call,
    ``y`` the window row (0 = bottom), ``triangle`` the index in the renderer's mesh, ``rgba``
    the shader's output (shading space) and ``result`` one of ``written``, ``alpha_test``,
    ``stencil``, ``depth``. With MSAA, ``(draw, x, y, triangle, codes, rgba, results,
    coverage)``: ``codes`` and ``results`` dicts by covered sample (``alpha_to_mask`` a result
    too), ``coverage`` the rasteriser's mask. ``triangles``: per draw call, the source
    triangles drawn (some clipped piece neither culled nor of zero area).
    """

    def __init__(self) -> None:
        self.fragments: list[tuple] = []
        self.triangles: dict[int, int] = {}

    def counts(self) -> dict[int, tuple[int, int]]:
        """Per draw call: (fragments rasterised, fragments written: with MSAA, those with a sample written)."""
        out: dict[int, list[int]] = {}
        for draw, _, _, _, _, _, result, *_ in self.fragments:
            c = out.setdefault(draw, [0, 0])
            c[0] += 1
            c[1] += "written" in result.values() if isinstance(result, dict) else result == "written"
        return {k: (v[0], v[1]) for k, v in out.items()}

    def samples_written(self) -> dict[int, int]:
        """Per draw call with MSAA: the samples written (what GL's occlusion query counts)."""
        out: dict[int, int] = {}
        for draw, _, _, _, _, _, results, _ in self.fragments:
            out[draw] = out.get(draw, 0) + sum(r == "written" for r in results.values())
        return out


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


def renderer_calls(scene, r) -> list:
    """The draw calls of renderer ``r`` as (pass, light): its passes in order as the forward path
    draws them (:func:`pass_draws`), a ForwardAdd pass once per per-pixel light (:func:`pixel_lights`)."""
    passes = r.material.draw_passes
    calls = []
    for p in passes:
        how, _ = pass_draws(p, passes)
        if how == ONCE:
            calls.append((p, None))
        elif how == PER_LIGHT:
            calls.extend((p, light) for light in pixel_lights(scene, r))
    return calls


def corner_colors(scene, mesh) -> list | None:
    """The mesh's corner vertex colours in shading space (§7: converted as texels are), or None."""
    if mesh.colors is None:
        return None
    linear = scene.color_space is ColorSpace.Linear
    if mesh.color_encoding == "sRGB":
        conv = decode if linear else (lambda c: c)
    else:
        conv = (lambda c: c) if linear else encode
    return [[[conv(c[0]), conv(c[1]), conv(c[2]), c[3]] for c in tri]
            for tri in to_list(np.asarray(mesh.colors, dtype=np.float32))]


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
    colors = corner_colors(scene, r.mesh) if r.material.vertex_color is not VertexColor.Off else None

    def clip_of(vtx):
        x, y, z = vtx
        return [((MVP[i][0] * x + MVP[i][1] * y) + MVP[i][2] * z) + MVP[i][3] for i in range(4)]

    def world_of(vtx):  # §1's world position (a ForwardAdd draw's point or spot light reads it)
        x, y, z = vtx
        return [((M[i][0] * x + M[i][1] * y) + M[i][2] * z) + M[i][3] for i in range(3)]

    def vertex_stage(p):
        """Per source triangle: (index, clipped triangles, whether clipped, corner attributes)."""
        prims = []
        skipped = 0
        for t, tri in enumerate(triangles):
            if p.outline_mode is OutlineMode.Off:
                clips = [clip_of(positions[k]) for k in tri]
            else:  # the outline vertex program, per corner
                clips = [sh.outline_clip(p, positions[k], normals[t][c], M, V, P,
                                         sh.width_factor(r.material, uvs[t][c] if uvs is not None else [0.0, 0.0],
                                                         scene.color_space is ColorSpace.Linear))
                         for c, k in enumerate(tri)]
            if not all(math.isfinite(c) for v in clips for c in v):
                skipped += 1
                continue
            nws = [[(N[i][0] * n[0] + N[i][1] * n[1]) + N[i][2] * n[2] for i in range(3)] for n in normals[t]]
            attrs = {"uv": uvs[t] if uvs is not None else [[0.0, 0.0]] * 3, "nw": nws,
                     "vc": None if colors is None else colors[t], "wp": [world_of(positions[k]) for k in tri]}
            unit = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0])
            verts = [clips[k] + list(unit[k]) for k in range(3)]
            clipped = clip_triangle(verts)
            prims.append((t, clipped, not (len(clipped) == 1 and clipped[0] is verts), attrs))
        return prims, skipped

    # Vertex stage once per vertex program: the same for every pass with it.
    stages = {}
    plain, skipped = vertex_stage(Pass())
    stages[None] = plain
    if skipped and warnings is not None:
        warnings.append(f"object {r.name!r} slot {r.slot}: {skipped} non-finite triangle(s) skipped")

    shader = Shader(scene, r.material)
    linear = scene.color_space is ColorSpace.Linear
    for p, light in renderer_calls(scene, r):
        if budget[0] <= 0:
            return
        budget[0] -= 1
        budget[1] += 1
        where = None if log is None else [budget[1], 0]
        key = None if p.outline_mode is OutlineMode.Off else (p.outline_mode, p.outline_formula,
                                                               p.outline_width, p.outline_max_distance)
        if key not in stages:
            stages[key] = vertex_stage(p)[0]
        shader.for_light(light, linear).for_pass(p)
        drawn = 0
        for t, tris, clipped, attrs in stages[key]:
            if where is not None:
                where[1] = t
            hit = False
            for tri in tris:
                hit = raster_triangle(tri, attrs, clipped, mirrored, p, shader, buf, log, where) or hit
            drawn += hit
        if log is not None:
            log.triangles[budget[1]] = drawn


def raster_triangle(tri, attrs, clipped: bool, mirrored: bool, p, shader: Shader, buf: Buffers,
                    log: FragmentLog | None = None, where: list | None = None) -> bool:
    """Rasterise one (clipped) triangle with its source triangle's corner attributes ``attrs``;
    returns whether it was drawn (not culled, not zero-area)."""
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

    def uv_at(qx: int, qy: int) -> tuple[float, float]:
        """Texture coordinates at pixel centre (qx, qy), covered or not (§7 "Mipmaps": helper
        pixels): §4's edge functions over the signed area, §6's weights and interpolation."""
        Qx, Qy = qx * S + HALF, qy * S + HALF
        sign = 1 if area2 > 0 else -1
        Xs, Ys = (X0, X1, X2), (Y0, Y1, Y2)
        bary = []
        for k in range(3):
            a, b = (k + 1) % 3, (k + 2) % 3
            e = (Xs[b] - Xs[a]) * (Qy - Ys[a]) - (Ys[b] - Ys[a]) * (Qx - Xs[a])
            bary.append(float(e * sign) / A)
        t = [bary[k] * win[k][3] for k in range(3)]
        s_ = (t[0] + t[1]) + t[2]
        o = [div(tk, s_) for tk in t]
        if clipped:
            B = [win[k][4] for k in range(3)]
            o = [(o[0] * B[0][j] + o[1] * B[1][j]) + o[2] * B[2][j] for j in range(3)]
        return shader.texture_uv(lerp3(o, attrs["uv"], 2))

    def edges(Px, Py):
        Ea = (Xc - Xb) * (Py - Yb) - (Yc - Yb) * (Px - Xb)
        Eb = (Xa - Xc) * (Py - Yc) - (Ya - Yc) * (Px - Xc)
        Ec = (Xb - Xa) * (Py - Ya) - (Yb - Ya) * (Px - Xa)
        return Ea, Eb, Ec

    def inside(Ea, Eb, Ec) -> bool:
        return ((Ea > 0 or (Ea == 0 and tl_a)) and (Eb > 0 or (Eb == 0 and tl_b))
                and (Ec > 0 or (Ec == 0 and tl_c)))

    def weights(Ea, Eb, Ec):
        ba, bb, bc = float(Ea) / A, float(Eb) / A, float(Ec) / A
        if area2 > 0:
            return (ba, bb, bc)
        return (ba, bc, bb)  # order (v0, v2, v1): a = v0, b = v2, c = v1

    xs = (X0, X1, X2)
    ys = (Y0, Y1, Y2)
    margin = 0 if buf.samples == 1 else 1  # samples lie up to half a pixel from the centre
    xlo = max(0, (min(xs) - HALF) // S - margin)
    xhi = min(W - 1, (max(xs) - HALF) // S + 1 + margin)
    ylo = max(0, (min(ys) - HALF) // S - margin)
    yhi = min(H - 1, (max(ys) - HALF) // S + 1 + margin)
    positions = sample_positions(buf.samples)
    for py in range(ylo, yhi + 1):
        for px in range(xlo, xhi + 1):
            if buf.samples == 1:
                centre = edges(px * S + HALF, py * S + HALF)
                if inside(*centre):
                    fragment(px, py, weights(*centre), win, zws, bias, use_offset, attrs, p, shader, buf, log, where,
                             uv_at)
                continue
            # MSAA (docs/pipeline.md §10): each sample tested at its position; the pixel is shaded
            # once at its centre (inside the triangle or not) and has a depth per covered sample.
            at_samples = {}
            for k, (ox, oy) in enumerate(positions):
                e = edges(px * S + ox, py * S + oy)
                if inside(*e):
                    at_samples[k] = weights(*e)
            if at_samples:
                centre = weights(*edges(px * S + HALF, py * S + HALF))
                fragment(px, py, centre, win, zws, bias, use_offset, attrs, p, shader, buf, log, where, uv_at,
                         at_samples)
    return True


def sample_positions(samples: int) -> list:
    """docs/pipeline.md §10: the standard sample positions in sub-pixels from the pixel's lower-left
    corner, y up (1/16-pixel tables times 16); sample k is bit k of a coverage mask."""
    table = {
        1: [(8, 8)],
        2: [(12, 12), (4, 4)],
        4: [(6, 2), (14, 6), (2, 10), (10, 14)],
        8: [(9, 5), (7, 11), (13, 9), (5, 3), (3, 13), (1, 7), (11, 15), (15, 1)],
    }[samples]
    return [(x * 16, y * 16) for x, y in table]


def lerp3(o: list, corners: list, n: int) -> list:
    """docs/pipeline.md §6: ``(o0*a0 + o1*a1) + o2*a2``, or the corner value when all three are equal."""
    if list(corners[0]) == list(corners[1]) == list(corners[2]):
        return [float(corners[0][c]) for c in range(n)]
    return [(o[0] * corners[0][c] + o[1] * corners[1][c]) + o[2] * corners[2][c] for c in range(n)]


def quad_lod(px: int, py: int, uv_at, w: int, h: int) -> float:
    """§7 "Mipmaps": the LOD of the 2x2 quad of pixel (px, py) (y up) for a w x h base level."""
    x0, y0 = px & ~1, py & ~1
    u00, v00 = uv_at(x0, y0)
    u10, v10 = uv_at(x0 + 1, y0)
    u01, v01 = uv_at(x0, y0 + 1)
    a, b = (u10 - u00) * w, (v10 - v00) * h
    rx = a * a + b * b
    a, b = (u01 - u00) * w, (v01 - v00) * h
    ry = a * a + b * b
    return sh.log2_lod(sh.nmax(rx, ry))


def depth_code(bw, zws, bias, use_offset) -> int:
    """§5: the 24-bit depth code at screen barycentrics ``bw``."""
    b0, b1, b2 = bw
    z = (b0 * zws[0] + b1 * zws[1]) + b2 * zws[2]
    if use_offset:
        z = z + bias
    z = min(max(z, 0.0), 1.0)
    return math.floor(z * DMAX + 0.5)


def fragment(px, py, bw, win, zws, bias, use_offset, attrs, p, shader: Shader, buf: Buffers,
             log: FragmentLog | None = None, where: list | None = None, uv_at=None,
             at_samples: dict | None = None) -> None:
    """One fragment at window pixel (px, py), screen barycentrics ``bw`` at its centre; with MSAA
    ``at_samples`` {covered sample: its barycentrics}."""
    if at_samples is not None:
        sample_fragment(px, py, bw, win, zws, bias, use_offset, attrs, p, shader, buf, log, where, uv_at,
                        at_samples)
        return
    # §5 depth
    d = depth_code(bw, zws, bias, use_offset)
    rgba = shade_at(px, py, bw, win, attrs, shader, uv_at)
    if p.alpha_test and not alpha_survives(rgba[3], shader.cutoff, p.alpha_test_comp):
        result = "alpha_test"
    elif buf.collect is not None:  # sorted reference, step 2: kept for the per-pixel sort
        if p.color_mask:
            buf.collect.append((py, px, 0, d, len(buf.collect), rgba, p))
        return
    else:
        result = merge_fragment(px, py, d, rgba, p, buf)
    if log is not None:
        log.fragments.append((where[0], px, py, where[1], d, rgba, result))


def shade_at(px, py, bw, win, attrs, shader: Shader, uv_at) -> list:
    """§6 perspective-correct interpolation at screen barycentrics ``bw`` of pixel (px, py), then
    §7 shading (the LOD of its quad through ``uv_at`` when the texture has mipmaps)."""
    t = [bw[k] * win[k][3] for k in range(3)]
    s = (t[0] + t[1]) + t[2]
    pk = [div(tk, s) for tk in t]
    B = [win[k][4] for k in range(3)]
    o = [(pk[0] * B[0][j] + pk[1] * B[1][j]) + pk[2] * B[2][j] for j in range(3)]
    uvf = lerp3(o, attrs["uv"], 2)
    nwf = lerp3(o, attrs["nw"], 3)
    vcf = None if attrs["vc"] is None else lerp3(o, attrs["vc"], 4)
    wpf = lerp3(o, attrs["wp"], 3) if shader.lambert and shader.add is not None else None
    lod = None
    if shader.mips is not None:
        lod = quad_lod(px, py, uv_at, shader.tw, shader.th)
    return shader.shade(uvf, nwf, vcf, wpf, lod)


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


def alpha_to_mask(alpha: float, samples: int) -> int:
    """docs/pipeline.md §10 (llvmpipe's rule): sample s of N covered when alpha > s/N."""
    return sum(1 << s for s in range(samples) if alpha > s / samples)


def sample_fragment(px, py, bw, win, zws, bias, use_offset, attrs, p, shader: Shader, buf: Buffers,
                    log: FragmentLog | None, where: list | None, uv_at, at_samples: dict) -> None:
    """docs/pipeline.md §10: a fragment covering samples ``at_samples`` {sample: barycentrics}:
    shaded once with the centre's barycentrics ``bw``, alpha-tested once; AlphaToMask drops
    samples; each remaining sample goes through the merger with its own depth."""
    rgba = shade_at(px, py, bw, win, attrs, shader, uv_at)
    codes = {k: depth_code(w, zws, bias, use_offset) for k, w in at_samples.items()}
    coverage = sum(1 << k for k in at_samples)
    results = {}
    if p.alpha_test and not alpha_survives(rgba[3], shader.cutoff, p.alpha_test_comp):
        results = {k: "alpha_test" for k in at_samples}
    elif buf.collect is not None:  # sorted reference, step 2: each sample reached kept for its own sort
        keep = coverage & alpha_to_mask(rgba[3], buf.samples) if p.alpha_to_mask else coverage
        if p.color_mask:
            buf.collect.extend((py, px, k, codes[k], len(buf.collect) + j, rgba, p)
                               for j, k in enumerate(k for k in sorted(at_samples) if keep >> k & 1))
        return
    else:
        keep = coverage & alpha_to_mask(rgba[3], buf.samples) if p.alpha_to_mask else coverage
        for k in sorted(at_samples):
            results[k] = merge_fragment(px, py, codes[k], rgba, p, buf, k) if keep >> k & 1 else "alpha_to_mask"
    if log is not None:
        log.fragments.append((where[0], px, py, where[1], codes, rgba, results, coverage))


def merge_fragment(px: int, py: int, d: int, rgba: list, p, buf: Buffers, sample: int = 0) -> str:
    """§8 output merger for one fragment at window pixel (px, py) (its ``sample`` with MSAA) with
    depth code ``d``; returns ``written`` or the test that discarded it (``stencil``, ``depth``)."""
    s_old = buf.get(buf.stencil, px, py, sample)
    if p.stencil:
        ref, rm, wm = p.stencil_ref, p.stencil_read_mask, p.stencil_write_mask

        def apply(op):
            buf.put(buf.stencil, px, py, sample, (s_old & ~wm & 255) | (stencil_op(op, s_old, ref) & wm))

        if not compare(p.stencil_comp, ref & rm, s_old & rm):
            apply(p.stencil_fail)
            return "stencil"
    if not compare(p.ztest, d, buf.get(buf.depth, px, py, sample)):
        if p.stencil:
            apply(p.stencil_zfail)
        return "depth"
    if p.stencil:
        apply(p.stencil_pass)
    if p.zwrite:
        buf.put(buf.depth, px, py, sample, d)
    buf.write_color(px, py, p, rgba, sample)
    return "written"


# ---------------------------------------------------------------- docs/sorting.md sorted reference


def render_sorted_reference(scene: DrawScene):
    """docs/sorting.md's sorted reference, one fragment at a time; returns ``(color, depth, stencil)``.

    Queues up to 2500 draw as usual; every fragment of queues 2501..3999 that survives culling
    and the alpha test (passes with ColorMask 0 left out: they write nothing) is kept, then
    the kept fragments are merged pixel by pixel far to near (larger depth code first; ties in
    draw order, then primitive order) with their pass state and no depth writes; Overlay
    (4000 and up) draws last as usual. With MSAA every sample a fragment reaches (covered and
    past AlphaToMask) is kept with that sample's depth code and sorted with the sample's others.
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
    kept.sort(key=lambda f: (f[0], f[1], f[2], -f[3], f[4]))  # sample, far first, then arrival order
    for py, px, sample, d, _, rgba, p in kept:
        merge_fragment(px, py, d, rgba, replace(p, zwrite=False), buf, sample)
    for r in renderers:
        if r.material.render_queue >= 4000:
            draw_renderer(scene, r, V, P, buf, None, budget)
    return buf.arrays()
