#!/usr/bin/env python3
"""Benchmark: the project's renderer against OpenGL (Mesa llvmpipe), EEVEE and Workbench.

    .venv/bin/python -m scripts.benchmark                      # the full run (docs/benchmark.md)
    .venv/bin/python -m scripts.benchmark --quick              # small sizes, a smoke run
    .venv/bin/python -m scripts.benchmark --scenes S1,S4 --repeats 5 --json out.json --plot docs/benchmark.png
    .venv/bin/python -m scripts.benchmark --from-json out.json --write-doc docs/benchmark.md   # no run

Run it from the repository root (``-m``): the workers import ``addon`` and ``tests.reference``
from there, and ``blendlib`` as installed (editable) in the environment.

Every scene is a real Blender scene built with bpy (or a file of ``blend_files/``), so that
every backend starts from the same data:

- ``project``: ``blendlib.blender.build_draw_scene`` (extraction: evaluated bpy scene → DrawScene)
  then ``blendlib.render_scene`` (the numpy renderer), timed separately;
- ``opengl``: the same DrawScene drawn by :class:`tests.reference.glref.GLRenderer` (moderngl, EGL,
  Mesa llvmpipe): clear + every draw call + glFinish + readback of colour, depth and stencil.
  Context creation, vertex upload and the first (shader-compiling) draw are reported apart;
- ``eevee``: ``bpy.ops.render.render()`` with ``BLENDER_EEVEE`` and ``taa_render_samples = 1``;
- ``workbench``: ``bpy.ops.render.render()`` with ``BLENDER_WORKBENCH``.

Each backend lives in its own worker process (so GL contexts, caches and memory figures do not
mix); the parent builds the scene in every worker, does one untimed warm-up run per backend
(its time is reported as "first"), then alternates timed runs A, B, C, D, A, B, ... and reports
medians. Only one worker runs at a time.

Peak memory of the project's render: the worker resets its peak resident set size
(``/proc/self/clear_refs`` ← 5) just before ``render_scene`` and reads ``VmHWM`` after it:
"peak RSS over the RSS before the render" is what the render needs on top of the Blender
process and the input scene (numpy buffers, chunks, the frame). CPU use is the process CPU
time (all threads) over wall time of the same call: 2.0 means both cores busy.

More series of the project worker (docs/benchmark.md, "What is timed"):

- S1, S2 and every S3 scene: the frame debugger's draw list, the pixel history
  of the frame centre, a capture with snapshots, a slider step to the middle draw, and
  ``analyze(draw, advice=False)``, each alternated with a plain ``render_scene`` of the same
  DrawScene and reported as a ratio to it; tracemalloc peaks of a render, a capture, an analysis;
- every S3 scene: the viewport through the scene camera's matrices at 960x540:
  extraction, the reduced (1/4 per side) and the full frame, change → first frame, and the
  same through :class:`blendlib.blender.viewport.ViewportScheduler`;
- S2p: S2's planes through a perspective camera, at varied depths and angles.

The load average at the start and the end of the run, the CPU time the host took (steal) and
a host speed probe (:func:`speed_probe_ms`, sampled between scenes) are printed and written
to the doc: on a shared machine absolute times are noisy, ratios from alternating runs less so.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BACKENDS = ("project", "opengl", "eevee", "workbench")

# ---------------------------------------------------------------------------------------------
# The scenes
# ---------------------------------------------------------------------------------------------


def sphere_k(triangles: int) -> int:
    """A UV sphere with ``2k`` segments and ``k + 1`` rings has ``2*2k*k = 4k²`` triangles."""
    return max(2, round(math.sqrt(triangles / 4.0)))


#: Scene groups whose project worker also times the frame debugger and the sorted reference
#: against a plain render (issues 11 and 12).
EXPLAIN_GROUPS = ("S1", "S2", "S3")
#: The viewport size of issue 13 (every S3 scene through blendlib.blender.viewport), and --quick's.
VIEWPORT_SIZE, VIEWPORT_QUICK = (960, 540), (320, 180)


def plan_cases(args) -> list[dict]:
    """The cases to run, in order. Each is a plain dict (sent as JSON to the workers)."""
    quick = args.quick
    wanted = {s.strip().upper() for s in args.scenes.split(",") if s.strip()}  # "S2p" -> "S2P"
    full_hd = (480, 270) if quick else (1920, 1080)
    cases: list[dict] = []
    if "S1" in wanted:
        cases.append(dict(id="S1", group="S1", kind="sphere", k=sphere_k(20_000 if quick else 200_000),
                          width=full_hd[0], height=full_hd[1], fill=1 / 3,
                          label="UV sphere, Cull Off, ZWrite Off, alpha blend"))
    if "S2" in wanted:
        cases.append(dict(id="S2", group="S2", kind="planes", count=10 if quick else 50,
                          width=full_hd[0], height=full_hd[1],
                          label="transparent planes, each half the frame"))
    if "S2P" in wanted:
        cases.append(dict(id="S2p", group="S2p", kind="planes-perspective", count=10 if quick else 50,
                          width=full_hd[0], height=full_hd[1],
                          label="transparent planes, perspective, varied depths and angles, most of the frame each"))
    if "S3" in wanted:
        blend_dir = Path(args.blend_dir)
        files = sorted(blend_dir.glob("*.blend")) if blend_dir.is_dir() else []
        size = (320, 180) if quick else (1280, 720)
        for f in files:
            cases.append(dict(id=f"S3:{f.stem}", group="S3", kind="blend", path=str(f.resolve()),
                              width=size[0], height=size[1], label=f"blend_files/{f.name}",
                              viewport=list(VIEWPORT_QUICK if quick else VIEWPORT_SIZE)))
        if not files:
            print(f"note: S3 skipped: no .blend files in {blend_dir}", file=sys.stderr)
    if "S4" in wanted:
        cases.append(dict(id="S4", group="S4", kind="monkey", levels=3 if quick else 5,
                          width=full_hd[0], height=full_hd[1], label="subdivided monkey, opaque"))
    if "SCALING" in wanted:
        tris = [2_000, 8_000, 32_000] if quick else [10_000, 30_000, 100_000, 300_000, 1_000_000]
        for t in tris:
            k = sphere_k(t)
            cases.append(dict(id=f"tris {4 * k * k}", group="scale-tris", kind="sphere", k=k,
                              width=full_hd[0], height=full_hd[1], fill=1 / 3,
                              label="S1 material, triangles vary"))
        sizes = ([(160, 90), (320, 180), (640, 360)] if quick
                 else [(854, 480), (1280, 720), (1920, 1080), (2560, 1440), (3840, 2160)])
        k = sphere_k(8_000 if quick else 200_000)
        for w, h in sizes:
            cases.append(dict(id=f"{w}x{h}", group="scale-res", kind="sphere", k=k, width=w, height=h,
                              fill=1 / 3, label="S1 material, resolution varies"))
    if not getattr(args, "no_explain", False):
        for case in cases:
            if case["group"] in EXPLAIN_GROUPS:
                case["explain"] = True
    return cases


ALPHA_BLEND = dict(blend=True, zwrite=False, src_blend="SrcAlpha", dst_blend="OneMinusSrcAlpha")


def _unity_settings(mat, *, queue: str, color, passes: list[dict], lighting: str = "Lambert") -> None:
    """Give ``mat`` Unity settings (``Material.unity``) through the schema's writer, which stores
    the same values whether or not the add-on is registered."""
    from blendlib.blender import write_material

    write_material(mat, enabled=True, queue=queue, color=tuple(color), lighting=lighting, passes=passes)


def _principled(mat, color, alpha: float, blended: bool, backface_culling: bool) -> None:
    """The same look for EEVEE/Workbench: Principled BSDF Base Color/Alpha, EEVEE blend mode."""
    mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Alpha"].default_value = alpha
    mat.diffuse_color = (*color, alpha)  # Workbench (material colour)
    mat.surface_render_method = "BLENDED" if blended else "DITHERED"
    mat.use_backface_culling = backface_culling


def _srgb_encode(x: float) -> float:
    return x * 12.92 if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055


def _material(name: str, color_linear, alpha: float, *, transparent: bool, cull: str):
    import bpy

    mat = bpy.data.materials.new(name)
    _principled(mat, color_linear, alpha, blended=transparent, backface_culling=cull != "Off")
    color = tuple(_srgb_encode(c) for c in color_linear) + (alpha,)  # _Color is sRGB-encoded
    if transparent:
        _unity_settings(mat, queue="Transparent", color=color, passes=[dict(ALPHA_BLEND, cull=cull)])
    else:
        _unity_settings(mat, queue="Geometry", color=color, passes=[dict(cull=cull)])
    return mat


def _look_at(obj, target) -> None:
    from mathutils import Vector

    direction = Vector(target) - obj.location
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


def _common(scene, width: int, height: int) -> None:
    import bpy

    scene.render.resolution_x, scene.render.resolution_y = int(width), int(height)
    scene.render.resolution_percentage = 100
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    if scene.world is None:
        scene.world = bpy.data.worlds.new("World")
    scene.eevee.taa_render_samples = 1


def _add_camera(scene, location, target, ortho_scale: float | None = None):
    import bpy

    cam = bpy.data.cameras.new("Camera")
    cam.clip_start, cam.clip_end = 0.1, 100.0
    if ortho_scale is not None:
        cam.type = "ORTHO"
        cam.ortho_scale = ortho_scale
    obj = bpy.data.objects.new("Camera", cam)
    scene.collection.objects.link(obj)
    obj.location = location
    _look_at(obj, target)
    scene.camera = obj
    return obj


def _add_sun(scene) -> None:
    import bpy

    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 2.0
    obj = bpy.data.objects.new("Sun", sun)
    scene.collection.objects.link(obj)
    obj.rotation_euler = (0.6, 0.2, 0.8)


def uv_sphere_mesh(name: str, k: int):
    """A unit UV sphere with ``2k`` segments and ``k + 1`` rings (``4k²`` triangles), normals outwards.
    Built with ``foreach_set`` (``bmesh.ops.create_uvsphere`` takes ~15 s for 200k triangles)."""
    import bpy
    import numpy as np

    nlon, nlat = 2 * k, k + 1
    lat = np.pi * np.arange(1, nlat) / nlat  # polar angles of the nlat - 1 vertex rings
    lon = 2 * np.pi * np.arange(nlon) / nlon
    st, ct = np.sin(lat)[:, None], np.cos(lat)[:, None]
    ring = np.stack([st * np.cos(lon), st * np.sin(lon), np.broadcast_to(ct, (nlat - 1, nlon))], -1)
    co = np.concatenate([[[0.0, 0.0, 1.0]], ring.reshape(-1, 3), [[0.0, 0.0, -1.0]]]).astype(np.float32)
    top, bottom = 0, len(co) - 1
    idx = 1 + np.arange((nlat - 1) * nlon).reshape(nlat - 1, nlon)
    nxt = np.roll(idx, -1, axis=1)
    caps_top = np.stack([np.full(nlon, top), idx[0], nxt[0]], -1)
    caps_bottom = np.stack([np.full(nlon, bottom), nxt[-1], idx[-1]], -1)
    quads = np.stack([idx[:-1], idx[1:], nxt[1:], nxt[:-1]], -1).reshape(-1, 4)
    loops = np.concatenate([caps_top.ravel(), quads.ravel(), caps_bottom.ravel()]).astype(np.int32)
    sizes = np.concatenate([np.full(nlon, 3), np.full(len(quads), 4), np.full(nlon, 3)]).astype(np.int32)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int32)
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(co))
    me.vertices.foreach_set("co", co.ravel())
    me.loops.add(len(loops))
    me.loops.foreach_set("vertex_index", loops)
    me.polygons.add(len(sizes))
    me.polygons.foreach_set("loop_start", starts)
    me.update()
    me.validate(verbose=False)
    return me


def build_case(case: dict):
    """Build the case's Blender scene in this process; returns the scene."""
    import bpy

    if case["kind"] == "blend":
        bpy.ops.wm.open_mainfile(filepath=case["path"], load_ui=False)
        scene = bpy.context.scene
        _common(scene, case["width"], case["height"])
        return scene

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    _common(scene, case["width"], case["height"])
    world = scene.world
    world.color = (0.05, 0.05, 0.05)
    _add_sun(scene)
    w, h = case["width"], case["height"]

    if case["kind"] == "sphere":
        me = uv_sphere_mesh("Sphere", int(case["k"]))
        me.shade_smooth()
        obj = bpy.data.objects.new("Sphere", me)
        scene.collection.objects.link(obj)
        obj.data.materials.append(_material("Glass", (0.2, 0.45, 1.0), 0.5, transparent=True, cull="Off"))
        # Silhouette radius r_px = f_px / sqrt(d² - 1) with the 50 mm lens on the 36 mm sensor (width fit).
        f_px = 50.0 / 36.0 * max(w, h)
        r_px = math.sqrt(case["fill"] * w * h / math.pi)
        d = math.sqrt((f_px / r_px) ** 2 + 1.0)
        _add_camera(scene, (0.0, -d, 0.0), (0.0, 0.0, 0.0))
    elif case["kind"] == "planes":
        # Orthographic camera looking down -Z; frame = 16 x 9 units; each plane 8 x 9 (half the frame).
        me = bpy.data.meshes.new("Plane")
        me.from_pydata([(-4, -4.5, 0), (4, -4.5, 0), (4, 4.5, 0), (-4, 4.5, 0)], [], [(0, 1, 2, 3)])
        mat = _material("Veil", (1.0, 0.5, 0.2), 0.1, transparent=True, cull="Back")
        me.materials.append(mat)
        seed = 12345
        for i in range(int(case["count"])):
            seed = (seed * 1103515245 + 12345) % 2**31
            x = (seed / 2**31 - 0.5) * 8.0  # centre in [-4, 4]: the plane stays inside the frame
            obj = bpy.data.objects.new(f"Plane.{i:03d}", me)
            scene.collection.objects.link(obj)
            obj.location = (x, 0.0, i * 0.05)
        _add_camera(scene, (0.0, 0.0, 10.0), (0.0, 0.0, 0.0), ortho_scale=16.0 * max(1.0, (16 / 9) / (w / h)))
    elif case["kind"] == "planes-perspective":
        # S2p: the S2 planes through a 50 mm perspective camera at the origin looking
        # down -Z; each plane at a depth in [2, 8], tilted up to 35 degrees about X and Y and
        # turned up to 20 degrees about Z, sized to 90 % of the frustum at its depth and shifted
        # by up to 10 %: each covers most of the frame, with perspective-correct interpolation.
        me = bpy.data.meshes.new("Plane")
        me.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
        me.materials.append(_material("Veil", (1.0, 0.5, 0.2), 0.1, transparent=True, cull="Back"))
        half_w = 18.0 / 50.0  # frustum half-width per unit of depth (36 mm sensor, width fit)
        aspect = h / w
        seed = 54321

        def uniform(lo, hi):
            nonlocal seed
            seed = (seed * 1103515245 + 12345) % 2**31
            return lo + (hi - lo) * seed / 2**31

        for i in range(int(case["count"])):
            depth = uniform(2.0, 8.0)
            hw, hh = half_w * depth, half_w * depth * aspect
            obj = bpy.data.objects.new(f"Plane.{i:03d}", me)
            scene.collection.objects.link(obj)
            obj.location = (uniform(-0.1, 0.1) * hw, uniform(-0.1, 0.1) * hh, -depth)
            obj.rotation_euler = (math.radians(uniform(-35, 35)), math.radians(uniform(-35, 35)),
                                  math.radians(uniform(-20, 20)))
            obj.scale = (0.9 * hw, 0.9 * hh, 1.0)
        _add_camera(scene, (0.0, 0.0, 0.0), (0.0, 0.0, -1.0))
    elif case["kind"] == "monkey":
        bpy.ops.mesh.primitive_monkey_add(size=2.0)
        obj = bpy.context.object
        mod = obj.modifiers.new("Subdivision", "SUBSURF")
        mod.levels = mod.render_levels = int(case["levels"])
        obj.data.shade_smooth()
        obj.data.materials.append(_material("Clay", (0.8, 0.6, 0.5), 1.0, transparent=False, cull="Back"))
        _add_camera(scene, (0.0, -6.5, 0.4), (0.0, 0.0, 0.0))
    else:
        raise ValueError(f"unknown case kind {case['kind']!r}")
    bpy.context.view_layer.update()
    return scene


