"""Blender's pixel order: the one flip from the renderer's top-first frames to Blender's bottom-first buffers.

The renderer's frames hold row 0 at the top (as images are read); Blender's images
(``Image.pixels``), render passes (``RenderPass.rect``) and GPU textures hold row 0 at the
bottom (OpenGL's convention). Everything handed to Blender goes through :func:`bottom_first`.
"""

from __future__ import annotations

import numpy as np


def bottom_first(image: np.ndarray) -> np.ndarray:
    """A top-row-first ``(H, W)`` or ``(H, W, C)`` image as Blender's ``(H*W, C)`` float32 buffer,
    C-contiguous, bottom row first, each row left to right (C = 1 for an ``(H, W)`` image).

    That is the layout of ``RenderPass.rect``; ``.ravel()`` of it (a view, no copy) is the flat
    ``(H*W*C,)`` layout of ``Image.pixels.foreach_set`` and ``gpu.types.Buffer``."""
    rows = np.asarray(image)
    if rows.ndim == 2:
        rows = rows[..., np.newaxis]
    if rows.ndim != 3:
        raise ValueError(f"bottom_first: expected an (H, W) or (H, W, C) image, got shape {rows.shape}")
    height, width, channels = rows.shape
    return np.ascontiguousarray(rows[::-1], dtype=np.float32).reshape(height * width, channels)
