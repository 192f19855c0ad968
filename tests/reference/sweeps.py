"""Structured state sweeps: one scene per family that covers every value of a pass state.

Each builder returns a :class:`DrawScene` on the pixel-exact :func:`screen_camera`
(orthographic, world x/y = window pixels). Every quad has its edges on pixel
boundaries, so no pixel centre lies on an edge and the fill rule never decides
(GL and the spec then cover exactly the same pixels); depth is constant per quad.

- :func:`blend_sweep`: every src factor x dst factor x op (605 cells) for colour,
  and again every combination for alpha through ``separate_alpha``, over a
  random per-pixel destination.
- :func:`ztest_sweep`: every ZTest x ZWrite x (nearer, equal, farther).
- :func:`cull_sweep`: every Cull x facing x mirrored matrix.
- :func:`colormask_sweep`: all 16 ColorMask subsets, blended and not.
- :func:`stencil_sweep`: every comparison x every op in pass / fail / zfail, with masks.
- :func:`texture_sweep`: both filters x both wraps x three encodings x tiling/offset.
- :func:`alpha_test_sweep`, :func:`alpha_test_comp_sweep` (every comparison), :func:`offset_sweep`.
"""

from __future__ import annotations

import itertools

import numpy as np

from blendlib.core.scene import DrawScene
from blendlib.core.vocabulary import (
    CHANNELS,
    ZTEST_FUNCTIONS,
    BlendFactor,
    BlendOp,
    ColorSpace,
    CompareFunction,
    Cull,
    Lighting,
    Material,
    Pass,
    Queue,
    StencilOp,
    Texture,
    TextureFilter,
    TextureWrap,
)

from .scenes import make_mesh, quad, renderer, scale, screen_camera, translate

BLEND_COMBOS = list(itertools.product(BlendFactor, BlendFactor, BlendOp))  # 605


def _background(rng, w, h, lo=0.0, hi=1.0, z=-1.0, passes=None, encoding="Data") -> object:
    """A full-frame opaque quad with one random texel per pixel (Point sampling)."""
    px = rng.uniform(lo, hi, size=(h, w, 4)).astype(np.float32)
    tex = Texture(px, encoding=encoding, name="background")
    mat = Material(name="Background", queue=Queue.Background, main_tex=tex, lighting=Lighting.Unlit,
                   main_tex_filter=TextureFilter.Point, main_tex_wrap=TextureWrap.Clamp,
                   passes=tuple(passes or (Pass(),)))
    return renderer(quad(0, 0, w, h, z=z), mat, name="_background")


