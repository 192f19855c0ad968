"""Output merger (docs/pipeline.md §8): stencil, depth, blending, colour mask — in exact primitive order.

A chunk of fragments arrives in draw order. Fragments alone on their pixel are
independent and applied at once. The rest are sorted stably by pixel, ranked
within their pixel (0 = first drawn), and applied layer by layer: layer k holds
the k-th fragment of every such pixel, so each layer touches distinct pixels and
is one vectorised read-modify-write. The result equals applying the fragments one
by one in order, as a GPU does, with a loop over layers (the depth complexity of
one draw call), never over fragments or pixels.
"""

from __future__ import annotations

import contextlib
import threading
from collections import OrderedDict
from enum import IntEnum

import numpy as np

from . import colorspace
from .parts import run_parts
from .vertex import DEPTH_MAX
from .vocabulary import BlendFactor, BlendOp, ColorSpace, CompareFunction, Pass, StencilOp


class Outcome(IntEnum):
    """What happened to a fragment in the per-fragment pipeline (the test that discarded it)."""

    WRITTEN = 0  # passed every test (ColorMask may still write no channel)
    ALPHA_TEST = 1
    STENCIL = 2
    DEPTH = 3

_COMPARE = {
    CompareFunction.Less: np.less,
    CompareFunction.Greater: np.greater,
    CompareFunction.LEqual: np.less_equal,
    CompareFunction.GEqual: np.greater_equal,
    CompareFunction.Equal: np.equal,
    CompareFunction.NotEqual: np.not_equal,
}
_CHANNEL_INDEX = {"R": 0, "G": 1, "B": 2, "A": 3}
_FLOAT32_255 = np.float32(255.0)
_FLOAT32_DEPTH_MAX = np.float32(DEPTH_MAX)
#: One LDR pixel (four 8-bit codes, R in the low byte) and one HDR pixel (four float32) as a
#: single element: fancy indexing of whole pixels is several times faster than of (N, 4) rows.
_PIXEL4 = np.dtype("<u4")
_PIXEL16 = np.dtype((np.void, 16))
#: ColorMask letters → the bits of their channel in a packed LDR pixel.
_MASK_BITS = {"R": 0x000000FF, "G": 0x0000FF00, "B": 0x00FF0000, "A": 0xFF000000}


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


class FrameBuffers:
    """Colour, depth and stencil of a frame, flat in window order (index ``y*W + x``, y up).

    ``color``: LDR (H*W, 4) uint8 codes (sRGB-encoded rgb in Linear), HDR (H*W, 4) float32.
    ``depth``: (H*W,) int64 in 0..2**24-1. ``stencil``: (H*W,) uint8.
    """

    def __init__(self, width: int, height: int, hdr: bool, color_space: ColorSpace, clear_rgba,
                 band: tuple[int, int] | None = None) -> None:
        """Buffers cleared to ``clear_rgba``, depth 1.0 and stencil 0; with ``band`` (y0, y1)
        only those rows are cleared (a band render never reads the others)."""
        self.width, self.height = int(width), int(height)
        self.hdr = bool(hdr)
        self.linear = color_space is ColorSpace.Linear
        n = self.width * self.height
        lo, hi = (0, n) if band is None else (band[0] * self.width, band[1] * self.width)
        clear = np.array([float(c) for c in clear_rgba], dtype=np.float64)[None, :]
        if self.hdr:
            self.color = np.empty((n, 4), dtype=np.float32)
        else:
            self.color = np.empty((n, 4), dtype=np.uint8)
        # One fill of whole packed pixels (a (1, 4) broadcast copies byte by byte, 50x slower).
        self.packed()[lo:hi].fill(np.ascontiguousarray(self.encode(clear)).view(self.packed().dtype)[0, 0])
        self.depth = np.empty(n, dtype=np.int64)
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
        src_color = self.color.reshape(self.height, w, 4)[y0:y1][::-1]
        src_depth = self.depth.reshape(self.height, w)[y0:y1][::-1]

        def rows(lo: int, hi: int) -> None:
            if self.hdr:
                color[lo:hi] = src_color[lo:hi]
            else:
                # float32 division of the exact integers equals float32(q / 255.0) for every code
                # and float32(d / (2**24 - 1)) for every depth code (both checked exhaustively in
                # tests/core/test_fastpaths.py), at a seventh of a table lookup's time.
                np.divide(src_color[lo:hi], _FLOAT32_255, out=color[lo:hi], dtype=np.float32)
            np.divide(src_depth[lo:hi], _FLOAT32_DEPTH_MAX, out=depth[lo:hi], dtype=np.float32)

        run_parts(pool, parts, h, rows, min_part=64)
        stencil[...] = self.stencil.reshape(self.height, w)[y0:y1][::-1]
        return color, depth, stencil


