"""How each feature folder registers: its classes, then what it attaches to Blender's types.

Every feature package (``material_settings``, ``shaderlab``, ``sort_analysis``, ``engine``,
``frame_debugger``) builds its ``register``/``unregister`` pair with :func:`feature`, like
``bpy.utils.register_classes_factory`` but symmetric and safe to call twice in a row: classes
already registered are skipped on register, classes not registered are skipped on unregister.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence


def feature(classes: Sequence[type], attach: Callable[[], None] | None = None,
            detach: Callable[[], None] | None = None) -> tuple[Callable[[], None], Callable[[], None]]:
    """``(register, unregister)`` of one feature.

    ``register`` registers ``classes`` in order (property groups before the pointers and
    collections that use them), then calls ``attach`` (pointer properties on Blender's types,
    handlers); ``unregister`` calls ``detach`` first, then unregisters the classes in reverse order.
    ``attach`` and ``detach`` must tolerate being called twice."""

    def register() -> None:
        import bpy

        for cls in classes:
            if not getattr(cls, "is_registered", False):
                bpy.utils.register_class(cls)
        if attach is not None:
            attach()

    def unregister() -> None:
        import bpy

        if detach is not None:
            detach()
        for cls in reversed(classes):
            if getattr(cls, "is_registered", False):
                bpy.utils.unregister_class(cls)

    return register, unregister
