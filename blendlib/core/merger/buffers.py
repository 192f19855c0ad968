"""The output merger's buffers (docs/pipeline.md §8): colour, depth and stencil, and the tests that read them.

:class:`FrameBuffers` stores a frame flat in window order and converts between shading-space
values and what the colour buffer stores; :func:`compare` and :func:`stencil_op` are the depth
and stencil tests and stencil operations; :class:`Outcome` names the test that discarded a
fragment (the observers' record of :func:`.ordering.apply_layer`).
"""

from __future__ import annotations

import functools
import threading
import weakref
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
#: Rows converted per step by :meth:`FrameBuffers.output` (cast, then divided in place while the
#: piece is in cache: 1920 × 64 pixels are 2 MB of float32 colour; docs/benchmark.md, round fifteen).
OUTPUT_ROWS = 64
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
    """The resolved pixels (P, 4) of ``stored`` (N, P, 4) samples (uint8 codes, or float32 in HDR),
    as llvmpipe's resolve blit (``util_make_fs_msaa_resolve``: a float32 sum from 0 in sample
    order, times 1/N) computes them, measured bit for bit on RGBA8: LDR ``v_s = float32(q_s) *
    float32(1/255)``, ``avg = (((v_0 + v_1) + ...) * float32(1/N))`` and the code
    ``rint(float32(avg * 255))`` (ties to even). Linear LDR (an sRGB framebuffer): rgb samples
    are decoded first (float32 of the exact decode), averaged likewise and encoded exactly, as a
    resolve with ``GL_FRAMEBUFFER_SRGB`` (and Direct3D's resolve of sRGB formats) does it; alpha
    as in Gamma. HDR: the float32 average. Returns uint8 codes (P, 4), or float32 in HDR."""
    f32 = np.float32
    inverse = f32(1.0 / samples)
    acc = np.zeros((stored.shape[1], 4), dtype=f32)  # from 0, as the resolve shader (0 + -0.0 is 0.0)
    if hdr:
        for s in range(samples):
            acc += stored[s]
        acc *= inverse
        return acc
    values = np.empty(stored.shape, dtype=f32)
    if linear:
        values[..., :3] = colorspace.DECODE_LUT[stored[..., :3]]
        np.multiply(stored[..., 3], f32(1.0 / 255.0), out=values[..., 3], dtype=f32)
    else:
        np.multiply(stored, f32(1.0 / 255.0), out=values, dtype=f32)
    for s in range(samples):
        acc += values[s]
    acc *= inverse
    out = np.empty((stored.shape[1], 4), dtype=np.uint8)
    if linear:
        out[:, :3] = colorspace.quantize_encoded(acc[:, :3].astype(np.float64))
        out[:, 3] = np.rint(acc[:, 3] * f32(255.0))
    else:
        out[:] = np.rint(acc * f32(255.0))
    return out


@functools.cache
def _uniform_resolve_table(samples: int, linear: bool) -> np.ndarray | None:
    """(256, 4) uint8: the resolve of a pixel whose N samples all hold code q (row q, per channel),
    or None where that is q itself (the case for 2, 4 and 8 samples, Gamma and Linear: checked
    here, not assumed)."""
    codes = np.arange(256, dtype=np.uint8)[:, None].repeat(4, axis=1)
    table = resolve_colors(np.ascontiguousarray(np.broadcast_to(codes, (samples, 256, 4))), samples, False, linear)
    return None if np.array_equal(table, codes) else table


def resolve_planes(planes: np.ndarray, uniform: np.ndarray, samples: int, hdr: bool, linear: bool) -> np.ndarray:
    """:func:`resolve_colors` of pixels stored as ``planes`` (N, P, 4) with ``uniform`` (P,) bool
    flags (:attr:`FrameBuffers.uniform`: the pixel's samples all hold plane 0's colour, the other
    planes possibly stale). The same values as resolving N copies of plane 0 there."""
    out = np.empty((planes.shape[1], 4), dtype=np.float32 if hdr else np.uint8)
    mixed = np.flatnonzero(~uniform)
    if mixed.size:
        stored = planes.take(mixed, axis=1)
        # Samples left bit-identical by fragments that each covered only some of them resolve as
        # uniform pixels do.
        words = stored.view(np.uint32).reshape(samples, mixed.size, -1)
        equal = (words[1:] == words[:1]).all(axis=(0, 2))
        uniform = uniform.copy()
        uniform[mixed[equal]] = True
        differ = ~equal
        out[mixed[differ]] = resolve_colors(stored[:, differ], samples, hdr, linear)
    same = np.flatnonzero(uniform)
    if same.size:
        first = planes[0].take(same, axis=0)
        if hdr:
            out[same] = resolve_colors(np.broadcast_to(first, (samples, *first.shape)), samples, hdr, linear)
        else:
            table = _uniform_resolve_table(samples, linear)
            out[same] = first if table is None else table[first, np.arange(4)]
    return out


