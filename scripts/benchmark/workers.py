"""The backends' workers, one process each, and the JSON-lines protocol between them and the parent.

A worker is ``python -m scripts.benchmark --worker KIND`` (:func:`serve`); the parent holds a
:class:`WorkerProcess` for each. The parent writes one JSON command per line on the worker's
stdin — ``options``, ``setup`` (build the case's scene and run once, untimed), ``run`` (one timed
run), ``profile``, ``explain``, ``viewport`` (the project worker's other series), ``end``,
``quit`` — and reads one JSON answer per line, ``{"ok": true, ...figures}`` or ``{"ok": false,
"error": "..."}``, from the worker's original stdout; everything else a worker prints (Blender's
own messages) goes to its stderr, the run's log.

The renderer's process-level modules (the band renderer, the allocator setting) are imported
here only.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
import traceback
from pathlib import Path

from scripts.benchmark.cases import REPO
from scripts.benchmark.timing import Timer, median, proc_status, process_cpu_s, reset_peak, traced_peak_mb

#: Timed series of ProjectWorker.explain (medians), in their alternation order.
EXPLAIN_TIMES = ("plain_s", "drawlist_s", "pixel_s", "capture_s", "step_s", "analyze_s", "advised_s")
#: How many inversion pairs the timed ``analyze`` with advice advises (the CLI's default).
ADVICE_PAIRS = 5
#: Timed series of ProjectWorker.viewport (medians).
VIEWPORT_TIMES = ("extract_s", "reduced_s", "full_s", "reduced_view_s", "full_view_s", "full_one_process_s",
                  "first_frame_s", "render_view_s", "scheduler_first_s", "scheduler_full_s")


def _build_case(case: dict):
    """The case's Blender scene, built in this worker (bpy is imported in workers only)."""
    from scripts.benchmark.scenes import build_case

    return build_case(case)


def _turn_about_z(angle: float):
    """(4, 4) float64 rotation by ``angle`` radians about the world z axis."""
    import numpy as np

    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=np.float64)


def forward_add_prices(draw, repeats: int) -> list[dict]:
    """Each renderer's ForwardAdd draws against its ForwardBase draw, in one-thread renders
    timed draw by draw (an observer's ``draw_begin``/``draw_end``; medians over ``repeats``):
    ``[{"renderer", "base_s", "add_s" (the dearest of its ForwardAdd draws), "ratio"}]``, empty
    when the scene has no ForwardAdd draw."""
    from blendlib.core.pipeline import render_scene
    from blendlib.core.records import FrameObserver

    class DrawClock(FrameObserver):
        exact_boundaries = True  # one draw at a time, each between its own begin and end
        reads_fragments = False  # each draw as an unobserved render draws it
        per_sample = True

        def __init__(self) -> None:
            self.seconds: dict[int, float] = {}
            self.calls: dict[int, object] = {}
            self.started = 0.0

        def draw_begin(self, call, buffers) -> None:
            self.started = time.perf_counter()

        def draw_end(self, call, buffers, triangles) -> None:
            self.seconds[call.index] = time.perf_counter() - self.started
            self.calls[call.index] = call

    runs = []
    for _ in range(max(1, repeats)):
        clock = DrawClock()
        render_scene(draw, workers=1, observer=clock)
        runs.append(clock)
    calls = runs[0].calls
    if not any(c.light is not None for c in calls.values()):
        return []
    seconds = {k: median([r.seconds[k] for r in runs]) for k in calls}
    base: dict[tuple, float] = {}
    add: dict[tuple, float] = {}
    for k, c in calls.items():
        key = (c.renderer.name, c.renderer.slot)
        if c.light is None and c.state.light_mode.name == "ForwardBase":
            base[key] = base.get(key, 0.0) + seconds[k]
        elif c.light is not None:
            add[key] = max(add.get(key, 0.0), seconds[k])
    return [{"renderer": f"{name}[{slot}]", "base_s": base[(name, slot)], "add_s": add[(name, slot)],
             "ratio": add[(name, slot)] / base[(name, slot)] if base[(name, slot)] > 0 else None}
            for name, slot in sorted(add) if (name, slot) in base]


