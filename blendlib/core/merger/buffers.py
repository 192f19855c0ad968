"""The output merger's buffers (docs/pipeline.md §8): colour, depth and stencil, and the tests that read them.

:class:`FrameBuffers` stores a frame flat in window order and converts between shading-space
values and what the colour buffer stores; :func:`compare` and :func:`stencil_op` are the depth
and stencil tests and stencil operations; :class:`Outcome` names the test that discarded a
fragment (the observers' record of :func:`.ordering.apply_layer`).
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from .. import colorspace
from ..parts import run_parts
from ..vertex import DEPTH_MAX
from ..vocabulary import ColorSpace, CompareFunction, StencilOp


class Outcome(IntEnum):
    """What happened to a fragment in the per-fragment pipeline (the test that discarded it)."""

    WRITTEN = 0  # passed every test (ColorMask may still write no channel)
    ALPHA_TEST = 1
    STENCIL = 2
    DEPTH = 3
    ALPHA_TO_MASK = 4  # MSAA: a covered sample AlphaToMask removed
    NOT_COVERED = -1  # MSAA: a sample of the pixel the fragment does not cover


_COMPARE = {
    CompareFunction.Less: np.less,
    CompareFunction.Greater: np.greater,
    CompareFunction.LEqual: np.less_equal,
    CompareFunction.GEqual: np.greater_equal,
    CompareFunction.Equal: np.equal,
    CompareFunction.NotEqual: np.not_equal,
}
_FLOAT32_255 = np.float32(255.0)
_FLOAT32_DEPTH_MAX = np.float32(DEPTH_MAX)
#: One LDR pixel (four 8-bit codes, R in the low byte) and one HDR pixel (four float32) as a
#: single element: fancy indexing of whole pixels is several times faster than of (N, 4) rows.
_PIXEL4 = np.dtype("<u4")
_PIXEL16 = np.dtype((np.void, 16))


def compare(func: CompareFunction, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a OP b`` elementwise as a bool array."""
    if func is CompareFunction.Always:
        return np.ones(np.broadcast(a, b).shape, dtype=bool)
    if func is CompareFunction.Never:
        return np.zeros(np.broadcast(a, b).shape, dtype=bool)
    return _COMPARE[func](a, b)


def stencil_op(op: StencilOp, s: np.ndarray, ref: int) -> np.ndarray:
    """The new stencil value (int64) before the write mask."""
    s = s.astype(np.int64)
    if op is StencilOp.Keep:
        return s
    if op is StencilOp.Zero:
        return np.zeros_like(s)
    if op is StencilOp.Replace:
        return np.full_like(s, ref)
    if op is StencilOp.IncrSat:
        return np.minimum(s + 1, 255)
    if op is StencilOp.DecrSat:
        return np.maximum(s - 1, 0)
    if op is StencilOp.Invert:
        return 255 - s
    if op is StencilOp.IncrWrap:
        return (s + 1) & 255
    return (s - 1) & 255  # DecrWrap


def resolve_colors(stored: np.ndarray, samples: int, hdr: bool, linear: bool) -> np.ndarray:
    """The resolved pixels (P, 4) of ``stored`` (P, N, 4) samples (uint8 codes, or float32 in HDR),
    as llvmpipe's resolve blit (``util_make_fs_msaa_resolve``: a float32 sum from 0 in sample
    order, times 1/N) computes them, measured bit for bit on RGBA8: LDR ``v_s = float32(q_s) *
    float32(1/255)``, ``avg = (((v_0 + v_1) + ...) * float32(1/N))`` and the code
    ``rint(float32(avg * 255))`` (ties to even). Linear LDR (an sRGB framebuffer): rgb samples
    are decoded first (float32 of the exact decode), averaged likewise and encoded exactly, as a
    resolve with ``GL_FRAMEBUFFER_SRGB`` (and Direct3D's resolve of sRGB formats) does it; alpha
    as in Gamma. HDR: the float32 average. Returns uint8 codes (P, 4), or float32 in HDR."""
    f32 = np.float32
    inverse = f32(1.0 / samples)
    acc = np.zeros((stored.shape[0], 4), dtype=f32)  # from 0, as the resolve shader (0 + -0.0 is 0.0)
    if hdr:
        for s in range(samples):
            acc += stored[:, s]
        acc *= inverse
        return acc
    values = np.empty(stored.shape, dtype=f32)
    if linear:
        values[..., :3] = colorspace.DECODE_LUT[stored[..., :3]]
        np.multiply(stored[..., 3], f32(1.0 / 255.0), out=values[..., 3], dtype=f32)
    else:
        np.multiply(stored, f32(1.0 / 255.0), out=values, dtype=f32)
    for s in range(samples):
        acc += values[:, s]
    acc *= inverse
    out = np.empty((stored.shape[0], 4), dtype=np.uint8)
    if linear:
        out[:, :3] = colorspace.quantize_encoded(acc[:, :3].astype(np.float64))
        out[:, 3] = np.rint(acc[:, 3] * f32(255.0))
    else:
        out[:] = np.rint(acc * f32(255.0))
    return out


