"""Blending (docs/pipeline.md §8): the blend equations and factors, and the blend tables that
tabulate them for constant colours over 8-bit buffers.

- :func:`blend` (and :func:`blend_fragments`, over packed stored pixels): the source over the
  destination with a pass's factors and ops, channel by channel.
- :func:`blend_lut` / :class:`BlendTable`: every (colour, destination code) result of a
  :func:`lut_eligible` pass, computed by the same functions, so a lookup equals the blend bit
  for bit; :func:`table_pays` decides when a table is cheaper than blending each fragment.
- :class:`RecentTables` (:data:`RECENT_TABLES`): tables kept across renders by content;
  :class:`BlendTables`: one draw call's tables, shared by its band workers;
  :func:`find_table`: a call's table for a palette, from either, built once.
"""

from __future__ import annotations

import contextlib
import threading
from collections import OrderedDict

import numpy as np

from .. import colorspace
from ..gather import gather
from ..vocabulary import BlendFactor, BlendOp, Pass
from .buffers import FrameBuffers


def _apply_op(op: BlendOp, s: np.ndarray, fs, d: np.ndarray, fd) -> np.ndarray:
    """The blend equation of one channel, a new array (N,) float64: ``s * fs + d * fd`` for Add
    (Sub and RevSub alike), the operands in that order, the sum made in one product's array, and
    a ``One`` factor's product left out (x * 1.0 is x, bit for bit)."""
    if op is BlendOp.Min:
        return np.minimum(s, d)
    if op is BlendOp.Max:
        return np.maximum(s, d)
    if op is BlendOp.RevSub:
        s, fs, d, fd = d, fd, s, fs  # d * fd - s * fs
    combine = np.add if op is BlendOp.Add else np.subtract
    one_s = isinstance(fs, float) and fs == 1.0
    one_d = isinstance(fd, float) and fd == 1.0
    if one_s and one_d:
        return combine(s, d)
    if one_s:
        second = np.multiply(d, fd)
        return combine(s, second, out=second)
    first = np.multiply(s, fs)
    return combine(first, d if one_d else np.multiply(d, fd), out=first)


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
        src = np.minimum(np.maximum(palette, 0.0), 1.0).repeat(256, axis=0)
        codes = np.tile(np.arange(256, dtype=np.uint8), k)[:, None].repeat(4, axis=1)
        return buf.encode(blend(p, src, buf.decode(codes))).reshape(k, 256, 4)
    # The per-fragment blend itself, over packed destinations whose four bytes hold d.
    stored = np.tile(np.arange(256, dtype=np.uint32) * np.uint32(0x01010101), k)
    packed = blend_fragments(buf, p, stored, palette.repeat(256, axis=0))
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
            return self.direct.take(ids)
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
            value = table.take(index)
            if out is None:
                out = value
            else:
                out |= value
        return out


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


#: Factor pairs (source, destination) whose sum is at most 1 — ``F`` and ``1 − F`` — or with a
#: zero: ``Add`` of a source and a destination in [0, 1] weighted by them stays at or below 1.
_WITHIN_ONE = frozenset({*((f, g) for a, b in ((BlendFactor.SrcColor, BlendFactor.OneMinusSrcColor),
                                               (BlendFactor.SrcAlpha, BlendFactor.OneMinusSrcAlpha),
                                               (BlendFactor.DstColor, BlendFactor.OneMinusDstColor),
                                               (BlendFactor.DstAlpha, BlendFactor.OneMinusDstAlpha))
                            for f, g in ((a, b), (b, a)))})


def _clamps(p: Pass, c: int) -> tuple[bool, bool]:
    """Whether channel ``c``'s blend result (3 = alpha) may fall below 0 and above 1, for a source
    clamped into [0, 1] over a destination in [0, 1]: every factor lies in [0, 1], so ``Add`` is
    at least 0 and ``Sub``/``RevSub`` at most 1; ``Min``/``Max`` pick one of the two; ``Add`` stays
    at most 1 for factors ``F`` and ``1 − F`` (``fl(s·F) ≤ F``, ``fl(d·fl(1 − F)) ≤ fl(1 − F)``,
    and ``F + fl(1 − F) ≤ 1 + 2⁻⁵⁴`` rounds to at most 1), or with a ``Zero`` factor. Without
    blending the source is the result."""
    if not p.blend:
        return False, False
    src, dst, op = p.alpha_factors if c == 3 else (p.src_blend, p.dst_blend, p.blend_op)
    if op is BlendOp.Min or op is BlendOp.Max:
        return False, False
    if op is not BlendOp.Add:
        return True, False
    return False, not (src is BlendFactor.Zero or dst is BlendFactor.Zero or (src, dst) in _WITHIN_ONE)


