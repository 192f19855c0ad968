#!/usr/bin/env python3
"""Benchmark: the project's renderer against OpenGL (Mesa llvmpipe), EEVEE and Workbench.

    .venv/bin/python -m scripts.benchmark                      # the full run (docs/benchmark.md)
    .venv/bin/python -m scripts.benchmark --quick              # small sizes, a smoke run
    .venv/bin/python -m scripts.benchmark --scenes S1,S4 --repeats 5 --json out.json --plot docs/benchmark.png

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


def plan_cases(args) -> list[dict]:
    """The cases to run, in order. Each is a plain dict (sent as JSON to the workers)."""
    quick = args.quick
    wanted = {s.strip().upper() for s in args.scenes.split(",") if s.strip()}
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
    if "S3" in wanted:
        blend_dir = Path(args.blend_dir)
        files = sorted(blend_dir.glob("*.blend")) if blend_dir.is_dir() else []
        size = (320, 180) if quick else (1280, 720)
        for f in files:
            cases.append(dict(id=f"S3:{f.stem}", group="S3", kind="blend", path=str(f.resolve()),
                              width=size[0], height=size[1], label=f"blend_files/{f.name}"))
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

    def traced_peak(self) -> float:
        """Peak of the memory allocated during one (untimed) ``render_scene`` call, in MiB: Python
        objects and numpy buffers (numpy reports its data allocations to tracemalloc), the frame
        included, the input DrawScene excluded."""
        import tracemalloc

        from blendlib import blender
        from blendlib.core.pipeline import render_scene

        draw = blender.build_draw_scene(self.scene)
        tracemalloc.start()
        try:
            base = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
            frame = render_scene(draw, **self._kwargs())
            peak = tracemalloc.get_traced_memory()[1] - base
            del frame
        finally:
            tracemalloc.stop()
        return peak / 2**20

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
        from blendlib.core.pipeline import render_scene

        kwargs = self._kwargs()
        with Timer() as te:
            draw = blender.build_draw_scene(self.scene)
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


def format_table(results: list[dict], markdown: bool = False) -> str:
    rows = table_rows(results)
    if markdown:
        lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "|".join("---" for _ in COLUMNS) + "|"]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        return "\n".join(lines)
    widths = [max(len(c), *(len(r[i]) for r in rows)) if rows else len(c) for i, c in enumerate(COLUMNS)]
    fmt = "  ".join(f"{{:{'<' if i == 0 else '>'}{w}}}" for i, w in enumerate(widths))
    lines = [fmt.format(*COLUMNS), fmt.format(*("-" * w for w in widths))]
    lines += [fmt.format(*r) for r in rows]
    return "\n".join(lines)


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


def targets(results: list[dict], quick: bool) -> list[tuple[str, str, bool | None]]:
    """(target, figure, met?) lines of issue 5."""
    by_id = {r["case"]["id"]: r for r in results}
    out = []
    for sid, limit in (("S1", 8), ("S2", 10), ("S4", 5)):
        r = by_id.get(sid)
        if r and r["ratio_gl"] is not None:
            out.append((f"{sid} render within {limit}x of OpenGL/llvmpipe", _fmt_x(r["ratio_gl"]),
                        r["ratio_gl"] <= limit))
    s3 = [r for r in results if r["case"]["group"] == "S3" and r["ratio_eevee"] is not None]
    for r in s3:
        out.append((f"{r['case']['id']} faster than EEVEE (1 sample)", _fmt_x(r["ratio_eevee"]), r["ratio_eevee"] < 1))
    r = by_id.get("S4")
    p = r and r["median"].get("project")
    if p:
        tris = r["setup"]["project"]["triangles"]
        out.append((f"extraction of the {_fmt_n(tris)}-triangle evaluated mesh under 0.3 s",
                    f"{p['extract_s']:.3f} s", p["extract_s"] < 0.3))
        out.append(("S4 peak memory of the render under 2 GB",
                    f"{p['peak_mb']:.0f} MB allocated (whole worker process incl. Blender and the scene: "
                    f"{p.get('rss_mb', 0):.0f} MB RSS)", p["peak_mb"] < 2048))
    sc = scaling_summary(results)
    for key, label in (("scale-tris/project", "triangles"), ("scale-res/project", "covered pixels")):
        if key in sc:
            out.append((f"cost grows at most linearly with {label} (log-log slope <= 1.1)",
                        f"{sc[key]:.2f}", sc[key] <= 1.1))
    big = [r for r in results if r["case"]["width"] * r["case"]["height"] >= 1920 * 1080
           and r["median"].get("project")]
    if big:
        cpu = median([r["median"]["project"]["cpu_ratio"] for r in big])
        out.append(("both CPU cores busy on large frames (median CPU time / wall >= 1.5)", f"{cpu:.2f}", cpu >= 1.5))
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
    """Three panels: time vs triangles and time vs covered pixels (log-log, the scaling groups),
    and every scene's total time per backend (log bars). Written atomically as PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from blendlib.formats.atomic import write_atomic

    path.parent.mkdir(parents=True, exist_ok=True)
    tri = _scaling_series(results, "scale-tris", "triangles")
    res = _scaling_series(results, "scale-res", "covered_px")
    bars = [r for r in results if r["case"]["group"] in ("S1", "S2", "S3", "S4")]
    fig = Figure(figsize=(16, 5))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 3)
    for ax, series, xl, t in ((axes[0], tri, "triangles", "time vs triangles (1080p)"),
                              (axes[1], res, "covered pixels", "time vs covered pixels (200k tris)")):
        for name, color, s in series:
            ax.loglog(*zip(*s, strict=True), "o-", color=color, label=name)
        ax.set_xlabel(xl)
        ax.set_ylabel("seconds (median)")
        ax.set_title(t)
        ax.grid(True, which="both", alpha=0.3)
        if series:
            ax.legend()
    ax = axes[2]
    names = [r["case"]["id"] for r in bars]
    for j, (kind, _key, color) in enumerate(SERIES):
        vals = [(r["median"].get(kind) or {}).get("total_s") or 0 for r in bars]
        ax.bar([i + j * 0.2 for i in range(len(bars))], vals, 0.2, color=color, label=kind)
    ax.set_xticks([i + 0.3 for i in range(len(bars))], names, rotation=30, ha="right")
    ax.set_yscale("log")
    ax.set_ylabel("seconds (median)")
    ax.set_title("scenes: total time")
    if bars:
        ax.legend()
    fig.suptitle(title)
    fig.text(0.5, 0.01, "project = render_scene in the first two plots, extraction + render in the third",
             ha="center", fontsize=9)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    write_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=80))
    return path


