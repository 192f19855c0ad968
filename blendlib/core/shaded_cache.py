"""Shaded chunks kept across renders of variants of one scene that draw the same calls in
another order (the advice's candidate fixes, :mod:`blendlib.explain.advice`).

A chunk's shaded fragments (:func:`.fragment.shade_chunk`) are a pure function of its draw
call (mesh, material, pass, light, camera), its rows and the derived state it is shaded with —
and of the stored depth when it is shaded, which an early depth test and the rows' depth floors
read (:class:`.records.DrawState`). The stored depth and stencil at a call are those the render
started from, changed by the calls drawn before it that write depth or stencil, one after the
other. So a chunk is keyed by

- the caller's key of its call (equal keys: the same draw — the advice's draw-list signature),
- the keys of the calls before it in the render that write depth or stencil, in order,
- the buffers the render started from (resumed, by identity, kept alive here),
- the screen band drawn (buffer rows; a band render's own rows are within it) and the chunk's
  rows within it,
- the derived state's own choices (observed, early depth test, hierarchical-Z bound, unlit
  fragments dropped, colours read).

A state that reads the stored colour while it shades (:attr:`.records.DrawState.dark_alpha`)
or colours read through a mask is not kept, nor are MSAA chunks. Chunks are kept up to a byte
budget counted per fragment (their arrays and what their deferred depth and triangles hold);
past it, nothing more is kept. Renders reading the cache take the same fragments they would
shade, so frames and observations are bit for bit those without it.
"""

from __future__ import annotations

import threading

from .records import DrawState, ShadedFragments

#: Bytes the kept chunks may hold, counted at :data:`BYTES_PER_FRAGMENT` a fragment.
SHADED_CACHE_BYTES = 96 << 20
#: What one kept fragment holds at most: pixel, depth, colour, id, alive, its barycentrics and
#: source row kept for the deferred depth and triangles (bytes).
BYTES_PER_FRAGMENT = 96

_EMPTY = object()  # a chunk that shaded no fragment


class ShadedCache:
    """Shaded chunks by key (module doc), up to ``max_bytes``; shared by the renders given it,
    one or several threads at a time (a band's keys are its own)."""

    def __init__(self, max_bytes: int = SHADED_CACHE_BYTES) -> None:
        self.max_bytes = int(max_bytes)
        self.nbytes = 0
        self.hits = 0
        self.misses = 0
        self._chunks: dict[tuple, object] = {}
        self._held: dict[int, object] = {}  # buffers renders resumed from, kept so their ids stay theirs
        self._numbers: dict = {}  # call key → a small number: chunk keys hash numbers, not passes
        self._lock = threading.Lock()

    def number(self, key) -> int:
        """A number for a call's key, the same for equal keys."""
        with self._lock:
            return self._numbers.setdefault(key, len(self._numbers))

    def origin(self, buffers) -> int | None:
        """The key of the buffers a render starts from (None: cleared ones), kept alive here."""
        if buffers is None:
            return None
        with self._lock:
            self._held.setdefault(id(buffers), buffers)
        return id(buffers)

    def get(self, key: tuple) -> tuple[bool, ShadedFragments | None]:
        """(found, the chunk's fragments or None when it shaded none)."""
        hit = self._chunks.get(key)
        if hit is None:
            self.misses += 1
            return False, None
        self.hits += 1
        return True, None if hit is _EMPTY else hit

    def put(self, key: tuple, shaded: ShadedFragments | None) -> None:
        size = 0 if shaded is None else shaded.count * BYTES_PER_FRAGMENT
        with self._lock:
            if key in self._chunks or self.nbytes + size > self.max_bytes:
                return
            self._chunks[key] = _EMPTY if shaded is None else shaded
            self.nbytes += size


def call_slots(cache: ShadedCache, calls, keys, writes, resumed=None) -> dict[int, tuple]:
    """Per draw call index of ``calls`` (in draw order), its chunks' key prefix in ``cache``:
    (its key, the keys of the calls before it that write depth or stencil, in order; each key
    by its :meth:`ShadedCache.number`; the :meth:`ShadedCache.origin` of ``resumed``, the
    buffers the render starts from, None: cleared ones). ``keys``: call index → key (a call
    missing has none: neither it nor, when it writes depth or stencil, any call after it is
    kept); ``writes(call)``: whether it writes depth or stencil."""
    origin = cache.origin(resumed)
    slots: dict[int, tuple] = {}
    history: tuple = ()
    for call in calls:
        key = keys.get(call.index)
        number = None if key is None else cache.number(key)
        if number is not None:
            slots[call.index] = (number, history, origin)
        if writes(call):
            if number is None:
                break
            history = (*history, number)
    return slots


def state_key(state: DrawState) -> tuple | None:
    """What of a derived state a chunk's key holds beyond its call (module doc); None: not kept."""
    if state.dark_alpha is not None or state.samples != 1 or not isinstance(state.colors_read, bool):
        return None
    return (state.observed, state.early_depth is not None, state.zbound is not None, state.dark_skip,
            state.colors_read)


__all__ = ["SHADED_CACHE_BYTES", "ShadedCache", "call_slots", "state_key"]