def _blend_ldr(buf: FrameBuffers, p: Pass, stored: np.ndarray, rgba: np.ndarray) -> np.ndarray:
    """:func:`blend_fragments` of an 8-bit buffer, one channel at a time on contiguous (N,)
    arrays: the operations of :func:`blend` and :meth:`FrameBuffers.encode`, element by element."""
    codes = stored.view(np.uint8).reshape(-1, 4)
    n = stored.shape[0]
    # Channels first, clamped into a new array (the caller's colours must survive — MSAA applies
    # them to every sample) by one clip, min(max(v, 0), 1) with NaN kept as it is, and every later
    # operation on contiguous rows.
    src = np.empty((4, n), dtype=np.float64)
    np.clip(rgba.T, 0.0, 1.0, out=src)
    result = list(src)
    if p.blend:
        dst = np.empty((4, n), dtype=np.float64)
        if buf.linear:
            gather(colorspace.DECODE_LUT, codes.T[:3], out=dst[:3])  # codes < 256: in range
            np.divide(codes[:, 3], 255.0, out=dst[3])
        else:
            np.divide(codes.T, 255.0, out=dst)
        result = _blend_channels(p, result, list(dst))
    out = np.empty((n, 4), dtype=np.uint8)
    for c in range(4):
        if buf.linear and c < 3:
            out[:, c] = colorspace.quantize_encoded(result[c])
        else:  # in place: each result row is this function's own array; clamps only where needed
            out[:, c] = colorspace.unorm_codes_in_place(result[c], *_clamps(p, c), floor=False)
    return out.view(stored.dtype).reshape(-1)


def blend_fragments(buf: FrameBuffers, p: Pass, stored: np.ndarray, rgba: np.ndarray) -> np.ndarray:
    """Packed stored values (N,) of blending ``rgba`` (N, 4) float64 over the packed ``stored`` (N,)."""
    if not buf.hdr:
        return _blend_ldr(buf, p, stored, rgba)
    src = rgba
    if p.blend:
        src = blend(p, src, buf.decode(stored.view(np.float32).reshape(-1, 4)))
    return np.ascontiguousarray(buf.encode(src)).view(stored.dtype).reshape(-1)


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


def find_table(buf: FrameBuffers, p: Pass, palette: np.ndarray, fragments: int,
               tables: dict | None = None) -> BlendTable:
    """The :class:`BlendTable` of ``palette`` (K, 4) float64 under pass ``p`` for a chunk of
    ``fragments``: in pair form when the chunk holds :data:`PAIR_TABLE_FRAGMENTS` fragments per
    colour. Taken from ``tables`` (the draw call's, kept by its caller), else from
    :data:`RECENT_TABLES` in either form (both give the same values), else built and kept in
    both. With a :class:`BlendTables`, a table is built once under its own key's lock."""
    pairs = palette.shape[0] * PAIR_TABLE_FRAGMENTS <= fragments
    key = (palette.tobytes(), pairs)
    lut = None if tables is None else tables.get(key)
    if lut is not None:
        return lut
    with tables.key_lock(key) if isinstance(tables, BlendTables) else contextlib.nullcontext():
        lut = None if tables is None else tables.get(key)
        if lut is None:
            kept = (p, buf.hdr, buf.linear, key)
            lut = RECENT_TABLES.get(kept)
            if lut is None:
                lut = RECENT_TABLES.get((p, buf.hdr, buf.linear, (key[0], not pairs)))
            if lut is None:
                lut = BlendTable(blend_lut(buf, p, palette), pairs=pairs)
                RECENT_TABLES.put(kept, lut)
            if tables is not None:
                tables[key] = lut
    return lut
