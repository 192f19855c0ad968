"""The sort analysis' passes of F12's render result (``ViewLayer.unity_analysis.use_passes``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from blendlib import blender
from blendlib.blender.pixels import bottom_first

from .properties import ERROR_PASS, OVERDRAW_PASS, REFERENCE_PASS


def render_passes() -> tuple[tuple[str, int, str, str], ...]:
    """(name, channels, channel ids, type) of the analysis passes of the render result."""
    return ((REFERENCE_PASS, 4, "RGBA", "COLOR"), (ERROR_PASS, 1, "X", "VALUE"), (OVERDRAW_PASS, 2, "XY", "VECTOR"))


def result_arrays(analysis) -> dict[str, np.ndarray]:
    """Pass name → (H*W, channels) float32, bottom row first, of an
    :class:`~blendlib.explain.sorted_reference.Analysis`: the reference as linear RGBA with its
    alpha (like Combined), the error, the overdraw counts (X rasterised, Y written: two channels,
    no third one to misread)."""
    reference = blender.linear_rgba(replace(analysis.frame, color=analysis.reference))
    overdraw = analysis.overdraw.astype(np.float32)
    return {REFERENCE_PASS: bottom_first(reference), ERROR_PASS: bottom_first(analysis.error),
            OVERDRAW_PASS: bottom_first(overdraw)}