def _cells(count: int, cell: int = 2):
    """Grid of ``count`` cells of ``cell`` x ``cell`` pixels: (frame w, h, list of (x0, y0))."""
    cols = int(np.ceil(np.sqrt(count)))
    rows = int(np.ceil(count / cols))
    origins = [((k % cols) * cell, (k // cols) * cell) for k in range(count)]
    return cols * cell, rows * cell, origins


def _scene(w, h, renderers, **kw) -> DrawScene:
    kw.setdefault("clear_color", (0.19, 0.30, 0.47, 0.0))
    return DrawScene(camera=screen_camera(w, h), renderers=tuple(renderers), light=None, **kw)


def blend_sweep(color_space: ColorSpace = ColorSpace.Gamma, hdr: bool = False, seed: int = 1) -> DrawScene:
    rng = np.random.default_rng(seed)
    w, h, origins = _cells(len(BLEND_COMBOS))
    hi = 1.5 if hdr else 1.0
    rs = [_background(rng, w, h, 0.0, hi)]
    for k, ((sf, df, op), (x, y)) in enumerate(zip(BLEND_COMBOS, origins, strict=True)):
        sa, da, opa = BLEND_COMBOS[(k * 37 + 11) % len(BLEND_COMBOS)]
        p = Pass(blend=True, zwrite=False, src_blend=sf, dst_blend=df, blend_op=op,
                 separate_alpha=True, src_blend_alpha=sa, dst_blend_alpha=da, blend_op_alpha=opa)
        color = tuple(float(c) for c in rng.uniform(0.0, hi, 4))
        mat = Material(name=f"blend{k}", queue=Queue.Transparent, color=color, lighting=Lighting.Unlit, passes=(p,))
        rs.append(renderer(quad(x, y, x + 2, y + 2, z=0.0), mat, name=f"cell{k:04d}"))
    return _scene(w, h, rs, color_space=color_space, hdr=hdr)


def blend_sweep_plain(color_space: ColorSpace = ColorSpace.Gamma, hdr: bool = False, seed: int = 2) -> DrawScene:
    """Every factor x factor x op with the same state for alpha (``separate_alpha`` off)."""
    rng = np.random.default_rng(seed)
    w, h, origins = _cells(len(BLEND_COMBOS))
    hi = 1.5 if hdr else 1.0
    rs = [_background(rng, w, h, 0.0, hi)]
    for k, ((sf, df, op), (x, y)) in enumerate(zip(BLEND_COMBOS, origins, strict=True)):
        p = Pass(blend=True, zwrite=False, src_blend=sf, dst_blend=df, blend_op=op)
        color = tuple(float(c) for c in rng.uniform(0.0, hi, 4))
        mat = Material(name=f"blend{k}", queue=Queue.Transparent, color=color, lighting=Lighting.Unlit, passes=(p,))
        rs.append(renderer(quad(x, y, x + 2, y + 2, z=0.0), mat, name=f"cell{k:04d}"))
    return _scene(w, h, rs, color_space=color_space, hdr=hdr)


def ztest_sweep(seed: int = 3) -> DrawScene:
    """Background at z=0.123 writes depth; each cell draws a quad nearer / equal / farther with a ZTest."""
    rng = np.random.default_rng(seed)
    combos = list(itertools.product(ZTEST_FUNCTIONS, (True, False), (0.3, 0.0, -0.3)))
    w, h, origins = _cells(len(combos), cell=2)
    base = 0.123  # window depth 0.49385: away from the tie d*DMAX = n + 0.5 that z = 0 would hit
    rs = [_background(rng, w, h, z=base)]
    for k, ((zt, zw, dz), (x, y)) in enumerate(zip(combos, origins, strict=True)):
        color = tuple(float(c) for c in rng.uniform(0, 1, 4))
        # Two passes: the tested one, then a LEqual overlay that shows what the depth buffer holds.
        p1 = Pass(ztest=zt, zwrite=zw)
        p2 = Pass(ztest=CompareFunction.Equal, zwrite=False, blend=True, src_blend=BlendFactor.One,
                  dst_blend=BlendFactor.One, color_mask=frozenset("A"))
        mat = Material(name=f"z{k}", queue=Queue.Geometry, color=color, lighting=Lighting.Unlit, passes=(p1, p2))
        rs.append(renderer(quad(x, y, x + 2, y + 2, z=base + dz), mat, name=f"cell{k:04d}"))
    return _scene(w, h, rs)


def cull_sweep(seed: int = 4) -> DrawScene:
    """Every Cull x facing (quad wound CCW or CW) x mirrored matrix (scale -1 on x or z)."""
    rng = np.random.default_rng(seed)
    combos = list(itertools.product(Cull, (False, True), ("none", "x", "z", "xyz")))
    w, h, origins = _cells(len(combos), cell=3)
    rs = []
    for k, ((cull, flip, mirror), (x, y)) in enumerate(zip(combos, origins, strict=True)):
        color = tuple(float(c) for c in rng.uniform(0.2, 1, 3)) + (1.0,)
        m = quad(-1.5, -1.5, 1.5, 1.5, z=0.0)
        if flip:
            m = make_mesh(m.positions, m.triangles[:, ::-1], uvs=None)
        sx, sz = {"none": (1, 1), "x": (-1, 1), "z": (1, -1), "xyz": (-1, -1)}[mirror]
        sy = -1 if mirror == "xyz" else 1
        matrix = translate(x + 1.5, y + 1.5, 0.0) @ scale(sx, sy, sz)
        mat = Material(name=f"c{k}", color=color, lighting=Lighting.Unlit, passes=(Pass(cull=cull),))
        rs.append(renderer(m, mat, name=f"cell{k:04d}", matrix=matrix))
    return _scene(w, h, rs)


def colormask_sweep(color_space: ColorSpace = ColorSpace.Gamma, hdr: bool = False, seed: int = 5) -> DrawScene:
    rng = np.random.default_rng(seed)
    masks = [frozenset(c for i, c in enumerate(CHANNELS) if bits >> i & 1) for bits in range(16)]
    combos = list(itertools.product(masks, (False, True)))
    w, h, origins = _cells(len(combos))
    rs = [_background(rng, w, h)]
    for k, ((mask, blend), (x, y)) in enumerate(zip(combos, origins, strict=True)):
        p = Pass(color_mask=mask, blend=blend, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha)
        color = tuple(float(c) for c in rng.uniform(0, 1, 4))
        mat = Material(name=f"m{k}", queue=Queue.Transparent, color=color, lighting=Lighting.Unlit, passes=(p,))
        rs.append(renderer(quad(x, y, x + 2, y + 2, z=0.0), mat, name=f"cell{k:04d}"))
    return _scene(w, h, rs, color_space=color_space, hdr=hdr)


def stencil_sweep(seed: int = 6) -> DrawScene:
    """Every comparison x op (as pass, fail and zfail op): a writer sets the stencil, a tester reads it.

    Each cell: pass A (stencil Replace with ref ``a``) writes a known value; pass B with the tested
    comparison/op and ref/masks, half the cells behind the background depth (zfail path).
    The stencil buffer and a colour write show the outcome.
    """
    rng = np.random.default_rng(seed)
    combos = list(itertools.product(CompareFunction, StencilOp, (False, True)))
    w, h, origins = _cells(len(combos))
    rs = [_background(rng, w, h, z=0.0, passes=[Pass()])]
    for k, ((comp, op, behind), (x, y)) in enumerate(zip(combos, origins, strict=True)):
        a = int(rng.integers(0, 256))
        ref = int(rng.choice([a, (a + 1) & 255, (a - 1) & 255, int(rng.integers(0, 256))]))
        read = int(rng.choice([255, 0x0F, 0xF0, int(rng.integers(0, 256))]))
        write = int(rng.choice([255, 0x3C, int(rng.integers(0, 256))]))
        ops = [StencilOp.Keep] * 3
        ops[k % 3] = op
        writer = Pass(stencil=True, stencil_ref=a, stencil_comp=CompareFunction.Always,
                      stencil_pass=StencilOp.Replace, stencil_zfail=StencilOp.Replace,
                      ztest=CompareFunction.Always, zwrite=False, color_mask=frozenset())
        tester = Pass(stencil=True, stencil_ref=ref, stencil_read_mask=read, stencil_write_mask=write,
                      stencil_comp=comp, stencil_pass=ops[0], stencil_fail=ops[1], stencil_zfail=ops[2],
                      zwrite=False)
        color = tuple(float(c) for c in rng.uniform(0, 1, 4))
        mat = Material(name=f"s{k}", queue=Queue.Transparent, color=color, lighting=Lighting.Unlit,
                       passes=(writer, tester))
        rs.append(renderer(quad(x, y, x + 2, y + 2, z=-0.5 if behind else 0.5), mat, name=f"cell{k:04d}"))
    return _scene(w, h, rs)


def texture_sweep(color_space: ColorSpace = ColorSpace.Gamma, hdr: bool = False, seed: int = 7) -> DrawScene:
    """Both filters x both wraps x three encodings x two texture sizes, tiled and offset."""
    rng = np.random.default_rng(seed)
    combos = list(itertools.product(TextureFilter, TextureWrap, ("sRGB", "Linear", "Data"), ((1, 3), (4, 2))))
    cell = 8
    w, h, origins = _cells(len(combos), cell=cell)
    rs = []
    for k, ((filt, wrap, enc, (tw, th)), (x, y)) in enumerate(zip(combos, origins, strict=True)):
        tex = Texture(rng.uniform(0, 1, size=(th, tw, 4)).astype(np.float32), encoding=enc, name=f"t{k}")
        mat = Material(name=f"t{k}", color=(1, 1, 1, 1), main_tex=tex, main_tex_filter=filt, main_tex_wrap=wrap,
                       main_tex_tiling=(1.7, -1.3), main_tex_offset=(0.23, 0.61), lighting=Lighting.Unlit)
        rs.append(renderer(quad(x, y, x + cell, y + cell, z=0.0), mat, name=f"cell{k:04d}"))
    return _scene(w, h, rs, color_space=color_space, hdr=hdr)


def alpha_test_sweep(seed: int = 8) -> DrawScene:
    """Textured quads with alpha ramps against several cutoffs (values kept away from the cutoff)."""
    rng = np.random.default_rng(seed)
    cutoffs = [0.0, 0.25, 0.5, 0.75, 1.0]
    cell = 4
    w, h, origins = _cells(len(cutoffs) * 2, cell=cell)
    rs = [_background(rng, w, h, z=-1.0)]
    for k, (x, y) in enumerate(origins):
        cutoff = cutoffs[k % len(cutoffs)]
        alphas = np.array([0.1, 0.3, 0.6, 0.9, 1.0, 0.05, 0.4, 0.8], dtype=np.float32)
        px = np.ones((cell, cell, 4), np.float32)
        px[..., 3] = rng.choice(alphas, size=(cell, cell))
        px[..., :3] = rng.uniform(0, 1, size=(cell, cell, 3))
        tex = Texture(px, encoding="Data")
        mat = Material(name=f"a{k}", main_tex=tex, main_tex_filter=TextureFilter.Point, cutoff=cutoff,
                       lighting=Lighting.Unlit, alpha_scale=1.0 if k < len(cutoffs) else 0.5,
                       passes=(Pass(alpha_test=True),))
        rs.append(renderer(quad(x, y, x + cell, y + cell, z=0.0), mat, name=f"cell{k:04d}"))
    return _scene(w, h, rs)


def alpha_test_comp_sweep(seed: int = 10) -> DrawScene:
    """Every alpha-test comparison x cutoff, on texels whose alpha is below, equal to or above the
    cutoff (values exact in float32 and float64, so Equal and the boundaries are decided alike)."""
    rng = np.random.default_rng(seed)
    cutoffs = [0.0, 0.25, 0.5, 1.0]
    combos = list(itertools.product(CompareFunction, cutoffs))
    cell = 4
    w, h, origins = _cells(len(combos), cell=cell)
    rs = [_background(rng, w, h, z=-1.0)]
    alphas = np.array([0.0, 0.125, 0.25, 0.375, 0.5, 0.75, 1.0], dtype=np.float32)
    for k, ((comp, cutoff), (x, y)) in enumerate(zip(combos, origins, strict=True)):
        px = np.ones((cell, cell, 4), np.float32)
        px[..., 3] = rng.choice(alphas, size=(cell, cell))
        px[..., :3] = rng.uniform(0, 1, size=(cell, cell, 3))
        mat = Material(name=f"c{k}", main_tex=Texture(px, encoding="Data"), main_tex_filter=TextureFilter.Point,
                       cutoff=cutoff, lighting=Lighting.Unlit, passes=(Pass(alpha_test=True, alpha_test_comp=comp),))
        rs.append(renderer(quad(x, y, x + cell, y + cell, z=0.0), mat, name=f"cell{k:04d}"))
    return _scene(w, h, rs)


def offset_sweep(seed: int = 9) -> DrawScene:
    """Polygon offset units on coincident quads: a base quad, then one with Offset 0,u and ZTest Less/LEqual."""
    rng = np.random.default_rng(seed)
    combos = list(itertools.product((-2.0, -1.0, 0.0, 1.0, 2.0), (CompareFunction.Less, CompareFunction.LEqual,
                                                                   CompareFunction.Greater)))
    w, h, origins = _cells(len(combos))
    rs = []
    for k, ((units, zt), (x, y)) in enumerate(zip(combos, origins, strict=True)):
        base = Material(name=f"b{k}", queue=Queue.Geometry, color=(0.2, 0.2, 0.2, 1.0), lighting=Lighting.Unlit)
        color = tuple(float(c) for c in rng.uniform(0.3, 1, 3)) + (1.0,)
        top = Material(name=f"o{k}", queue=Queue.Transparent, color=color, lighting=Lighting.Unlit,
                       passes=(Pass(offset_units=units, ztest=zt, zwrite=True),))
        rs.append(renderer(quad(x, y, x + 2, y + 2, z=0.37), base, name=f"base{k:04d}"))
        rs.append(renderer(quad(x, y, x + 2, y + 2, z=0.37), top, name=f"cell{k:04d}"))
    return _scene(w, h, rs)


SWEEPS = {
    "blend_gamma_ldr": lambda: blend_sweep(ColorSpace.Gamma, False),
    "blend_linear_ldr": lambda: blend_sweep(ColorSpace.Linear, False),
    "blend_gamma_hdr": lambda: blend_sweep(ColorSpace.Gamma, True),
    "blend_linear_hdr": lambda: blend_sweep(ColorSpace.Linear, True),
    "blend_plain_gamma_ldr": lambda: blend_sweep_plain(ColorSpace.Gamma, False),
    "blend_plain_linear_ldr": lambda: blend_sweep_plain(ColorSpace.Linear, False),
    "blend_plain_hdr": lambda: blend_sweep_plain(ColorSpace.Gamma, True),
    "ztest": ztest_sweep,
    "cull": cull_sweep,
    "colormask_gamma_ldr": lambda: colormask_sweep(ColorSpace.Gamma, False),
    "colormask_linear_ldr": lambda: colormask_sweep(ColorSpace.Linear, False),
    "colormask_hdr": lambda: colormask_sweep(ColorSpace.Gamma, True),
    "stencil": stencil_sweep,
    "texture_gamma": lambda: texture_sweep(ColorSpace.Gamma, False),
    "texture_linear": lambda: texture_sweep(ColorSpace.Linear, False),
    "texture_linear_hdr": lambda: texture_sweep(ColorSpace.Linear, True),
    "alpha_test": alpha_test_sweep,
    "alpha_test_comp": alpha_test_comp_sweep,
    "offset": offset_sweep,
}
