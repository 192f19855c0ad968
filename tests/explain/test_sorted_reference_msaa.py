"""docs/sorting.md with MSAA: the sorted reference per sample — each sample's transparent fragments
sorted by that sample's depth, resolved as the frame is — equals the scalar reference's sorted mode
bit for bit, and the per-pixel statistics keep their definitions."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from blendlib.core.drawlist import draw_calls
from blendlib.core.vocabulary import Queue, SortMode
from blendlib.explain import advice
from blendlib.explain.advice import analyze_and_advise
from blendlib.explain.sorted_reference import analyze
from tests.explain.test_sorted_reference import BLEND, transparent
from tests.explain.test_sorted_reference import assert_reference as assert_sorted_reference
from tests.reference import scenes as sc
from tests.reference.random_scenes import scenes, seeded_scene
from tests.reference.scalar import FragmentLog, render_reference


def assert_reference(scene):
    """:func:`assert_sorted_reference`, and the frame equal to the scalar reference's."""
    result = assert_sorted_reference(scene)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        frame, _, _ = render_reference(scene)
    assert np.array_equal(result.frame.color, frame)
    return result


@pytest.mark.parametrize("samples", [2, 4, 8])
@pytest.mark.parametrize("seed", range(0, 60, 6))
def test_msaa_scenes_equal_the_scalar_sorted_reference_per_sample(seed, samples):
    assert_reference(seeded_scene(seed, msaa=samples))
    assert_reference(transparent(seeded_scene(seed, msaa=samples)))
    assert_reference(transparent(seeded_scene(seed + 1, shared=False, msaa=samples), every=2))



@settings(max_examples=30, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(scenes(msaa=0), st.integers(1, 3))
def test_random_msaa_scenes_equal_the_scalar_sorted_reference(scene, every):
    """Every state, stencil, depth test, alpha test and AlphaToMask the random scenes draw."""
    assert_reference(transparent(scene, every=every))

def test_crossing_quads_are_sorted_sample_by_sample():
    """Two 40 % quads crossing in depth: along the crossing the samples of one pixel lie on
    either side of it, so each sample takes its own order — those pixels resolve to colours
    between the two orders' (neither quad wholly in front), the scalar reference's exactly."""
    cam = sc.screen_camera(16, 8)
    mat = sc.unlit((0.2, 0.9, 0.3, 0.4), queue=Queue.Transparent, passes=[BLEND])
    other = sc.unlit((0.9, 0.2, 0.6, 0.4), queue=Queue.Transparent, passes=[BLEND])
    rising = sc.make_mesh([(0, 0, -4), (16, 0, 4), (16, 8, 4), (0, 8, -4)], [(0, 1, 2), (0, 2, 3)])
    falling = sc.make_mesh([(0, 0, 3.7), (16, 0, -4.3), (16, 8, -4.3), (0, 8, 3.7)], [(0, 1, 2), (0, 2, 3)])
    scene = replace(sc.scene(cam, sc.renderer(rising, mat, name="A"), sc.renderer(falling, other, name="B")), msaa=4)
    result = assert_reference(scene)
    ref = np.rint(result.reference[..., :3] * 255).astype(np.int64)
    left, right = ref[4, 1], ref[4, 14]  # B nearer on the left, A nearer on the right
    assert np.abs(left - right).max() > 20
    row = ref[4]
    between = [x for x in range(16) if not (np.array_equal(row[x], left) or np.array_equal(row[x], right))]
    assert between, row.tolist()
    for x in between:  # each such pixel mixes the two orders' sample colours
        lo, hi = np.minimum(left, right), np.maximum(left, right)
        assert np.all((row[x] >= lo - 1) & (row[x] <= hi + 1)), (x, row[x], left, right)
    # B (its centre farther) is drawn first, so where it is nearer — the left — the pair (B, A) is
    # inverted, every sample there and some samples of the crossing pixels
    assert [c.renderer.name for c in draw_calls(scene)] == ["B", "A"]
    assert [(i.front, i.behind) for i in result.inversions] == [(("B", 0), ("A", 0))]
    inverted = result.inverted > 0
    assert inverted[:, :7].all() and not inverted[:, 9:].any()
    assert 4 * 8 * 7 < result.inversions[0].pixels < 4 * 8 * 9  # counted in samples


@pytest.mark.parametrize("seed", [4, 9, 17])
def test_msaa_overdraw_counts_pixel_fragments_as_the_scalar_reference_logs_them(seed):
    """Overdraw with MSAA: per pixel, the pixel fragments rasterised (a sample covered) and those
    with a sample written — the draw list's ``fragments`` and ``written``."""
    scene = transparent(seeded_scene(seed, msaa=4), every=2)
    cam = scene.camera
    log = FragmentLog()
    render_reference(scene, log=log)
    expected = np.zeros((cam.height, cam.width, 2), dtype=np.int64)
    for _, x, y, _, _, _, results, _ in log.fragments:
        expected[y, x, 0] += 1
        expected[y, x, 1] += "written" in results.values()
    result = analyze(scene)
    assert result.overdraw.sum() > 0
    assert np.array_equal(result.overdraw, expected[::-1])


def test_advice_measures_msaa_scenes_per_sample():
    """Advice renders changed scenes with MSAA too; its pair counts are the analysis's (in samples)."""
    scene = transparent(seeded_scene(18, msaa=4))
    result = analyze_and_advise(scene)
    assert result.inversions
    measurer = advice._Measurer(scene, result, [(i.front, i.behind) for i in result.inversions], None, None)
    changed = replace(scene, sort_mode=SortMode.Orthographic if scene.sort_mode is not SortMode.Orthographic
                      else SortMode.Perspective)
    counts, _ = measurer.measure(changed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        again = analyze(changed)
    for pair, count in counts.items():
        assert count == again.pair_pixels(*pair)