# ---------------------------------------------------------------------------------------------
# Workers (one process per backend)
# ---------------------------------------------------------------------------------------------


def _proc_status() -> dict[str, int]:
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


def _reset_peak() -> bool:
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


#: Timed series of ProjectWorker.explain (medians), in their alternation order.
EXPLAIN_TIMES = ("plain_s", "drawlist_s", "pixel_s", "capture_s", "step_s", "analyze_s")
#: Timed series of ProjectWorker.viewport (medians).
VIEWPORT_TIMES = ("extract_s", "reduced_s", "full_s", "reduced_view_s", "full_view_s", "full_one_process_s",
                  "first_frame_s", "render_view_s", "scheduler_first_s", "scheduler_full_s")


def _turn_about_z(angle: float):
    """(4, 4) float64 rotation by ``angle`` radians about the world z axis."""
    import numpy as np

    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=np.float64)


class Timer:
    def __enter__(self):
        self.cpu0, self.t0 = time.process_time(), time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.wall = time.perf_counter() - self.t0
        self.cpu = time.process_time() - self.cpu0


class ProjectWorker:
    def __init__(self, opts: dict):
        self.opts = opts

    def setup(self, case: dict) -> dict:
        self.scene = build_case(case)
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

    def run(self, first: bool = False) -> dict:
        import numpy as np

        from blendlib import blender
        from blendlib.core import merger
        from blendlib.core.pipeline import render_scene

        kwargs = self._kwargs()
        with Timer() as te:
            draw = blender.build_draw_scene(self.scene)
        # A render from scratch: no blend tables kept from the previous run (the viewport and
        # explain series keep them, as an interactive session does).
        merger.RECENT_TABLES.clear()
        can_peak = _reset_peak()
        rss0 = _proc_status().get("VmRSS", 0)
        with Timer() as tr:
            frame = render_scene(draw, **kwargs)
        peak = _proc_status().get("VmHWM", 0) if can_peak else 0
        out = {
            "extract_s": te.wall, "render_s": tr.wall, "total_s": te.wall + tr.wall,
            "cpu_ratio": tr.cpu / tr.wall if tr.wall > 0 else 0.0,
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
        alternating runs (plain, draw list, pixel history, capture, step, analyze, plain, ...):
        medians in seconds, ratios to the plain render's median, and the tracemalloc peaks
        (MiB, one untimed call each) of a plain render, a capture and an analysis."""
        from blendlib import blender
        from blendlib.core.pipeline import render_scene
        from blendlib.explain import framedebug as fd
        from blendlib.explain.sorted_reference import analyze

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
                analysis = analyze(draw, advice=False, workers=workers)
            runs["analyze_s"].append(t.wall)
            info.update(inversion_pairs=len(analysis.inversions), differing_px=int(analysis.differing))
            del analysis
        info.update(fragments=sum(s.fragments for s in stats), written=sum(s.written for s in stats),
                    pixel=[x, y], pixel_fragments=len(history.fragments))
        out = {k: median(v) for k, v in runs.items()}
        plain = out["plain_s"]
        for k in EXPLAIN_TIMES[1:]:
            out[k.replace("_s", "_ratio")] = out[k] / plain if plain > 0 else None
        out["plain_peak_mb"] = traced_peak_mb(lambda d: render_scene(d, **kwargs), draw)
        out["capture_peak_mb"] = traced_peak_mb(lambda d: fd.FrameCapture.capture(d, workers=workers), draw)
        out["analyze_peak_mb"] = traced_peak_mb(lambda d: analyze(d, advice=False, workers=workers), draw)
        out.update(info)
        out["size"] = [int(cam.width), int(cam.height)]
        return {"explain": out}

    def viewport(self, width: int, height: int, repeats: int) -> dict:
        """The viewport through the scene camera's view and projection matrices (turned a little
        each run) at ``width`` x ``height``: after a view change, the reduced first frame (1/4 per
        side) and the full frame; then after a scene change seen through that view, extraction
        of the viewport template, the reduced and the full frame; each timed directly as the
        viewport renders them (a :class:`~blendlib.core.bandprocs.BandRenderer` with its helper
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
        from blendlib.core.bandprocs import BandRenderer
        from blendlib.core.pipeline import render_scene

        scene = self.scene
        depsgraph = bpy.context.evaluated_depsgraph_get()
        cam_obj = scene.camera.evaluated_get(depsgraph)
        view = np.linalg.inv(vp.as_matrix(cam_obj.matrix_world, "matrix_world"))
        proj = vp.as_matrix(cam_obj.calc_matrix_camera(depsgraph, x=width, y=height), "projection")
        camera = vp.camera_from_matrices(view, proj, width, height)
        small = vp.reduced_size(width, height)
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

        sched = vp.ViewportScheduler(on_ready=on_ready)
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
                    if small and vp.begins_early(bands):
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
                    if small and vp.begins_early(bands):
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
    def __init__(self, opts: dict):
        from tests.reference import glref

        with Timer() as t:
            glref.context()
        self.context_s = t.wall
        self.renderer = None

    def setup(self, case: dict) -> dict:
        from blendlib import blender
        from tests.reference import glref

        scene = build_case(case)
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
    engine = ""

    def __init__(self, opts: dict):
        pass

    def setup(self, case: dict) -> dict:
        import bpy

        self.scene = build_case(case)
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


def worker_main(kind: str) -> int:
    """Serve JSON-line commands on stdin; answers go to the original stdout, everything else
    (Blender's own prints) to stderr."""
    from blendlib.core.allocator import keep_freed_memory

    # As the command line does (and as Blender's own jemalloc behaves): freed memory is kept
    # for reuse, in every backend's worker alike (blendlib/core/allocator.py).
    keep_freed_memory()
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    try:
        import addon  # noqa: F401  (the add-on registers Material.unity when it is there)

        addon.register()
        registered = True
    except Exception:  # noqa: BLE001 - without the add-on the bridge reads the stored properties
        registered = False
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


class Worker:
    """The parent's handle on one worker process."""

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


# ---------------------------------------------------------------------------------------------
# The run
# ---------------------------------------------------------------------------------------------


def median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def run_case(case: dict, workers: dict[str, Worker], repeats: int, say, profile: int = 0) -> dict:
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


def _fmt_t(v) -> str:
    if v is None:
        return "-"
    if v >= 100:
        return f"{v:.0f}"
    if v >= 10:
        return f"{v:.1f}"
    if v >= 1:
        return f"{v:.2f}"
    return f"{v:.3f}"


def _fmt_x(v) -> str:
    if v is None:
        return "-"
    return f"{v:.3f}x" if v < 0.1 else f"{v:.2f}x" if v < 1 else f"{v:.1f}x" if v < 100 else f"{v:.0f}x"


def _fmt_n(v) -> str:
    if v is None:
        return "-"
    if v >= 1e6:
        return f"{v / 1e6:.2f}M"
    if v >= 1e3:
        return f"{v / 1e3:.0f}k"
    return str(int(v))


COLUMNS = ("scene", "tris", "size", "covered", "extract s", "render s", "project s", "OpenGL s",
           "EEVEE s", "Workbench s", "proj/GL", "proj/EEVEE", "peak MB", "CPU")


def table_rows(results: list[dict]) -> list[list[str]]:
    rows = []
    for res in results:
        case = res["case"]
        m = res["median"]
        p, g, e, wb = (m.get(k) for k in BACKENDS)
        ps = res["setup"].get("project", {})
        rows.append([
            case["id"], _fmt_n(ps.get("triangles")), f"{case['width']}x{case['height']}",
            _fmt_n(ps.get("covered_px")),
            _fmt_t(p and p["extract_s"]), _fmt_t(p and p["render_s"]), _fmt_t(p and p["total_s"]),
            _fmt_t(g and g["total_s"]), _fmt_t(e and e["total_s"]), _fmt_t(wb and wb["total_s"]),
            _fmt_x(res["ratio_gl"]), _fmt_x(res["ratio_eevee"]),
            "-" if not p else f"{p['peak_mb']:.0f}", "-" if not p else f"{p['cpu_ratio']:.2f}",
        ])
    return rows


def format_table(results: list[dict], markdown: bool = False, columns=COLUMNS, rows_of=table_rows) -> str:
    """The main table (default), or with ``columns`` and ``rows_of`` another one (explain, viewport)."""
    rows = rows_of(results)
    if markdown:
        lines = ["| " + " | ".join(columns) + " |", "|" + "|".join("---" for _ in columns) + "|"]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        return "\n".join(lines)
    widths = [max(len(c), *(len(r[i]) for r in rows)) if rows else len(c) for i, c in enumerate(columns)]
    fmt = "  ".join(f"{{:{'<' if i == 0 else '>'}{w}}}" for i, w in enumerate(widths))
    lines = [fmt.format(*columns), fmt.format(*("-" * w for w in widths))]
    lines += [fmt.format(*r) for r in rows]
    return "\n".join(lines)


EXPLAIN_COLUMNS = ("scene", "size", "draws", "fragments", "plain s", "draw list", "pixel", "capture",
                   "step (to<-from)", "analyze", "plain MB", "capture MB", "analyze MB")
VIEWPORT_COLUMNS = ("scene", "size", "extract ms", "reduced ms", "full ms", "reduced (view) ms", "full (view) ms",
                    "full 1 proc. ms", "change->first ms", "render_view ms", "sched. first ms", "sched. full ms")


def explain_rows(results: list[dict]) -> list[list[str]]:
    """Frame debugger and sorted reference: ratios to a plain render of the same
    DrawScene in alternating runs, and tracemalloc peaks."""
    rows = []
    for res in results:
        e = res.get("explain")
        if not e:
            continue
        rows.append([
            res["case"]["id"], f"{e['size'][0]}x{e['size'][1]}", str(e["draws"]), _fmt_n(e["fragments"]),
            _fmt_t(e["plain_s"]), _fmt_x(e["drawlist_ratio"]), _fmt_x(e["pixel_ratio"]), _fmt_x(e["capture_ratio"]),
            f"{_fmt_x(e['step_ratio'])} ({e['step_to']}<-{e['step_from']})", _fmt_x(e["analyze_ratio"]),
            f"{e['plain_peak_mb']:.0f}", f"{e['capture_peak_mb']:.0f}", f"{e['analyze_peak_mb']:.0f}",
        ])
    return rows


def viewport_rows(results: list[dict]) -> list[list[str]]:
    """Viewport frames, medians in milliseconds."""
    rows = []
    for res in results:
        v = res.get("viewport")
        if not v:
            continue
        rows.append([res["case"]["id"], f"{v['size'][0]}x{v['size'][1]}"]
                    + [f"{v[k] * 1000:.1f}" if k in v else "-" for k in VIEWPORT_TIMES])
    return rows


def loglog_slope(xs, ys) -> float | None:
    pts = [(math.log(x), math.log(y)) for x, y in zip(xs, ys, strict=True) if x and y and x > 0 and y > 0]
    if len(pts) < 2:
        return None
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    return sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx if sxx else None


def scaling_summary(results: list[dict]) -> dict:
    out = {}
    for group, xkey in (("scale-tris", "triangles"), ("scale-res", "covered_px")):
        rs = [r for r in results if r["case"]["group"] == group]
        for kind in ("project", "opengl", "eevee"):
            xs = [r["setup"].get("project", {}).get(xkey) for r in rs]
            ys = [r["median"].get(kind, {}).get("render_s" if kind == "project" else "total_s") for r in rs]
            s = loglog_slope(xs, ys)
            if s is not None:
                out[f"{group}/{kind}"] = s
    return out


def _worst(rows: list[tuple[str, float]], limit: float, fmt=None) -> tuple[str, bool]:
    """(figure, met?) of several scenes against one limit: the worst value and its scene, the range."""
    fmt = fmt or _fmt_x
    name, worst = max(rows, key=lambda r: r[1])
    best = min(r[1] for r in rows)
    met = sum(v <= limit for _, v in rows)
    return (f"worst {fmt(worst)} ({name}); range {fmt(best)}–{fmt(worst)}; {met} of {len(rows)} met",
            worst <= limit)


def targets(results: list[dict], quick: bool) -> list[tuple[str, str, str, bool | None]]:
    """``(issue, target, figure, met?)`` lines: issue 5 (round 1), issue 14 (speed, round 2),
    issue 11 (frame debugger), issue 12 (sorted reference), issue 13 (viewport)."""
    by_id = {r["case"]["id"]: r for r in results}
    out = []
    r1 = "5 (round 1)"
    for sid, limit in (("S1", 8), ("S2", 10), ("S4", 5)):
        r = by_id.get(sid)
        if r and r["ratio_gl"] is not None:
            out.append((r1, f"{sid} render within {limit}x of OpenGL/llvmpipe", _fmt_x(r["ratio_gl"]),
                        r["ratio_gl"] <= limit))
    s3 = [r for r in results if r["case"]["group"] == "S3" and r["ratio_eevee"] is not None]
    for r in s3:
        out.append((r1, f"{r['case']['id']} faster than EEVEE (1 sample)", _fmt_x(r["ratio_eevee"]),
                    r["ratio_eevee"] < 1))
    r = by_id.get("S4")
    p = r and r["median"].get("project")
    if p:
        tris = r["setup"]["project"]["triangles"]
        out.append((r1, f"extraction of the {_fmt_n(tris)}-triangle evaluated mesh under 0.3 s",
                    f"{p['extract_s']:.3f} s", p["extract_s"] < 0.3))
        out.append((r1, "S4 peak memory of the render under 2 GB",
                    f"{p['peak_mb']:.0f} MB allocated (whole worker process incl. Blender and the scene: "
                    f"{p.get('rss_mb', 0):.0f} MB RSS)", p["peak_mb"] < 2048))
    sc = scaling_summary(results)
    for key, label in (("scale-tris/project", "triangles"), ("scale-res/project", "covered pixels")):
        if key in sc:
            out.append((r1, f"cost grows at most linearly with {label} (log-log slope <= 1.1)",
                        f"{sc[key]:.2f}", sc[key] <= 1.1))
    big = [r for r in results if r["case"]["width"] * r["case"]["height"] >= 1920 * 1080
           and r["median"].get("project")]
    if big:
        cpu = median([r["median"]["project"]["cpu_ratio"] for r in big])
        out.append((r1, "both CPU cores busy on large frames (median CPU time / wall >= 1.5)", f"{cpu:.2f}",
                    cpu >= 1.5))

    # Issue 14: speed, round two.
    r2 = "14 (round 2)"
    for sid, limit in (("S1", 4), ("S2", 3), ("S2p", 3), ("S4", 2.5)):
        r = by_id.get(sid)
        if r and r["ratio_gl"] is not None:
            out.append((r2, f"{sid} render within {limit:g}x of OpenGL/llvmpipe", _fmt_x(r["ratio_gl"]),
                        r["ratio_gl"] <= limit))
    rows = [(r["case"]["id"], r["ratio_gl"]) for r in results if r["case"]["group"] == "S3" and r["ratio_gl"]]
    if rows:
        out.append((r2, "every S3 scene within 4x of OpenGL/llvmpipe", *_worst(rows, 4)))
    rows = [(r["case"]["id"], r["ratio_gl"]) for r in results
            if r["case"]["group"] in ("S1", "S2", "S2p", "S3", "S4") and r["ratio_gl"]]
    if rows:
        out.append((r2, "goal beyond: 3x of OpenGL everywhere", *_worst(rows, 3)))
    for sid in ("S2", "S4"):
        p = by_id.get(sid) and by_id[sid]["median"].get("project")
        if p:
            out.append((r2, f"{sid} peak memory of a plain render under 1 GB", f"{p['peak_mb']:.0f} MB",
                        p["peak_mb"] < 1024))

    # Issues 11 and 12: the frame debugger and the sorted reference against a plain render.
    explained = [r for r in results if r.get("explain")]

    def ratio_lines(issue, label, key, limit, fmt_limit):
        for sid in ("S1", "S2"):
            e = by_id.get(sid, {}).get("explain")
            if e and e.get(key) is not None:
                out.append((issue, f"{sid}: {label} {fmt_limit}", _fmt_x(e[key]), e[key] <= limit))
        rows = [(r["case"]["id"], r["explain"][key]) for r in explained
                if r["case"]["group"] == "S3" and r["explain"].get(key) is not None]
        if rows:
            out.append((issue, f"every S3 scene: {label} {fmt_limit}", *_worst(rows, limit)))

    ratio_lines("11", "draw list", "drawlist_ratio", 1.25, "within about one plain render (<= 1.25x)")
    ratio_lines("11", "pixel history", "pixel_ratio", 1.25, "within about one plain render (<= 1.25x)")
    ratio_lines("11", "slider step to the middle draw from the nearest snapshot", "step_ratio", 1.0,
                "cheaper than a render (< 1x)")
    e = by_id.get("S2", {}).get("explain")
    if e:
        w, h = e["size"]
        out.append(("11", f"S2 capture at {w}x{h} peak memory under 2 GB",
                    f"{e['capture_peak_mb']:.0f} MB ({e['snapshots']} snapshots, {e['snapshot_mb']:.0f} MB)",
                    e["capture_peak_mb"] < 2048))
    ratio_lines("12", "analyze", "analyze_ratio", 3.0, "within 3x of a plain render")
    if e:
        out.append(("12", f"S2 analyze at {w}x{h} peak memory under 2 GB", f"{e['analyze_peak_mb']:.0f} MB",
                    e["analyze_peak_mb"] < 2048))

    # Issue 13: viewport frames of every S3 scene.
    vps = [r for r in results if r.get("viewport")]
    if vps:
        w, h = vps[0]["viewport"]["size"]

        def ms(v):
            return f"{v * 1000:.0f} ms" if v >= 0.01 else f"{v * 1000:.1f} ms"

        # Each frame after a scene change or a view change, whichever is slower (older JSON: the former).
        for keys, limit, label in ((("full_s", "full_view_s"), 0.060,
                                    f"viewport full frame {w}x{h} <= 60 ms median (after an edit or a view change)"),
                                   (("reduced_s", "reduced_view_s"), 0.020,
                                    "viewport reduced frame (1/4 per side) <= 20 ms median (after an edit or a view "
                                    "change)")):
            out.append(("13", f"every S3 scene: {label}",
                        *_worst([(r["case"]["id"], max(r["viewport"].get(k, 0.0) for k in keys)) for r in vps],
                                limit, ms)))
        # First frame after a change (extraction + reduced frame through the scheduler's thread)
        # within one full-frame time plus extraction: the margin is scheduler_first - (full + extract).
        rows = [(r["case"]["id"], r["viewport"]["scheduler_first_s"]
                 - (r["viewport"]["full_s"] + r["viewport"]["extract_s"])) for r in vps]
        name, margin = max(rows, key=lambda x: x[1])
        first = next(r["viewport"] for r in vps if r["case"]["id"] == name)
        out.append(("13", "every S3 scene: first frame after a change within one frame time plus extraction",
                    f"worst {name}: {ms(first['scheduler_first_s'])} vs {ms(first['full_s'] + first['extract_s'])}",
                    margin <= 0))
    return out


# ---------------------------------------------------------------------------------------------
# The plot (matplotlib, Agg)
# ---------------------------------------------------------------------------------------------

SERIES = (("project", "render_s", "#1f77b4"), ("opengl", "total_s", "#ff7f0e"),
          ("eevee", "total_s", "#2ca02c"), ("workbench", "total_s", "#9467bd"))


def _scaling_series(results, group, xkey):
    """``[(backend, colour, [(x, seconds), ...]), ...]`` of one scaling group (points with both > 0)."""
    rs = [r for r in results if r["case"]["group"] == group]
    out = []
    for kind, key, color in SERIES:
        s = [(r["setup"].get("project", {}).get(xkey) or 0, (r["median"].get(kind) or {}).get(key) or 0) for r in rs]
        s = [p for p in s if p[0] and p[1]]
        if s:
            out.append((kind, color, s))
    return out


def write_plot(results: list[dict], path: Path, title: str) -> Path:
    """One panel per kind of figure the run has: time vs triangles and time vs covered pixels
    (log-log, the scaling groups), every scene's total time per backend (log bars), the frame
    debugger's and the sorted reference's ratios to a plain render, and the viewport's frame
    times. Written atomically as PNG, 16/3 x 5 inches per panel at 80 dpi."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from blendlib.formats.atomic import write_atomic

    path.parent.mkdir(parents=True, exist_ok=True)
    tri = _scaling_series(results, "scale-tris", "triangles")
    res = _scaling_series(results, "scale-res", "covered_px")
    bars = [r for r in results if r["case"]["group"] in ("S1", "S2", "S2p", "S3", "S4")]
    explained = [r for r in results if r.get("explain")]
    viewports = [r for r in results if r.get("viewport")]
    panels = []

    def scaling_panel(series, xl, t):
        def draw(ax):
            for name, color, s in series:
                ax.loglog(*zip(*s, strict=True), "o-", color=color, label=name)
            ax.set_xlabel(xl)
            ax.set_ylabel("seconds (median)")
            ax.set_title(t)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend()
        return draw

    def grouped_bars(ax, rs, series, value):
        width = 0.8 / len(series)
        for j, (label, key, color) in enumerate(series):
            ax.bar([i + j * width for i in range(len(rs))], [value(r, key) or 0 for r in rs], width,
                   color=color, label=label)
        ax.set_xticks([i + 0.4 - width / 2 for i in range(len(rs))], [r["case"]["id"] for r in rs],
                      rotation=30, ha="right")
        ax.legend(fontsize=8)

    def scenes_panel(ax):
        grouped_bars(ax, bars, [(kind, kind, color) for kind, _key, color in SERIES],
                     lambda r, kind: (r["median"].get(kind) or {}).get("total_s"))
        ax.set_yscale("log")
        ax.set_ylabel("seconds (median)")
        ax.set_title("scenes: total time (project = extraction + render)")

    def explain_panel(ax):
        grouped_bars(ax, explained, [("draw list", "drawlist_ratio", "#1f77b4"), ("pixel history", "pixel_ratio",
                                                                                   "#ff7f0e"),
                                     ("capture", "capture_ratio", "#2ca02c"), ("step", "step_ratio", "#9467bd"),
                                     ("analyze", "analyze_ratio", "#d62728")],
                     lambda r, key: r["explain"].get(key))
        ax.set_yscale("log")
        # a one-draw scene's step returns the kept frame (~1e-5: off the axis); room for the legend
        ax.set_ylim(0.01, 30)
        ax.legend(fontsize=8, ncol=3, loc="upper left")
        for y, style in ((1.0, "-"), (3.0, "--")):
            ax.axhline(y, color="grey", linestyle=style, linewidth=0.8)
        ax.set_ylabel("time / plain render (median)")
        ax.set_title("frame debugger and analyze vs a plain render")

    def viewport_panel(ax):
        w, h = viewports[0]["viewport"]["size"]
        grouped_bars(ax, viewports, [("reduced frame", "reduced_s", "#2ca02c"), ("full frame", "full_s", "#1f77b4"),
                                     ("change -> first frame", "scheduler_first_s", "#ff7f0e")],
                     lambda r, key: r["viewport"][key] * 1000)
        for y in (20, 60):
            ax.axhline(y, color="grey", linestyle="--", linewidth=0.8)
        ax.set_ylabel("milliseconds (median)")
        ax.set_title(f"viewport {w}x{h} (targets 20 / 60 ms)")

    if tri:
        panels.append(scaling_panel(tri, "triangles", "time vs triangles (1080p)"))
    if res:
        panels.append(scaling_panel(res, "covered pixels", "time vs covered pixels (200k tris)"))
    if bars:
        panels.append(scenes_panel)
    if explained:
        panels.append(explain_panel)
    if viewports:
        panels.append(viewport_panel)
    n = max(len(panels), 1)
    fig = Figure(figsize=(16 / 3 * n, 5))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, n, squeeze=False)[0]
    for ax, panel in zip(axes, panels, strict=False):
        panel(ax)
    fig.suptitle(title)
    fig.tight_layout()
    write_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=80))
    return path


# ---------------------------------------------------------------------------------------------
# main
# ---------------------------------------------------------------------------------------------


def parse_args(argv=None):
    ap = argparse.ArgumentParser(prog="python -m scripts.benchmark", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small sizes (a smoke run of a minute or so)")
    ap.add_argument("--scenes", default="S1,S2,S2p,S3,S4,scaling",
                    help="comma-separated subset of S1,S2,S2p,S3,S4,scaling (default: all)")
    ap.add_argument("--backends", default=",".join(BACKENDS),
                    help=f"comma-separated subset of {','.join(BACKENDS)} (default: all)")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per backend and scene (default 3)")
    ap.add_argument("--json", metavar="OUT.json", help="write every run's figures as JSON")
    ap.add_argument("--plot", metavar="OUT.png", help="write the plot image (e.g. docs/benchmark.png)")
    ap.add_argument("--markdown", action="store_true", help="also print the table as Markdown")
    ap.add_argument("--write-doc", metavar="DOC.md",
                    help="replace the results section of DOC.md (between the <!-- results:start --> and "
                         "<!-- results:end --> markers) with this run's tables, e.g. docs/benchmark.md")
    ap.add_argument("--blend-dir", default=str(REPO / "blend_files"), help="the S3 scenes (default blend_files/)")
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
    args = parse_args(argv)
    if args.worker:
        return worker_main(args.worker)
    if args.from_json:
        data = json.loads(Path(args.from_json).read_text())
        return report(args, data["results"], data["env"], None)
    kinds = [k.strip().lower() for k in args.backends.split(",") if k.strip()]
    bad = [k for k in kinds if k not in BACKENDS]
    if bad or "project" not in kinds:
        print(f"error: --backends must include project and be a subset of {','.join(BACKENDS)}", file=sys.stderr)
        return 2
    cases = plan_cases(args)
    if not cases:
        print("error: no scenes selected", file=sys.stderr)
        return 2
    log_path = Path(args.log) if args.log else Path(tempfile.mkstemp(prefix="benchmark-", suffix=".log")[1])
    started = time.perf_counter()
    load_start = _loadavg()
    ticks_start = _cpu_ticks()
    probes = [speed_probe_ms()]

    def say(msg):
        print(msg, file=sys.stderr, flush=True)

    say(f"worker log: {log_path}")
    with open(log_path, "a") as log:
        workers: dict[str, Worker] = {}
        try:
            for k in kinds:
                w = Worker(k, log)
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
                probes.append(speed_probe_ms())  # between scenes: no worker is busy
        finally:
            addon = workers.get("project").addon if "project" in workers else False
            for w in workers.values():
                w.close()

    elapsed = time.perf_counter() - started
    import numpy as np

    env = {
        "python": platform.python_version(), "numpy": np.__version__, "cpus": os.cpu_count(),
        "machine": platform.machine(), "processor": _cpu_name(), "repeats": args.repeats,
        "quick": bool(args.quick), "addon_registered": addon, "elapsed_s": elapsed,
        "loadavg": [load_start, _loadavg()] if load_start else None,
        "steal_pct": _steal_pct(ticks_start, _cpu_ticks()),
        "speed_probe_ms": probes,
        "command": " ".join(["python", "-m", "scripts.benchmark", *(argv if argv is not None else sys.argv[1:])]),
    }
    return report(args, results, env, log_path)


def report(args, results: list[dict], env: dict, log_path: Path | None) -> int:
    """Print the tables and targets of a run; write the JSON, the doc's results and the plot as asked."""
    args.quick, args.repeats = env["quick"], env["repeats"]
    elapsed = env["elapsed_s"]
    print()
    print(f"Unity Passes benchmark — {env['processor']}, {env['cpus']} CPUs, numpy {env['numpy']}, "
          f"{args.repeats} runs each (median){', QUICK sizes' if args.quick else ''}")
    if env["loadavg"]:
        print(f"load average (1, 5, 15 min): {_fmt_load(env['loadavg'][0])} at the start, "
              f"{_fmt_load(env['loadavg'][1])} at the end")
    if env.get("steal_pct") is not None:
        print(f"CPU time the virtual machine's host took (steal) during the run: {env['steal_pct']:.1f} %")
    if env.get("speed_probe_ms"):
        print(f"host speed probe: {_fmt_probes(env['speed_probe_ms'])}")
    print("times in seconds; 'project s' = extract + render; proj/GL = render / OpenGL (draw + readback); "
          "proj/EEVEE = project / EEVEE;")
    print("peak MB = peak memory allocated during render_scene (tracemalloc: numpy buffers + Python objects, "
          "untimed run); CPU = process CPU time / wall of render_scene (2.0 = both cores)")
    print()
    print(format_table(results))
    setup_lines = []
    for r in results:
        s = r["setup"]
        parts = []
        if "opengl" in s:
            gl = s["opengl"]
            parts.append(f"OpenGL upload {_fmt_t(gl['upload_s'])} s, first draw {_fmt_t(gl['first_s'])} s")
        for k in ("eevee", "workbench", "project"):
            if k in s:
                parts.append(f"{k} first run {_fmt_t(s[k]['first_s'])} s")
        if r["errors"]:
            parts.append("errors: " + "; ".join(f"{k}: {v}" for k, v in r["errors"].items()))
        setup_lines.append(f"  {r['case']['id']}: " + ", ".join(parts))
    print()
    print("Not in the medians (first runs include shader compilation; OpenGL context creation "
          f"{_fmt_t(next((r['setup']['opengl']['context_s'] for r in results if 'opengl' in r['setup']), None))} s):")
    print("\n".join(setup_lines))
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
    tg = targets(results, args.quick)
    if tg:
        print()
        print("Targets of issues 5, 14, 11, 12, 13" + (" (QUICK sizes: not the real targets)" if args.quick else "")
              + ":")
        for issue, label, fig, ok in tg:
            print(f"  [{'ok' if ok else 'MISS'}] issue {issue}: {label}: {fig}")
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
    if args.markdown:
        print()
        print(results_markdown(results, env, sc, tg, None))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps({"env": env, "results": results, "scaling": sc,
                                               "targets": tg}, indent=1, default=str))
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


