"""Blender lights as Unity forward lights (SPEC §12): ``Light.unity`` values, derived or stored.

A Blender light's Unity values follow the light unless ``Light.unity.use_blender_values`` is off:

- intensity: a Sun's Strength (the main light's convention, docs/pipeline.md §7: ``colour ×
  strength``); a Point's or Spot's Power in watts ÷ 4π ÷ π — the chain a Blender user's light
  takes to Unity through glTF: Blender's glTF exporter writes W / 4π (KHR_lights_punctual), and
  Unity's glTFast importer divides by π for the built-in pipeline (a 1000 W point light: 25.3).
- range: the light's Custom Distance when that is on (what Blender's glTF exporter writes as the
  range), else 10 m, the range of a new Unity point or spot light.
- spot angle: the Spot Size in degrees (both are the full cone angle).
- render mode: Auto (stored; the panel's choice).

bpy is not imported here: the functions take Blender light data blocks.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.scene import ForwardLight
from ..core.vocabulary import LightRenderMode, LightType
from .schema import light_settings

#: The range of a new Unity point or spot light, used when the Blender light sets no custom distance.
DEFAULT_RANGE = 10.0
_TYPES = {"SUN": LightType.Directional, "POINT": LightType.Point, "SPOT": LightType.Spot}


def derived_light_values(light: Any) -> dict[str, float]:
    """``{"intensity", "range", "spot_angle"}`` of a Blender light (``bpy.types.Light``) by the
    conventions of the module docstring."""
    if light.type == "SUN":
        intensity = float(light.energy)
    else:
        intensity = float(light.energy) / (4.0 * math.pi) / math.pi
    use_custom = bool(getattr(light, "use_custom_distance", False))
    distance = float(getattr(light, "cutoff_distance", 0.0))
    spot_size = float(getattr(light, "spot_size", math.radians(30.0)))
    return {"intensity": intensity, "range": distance if use_custom and distance > 0 else DEFAULT_RANGE,
            "spot_angle": math.degrees(spot_size)}


def unity_light_values(light: Any) -> dict[str, Any]:
    """The Unity values a light renders with: :func:`derived_light_values` while
    ``use_blender_values`` is on, else the stored ones; plus ``render_mode``."""
    stored = light_settings(light)
    values = derived_light_values(light) if stored["use_blender_values"] else \
        {k: float(stored[k]) for k in ("intensity", "range", "spot_angle")}
    values["render_mode"] = stored["render_mode"]
    return values


def is_forward_light(light: Any) -> bool:
    """Whether a Blender light type becomes a Unity forward light (Area lights have no counterpart)."""
    return light.type in _TYPES


def forward_light(name: str, light: Any, matrix_world: np.ndarray) -> ForwardLight:
    """The :class:`ForwardLight` of a Blender light data block placed by ``matrix_world`` (4, 4)."""
    values = unity_light_values(light)
    axis = matrix_world[:3, :3] @ np.array([0.0, 0.0, 1.0])
    norm = float(np.linalg.norm(axis))
    axis = axis / norm if norm > 0 else np.array([0.0, 0.0, 1.0])
    return ForwardLight(
        name=name,
        type=_TYPES[light.type],
        position=tuple(float(v) for v in matrix_world[:3, 3]),
        axis=tuple(float(v) for v in axis),
        color=tuple(float(c) for c in light.color),
        intensity=values["intensity"],
        range=values["range"],
        spot_angle=min(max(values["spot_angle"], 1e-3), 179.999),
        render_mode=LightRenderMode.parse(values["render_mode"]),
    )
