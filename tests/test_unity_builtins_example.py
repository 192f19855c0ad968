"""The Unity built-in shaders example (blend_files/unity_builtins.blend, scripts/unity_builtins.py): Unity's
own shaders, imported from their text, draw what their text and Unity's blend equations say.

Expected values come from the shaders' text (Unity's built-in shader source 2019.4, quoted beside each
check), the two ``.mat`` files of blend_files/unity/ and the blend equations of Unity's manual
("ShaderLab: Blend": ``result = src * SrcFactor + dst * DstFactor``), applied in numpy to 8-bit codes
(the frame stores ``floor(255 v + 0.5)`` after every blend; the scene is in Gamma colour space, so
colours are their codes / 255). What a frame *starts from* is measured separately: the background
is the frame drawn without the object (the opaque backdrop and what came before), and a texture's
value at a pixel is the object drawn alone with ``Blend Off`` and a white unlit material (its texel,
exact where the surrounding 3x3 pixels read the same flat texel value).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from blendlib.core.drawlist import draw_calls
from blendlib.core.vocabulary import (
    BlendFactor,
    CompareFunction,
    Cull,
    Lighting,
    LightMode,
    Pass,
    Queue,
    TextureFilter,
    VertexColor,
)
from tests.support import goldens as mg

F = BlendFactor
RGB, RGBA = frozenset("RGB"), frozenset("RGBA")


@pytest.fixture(scope="module")
def draw():
    return mg.load_draw_scenes(mg.BLEND_DIR / "unity_builtins.blend")["UnityBuiltins"]


@pytest.fixture(scope="module")
def frame(draw):
    return mg.render_codes(draw)["color"].astype(np.int64)


@pytest.fixture(scope="module")
def free(draw) -> np.ndarray:
    """(H, W) bool: the pixels no label covers (labels are opaque and drawn first)."""
    labels = tuple(r for r in draw.renderers if r.name.startswith("Label"))
    return mg.render_codes(dataclasses.replace(draw, renderers=labels))["depth"] == mg.DMAX


def renderer(draw, name: str):
    (r,) = [r for r in draw.renderers if r.name == name]
    return r


def without(draw, *names: str) -> np.ndarray:
    """The frame's colour codes (int64) drawn without the renderers ``names``: what they blend over."""
    kept = tuple(r for r in draw.renderers if r.name not in names)
    return mg.render_codes(dataclasses.replace(draw, renderers=kept))["color"].astype(np.int64)


def alone(draw, r, **material) -> tuple[np.ndarray, np.ndarray]:
    """Renderer ``r`` drawn alone, ``Blend Off`` ZWrite On Cull Back, no alpha test, its material
    changed by ``material``: (coverage mask (H, W) bool, colour codes (H, W, 4) int64)."""
    m = dataclasses.replace(r.material, passes=(Pass(cull=Cull.Back),), cutoff=0.0, **material)
    out = mg.render_codes(dataclasses.replace(draw, renderers=(dataclasses.replace(r, material=m),)))
    return out["depth"] < mg.DMAX, out["color"].astype(np.int64)