#: A free entry of :meth:`FrameBuffers.peel_scratch` (greater than any fragment's index).
PEEL_FREE = np.iinfo(np.int64).max

# The peel table of the last buffers gone, all free again: the next buffers of its size take it
# instead of filling a new one (16.6 MB at 1080p, a few ms a render). One is kept at most.
_spare_peel: list[np.ndarray] = []
_spare_lock = threading.Lock()


def _peel_table(size: int) -> np.ndarray:
    """(size,) int64 every entry :data:`PEEL_FREE`: the spare table when it has that size."""
    with _spare_lock:
        if _spare_peel and _spare_peel[0].size == size:
            return _spare_peel.pop()
    return np.full(size, PEEL_FREE, dtype=np.int64)


def _keep_spare(table: np.ndarray) -> None:
    """Keep the table of buffers gone (left all free by its users) as the spare."""
    with _spare_lock:
        _spare_peel[:] = [table]


class FrameBuffers:
    """Colour, depth and stencil of a frame, flat in window order (index ``y*W + x``, y up).

    ``color``: LDR (H*W, 4) uint8 codes (sRGB-encoded rgb in Linear), HDR (H*W, 4) float32.
    ``depth``: (H*W,) int64 in 0..2**24-1. ``stencil``: (H*W,) uint8.

    With ``samples`` N > 1 (MSAA) every pixel holds N samples, stored as N planes of the frame:
    sample ``s`` of pixel ``p`` at index ``s*H*W + p`` (the merger applies a sample's fragments
    to its plane); ``depth`` is int32 then (24-bit codes fit; 8x at 1080p holds 16.6M samples).
    ``uniform`` (H*W,) bool: the pixel's samples all hold the colour of plane 0, whose value alone
    is kept up to date there (as GPUs compress colour: fragments covering a whole pixel of
    equal samples are blended once, :func:`..msaa.merge_samples`; :meth:`spread` writes the
    others before samples part ways). Depth and stencil are always per sample. :meth:`output`
    resolves the samples (:func:`resolve_planes`).
    """

    def __init__(self, width: int, height: int, hdr: bool, color_space: ColorSpace, clear_rgba,
                 band: tuple[int, int] | None = None, samples: int = 1,
                 shared: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Buffers cleared to ``clear_rgba``, depth 1.0 and stencil 0; with ``band`` (y0, y1)
        only those rows are cleared (a band render never reads the others). ``shared``: (depth,
        stencil) arrays to hold as they are instead (:meth:`copy`'s ``colors_only``)."""
        self.width, self.height = int(width), int(height)
        self.hdr = bool(hdr)
        self.linear = color_space is ColorSpace.Linear
        self.samples = int(samples)
        pixels = self.width * self.height
        n = pixels * self.samples
        lo, hi = (0, pixels) if band is None else (band[0] * self.width, band[1] * self.width)
        clear = np.array([float(c) for c in clear_rgba], dtype=np.float64)[None, :]
        if self.hdr:
            self.color = np.empty((n, 4), dtype=np.float32)
        else:
            self.color = np.empty((n, 4), dtype=np.uint8)
        # One fill of whole packed pixels (a (1, 4) broadcast copies byte by byte), in every plane.
        self.packed().reshape(self.samples, pixels)[:, lo:hi].fill(
            np.ascontiguousarray(self.encode(clear)).view(self.packed().dtype)[0, 0])
        if shared is not None:
            self.depth, self.stencil = shared
        else:
            self.depth = np.empty(n, dtype=np.int64 if self.samples == 1 else np.int32)
            self.depth.reshape(self.samples, pixels)[:, lo:hi] = DEPTH_MAX
            self.stencil = np.empty(n, dtype=np.uint8)
            self.stencil.reshape(self.samples, pixels)[:, lo:hi] = 0
        self.uniform = None if self.samples == 1 else np.ones(pixels, dtype=bool)
        self._peel = None
        self._peel_lock = threading.Lock()

    def peel_scratch(self) -> np.ndarray:
        """(H*W,) int64, every entry :data:`PEEL_FREE`: the table in which the merger finds each
        pixel's first remaining fragment (:func:`.ordering.primitive_layers`), made on first use
        and kept for the buffers' life, then as the spare of the next buffers of its size.
        Whoever uses it leaves it as it found it; screen-band workers share it, as they share
        the buffers, because they touch disjoint pixels."""
        if self._peel is None:
            with self._peel_lock:
                if self._peel is None:
                    self._peel = _peel_table(self.plane)
                    weakref.finalize(self, _keep_spare, self._peel)
        return self._peel

    def spread(self, pixels: np.ndarray) -> None:
        """Write the colour of plane 0 into every sample of ``pixels`` (K,) int64 (uniform ones,
        distinct), which are then no longer uniform: their samples are about to part ways."""
        packed, plane = self.packed(), self.plane
        value = packed[pixels]
        for s in range(1, self.samples):
            packed[s * plane + pixels] = value
        self.uniform[pixels] = False

    def rejoin(self, pixels: np.ndarray) -> None:
        """Mark those of ``pixels`` (K,) int64 whose samples hold bit-identical colours uniform."""
        words = self.color.view(np.uint32).reshape(self.samples, self.plane, -1)  # 1 (LDR) or 4 (HDR) words
        first = words[0, pixels]
        same = np.ones(pixels.size, dtype=bool)
        for s in range(1, self.samples):
            same &= (words[s, pixels] == first).all(axis=1)
        self.uniform[pixels[same]] = True

    def sample_colors(self, pixels: np.ndarray) -> np.ndarray:
        """(K, N, 4) the stored colour of every sample of ``pixels`` (K,) int64 (uniform pixels'
        from plane 0)."""
        planes = self.color.reshape(self.samples, self.plane, 4)
        out = np.ascontiguousarray(planes.take(pixels, axis=1).transpose(1, 0, 2))
        if self.uniform is not None:
            same = self.uniform[pixels]
            out[same] = out[same, :1]
        return out

    @property
    def plane(self) -> int:
        """Elements of one sample plane (H*W): sample ``s`` of pixel ``p`` is at ``s*plane + p``."""
        return self.width * self.height

    def packed(self) -> np.ndarray:
        """The colour buffer with one element per pixel, for gathers and scatters of whole pixels:
        LDR (H*W,) little-endian uint32 (R in the low byte), HDR (H*W,) 16-byte void. A view."""
        if self.hdr:
            return self.color.view(_PIXEL16).reshape(-1)
        return self.color.view(_PIXEL4).reshape(-1)

    def copy(self, band: tuple[int, int] | None = None, colors_only: bool = False) -> FrameBuffers:
        """An independent copy (a snapshot to resume from); with ``band`` (y0, y1) only those rows
        are copied, the others left unset (what a band render resumed from it reads).
        ``colors_only``: the depth and stencil arrays are these buffers' own, shared, not copied:
        for a render that never writes them (no ZWrite, no stencil)."""
        other = FrameBuffers.unset(self.kind, shared=(self.depth, self.stencil) if colors_only else None)
        self.copy_rows(other, *(band or (0, self.height)), colors_only=colors_only)
        return other

    @property
    def kind(self) -> tuple[int, int, bool, bool, int]:
        """(width, height, hdr, linear, samples): what :meth:`unset` needs to make buffers like these."""
        return self.width, self.height, self.hdr, self.linear, self.samples

    @classmethod
    def unset(cls, kind: tuple[int, int, bool, bool, int],
              shared: tuple[np.ndarray, np.ndarray] | None = None) -> FrameBuffers:
        """Buffers of :attr:`kind` ``kind``, every array unset (rows to be filled by :meth:`copy_rows`);
        ``shared``: (depth, stencil) arrays of buffers of that kind to hold instead of new ones."""
        width, height, hdr, linear, samples = kind
        return cls(width, height, hdr, ColorSpace.Linear if linear else ColorSpace.Gamma, (0.0, 0.0, 0.0, 0.0),
                   band=(0, 0), samples=samples, shared=shared)

    def by_row(self) -> dict[str, np.ndarray]:
        """Every buffer as a (planes, H, W, ...) view, so rows are the second axis: ``color``,
        ``depth`` and ``stencil`` with a plane per sample, and with MSAA ``uniform`` (one plane)."""
        shape = (self.samples, self.height, self.width)
        views = {name: array.reshape(*shape, *array.shape[1:])
                 for name, array in (("color", self.color), ("depth", self.depth), ("stencil", self.stencil))}
        if self.uniform is not None:
            views["uniform"] = self.uniform.reshape(1, self.height, self.width)
        return views

    def copy_rows(self, other: FrameBuffers, y0: int, y1: int, colors_only: bool = False) -> None:
        """Copy rows ``[y0, y1)`` (every sample plane) of these buffers into ``other`` (same kind);
        ``colors_only``: the colour (and MSAA's uniform flags) alone."""
        into = other.by_row()
        for name, rows in self.by_row().items():
            if not (colors_only and name in ("depth", "stencil")):
                into[name][:, y0:y1] = rows[:, y0:y1]

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
               out: tuple[np.ndarray, np.ndarray | None, np.ndarray | None] | None = None, color_only: bool = False,
               ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """(color (H, W, 4) float32, depth (H, W) float32, stencil (H, W) uint8), row 0 = top.

        ``pool`` / ``parts``: a thread pool to convert row ranges on (numpy's divisions
        release the GIL); the result does not depend on the split. ``band`` (y0, y1): only
        buffer rows ``[y0, y1)`` (from the bottom), so H = y1 - y0. ``out``: three arrays of
        those shapes and dtypes to write into (and return) instead of new ones.
        ``color_only``: the colour alone (depth and stencil None, and None in ``out``): the
        sorted reference's image.
        """
        y0, y1 = (0, self.height) if band is None else band
        h, w = y1 - y0, self.width
        if out is None:
            color = np.empty((h, w, 4), dtype=np.float32)
            depth = None if color_only else np.empty((h, w), dtype=np.float32)
            stencil = None if color_only else np.empty((h, w), dtype=np.uint8)
        else:
            color, depth, stencil = out
            if color_only and (depth is not None or stencil is not None):
                raise ValueError("output: color_only writes no depth or stencil (None in out)")
            for array, shape, dtype in zip(out, ((h, w, 4), (h, w), (h, w)), (np.float32, np.float32, np.uint8),
                                           strict=True):
                if array is None and color_only:
                    continue
                if array.shape != shape or array.dtype != dtype:
                    raise ValueError(f"out array {array.dtype} {array.shape} is not {np.dtype(dtype)} {shape}")
        n = self.samples
        # Depth and stencil of a multisampled pixel: its sample 0 (what GL's blit of a
        # multisampled depth-stencil buffer gives, measured on llvmpipe).
        src_color = self.color.reshape(n, self.height, w, 4)[:, y0:y1][:, ::-1]
        src_depth = self.depth.reshape(n, self.height, w)[0, y0:y1][::-1]

        planes = self.color.reshape(n, -1, 4)

        def rows(lo: int, hi: int) -> None:
            if n > 1:  # output rows [lo, hi) are buffer rows [y1 - hi, y1 - lo): contiguous in every plane
                first, end = (y1 - hi) * w, (y1 - lo) * w
                resolved = resolve_planes(planes[:, first:end], self.uniform[first:end], n, self.hdr, self.linear)
                part = resolved.reshape(hi - lo, w, 4)[::-1]
            else:
                part = src_color[0, lo:hi]
            color[lo:hi] = part
            if not self.hdr:
                # float32 division of the exact integers equals float32(q / 255.0) for every code
                # and float32(d / (2**24 - 1)) for every depth code (both checked exhaustively in
                # tests/core/test_fastpaths.py), cheaper than a table lookup. Codes and depth codes
                # (below 2**24) convert to float32 exactly, so casting first and dividing in place
                # gives the same values, without the mixed-type division's buffered casts.
                np.divide(color[lo:hi], _FLOAT32_255, out=color[lo:hi])
            if depth is not None:
                depth[lo:hi] = src_depth[lo:hi]
                np.divide(depth[lo:hi], _FLOAT32_DEPTH_MAX, out=depth[lo:hi])

        # Pieces of OUTPUT_ROWS rows: each piece's float32 rows are divided while still in cache.
        run_parts(pool, parts, h, rows, min_part=64, piece=OUTPUT_ROWS)
        if stencil is not None:
            stencil[...] = self.stencil.reshape(n, self.height, w)[0, y0:y1][::-1]
        return color, depth, stencil
