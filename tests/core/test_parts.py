"""blendlib.core.parts: per-element work split into contiguous ranges, on a given executor or here."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

from blendlib.core.parts import run_parts


def test_run_parts_covers_the_range_in_pieces_in_order():
    pool = ThreadPoolExecutor(max_workers=2)
    try:
        for n, piece, threads, parts in ((100, 7, None, 1), (100, 7, pool, 2), (100, None, pool, 2),
                                         (5, 7, pool, 2), (0, 7, None, 1), (1 << 17, None, pool, 2)):
            seen = []
            run_parts(threads, parts, n, lambda lo, hi, seen=seen: seen.append((lo, hi)), piece=piece)
            seen.sort()
            assert seen[0][0] == 0 and seen[-1][1] == n
            assert all(a[1] == b[0] for a, b in zip(seen, seen[1:], strict=False))
            if piece is not None:
                assert all(hi - lo <= piece for lo, hi in seen) and len(seen) == max(1, -(-n // piece))
            elif n >= 1 << 16:
                assert len(seen) == parts  # no piece: the parts alone
            else:
                assert seen == [(0, n)]
    finally:
        pool.shutdown()
