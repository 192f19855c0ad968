"""The frame debugger's Blender side (docs/framedebugger.md): capture a scene, show a buffer after a draw call.

The work itself is bpy-free (:mod:`blendlib.explain.framedebug`); here a Blender scene becomes a
DrawScene and a chosen buffer of the frame after draw K becomes the image "Unity Frame Debugger".
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..core.records import Frame
from ..explain import framedebug as fd
from .render import draw_scene, write_image

#: The image the frame debugger shows its frames in.
IMAGE_NAME = "Unity Frame Debugger"
#: Buffers the frame debugger can show.
BUFFERS = ("COLOR", "ALPHA", "DEPTH", "STENCIL")
#: Highlight colour (frame values) mixed half and half over the selected draw's pixels.
HIGHLIGHT = np.array([1.0, 0.0, 1.0], dtype=np.float32)


def capture(scene: Any = None, *, depsgraph: Any = None, progress: Callable[[float], None] | None = None,
            should_cancel: Callable[[], bool] | None = None, memory: int = fd.SNAPSHOT_MEMORY) -> fd.FrameCapture:
    """Render ``scene`` (default: the context scene) once as F12 evaluates it (or as ``depsgraph``
    does, :func:`blendlib.blender.render.draw_scene`), keeping draw statistics and snapshots.

    Raises :class:`SceneError` (no camera, bad input) or :class:`RenderCancelled`."""
    return fd.FrameCapture.capture(draw_scene(scene, depsgraph), progress=progress, should_cancel=should_cancel,
                                   memory=memory)


def draw_list(scene: Any = None, *, depsgraph: Any = None, **kwargs) -> list[fd.DrawStats]:
    """The draw calls of a Blender scene with their statistics; see :func:`blendlib.draw_list`."""
    return fd.draw_list(draw_scene(scene, depsgraph), **kwargs)


def pixel_history(scene: Any, x: int, y: int, *, depsgraph: Any = None, **kwargs) -> fd.PixelHistory:
    """The history of pixel (x from the left, y from the top); see :func:`blendlib.pixel_history`."""
    return fd.pixel_history(draw_scene(scene, depsgraph), x, y, **kwargs)


def buffer_rgba(frame: Frame, buffer: str, mask: np.ndarray | None = None) -> tuple[np.ndarray, bool]:
    """The (H, W, 4) float32 picture of one buffer (row 0 = top) and whether its rgb is encoded.

    ``COLOR``: the frame values, opaque; ``ALPHA``: alpha as grey; ``DEPTH``: window depth as
    grey (near dark, cleared white); ``STENCIL``: the stencil value / 255 as grey. ``mask`` (H, W)
    bool: pixels mixed half and half with magenta (the selected draw's pixels)."""
    if buffer not in BUFFERS:
        raise ValueError(f"buffer must be one of {', '.join(BUFFERS)}, got {buffer!r}")
    h, w = frame.color.shape[:2]
    if buffer == "COLOR":
        out = np.array(frame.color, dtype=np.float32, copy=True)
        encoded = frame.encoded
    else:
        grey = {"ALPHA": lambda: frame.color[..., 3], "DEPTH": lambda: frame.depth,
                "STENCIL": lambda: frame.stencil.astype(np.float32) / 255.0}[buffer]()
        out = np.repeat(np.asarray(grey, dtype=np.float32)[..., None], 4, axis=-1)
        encoded = True  # grey values shown as they are
    out[..., 3] = 1.0
    if mask is not None and mask.any():
        out[mask, :3] = 0.5 * out[mask, :3] + 0.5 * HIGHLIGHT
    return out.reshape(h, w, 4), encoded


def show(cap: fd.FrameCapture, k: int, buffer: str = "COLOR", highlight: bool = False) -> Any:
    """Write ``buffer`` of the frame after draw ``k`` (replayed from the nearest snapshot) into
    the image :data:`IMAGE_NAME`; returns the image."""
    frame, mask = cap.frame_after(k, highlight=highlight)
    rgba, encoded = buffer_rgba(frame, buffer, mask)
    shown = Frame(color=rgba, depth=frame.depth, stencil=frame.stencil, encoded=encoded)
    return write_image(shown, IMAGE_NAME, encoded=encoded)
