"""A run's report: the tables and targets printed, the JSON, the doc's results section, the plot.

``--write-doc DOC.md`` replaces only what lies between :data:`RESULTS_START` and
:data:`RESULTS_END` in the doc (docs/benchmark.md): the method above and the reading of the
runs below are prose, kept by hand.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from pathlib import Path

from scripts.benchmark import host
from scripts.benchmark.cases import REPO
from scripts.benchmark.plot import write_plot
from scripts.benchmark.tables import (
    EXPLAIN_COLUMNS,
    VIEWPORT_COLUMNS,
    explain_rows,
    fmt_t,
    format_table,
    viewport_rows,
)
from scripts.benchmark.targets import scaling_summary, targets

RESULTS_START, RESULTS_END = "<!-- results:start -->", "<!-- results:end -->"


def report(args, results: list[dict], env: dict, log_path: Path | None) -> int:
    """Print the tables and targets of a run; write the JSON, the doc's results and the plot as
    ``args`` asks. Exit status 1 when the project's backend failed on a scene."""
    args.quick, args.repeats = env["quick"], env["repeats"]
    elapsed = env["elapsed_s"]
    print()
    print(f"Unity Passes benchmark — {env['processor']}, {env['cpus']} CPUs, numpy {env['numpy']}, "
          f"{args.repeats} runs each (median){', QUICK sizes' if args.quick else ''}")
    if env["loadavg"]:
        print(f"load average (1, 5, 15 min): {host.format_load(env['loadavg'][0])} at the start, "
              f"{host.format_load(env['loadavg'][1])} at the end")
    if env.get("steal_pct") is not None:
        print(f"CPU time the virtual machine's host took (steal) during the run: {env['steal_pct']:.1f} %")
    if env.get("speed_probe_ms"):
        print(f"host speed probe: {host.format_probes(env['speed_probe_ms'])}")
    print("times in seconds; 'project s' = extract + render; proj/GL = render / OpenGL (draw + readback); "
          "proj/EEVEE = project / EEVEE;")
    print("peak MB = peak memory allocated during render_scene (tracemalloc: numpy buffers + Python objects, "
          "untimed run); CPU = process CPU time / wall of render_scene (2.0 = both cores)")
    print()
    print(format_table(results))
    print()
    print("Not in the medians (first runs include shader compilation; OpenGL context creation "
          f"{fmt_t(next((r['setup']['opengl']['context_s'] for r in results if 'opengl' in r['setup']), None))} s):")
    print("\n".join(_setup_lines(results)))
    sc = scaling_summary(results)
    if sc:
        print()
        print("Scaling (log-log slope of median time; 1.0 = linear): "
              + ", ".join(f"{k} {v:.2f}" for k, v in sc.items()))
    if explain_rows(results):
        print()
        print("Frame debugger and sorted reference: times as ratios to a plain render of the "
              "same DrawScene, alternating runs, medians; MB = tracemalloc peak of one untimed call")
        print(format_table(results, columns=EXPLAIN_COLUMNS, rows_of=explain_rows))
    if viewport_rows(results):
        print()
        print("Viewport, through the scene camera's matrices; medians in ms; change->first = "
              "extraction + reduced frame; sched. = through ViewportScheduler, from the start of the extraction")
        print(format_table(results, columns=VIEWPORT_COLUMNS, rows_of=viewport_rows))
    tg = targets(results)
    if tg:
        print()
        print("Targets" + (" (QUICK sizes: not the real targets)" if args.quick else "") + ":")
        for t in tg:
            print(f"  [{'ok' if t.met else 'MISS'}] {t.measure} {t.limit}: {t.figure}")
    _print_profiles(results)
    if args.markdown:
        print()
        print(results_markdown(results, env, sc, tg, None))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps({"env": env, "results": results, "scaling": sc,
                                               "targets": [dataclasses.asdict(t) for t in tg]},
                                              indent=1, default=str))
        print(f"\nJSON: {args.json}")
    if args.write_doc:
        write_doc(Path(args.write_doc), results, env, sc, tg, args.plot)
        print(f"results written into {args.write_doc}")
    if args.plot:
        p = write_plot(results, Path(args.plot), f"Unity Passes benchmark, {env['cpus']} CPUs"
                       + (" (quick sizes)" if args.quick else ""))
        print(f"plot: {p}")
    print(f"\n({elapsed:.0f} s in all" + (f"; worker log {log_path})" if log_path else ")"))
    failed = any(k.startswith("project") for r in results for k in r["errors"])
    return 1 if failed else 0


