"""A glTF texture as UniGLTF loads it for ``_MainTex``: filter, wrap, mipmaps and ``_MainTex_ST``.

Sampler (vrm-c/UniVRM ``Assets/UniGLTF/Runtime/UniGLTF/IO/TextureIO/TextureSamplerUtil.cs``
@140701c1, ``ImportFilterMode`` / ``ImportWrapMode``; the filter comes from ``minFilter``)::

    case glFilter.NEAREST: case glFilter.NEAREST_MIPMAP_NEAREST:  return (FilterMode.Point, false);
    case glFilter.NEAREST_MIPMAP_LINEAR:                          return (FilterMode.Point, true);
    case glFilter.NONE: case glFilter.LINEAR:                     return (FilterMode.Bilinear, false);
    case glFilter.LINEAR_MIPMAP_NEAREST: case glFilter.LINEAR_MIPMAP_LINEAR:
                                                                  return (FilterMode.Bilinear, true);

A texture without a sampler takes ``SamplerParam.Default`` (Repeat, Bilinear, mipmaps on:
``Import/SamplerParam.cs`` @e9da5e2b). A sampler object without ``minFilter`` reads as
``glFilter.NEAREST``, the C# field's default (``Format/glTFTexture.cs`` @4ebfcb11). Unity has
one wrap mode per axis and a Mirror mode; this renderer has one wrap for both axes and no Mirror:
those cases import with a warning (Mirror as Repeat, differing axes as the U axis's mode).

``KHR_texture_transform`` (``TextureTransform.cs`` @b147b061, "UV Coordinate Conversion: glTF
(top-left origin) to Unity (bottom-left origin)")::

    return (new Vector2(s.x, s.y), new Vector2(o.x, 1.0f - o.y - s.y));

``rotation`` and ``texCoord`` are ignored by UniGLTF (a warning here). Blender's glTF importer
flips V the same way (``uvs[:, 1] = 1 - v``), so the resulting tiling and offset apply to
Blender's UVs unchanged.
"""

from __future__ import annotations

import math
from typing import Any

from ...core.vocabulary import TextureFilter, TextureWrap

NEAREST, LINEAR = 9728, 9729
NEAREST_MIPMAP_NEAREST, LINEAR_MIPMAP_NEAREST = 9984, 9985
NEAREST_MIPMAP_LINEAR, LINEAR_MIPMAP_LINEAR = 9986, 9987
CLAMP_TO_EDGE, MIRRORED_REPEAT, REPEAT = 33071, 33648, 10497

#: glTF ``minFilter`` → (Unity filter, mipmaps), ``TextureSamplerUtil.ImportFilterMode``.
MIN_FILTERS: dict[int | None, tuple[TextureFilter, bool]] = {
    NEAREST: (TextureFilter.Point, False),
    NEAREST_MIPMAP_NEAREST: (TextureFilter.Point, False),
    NEAREST_MIPMAP_LINEAR: (TextureFilter.Point, True),
    None: (TextureFilter.Bilinear, False),  # glFilter.NONE
    LINEAR: (TextureFilter.Bilinear, False),
    LINEAR_MIPMAP_NEAREST: (TextureFilter.Bilinear, True),
    LINEAR_MIPMAP_LINEAR: (TextureFilter.Bilinear, True),
}
WRAPS = {CLAMP_TO_EDGE: "Clamp", MIRRORED_REPEAT: "Mirror", REPEAT: "Repeat"}


def sampler_settings(sampler: dict[str, Any] | None, where: str, warnings: list[str]) -> dict[str, Any]:
    """``main_tex_filter``, ``main_tex_wrap`` and ``main_tex_mipmaps`` of a glTF sampler (None: no
    sampler), as UniGLTF imports them; what this renderer cannot hold is appended to ``warnings``."""
    if sampler is None:
        return {"main_tex_filter": TextureFilter.Bilinear, "main_tex_wrap": TextureWrap.Repeat,
                "main_tex_mipmaps": True}
    min_filter = sampler.get("minFilter", NEAREST)
    if min_filter not in MIN_FILTERS:
        warnings.append(f"{where}: unknown minFilter {min_filter!r}; imported as Bilinear")
        min_filter = LINEAR
    texture_filter, mipmaps = MIN_FILTERS[min_filter]
    wrap_u, wrap_v = (WRAPS.get(sampler.get(key, REPEAT)) for key in ("wrapS", "wrapT"))
    if wrap_u is None or wrap_v is None:
        warnings.append(f"{where}: unknown wrap mode {sampler.get('wrapS')!r}/{sampler.get('wrapT')!r}; "
                        "imported as Repeat")
        wrap_u, wrap_v = wrap_u or "Repeat", wrap_v or "Repeat"
    if wrap_u != wrap_v:
        warnings.append(f"{where}: wrap {wrap_u} in U and {wrap_v} in V (Unity keeps both); "
                        f"this renderer has one wrap mode: {wrap_u if wrap_u != 'Mirror' else 'Repeat'} for both")
    if wrap_u == "Mirror":
        warnings.append(f"{where}: MIRRORED_REPEAT (Unity's Mirror) is drawn as Repeat")
        wrap_u = "Repeat"
    return {"main_tex_filter": texture_filter, "main_tex_wrap": TextureWrap.parse(wrap_u), "main_tex_mipmaps": mipmaps}


def _pair(value: Any, default: tuple[float, float], what: str) -> tuple[float, float]:
    if value is None:
        return default
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        raise ValueError(f"{what} must be two finite numbers, got {value!r}")
    return float(value[0]), float(value[1])


def texture_transform_st(texture_info: dict[str, Any], where: str, warnings: list[str]
                         ) -> tuple[tuple[float, float], tuple[float, float]]:
    """(tiling, offset) of a textureInfo's ``KHR_texture_transform`` in Unity's UV space
    (``VerticalFlipScaleOffset``); identity without the extension. ValueError for malformed numbers."""
    transform = (texture_info.get("extensions") or {}).get("KHR_texture_transform")
    if not isinstance(transform, dict):
        return (1.0, 1.0), (0.0, 0.0)
    scale = _pair(transform.get("scale"), (1.0, 1.0), f"{where}.KHR_texture_transform.scale")
    offset = _pair(transform.get("offset"), (0.0, 0.0), f"{where}.KHR_texture_transform.offset")
    if transform.get("rotation", 0) not in (0, 0.0):
        warnings.append(f"{where}: KHR_texture_transform rotation {transform['rotation']} is ignored, "
                        "as UniGLTF ignores it")
    if "texCoord" in transform:
        warnings.append(f"{where}: KHR_texture_transform texCoord is ignored, as UniGLTF ignores it")
    return scale, (offset[0], 1.0 - offset[1] - scale[1])
