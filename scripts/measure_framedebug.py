"""Frame debugger costs (issue 11): draw list, pixel history, capture and stepping against one
plain render, on S1-like and S2-like scenes built with scripts/benchmark.py's builders.

    python scripts/measure_framedebug.py [--s1-triangles 50000] [--s1-size 960x540] [--s2-size 1920x1080]

Prints one line per measurement (median of 3 for the timings) and the peak memory of the process.
Not a test: numbers depend on the machine.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import benchmark  # noqa: E402

from blendlib.blender import build_draw_scene  # noqa: E402
from blendlib.core.pipeline import render_scene  # noqa: E402
from blendlib.explain import framedebug as fd  # noqa: E402


def timed(fn, repeats=3):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return sorted(times)[len(times) // 2]


def measure(label: str, case: dict) -> None:
    scene = benchmark.build_case(case)
    draw = build_draw_scene(scene)
    w, h = draw.camera.width, draw.camera.height
    plain = timed(lambda: render_scene(draw))
    stats = timed(lambda: fd.draw_list(draw))
    pixel = timed(lambda: fd.pixel_history(draw, w // 2, h // 2))
    cap_t = time.perf_counter()
    cap = fd.FrameCapture.capture(draw)
    cap_t = time.perf_counter() - cap_t
    n = len(cap.stats)
    step = timed(lambda: cap.frame_after(max(1, n // 2 + 1)))
    hist = fd.pixel_history(draw, w // 2, h // 2)
    print(f"{label}: {w}x{h}, {n} draws, {sum(s.triangles for s in cap.stats)} triangles drawn, "
          f"{sum(s.fragments for s in cap.stats)} fragments")
    print(f"  plain render {plain:.3f} s | draw list {stats:.3f} s ({stats / plain:.2f}x) | pixel history "
          f"{pixel:.3f} s ({pixel / plain:.2f}x, {len(hist.fragments)} fragments) | capture {cap_t:.3f} s "
          f"({cap_t / plain:.2f}x) | step to draw {n // 2 + 1} {step:.3f} s ({step / plain:.2f}x)")
    print(f"  snapshots: every {cap.interval} draws, {len(cap.snapshots)} kept, "
          f"{cap.snapshot_memory / 2**20:.0f} MB (bound {fd.SNAPSHOT_MEMORY / 2**20:.0f} MB)")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--s1-triangles", type=int, default=50_000)
    parser.add_argument("--s1-size", default="960x540")
    parser.add_argument("--s2-size", default="1920x1080")
    args = parser.parse_args()
    s1w, s1h = (int(v) for v in args.s1_size.split("x"))
    s2w, s2h = (int(v) for v in args.s2_size.split("x"))
    measure("S1-like", dict(kind="sphere", k=benchmark.sphere_k(args.s1_triangles), width=s1w, height=s1h,
                            fill=1 / 3))
    measure("S2-like", dict(kind="planes", count=50, width=s2w, height=s2h))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak memory of the process: {peak:.0f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
