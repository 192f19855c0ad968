"""Gathers by index arrays that are in range by construction.

numpy's ``take`` checks every index in its default mode ("raise") and, given ``out``, first
gathers into a buffer and then copies it over; its "wrap" mode gives the same values for every
index the default accepts (negative ones count from the end alike) without either cost. The
pipeline's own index arrays (run and row indices, layer selections, pixels within the buffers)
are built from the extents of the arrays they index, so they take :func:`gather`; so do texel
indices (wrapped into the texture) and a scene's triangles, which the scene's validation checks.

``take`` of a non-contiguous source copies the whole source to contiguous memory first: a few
elements of a strided column of a large array are read by indexing (``column[index]``) instead.
"""

from __future__ import annotations

import numpy as np


def gather(values: np.ndarray, index: np.ndarray, axis: int | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """``np.take(values, index, axis, out)`` for an array ``values`` and ``index`` (integer array)
    whose entries all lie in ``-n..n-1`` of ``values``' extent along ``axis`` (the flattened array
    for None)."""
    # The method, not np.take: the function's Python wrapper costs about 2 µs a call, as much as
    # the gather itself on the small arrays of a viewport frame (hundreds of calls each).
    return values.take(index, axis=axis, out=out, mode="wrap")


def scatter_rows(dest: np.ndarray, index: np.ndarray, rows: np.ndarray) -> None:
    """``dest[index] = rows`` for a C-contiguous (N, C) ``dest``, ``index`` (M,) distinct and in
    range, ``rows`` (M, C) of ``dest``'s dtype — or one row (1, C), put at every index: each row
    moved whole (as one C-item value), where numpy's fancy assignment of rows (or of a scalar to
    rows, about 4x slower) sets them element by element."""
    row = np.dtype((np.void, dest.shape[1] * dest.itemsize))
    values = np.ascontiguousarray(rows, dtype=dest.dtype).view(row).reshape(-1)
    np.put(dest.view(row).reshape(-1), index, values, mode="wrap")  # put repeats a shorter values