class ProjectWorker:
    """The project: extraction (``build_draw_scene``) and ``render_scene`` timed apart, and the
    series only it has (:meth:`profile`, :meth:`explain`, :meth:`viewport`). ``opts``: the
    ``workers`` and ``chunk_candidates`` given to ``render_scene`` (None: its own)."""

    def __init__(self, opts: dict):
        self.opts = opts

    def setup(self, case: dict) -> dict:
        self.scene = _build_case(case)
        from blendlib import blender

        blender.build_draw_scene(self.scene)  # evaluates the depsgraph (untimed), like a viewport would
        first = self.run(first=True)
        return {"first_s": first["total_s"], "triangles": first["triangles"], "covered_px": first["covered_px"],
                "peak_mb": self.traced_peak()}

    def traced_peak(self, call=None) -> float:
        """Peak of the memory allocated during one (untimed) call of ``call(draw)`` (default
        ``render_scene``), in MiB: Python objects and numpy buffers (numpy reports its data
        allocations to tracemalloc), the result included, the input DrawScene excluded."""
        from blendlib import blender
        from blendlib.core.pipeline import render_scene

        draw = blender.build_draw_scene(self.scene)
        kwargs = self._kwargs()
        return traced_peak_mb(call or (lambda d: render_scene(d, **kwargs)), draw)

    def _kwargs(self) -> dict:
        kwargs = {}
        if self.opts.get("workers"):
            kwargs["workers"] = self.opts["workers"]
        if self.opts.get("chunk_candidates"):
            kwargs["chunk_candidates"] = self.opts["chunk_candidates"]
        return kwargs

    def final(self):
        """What renders a final frame: F12's renderer (:func:`blendlib.blender.render_frame`, large
        frames in two bands with a helper process, started here once, untimed, as in a session
        after its first render), or ``render_scene`` with the given ``workers`` /
        ``chunk_candidates``."""
        from blendlib.core.pipeline import render_scene
        from blendlib.runtime import bandprocs

        kwargs = self._kwargs()
        if kwargs:
            return None, lambda draw: render_scene(draw, **kwargs)
        bands = bandprocs.final_renderer()
        bands.wait_ready()
        return bands, bands

    def run(self, first: bool = False) -> dict:
        import numpy as np

        from blendlib import blender
        from blendlib.core import merger

        bands, render = self.final()
        with Timer() as te:
            draw = blender.build_draw_scene(self.scene)
        # A render from scratch: no blend tables kept from the previous run, here or in the
        # helper (the viewport and explain series keep them, as an interactive session does).
        if bands is None:
            merger.RECENT_TABLES.clear()
        else:
            bands.forget_tables()  # this process's tables and, before the next band, the helper's
        can_peak = reset_peak()
        rss0 = proc_status().get("VmRSS", 0)
        helper = None if bands is None else bands.helper_pid
        helper_cpu0 = process_cpu_s(helper)
        split0 = 0 if bands is None else bands.split_frames
        with Timer() as tr:
            frame = render(draw)
        helper_cpu = process_cpu_s(helper) - helper_cpu0
        peak = proc_status().get("VmHWM", 0) if can_peak else 0
        out = {
            "extract_s": te.wall, "render_s": tr.wall, "total_s": te.wall + tr.wall,
            "cpu_ratio": (tr.cpu + helper_cpu) / tr.wall if tr.wall > 0 else 0.0,
            "split": bands is not None and bands.split_frames > split0,  # drawn in two bands
            "rss_peak_mb": max(0, peak - rss0) / 2**20, "rss_mb": peak / 2**20,
            "triangles": int(sum(r.mesh.triangle_count for r in draw.renderers)),
        }
        if first:
            c = frame.color
            background = c[0, 0]
            out["covered_px"] = int(np.count_nonzero(np.any(c != background, axis=-1)))
        del frame, draw
        return out

    def explain(self, repeats: int) -> dict:
        """The frame debugger and the sorted reference on this scene's
        DrawScene, each timed against a plain ``render_scene`` of the same DrawScene in
        alternating runs (plain, draw list, pixel history, capture, step, analyze, analyze with
        advice, plain, ...): medians in seconds, ratios to the plain render's median (advice: also
        to the analysis without it), the tracemalloc peaks (MiB, one untimed call each) of a plain
        render, a capture and an analysis, and for scenes with ForwardAdd draws the price of each
        (:func:`forward_add_prices`)."""
        from blendlib import blender
        from blendlib.core.pipeline import render_scene
        from blendlib.explain import framedebug as fd
        from blendlib.explain.advice import analyze_and_advise
        from blendlib.explain.sorted_reference import analyze
        from blendlib.runtime.forked import ForkedMap

        draw = blender.build_draw_scene(self.scene)
        kwargs = self._kwargs()
        workers = kwargs.get("workers")
        cam = draw.camera
        x, y = int(cam.width) // 2, int(cam.height) // 2  # the pixel at the frame centre
        runs: dict[str, list[float]] = {k: [] for k in EXPLAIN_TIMES}
        info: dict = {}
        for _ in range(repeats):
            with Timer() as t:
                frame = render_scene(draw, **kwargs)
            runs["plain_s"].append(t.wall)
            del frame
            with Timer() as t:
                stats = fd.draw_list(draw, workers=workers)
            runs["drawlist_s"].append(t.wall)
            with Timer() as t:
                history = fd.pixel_history(draw, x, y, workers=workers)
            runs["pixel_s"].append(t.wall)
            with Timer() as t:
                cap = fd.FrameCapture.capture(draw, workers=workers)
            runs["capture_s"].append(t.wall)
            # The slider moved to the middle draw: replayed from the nearest snapshot before it.
            k = max(1, math.ceil(len(cap.stats) / 2))
            base = max((s for s in cap.snapshots if s < k), default=0)
            with Timer() as t:
                cap.frame_after(k, workers=workers)
            runs["step_s"].append(t.wall)
            info.update(draws=len(cap.stats), snapshots=len(cap.snapshots), interval=cap.interval,
                        snapshot_mb=cap.snapshot_memory / 2**20, step_to=k, step_from=base)
            del cap
            with Timer() as t:
                analysis = analyze(draw, workers=workers)
            runs["analyze_s"].append(t.wall)
            info.update(inversion_pairs=len(analysis.inversions), differing_px=int(analysis.differing))
            del analysis
            with Timer() as t:
                # As the command line and blendlib.analyze measure the candidates: shared with a
                # forked process where that pays (one process when the run asks for one thread).
                advised = analyze_and_advise(draw, max_advice=ADVICE_PAIRS, workers=workers,
                                             measure_map=ForkedMap(1 if workers == 1 else None))
            runs["advised_s"].append(t.wall)
            info.update(advice_items=len(advised.advice))
            del advised
        info.update(fragments=sum(s.fragments for s in stats), written=sum(s.written for s in stats),
                    pixel=[x, y], pixel_fragments=len(history.fragments))
        out = {k: median(v) for k, v in runs.items()}
        plain = out["plain_s"]
        for k in EXPLAIN_TIMES[1:]:
            out[k.replace("_s", "_ratio")] = out[k] / plain if plain > 0 else None
        out["advice_over_analyze"] = out["advised_s"] / out["analyze_s"] if out["analyze_s"] > 0 else None
        prices = forward_add_prices(draw, repeats)
        if prices:
            out["forward_add"] = prices
        out["plain_peak_mb"] = traced_peak_mb(lambda d: render_scene(d, **kwargs), draw)
        out["capture_peak_mb"] = traced_peak_mb(lambda d: fd.FrameCapture.capture(d, workers=workers), draw)
        out["analyze_peak_mb"] = traced_peak_mb(lambda d: analyze(d, workers=workers), draw)
        out.update(info)
        out["size"] = [int(cam.width), int(cam.height)]
        return {"explain": out}

    def viewport(self, width: int, height: int, repeats: int) -> dict:
        """The viewport through the scene camera's view and projection matrices (turned a little
        each run) at ``width`` x ``height``: after a view change, the reduced first frame (1/4 per
        side) and the full frame; then after a scene change seen through that view, extraction
        of the viewport template, the reduced and the full frame; each timed directly as the
        viewport renders them (a :class:`BandRenderer` with its helper
        process started; as in the scheduler, after a heavy split frame
        (:func:`viewport.begins_early`) the helper begins the next full frame's band before the
        reduced frame renders, and the reduced time includes that request), the full frame also
        by ``render_scene`` in this process alone; the time from a change to the first frame
        (extraction + reduced frame); :func:`render_view` end to end; and the same
        through a :class:`ViewportScheduler` (extraction on this thread, frames on its worker
        thread: from the start of the extraction to each frame's ``on_ready``). A change is a
        1e-4 nudge of one mesh object, evaluated (untimed, Blender's work) before each run; each
        extraction reuses the unchanged parts of the one before, as the add-on's viewport does."""
        import dataclasses
        import threading

        import bpy
        import numpy as np

        from blendlib.blender import viewport as vp
        from blendlib.core.pipeline import render_scene
        from blendlib.runtime import scheduler
        from blendlib.runtime.bandprocs import BandRenderer

        scene = self.scene
        depsgraph = bpy.context.evaluated_depsgraph_get()
        cam_obj = scene.camera.evaluated_get(depsgraph)
        view = np.linalg.inv(vp.as_matrix(cam_obj.matrix_world, "matrix_world"))
        proj = vp.as_matrix(cam_obj.calc_matrix_camera(depsgraph, x=width, y=height), "projection")
        camera = vp.camera_from_matrices(view, proj, width, height)
        small = scheduler.reduced_size(width, height)
        reduced = dataclasses.replace(camera, width=small[0], height=small[1]) if small else camera
        target = next((o for o in scene.objects if o.type == "MESH"), None)
        nudges = [0]

        def change() -> None:
            if target is not None:
                nudges[0] += 1
                target.location.x += 1e-4 if nudges[0] % 2 else -1e-4
            bpy.context.view_layer.update()

        stamps: list[float] = []
        ready = threading.Condition()

        def on_ready() -> None:
            with ready:
                stamps.append(time.perf_counter())
                ready.notify_all()

        sched = scheduler.ViewportScheduler(on_ready=on_ready)
        bands = BandRenderer()
        bands.wait_ready()
        runs: dict[str, list[float]] = {k: [] for k in VIEWPORT_TIMES}
        template = None
        try:
            for i in range(repeats):
                # The user turns the view (0.6 degrees about the world z axis, alternately either
                # way): the same template through a new camera, nothing kept from frames before.
                turned = vp.camera_from_matrices(view @ _turn_about_z(0.01 if i % 2 else -0.01), proj, width, height)
                turned_small = dataclasses.replace(turned, width=reduced.width, height=reduced.height)
                if template is None:
                    template = vp.extract_template(scene, depsgraph)
                seen = dataclasses.replace(template, camera=turned)
                with Timer() as tr2:  # as the scheduler does: after a heavy split frame the helper
                    if small and scheduler.begins_early(bands):
                        bands.begin(seen)  # begins the next one before the reduced frame renders
                    bands(dataclasses.replace(template, camera=turned_small))
                with Timer() as tf2:
                    bands(seen)
                # ... then edits the scene, seen through that view.
                change()
                with Timer() as te:  # as the add-on's viewport: unchanged parts of the last template reused
                    template = vp.extract_template(scene, depsgraph, previous=template)
                draw = dataclasses.replace(template, camera=turned)
                with Timer() as tr:
                    if small and scheduler.begins_early(bands):
                        bands.begin(draw)
                    bands(dataclasses.replace(template, camera=turned_small))
                with Timer() as tf:
                    bands(draw)
                with Timer() as t1:
                    render_scene(draw)
                runs["reduced_view_s"].append(tr2.wall)
                runs["full_view_s"].append(tf2.wall)
                runs["extract_s"].append(te.wall)
                runs["reduced_s"].append(tr.wall)
                runs["full_s"].append(tf.wall)
                runs["full_one_process_s"].append(t1.wall)
                runs["first_frame_s"].append(te.wall + tr.wall)
                change()
                with Timer() as tv:
                    vp.render_view(scene, view, proj, width, height, depsgraph=depsgraph)
                runs["render_view_s"].append(tv.wall)
                change()
                stamps.clear()
                t0 = time.perf_counter()
                template = vp.extract_template(scene, depsgraph, previous=template)
                sched.submit(dataclasses.replace(template, camera=camera), key=i)
                if not sched.wait_idle(timeout=120) or len(stamps) < (2 if small else 1):
                    raise RuntimeError(f"viewport scheduler gave {len(stamps)} frames: {sched.error}")
                runs["scheduler_first_s"].append(stamps[0] - t0)
                runs["scheduler_full_s"].append(stamps[-1] - t0)
        finally:
            sched.close()
            bands.close()
            if target is not None and nudges[0] % 2:
                target.location.x -= 1e-4  # leave the scene as it was
        out = {k: median(v) for k, v in runs.items()}
        out.update(size=[width, height], reduced_size=[reduced.width, reduced.height], runs=repeats,
                   split_frames=bands.split_frames, begun_frames=bands.begun_frames,
                   helper_failure=bands.failure)
        return {"viewport": out}

    def profile(self, top: int) -> dict:
        """cProfile of one extraction + render with ``workers=1`` (cProfile sees one thread only):
        the ``top`` functions by own time, and the share of the numpy-free Python overhead."""
        import cProfile
        import io
        import pstats

        from blendlib import blender
        from blendlib.core.pipeline import render_scene

        kwargs = {"workers": 1}
        if self.opts.get("chunk_candidates"):
            kwargs["chunk_candidates"] = self.opts["chunk_candidates"]
        prof = cProfile.Profile()
        prof.enable()
        draw = blender.build_draw_scene(self.scene)
        render_scene(draw, **kwargs)
        prof.disable()
        stats = pstats.Stats(prof)
        total = stats.total_tt
        rows = []
        for (file, line, func), (_cc, nc, tt, ct, _callers) in stats.stats.items():
            rows.append({"function": f"{Path(file).name}:{line}({func})" if line else func,
                         "calls": nc, "tottime": tt, "cumtime": ct})
        rows.sort(key=lambda r: -r["tottime"])
        buf = io.StringIO()
        pstats.Stats(prof, stream=buf).sort_stats("cumulative").print_stats(r"blendlib", top)
        return {"total_s": total, "top": rows[:top], "cumulative": buf.getvalue()}

    def end(self) -> dict:
        self.scene = None
        return {}