# ---------------------------------------------------------------------------------------------
# main
# ---------------------------------------------------------------------------------------------


def parse_args(argv=None):
    ap = argparse.ArgumentParser(prog="python -m scripts.benchmark", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small sizes (a smoke run of a minute or so)")
    ap.add_argument("--scenes", default="S1,S2,S3,S4,scaling",
                    help="comma-separated subset of S1,S2,S3,S4,scaling (default: all)")
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
                    help="after the timed runs, cProfile one project render of S1, S2, S4 (workers=1) "
                         "and print the top N functions by own time")
    ap.add_argument("--log", default=None, help="worker log file (default: a temporary file, path printed)")
    ap.add_argument("--worker", choices=BACKENDS, help=argparse.SUPPRESS)
    return ap.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.worker:
        return worker_main(args.worker)
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
                profile = args.profile if case["group"] in ("S1", "S2", "S4") else 0
                results.append(run_case(case, workers, args.repeats, say, profile))
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
        "command": " ".join(["python", "-m", "scripts.benchmark", *(argv if argv is not None else sys.argv[1:])]),
    }
    print()
    print(f"Unity Passes benchmark — {env['processor']}, {env['cpus']} CPUs, numpy {env['numpy']}, "
          f"{args.repeats} runs each (median){', QUICK sizes' if args.quick else ''}")
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
    tg = targets(results, args.quick)
    if tg:
        print()
        print("Targets of issue 5" + (" (QUICK sizes: not the real targets)" if args.quick else "") + ":")
        for label, fig, ok in tg:
            print(f"  [{'ok' if ok else 'MISS'}] {label}: {fig}")
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
        print(format_table(results, markdown=True))
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
    print(f"\n({elapsed:.0f} s in all; worker log {log_path})")
    failed = any(r["errors"].get("project") for r in results)
    return 1 if failed else 0


RESULTS_START, RESULTS_END = "<!-- results:start -->", "<!-- results:end -->"


def results_markdown(results, env, sc, tg, plot) -> str:
    lines = [
        f"Command: `{env['command']}`  ",
        f"Machine: {env['processor']}, {env['cpus']} CPUs; Python {env['python']}, numpy {env['numpy']}; "
        f"{env['repeats']} timed runs per backend, medians; {time.strftime('%Y-%m-%d')}; "
        f"{env['elapsed_s'] / 60:.0f} min in all.",
        "",
        format_table(results, markdown=True),
        "",
    ]
    if tg:
        lines += ["| target (issue 5) | figure | met |", "|---|---|---|"]
        lines += [f"| {label} | {fig} | {'yes' if ok else '**no**'} |" for label, fig, ok in tg]
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
