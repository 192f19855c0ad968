"""Sort analysis in Blender (docs/sorting.md): view-layer passes and a panel of inversions and advice.

- :mod:`.properties`: ``ViewLayer.unity_analysis`` (adds the ``UnitySortedReference``,
  ``UnitySortError`` and ``UnityOverdraw`` passes to F12's render result) and the last
  analysis' rows on the window manager (not saved, not scene data).
- :mod:`.ops`: "Analyze Sorting" (fills the rows) and "Apply Advice" (sets the suggested
  queue offset or sort setting).
- :mod:`.panel`: Render Properties › Unity Sort Analysis.
"""

from __future__ import annotations

from . import ops, panel, properties

CLASSES = properties.CLASSES + ops.CLASSES + panel.CLASSES


def render_passes() -> tuple[tuple[str, int, str, str], ...]:
    """(name, channels, channel ids, type) of the analysis passes of the render result."""
    return ((properties.REFERENCE_PASS, 4, "RGBA", "COLOR"), (properties.ERROR_PASS, 1, "X", "VALUE"),
            (properties.OVERDRAW_PASS, 3, "XYZ", "VECTOR"))


def result_arrays(analysis) -> dict:
    """Pass name → (H*W, channels) float32, bottom row first: the reference as linear RGBA with its
    alpha (like Combined), the error, the overdraw counts (X rasterised, Y written, Z 0)."""
    from dataclasses import replace

    import numpy as np

    from blendlib import blender

    reference = blender.linear_rgba(replace(analysis.frame, color=analysis.reference))
    h, w = reference.shape[:2]
    overdraw = np.zeros((h, w, 3), np.float32)
    overdraw[..., :2] = analysis.overdraw
    return {
        properties.REFERENCE_PASS: np.ascontiguousarray(reference[::-1]).reshape(h * w, 4),
        properties.ERROR_PASS: np.ascontiguousarray(analysis.error[::-1], dtype=np.float32).reshape(h * w, 1),
        properties.OVERDRAW_PASS: np.ascontiguousarray(overdraw[::-1]).reshape(h * w, 3),
    }


def register() -> None:
    import bpy

    for cls in CLASSES:
        bpy.utils.register_class(cls)
    properties.attach()


def unregister() -> None:
    import bpy

    properties.detach()
    for cls in reversed(CLASSES):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
