"""render_scene's ``band``: one process's share of a frame (the band helper of
blendlib.runtime.bandprocs draws one, this process the other). A band must equal the full
frame's rows bit for bit, whatever the cut.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from blendlib import SceneError, render_scene
from blendlib.core import raster, vertex
from blendlib.core.drawlist import draw_calls
from blendlib.core.prepare import setup_input
from blendlib.core.records import FrameObserver
from tests.reference.random_scenes import seeded_scene


def scene_at(seed: int, width: int = 72, height: int = 48):
    draw = seeded_scene(seed)
    return dataclasses.replace(draw, camera=dataclasses.replace(draw.camera, width=width, height=height))


@pytest.mark.parametrize("seed", [1, 4, 7, 12])
def test_band_renders_are_the_rows_of_the_full_frame(seed):
    """render_scene(band=...) draws exactly the full frame's rows, for cuts at the edges too
    (stencil, blending and depth writes of random scenes)."""
    draw = scene_at(seed)
    full = render_scene(draw, workers=1)
    height = draw.camera.height
    for cut in (1, 17, height // 2, height - 1):
        low = render_scene(draw, workers=1, band=(0, cut))
        high = render_scene(draw, workers=2, band=(cut, height))
        assert low.color.shape == (cut, draw.camera.width, 4)
        np.testing.assert_array_equal(np.concatenate([high.color, low.color]), full.color)
        np.testing.assert_array_equal(np.concatenate([high.depth, low.depth]), full.depth)
        np.testing.assert_array_equal(np.concatenate([high.stencil, low.stencil]), full.stencil)
        assert low.warnings == full.warnings == high.warnings


def test_coverage_rows_in_a_band_are_the_full_rows_there():
    draw = scene_at(5, 64, 40)
    renderer = next(r for r in draw.renderers if r.mesh.triangle_count)
    setup = vertex.setup_renderers([setup_input(renderer)], draw.camera)[0]
    selected = np.arange(setup.X.shape[0], dtype=np.int64)
    full = raster.coverage_rows(setup, selected, 64, 40)
    part = raster.coverage_rows(setup, selected, 64, 40, band=(9, 23))
    keep = (full.y >= 9) & (full.y < 23)
    assert 0 < part.count < full.count
    for name in raster.Rows.__dataclass_fields__:
        if getattr(full, name) is None:  # per-sample masks: MSAA only
            assert getattr(part, name) is None, name
            continue
        np.testing.assert_array_equal(getattr(part, name), getattr(full, name)[keep])


class _After(FrameObserver):
    exact_boundaries = True
    per_sample = True  # reads the buffers only

    def __init__(self, k: int) -> None:
        self.k, self.buffers = k, None

    def draw_end(self, call, buffers, triangles) -> None:
        if call.index == self.k:
            self.buffers = buffers.copy()


@pytest.mark.parametrize(("seed", "msaa"), [(1, 1), (4, 1), (7, 1), (4, 4)])
def test_band_renders_resume_from_buffers(seed, msaa):
    """A band with ``resume``: the band's rows of the full frame resumed from the same buffers
    (with MSAA too: every sample plane's rows)."""
    draw = dataclasses.replace(scene_at(seed), msaa=msaa)
    calls = len(draw_calls(draw))
    k = max(1, calls // 2)
    after = _After(k)
    render_scene(draw, workers=1, observer=after)
    full = render_scene(draw, workers=1, resume=(after.buffers, k))
    height = draw.camera.height
    for y0, y1 in ((0, 17), (11, height), (5, 6)):
        part = render_scene(draw, workers=2, resume=(after.buffers, k), band=(y0, y1))
        np.testing.assert_array_equal(part.color, full.color[height - y1:height - y0])
        np.testing.assert_array_equal(part.depth, full.depth[height - y1:height - y0])
        np.testing.assert_array_equal(part.stencil, full.stencil[height - y1:height - y0])


@pytest.mark.parametrize(("seed", "msaa"), [(4, 1), (8, 1), (15, 1), (18, 1), (8, 4)])
def test_resumed_renders_leave_the_buffers_they_resume_from_as_they_were(seed, msaa):
    """From every draw call on: a resumed render shares the depth and stencil buffers it
    resumes from when no later call writes either (ZWrite On or a stencil block), and copies
    them when one does; either way those buffers are left bit for bit as they were, and the
    frame (in a band too) is the whole render's."""
    draw = dataclasses.replace(scene_at(seed), msaa=msaa)
    calls = draw_calls(draw)
    full = render_scene(draw, workers=1)
    height = draw.camera.height
    shared = 0
    for k in range(1, len(calls)):
        after = _After(k)
        render_scene(draw, workers=1, observer=after)
        kept = {name: rows.copy() for name, rows in after.buffers.by_row().items()}
        shared += not any(c.state.zwrite or c.state.stencil for c in calls[k:])
        frame = render_scene(draw, workers=1, resume=(after.buffers, k))
        part = render_scene(draw, workers=2, resume=(after.buffers, k), band=(3, height - 5))
        for name, rows in after.buffers.by_row().items():
            np.testing.assert_array_equal(rows, kept[name], err_msg=f"{name} after resuming from draw {k}")
        for got, want in ((frame.color, full.color), (frame.depth, full.depth), (frame.stencil, full.stencil)):
            np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(part.color, full.color[5:height - 3])
        np.testing.assert_array_equal(part.depth, full.depth[5:height - 3])
    assert 0 < shared < len(calls) - 1  # both kinds of resume


def test_bad_bands_are_one_line_errors():
    draw = scene_at(2)
    for band in ((0, 0), (-1, 4), (10, 49), (30, 20)):
        with pytest.raises(SceneError, match="band"):
            render_scene(draw, band=band)


def test_band_renders_write_into_given_arrays():
    """``out``: a band goes straight into its rows of a whole frame's arrays."""
    draw = scene_at(7)
    full = render_scene(draw, workers=1)
    height, width = draw.camera.height, draw.camera.width
    color = np.full((height, width, 4), -1.0, dtype=np.float32)
    depth = np.full((height, width), -1.0, dtype=np.float32)
    stencil = np.full((height, width), 7, dtype=np.uint8)
    cut = 20  # buffer rows [0, 20) are the bottom 20 rows of the image
    frame = render_scene(draw, band=(0, cut), out=(color[height - cut:], depth[height - cut:], stencil[height - cut:]))
    assert np.shares_memory(frame.color, color) and np.shares_memory(frame.stencil, stencil)
    np.testing.assert_array_equal(color[height - cut:], full.color[height - cut:])
    np.testing.assert_array_equal(depth[height - cut:], full.depth[height - cut:])
    np.testing.assert_array_equal(stencil[height - cut:], full.stencil[height - cut:])
    assert np.all(color[:height - cut] == -1.0) and np.all(stencil[:height - cut] == 7)  # other rows untouched
    with pytest.raises(ValueError, match="out array"):
        render_scene(draw, band=(0, cut), out=(color, depth[height - cut:], stencil[height - cut:]))
