"""The alpha test's comparison (``Pass.alpha_test_comp``, SPEC §11.4): a fragment survives when
``alpha <comp> _Cutoff``; GEqual is the book's ``clip(alpha - _Cutoff)``.

Every comparison is also swept against the scalar and OpenGL references
(``tests/reference/sweeps.py``: ``alpha_test_comp``); here the values are checked by hand, and
draw calls fused for shared shading each test with their own comparison.
"""

from __future__ import annotations

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core import fragment
from blendlib.core.scene import DrawScene
from blendlib.core.vocabulary import CompareFunction, Lighting, Material, Pass, Texture, TextureFilter
from tests.reference.scalar import render_reference
from tests.reference.scenes import quad, renderer, screen_camera

ALPHAS = np.array([0.0, 0.25, 0.5, 0.75, 1.0, np.nan])
#: Which of ALPHAS survive against a cutoff of 0.5: the legacy AlphaTest command's comparisons
#: (Unity manual, "ShaderLab: legacy alpha testing"); GEqual as clip(alpha - 0.5), under which a
#: NaN difference is not negative and the fragment is kept.
SURVIVORS = {
    CompareFunction.GEqual: [False, False, True, True, True, True],
    CompareFunction.Greater: [False, False, False, True, True, False],
    CompareFunction.Less: [True, True, False, False, False, False],
    CompareFunction.LEqual: [True, True, True, False, False, False],
    CompareFunction.Equal: [False, False, True, False, False, False],
    CompareFunction.NotEqual: [True, True, False, True, True, True],
    CompareFunction.Always: [True] * 6,
    CompareFunction.Never: [False] * 6,
}


@pytest.mark.parametrize("comp", list(CompareFunction))
def test_every_comparison_by_hand(comp):
    rgba = np.zeros((ALPHAS.size, 4))
    rgba[:, 3] = ALPHAS
    want = np.array(SURVIVORS[comp])
    np.testing.assert_array_equal(fragment.alpha_test(rgba, None, None, 0.5, comp), want)
    # The same alphas from a palette (flat triangles), and half from each.
    palette, ids = rgba, np.arange(ALPHAS.size, dtype=np.int32)
    np.testing.assert_array_equal(fragment.alpha_test(None, ids, palette, 0.5, comp), want)
    mixed = np.where(np.arange(ALPHAS.size) % 2 == 0, ids, -1).astype(np.int32)
    np.testing.assert_array_equal(fragment.alpha_test(rgba, mixed, palette, 0.5, comp), want)


def test_geequal_is_the_default_and_the_books_clip():
    rgba = np.zeros((ALPHAS.size, 4))
    rgba[:, 3] = ALPHAS
    np.testing.assert_array_equal(fragment.alpha_test(rgba, None, None, 0.5), ~(ALPHAS - 0.5 < 0))
    assert Pass().alpha_test_comp is CompareFunction.GEqual


