"""The Unity settings of materials and scenes (README "Data model"), edited in two panels.

- :mod:`.properties`: ``Material.unity`` (queue, ``_Color``, ``_MainTex``, passes, ...) and
  ``Scene.unity`` (colour space, HDR, clear colour, ambient, sort mode), built from the schema of
  :mod:`blendlib.blender.schema`: their names and stored numbers are a file format.
- :mod:`.migration`: settings saved by older versions, brought to the current format on file load.
- :mod:`.ops`: pass list editing, presets, Fill from Principled BSDF, Use Standard View Transform.
- :mod:`.panel`: Material Properties › Unity Material (with its pass list and Presets menu) and
  Render Properties › Unity Camera.
"""

from __future__ import annotations

from ..registration import feature
from . import migration, ops, panel, properties

CLASSES = properties.CLASSES + ops.CLASSES + panel.CLASSES


def _attach() -> None:
    properties.attach()
    migration.attach()  # after the pointers: it migrates what is already loaded


def _detach() -> None:
    migration.detach()
    properties.detach()


register, unregister = feature(CLASSES, _attach, _detach)
