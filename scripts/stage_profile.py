"""Where a render's time goes: the share of each pipeline stage in a one-thread render.

    .venv/bin/python -m scripts.stage_profile --scenes S1,S2,S4 [--quick] [--markdown]

Builds the benchmark's scenes (``scripts.benchmark.scenes``), extracts each DrawScene once, renders it
once untimed and once under cProfile with ``workers=1`` (cProfile sees one thread only), and
maps the cumulative time of the pipeline's stage functions to stages:

- setup: ``vertex.setup_renderers`` (transform, clipping, snapping, areas; one renderer or a batch)
- coverage: ``raster.coverage_rows`` / ``coverage_rows_many`` / ``rasterize_rows`` / ``row_chunks`` /
  ``split_bands``
- interpolation: ``raster.interpolate`` / ``interpolate_runs`` (depth, weights, attributes)
- shading: ``shade.shade`` (texture sampling, lighting), ``mips.quad_lod`` and
  ``mips.sample_mipmapped`` (a mipmapped texture's LOD and trilinear sampling), ``shade.texel_palette``
  and ``shade.point_texel_index_of`` (Point-filtered textures shaded once per texel, fragments given
  their texel)
- ordering: ``merger.merge`` minus the layers it applies and the tables it builds (counting
  fragments per pixel, peeling layers; ``merger/ordering.py``)
- merge: ``merger.apply_layer`` and blend-table building (tests, blending, writes;
  ``merger/ordering.py``, ``merger/blending.py``)
- output: ``FrameBuffers`` creation and ``output`` (clear, conversion to the Frame's float32;
  ``merger/buffers.py``)
- other: the rest (draw list, per-chunk bookkeeping in ``pipeline``, Python overhead)

With ``--analysis`` it profiles the sorted reference instead (``workers=1``): ``analyze`` without
advice split into its phases — the observed render that keeps the transparent fragments
(``render``), step 2's sort and replay of the kept fragments (``step 2``: ``_Blocks.run``, its
blocks on their threads), the sorted reference and the sort error (``reference``) and the rest —
and the advice on top of it (``advise``, five pairs: the re-rendered fixes and the rest), each as a
multiple of a plain one-thread render.

cProfile adds a per-call cost, so shares of call-heavy stages read a little high. Run it from
the repository root; it is not a test.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
from pathlib import Path

STAGES = {
    "setup": [("vertex.py", "setup_renderers")],
    "coverage": [("raster.py", "coverage_rows"), ("raster.py", "coverage_rows_many"), ("raster.py", "rasterize_rows"),
                 ("raster.py", "row_chunks"), ("raster.py", "split_bands")],
    "interpolation": [("raster.py", "interpolate"), ("raster.py", "interpolate_runs")],
    "shading": [("shade.py", "shade"), ("shade.py", "texel_palette"), ("shade.py", "point_texel_index_of"),
                ("mips.py", "quad_lod"), ("mips.py", "sample_mipmapped")],
    "merge": [("ordering.py", "apply_layer")],
    "tables": [("blending.py", "blend_lut"), ("blending.py", "__init__")],
    "output": [("buffers.py", "output"), ("buffers.py", "__init__")],
}
ORDER = ("setup", "coverage", "interpolation", "shading", "ordering", "merge", "output", "other")


def stage_shares(stats: pstats.Stats) -> tuple[float, dict[str, float]]:
    """(total render seconds, seconds per stage) from the stats of one ``render_scene`` call."""
    cum = _cumulative(stats)
    total = max((ct for (_file, func), ct in cum.items() if func == "render_scene"), default=0.0)
    seconds = {stage: sum(cum.get(k, 0.0) for k in keys) for stage, keys in STAGES.items()}
    merge_total = cum.get(("ordering.py", "merge"), 0.0)
    seconds["ordering"] = max(merge_total - seconds["merge"] - seconds["tables"], 0.0)
    seconds["merge"] += seconds.pop("tables")
    seconds["other"] = max(total - sum(seconds.values()), 0.0)
    return total, {k: seconds[k] for k in ORDER}


def profile_draw(draw) -> tuple[float, dict[str, float]]:
    from blendlib.core import merger
    from blendlib.core.pipeline import render_scene

    render_scene(draw, workers=1)
    merger.RECENT_TABLES.clear()  # a render from scratch, as the benchmark's scene table times it
    prof = cProfile.Profile()
    prof.enable()
    render_scene(draw, workers=1)
    prof.disable()
    return stage_shares(pstats.Stats(prof))


ANALYSIS_PHASES = {
    "render": [("pipeline.py", "render_scene")],
    "step 2": [("sorted_reference.py", "run")],
    "reference": [("sorted_reference.py", "reference_from_codes"), ("sorted_reference.py", "sort_error")],
}


def profile_analysis(draw) -> dict[str, float]:
    """Seconds of a one-thread plain render, of ``analyze`` (no advice) by phase and of ``advise``
    (five pairs) split into its re-renders and the rest (module doc)."""
    import time

    from blendlib.core.pipeline import render_scene
    from blendlib.explain.advice import advise
    from blendlib.explain.sorted_reference import analyze

    render_scene(draw, workers=1)
    start = time.perf_counter()
    render_scene(draw, workers=1)
    out = {"plain": time.perf_counter() - start}
    analyze(draw, workers=1)
    prof = cProfile.Profile()
    prof.enable()
    analysis = analyze(draw, workers=1, keep_step1=True)
    prof.disable()
    cum = _cumulative(pstats.Stats(prof))
    out["analyze"] = cum.get(("sorted_reference.py", "analyze"), 0.0)
    for phase, keys in ANALYSIS_PHASES.items():
        out[phase] = sum(cum.get(k, 0.0) for k in keys)
    out["analyze other"] = max(out["analyze"] - sum(out[p] for p in ANALYSIS_PHASES), 0.0)
    prof = cProfile.Profile()
    prof.enable()
    advise(draw, analysis, 5, workers=1)
    prof.disable()
    cum = _cumulative(pstats.Stats(prof))
    out["advise"] = cum.get(("advice.py", "advise"), 0.0)
    out["advise renders"] = cum.get(("pipeline.py", "render_scene"), 0.0)
    out["advise other"] = max(out["advise"] - out["advise renders"], 0.0)
    return out


def _cumulative(stats: pstats.Stats) -> dict[tuple[str, str], float]:
    """Cumulative seconds per (file name, function) of profile ``stats`` (pstats counts a
    recursive function's time once)."""
    cum: dict[tuple[str, str], float] = {}
    for (file, _line, func), (_cc, _nc, _tt, ct, _callers) in stats.stats.items():
        key = (Path(file).name, func)
        cum[key] = cum.get(key, 0.0) + ct
    return cum


ANALYSIS_COLUMNS = ("analyze", "render", "step 2", "reference", "analyze other", "advise", "advise renders",
                    "advise other")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m scripts.stage_profile", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="S1,S2,S4", help="benchmark scene ids (default S1,S2,S4)")
    ap.add_argument("--quick", action="store_true", help="the benchmark's small sizes")
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    ap.add_argument("--analysis", action="store_true",
                    help="profile analyze and its advice instead of a render (multiples of a plain render)")
    args = ap.parse_args(argv)
    from blendlib import blender
    from scripts.benchmark.cases import plan_cases
    from scripts.benchmark.scenes import build_case

    rows = []
    for case in plan_cases(args.scenes, quick=args.quick, explain=False):
        if case["group"].startswith("scale-"):  # the scaling series is S1's sphere again
            continue
        draw = blender.build_draw_scene(build_case(case))
        if args.analysis:
            times = profile_analysis(draw)
            rows.append((case["id"], times))
            print(f"{case['id']:>16} plain {times['plain']:.3f} s  "
                  + "  ".join(f"{k} {times[k] / times['plain']:.2f}x" for k in ANALYSIS_COLUMNS), flush=True)
            continue
        total, seconds = profile_draw(draw)
        rows.append((case["id"], total, seconds))
        print(f"{case['id']:>16} {total:7.3f} s  " + "  ".join(f"{k} {v / total:4.0%}" for k, v in seconds.items()),
              flush=True)
    if args.markdown and args.analysis:
        print()
        print("| scene | plain s | " + " | ".join(ANALYSIS_COLUMNS) + " |")
        print("|---|---|" + "---|" * len(ANALYSIS_COLUMNS))
        for name, times in rows:
            print(f"| {name} | {times['plain']:.3f} | "
                  + " | ".join(f"{times[k] / times['plain']:.2f}x" for k in ANALYSIS_COLUMNS) + " |")
    elif args.markdown:
        print()
        print("| scene | one-thread s | " + " | ".join(ORDER) + " |")
        print("|---|---|" + "---|" * len(ORDER))
        for name, total, seconds in rows:
            print(f"| {name} | {total:.2f} | " + " | ".join(f"{seconds[k] / total:.0%}" for k in ORDER) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
