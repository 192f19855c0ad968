"""Draw-list ordering (docs/pipeline.md §0): render queues, distance sort, ties; which passes draw
(the forward rendering path's LightMode rules, SPEC §11.2) and each renderer's per-pixel lights
(SPEC §12); the numbered draw calls."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .scene import DrawScene, ForwardLight, Renderer, SceneError
from .vocabulary import LAST_OPAQUE_QUEUE, ONCE, PER_LIGHT, LightRenderMode, LightType, Pass, SortMode, pass_draws


def _dot3(a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] * b[0] + a[1] * b[1]) + a[2] * b[2])


def sort_key_distance(scene: DrawScene, renderer: Renderer) -> float:
    """The value the draw list sorts by (larger = farther): the squared camera distance for
    ``Perspective`` (the same order as the distance, without a square root), else the signed
    distance along the view axis or the sort axis."""
    cam = scene.camera
    mode = scene.sort_mode
    if mode is SortMode.Default:
        mode = SortMode.Orthographic if cam.orthographic else SortMode.Perspective
    delta = np.asarray(renderer.bounds_center, dtype=np.float64) - cam.position
    if mode is SortMode.Perspective:
        return _dot3(delta, delta)
    if mode is SortMode.Orthographic:
        return _dot3(delta, cam.forward)
    axis = np.asarray(scene.sort_axis, dtype=np.float64)
    length = float(np.sqrt(_dot3(axis, axis)))
    if length == 0.0 or not np.isfinite(length):
        raise SceneError("scene: sort_axis must be a non-zero finite vector for CustomAxis sorting")
    return _dot3(delta, axis / length)


def sort_distance(scene: DrawScene, renderer: Renderer) -> float:
    """The renderer's sort distance in scene units: Euclidean from the camera for ``Perspective``,
    signed along the view axis (``Orthographic``) or the sort axis (``CustomAxis``)."""
    key = sort_key_distance(scene, renderer)
    perspective = scene.sort_mode is SortMode.Perspective or (
        scene.sort_mode is SortMode.Default and not scene.camera.orthographic)
    return math.sqrt(key) if perspective else key


def sorted_renderers(scene: DrawScene) -> list[Renderer]:
    """Renderers in draw order: queue ascending; front to back up to 2500, back to front above."""

    def key(r: Renderer):
        queue = r.material.render_queue
        d = sort_key_distance(scene, r)
        return (queue, d if queue <= LAST_OPAQUE_QUEUE else -d, r.name, r.slot)

    return sorted(scene.renderers, key=key)


@dataclass(frozen=True, eq=False)
class DrawCall:
    """One draw call of the frame: one pass of one renderer.

    ``index`` counts from 1 in frame order (renderer order, then pass order); ``pass_index``
    is the 0-based index in the material's pass list; ``queue`` the render-queue number;
    ``distance`` the sort distance in scene units (:func:`sort_distance`).
    """

    index: int
    renderer: Renderer
    pass_index: int
    state: Pass
    queue: int
    distance: float
    #: The per-pixel light a ``ForwardAdd`` pass draws for (one call per light); None otherwise.
    light: ForwardLight | None = None


def _light_importance(light: ForwardLight, renderer: Renderer) -> float:
    """Unity ranks Auto lights "in order of decreasing brightness" at the object: intensity ×
    the brightest colour channel × the attenuation at the renderer's bounds centre (1 for
    directional lights)."""
    brightness = float(light.intensity) * max(float(c) for c in light.color)
    if light.type is LightType.Directional:
        return brightness
    delta = np.asarray(renderer.bounds_center, dtype=np.float64) - np.asarray(light.position, dtype=np.float64)
    r2 = _dot3(delta, delta) / (float(light.range) ** 2)
    return brightness * light_falloff(r2)


def light_falloff(r2: float) -> float:
    """Unity's built-in point/spot falloff at ``r2`` = (distance / range)², as its Lightweight
    pipeline states the built-in one: ``1 / (1 + 25 r2)``, faded linearly to 0 between 80 % of the
    range (r2 = 0.64) and the range."""
    if r2 >= 1.0:
        return 0.0
    return 1.0 / (1.0 + 25.0 * r2) * min(1.0, (1.0 - r2) / (1.0 - 0.64))


def world_half_extent(renderer: Renderer) -> np.ndarray:
    """(3,) float64 half size of the renderer's world-space bounding box: the axis-aligned box
    around its mesh's local bounding box transformed to world space (Unity's ``Renderer.bounds``)."""
    return np.abs(np.asarray(renderer.matrix_world, dtype=np.float64)[:3, :3]) @ renderer.mesh.half_size


def light_reaches(light: ForwardLight, renderer: Renderer) -> bool:
    """Whether ``light`` lights ``renderer``: a directional light always; a point or spot light when
    its range sphere meets the renderer's world bounding box."""
    if light.type is LightType.Directional:
        return True
    center = np.asarray(renderer.bounds_center, dtype=np.float64)
    half = world_half_extent(renderer)
    position = np.asarray(light.position, dtype=np.float64)
    delta = np.clip(position, center - half, center + half) - position  # from the light to the box's nearest point
    return _dot3(delta, delta) < float(light.range) ** 2


def pixel_lights(scene: DrawScene, renderer: Renderer) -> tuple[ForwardLight, ...]:
    """The lights whose ForwardAdd passes ``renderer`` draws, in draw order (SPEC §12, the Unity
    manual's forward-path rules): of the lights that reach it, Important ones always, then Auto ones
    by decreasing importance (:func:`_light_importance`; ties by name) up to the scene's pixel light
    count; NotImportant ones never (they would be vertex or SH lights, which are not drawn here)."""
    reaching = [light for light in scene.lights
                if light.render_mode is not LightRenderMode.NotImportant and light_reaches(light, renderer)]

    def ranked(mode: LightRenderMode) -> list[ForwardLight]:
        chosen = [light for light in reaching if light.render_mode is mode]
        return sorted(chosen, key=lambda light: (-_light_importance(light, renderer), light.name))

    important = ranked(LightRenderMode.Important)
    room = max(0, int(scene.pixel_light_count) - len(important))
    return tuple(important + ranked(LightRenderMode.Auto)[:room])


def draw_calls(scene: DrawScene) -> list[DrawCall]:
    """Every draw call of the frame in order, numbered from 1: renderers in draw order, each
    renderer's passes in order as :func:`pass_draws` says (a ForwardAdd pass once per light of
    :func:`pixel_lights`, in that order; passes that do not draw are left out). Raises
    :class:`~.scene.SceneError` (one line) for a scene that cannot be sorted."""
    calls: list[DrawCall] = []
    for r in sorted_renderers(scene):
        distance = sort_distance(scene, r)
        passes = r.material.draw_passes
        lights = None
        for k, p in enumerate(passes):
            how, _ = pass_draws(p, passes)
            if how == ONCE:
                calls.append(DrawCall(len(calls) + 1, r, k, p, r.material.render_queue, distance))
            elif how == PER_LIGHT:
                lights = pixel_lights(scene, r) if lights is None else lights
                for light in lights:
                    calls.append(DrawCall(len(calls) + 1, r, k, p, r.material.render_queue, distance, light))
    return calls


def writes_depth_or_stencil(call: DrawCall) -> bool:
    """Whether a draw call may change the depth or stencil buffer (ZWrite On, or a stencil
    block: the merger writes neither otherwise)."""
    return bool(call.state.zwrite or call.state.stencil)
