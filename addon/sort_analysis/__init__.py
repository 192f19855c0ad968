"""Sort analysis in Blender (docs/sorting.md): view-layer passes and a panel of inversions and advice.

- :mod:`.properties`: ``ViewLayer.unity_analysis`` (adds the ``UnitySortedReference``,
  ``UnitySortError`` and ``UnityOverdraw`` passes to F12's render result) and the last
  analysis' rows on the window manager (not saved, not scene data).
- :mod:`.passes`: those passes' arrays, which the render engine hands to Blender.
- :mod:`.ops`: "Analyze Sorting" (a job of :mod:`addon.jobs` when invoked: progress, Esc cancels;
  synchronous through ``execute``; fills the rows) and "Apply Advice" (sets the suggested queue
  offset or sort setting).
- :mod:`.panel`: Render Properties › Unity Sort Analysis.
"""

from __future__ import annotations

from ..registration import feature
from . import ops, panel, properties

CLASSES = properties.CLASSES + ops.CLASSES + panel.CLASSES

register, unregister = feature(CLASSES, properties.attach, properties.detach)
