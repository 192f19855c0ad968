"""The foliage example (blend_files/foliage.blend, scripts/make_blend_files.py ``build_foliage``): the
phenomena of alpha-tested leaves in numbers, from the definitions.

Two scenes share one collection: ``Foliage`` (MSAA off) and ``FoliageMSAA`` (MSAA 4x). Four columns
of leaf patches (the same 64x64 leaf texture, _Cutoff 0.5, Unlit): no mipmaps (Bilinear), mipmaps
(Trilinear), mipmaps with Preserve Coverage, and mipmaps with Preserve Coverage and AlphaToMask
without clip. The top row is near; the bottom row is ``FAR`` times farther and larger with the same
leaves, so the same screen size shows ``FAR`` times the texels per pixel (LOD ≈ log2 FAR higher).

- Mipmaps: level L is the 2x2 box average of level L-1 (Unity's texture importer); alpha-tested
  texels whose neighbours are transparent average below _Cutoff, so far leaves vanish. Without
  mipmaps the far patch samples level 0 and keeps its coverage (aliased: the shimmer of far foliage).
- Preserve Coverage: each level's alpha is scaled so that its share of texels at or above _Cutoff
  is level 0's (Unity's "Mip Maps Preserve Coverage").
- AlphaToMask (decisions.md, docs/pipeline.md §10): with N samples, sample s is covered iff
  alpha > s/N; with MSAA off it has no effect (the whole quad is drawn).
- MSAA shades once per pixel and alpha-tests per pixel: inside a quad every sample of a pixel holds
  the same colour, so MSAA does not smooth alpha-tested edges (only geometric ones).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from blendlib.core.vocabulary import Pass
from tests.support import goldens as mg

CUTOFF = 0.5
COLUMNS = ("no mipmaps", "mipmaps (Trilinear)", "+ Preserve Coverage", "AlphaToMask, no clip")


@pytest.fixture(scope="module")
def scenes() -> dict:
    return mg.load_draw_scenes(mg.BLEND_DIR / "foliage.blend")


def renderer(draw, name: str):
    (r,) = [r for r in draw.renderers if r.name == name]
    return r


def alone(draw, r, **material_changes) -> dict[str, np.ndarray]:
    """The codes of ``draw`` with only renderer ``r`` (its material changed by ``material_changes``)."""
    r = dataclasses.replace(r, material=dataclasses.replace(r.material, **material_changes))
    return mg.render_codes(dataclasses.replace(draw, renderers=(r,)))


def quad_interior(draw, r) -> np.ndarray:
    """(H, W) bool: the pixels of ``r``'s quad one pixel in from its outline (every sample covered)."""
    quad = alone(draw, r, passes=(Pass(),))["depth"] < mg.DMAX
    ys, xs = np.nonzero(quad)
    inner = np.zeros_like(quad)
    inner[ys.min() + 1:ys.max(), xs.min() + 1:xs.max()] = True
    return inner


def coverage(draw, name: str) -> float:
    """The share of the quad's interior pixels where ``name``'s alpha-tested leaves are drawn."""
    r = renderer(draw, name)
    inner = quad_interior(draw, r)
    return float((alone(draw, r)["depth"] < mg.DMAX)[inner].mean())


def box_levels(alpha: np.ndarray) -> list[np.ndarray]:
    """The mip levels of a square power-of-two alpha by 2x2 box averages, level 0 first."""
    levels = [alpha]
    while levels[-1].shape[0] > 1:
        a = levels[-1]
        levels.append((a[0::2, 0::2] + a[0::2, 1::2] + a[1::2, 0::2] + a[1::2, 1::2]) / 4)
    return levels


def leaf_alpha(draw) -> np.ndarray:
    return np.asarray(renderer(draw, "Near no mipmaps").material.main_tex.pixels, np.float64)[..., 3]


def far_lod(draw) -> float:
    """log2 of the far patch's texels per pixel: FAR x 64 texels across its width in pixels."""
    r = renderer(draw, "Far no mipmaps")
    quad = alone(draw, r, passes=(Pass(),))["depth"] < mg.DMAX
    xs = np.nonzero(quad.any(axis=0))[0]
    return float(np.log2(8 * 64 / (xs.max() - xs.min() + 1)))


@pytest.mark.parametrize("scene", ["Foliage", "FoliageMSAA"])
def test_far_leaves_vanish_with_mipmaps_and_keep_level_0s_coverage_without(scenes, scene):
    draw = scenes[scene]
    alpha = leaf_alpha(draw)
    levels = box_levels(alpha)
    base = float((alpha >= CUTOFF).mean())  # level 0's coverage at _Cutoff
    assert 0.15 < base < 0.2
    lod = far_lod(draw)
    assert 2.8 < lod < 3.2  # FAR = 8: three levels down
    level3 = float((levels[3] >= CUTOFF).mean())
    assert level3 < base / 2  # the box filter averages the narrow leaves below _Cutoff
    for column in COLUMNS[:3]:  # near, about one texel per pixel: level 0's coverage
        assert coverage(draw, f"Near {column}") == pytest.approx(base, abs=0.03)
    # without mipmaps the far patch samples level 0 everywhere: its coverage stays level 0's
    assert coverage(draw, "Far no mipmaps") == pytest.approx(base, abs=0.03)
    # with them it samples levels 3 and 4, whose alpha lost the leaves: bilinear filtering of the
    # few texels still at or above _Cutoff leaves less than their share
    plain = coverage(draw, "Far mipmaps (Trilinear)")
    assert plain <= level3
    assert plain < base / 4


