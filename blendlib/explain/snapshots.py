"""A capture's buffer snapshots, kept as row ranges shared between snapshots (docs/framedebugger.md).

A snapshot is the colour, depth and stencil buffers after a draw call (:class:`.framedebug.FrameCapture`
steps from the nearest one). Between two snapshots the draw calls usually reach only some rows
of the frame, so a snapshot copies only the rows that fragments reached since the one before
and shares the other rows' copies with it: memory and copying go with what changed, not with
the frame's size times the snapshots. Rows are taken band by band as the render draws them
(:meth:`.records.FrameObserver.snapshot_rows`), so no draw boundary has to be waited for.

:meth:`RowSnapshots.buffers` puts a snapshot's rows back together into whole
:class:`.merger.FrameBuffers` (what a render resumes from), bit for bit as they were.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..core.merger import FrameBuffers


@dataclass(frozen=True)
class _Rows:
    """Copies of rows ``y0 .. y0 + count - 1`` of every buffer (:meth:`.merger.FrameBuffers.by_row`,
    each (planes, count, W, ...); depth as int32: 24-bit codes)."""

    y0: int
    arrays: dict[str, np.ndarray]

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.arrays.values())


class RowSnapshots:
    """Snapshots by draw-call index, for buffers of ``height`` rows.

    ``touched(pix)`` (every merged chunk's pixels) marks rows changed since their last
    snapshot; ``take(index, previous, buffers, y0, y1)`` records rows ``[y0, y1)`` of snapshot
    ``index``: the marked ones copied, the others shared with snapshot ``previous`` (None: the
    first, every row copied). Screen-band workers call both for their own rows (disjoint),
    each band's snapshots in ascending order.
    """

    def __init__(self, height: int) -> None:
        self.height = int(height)
        self._lock = threading.Lock()
        self._dirty = np.ones(self.height, dtype=bool)  # (H,) rows changed since their last snapshot
        self._rows: dict[int, np.ndarray] = {}  # index → (H,) int32: the piece holding each row
        self._pieces: list[_Rows] = []
        self._kind: tuple | None = None  # the captured buffers' FrameBuffers.kind

    def touched(self, pix: np.ndarray, width: int) -> None:
        """Fragments were merged at pixels ``pix`` (N,) int64 (one band's chunk): mark their rows."""
        if pix.size:
            self._dirty[int(pix.min()) // width:int(pix.max()) // width + 1] = True

    def take(self, index: int, previous: int | None, buffers: FrameBuffers, y0: int, y1: int) -> None:
        """Rows ``[y0, y1)`` of snapshot ``index`` from ``buffers`` (see the class)."""
        with self._lock:
            if self._kind is None:
                self._kind = buffers.kind
            rows = self._rows.get(index)
            if rows is None:
                rows = self._rows[index] = np.full(self.height, -1, dtype=np.int32)
        if previous is None:
            self._dirty[y0:y1] = True
        else:
            rows[y0:y1] = self._rows[previous][y0:y1]
        changed = y0 + np.flatnonzero(self._dirty[y0:y1])
        if not changed.size:
            return
        a, b = int(changed[0]), int(changed[-1]) + 1  # one copy of the changed rows' range
        piece = _Rows(a, {name: view[:, a:b].astype(np.int32 if name == "depth" else view.dtype)
                          for name, view in buffers.by_row().items()})
        with self._lock:
            self._pieces.append(piece)
            number = len(self._pieces) - 1
        rows[a:b] = number
        self._dirty[a:b] = False

    def __iter__(self) -> Iterator[int]:
        return iter(sorted(self._rows))

    def __len__(self) -> int:
        return len(self._rows)

    def __contains__(self, index) -> bool:
        return index in self._rows

    @property
    def nbytes(self) -> int:
        """Bytes held by the copied rows (each shared copy counted once)."""
        return sum(p.nbytes for p in self._pieces)

    def buffers(self, index: int) -> FrameBuffers:
        """Snapshot ``index`` as whole buffers (new arrays: the snapshot stays as it is)."""
        out = FrameBuffers.unset(self._kind)
        into = out.by_row()
        rows = self._rows[index]
        bounds = np.flatnonzero(np.diff(rows)) + 1
        for a, b in zip([0, *bounds.tolist()], [*bounds.tolist(), self.height], strict=True):
            piece = self._pieces[int(rows[a])]
            for name, kept in piece.arrays.items():
                into[name][:, a:b] = kept[:, a - piece.y0:b - piece.y0]
        return out

    def __getitem__(self, index: int) -> FrameBuffers:
        return self.buffers(index)
