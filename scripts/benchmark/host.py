"""The machine during a run: load average, the CPU time the host took (steal), a speed probe.

On a shared machine absolute times are noisy, ratios from alternating runs less so; these
figures, printed with every run and written into the doc, show how busy or slow the host was.
"""

from __future__ import annotations

import os
import platform
import time


def cpu_ticks() -> list[int] | None:
    """All CPUs' time counters of /proc/stat (user, nice, system, idle, iowait, irq, softirq,
    steal, ...), or None where there is no such file."""
    try:
        with open("/proc/stat") as f:
            return [int(v) for v in f.readline().split()[1:]]
    except (OSError, ValueError):
        return None


def steal_pct(start: list[int] | None, end: list[int] | None) -> float | None:
    """Percent of the CPU time between two :func:`cpu_ticks` that a hypervisor gave to others."""
    if not start or not end or len(start) < 8 or len(end) < 8:
        return None
    total = sum(end[:8]) - sum(start[:8])
    return 100.0 * (end[7] - start[7]) / total if total > 0 else None


def speed_probe_ms(samples: int = 5) -> float:
    """Milliseconds of a fixed single-thread workload like the renderer's, the median of
    ``samples``: an interpreter loop, numpy operations on 100k-element arrays (in cache) and
    two passes over 32 MB arrays (memory bandwidth). Steal and load average miss the slow
    phases of a shared host (docs/benchmark.md, "The host"); this probe shows much of them."""
    import numpy as np

    values = np.arange(100_000, dtype=np.float64)
    big = np.arange(4_000_000, dtype=np.float64)
    scratch = np.empty_like(big)
    scratch.fill(0.0)  # pages touched before the timing
    times = []
    for _ in range(samples):
        start = time.perf_counter()
        total = 0
        for i in range(40_000):
            total += i & 7
        for _ in range(4):
            np.sort(np.sqrt(values * 1.5 + total))
        for _ in range(2):
            np.multiply(big, 1.5, out=scratch)
            np.add(scratch, big, out=scratch)
        times.append(time.perf_counter() - start)
    return float(np.median(times) * 1e3)


def format_probes(probes: list[float]) -> str:
    """'12.3 ms median, 11.9–14.0 ms over 6 samples (start and between scenes; lower is faster)'."""
    import numpy as np

    return (f"{np.median(probes):.1f} ms median, {min(probes):.1f}–{max(probes):.1f} ms over {len(probes)} "
            "samples (start and between scenes; lower is faster)")


def loadavg() -> list[float] | None:
    """The 1, 5 and 15 minute load averages, or None where the system has none."""
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except OSError:
        return None


def format_load(load) -> str:
    return ", ".join(f"{v:.1f}" for v in load) if load else "-"


def cpu_name() -> str:
    """The CPU's model name (/proc/cpuinfo), or what the platform says."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"
