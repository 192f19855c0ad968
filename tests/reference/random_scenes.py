"""Small random draw scenes that exercise every pass state, for the property tests.

One generator, two sources of randomness: :func:`scenes` is a hypothesis strategy
(shrinks to a minimal failing scene), :func:`seeded_scene` takes a seed (stable
batches for aggregate statistics such as the GL agreement share).

The scenes cover: 1-4 renderers of 1-8 triangles, triangles crossing the near and
the far plane, back faces, overlaps, negative-scale matrices, every Queue, every
Cull / ZTest / BlendFactor / BlendOp / ColorMask / StencilOp / comparison, separate
alpha, polygon offset, alpha test, textures of 1..4 x 1..4 texels with both
filters, both wraps and all three encodings, Gamma / Linear, LDR / HDR, every sort
mode, with and without a light.

With ``features`` (SPEC §12 and the outline of §11.6; drawn after everything above, so a seed's
scene without them stays the scene it always was): forward lights (directional, point and spot,
every render mode) drawing ForwardAdd passes, every LightMode, vertex colours (both encodings) with
Off / Multiply / Particle, textures up to 8 x 8 with mipmaps (every filter, Preserve Coverage) and
outline vertex programs (World / Screen, MToon 0.x / 1.0). With ``msaa`` 2, 4 or 8 samples (drawn
after the features), AlphaToMask on some passes.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from hypothesis import strategies as st

from blendlib.core.scene import Camera, DrawScene, ForwardLight, Light, Renderer
from blendlib.core.vocabulary import (
    CHANNELS,
    ZTEST_FUNCTIONS,
    BlendFactor,
    BlendOp,
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
    SortMode,
    StencilOp,
    Texture,
    TextureFilter,
    TextureWrap,
    VertexColor,
    pass_state_text,
)

from .scenes import look_at, make_mesh, orthographic, perspective


class _HypothesisPick:
    def __init__(self, draw):
        self.draw = draw

    def int(self, lo: int, hi: int) -> int:
        return self.draw(st.integers(lo, hi))

    def real(self, lo: float, hi: float, steps: int = 1000) -> float:
        """A value on a grid of ``steps`` intervals (shrinks towards ``lo``)."""
        return lo + (hi - lo) * self.draw(st.integers(0, steps)) / steps

    def choice(self, seq):
        seq = list(seq)
        return seq[self.draw(st.integers(0, len(seq) - 1))]

    def chance(self, p: float) -> bool:
        return self.draw(st.integers(0, 999)) < p * 1000


class _RngPick:
    def __init__(self, seed: int):
        self.rng = np.random.default_rng(seed)

    def int(self, lo: int, hi: int) -> int:
        return int(self.rng.integers(lo, hi + 1))

    def real(self, lo: float, hi: float, steps: int = 1000) -> float:
        return lo + (hi - lo) * int(self.rng.integers(0, steps + 1)) / steps

    def choice(self, seq):
        seq = list(seq)
        return seq[int(self.rng.integers(0, len(seq)))]

    def chance(self, p: float) -> bool:
        return bool(self.rng.random() < p)


def _color(pick, alpha_lo=0.0):
    return (pick.real(0, 1), pick.real(0, 1), pick.real(0, 1), pick.real(alpha_lo, 1))


def _pass(pick) -> Pass:
    kw = dict(
        cull=pick.choice(Cull),
        zwrite=pick.chance(0.5),
        ztest=pick.choice(ZTEST_FUNCTIONS) if pick.chance(0.6) else CompareFunction.LEqual,
        blend=pick.chance(0.6),
        src_blend=pick.choice(BlendFactor),
        dst_blend=pick.choice(BlendFactor),
        blend_op=pick.choice(BlendOp) if pick.chance(0.5) else BlendOp.Add,
        color_mask=frozenset(c for c in CHANNELS if pick.chance(0.8)) if pick.chance(0.3) else frozenset(CHANNELS),
        alpha_test=pick.chance(0.2),
    )
    if pick.chance(0.2):
        kw.update(separate_alpha=True, src_blend_alpha=pick.choice(BlendFactor),
                  dst_blend_alpha=pick.choice(BlendFactor), blend_op_alpha=pick.choice(BlendOp))
    if pick.chance(0.2):
        kw.update(offset_factor=float(pick.int(-2, 2)), offset_units=float(pick.int(-3, 3)))
    if pick.chance(0.35):
        kw.update(
            stencil=True, stencil_ref=pick.int(0, 255),
            stencil_read_mask=pick.choice([255, 255, 15, 0xF0, pick.int(0, 255)]),
            stencil_write_mask=pick.choice([255, 255, 7, pick.int(0, 255)]),
            stencil_comp=pick.choice(CompareFunction), stencil_pass=pick.choice(StencilOp),
            stencil_fail=pick.choice(StencilOp), stencil_zfail=pick.choice(StencilOp),
        )
    return Pass(**kw)


def _texture(pick) -> Texture:
    w, h = pick.int(1, 4), pick.int(1, 4)
    px = np.array([[_color(pick) for _ in range(w)] for _ in range(h)], dtype=np.float32)
    return Texture(px, encoding=pick.choice(["sRGB", "Linear", "Data"]), name="tex")


def _material(pick, index: int) -> Material:
    queue = pick.choice(Queue)
    return Material(
        name=f"M{index}",
        queue=queue,
        queue_offset=pick.choice([0, 0, 0, 1, -1]),
        color=_color(pick, alpha_lo=0.1),
        main_tex=_texture(pick) if pick.chance(0.5) else None,
        main_tex_tiling=(pick.real(-2, 3, 20), pick.real(-2, 3, 20)) if pick.chance(0.3) else (1.0, 1.0),
        main_tex_offset=(pick.real(-1, 1, 20), pick.real(-1, 1, 20)) if pick.chance(0.3) else (0.0, 0.0),
        main_tex_filter=pick.choice(TextureFilter),
        main_tex_wrap=pick.choice(TextureWrap),
        alpha_scale=pick.real(0, 1, 10) if pick.chance(0.3) else 1.0,
        cutoff=pick.real(0, 1, 100),
        lighting=pick.choice(Lighting),
        passes=tuple(_pass(pick) for _ in range(pick.int(1, 3))),
    )


def _featured_pass(pick, p: Pass) -> Pass:
    """``p`` with a LightMode (ForwardAdd often) and maybe an outline vertex program."""
    modes = [LightMode.ForwardBase, LightMode.ForwardAdd, LightMode.ForwardAdd, LightMode.Always,
             LightMode.ShadowCaster, LightMode.Vertex]
    kw = dict(light_mode=pick.choice(modes))
    if pick.chance(0.25):
        formula = pick.choice(OutlineFormula)
        mode = pick.choice([OutlineMode.World, OutlineMode.Screen])
        if mode is OutlineMode.World:
            width = pick.real(0, 20, 40) if formula is OutlineFormula.MToon0x else pick.real(0, 0.2, 40)
        else:
            width = pick.real(0, 10, 40) if formula is OutlineFormula.MToon0x else pick.real(0, 0.05, 40)
        kw.update(outline_mode=mode, outline_formula=formula, outline_width=width,
                  outline_max_distance=pick.real(1, 10, 9))
    return replace(p, **kw)


def _featured_material(pick, m: Material) -> Material:
    """``m`` with vertex colour use, a tint, and maybe a mipmapped texture of up to 8 x 8 texels."""
    kw = dict(vertex_color=pick.choice(VertexColor), tint_color=_color(pick),
              passes=tuple(_featured_pass(pick, p) for p in m.passes))
    if pick.chance(0.6):
        w, h = pick.int(1, 8), pick.int(1, 8)
        px = np.array([[_color(pick) for _ in range(w)] for _ in range(h)], dtype=np.float32)
        kw.update(main_tex=Texture(px, encoding=pick.choice(["sRGB", "Linear", "Data"]), name="mip"),
                  main_tex_mipmaps=pick.chance(0.8), main_tex_preserve_coverage=pick.chance(0.4),
                  main_tex_tiling=(pick.real(-3, 4, 28), pick.real(-3, 4, 28)))
    return replace(m, **kw)


def _featured_lights(pick) -> tuple[ForwardLight, ...]:
    lights = []
    for k in range(pick.int(0, 3)):
        kind = pick.choice(LightType)
        axis = (pick.real(-1, 1, 20), pick.real(-1, 1, 20), pick.choice([-1.0, 1.0]))
        lights.append(ForwardLight(
            name=f"L{k}", type=kind, position=(pick.real(-2, 2, 40), pick.real(-2, 2, 40), pick.real(-2, 2, 40)),
            axis=axis, color=_color(pick)[:3], intensity=pick.real(0, 2, 20), range=pick.real(0.5, 6, 22),
            spot_angle=pick.real(20, 150, 26),
            render_mode=pick.choice([LightRenderMode.Auto, LightRenderMode.Auto, LightRenderMode.Important,
                                     LightRenderMode.NotImportant])))
    return tuple(lights)


def _featured_renderer(pick, r: Renderer) -> Renderer:
    """``r`` with the material's features and maybe vertex colours."""
    mesh = r.mesh
    if pick.chance(0.7):
        t = mesh.triangle_count
        colors = np.array([[_color(pick) for _ in range(3)] for _ in range(t)], dtype=np.float32)
        if pick.chance(0.3):  # one colour per triangle: flat inputs
            colors[:, 1:] = colors[:, :1]
        mesh = replace(mesh, colors=colors, color_encoding=pick.choice(["sRGB", "Linear"]))
    return replace(r, mesh=mesh, material=_featured_material(pick, r.material))


