"""scripts/stage_profile.py maps a one-thread render's profile to pipeline stages."""

from __future__ import annotations

import numpy as np

from blendlib.core.vocabulary import Material, preset
from scripts import stage_profile
from tests.reference import scenes as sc


def _planes(n: int, near_first: bool = False):
    """``n`` alpha-blended planes, plane i at z = 0.01 i (nearer as i grows); ``near_first``: queue
    offsets -i draw them near to far, every pair inverted."""
    queue, passes = preset("Alpha Blend")
    rs = [sc.renderer(sc.quad(-4, -2.5, 4, 2.5, uv=False, z=0.01 * i),
                      Material(name=f"M{i}", color=(0.2, 0.4, 0.6, 0.3), queue=queue, passes=passes,
                               queue_offset=-i if near_first else 0), name=f"P{i}")
          for i in range(n)]
    return sc.scene(sc.camera(160, 90, eye=(0, 0, 10), fov=60), *rs)


def test_stages_cover_the_render_and_follow_the_work():
    total, seconds = stage_profile.profile_draw(_planes(6))
    assert tuple(seconds) == stage_profile.ORDER
    assert all(v >= 0 for v in seconds.values())
    # The stages and "other" partition the render's time (no stage function nests in another).
    assert np.isclose(sum(seconds.values()), total, rtol=1e-9)
    # Constant-colour planes: shaded once per triangle, so merging and coverage outweigh shading.
    assert seconds["coverage"] > 0 and seconds["merge"] > 0 and seconds["setup"] > 0
    assert seconds["interpolation"] == 0.0  # no depth (hierarchical-Z) and no varying attributes


def test_analysis_phases_partition_analyze_and_advise():
    times = stage_profile.profile_analysis(_planes(4, near_first=True))
    assert set(stage_profile.ANALYSIS_COLUMNS) | {"plain"} == set(times)
    assert all(v >= 0 for v in times.values()) and times["plain"] > 0
    parts = sum(times[k] for k in ("render", "step 2", "reference", "analyze other"))
    assert np.isclose(parts, times["analyze"], rtol=1e-9)
    assert np.isclose(times["advise renders"] + times["advise other"], times["advise"], rtol=1e-9)
    # Transparent planes: the observed render and step 2 (the sort) both run; the advice re-renders.
    assert times["render"] > 0 and times["step 2"] > 0 and times["advise renders"] > 0