class FrameBuffers:
    """Colour, depth and stencil of a frame, flat in window order (index ``y*W + x``, y up).

    ``color``: LDR (H*W, 4) uint8 codes (sRGB-encoded rgb in Linear), HDR (H*W, 4) float32.
    ``depth``: (H*W,) int64 in 0..2**24-1. ``stencil``: (H*W,) uint8.

    With ``samples`` N > 1 (MSAA) every pixel holds N samples: index ``(y*W + x)*N + s``, the
    arrays N times as long, ``depth`` int32 (24-bit codes fit; 8x at 1080p holds 16.6M samples);
    :meth:`output` resolves them (:func:`resolve_colors`).
    """

    def __init__(self, width: int, height: int, hdr: bool, color_space: ColorSpace, clear_rgba,
                 band: tuple[int, int] | None = None, samples: int = 1) -> None:
        """Buffers cleared to ``clear_rgba``, depth 1.0 and stencil 0; with ``band`` (y0, y1)
        only those rows are cleared (a band render never reads the others)."""
        self.width, self.height = int(width), int(height)
        self.hdr = bool(hdr)
        self.linear = color_space is ColorSpace.Linear
        self.samples = int(samples)
        row = self.width * self.samples  # elements per buffer row
        n = row * self.height
        lo, hi = (0, n) if band is None else (band[0] * row, band[1] * row)
        clear = np.array([float(c) for c in clear_rgba], dtype=np.float64)[None, :]
        if self.hdr:
            self.color = np.empty((n, 4), dtype=np.float32)
        else:
            self.color = np.empty((n, 4), dtype=np.uint8)
        # One fill of whole packed pixels (a (1, 4) broadcast copies byte by byte).
        self.packed()[lo:hi].fill(np.ascontiguousarray(self.encode(clear)).view(self.packed().dtype)[0, 0])
        self.depth = np.empty(n, dtype=np.int64 if self.samples == 1 else np.int32)
        self.depth[lo:hi] = DEPTH_MAX
        self.stencil = np.empty(n, dtype=np.uint8)
        self.stencil[lo:hi] = 0

    def packed(self) -> np.ndarray:
        """The colour buffer with one element per pixel, for gathers and scatters of whole pixels:
        LDR (H*W,) little-endian uint32 (R in the low byte), HDR (H*W,) 16-byte void. A view."""
        if self.hdr:
            return self.color.view(_PIXEL16).reshape(-1)
        return self.color.view(_PIXEL4).reshape(-1)

    def copy(self) -> FrameBuffers:
        """An independent copy (a snapshot to resume from)."""
        other = object.__new__(FrameBuffers)
        other.__dict__.update(self.__dict__)
        other.color, other.depth, other.stencil = self.color.copy(), self.depth.copy(), self.stencil.copy()
        return other

    def encode(self, rgba: np.ndarray) -> np.ndarray:
        """Shading-space values (N, 4) float64 → what the colour buffer stores."""
        if self.hdr:
            return rgba.astype(np.float32)
        out = np.empty(rgba.shape, dtype=np.uint8)
        if self.linear:
            out[:, :3] = colorspace.quantize_encoded(rgba[:, :3])
        else:
            out[:, :3] = colorspace.quantize_unorm(rgba[:, :3])
        out[:, 3] = colorspace.quantize_unorm(rgba[:, 3])
        return out

    def decode(self, stored: np.ndarray) -> np.ndarray:
        """Stored colour (N, 4) → shading-space float64 values (the blend destination)."""
        if self.hdr:
            return stored.astype(np.float64)
        if self.linear:
            out = np.empty(stored.shape, dtype=np.float64)
            out[:, :3] = colorspace.DECODE_LUT[stored[:, :3]]
            out[:, 3] = stored[:, 3] / 255.0
            return out
        return stored / 255.0

    def output(self, pool=None, parts: int = 1, band: tuple[int, int] | None = None,
               out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(color (H, W, 4) float32, depth (H, W) float32, stencil (H, W) uint8), row 0 = top.

        ``pool`` / ``parts``: a thread pool to convert row ranges on (numpy's divisions
        release the GIL); the result does not depend on the split. ``band`` (y0, y1): only
        buffer rows ``[y0, y1)`` (from the bottom), so H = y1 - y0. ``out``: three arrays of
        those shapes and dtypes to write into (and return) instead of new ones.
        """
        y0, y1 = (0, self.height) if band is None else band
        h, w = y1 - y0, self.width
        if out is None:
            color = np.empty((h, w, 4), dtype=np.float32)
            depth = np.empty((h, w), dtype=np.float32)
            stencil = np.empty((h, w), dtype=np.uint8)
        else:
            color, depth, stencil = out
            for array, shape, dtype in zip(out, ((h, w, 4), (h, w), (h, w)), (np.float32, np.float32, np.uint8),
                                           strict=True):
                if array.shape != shape or array.dtype != dtype:
                    raise ValueError(f"out array {array.dtype} {array.shape} is not {np.dtype(dtype)} {shape}")
        n = self.samples
        # Depth and stencil of a multisampled pixel: its sample 0 (what GL's blit of a
        # multisampled depth-stencil buffer gives, measured on llvmpipe).
        src_color = self.color.reshape(self.height, w, n, 4)[y0:y1][::-1]
        src_depth = self.depth.reshape(self.height, w, n)[y0:y1][::-1, :, 0]

        def rows(lo: int, hi: int) -> None:
            part = src_color[lo:hi]
            if n > 1:
                resolved = resolve_colors(part.reshape(-1, n, 4), n, self.hdr, self.linear)
                part = resolved.reshape(hi - lo, w, 4)
            else:
                part = part[:, :, 0]
            if self.hdr:
                color[lo:hi] = part
            else:
                # float32 division of the exact integers equals float32(q / 255.0) for every code
                # and float32(d / (2**24 - 1)) for every depth code (both checked exhaustively in
                # tests/core/test_fastpaths.py), cheaper than a table lookup.
                np.divide(part, _FLOAT32_255, out=color[lo:hi], dtype=np.float32)
            np.divide(src_depth[lo:hi], _FLOAT32_DEPTH_MAX, out=depth[lo:hi], dtype=np.float32)

        run_parts(pool, parts, h, rows, min_part=64)
        stencil[...] = self.stencil.reshape(self.height, w, n)[y0:y1][::-1, :, 0]
        return color, depth, stencil