def _matrix(pick) -> np.ndarray:
    m = np.eye(4)
    angle = pick.real(-math.pi, math.pi, 64)
    c, s = math.cos(angle), math.sin(angle)
    axis = pick.int(0, 2)
    i, j = [(1, 2), (0, 2), (0, 1)][axis]
    rot = np.eye(3)
    rot[i, i], rot[i, j], rot[j, i], rot[j, j] = c, -s, s, c
    sc = np.diag([pick.choice([1.0, 1.0, 0.5, 1.5, -1.0]) for _ in range(3)])
    m[:3, :3] = rot @ sc
    m[:3, 3] = [pick.real(-1, 1, 20) for _ in range(3)]
    return m


def _renderer(pick, index: int, shared: bool) -> Renderer:
    ntri = pick.int(1, 8)
    if shared:  # few vertices, reused: shared edges, duplicate and degenerate triangles
        nvert = pick.int(3, 3 + ntri)
        tri = np.array([[pick.int(0, nvert - 1) for _ in range(3)] for _ in range(ntri)], dtype=np.int64)
    else:  # three fresh vertices per triangle: no coincident triangles
        nvert = 3 * ntri
        tri = np.arange(nvert, dtype=np.int64).reshape(ntri, 3)
    pos = np.array([[pick.real(-2, 2) for _ in range(3)] for _ in range(nvert)])
    normals = np.array([[[pick.real(-1, 1, 20) for _ in range(3)] for _ in range(3)] for _ in range(ntri)])
    uvs = None
    if pick.chance(0.7):
        uvs = np.array([[[pick.real(-1, 2, 30) for _ in range(2)] for _ in range(3)] for _ in range(ntri)])
    mesh = make_mesh(pos, tri, normals=normals, uvs=uvs)
    m = _matrix(pick)
    world = pos @ m[:3, :3].T + m[:3, 3]
    center = (world.min(axis=0) + world.max(axis=0)) / 2
    return Renderer(f"R{pick.int(0, 3)}", pick.int(0, 1), mesh, m, _material(pick, index), center)


