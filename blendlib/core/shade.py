"""Shade stage: the book's ForwardBase fragment program (docs/pipeline.md §7), vectorised.

Scene-level constants (light, ambient, colours brought to shading space) are plain
Python floats computed once; per-fragment work is float64 numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import colorspace
from .scene import DrawScene
from .vocabulary import ColorSpace, Lighting, Material, Texture, TextureFilter, TextureWrap


def gamma_color_to_shading(rgb, color_space: ColorSpace) -> tuple[float, ...]:
    """COLOR_GAMMA (sRGB-encoded) colour → shading space: as is in Gamma, decoded in Linear."""
    if color_space is ColorSpace.Linear:
        return tuple(colorspace.decode(float(c)) for c in rgb)
    return tuple(float(c) for c in rgb)


def linear_color_to_shading(rgb, color_space: ColorSpace) -> tuple[float, ...]:
    """Linear Blender colour → shading space: encoded in Gamma, as is in Linear."""
    if color_space is ColorSpace.Gamma:
        return tuple(colorspace.encode(float(c)) for c in rgb)
    return tuple(float(c) for c in rgb)


@dataclass(frozen=True)
class Lights:
    """Shading-space lighting constants of a frame."""

    ambient: tuple[float, float, float]
    light: tuple[float, float, float]
    direction: tuple[float, float, float]


def frame_lights(scene: DrawScene) -> Lights:
    cs = scene.color_space
    if scene.ambient_is_linear:
        ambient = linear_color_to_shading(scene.ambient, cs)
    else:
        ambient = gamma_color_to_shading(scene.ambient, cs)
    if scene.light is None:
        return Lights(ambient=ambient, light=(0.0, 0.0, 0.0), direction=(0.0, 0.0, 0.0))
    lamp = linear_color_to_shading(scene.light.color, cs)
    energy = float(scene.light.energy)
    light = tuple(c * energy for c in lamp)
    lx, ly, lz = (float(v) for v in scene.light.direction)
    length = math.sqrt((lx * lx + ly * ly) + lz * lz)
    direction = (lx / length, ly / length, lz / length) if length > 0 else (0.0, 0.0, 0.0)
    return Lights(ambient=ambient, light=light, direction=direction)


def texture_texels(texture: Texture, color_space: ColorSpace) -> np.ndarray:
    """Texels converted to shading space before filtering: (h, w, 4) float64 (row 0 = v 0)."""
    texels = np.asarray(texture.pixels, dtype=np.float64).copy()
    rgb = texels[..., :3]
    if texture.encoding == "sRGB" and color_space is ColorSpace.Linear:
        texels[..., :3] = colorspace.decode_array(rgb)
    elif texture.encoding == "Linear" and color_space is ColorSpace.Gamma:
        texels[..., :3] = colorspace.encode_array(rgb)
    return texels


def _wrap(i: np.ndarray, size: int, wrap: TextureWrap) -> np.ndarray:
    """Float texel indices (integer-valued) → int64 indices in 0..size-1."""
    if wrap is TextureWrap.Repeat:
        return np.mod(i, float(size)).astype(np.int64)
    return np.minimum(np.maximum(i, 0.0), float(size - 1)).astype(np.int64)


def sample(texels: np.ndarray, uv: np.ndarray, filt: TextureFilter, wrap: TextureWrap) -> np.ndarray:
    """Sample (h, w, 4) float64 texels at uv (N, 2) float64 → (N, 4) float64 (§7; non-finite uv → texel (0, 0))."""
    h, w = texels.shape[:2]
    flat = texels.reshape(h * w, 4)
    u, v = uv[:, 0], uv[:, 1]
    finite = np.isfinite(u) & np.isfinite(v)
    with np.errstate(invalid="ignore", over="ignore"):
        if filt is TextureFilter.Point:
            i = np.where(finite, np.floor(u * w), 0.0)
            j = np.where(finite, np.floor(v * h), 0.0)
            return flat[_wrap(j, h, wrap) * w + _wrap(i, w, wrap)]
        fu = u * w - 0.5
        fv = v * h - 0.5
        i0 = np.where(finite, np.floor(fu), 0.0)
        j0 = np.where(finite, np.floor(fv), 0.0)
        au = np.where(finite, fu - i0, 0.0)[:, None]
        av = np.where(finite, fv - j0, 0.0)[:, None]
    i1, j1 = _wrap(i0 + 1.0, w, wrap), _wrap(j0 + 1.0, h, wrap)
    i0, j0 = _wrap(i0, w, wrap), _wrap(j0, h, wrap)
    lo = flat[j0 * w + i0] * (1.0 - au) + flat[j0 * w + i1] * au
    hi = flat[j1 * w + i0] * (1.0 - au) + flat[j1 * w + i1] * au
    return lo * (1.0 - av) + hi * av


def shade(
    material: Material,
    texels: np.ndarray | None,
    lights: Lights,
    color_space: ColorSpace,
    uv: np.ndarray,
    normal: np.ndarray,
) -> np.ndarray:
    """Fragment colours (N, 4) float64 in shading space, straight alpha.

    ``uv`` (N, 2) float64 interpolated mesh UVs; ``normal`` (N, 3) float64
    interpolated (unnormalised) world normals; ``texels`` from :func:`texture_texels`.
    """
    n = uv.shape[0]
    color = gamma_color_to_shading(material.color[:3], color_space) + (float(material.color[3]),)
    out = np.empty((n, 4), dtype=np.float64)
    if texels is None:
        # tex = (1, 1, 1, 1): 1.0 * c == c exactly, so albedo and alpha are the material's.
        albedo = np.array(color[:3], dtype=np.float64)[None, :]
        out[:, 3] = color[3] * float(material.alpha_scale)
    else:
        tu, tv = (float(v) for v in material.main_tex_tiling)
        ou, ov = (float(v) for v in material.main_tex_offset)
        uvp = np.empty_like(uv)
        uvp[:, 0] = uv[:, 0] * tu + ou
        uvp[:, 1] = uv[:, 1] * tv + ov
        tex = sample(texels, uvp, material.main_tex_filter, material.main_tex_wrap)
        albedo = tex[:, :3] * np.array(color[:3], dtype=np.float64)
        out[:, 3] = (tex[:, 3] * color[3]) * float(material.alpha_scale)
    if material.lighting is Lighting.Unlit:
        out[:, :3] = albedo
        return out
    nx, ny, nz = normal[:, 0], normal[:, 1], normal[:, 2]
    length = np.sqrt((nx * nx + ny * ny) + nz * nz)
    lx, ly, lz = lights.direction
    if np.all(length > 0):
        nxn, nyn, nzn = nx / length, ny / length, nz / length
    else:  # a zero normal shades as n = 0
        safe = length > 0
        divisor = np.where(safe, length, 1.0)
        nxn = np.where(safe, nx / divisor, 0.0)
        nyn = np.where(safe, ny / divisor, 0.0)
        nzn = np.where(safe, nz / divisor, 0.0)
    ndl = np.maximum(0.0, (nxn * lx + nyn * ly) + nzn * lz)
    ambient = np.array(lights.ambient, dtype=np.float64)
    light = np.array(lights.light, dtype=np.float64)
    out[:, :3] = ambient * albedo + (light * albedo) * ndl[:, None]
    return out