@pytest.mark.parametrize("scene", ["Foliage", "FoliageMSAA"])
def test_preserve_coverage_keeps_more_of_the_far_leaves(scenes, scene):
    """Preserve Coverage scales each level's alpha until its share of texels at or above _Cutoff is
    level 0's: the far patch keeps several times the plain mipmaps' leaves (filtering still thins
    them: bilinear samples between isolated covered texels fall below _Cutoff)."""
    draw = scenes[scene]
    base = float((leaf_alpha(draw) >= CUTOFF).mean())
    plain = coverage(draw, "Far mipmaps (Trilinear)")
    preserved = coverage(draw, "Far + Preserve Coverage")
    assert preserved > 2.5 * plain
    assert preserved < base
    assert coverage(draw, "Near + Preserve Coverage") == pytest.approx(base, abs=0.03)  # level 0 unchanged


def test_alpha_to_mask_without_msaa_has_no_effect(scenes):
    """MSAA off: AlphaToMask changes nothing, and the pass has no clip: the whole quad is drawn."""
    draw = scenes["Foliage"]
    assert draw.msaa == 1 and scenes["FoliageMSAA"].msaa == 4
    for row in ("Near", "Far"):
        r = renderer(draw, f"{row} AlphaToMask, no clip")
        assert r.material.passes[0].alpha_to_mask and not r.material.passes[0].alpha_test
        assert coverage(draw, r.name) == 1.0


def resolve_codes(codes: np.ndarray, count: np.ndarray, samples: int = 4) -> np.ndarray:
    """docs/pipeline.md §10's LDR resolve of ``count`` samples holding 8-bit ``codes`` and the
    others 0 (a black clear): float32 sum in sample order, times float32(1/N), rint of x 255."""
    v = (codes.astype(np.float32) * np.float32(1 / 255)).astype(np.float32)
    acc = np.zeros_like(v)
    for s in range(samples):
        acc = np.where((count > s)[..., None], (acc + v).astype(np.float32), acc)
    avg = (acc * np.float32(1 / samples)).astype(np.float32)
    return np.rint((avg * np.float32(255)).astype(np.float32)).astype(np.int64)


def test_alpha_to_mask_at_4x_covers_ceil_4_alpha_samples(scenes):
    """MSAA 4x: sample s is covered iff alpha > s/4, so a pixel inside the near AlphaToMask patch
    drawn alone over black resolves to the shader's colour times ceil(4 alpha) / 4 — 1, 2, 3 and 4
    samples all occur along the leaves' soft edges."""
    draw = scenes["FoliageMSAA"]
    r = renderer(draw, "Near AlphaToMask, no clip")
    inner = quad_interior(draw, r)
    black = dataclasses.replace(draw, clear_color=(0.0, 0.0, 0.0, 0.0))
    shader = mg.render_codes(dataclasses.replace(black, msaa=1, renderers=(r,)))["color"].astype(np.int64)
    resolved = mg.render_codes(dataclasses.replace(black, renderers=(r,)))["color"].astype(np.int64)
    alpha = shader[..., 3] / 255.0  # the shader's alpha to within half a step
    thresholds = np.arange(4) / 4  # s/4 for s = 0..3
    clear_of_ties = np.abs(alpha[..., None] - thresholds).min(axis=-1) > 0.5 / 255
    count = (alpha[..., None] > np.arange(4) / 4).sum(axis=-1)
    expected = resolve_codes(shader[..., :3], count)
    check = inner & clear_of_ties
    assert np.array_equal(resolved[..., :3][check], expected[check])
    assert np.isin(np.arange(1, 5), count[check]).all()
    # alpha 0 (code 0: within half a step of the threshold 0, so not checked above) covers nothing:
    # most of the quad stays black, the soft leaves are not a quad
    assert (resolved[inner][:, :3] == 0).all(axis=-1).mean() > 0.5


def test_msaa_does_not_smooth_alpha_tested_edges(scenes):
    """Shading and the alpha test run once per pixel: inside the alpha-tested quads every sample of
    a pixel is written with the same colour or none is, so the 4x frame equals the frame without
    MSAA on every interior pixel (the resolve of four equal codes is the code)."""
    plain = mg.render_codes(scenes["Foliage"])["color"]
    msaa = mg.render_codes(scenes["FoliageMSAA"])["color"]
    draw = scenes["FoliageMSAA"]
    for column in COLUMNS[:3]:
        for row in ("Near", "Far"):
            inner = quad_interior(draw, renderer(draw, f"{row} {column}"))
            assert np.array_equal(plain[inner], msaa[inner]), f"{row} {column}"
    # where AlphaToMask turns alpha into coverage, the edges are resolved to in-between colours
    inner = quad_interior(draw, renderer(draw, "Near AlphaToMask, no clip"))
    assert (plain[inner] != msaa[inner]).any(axis=-1).mean() > 0.5