def _camera(pick) -> Camera:
    w, h = pick.int(8, 24), pick.int(8, 24)
    theta = pick.real(0, 2 * math.pi, 64)
    phi = pick.real(-1.0, 1.0, 32)
    dist = pick.real(2.0, 4.0, 20)
    eye = (dist * math.cos(phi) * math.sin(theta), dist * math.sin(phi), dist * math.cos(phi) * math.cos(theta))
    near, far = pick.choice([(0.5, 100.0), (1.0, 4.5), (0.1, 6.0)])
    if pick.chance(0.25):
        size = pick.real(2.0, 5.0, 6)
        proj = orthographic(size * w / h, size, near, far)
        ortho = True
    else:
        proj = perspective(pick.real(30, 90, 12), w / h, near, far)
        ortho = False
    return Camera(look_at(eye), proj, w, h, orthographic=ortho)


def _with_alpha_to_mask(pick, r: Renderer) -> Renderer:
    """``r`` with AlphaToMask on some of its passes (drawn after the rest of the scene, so that
    scenes without MSAA stay those of the same seed before MSAA existed)."""
    passes = tuple(replace(p, alpha_to_mask=pick.chance(0.4)) for p in r.material.draw_passes)
    return replace(r, material=replace(r.material, passes=passes))


def build(pick, shared: bool = True, features: bool = False, msaa: int = 1) -> DrawScene:
    """A random scene; ``shared=False`` gives every triangle its own three vertices; ``features``
    adds lights, vertex colours, mipmaps and outlines (module docstring); ``msaa`` > 1: that many
    samples, and AlphaToMask on some passes."""
    scene = _build(pick, shared, features)
    if msaa == 1:
        return scene
    return replace(scene, msaa=msaa, renderers=tuple(_with_alpha_to_mask(pick, r) for r in scene.renderers))


