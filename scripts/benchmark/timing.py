"""How a call is measured: wall and CPU time, the process's resident-memory peak, traced allocations.

CPU use is the process CPU time (all threads; a render's helper process added:
:func:`process_cpu_s`) over the wall time of the same call: 2.0 means both cores busy. The
resident peak of a render: :func:`reset_peak` (``/proc/self/clear_refs`` ← 5) just before it and
``VmHWM`` after it; "peak RSS over the RSS before the render" is what it needs on top of the
Blender process and its input scene.
"""

from __future__ import annotations

import os
import statistics
import time


class Timer:
    """``with Timer() as t: ...`` then ``t.wall`` and ``t.cpu``: seconds of wall-clock and of
    process CPU time (all threads) the block took."""

    def __enter__(self):
        self.cpu0, self.t0 = time.process_time(), time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.wall = time.perf_counter() - self.t0
        self.cpu = time.process_time() - self.cpu0


def process_cpu_s(pid: int | None) -> float:
    """CPU seconds (user + system, all threads) another process has used so far, from
    ``/proc/PID/stat``; 0.0 for None or where the system cannot tell."""
    if pid is None:
        return 0.0
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()  # after the command name, which may hold spaces
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return 0.0


def median(values):
    """The median of the values that are not None, or None when there are none."""
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def proc_status() -> dict[str, int]:
    """This process's ``VmRSS`` (resident now) and ``VmHWM`` (resident peak) in bytes, those the
    system reports (none without ``/proc``)."""
    out = {}
    try:
        with open("/proc/self/status") as f:
            for line in f:
                key, _, rest = line.partition(":")
                if key in ("VmRSS", "VmHWM"):
                    out[key] = int(rest.split()[0]) * 1024
    except OSError:
        pass
    return out


def reset_peak() -> bool:
    """Reset this process's resident peak (``VmHWM``) to its resident size now; False where the
    system cannot."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def traced_peak_mb(call, *args) -> float:
    """Peak of the memory allocated during ``call(*args)`` over what was allocated before it, in
    MiB (tracemalloc: Python objects and numpy data buffers from every thread); the result is
    counted while it is alive, then dropped."""
    import tracemalloc

    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        result = call(*args)
        peak = tracemalloc.get_traced_memory()[1] - base
        del result
    finally:
        tracemalloc.stop()
    return peak / 2**20


def spread(values) -> float | None:
    """(max − min) / median of a series of timed runs; None below two runs."""
    values = [v for v in values if v is not None]
    if len(values) < 2:
        return None
    mid = median(values)
    return (max(values) - min(values)) / mid if mid > 0 else None


def spreads(res: dict) -> tuple[float | None, float | None]:
    """(the project's render spread, OpenGL's) over one case's repeats."""
    runs = res.get("runs", {})
    return (spread([r.get("render_s") for r in runs.get("project", [])]),
            spread([r.get("total_s") for r in runs.get("opengl", [])]))
