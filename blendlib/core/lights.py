"""The light of a ForwardAdd draw (docs/pipeline.md §7, "ForwardAdd: one additional light"), vectorised.

A ``ForwardAdd`` pass draws once per per-pixel light of its renderer (:func:`.drawlist.pixel_lights`)
and shades with that light only, as the book's ForwardAdd pass does (chapter 9,
``Chapter9-ForwardRendering.shader``): ``rgb = ((light × albedo) × max(0, N·L)) × atten``, no
ambient. :func:`add_light` brings a :class:`~.scene.ForwardLight` to shading space once per draw
call; :func:`light_terms` gives the per-fragment direction towards the light and attenuation:

- directional: ``L`` the lamp's +Z axis, ``atten = 1``;
- point: ``L`` from the fragment's world position towards the light, ``atten =``
  :func:`falloff` of ``r2 = d² / range²`` (Unity's built-in falloff as its Lightweight pipeline
  states it: ``1 / (1 + 25 r2)``, faded linearly to 0 between 80 % of the range and the range);
- spot: the point light's terms × the cone (:func:`spot_cone`): zero behind the lamp
  (``lightCoord.z > 0``), fully lit within 46/64 of the cone's radius at the fragment's depth
  along the spot's axis, falling linearly to 0 at the cone's edge — our approximation of Unity's
  default spot cookie (a soft disc whose pixels are not public; 46/64 is the inner cone Unity's
  own lightmapper derives from it, ``ExtractInnerCone``).

Every step is an IEEE float64 array operation in the order written in docs/pipeline.md §7, so the
scalar reference (tests/reference/scalar.py) gives the same bits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import colorspace
from .scene import ForwardLight
from .vocabulary import BlendFactor, BlendOp, ColorSpace, Lighting, LightType, Material, Pass

#: Unity's built-in falloff: the quadratic term of ``1 / (1 + 25 r2)`` and where the linear fade to
#: the range starts (80 % of the range: r2 = 0.64).
QUADRATIC = 25.0
FADE_START = 0.64
#: The default spot cookie is fully lit within this share of the cone's radius (Unity's
#: ``ExtractInnerCone``: ``tan(inner / 2) = tan(outer / 2) × (64 − 18) / 64``).
SPOT_INNER = 46.0 / 64.0
SPOT_FADE = 1.0 - SPOT_INNER  # 18/64, exact in binary


@dataclass(frozen=True)
class AddLight:
    """A ForwardAdd draw's light in shading space (made once per draw call by :func:`add_light`).

    ``color`` (3 floats): ``lamp_c × intensity`` with the lamp colour brought to shading space as
    the main light's (encoded in Gamma, linear in Linear). ``direction``: a directional light's unit
    vector towards the light. ``position``: a point or spot light's world position. ``spot_axis``: the
    unit vector a spot shines along (the lamp's −Z). ``range2``: ``range × range``; ``tan_half``:
    ``tan(spot_angle / 2)``.
    """

    type: LightType
    color: tuple[float, float, float]
    direction: tuple[float, float, float] = (0.0, 0.0, 0.0)
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    spot_axis: tuple[float, float, float] = (0.0, 0.0, -1.0)
    range2: float = 1.0
    tan_half: float = 1.0

    @property
    def positional(self) -> bool:
        """Whether the light's direction and attenuation depend on the fragment's position."""
        return self.type is not LightType.Directional


def _unit(v) -> tuple[float, float, float]:
    x, y, z = (float(c) for c in v)
    length = math.sqrt((x * x + y * y) + z * z)
    return (x / length, y / length, z / length) if length > 0 else (0.0, 0.0, 0.0)


def add_light(light: ForwardLight, color_space: ColorSpace) -> AddLight:
    """The shading-space constants of ``light`` for a ForwardAdd draw."""
    if color_space is ColorSpace.Gamma:
        lamp = [colorspace.encode(float(c)) for c in light.color]
    else:
        lamp = [float(c) for c in light.color]
    intensity = float(light.intensity)
    color = (lamp[0] * intensity, lamp[1] * intensity, lamp[2] * intensity)
    axis = _unit(light.axis)
    range_ = float(light.range)
    return AddLight(type=light.type, color=color, direction=axis,
                    position=tuple(float(c) for c in light.position),
                    spot_axis=(-axis[0], -axis[1], -axis[2]), range2=range_ * range_,
                    tan_half=math.tan(math.radians(float(light.spot_angle)) / 2.0))


def falloff(r2: np.ndarray) -> np.ndarray:
    """Unity's built-in point/spot falloff (N,) float64 at ``r2`` (N,) float64 = (distance / range)²:
    ``(1 / (1 + 25 r2)) × min(1, (1 − r2) / (1 − 0.64))``, and 0 where ``r2 >= 1`` (the same
    arithmetic as :func:`.drawlist.light_falloff`, NaN propagating)."""
    out = np.multiply(r2, QUADRATIC)
    out += 1.0
    np.divide(1.0, out, out=out)
    fade = np.subtract(1.0, r2)
    fade /= 1.0 - FADE_START
    np.minimum(1.0, fade, out=fade)
    out *= fade
    out[r2 >= 1.0] = 0.0
    return out


def spot_cone(light: AddLight, z: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """The spot's cone term (N,) float64 of fragments at depth ``z`` (N,) along the spot's axis and
    squared distance ``d2`` (N,) from the lamp: 0 where ``z <= 0``, else with ``rho = sqrt(max(d2 −
    z·z, 0)) / (z · tan_half)`` (the distance from the axis as a share of the cone's radius there),
    ``min(1, max(0, (1 − rho) / (18/64)))``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        q2 = np.multiply(z, z)
        np.subtract(d2, q2, out=q2)
        np.maximum(q2, 0.0, out=q2)
        rho = np.sqrt(q2, out=q2)
        rho /= np.multiply(z, light.tan_half)
        cone = np.subtract(1.0, rho, out=rho)
        cone /= SPOT_FADE
        np.maximum(cone, 0.0, out=cone)
        np.minimum(cone, 1.0, out=cone)
    cone[~(z > 0.0)] = 0.0
    return cone


def _from_lamp(light: AddLight, px: np.ndarray, py: np.ndarray,
               pz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``d = p − lamp`` per fragment (three (N,) float64) and ``d2 = (dx·dx + dy·dy) + dz·dz``:
    the one place both :func:`light_terms` and :func:`dark_fragments` compute them (the same bits)."""
    ox, oy, oz = light.position
    dx, dy, dz = np.subtract(px, ox), np.subtract(py, oy), np.subtract(pz, oz)
    d2 = np.multiply(dx, dx)
    d2 += np.multiply(dy, dy)
    d2 += np.multiply(dz, dz)
    return dx, dy, dz, d2


def _spot_cone_at(light: AddLight, dx: np.ndarray, dy: np.ndarray, dz: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """:func:`spot_cone` of fragments at ``d`` from the lamp: ``z = (dx·ax + dy·ay) + dz·az``."""
    ax, ay, az = light.spot_axis
    z = np.multiply(dx, ax)
    z += np.multiply(dy, ay)
    z += np.multiply(dz, az)
    return spot_cone(light, z, d2)


def light_terms(light: AddLight, px: np.ndarray, py: np.ndarray,
                pz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per fragment at world positions ``px, py, pz`` (N,) float64 of a point or spot light: the unit
    vector towards the light ``(lx, ly, lz)`` (0 at the lamp itself) and the attenuation ``atten``,
    each (N,) float64. With ``d = p − lamp``: ``d2 = (dx·dx + dy·dy) + dz·dz``, ``l = −d / sqrt(d2)``,
    ``atten = falloff(d2 / range2)``, times :func:`spot_cone` for a spot
    (``z = (dx·ax + dy·ay) + dz·az`` along its axis)."""
    dx, dy, dz, d2 = _from_lamp(light, px, py, pz)
    length = np.sqrt(d2)
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = [np.divide(np.negative(v), length) for v in (dx, dy, dz)]
    at_lamp = length == 0.0
    if at_lamp.any():
        for v in unit:
            v[at_lamp] = 0.0
    atten = falloff(np.divide(d2, light.range2))
    if light.type is LightType.Spot:
        atten = np.multiply(_spot_cone_at(light, dx, dy, dz, d2), atten)
    return unit[0], unit[1], unit[2], atten

#: Shading inputs (colours, texels, the light's colour) at most this large in magnitude give
#: finite products, so a zero attenuation gives an exactly zero colour.
DARK_SKIP_PEAK = 1e30


def dark_skip_applies(p: Pass, material: Material, light: AddLight | None, texture_peak: float,
                      hdr: bool, samples: int, observed: bool) -> tuple[bool, bool]:
    """Whether the fragments of a point or spot light's ForwardAdd draw that the light does not
    reach change nothing, and whether that needs the stored alpha to be 255: ``(applies,
    needs_saturated_alpha)``.

    Out of reach (:func:`dark_fragments`) the colour is ``((light × albedo) × ndl) × 0``, exactly
    0 when every input is finite and bounded (``texture_peak``: the texture's largest magnitude,
    0 without one). An 8-bit buffer blended with ``BlendOp Add`` and destination factor ``One``
    then stores ``quantize(0 × src_factor + dst) = dst`` in colour. Alpha is kept when the pass
    writes none; with an alpha ``Add`` and destination factor ``One``, when the source alpha factor
    is ``Zero``, else only where the stored alpha is already 1 (a non-negative addition saturates). Not with stencil,
    ZWrite, an outline colour, MSAA (per-sample coverage), an HDR buffer (no saturation) or an
    ``observed`` draw whose every fragment's colour the observer reads (under an observer that
    does not, the unreached fragments are merged with rgb 0 instead of dropped: DrawState.dark_skip)."""
    if (light is None or not light.positional or hdr or samples != 1 or observed or p.stencil or p.zwrite
            or p.outline_color is not None or material.lighting is Lighting.Unlit or not p.blend
            or p.blend_op is not BlendOp.Add or p.dst_blend is not BlendFactor.One):
        return False, False
    peaks = [texture_peak, *(abs(float(c)) for c in (*material.color, *material.tint_color, material.alpha_scale,
                                                      *light.color))]
    if not all(v <= DARK_SKIP_PEAK for v in peaks):  # NaN fails too
        return False, False
    if "A" not in p.color_mask:
        return True, False
    src_alpha, dst_alpha, alpha_op = p.alpha_factors
    if alpha_op is not BlendOp.Add or dst_alpha is not BlendFactor.One:
        return False, False
    return True, src_alpha is not BlendFactor.Zero  # Zero: alpha_s × 0 + alpha_d = alpha_d anywhere


def dark_fragments(light: AddLight, px: np.ndarray, py: np.ndarray, pz: np.ndarray) -> np.ndarray:
    """(N,) bool: the fragments at world positions ``px, py, pz`` (N,) float64 whose attenuation
    :func:`light_terms` computes as exactly 0 — at or beyond the light's range (``falloff`` of
    ``r2 >= 1``), or for a spot where :func:`spot_cone` is 0 (behind the lamp or outside the cone;
    0 times a finite falloff) — by the same operations on the same values."""
    dx, dy, dz, d2 = _from_lamp(light, px, py, pz)
    r2 = np.divide(d2, light.range2)
    dark = r2 >= 1.0
    if light.type is LightType.Spot:
        dark |= (_spot_cone_at(light, dx, dy, dz, d2) == 0.0) & np.isfinite(r2)
    return dark


#: The reach of :func:`segments_reach` is widened by this share of the reach's radius, and by
#: :data:`REACH_SCALE_MARGIN` of the largest coordinate in play: far above the rounding of the
#: positions' interpolation (a few units in the last place of those coordinates).
REACH_MARGIN = 1e-6
REACH_SCALE_MARGIN = 1e-9


def segments_reach(light: AddLight, a: np.ndarray, b: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """The part of each segment ``a + t (b − a)``, ``0 <= t <= 1`` (``a``, ``b`` (R, 3) float64
    world positions), that may lie within the light's range sphere (about the lamp) and, for a
    spot, within its cone (:func:`_cone_span`): ``(t_lo, t_hi)``, two (R,) float64 in [0, 1], empty (``t_lo > t_hi``)
    where the whole segment keeps out. Both are widened by :data:`REACH_MARGIN` of the radius (and
    of ``tan θ``) and by :data:`REACH_SCALE_MARGIN` of the largest magnitude in play (``scale``:
    that of the coordinates the segments' points are interpolated from), far above the rounding of
    the positions' interpolation: points at ``t`` outside the part, and positions interpolated
    near them, are ones :func:`dark_fragments` calls dark. A segment with a non-finite end (or
    whose terms overflow) is kept whole; one of no length is kept whole or not at all."""
    radius = math.sqrt(light.range2)
    c = np.asarray(light.position, dtype=np.float64)
    slack = REACH_SCALE_MARGIN * max(scale, float(np.abs(c).max()), radius)
    bound = radius * (1.0 + REACH_MARGIN) + slack
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        d = b - a
        off = a - c
        dd = np.einsum("ij,ij->i", d, d)
        half = np.einsum("ij,ij->i", d, off)  # |off + t d|² − bound² = dd t² + 2 half t + cc
        cc = np.einsum("ij,ij->i", off, off) - bound * bound
        disc = half * half - dd * cc
        root = np.sqrt(disc)
        t_lo = (-half - root) / dd
        t_hi = (-half + root) / dd
        np.maximum(t_lo, 0.0, out=t_lo)
        np.minimum(t_hi, 1.0, out=t_hi)
        missed = disc < 0.0
        t_lo[missed] = 1.0
        t_hi[missed] = 0.0
        point = dd == 0.0  # no length: in or out whole
        t_lo[point] = np.where(cc[point] <= 0.0, 0.0, 1.0)
        t_hi[point] = np.where(cc[point] <= 0.0, 1.0, 0.0)
    unknown = ~(np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1) & np.isfinite(dd) & np.isfinite(half)
                & np.isfinite(cc) & np.isfinite(disc))
    if light.type is LightType.Spot:
        cone_lo, cone_hi = _cone_span(light, slack, a, b)
        np.maximum(t_lo, cone_lo, out=t_lo)
        np.minimum(t_hi, cone_hi, out=t_hi)
    t_lo[unknown] = 0.0
    t_hi[unknown] = 1.0
    return t_lo, t_hi


def _cone_span(light: AddLight, slack: float, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The part ``[t_lo, t_hi]`` (two (R,) float64 in [0, 1]; empty where ``t_lo > t_hi``) of each
    segment ``a + t (b − a)`` (``a``, ``b`` (R, 3) float64) that may lie in a spot's cone (where
    :func:`spot_cone` is not 0), widened by :data:`REACH_MARGIN` in ``tan`` and by ``slack`` in every
    direction (its apex moved back along the axis by ``slack × (1 + 1/sin θ)``, so the cone holds
    every point within ``slack`` of the original).

    With ``d(t) = a − apex + t (b − a)`` and ``z(t) = d(t) · axis``, a point is in the cone when
    ``z > 0`` and ``g = (1 + tan²) z² − |d|² > 0``, ``g`` quadratic in t. Where ``g`` is at least
    minus a margin above its rounding within the part of [0, 1] where ``z >= 0``: one interval
    when ``g`` opens downwards, up to two when it opens upwards (then their hull is taken, a
    superset), the whole front part when ``g`` never falls below it."""
    count = a.shape[0]
    tan = light.tan_half * (1.0 + REACH_MARGIN)
    if not math.isfinite(tan) or tan <= 0.0:
        return np.zeros(count, dtype=np.float64), np.ones(count, dtype=np.float64)
    k = 1.0 + tan * tan
    axis = np.asarray(light.spot_axis, dtype=np.float64)
    back = slack * (1.0 + math.sqrt(k) / tan)  # 1 / sin θ = sqrt(1 + tan²) / tan
    apex = np.asarray(light.position, dtype=np.float64) - back * axis
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d0 = a - apex
        e = b - a
        # einsum, not ``@``: a matrix-vector product goes to OpenBLAS, whose worker threads then
        # spin for a while on the other core, where a band worker of the render runs.
        z0 = np.einsum("ij,j->i", d0, axis)
        ez = np.einsum("ij,j->i", e, axis)
        ee = np.einsum("ij,ij->i", e, e)
        dd = np.einsum("ij,ij->i", d0, d0)
        alpha = k * ez * ez - ee
        beta = 2.0 * (k * z0 * ez - np.einsum("ij,ij->i", d0, e))
        size = np.sqrt(dd) + np.sqrt(ee)
        gamma = (k * z0 * z0 - dd) + 1e-12 * k * size * size  # g plus the margin
        # The front part of [0, 1]: z0 + t ez >= 0.
        root = -z0 / ez
        front_lo = np.where(ez > 0.0, np.maximum(root, 0.0), 0.0)
        front_hi = np.where(ez < 0.0, np.minimum(root, 1.0), 1.0)
        flat = ez == 0.0
        front_lo[flat] = np.where(z0[flat] >= 0.0, 0.0, 1.0)
        front_hi[flat] = np.where(z0[flat] >= 0.0, 1.0, 0.0)
        disc = beta * beta - 4.0 * alpha * gamma
        sq = np.sqrt(np.maximum(disc, 0.0))
        r1 = (-beta - sq) / (2.0 * alpha)
        r2 = (-beta + sq) / (2.0 * alpha)
        r_lo, r_hi = np.minimum(r1, r2), np.maximum(r1, r2)
        # Up to two pieces where g >= −margin, each cut to the front part.
        # Where g opens neither way with roots (never below the margin, or linear in t): the
        # front part whole.
        lo1, hi1 = front_lo.copy(), front_hi.copy()
        lo2, hi2 = np.ones(count), np.zeros(count)  # empty unless g opens upwards and has roots
        down = alpha < 0.0
        lo1[down] = np.maximum(front_lo[down], r_lo[down])
        hi1[down] = np.minimum(front_hi[down], r_hi[down])
        lo1[down & ~(disc >= 0.0)] = 1.0
        hi1[down & ~(disc >= 0.0)] = 0.0
        up = (alpha > 0.0) & (disc >= 0.0)
        hi1[up] = np.minimum(front_hi[up], r_lo[up])
        lo2[up] = np.maximum(front_lo[up], r_hi[up])
        hi2[up] = front_hi[up]
        first, second = lo1 <= hi1, lo2 <= hi2
        t_lo = np.where(first, lo1, np.where(second, lo2, 1.0))
        t_hi = np.where(second, hi2, np.where(first, hi1, 0.0))
        unknown = ~(np.isfinite(alpha) & np.isfinite(beta) & np.isfinite(gamma) & np.isfinite(front_lo)
                    & np.isfinite(front_hi) & np.isfinite(r_lo) & np.isfinite(r_hi))
    t_lo[unknown] = 0.0
    t_hi[unknown] = 1.0
    return t_lo, t_hi
