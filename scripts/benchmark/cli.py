"""The command line and the run: workers started, every case run through them, the report.

    .venv/bin/python -m scripts.benchmark [--quick] [--scenes ...] [--backends ...] [--plot ...] [--write-doc ...]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import scripts.benchmark
from scripts.benchmark import host
from scripts.benchmark.cases import BACKENDS, BLEND_DIR, SCENE_GROUPS, plan_cases
from scripts.benchmark.report import report
from scripts.benchmark.timing import median
from scripts.benchmark.workers import WorkerProcess, serve

DESCRIPTION = scripts.benchmark.__doc__.split("\n\n")[0]


def run_case(case: dict, workers: dict[str, WorkerProcess], repeats: int, say, profile: int = 0) -> dict:
    """One case through every worker: setup (the scene and an untimed first run), ``repeats``
    alternating timed runs, the project's profile, frame-debugger and viewport series as the case
    asks; the medians and the ratios to OpenGL and EEVEE. ``say`` prints progress."""
    res = {"case": case, "setup": {}, "runs": {k: [] for k in workers}, "errors": {}}
    active = []
    for kind, w in workers.items():
        t = time.perf_counter()
        r = w.call("setup", case=case)
        if r.pop("ok"):
            res["setup"][kind] = r
            active.append(kind)
            say(f"  {case['id']}: {kind} ready ({time.perf_counter() - t:.1f} s, first run {r['first_s']:.3f} s)")
        else:
            res["errors"][kind] = r.get("error", "?")
            say(f"  {case['id']}: {kind} FAILED: {res['errors'][kind]}")
    for _ in range(repeats):
        for kind in active:  # alternate: A, B, C, D, A, B, ...
            r = workers[kind].call("run")
            if r.pop("ok"):
                res["runs"][kind].append(r)
            else:
                res["errors"][kind] = r.get("error", "?")
    if profile and "project" in active:
        r = workers["project"].call("profile", top=profile)
        if r.pop("ok"):
            res["profile"] = r
    if "project" in active and case.get("explain"):
        say(f"  {case['id']}: frame debugger and sorted reference against a plain render")
        r = workers["project"].call("explain", repeats=repeats)
        if r.pop("ok"):
            res["explain"] = r["explain"]
        else:
            res["errors"]["project explain"] = r.get("error", "?")
    if "project" in active and case.get("viewport"):
        vw, vh = case["viewport"]
        say(f"  {case['id']}: viewport frames at {vw}x{vh}")
        r = workers["project"].call("viewport", width=vw, height=vh, repeats=max(5, 3 * repeats))
        if r.pop("ok"):
            res["viewport"] = r["viewport"]
        else:
            res["errors"]["project viewport"] = r.get("error", "?")
    for kind in active:
        workers[kind].call("end")
    res["median"] = {}
    for kind, runs in res["runs"].items():
        if runs:
            keys = runs[0].keys()
            med = {k: median([r.get(k) for r in runs]) for k in keys}
            if "rss_mb" in keys:
                med["rss_peak_mb"] = max(r["rss_peak_mb"] for r in runs)
                med["rss_mb"] = max(r["rss_mb"] for r in runs)
                med["peak_mb"] = res["setup"]["project"].get("peak_mb", 0.0)
            res["median"][kind] = med
    p, g, e = (res["median"].get(k) for k in ("project", "opengl", "eevee"))
    res["ratio_gl"] = p["render_s"] / g["total_s"] if p and g and g["total_s"] > 0 else None
    res["ratio_gl_total"] = p["total_s"] / g["total_s"] if p and g and g["total_s"] > 0 else None
    res["ratio_eevee"] = p["total_s"] / e["total_s"] if p and e and e["total_s"] > 0 else None
    return res


def parse_args(argv=None):
    ap = argparse.ArgumentParser(prog="python -m scripts.benchmark", description=DESCRIPTION,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small sizes: a smoke run of every series")
    ap.add_argument("--scenes", default=",".join(SCENE_GROUPS),
                    help=f"comma-separated subset of {','.join(SCENE_GROUPS)} (default: all)")
    ap.add_argument("--backends", default=",".join(BACKENDS),
                    help=f"comma-separated subset of {','.join(BACKENDS)} (default: all)")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per backend and scene (default 3)")
    ap.add_argument("--json", metavar="OUT.json", help="write every run's figures as JSON")
    ap.add_argument("--plot", metavar="OUT.png", help="write the plot image (e.g. docs/benchmark.png)")
    ap.add_argument("--markdown", action="store_true", help="also print the table as Markdown")
    ap.add_argument("--write-doc", metavar="DOC.md",
                    help="replace the results section of DOC.md (between the <!-- results:start --> and "
                         "<!-- results:end --> markers) with this run's tables, e.g. docs/benchmark.md")
    ap.add_argument("--blend-dir", default=str(BLEND_DIR), help="the S3 scenes (default blend_files/)")
    ap.add_argument("--workers", type=int, default=0, help="render_scene(workers=...) (default: its own)")
    ap.add_argument("--chunk-candidates", type=int, default=0, help="render_scene(chunk_candidates=...)")
    ap.add_argument("--profile", type=int, default=0, metavar="N",
                    help="after the timed runs, cProfile one project render of S1, S2, S2p, S4 (workers=1) "
                         "and print the top N functions by own time")
    ap.add_argument("--no-explain", action="store_true",
                    help="skip the frame debugger and sorted-reference series of S1, S2, S3")
    ap.add_argument("--from-json", metavar="IN.json",
                    help="run nothing: print the tables of a run saved with --json (and write --plot, "
                         "--write-doc, --markdown from it)")
    ap.add_argument("--log", default=None, help="worker log file (default: a temporary file, path printed)")
    ap.add_argument("--worker", choices=BACKENDS, help=argparse.SUPPRESS)
    return ap.parse_args(argv)


def main(argv=None) -> int:
    """The command line: a run (or ``--from-json``, a saved one) and its report; a worker with ``--worker``."""
    args = parse_args(argv)
    if args.worker:
        return serve(args.worker)
    if args.from_json:
        data = json.loads(Path(args.from_json).read_text())
        return report(args, data["results"], data["env"], None)
    kinds = [k.strip().lower() for k in args.backends.split(",") if k.strip()]
    bad = [k for k in kinds if k not in BACKENDS]
    if bad or "project" not in kinds:
        print(f"error: --backends must include project and be a subset of {','.join(BACKENDS)}", file=sys.stderr)
        return 2
    cases = plan_cases(args.scenes, quick=args.quick, blend_dir=args.blend_dir, explain=not args.no_explain)
    if not cases:
        print("error: no scenes selected", file=sys.stderr)
        return 2
    log_path = Path(args.log) if args.log else Path(tempfile.mkstemp(prefix="benchmark-", suffix=".log")[1])
    started = time.perf_counter()
    load_start = host.loadavg()
    ticks_start = host.cpu_ticks()
    probes = [host.speed_probe_ms()]

    def say(msg):
        print(msg, file=sys.stderr, flush=True)

    say(f"worker log: {log_path}")
    with open(log_path, "a") as log:
        workers: dict[str, WorkerProcess] = {}
        try:
            for k in kinds:
                w = WorkerProcess(k, log)
                if w.ok:
                    workers[k] = w
                else:
                    say(f"backend {k} unavailable: {w.error}")
                    w.close()
            if "project" not in workers:
                say("error: the project worker did not start")
                return 1
            opts = {"workers": args.workers or None, "chunk_candidates": args.chunk_candidates or None}
            workers["project"].call("options", options=opts)
            results = []
            for case in cases:
                say(f"{case['id']}: {case['label']}, {case['width']}x{case['height']}")
                profile = args.profile if case["group"] in ("S1", "S2", "S2p", "S4") else 0
                results.append(run_case(case, workers, args.repeats, say, profile))
                probes.append(host.speed_probe_ms())  # between scenes: no worker is busy
        finally:
            addon = workers.get("project").addon if "project" in workers else False
            for w in workers.values():
                w.close()

    elapsed = time.perf_counter() - started
    import numpy as np

    env = {
        "python": platform.python_version(), "numpy": np.__version__, "cpus": os.cpu_count(),
        "machine": platform.machine(), "processor": host.cpu_name(), "repeats": args.repeats,
        "quick": bool(args.quick), "addon_registered": addon, "elapsed_s": elapsed,
        "loadavg": [load_start, host.loadavg()] if load_start else None,
        "steal_pct": host.steal_pct(ticks_start, host.cpu_ticks()),
        "speed_probe_ms": probes,
        "command": " ".join(["python", "-m", "scripts.benchmark", *(argv if argv is not None else sys.argv[1:])]),
    }
    return report(args, results, env, log_path)