class OpenGLWorker:
    """The same DrawScene through OpenGL (llvmpipe): draw calls, glFinish and readback timed;
    context creation, upload and the first draw reported apart."""

    def __init__(self, opts: dict):
        from tests.reference import glref

        with Timer() as t:
            glref.context()
        self.context_s = t.wall
        self.renderer = None

    def setup(self, case: dict) -> dict:
        from blendlib import blender
        from tests.reference import glref

        scene = _build_case(case)
        draw = blender.build_draw_scene(scene)
        with Timer() as tu:
            self.renderer = glref.GLRenderer(draw)
        with Timer() as tf:
            self._draw()
        return {"context_s": self.context_s, "upload_s": tu.wall, "first_s": tf.wall}

    def _draw(self):
        r = self.renderer
        r.render()
        r.finish()
        return r.read()

    def run(self) -> dict:
        with Timer() as t:
            self._draw()
        return {"total_s": t.wall, "cpu_ratio": t.cpu / t.wall if t.wall > 0 else 0.0}

    def end(self) -> dict:
        if self.renderer is not None:
            self.renderer.release()
            self.renderer = None
        return {}


class BlenderWorker:
    """One of Blender's engines: ``bpy.ops.render.render()`` of the scene, as F12 costs."""

    engine = ""

    def __init__(self, opts: dict):
        pass

    def setup(self, case: dict) -> dict:
        import bpy

        self.scene = _build_case(case)
        self.scene.render.engine = self.engine
        self.scene.eevee.taa_render_samples = 1
        with Timer() as t:
            bpy.ops.render.render(write_still=False)
        return {"first_s": t.wall}

    def run(self) -> dict:
        import bpy

        with Timer() as t:
            bpy.ops.render.render(write_still=False)
        return {"total_s": t.wall, "cpu_ratio": t.cpu / t.wall if t.wall > 0 else 0.0}

    def end(self) -> dict:
        return {}


