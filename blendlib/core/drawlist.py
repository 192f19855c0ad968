"""Draw-list ordering (docs/pipeline.md §0): render queues, distance sort, ties; the numbered draw calls."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .scene import DrawScene, Renderer, SceneError
from .vocabulary import LAST_OPAQUE_QUEUE, Pass, SortMode


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


def draw_calls(scene: DrawScene) -> list[DrawCall]:
    """Every draw call of the frame in order: each renderer's passes in order, numbered from 1.
    Raises :class:`~.scene.SceneError` (one line) for a scene that cannot be sorted."""
    calls: list[DrawCall] = []
    for r in sorted_renderers(scene):
        distance = sort_distance(scene, r)
        for k, p in enumerate(r.material.draw_passes):
            calls.append(DrawCall(len(calls) + 1, r, k, p, r.material.render_queue, distance))
    return calls