def texels(draw, r, point: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """``r``'s texture at each pixel: (mask of pixels where it is exact, codes (H, W, 4) int64). A
    Point-filtered texture (``point``) is exact wherever it is drawn (every pixel reads one texel); a
    bilinear one where the pixel and its eight neighbours are covered and read the same codes (a
    flat texel area)."""
    mask, codes = alone(draw, r, vertex_color=VertexColor.Off, lighting=Lighting.Unlit, color=(1.0, 1.0, 1.0, 1.0),
                        alpha_scale=1.0)
    if point:
        assert r.material.main_tex_filter is TextureFilter.Point
        return mask, codes
    h, w = mask.shape
    flat = mask.copy()
    flat[[0, -1], :] = flat[:, [0, -1]] = False
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            shifted = np.roll(np.roll(codes, dy, axis=0), dx, axis=1)
            flat &= np.roll(np.roll(mask, dy, axis=0), dx, axis=1) & (shifted == codes).all(axis=2)
    return flat, codes


def quads(r) -> list:
    """A particle system's quads (two triangles each, in draw order) as renderers of their own."""
    mesh = r.mesh
    out = []
    for k in range(mesh.triangle_count // 2):
        rows = slice(2 * k, 2 * k + 2)
        part = dataclasses.replace(mesh, triangles=mesh.triangles[rows], normals=mesh.normals[rows],
                                   uvs=mesh.uvs[rows], colors=mesh.colors[rows],
                                   polygons=None if mesh.polygons is None else mesh.polygons[rows],
                                   loop_triangles=None if mesh.loop_triangles is None else mesh.loop_triangles[rows])
        out.append(dataclasses.replace(r, mesh=part))
    return out


def quantise(v) -> np.ndarray:
    return np.floor(np.clip(v, 0.0, 1.0) * 255.0 + 0.5).astype(np.int64)


# --------------------------------------------------------------------------- the state, from the text


def test_every_material_has_the_state_its_shader_text_gives(draw):
    """Particle Alpha Blend/Add/Multiply.shader: 'Category { Tags { "Queue"="Transparent" … } Blend SrcAlpha
    OneMinusSrcAlpha | Blend SrcAlpha One | Blend Zero SrcColor; ColorMask RGB (not in Multiply); Cull Off
    Lighting Off ZWrite Off', '_TintColor ("Tint Color", Color) = (0.5,0.5,0.5,0.5)'; Sprites-Default.shader
    'Cull Off Lighting Off ZWrite Off Blend One OneMinusSrcAlpha'; UI-Default.shader 'ZTest
    [unity_GUIZTestMode] … Blend SrcAlpha OneMinusSrcAlpha ColorMask [_ColorMask]' (_ColorMask 15) and a
    Stencil block; Unlit-Alpha.shader 'ZWrite Off Blend SrcAlpha OneMinusSrcAlpha' (Cull Back by default);
    AlphaTest-Diffuse.shader '"Queue"="AlphaTest"', '_Cutoff ("Alpha cutoff", Range(0,1)) = 0.5'."""
    expected = {
        "Alpha Blended Particles": (Queue.Transparent, Cull.Off, False, (F.SrcAlpha, F.OneMinusSrcAlpha), RGB),
        "Additive Particles": (Queue.Transparent, Cull.Off, False, (F.SrcAlpha, F.One), RGB),
        "Multiply Particles": (Queue.Transparent, Cull.Off, False, (F.Zero, F.SrcColor), RGBA),
        "Sprite": (Queue.Transparent, Cull.Off, False, (F.SrcAlpha, F.OneMinusSrcAlpha), RGBA),
        "UI Panel": (Queue.Transparent, Cull.Off, False, (F.SrcAlpha, F.OneMinusSrcAlpha), RGBA),
        "Glass Pane": (Queue.Transparent, Cull.Back, False, (F.SrcAlpha, F.OneMinusSrcAlpha), RGBA),
        "Cutout Cube": (Queue.AlphaTest, Cull.Back, True, None, RGB),
    }
    for name, (queue, cull, zwrite, factors, mask) in expected.items():
        r = renderer(draw, name)
        p = r.material.passes[0]
        assert (r.material.queue, p.cull, p.zwrite, p.color_mask) == (queue, cull, zwrite, mask), name
        assert (factors is None) is (not p.blend), name
        if factors is not None:
            assert (p.src_blend, p.dst_blend) == factors, name
    for name in ("Alpha Blended Particles", "Additive Particles"):
        m = renderer(draw, name).material
        assert m.vertex_color is VertexColor.Particle and m.tint_color == (0.5, 0.5, 0.5, 0.5)
    # Sprites/Default premultiplies in its program ('c.rgb *= c.a'), so 'Blend One OneMinusSrcAlpha'
    # draws as SrcAlpha for colour and keeps One OneMinusSrcAlpha for alpha.
    sprite = renderer(draw, "Sprite").material.passes[0]
    assert sprite.separate_alpha and (sprite.src_blend_alpha, sprite.dst_blend_alpha) == (F.One, F.OneMinusSrcAlpha)
    ui = renderer(draw, "UI Panel").material.passes[0]
    assert ui.stencil and ui.ztest is CompareFunction.LEqual
    cutout = renderer(draw, "Cutout Cube").material
    assert cutout.passes[0].alpha_test and cutout.cutoff == 0.5
    assert cutout.passes[0].alpha_test_comp is CompareFunction.GEqual  # 'clip (o.Alpha - _Cutoff)'


def test_standard_materials_take_their_mode_from_the_mat_files(draw):
    """blend_files/unity/Standard Fade.mat: '_Mode: 2', '_SrcBlend: 5' (SrcAlpha), '_DstBlend: 10'
    (OneMinusSrcAlpha), '_ZWrite: 0', keyword _ALPHABLEND_ON, 'm_CustomRenderQueue: 3000'; Standard
    Transparent.mat (Unity 5.5's layout): '_Mode 3', '_SrcBlend 1' (One: the program premultiplies,
    '_ALPHAPREMULTIPLY_ON'), '_DstBlend 10'; both '_Color: {r: 0.95, g: 0.55, b: 0.2, a: 0.55}'."""
    fade, transparent = renderer(draw, "Standard Fade").material, renderer(draw, "Standard Transparent").material
    for m in (fade, transparent):
        assert (m.queue, m.queue_offset) == (Queue.Transparent, 0)
        assert m.color == pytest.approx((0.95, 0.55, 0.2, 0.55))
        p = m.passes[0]
        assert (p.name, p.light_mode, p.zwrite) == ("FORWARD", LightMode.ForwardBase, False)
        assert (p.src_blend, p.dst_blend) == (F.SrcAlpha, F.OneMinusSrcAlpha)
    assert not fade.passes[0].separate_alpha
    t = transparent.passes[0]
    assert t.separate_alpha and (t.src_blend_alpha, t.dst_blend_alpha) == (F.One, F.OneMinusSrcAlpha)


def test_each_object_draws_its_forward_pass_once_under_one_sun(draw):
    """Surface shaders' FORWARD ForwardAdd passes, PREPASS, DEFERRED and Meta do not draw in a forward
    frame with only a directional light; the others' single pass is drawn once."""
    calls = [c for c in draw_calls(draw) if not c.renderer.name.startswith("Label")]
    names = [c.renderer.name for c in calls]
    assert len(names) == len(set(names)) == 11
    assert names[0] == "Backdrop" and names[1] == "Cutout Cube"  # Geometry 2000, then AlphaTest 2450
    assert all(c.queue == 3000 for c in calls[2:])


# --------------------------------------------------------------------------- particles


def _particle_expected(name: str, dst: np.ndarray, vc: np.ndarray, tex: np.ndarray) -> np.ndarray:
    """One quad of a particle system blended over ``dst`` codes (N, 4), by the shader's text;
    ``vc`` (4,) the vertex colour, ``tex`` (N, 4) the texel, both in [0, 1]."""
    d = dst / 255.0
    out = dst.astype(np.float64) / 255.0
    if name == "Multiply Particles":
        # 'prev = i.color * tex2D(_MainTex, i.texcoord); fixed4 col = lerp(half4(1,1,1,1), prev, prev.a)'
        # with prev.a = 1 (opaque texture and vertex alpha): col = prev; 'Blend Zero SrcColor': dst * col.
        prev = vc * tex
        assert np.all(prev[:, 3] == 1.0)
        return quantise(d * prev)
    # '2.0f * i.color * _TintColor * tex2D(_MainTex, i.texcoord)' (Alpha Blended: 'o.color = v.color *
    # _TintColor' then '2.0f * i.color * tex'), _TintColor (0.5, 0.5, 0.5, 0.5).
    col = 2.0 * vc * 0.5 * tex
    a = col[:, 3:4]
    if name == "Alpha Blended Particles":  # Blend SrcAlpha OneMinusSrcAlpha, ColorMask RGB
        out[:, :3] = col[:, :3] * a + d[:, :3] * (1.0 - a)
    else:  # Additive: Blend SrcAlpha One, ColorMask RGB
        out[:, :3] = col[:, :3] * a + d[:, :3]
    return quantise(out)


@pytest.mark.parametrize("name", ["Alpha Blended Particles", "Additive Particles", "Multiply Particles"])
def test_particles_blend_as_their_shader_text_says(draw, frame, free, name):
    """Every pixel where each covering quad reads a flat texel: the quads blended over the frame
    without the system, in the mesh's order, each as its shader and Blend line say — overlaps too."""
    r = renderer(draw, name)
    dst = without(draw, name)
    parts = quads(r)
    assert len(parts) == 3
    known = np.ones(dst.shape[:2], bool)
    covered = np.zeros(dst.shape[:2], np.int64)
    probes = []
    for part in parts:
        flat, tex = texels(draw, part)
        mask, _ = alone(draw, part)
        known &= flat | ~mask
        covered += mask
        probes.append((mask, tex))
    pixels = known & (covered > 0) & free
    assert pixels.sum() > 150 and (pixels & (covered >= 2)).sum() > 30  # single quads and overlaps
    expected = dst[pixels]
    for part, (mask, tex) in zip(parts, probes, strict=True):
        vc = part.mesh.colors[0, 0].astype(np.float64)
        here = mask[pixels]
        expected[here] = _particle_expected(name, expected[here], vc, tex[pixels][here] / 255.0)
    np.testing.assert_array_equal(frame[pixels], expected)
    # ColorMask RGB: the frame's alpha is the backdrop's (255) under the alpha-blended and additive systems
    assert (frame[pixels][:, 3] == 255).all()
    # what the system does at all: the frame differs from what it blends over where its quads show
    assert (np.abs(frame[pixels] - dst[pixels]).max(axis=1) > 8).mean() > 0.3


# --------------------------------------------------------------------------- sprites, UI, unlit


@pytest.mark.parametrize("name", ["Sprite", "UI Panel", "Glass Pane"])
def test_sprite_ui_and_unlit_transparent_blend_their_texture_and_vertex_colour(draw, frame, free, name):
    """Sprites/Default: 'c = SampleSpriteTexture(uv) * IN.color; c.rgb *= c.a' (IN.color = vertex colour
    × _Color (1,1,1,1) × _RendererColor (1,1,1,1)), 'Blend One OneMinusSrcAlpha': rgb = c.rgb·c.a +
    dst·(1 − c.a), alpha = c.a + dst.a·(1 − c.a). UI/Default: 'color = (tex2D(_MainTex, uv) +
    _TextureSampleAdd) * IN.color' (IN.color = 'v.color * _Color'), 'Blend SrcAlpha OneMinusSrcAlpha'
    for colour and alpha. Unlit/Transparent: 'col = tex2D(_MainTex, i.texcoord)', the same blend. Their
    textures are Point-filtered (the texture's Filter Mode), so every covered pixel reads one texel."""
    r = renderer(draw, name)
    dst = without(draw, name) / 255.0
    mask, tex = texels(draw, r, point=True)
    mask &= free
    assert mask.sum() > 500
    vc = r.mesh.colors[0, 0].astype(np.float64) if name != "Glass Pane" else np.ones(4)
    c = tex[mask] / 255.0 * vc
    a = c[:, 3:4]
    d = dst[mask]
    expected = np.empty_like(c)
    expected[:, :3] = c[:, :3] * a + d[:, :3] * (1.0 - a)
    expected[:, 3:] = (a if name == "Sprite" else a * a) + d[:, 3:] * (1.0 - a)
    np.testing.assert_array_equal(frame[mask], quantise(expected))


# --------------------------------------------------------------------------- legacy lit shaders


def test_cutout_discards_exactly_the_texels_below_cutoff(draw, frame, free):
    """AlphaTest-Diffuse.shader: '#pragma surface surf Lambert alphatest:_Cutoff', '_Cutoff … = 0.5',
    'fixed4 c = tex2D(_MainTex, IN.uv_MainTex) * _Color; o.Alpha = c.a': a texel of alpha 64 (0.25) is
    discarded — the frame there is the frame without the cube — and one of 230 (0.9) draws the lit
    colour opaquely (the FORWARD pass has no Blend; 'ColorMask RGB' keeps the frame's alpha)."""
    r = renderer(draw, "Cutout Cube")
    mask, tex = texels(draw, r, point=True)
    mask &= free
    _, lit = alone(draw, r)
    behind = without(draw, "Cutout Cube")
    alpha = tex[..., 3]
    assert set(np.unique(alpha[mask]).tolist()) == {64, 230}
    holes, kept = mask & (alpha == 64), mask & (alpha == 230)
    assert holes.sum() > 50 and kept.sum() > 50
    np.testing.assert_array_equal(frame[holes], behind[holes])
    np.testing.assert_array_equal(frame[kept][:, :3], lit[kept][:, :3])
    assert (frame[kept][:, 3] == behind[kept][:, 3]).all()
    assert (np.abs(frame[kept] - behind[kept]).max(axis=1) > 8).mean() > 0.9


def test_transparent_diffuse_fades_its_lit_colour_with_colormask_rgb(draw, frame, free):
    """Alpha-Diffuse.shader: '#pragma surface surf Lambert alpha:fade' → 'Blend SrcAlpha OneMinusSrcAlpha
    … ColorMask RGB' (Unity's compiled listing): rgb = S·a + dst·(1 − a) with a the texel's alpha × _Color.a
    (1), the frame's alpha untouched. S is the lit colour drawn alone (8-bit, so within one code)."""
    r = renderer(draw, "Transparent Diffuse Cube")
    mask, tex = texels(draw, r, point=True)
    mask &= free
    _, lit = alone(draw, r)
    behind = without(draw, r.name)
    a = tex[mask][:, 3:4] / 255.0
    assert set(np.unique(tex[mask][:, 3]).tolist()) == {153, 255}
    expected = quantise(lit[mask][:, :3] / 255.0 * a + behind[mask][:, :3] / 255.0 * (1.0 - a))
    assert np.abs(frame[mask][:, :3] - expected).max() <= 1
    assert (frame[mask][:, 3] == behind[mask][:, 3]).all()


# --------------------------------------------------------------------------- Standard Fade vs Transparent


def test_standard_fade_and_transparent_differ_in_the_alpha_they_leave(draw, frame, free):
    """Both blend the lit colour by _Color.a = 0.55 (Fade: 'Blend SrcAlpha OneMinusSrcAlpha'; Transparent:
    'Blend One OneMinusSrcAlpha' over a colour the program premultiplied, the same rgb). Over the opaque
    backdrop (alpha 1) Fade leaves alpha a·a + 1·(1 − a) = 0.7525 → 192; Transparent a + 1·(1 − a) = 1 → 255."""
    a = 0.55
    for name, alpha_code in (("Standard Fade", 192), ("Standard Transparent", 255)):
        r = renderer(draw, name)
        mask, lit = alone(draw, r)
        mask &= free
        behind = without(draw, name)
        assert mask.sum() > 300
        assert (behind[mask][:, 3] == 255).all()
        assert (frame[mask][:, 3] == alpha_code).all(), name
        expected = quantise(lit[mask][:, :3] / 255.0 * a + behind[mask][:, :3] / 255.0 * (1.0 - a))
        assert np.abs(frame[mask][:, :3] - expected).max() <= 1, name
    assert quantise(a * a + (1.0 - a)) == 192


# --------------------------------------------------------------------------- the builder


def test_the_builder_names_the_missing_corpus_in_one_line(monkeypatch, tmp_path):
    """scripts/unity_builtins.py needs Unity's built-in shader source; without it, one clear line."""
    from scripts import unity_builtins

    monkeypatch.setattr(unity_builtins, "default_corpus", lambda: tmp_path / "unity-builtin-shaders-2019.4")
    with pytest.raises(SystemExit) as exc:
        unity_builtins.builtin_shaders()
    message = str(exc.value)
    assert "\n" not in message and str(tmp_path / "unity-builtin-shaders-2019.4") in message
    assert "shared/corpus/unity-builtin-shaders-2019.4" in message
