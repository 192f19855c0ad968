"""Draw-list ordering (SPEC §4, docs/pipeline.md §0): render queues, distance sort, ties."""

from __future__ import annotations

import numpy as np

from .scene import DrawScene, Renderer
from .vocabulary import LAST_OPAQUE_QUEUE, Pass, SortMode


def _dot3(a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] * b[0] + a[1] * b[1]) + a[2] * b[2])


def sort_distance(scene: DrawScene, renderer: Renderer) -> float:
    """The renderer's sort distance for the scene's sort mode (larger = farther)."""
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
        raise ValueError("scene: sort_axis must be a non-zero finite vector for CustomAxis sorting")
    return _dot3(delta, axis / length)


def sorted_renderers(scene: DrawScene) -> list[Renderer]:
    """Renderers in draw order: queue ascending; front to back up to 2500, back to front above."""

    def key(r: Renderer):
        queue = r.material.render_queue
        d = sort_distance(scene, r)
        return (queue, d if queue <= LAST_OPAQUE_QUEUE else -d, r.name, r.slot)

    return sorted(scene.renderers, key=key)


def draw_calls(scene: DrawScene) -> list[tuple[Renderer, Pass]]:
    """Every draw call of the frame in order: each renderer's passes in order."""
    return [(r, p) for r in sorted_renderers(scene) for p in r.material.draw_passes]
