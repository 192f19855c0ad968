"""Structured sweeps of SPEC §12's shading features and the outline vertex program: one scene per
family that covers every value of the new enums.

- :func:`light_sweep`: ForwardAdd passes (``Blend One One`` and ``Blend SrcAlpha One``) under a
  directional, two point and a spot light, Lambert and Unlit materials, smooth and flat normals.
- :func:`vertex_color_sweep`: every ``VertexColor`` x colour encoding x texture or none x Lambert
  or Unlit, colours varying per corner (and one colour per triangle), a mesh without colours.
- :func:`mip_sweep`: a receding textured plane (LOD from 0 to the last level) per filter, with and
  without mipmaps, and an alpha-tested plane with Preserve Coverage; whole, or cut into strips.
- :func:`outline_sweep`: spheres with an outline pass (Cull Front, Offset 1, 1) in World and Screen
  mode of both MToon formulas, under uniform, non-uniform and mirroring matrices.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np

from blendlib.core.scene import DrawScene, ForwardLight, Light
from blendlib.core.vocabulary import (
    BlendFactor,
    ColorSpace,
    CompareFunction,
    Cull,
    Lighting,
    LightMode,
    LightRenderMode,
    LightType,
    Material,
    OutlineFormula,
    OutlineMode,
    Pass,
    Queue,
    Texture,
    TextureFilter,
    TextureWrap,
    VertexColor,
)

from .scenes import camera, make_mesh, quad, renderer, scale, screen_camera, translate, uv_sphere

BASE = Pass(name="Base", light_mode=LightMode.ForwardBase)
ADD = Pass(name="Add", light_mode=LightMode.ForwardAdd, zwrite=False, blend=True, src_blend=BlendFactor.One,
           dst_blend=BlendFactor.One)
BLEND_BASE = Pass(name="Base", light_mode=LightMode.ForwardBase, zwrite=False, blend=True,
                  src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha)
BLEND_ADD = Pass(name="Add", light_mode=LightMode.ForwardAdd, zwrite=False, blend=True,
                 src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.One)


def grid(n: int, size: float, z: float = 0.0, bumpy: bool = True):
    """An n x n grid of quads over [-size/2, size/2]² at height ``z`` facing +Z, with UVs 0..1 and
    (``bumpy``) smooth normals tilted per vertex, so the Lambert term varies inside triangles."""
    xs = np.linspace(-size / 2, size / 2, n + 1)
    pos = np.array([(x, y, z) for y in xs for x in xs])
    tri = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            tri += [(a, a + 1, a + n + 2), (a, a + n + 2, a + n + 1)]
    tri = np.array(tri)
    uv = (pos[:, :2] + size / 2) / size
    vertex_normal = np.array([(0.35 * math.sin(3 * x), 0.35 * math.cos(2 * y), 1.0) for x, y, _ in pos])
    normals = vertex_normal[tri] if bumpy else None
    return make_mesh(pos, tri, normals=normals, uvs=uv[tri])


def _lights() -> tuple[ForwardLight, ...]:
    important = LightRenderMode.Important
    return (
        ForwardLight("Fill", LightType.Directional, axis=(-0.5, 0.3, 0.8), color=(0.3, 0.5, 1.0), intensity=0.6,
                     render_mode=important),
        ForwardLight("Point A", LightType.Point, position=(-1.2, 0.6, 0.9), color=(1.0, 0.55, 0.2), intensity=1.5,
                     range=3.0, render_mode=important),
        ForwardLight("Point B", LightType.Point, position=(1.4, -0.8, 0.5), color=(0.4, 1.0, 0.5), intensity=2.0,
                     range=2.2, render_mode=important),
        ForwardLight("Spot", LightType.Spot, position=(0.3, 1.2, 2.0), axis=(-0.1, 0.45, 0.9), color=(1.0, 1.0, 0.9),
                     intensity=1.8, range=5.0, spot_angle=50.0, render_mode=important),
    )


def light_sweep(color_space: ColorSpace = ColorSpace.Gamma, hdr: bool = False, seed: int = 21) -> DrawScene:
    """A lit floor (opaque: ForwardBase + ``Blend One One`` ForwardAdd), a transparent sphere
    (``Blend SrcAlpha OneMinusSrcAlpha`` + ``Blend SrcAlpha One``), a flat-shaded Lambert quad and an
    Unlit quad whose ForwardAdd passes output their albedo, under four per-pixel lights."""
    rng = np.random.default_rng(seed)
    tex = Texture(rng.uniform(0.3, 1.0, size=(8, 8, 4)).astype(np.float32), encoding="sRGB", name="floor")
    floor = Material(name="Floor", color=(0.9, 0.85, 0.8, 1.0), main_tex=tex, passes=(BASE, ADD))
    glass = Material(name="Glass", queue=Queue.Transparent, color=(0.6, 0.8, 1.0, 0.45), passes=(BLEND_BASE, BLEND_ADD))
    flat = Material(name="Flat", color=(0.8, 0.7, 0.6, 1.0), passes=(BASE, ADD))
    unlit = Material(name="Unlit", color=(0.2, 0.3, 0.25, 1.0), lighting=Lighting.Unlit, queue=Queue.Transparent,
                     passes=(BLEND_BASE, BLEND_ADD))
    renderers = (
        renderer(grid(10, 4.0), floor, name="Floor"),
        renderer(uv_sphere(0.6, 16, 10), glass, name="Glass", matrix=translate(0.4, 0.2, 0.7)),
        renderer(grid(2, 0.8, bumpy=False), flat, name="Flat", matrix=translate(-1.3, -1.2, 0.3)),
        renderer(quad(1.0, 1.0, 1.8, 1.8, z=0.2), unlit, name="Unlit"),
    )
    cam = camera(96, 72, eye=(0.0, -3.2, 3.6), target=(0.0, 0.0, 0.3), fov=55.0)
    return DrawScene(camera=cam, renderers=renderers, light=Light(direction=(0.2, -0.4, 0.9), color=(1.0, 0.95, 0.9),
                                                                    energy=0.7),
                     ambient=(0.1, 0.1, 0.12), color_space=color_space, hdr=hdr, lights=_lights(),
                     pixel_light_count=2)


def vertex_color_sweep(color_space: ColorSpace = ColorSpace.Gamma, seed: int = 22) -> DrawScene:
    """Every VertexColor x encoding x texture x lighting on 8 x 8 pixel quads of per-corner
    colours (the last row: one colour per triangle, and quads of a mesh without colours)."""
    rng = np.random.default_rng(seed)
    tex = Texture(rng.uniform(0.1, 1.0, size=(4, 4, 4)).astype(np.float32), encoding="sRGB", name="tex")
    combos = list(itertools.product(VertexColor, ("sRGB", "Linear"), (None, tex), Lighting, (False, True)))
    cols = 12
    cell = 8
    rows = -(-len(combos) // cols) + 1
    w, h = cols * cell, rows * cell
    renderers = []
    for k, (mode, encoding, texture, lighting, flat) in enumerate(combos):
        x0, y0 = (k % cols) * cell, (k // cols) * cell
        mesh = quad(x0, y0, x0 + cell, y0 + cell, z=0.0)
        colors = rng.uniform(0.0, 1.0, size=(2, 3, 4)).astype(np.float32)
        if flat:
            colors[:, 1:] = colors[:, :1]
        normals = rng.uniform(-0.4, 0.4, size=(2, 3, 3)).astype(np.float32)
        normals[..., 2] = 1.0
        mesh = type(mesh)(mesh.positions, mesh.triangles, normals, mesh.uvs, colors=colors, color_encoding=encoding)
        mat = Material(name=f"M{k}", color=tuple(rng.uniform(0.3, 1.0, 4).tolist()), main_tex=texture,
                       main_tex_filter=TextureFilter.Point, lighting=lighting, vertex_color=mode,
                       tint_color=tuple(rng.uniform(0.2, 0.8, 4).tolist()))  # Blend Off: alpha as written
        renderers.append(renderer(mesh, mat, name=f"Q{k:03d}"))
    for k, mode in enumerate(VertexColor):  # no colour attribute: white
        x0, y0 = k * cell, (rows - 1) * cell
        mat = Material(name=f"White{k}", color=(0.7, 0.5, 0.3, 0.8), lighting=Lighting.Unlit, vertex_color=mode,
                       tint_color=(0.4, 0.6, 0.2, 0.5))
        renderers.append(renderer(quad(x0, y0, x0 + cell, y0 + cell), mat, name=f"W{k}"))
    return DrawScene(camera=screen_camera(w, h), renderers=tuple(renderers),
                     light=Light(direction=(0.3, 0.4, 0.9), color=(1.0, 0.9, 0.8), energy=0.8),
                     ambient=(0.2, 0.2, 0.25), color_space=color_space)


def mip_texture(seed: int = 23, size: int = 32) -> Texture:
    """A texture with detail at every scale: random texels, a checker, alpha from a ramp and the checker."""
    rng = np.random.default_rng(seed)
    px = rng.uniform(0.0, 1.0, size=(size, size, 4)).astype(np.float32)
    j, i = np.mgrid[0:size, 0:size]
    checker = ((i // 4 + j // 4) % 2).astype(np.float32)
    px[..., 0] = 0.25 + 0.5 * checker + 0.2 * px[..., 0]
    px[..., 3] = np.clip(0.2 + 0.7 * checker * px[..., 3] + 0.1 * (i / size), 0, 1)
    return Texture(px, encoding="sRGB", name="mips")


def receding_plane(strips: int = 1):
    """The plane x in [-1, 1], y in [0, 40] facing +Z with UVs 0..1, cut across y into ``strips``
    equal strips of two triangles each."""
    ys = 40.0 * np.linspace(0.0, 1.0, strips + 1) ** 2
    pos = [(x, y, 0.0) for y in ys for x in (-1.0, 1.0)]
    tri, uv = [], []
    for j in range(strips):
        a = 2 * j
        v0, v1 = j / strips, (j + 1) / strips
        tri += [(a, a + 1, a + 3), (a, a + 3, a + 2)]
        uv += [[(0, v0), (1, v0), (1, v1)], [(0, v0), (1, v1), (0, v1)]]
    return make_mesh(pos, tri, uvs=uv)


def mip_sweep(filt: TextureFilter = TextureFilter.Trilinear, color_space: ColorSpace = ColorSpace.Gamma,
              strips: int = 1, tiling: tuple[float, float] = (4.0, 24.0)) -> DrawScene:
    """A long receding plane tiled ``tiling`` (4 x 24: LOD from below 0 to past the last level) with mipmaps,
    the same without (left), and an alpha-tested one with Preserve Coverage (right), filter ``filt``;
    ``strips``: the planes cut into that many strips across (:func:`receding_plane`): with a
    coarser tiling the near strips' texels are magnified throughout and the far ones' minified."""
    tex = mip_texture()
    plane = receding_plane(strips)

    def material(name: str, **kw) -> Material:
        return Material(name=name, main_tex=tex, main_tex_filter=filt, main_tex_wrap=TextureWrap.Repeat,
                        main_tex_tiling=tiling, lighting=Lighting.Unlit, **kw)

    renderers = (
        renderer(plane, material("Mipmapped", main_tex_mipmaps=True), name="A", matrix=translate(-0.2, 0, 0)),
        renderer(plane, material("Plain"), name="B", matrix=translate(-2.25, 0, 0)),
        renderer(plane, material("Coverage", main_tex_mipmaps=True, main_tex_preserve_coverage=True, cutoff=0.5,
                                 queue=Queue.AlphaTest, passes=(Pass(alpha_test=True),)),
                 name="C", matrix=translate(1.85, 0, 0)),
    )
    cam = camera(120, 80, eye=(0.0, -1.0, 0.9), target=(0.0, 6.0, 0.0), fov=60.0, near=0.1, far=60.0)
    return DrawScene(camera=cam, renderers=renderers, light=None, color_space=color_space, clear_color=(0, 0, 0, 1))


#: (outline colour, lighting mix) of :func:`outline_sweep`'s eight spheres with ``colored``: MToon 0.x's
#: fixed colour (mix 0), mixes between, the lit colour times the outline colour (1), and none.
OUTLINE_COLORS = (((1.0, 0.0, 0.0), 0.0), ((0.2, 0.6, 1.0), 1.0), ((0.9, 0.8, 0.1), 0.5), (None, 0.0),
                  ((0.0, 0.0, 0.0), 0.25), ((1.0, 1.0, 1.0), 1.0), ((0.35, 0.1, 0.7), 0.75), ((0.5, 0.5, 0.5), 0.0))


def planar_uvs(mesh, radius: float):
    """``mesh`` with UVs projected along z: (0.5 + x / 2r, 0.5 + y / 2r) per corner."""
    pos = np.asarray(mesh.positions, np.float64)[np.asarray(mesh.triangles)]
    return replace(mesh, uvs=(0.5 + pos[..., :2] / (2 * radius)).astype(np.float32))


def width_texture(k: int) -> dict:
    """Material fields of an outline-width texture for sphere ``k`` of :func:`outline_sweep`: red
    0, 0.25, 0.75, 1 across (0.x's are imported sRGB, 1.0's linear data), Point or Bilinear, with a
    ``_MainTex`` tiling and offset (the coordinates MToon samples it at)."""
    red = np.array([0.0, 0.25, 0.75, 1.0], np.float32)
    pixels = np.ones((2, 4, 4), np.float32)
    pixels[..., 0] = red
    texture = Texture(pixels, encoding="sRGB" if k % 4 < 2 else "Data", name=f"Width{k}")
    first = k < 4
    return dict(outline_width_tex=texture,
                outline_width_tex_filter=TextureFilter.Point if k % 2 else TextureFilter.Bilinear,
                outline_width_tex_wrap=TextureWrap.Clamp if first else TextureWrap.Repeat,
                main_tex_tiling=(1.0, 1.0) if first else (0.8, 1.0),
                main_tex_offset=(0.0, 0.0) if first else (0.1, 0.0))


def outline_sweep(seed: int = 24, colored: bool = False, color_space: ColorSpace = ColorSpace.Gamma,
                  width_textures: bool = False) -> DrawScene:
    """Spheres with a base pass and an outline pass (Cull Front, Offset 1, 1, ZWrite On) in every
    OutlineMode x OutlineFormula, under uniform, non-uniform (World 0.x) and mirroring matrices;
    ``colored``: the outline passes with MToon's outline colours (:data:`OUTLINE_COLORS`);
    ``width_textures``: the materials with outline-width textures (:func:`width_texture`)."""
    rng = np.random.default_rng(seed)
    sphere = uv_sphere(0.45, 18, 12)
    if width_textures:
        sphere = planar_uvs(sphere, 0.45)
    widths = {(OutlineMode.World, OutlineFormula.MToon0x): 6.0, (OutlineMode.World, OutlineFormula.MToon10): 0.05,
              (OutlineMode.Screen, OutlineFormula.MToon0x): 1.5, (OutlineMode.Screen, OutlineFormula.MToon10): 0.01}
    renderers = []
    spots = [(-1.5, 0.6), (-0.5, 0.6), (0.5, 0.6), (1.5, 0.6), (-1.5, -0.6), (-0.5, -0.6), (0.5, -0.6), (1.5, -0.6)]
    combos = [(mode, formula, m) for m in ("uniform", "stretched") for mode in (OutlineMode.World, OutlineMode.Screen)
              for formula in OutlineFormula]
    for k, ((mode, formula, kind), (x, y)) in enumerate(zip(combos, spots, strict=True)):
        outline = Pass(name="Outline", cull=Cull.Front, offset_factor=1.0, offset_units=1.0, outline_mode=mode,
                       outline_formula=formula, outline_width=widths[(mode, formula)],
                       outline_max_distance=3.0)
        if colored:
            outline = replace(outline, outline_color=OUTLINE_COLORS[k][0], outline_lighting_mix=OUTLINE_COLORS[k][1])
        mat = Material(name=f"Toon{k}", color=tuple(rng.uniform(0.3, 1.0, 3).tolist()) + (1.0,),
                       lighting=Lighting.Unlit if k % 2 else Lighting.Lambert, passes=(Pass(name="Base"), outline),
                       **(width_texture(k) if width_textures else {}))
        matrix = translate(x, y, 0.0)
        if kind == "stretched":
            matrix = matrix @ scale(1.3 if k % 2 else -1.3, 0.8, 1.0)
        renderers.append(renderer(sphere, mat, name=f"S{k}", matrix=matrix))
    backdrop = Material(name="Back", color=(0.2, 0.25, 0.3, 1.0), lighting=Lighting.Unlit,
                        passes=(Pass(ztest=CompareFunction.LEqual),))
    renderers.append(renderer(quad(-3, -2, 3, 2, z=-1.0), backdrop, name="Back"))
    cam = camera(128, 72, eye=(0.2, -0.4, 4.5), target=(0.0, 0.0, 0.0), fov=45.0)
    return DrawScene(camera=cam, renderers=tuple(renderers), light=Light(direction=(0.3, 0.5, 0.8)),
                     ambient=(0.25, 0.25, 0.3), color_space=color_space)


FEATURE_SWEEPS = {
    "lights_gamma": lambda: light_sweep(ColorSpace.Gamma),
    "lights_linear": lambda: light_sweep(ColorSpace.Linear),
    "lights_linear_hdr": lambda: light_sweep(ColorSpace.Linear, hdr=True),
    "vertex_colors_gamma": lambda: vertex_color_sweep(ColorSpace.Gamma),
    "vertex_colors_linear": lambda: vertex_color_sweep(ColorSpace.Linear),
    "mips_point": lambda: mip_sweep(TextureFilter.Point),
    "mips_bilinear": lambda: mip_sweep(TextureFilter.Bilinear),
    "mips_trilinear": lambda: mip_sweep(TextureFilter.Trilinear),
    "mips_trilinear_linear": lambda: mip_sweep(TextureFilter.Trilinear, ColorSpace.Linear),
    "mips_strips_point": lambda: mip_sweep(TextureFilter.Point, strips=16, tiling=(0.5, 3.0)),
    "mips_strips_trilinear": lambda: mip_sweep(TextureFilter.Trilinear, strips=16, tiling=(0.5, 3.0)),
    "outline": outline_sweep,
    "outline_color": lambda: outline_sweep(colored=True),
    "outline_color_linear": lambda: outline_sweep(colored=True, color_space=ColorSpace.Linear),
    "outline_width_tex": lambda: outline_sweep(colored=True, width_textures=True),
    "outline_width_tex_linear": lambda: outline_sweep(width_textures=True, color_space=ColorSpace.Linear),
}