class EeveeWorker(BlenderWorker):
    engine = "BLENDER_EEVEE"


class WorkbenchWorker(BlenderWorker):
    engine = "BLENDER_WORKBENCH"


WORKERS = {"project": ProjectWorker, "opengl": OpenGLWorker, "eevee": EeveeWorker, "workbench": WorkbenchWorker}


def serve(kind: str) -> int:
    """Serve JSON-line commands on stdin; answers go to the original stdout, everything else
    (Blender's own prints) to stderr."""
    from blendlib.runtime.allocator import keep_freed_memory

    # As the command line does (and as Blender's own jemalloc behaves): freed memory is kept
    # for reuse, in every backend's worker alike.
    keep_freed_memory()
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    from scripts import scenekit

    registered = scenekit.register_addon(f"benchmark {kind} worker")  # without it: the stored properties
    try:
        w = WORKERS[kind]({})
        proto.write(json.dumps({"ok": True, "addon": registered}) + "\n")
    except Exception as exc:  # noqa: BLE001
        proto.write(json.dumps({"ok": False, "error": f"{type(exc).__name__}: {exc}"}) + "\n")
        return 1
    for line in sys.stdin:
        msg = json.loads(line)
        cmd = msg["cmd"]
        if cmd == "quit":
            break
        try:
            if cmd == "options":
                if isinstance(w, ProjectWorker):
                    w.opts.update(msg["options"])
                res = {}
            elif cmd == "setup":
                res = w.setup(msg["case"])
            elif cmd == "run":
                res = w.run()
            elif cmd == "profile":
                res = w.profile(int(msg.get("top", 25)))
            elif cmd == "explain":
                res = w.explain(int(msg["repeats"]))
            elif cmd == "viewport":
                res = w.viewport(int(msg["width"]), int(msg["height"]), int(msg["repeats"]))
            elif cmd == "end":
                res = w.end()
            else:
                raise ValueError(f"unknown command {cmd!r}")
            proto.write(json.dumps({"ok": True, **res}) + "\n")
        except Exception as exc:  # noqa: BLE001 - reported to the parent, which skips the backend
            traceback.print_exc()
            proto.write(json.dumps({"ok": False, "error": f"{type(exc).__name__}: {exc}"}) + "\n")
    return 0


class WorkerProcess:
    """The parent's handle on one worker process: :meth:`call` sends a command, returns the answer."""

    def __init__(self, kind: str, log):
        self.kind = kind
        # ``-m`` from the repository root: the worker imports scripts, addon and tests from there.
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "scripts.benchmark", "--worker", kind], cwd=REPO,
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=log, text=True, bufsize=1,
        )
        hello = self._read()
        self.ok = hello.get("ok", False)
        self.error = hello.get("error", "")
        self.addon = hello.get("addon", False)

    def _read(self) -> dict:
        line = self.proc.stdout.readline()
        if not line:
            return {"ok": False, "error": f"{self.kind} worker exited (see the log)"}
        return json.loads(line)

    def call(self, cmd: str, **kw) -> dict:
        if self.proc.poll() is not None:
            return {"ok": False, "error": f"{self.kind} worker is not running"}
        self.proc.stdin.write(json.dumps({"cmd": cmd, **kw}) + "\n")
        self.proc.stdin.flush()
        return self._read()

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                self.proc.stdin.write(json.dumps({"cmd": "quit"}) + "\n")
                self.proc.stdin.flush()
                self.proc.wait(timeout=30)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()