def _build(pick, shared: bool, features: bool) -> DrawScene:
    cam = _camera(pick)
    renderers = tuple(_renderer(pick, k, shared) for k in range(pick.int(1, 4)))
    light = None
    if pick.chance(0.7):
        light = Light(direction=(pick.real(-1, 1, 20), pick.real(-1, 1, 20), pick.real(0.1, 1, 20)),
                      color=_color(pick)[:3], energy=pick.real(0, 3, 30))
    scene = _scene(pick, cam, renderers, light)
    if not features:
        return scene
    return replace(scene, renderers=tuple(_featured_renderer(pick, r) for r in scene.renderers),
                   lights=_featured_lights(pick), pixel_light_count=pick.int(0, 3))


def _scene(pick, cam, renderers, light) -> DrawScene:
    return DrawScene(
        camera=cam,
        renderers=renderers,
        light=light,
        ambient=_color(pick)[:3],
        ambient_is_linear=pick.chance(0.5),
        color_space=pick.choice(ColorSpace),
        hdr=pick.chance(0.4),
        clear_color=_color(pick),
        sort_mode=pick.choice(SortMode),
        sort_axis=(pick.real(-1, 1, 10), pick.real(-1, 1, 10), pick.choice([-1.0, 1.0])),
    )


@st.composite
def scenes(draw, shared: bool = True, features: bool = False, msaa: int = 1) -> DrawScene:
    """Hypothesis strategy: a small random draw scene (``msaa`` 0: 2, 4 or 8 samples, drawn)."""
    if msaa == 0:
        msaa = draw(st.sampled_from((2, 4, 8)))
    return build(_HypothesisPick(draw), shared, features, msaa)


def seeded_scene(seed: int, shared: bool = True, features: bool = False, msaa: int = 1) -> DrawScene:
    """The same kind of scene from a numpy seed (stable, for aggregate statistics)."""
    return build(_RngPick(seed), shared, features, msaa)


def describe(scene: DrawScene) -> str:
    """A readable dump of a scene (for failure messages)."""
    cam = scene.camera
    lines = [
        f"camera {cam.width}x{cam.height} ortho={cam.orthographic} view={cam.view_matrix.tolist()} "
        f"proj={cam.projection.tolist()}",
        f"color_space={scene.color_space} hdr={scene.hdr} clear={scene.clear_color} ambient={scene.ambient} "
        f"linear_ambient={scene.ambient_is_linear} light={scene.light} sort={scene.sort_mode} {scene.sort_axis} "
        f"msaa={scene.msaa}",
        f"lights={scene.lights} pixel_light_count={scene.pixel_light_count}",
    ]
    for r in scene.renderers:
        mat = r.material
        lines.append(f"renderer {r.name}/{r.slot} matrix={np.asarray(r.matrix_world).tolist()}")
        lines.append(f"  positions={np.asarray(r.mesh.positions).tolist()} triangles={r.mesh.triangles.tolist()}")
        lines.append(f"  material queue={mat.render_queue} color={mat.color} lighting={mat.lighting} "
                     f"tex={None if mat.main_tex is None else mat.main_tex.pixels.shape} "
                     f"{mat.main_tex_filter} {mat.main_tex_wrap} cutoff={mat.cutoff} mips={mat.main_tex_mipmaps} "
                     f"preserve={mat.main_tex_preserve_coverage} vertex_color={mat.vertex_color} tint={mat.tint_color} "
                     f"colors={None if r.mesh.colors is None else r.mesh.color_encoding}")
        for p in mat.draw_passes:
            lines.append(f"  pass {pass_state_text(p)} {p.light_mode} outline={p.outline_mode} "
                         f"{p.outline_formula} {p.outline_width} {p.outline_max_distance}")
    return "\n".join(lines)