def test_fused_calls_each_test_their_own_comparison(monkeypatch):
    """Eight quads with one texture and material, one per comparison, are shaded together
    (``fuse.fuse_shared_shading``) and each keeps exactly the texels its comparison passes: the
    texture maps one texel to one pixel, so a quad's drawn pixels are counted by hand."""
    from blendlib.core import pipeline

    rng = np.random.default_rng(3)
    cell = 4
    texels = np.ones((cell, cell, 4), np.float32)
    texels[..., :3] = rng.uniform(0.2, 1.0, (cell, cell, 3))
    texels[..., 3] = rng.choice(np.array([0.0, 0.25, 0.5, 0.75, 1.0], np.float32), (cell, cell))
    texture = Texture(texels, encoding="Data", name="alphas")
    comps = list(CompareFunction)
    renderers = []
    for k, comp in enumerate(comps):
        mat = Material(name="Cut", main_tex=texture, main_tex_filter=TextureFilter.Point, cutoff=0.5,
                       lighting=Lighting.Unlit, passes=(Pass(alpha_test=True, alpha_test_comp=comp),))
        renderers.append(renderer(quad(k * cell, 0, (k + 1) * cell, cell), mat, name=f"Quad{k}"))
    clear = (0.0, 0.0, 0.0, 0.0)
    scene = DrawScene(camera=screen_camera(cell * len(comps), cell), renderers=tuple(renderers), light=None,
                      clear_color=clear)
    groups = []
    original = pipeline.fuse_shared_shading

    def recording(prepared, memo=None):
        out = original(prepared, memo)
        groups.append((len(prepared), len(out)))
        return out

    monkeypatch.setattr(pipeline, "fuse_shared_shading", recording)
    frame = render_scene(scene, workers=1)
    assert groups and groups[0][1] < groups[0][0]  # the quads were shaded together
    color, _, _ = render_reference(scene)
    np.testing.assert_array_equal(frame.color, color)
    alpha = texels[..., 3].astype(np.float64)
    for k, comp in enumerate(comps):
        drawn = int(np.any(frame.color[:, k * cell:(k + 1) * cell] != clear, axis=-1).sum())
        expect = {CompareFunction.GEqual: alpha >= 0.5, CompareFunction.Greater: alpha > 0.5,
                  CompareFunction.Less: alpha < 0.5, CompareFunction.LEqual: alpha <= 0.5,
                  CompareFunction.Equal: alpha == 0.5, CompareFunction.NotEqual: alpha != 0.5,
                  CompareFunction.Always: alpha == alpha, CompareFunction.Never: alpha != alpha}[comp]
        assert drawn == int(expect.sum()), comp


def _cutout_scene(mode, mipmaps: bool) -> DrawScene:
    """A lit quad with smooth per-corner normals and colours, a random texture with alpha in
    [0, 1] (Bilinear, or Trilinear with mipmaps, tiled so several levels are sampled) and an alpha
    test that discards about half of its fragments, over an opaque backdrop."""
    from blendlib.core.scene import Light, Mesh
    from blendlib.core.vocabulary import Queue, TextureWrap

    rng = np.random.default_rng(9)
    texture = Texture(rng.uniform(0, 1, (16, 16, 4)).astype(np.float32), name="leaves")
    base = quad(0, 0, 48, 40, z=1.0)
    normals = rng.uniform(-0.3, 0.3, size=(2, 3, 3)).astype(np.float32)
    normals[..., 2] = 1.0
    colors = rng.uniform(0.3, 1.0, size=(2, 3, 4)).astype(np.float32)
    mesh = Mesh(base.positions, base.triangles, normals, base.uvs, colors=colors, color_encoding="sRGB")
    cutout = Material(name="Cutout", queue=Queue.AlphaTest, color=(0.9, 0.8, 0.7, 0.95), main_tex=texture,
                      main_tex_filter=TextureFilter.Trilinear if mipmaps else TextureFilter.Bilinear,
                      main_tex_wrap=TextureWrap.Repeat, main_tex_tiling=(3.0, 2.0) if mipmaps else (1.0, 1.0),
                      main_tex_mipmaps=mipmaps, lighting=Lighting.Lambert, vertex_color=mode, cutoff=0.45,
                      tint_color=(0.6, 0.5, 0.4, 0.7), passes=(Pass(alpha_test=True),))
    back = Material(name="Back", color=(0.2, 0.3, 0.4, 1.0), lighting=Lighting.Unlit)
    return DrawScene(camera=screen_camera(48, 40), light=Light(direction=(0.3, 0.2, 0.9)), ambient=(0.2, 0.2, 0.2),
                     renderers=(renderer(quad(0, 0, 48, 40, z=-1.0), back, name="Back"),
                                renderer(mesh, cutout, name="Cutout")))


