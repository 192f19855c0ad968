"""The "Unity Frame Debugger" (docs/framedebugger.md): capture a frame, step through its draw calls, read a
pixel's history, in the Image Editor's sidebar (tab "Unity").

- :mod:`.properties`: ``Scene.unity_frame_debugger`` (the captured draw list, the selected draw,
  the buffer shown, the pixel and its fragments).
- :mod:`.ops`: Capture and Pixel History operators (jobs of :mod:`addon.jobs` when invoked:
  progress and Esc to cancel; synchronous through ``execute``), the capture cache.
- :mod:`.panel`: the panel, its sub-panels and lists.
"""

from __future__ import annotations

from ..registration import feature
from . import ops, panel, properties

CLASSES = properties.CLASSES + ops.CLASSES + panel.CLASSES


def _detach() -> None:
    ops.forget_capture()
    properties.detach()


register, unregister = feature(CLASSES, properties.attach, _detach)