RESULTS_START, RESULTS_END = "<!-- results:start -->", "<!-- results:end -->"


def results_markdown(results, env, sc, tg, plot) -> str:
    load = env.get("loadavg")
    lines = [
        f"Command: `{env['command']}`  ",
        f"Machine: {env['processor']}, {env['cpus']} CPUs; Python {env['python']}, numpy {env['numpy']}; "
        f"{env['repeats']} timed runs per backend, medians; {time.strftime('%Y-%m-%d')}; "
        f"{env['elapsed_s'] / 60:.0f} min in all."
        + (f"  \nLoad average (1, 5, 15 min) at the start {_fmt_load(load[0])}, at the end {_fmt_load(load[1])} "
           f"on {env['cpus']} CPUs: the machine was shared, absolute times are noisy; ratios come from "
           "alternating runs." if load else "")
        + (f" The host took {env['steal_pct']:.1f} % of the CPU time during the run (steal)."
           if env.get("steal_pct") is not None else "")
        + (f" Host speed probe: {_fmt_probes(env['speed_probe_ms'])}." if env.get("speed_probe_ms") else ""),
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
        lines += ["| issue | target | figure | met |", "|---|---|---|---|"]
        lines += [f"| {issue} | {label} | {fig} | {'yes' if ok else '**no**'} |" for issue, label, fig, ok in tg]
        lines.append("")
    if sc:
        lines.append("Log-log slope of the median time (1.0 = linear): "
                     + ", ".join(f"{k} {v:.2f}" for k, v in sc.items()) + ".")
        lines.append("")
    if plot:
        lines += [f"![benchmark plot]({os.path.relpath(Path(plot).resolve(), REPO / 'docs')})", ""]
    return "\n".join(lines)


def write_doc(doc: Path, results, env, sc, tg, plot) -> None:
    text = doc.read_text() if doc.exists() else f"# Benchmark\n\n{RESULTS_START}\n{RESULTS_END}\n"
    if RESULTS_START not in text or RESULTS_END not in text:
        text = text.rstrip("\n") + f"\n\n{RESULTS_START}\n{RESULTS_END}\n"
    head, rest = text.split(RESULTS_START, 1)
    _, tail = rest.split(RESULTS_END, 1)
    body = results_markdown(results, env, sc, tg, plot)
    doc.write_text(f"{head}{RESULTS_START}\n{body}\n{RESULTS_END}{tail}")


def _cpu_ticks() -> list[int] | None:
    """All CPUs' time counters of /proc/stat (user, nice, system, idle, iowait, irq, softirq,
    steal, ...), or None where there is no such file."""
    try:
        with open("/proc/stat") as f:
            return [int(v) for v in f.readline().split()[1:]]
    except (OSError, ValueError):
        return None


def _steal_pct(start: list[int] | None, end: list[int] | None) -> float | None:
    """Percent of the CPU time between two :func:`_cpu_ticks` that a hypervisor gave to others."""
    if not start or not end or len(start) < 8 or len(end) < 8:
        return None
    total = sum(end[:8]) - sum(start[:8])
    return 100.0 * (end[7] - start[7]) / total if total > 0 else None


def speed_probe_ms(samples: int = 5) -> float:
    """Milliseconds of a fixed single-thread workload like the renderer's, the median of
    ``samples``: an interpreter loop, numpy operations on 100k-element arrays (in cache) and
    two passes over 32 MB arrays (memory bandwidth). Steal and load average miss the slow
    phases of a shared host (the same render took up to 1.5x as long for minutes at a time
    with no steal); this probe shows much of them."""
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


def _fmt_probes(probes: list[float]) -> str:
    """'12.3 ms median, 11.9–14.0 ms over 6 samples (start and between scenes; lower is faster)'."""
    import numpy as np

    return (f"{np.median(probes):.1f} ms median, {min(probes):.1f}–{max(probes):.1f} ms over {len(probes)} "
            "samples (start and between scenes; lower is faster)")


def _loadavg() -> list[float] | None:
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except OSError:
        return None


def _fmt_load(load) -> str:
    return ", ".join(f"{v:.1f}" for v in load) if load else "-"


def _cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


if __name__ == "__main__":
    if not __package__:  # run as a file: the repository root (addon, tests) is not importable
        sys.exit("error: run the benchmark from the repository root as: python -m scripts.benchmark [options]")
    sys.exit(main())
