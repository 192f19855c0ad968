"""Stored ``Material.unity`` / ``Scene.unity`` settings of older files, migrated as they load.

The migration itself (schema versions, what changed between them) is
:mod:`blendlib.blender.migration`, which also reads old settings correctly without the add-on;
here a ``load_post`` handler rewrites them in place so the panels show the current format.
:func:`attach` installs it and migrates what is already loaded; :func:`detach` removes it.
"""

from __future__ import annotations

import bpy
from bpy.app.handlers import persistent

from blendlib.blender import migrate_data


@persistent
def migrate_on_load(*_args) -> None:
    """``load_post`` handler: bring the Unity settings of every material and scene to the current
    schema version. While the add-on is enabled at Blender's start-up, ``bpy.data`` is not yet
    readable; the files loaded afterwards are migrated by this handler."""
    try:
        data = bpy.data
        data.materials  # noqa: B018 - raises AttributeError on the restricted start-up data
    except AttributeError:
        return
    migrate_data(data)


def attach() -> None:
    if migrate_on_load not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(migrate_on_load)
    migrate_on_load()


def detach() -> None:
    for handler in [h for h in bpy.app.handlers.load_post if _is_migration_handler(h)]:
        bpy.app.handlers.load_post.remove(handler)  # also one left by a reloaded copy of this module


def _is_migration_handler(handler) -> bool:
    return getattr(handler, "__module__", None) == __name__ and getattr(handler, "__name__", None) == "migrate_on_load"
