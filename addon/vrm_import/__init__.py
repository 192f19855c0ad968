"""File › Import › VRM/glTF with Unity settings (SPEC §11.6).

- :mod:`.ops`: the import operator (``unity.import_vrm``): Blender's glTF importer for the geometry,
  then every material's Unity settings as UniVRM / UniGLTF set them
  (:func:`blendlib.blender.gltf_import.import_gltf`), and its menu entry.
"""

from __future__ import annotations

from ..registration import feature
from . import ops

__all__ = ["ops", "register", "unregister"]

register, unregister = feature(ops.CLASSES, attach=ops.add_menu_entry, detach=ops.remove_menu_entry)