def _setup_lines(results: list[dict]) -> list[str]:
    """Per scene, what the medians leave out: OpenGL's upload and first draw, every backend's first
    run, the errors."""
    lines = []
    for r in results:
        s = r["setup"]
        parts = []
        if "opengl" in s:
            gl = s["opengl"]
            parts.append(f"OpenGL upload {fmt_t(gl['upload_s'])} s, first draw {fmt_t(gl['first_s'])} s")
        for k in ("eevee", "workbench", "project"):
            if k in s:
                parts.append(f"{k} first run {fmt_t(s[k]['first_s'])} s")
        if r["errors"]:
            parts.append("errors: " + "; ".join(f"{k}: {v}" for k, v in r["errors"].items()))
        lines.append(f"  {r['case']['id']}: " + ", ".join(parts))
    return lines


def _print_profiles(results: list[dict]) -> None:
    """The ``--profile`` tables: each profiled scene's top functions by own time."""
    for r in results:
        prof = r.get("profile")
        if not prof:
            continue
        print()
        print(f"Profile of {r['case']['id']} (one extraction + render, workers=1, cProfile "
              f"{prof['total_s']:.2f} s): top functions by own time")
        print(f"  {'own s':>7} {'share':>6} {'cum s':>7} {'calls':>7}  function")
        for row in prof["top"]:
            print(f"  {row['tottime']:7.3f} {row['tottime'] / prof['total_s']:6.1%} {row['cumtime']:7.3f} "
                  f"{row['calls']:7d}  {row['function']}")


def results_markdown(results, env, sc, tg, plot) -> str:
    """The doc's results section: the run's command, machine and host figures, every table, the
    targets, the scaling slopes and the plot."""
    load = env.get("loadavg")
    lines = [
        f"Command: `{env['command']}`  ",
        f"Machine: {env['processor']}, {env['cpus']} CPUs; Python {env['python']}, numpy {env['numpy']}; "
        f"{env['repeats']} timed runs per backend, medians; {time.strftime('%Y-%m-%d')}; "
        f"{env['elapsed_s'] / 60:.0f} min in all."
        + (f"  \nLoad average (1, 5, 15 min) at the start {host.format_load(load[0])}, at the end "
           f"{host.format_load(load[1])} on {env['cpus']} CPUs: the machine was shared, absolute times are noisy; "
           "ratios come from alternating runs." if load else "")
        + (f" The host took {env['steal_pct']:.1f} % of the CPU time during the run (steal)."
           if env.get("steal_pct") is not None else "")
        + (f" Host speed probe: {host.format_probes(env['speed_probe_ms'])}." if env.get("speed_probe_ms") else ""),
        "",
        format_table(results, markdown=True),
        "",
    ]
    if explain_rows(results):
        lines += ["Frame debugger and sorted reference: each time as a ratio to a plain "
                  "`render_scene` of the same DrawScene, alternating runs, medians; MB = tracemalloc peak of one "
                  "untimed call.", "",
                  format_table(results, markdown=True, columns=EXPLAIN_COLUMNS, rows_of=explain_rows), ""]
    if viewport_rows(results):
        lines += ["Viewport, through the scene camera's view and projection matrices; medians in ms.",
                  "", format_table(results, markdown=True, columns=VIEWPORT_COLUMNS, rows_of=viewport_rows), ""]
    if tg:
        lines += ["| target | limit | figure | met |", "|---|---|---|---|"]
        lines += [f"| {t.measure} | {t.limit} | {t.figure} | {'yes' if t.met else '**no**'} |" for t in tg]
        lines.append("")
    if sc:
        lines.append("Log-log slope of the median time (1.0 = linear): "
                     + ", ".join(f"{k} {v:.2f}" for k, v in sc.items()) + ".")
        lines.append("")
    if plot:
        lines += [f"![benchmark plot]({os.path.relpath(Path(plot).resolve(), REPO / 'docs')})", ""]
    return "\n".join(lines)


def write_doc(doc: Path, results, env, sc, tg, plot) -> None:
    """Replace the results section of ``doc`` (created, or the markers appended, when missing)."""
    text = doc.read_text() if doc.exists() else f"# Benchmark\n\n{RESULTS_START}\n{RESULTS_END}\n"
    if RESULTS_START not in text or RESULTS_END not in text:
        text = text.rstrip("\n") + f"\n\n{RESULTS_START}\n{RESULTS_END}\n"
    head, rest = text.split(RESULTS_START, 1)
    _, tail = rest.split(RESULTS_END, 1)
    body = results_markdown(results, env, sc, tg, plot)
    doc.write_text(f"{head}{RESULTS_START}\n{body}\n{RESULTS_END}{tail}")
