"""ShaderLab ``.shader`` files for a material's Unity settings (README "ShaderLab import and export").

- :mod:`.ops`: Import ShaderLab… (file browser: a ``.shader`` or a Unity ``.mat``), Import ShaderLab
  from Clipboard, Export ShaderLab… (file browser); parsing and writing are
  :mod:`blendlib.formats.shaderlab`'s.
- :mod:`.project`: Link Unity Project… (every material named as a project's ``.mat`` takes its settings).
- :mod:`.panel`: their row in the Unity Material panel (:mod:`addon.material_settings.panel`).
"""

from __future__ import annotations

from ..registration import feature
from . import ops, panel, project

__all__ = ["ops", "panel", "project", "register", "unregister"]

register, unregister = feature(ops.CLASSES + project.CLASSES)