@pytest.mark.parametrize("mipmaps", [False, True])
@pytest.mark.parametrize("mode", ["Off", "Multiply", "Particle"])
def test_alpha_is_tested_before_the_rest_is_shaded(mode, mipmaps, monkeypatch):
    """The fragment's alpha reads neither lighting nor the outline, so a textured pass with an
    alpha test samples the texture's alpha first and shades only the fragments that pass; the
    frame equals the scalar reference. Observed, every fragment is shaded (the frame debugger
    shows discarded fragments' colours)."""
    from blendlib.core import mips, pipeline, shade
    from blendlib.core.vocabulary import VertexColor

    scene = _cutout_scene(VertexColor[mode], mipmaps)
    shaded = []
    original = shade.shade_texels
    monkeypatch.setattr(shade, "shade_texels", lambda material, tex, lights, space, normal, *args, **kw: shaded.append(
        (material.name, normal.shape[0])) or original(material, tex, lights, space, normal, *args, **kw))
    sampled = []  # (channels, fragments) of each texture sample (the backdrop has no texture)
    module, name = (mips, "sample_mipmapped") if mipmaps else (shade, "sample")
    real = getattr(module, name)
    monkeypatch.setattr(module, name, lambda *a, **kw: sampled.append((tuple(a[-1]), a[1].shape[0]))
                        or real(*a, **kw))
    frame = render_scene(scene, workers=1)
    # The alpha is sampled once, for every fragment; the survivors' red, green and blue alone after it.
    assert [n for channels, n in sampled if 3 in channels] == [48 * 40]
    color, depth, _ = render_reference(scene)
    np.testing.assert_array_equal(frame.color, color)
    np.testing.assert_array_equal(frame.depth, depth)
    cut = sum(count for name, count in shaded if name == "Cutout")
    assert 0.2 * 48 * 40 < cut < 0.8 * 48 * 40, cut  # the survivors only
    assert sum(n for channels, n in sampled if channels == (0, 1, 2)) == cut
    # They are exactly the fragments that passed: the pixels where the quad changed the frame.
    backdrop = render_scene(DrawScene(camera=scene.camera, light=scene.light, ambient=scene.ambient,
                                      renderers=scene.renderers[:1]), workers=1)
    assert cut == int(np.any(frame.color != backdrop.color, axis=-1).sum())
    shaded.clear()
    render_scene(scene, workers=1, observer=pipeline.FrameObserver())
    assert sum(count for name, count in shaded if name == "Cutout") == 48 * 40


@pytest.mark.parametrize("mipmaps", [False, True])
def test_a_few_discarded_fragments_are_shaded_with_the_rest_from_the_alpha_sampled_once(mipmaps, monkeypatch):
    """When the alpha test discards only a few fragments, all are shaded (a discarded one's colour
    is never read) rather than the survivors gathered out: the texture's alpha, sampled for the
    test, is not sampled again, and the frame equals the scalar reference."""
    from dataclasses import replace

    from blendlib.core import mips, shade
    from blendlib.core.vocabulary import VertexColor

    scene = _cutout_scene(VertexColor.Multiply, mipmaps)
    cut = replace(scene.renderers[1].material, cutoff=0.1)
    scene = replace(scene, renderers=(scene.renderers[0], replace(scene.renderers[1], material=cut)))
    sampled = []
    module, name = (mips, "sample_mipmapped") if mipmaps else (shade, "sample")
    real = getattr(module, name)
    monkeypatch.setattr(module, name, lambda *a, **kw: sampled.append((tuple(a[-1]), a[1].shape[0]))
                        or real(*a, **kw))
    frame = render_scene(scene, workers=1)
    color, depth, _ = render_reference(scene)
    np.testing.assert_array_equal(frame.color, color)
    np.testing.assert_array_equal(frame.depth, depth)
    backdrop = render_scene(replace(scene, renderers=scene.renderers[:1]), workers=1)
    survivors = int(np.any(frame.color != backdrop.color, axis=-1).sum())
    assert 0 < 48 * 40 - survivors < 48 * 40 // 8  # a few discarded
    assert sampled == [((3,), 48 * 40), ((0, 1, 2), 48 * 40)]
