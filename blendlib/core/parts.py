"""Per-element work split into contiguous ranges: cache-sized pieces, on an executor the caller gives.

The stages that work per vertex, per triangle or per buffer row (:mod:`.vertex`, :mod:`.raster`,
:meth:`.merger.FrameBuffers.output`) split their element range with :func:`run_parts`. It lives
in the core, beside the stages, rather than with the process and thread machinery of
:mod:`blendlib.runtime`, because it owns no threads: it is handed an executor (the render's
thread pool, or None) and only decides the ranges, which are a property of the arithmetic
(each range writes its own slice of preallocated outputs, so the result never depends on the
split). Who creates and ends threads is the driver's business (:func:`.pipeline.render_scene`).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor

import numpy as np

#: Elements (vertices, triangles) per piece of the per-element stages. A piece's arrays (64k
#: int64 or float64: 512 KB each) stay in a core's 1 MB L2 cache through the dozens of array
#: operations a stage makes over them; a million triangles at once stream every operation
#: through memory, which two cores share (docs/benchmark.md, "Why the constants are what they are").
PIECE = 1 << 16


def run_parts(pool: Executor | None, parts: int, n: int, fn: Callable[[int, int], None], min_part: int = 1 << 15,
              piece: int | None = None) -> None:
    """Call ``fn(lo, hi)`` over ``[0, n)`` in contiguous ranges, on ``pool`` when given.

    Up to ``parts`` ranges on the pool (none below ``2 * min_part`` elements), and with
    ``piece`` at least as many as keep each range within ``piece`` elements (equal sizes; the
    pool's threads take them in order, without a pool they run one after another here).
    ``fn`` must only write its own slice of preallocated outputs. Returns when every range
    is done; an exception of ``fn`` is raised here.
    """
    count = 1 if pool is None or parts <= 1 or n < 2 * min_part else parts
    if piece is not None:
        count = max(count, -(-n // piece))
    if count <= 1:
        fn(0, n)
        return
    bounds = np.linspace(0, n, count + 1).astype(np.int64)
    ranges = [(int(lo), int(hi)) for lo, hi in zip(bounds[:-1], bounds[1:], strict=True) if hi > lo]
    if pool is None or parts <= 1:
        for lo, hi in ranges:
            fn(lo, hi)
        return
    futures = [pool.submit(fn, lo, hi) for lo, hi in ranges]
    for f in futures:
        f.result()
