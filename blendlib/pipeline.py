"""The frame driver: draw list → per draw call (vertex → raster → shade → output merger) → Frame."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .scene import DrawScene


class RenderCancelled(Exception):
    """Raised when ``should_cancel()`` returned True; no buffers are returned."""


@dataclass(eq=False)
class Frame:
    """A rendered frame. Row 0 is the top of the image.

    - ``color`` (H, W, 4) float32: the stored frame values (sRGB-encoded in Gamma
      mode and in Linear LDR; linear in Linear HDR).
    - ``depth`` (H, W) float32: window depth ``d / (2**24 - 1)``.
    - ``stencil`` (H, W) uint8.
    - ``warnings``: one line each (skipped triangles, empty meshes, missing images).
    """

    color: np.ndarray
    depth: np.ndarray
    stencil: np.ndarray
    warnings: list[str] = field(default_factory=list)


def render_scene(
    scene: DrawScene,
    *,
    progress: Callable[[float], None] | None = None,
    should_cancel: Callable[[], bool] | None = None,
) -> Frame:
    """Render a draw scene exactly as Unity's built-in pipeline would (docs/pipeline.md).

    ``progress(fraction)`` is called between draw calls; ``should_cancel()`` is polled
    between draw calls and chunks, and a True answer raises :class:`RenderCancelled`.
    Raises :class:`blendlib.scene.SceneError` (one line) for input that cannot render.
    """
    raise NotImplementedError("renderer core is being written")
