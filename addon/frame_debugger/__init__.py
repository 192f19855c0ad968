"""The "Unity Frame Debugger" (docs/framedebugger.md): capture a frame, step through its draw calls, read a
pixel's history, in the Image Editor's sidebar (tab "Unity").

- :mod:`.properties`: ``Scene.unity_frame_debugger`` (the captured draw list, the selected draw,
  the buffer shown, the pixel and its fragments).
- :mod:`.ops`: Capture and Pixel History operators (a background job with progress and Esc to
  cancel when invoked; synchronous through ``execute``), the capture cache.
- :mod:`.panel`: the panel, its sub-panels and lists.

``register()``/``unregister()`` are symmetric and may each run twice.
"""

from __future__ import annotations


def _classes():
    from . import ops, panel, properties

    return properties.CLASSES + ops.CLASSES + panel.CLASSES


def register() -> None:
    import bpy

    from . import properties

    unregister()
    for cls in _classes():
        bpy.utils.register_class(cls)
    properties.attach()


def unregister() -> None:
    import bpy

    from . import ops, properties

    ops.forget_capture()
    properties.detach()
    for cls in reversed(_classes()):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
