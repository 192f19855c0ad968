"""Heat-map legends (blendlib/formats/heatmap.py): ticks at round values, the data never under text."""

from __future__ import annotations

import numpy as np
import pytest

from blendlib.formats import heatmap


def test_ticks_at_round_values_between_zero_and_the_peak():
    """Before, the overdraw legend had ticks at 0 and the maximum only."""
    assert heatmap.tick_values(7, 600, integer=True) == [0, 1, 2, 3, 4, 5, 6, 7]
    assert heatmap.tick_values(46, 600) == [0, 5, 10, 15, 20, 25, 30, 35, 40, 45, 46]
    assert heatmap.tick_values(46, 120) == [0, 20, 40, 46]
    assert heatmap.tick_values(0.3, 600) == pytest.approx([0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3])
    assert heatmap.tick_values(3, 600, integer=True) == [0, 1, 2, 3]  # counts: never 0.5
    assert heatmap.tick_values(0, 600) == [0.0]


def test_legend_ticks_are_drawn_where_the_bar_has_those_values():
    values = np.tile(np.arange(640, dtype=np.float64) / 639 * 46, (20, 1))
    image = heatmap.heat_image(values, "error in 8-bit steps")
    assert image.shape == (20 + heatmap.LEGEND_HEIGHT, 640, 4)
    tick_row = image[20 + 15, :, :3]  # the tick marks below the bar are white
    white = np.flatnonzero((tick_row == 1).all(axis=1))
    margin, length = 4, 632
    expected = [margin + round(t / 46 * (length - 1)) for t in heatmap.tick_values(46, length)]
    assert white.tolist() == expected


def test_panel_names_sit_above_the_maps_not_over_them():
    """Before, each panel's name was written into its top-left corner, over the data."""
    a = np.full((30, 50), 2.0)
    b = np.zeros((30, 50))
    image = heatmap.heat_panels([(a, "rasterised"), (b, "written")], "fragments per pixel", integer=True)
    top = heatmap.CAPTION_HEIGHT
    assert image.shape == (top + 30 + heatmap.LEGEND_HEIGHT, 102, 4)
    np.testing.assert_array_equal(image[top:top + 30, :50], heatmap.colour_map(a, 2.0))  # untouched data
    np.testing.assert_array_equal(image[top:top + 30, 52:], heatmap.colour_map(b, 2.0))
    caption = image[:top, :, :3]
    assert len(np.unique(caption.reshape(-1, 3), axis=0)) > 2  # the names are drawn there