def _apply_op(op: BlendOp, s: np.ndarray, fs, d: np.ndarray, fd) -> np.ndarray:
    if op is BlendOp.Min:
        return np.minimum(s, d)
    if op is BlendOp.Max:
        return np.maximum(s, d)
    if op is BlendOp.Add:
        return s * fs + d * fd
    if op is BlendOp.Sub:
        return s * fs - d * fd
    return d * fd - s * fs  # RevSub


def blend(p: Pass, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Blend result (N, 4) float64 from source and destination in shading space (§8)."""
    if not p.blend:
        return src
    out = np.empty_like(src)
    for c, channel in enumerate(_blend_channels(p, [src[:, k] for k in range(4)], [dst[:, k] for k in range(4)])):
        out[:, c] = channel
    return out


#: Colour factors that are one array for R, G and B alike (computed once per blend).
_SHARED_BY_RGB = frozenset({BlendFactor.SrcAlpha, BlendFactor.OneMinusSrcAlpha, BlendFactor.DstAlpha,
                            BlendFactor.OneMinusDstAlpha, BlendFactor.SrcAlphaSaturate})


def _blend_channels(p: Pass, s: list, d: list) -> list:
    """The blend of each channel (R, G, B, A) from four source and four destination (N,) arrays."""
    sa, da, opa = p.alpha_factors
    shared: dict = {}  # a factor R, G and B share, computed for R and reused (the same values)

    def colour_factor(f: BlendFactor, c: int):
        if f not in _SHARED_BY_RGB:
            return _channel_factor(f, c, s, d)
        if f not in shared:
            shared[f] = _channel_factor(f, c, s, d)
        return shared[f]

    out = [_apply_op(p.blend_op, s[c], colour_factor(p.src_blend, c), d[c], colour_factor(p.dst_blend, c))
           for c in range(3)]
    out.append(_apply_op(opa, s[3], _channel_factor(sa, 3, s, d), d[3], _channel_factor(da, 3, s, d)))
    return out


#: Colour factors that read another channel of the destination (its alpha): a per-channel
#: lookup table cannot express them.
_CROSS_CHANNEL = frozenset({BlendFactor.DstAlpha, BlendFactor.OneMinusDstAlpha, BlendFactor.SrcAlphaSaturate})


def lut_eligible(p: Pass, hdr: bool) -> bool:
    """Whether each written channel of this pass depends only on the source and the same
    destination channel's 8-bit code, so :func:`blend_lut` can tabulate it exactly."""
    if hdr:
        return False
    return not p.blend or (p.src_blend not in _CROSS_CHANNEL and p.dst_blend not in _CROSS_CHANNEL)


def table_rows(p: Pass) -> int:
    """Rows per colour of :func:`blend_lut`: 256 destination codes, or 1 for ``Blend Off``
    (the stored value is the source's, whatever the destination)."""
    return 256 if p.blend else 1


def table_pays(p: Pass, hdr: bool, linear: bool, palette: np.ndarray, fragments: int) -> bool:
    """Whether ``fragments`` of colours from ``palette`` (K, 4) should blend through a
    :class:`BlendTable`: the pass allows it (:func:`lut_eligible`) and the table is no larger
    than the fragments it serves, or a render before this one already built it (kept in
    :data:`RECENT_TABLES`: a viewport's reduced frames after its full ones)."""
    if not lut_eligible(p, hdr):
        return False
    if palette.shape[0] * table_rows(p) <= fragments:
        return True
    key = palette.tobytes()
    return any(RECENT_TABLES.peek((p, hdr, linear, (key, pairs))) for pairs in (False, True))


def blend_lut(buf: FrameBuffers, p: Pass, palette: np.ndarray) -> np.ndarray:
    """Stored codes for every (source colour, destination code): (K, 256, 4) uint8, or
    (K, 1, 4) for ``Blend Off`` (:func:`table_rows`).

    Row (k, d) is the ordinary blend of ``palette[k]`` over a destination whose four
    channels all hold code ``d``, computed by the same functions as per-fragment blending,
    so a lookup equals the per-fragment result bit for bit (for :func:`lut_eligible` passes).
    """
    k = palette.shape[0]
    if not p.blend:
        return buf.encode(np.minimum(np.maximum(palette, 0.0), 1.0)).reshape(k, 1, 4)
    if buf.hdr:
        src = np.repeat(np.minimum(np.maximum(palette, 0.0), 1.0), 256, axis=0)
        codes = np.repeat(np.tile(np.arange(256, dtype=np.uint8), k)[:, None], 4, axis=1)
        return buf.encode(blend(p, src, buf.decode(codes))).reshape(k, 256, 4)
    # The per-fragment blend itself, over packed destinations whose four bytes hold d.
    stored = np.tile(np.arange(256, dtype=np.uint32) * np.uint32(0x01010101), k)
    packed = _blend_fragments(buf, p, stored, np.repeat(palette, 256, axis=0))
    return packed.view(np.uint8).reshape(k, 256, 4)


#: A table of two channels (65536 destination pairs, 256 KB) per colour pays once a chunk
#: holds this many fragments of the colour; below it, four 256-entry channel tables per colour.
PAIR_TABLE_FRAGMENTS = 1 << 15


class BlendTable:
    """A :func:`blend_lut` table in the packed form the lookups read (LDR buffers only).

    ``pairs`` False: four tables of (K*256,) uint32, channel ``c``'s result code already
    shifted to its byte, indexed ``id*256 + code_c``. ``pairs`` True: two tables of
    (K*65536,) uint32 for channels (R, G) and (B, A), indexed ``id*65536 + (code_lo |
    code_hi << 8)`` — two lookups per fragment instead of four.
    """

    def __init__(self, lut: np.ndarray, pairs: bool = False) -> None:
        self.size = int(lut.shape[0])
        self.pairs = bool(pairs)
        self.direct = None
        if lut.shape[1] == 1:  # Blend Off: one packed value per colour, whatever is stored
            self.direct = np.ascontiguousarray(lut.reshape(-1, 4)).view(np.uint32).reshape(-1)
            return
        t = lut.astype(np.uint32)
        if self.pairs:
            self.tables = [((t[:, None, :, c] << (8 * c)) | (t[:, :, None, c + 1] << (8 * c + 8))).reshape(-1)
                           for c in (0, 2)]
        else:
            self.tables = [(t[:, :, c] << (8 * c)).reshape(-1) for c in range(4)]

    @property
    def nbytes(self) -> int:
        return int(self.direct.nbytes) if self.direct is not None else sum(int(t.nbytes) for t in self.tables)

    def lookup(self, stored: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """New packed pixels (N,) uint32 for ``stored`` (N,) uint32 and palette ``ids`` (N,) >= 0."""
        if self.direct is not None:
            return np.take(self.direct, ids)
        base = None
        if self.size > 1:
            base = ids.astype(np.intp) << (16 if self.pairs else 8)
        out = None
        if self.pairs:
            parts = (np.bitwise_and(stored, 0xFFFF).astype(np.intp), (stored >> 16).astype(np.intp))
        else:
            parts = [np.bitwise_and(stored, 0xFF).astype(np.intp)] + [
                np.bitwise_and(stored >> (8 * c), 0xFF).astype(np.intp) for c in (1, 2, 3)]
        for table, index in zip(self.tables, parts, strict=True):
            if base is not None:
                index += base
            value = np.take(table, index)
            if out is None:
                out = value
            else:
                out |= value
        return out


def apply_layer(
    buf: FrameBuffers, p: Pass, pix: np.ndarray, depth: np.ndarray | None, rgba: np.ndarray | None,
    ids: np.ndarray | None = None, lut: BlendTable | None = None, outcome: np.ndarray | None = None,
) -> None:
    """Apply fragments on *distinct* pixels: stencil → depth → stencil op → depth write → blend → mask.

    ``pix`` (N,) int64, ``depth`` (N,) int64, ``rgba`` (N, 4) float64 shading-space colours.
    ``depth`` None: every fragment is known to pass the depth test (the caller proved it) and
    the pass does not write depth. With ``ids`` (N,) int32 and a :class:`BlendTable` ``lut``
    (built once per palette by the caller), fragments with ``ids >= 0`` take their stored codes from
    the table (their ``rgba`` rows are not read; ``rgba`` may be None when all are tabled).
    ``outcome`` (N,) int8, optional: receives each fragment's :class:`Outcome`.
    """
    if depth is None:
        passed = None
        if outcome is not None:
            outcome[:] = Outcome.WRITTEN
    else:
        passed = compare(p.ztest, depth, buf.depth[pix])
        if outcome is not None:
            outcome[:] = np.where(passed, Outcome.WRITTEN, Outcome.DEPTH)
    if p.stencil:
        s_old = buf.stencil[pix]
        rm, wm, ref = p.stencil_read_mask, p.stencil_write_mask, p.stencil_ref
        s_pass = compare(p.stencil_comp, np.int64(ref & rm), s_old.astype(np.int64) & rm)
        z_pass = s_pass if passed is None else passed & s_pass
        zfail = s_old if passed is None else stencil_op(p.stencil_zfail, s_old, ref)
        new = np.where(~s_pass, stencil_op(p.stencil_fail, s_old, ref),
                       np.where(z_pass, stencil_op(p.stencil_pass, s_old, ref), zfail))
        buf.stencil[pix] = ((s_old.astype(np.int64) & (~wm & 255)) | (new & wm)).astype(np.uint8)
        passed = z_pass
        if outcome is not None:
            outcome[~s_pass] = Outcome.STENCIL
    if passed is not None:
        if not np.any(passed):
            return
        if not passed.all():
            index = np.flatnonzero(passed)
            pix = np.take(pix, index)
            depth = None if depth is None else np.take(depth, index)
            rgba = None if rgba is None else np.take(rgba, index, axis=0)
            ids = None if ids is None else np.take(ids, index)
    if p.zwrite:
        buf.depth[pix] = depth
    if not p.color_mask:
        return
    packed = buf.packed()
    stored = packed[pix]
    if ids is not None:
        tabled = ids >= 0
        if tabled.all():
            result = lut.lookup(stored, ids)
        else:
            result = np.empty_like(stored)
            result[tabled] = lut.lookup(stored[tabled], ids[tabled])
            plain = ~tabled
            result[plain] = _blend_fragments(buf, p, stored[plain], rgba[plain])
    else:
        result = _blend_fragments(buf, p, stored, rgba)
    if len(p.color_mask) < 4:
        if buf.hdr:
            merged = result.view(np.float32).reshape(-1, 4)
            old = stored.view(np.float32).reshape(-1, 4)
            keep = [_CHANNEL_INDEX[c] for c in "RGBA" if c not in p.color_mask]
            merged[:, keep] = old[:, keep]
        else:
            bits = np.uint32(sum(_MASK_BITS[c] for c in p.color_mask))
            result = (stored & ~bits) | (result & bits)
    packed[pix] = result


def _channel_factor(f: BlendFactor, c: int, s: list, d: list):
    """Blend factor of channel ``c`` (3 = alpha) as a scalar or (N,) array, from channel lists
    ``s`` / ``d`` (four (N,) float64 arrays each); SrcAlphaSaturate is 1 for alpha (§8)."""
    if f is BlendFactor.One or (c == 3 and f is BlendFactor.SrcAlphaSaturate):
        return 1.0
    if f is BlendFactor.Zero:
        return 0.0
    if f is BlendFactor.SrcAlphaSaturate:
        return np.minimum(s[3], 1.0 - d[3])
    if c == 3:
        base = s[3] if f in (BlendFactor.SrcColor, BlendFactor.SrcAlpha, BlendFactor.OneMinusSrcColor,
                             BlendFactor.OneMinusSrcAlpha) else d[3]
    else:
        base = {
            BlendFactor.SrcColor: s[c], BlendFactor.OneMinusSrcColor: s[c],
            BlendFactor.SrcAlpha: s[3], BlendFactor.OneMinusSrcAlpha: s[3],
            BlendFactor.DstColor: d[c], BlendFactor.OneMinusDstColor: d[c],
            BlendFactor.DstAlpha: d[3], BlendFactor.OneMinusDstAlpha: d[3],
        }[f]
    return 1.0 - base if f.value.startswith("OneMinus") else base


def _blend_ldr(buf: FrameBuffers, p: Pass, stored: np.ndarray, rgba: np.ndarray) -> np.ndarray:
    """:func:`_blend_fragments` of an 8-bit buffer, one channel at a time on contiguous (N,)
    arrays: the operations of :func:`blend` and :meth:`FrameBuffers.encode`, element by element."""
    codes = stored.view(np.uint8).reshape(-1, 4)
    n = stored.shape[0]
    # Channels first, clamped in place: one copy, and every later operation on contiguous rows.
    src = np.ascontiguousarray(rgba.T, dtype=np.float64)
    np.maximum(src, 0.0, out=src)
    np.minimum(src, 1.0, out=src)
    result = list(src)
    if p.blend:
        dst = np.empty((4, n), dtype=np.float64)
        if buf.linear:
            np.take(colorspace.DECODE_LUT, codes.T[:3], out=dst[:3], mode="clip")  # codes < 256: in range
            np.divide(codes[:, 3], 255.0, out=dst[3])
        else:
            np.divide(codes.T, 255.0, out=dst)
        result = _blend_channels(p, result, list(dst))
    out = np.empty((n, 4), dtype=np.uint8)
    for c in range(4):
        if buf.linear and c < 3:
            out[:, c] = colorspace.quantize_encoded(result[c])
        else:  # in place: each result row is this function's own array
            out[:, c] = colorspace.unorm_codes_in_place(result[c])
    return out.view(stored.dtype).reshape(-1)


def _blend_fragments(buf: FrameBuffers, p: Pass, stored: np.ndarray, rgba: np.ndarray) -> np.ndarray:
    """Packed stored values (N,) of blending ``rgba`` (N, 4) float64 over the packed ``stored`` (N,)."""
    if not buf.hdr:
        return _blend_ldr(buf, p, stored, rgba)
    src = rgba
    if p.blend:
        src = blend(p, src, buf.decode(stored.view(np.float32).reshape(-1, 4)))
    return np.ascontiguousarray(buf.encode(src)).view(stored.dtype).reshape(-1)


#: Up to this many fragments per pixel, layers are peeled (one ``minimum.at`` per layer);
#: deeper draw calls rank all fragments with one stable sort instead.
PEEL_LAYERS = 8


class RecentTables:
    """Blend tables of recent renders by content — (pass, colour space, palette, form) —
    dropping the least recently used past ``max_bytes``. A viewport, an animation, the frame
    debugger and ``analyze`` render the same palettes under the same passes again and again;
    a table is a pure function of its key, so a kept one equals a rebuilt one bit for bit."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = int(max_bytes)
        self._tables: OrderedDict = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()

    def get(self, key) -> BlendTable | None:
        with self._lock:
            table = self._tables.get(key)
            if table is not None:
                self._tables.move_to_end(key)
            return table

    def peek(self, key) -> bool:
        """Whether a table is kept under ``key`` (its recency unchanged)."""
        with self._lock:
            return key in self._tables

    def put(self, key, table: BlendTable) -> None:
        with self._lock:
            if key in self._tables or table.nbytes > self.max_bytes:
                return
            self._tables[key] = table
            self._bytes += table.nbytes
            while self._bytes > self.max_bytes:
                _, dropped = self._tables.popitem(last=False)
                self._bytes -= dropped.nbytes

    @property
    def nbytes(self) -> int:
        return self._bytes

    def __len__(self) -> int:
        return len(self._tables)

    def clear(self) -> None:
        with self._lock:
            self._tables.clear()
            self._bytes = 0


#: The process's kept blend tables (a pair table of one colour is 512 KB, a channel table 4 KB).
RECENT_TABLES = RecentTables(64 << 20)


class BlendTables(dict):
    """The :class:`BlendTable` s of one draw call, by palette, shared by its band workers: a
    table is built once, under a lock of its own key (a worker needing the same table waits for
    it instead of building it too; other tables are built meanwhile)."""

    def __init__(self) -> None:
        super().__init__()
        self._guard = threading.Lock()
        self._locks: dict = {}

    def key_lock(self, key) -> threading.Lock:
        with self._guard:
            return self._locks.setdefault(key, threading.Lock())


_NEARER_PASSES = (CompareFunction.Less, CompareFunction.LEqual)


def order_free_depth(p: Pass) -> bool:
    """Whether a pass only keeps the nearest (or farthest) depth per pixel: ZWrite On with
    ZTest Less, LEqual, Greater or GEqual, no colour written, no stencil. Its fragments can
    then be applied in any order (the merger takes a per-pixel minimum or maximum)."""
    return (not p.color_mask and not p.stencil and p.zwrite
            and p.ztest in (*_NEARER_PASSES, CompareFunction.Greater, CompareFunction.GEqual))


def merge(
    buf: FrameBuffers, p: Pass, pix: np.ndarray, depth: np.ndarray | None, rgba: np.ndarray | None,
    ids: np.ndarray | None = None, palette: np.ndarray | None = None, outcome: np.ndarray | None = None,
    disjoint: bool = False, tables: dict | None = None,
) -> int:
    """Apply a chunk of fragments (in draw order) exactly as one-by-one; returns the layer count
    (1 for a pass whose result does not depend on the order: :func:`order_free_depth`).

    Optional ``ids`` (N,) int32 / ``palette`` (K, 4) float64: fragments with ``ids >= 0``
    have the colour ``palette[ids]`` (constant over their triangle) and blend through a
    lookup table (:func:`blend_lut`); only valid when :func:`lut_eligible`.
    Optional ``outcome`` (N,) int8 receives each fragment's :class:`Outcome`.
    ``depth`` None: all fragments pass the depth test and the pass writes no depth (see
    :func:`apply_layer`). ``disjoint``: the caller knows the fragments hit distinct pixels.
    ``tables``: a dict the caller keeps for the chunks of one draw call (same pass and
    buffer kind): blend tables are built once per palette there instead of once per chunk
    (a :class:`BlendTables` when band workers share it); tables of earlier renders are
    taken from :data:`RECENT_TABLES`.
    """
    n = pix.shape[0]
    if n == 0:
        return 0
    if outcome is None and depth is not None and order_free_depth(p):
        # Applied one by one, each fragment replaces the stored depth when nearer (farther):
        # the pixel ends with the minimum (maximum) of its stored and fragment depths.
        (np.minimum if p.ztest in _NEARER_PASSES else np.maximum).at(buf.depth, pix, depth)
        return 1
    lut = None
    if ids is not None:
        pairs = palette.shape[0] * PAIR_TABLE_FRAGMENTS <= n
        key = (palette.tobytes(), pairs)
        lut = None if tables is None else tables.get(key)
        if lut is None:
            with tables.key_lock(key) if isinstance(tables, BlendTables) else contextlib.nullcontext():
                lut = None if tables is None else tables.get(key)
                if lut is None:
                    kept = (p, buf.hdr, buf.linear, key)
                    # Either form of a kept table gives the same values (pairs of channels or one).
                    lut = RECENT_TABLES.get(kept)
                    if lut is None:
                        lut = RECENT_TABLES.get((p, buf.hdr, buf.linear, (key[0], not pairs)))
                    if lut is None:
                        lut = BlendTable(blend_lut(buf, p, palette), pairs=pairs)
                        RECENT_TABLES.put(kept, lut)
                    if tables is not None:
                        tables[key] = lut

    def layer(sel) -> None:
        if sel is None:
            apply_layer(buf, p, pix, depth, rgba, ids, lut, outcome)
            return
        codes = None if outcome is None else np.empty(sel.shape[0], dtype=np.int8)
        # np.take: fancy indexing of (N, 4) rows costs several times more.
        apply_layer(buf, p, np.take(pix, sel), None if depth is None else np.take(depth, sel),
                    None if rgba is None else np.take(rgba, sel, axis=0),
                    None if ids is None else np.take(ids, sel), lut, codes)
        if codes is not None:
            outcome[sel] = codes

    if disjoint:
        layer(None)
        return 1
    lo = int(pix.min())
    local = pix - lo
    counts = np.bincount(local, minlength=int(pix.max()) - lo + 1)
    layers = int(counts.max())
    if layers == 1:
        layer(None)
        return 1
    if layers <= PEEL_LAYERS:
        # Layer k = the first remaining fragment of each pixel, found with an unbuffered minimum.
        first = np.full(counts.size, n, dtype=np.int64)
        remaining = np.arange(n, dtype=np.int64)
        while remaining.size:
            where = local[remaining]
            np.minimum.at(first, where, remaining)
            is_first = first[where] == remaining
            layer(remaining[is_first])
            first[where] = n
            remaining = remaining[~is_first]
        return layers
    order = np.argsort(local, kind="stable")
    sp = local[order]
    starts = np.ones(sp.size, dtype=bool)
    starts[1:] = sp[1:] != sp[:-1]
    rank = np.arange(sp.size) - np.maximum.accumulate(np.where(starts, np.arange(sp.size), 0))
    by_rank = order[np.argsort(rank.astype(np.int32), kind="stable")]
    bounds = np.concatenate([[0], np.cumsum(np.bincount(rank, minlength=layers))])
    for k in range(layers):
        layer(by_rank[bounds[k]:bounds[k + 1]])
    return layers
