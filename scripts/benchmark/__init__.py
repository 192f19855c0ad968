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
medians. Only one worker runs at a time. docs/benchmark.md describes every series.

The package, one concern per module:

- ``cases``: what a run measures (the cases, plain dicts; no bpy, the parent plans with it);
- ``scenes``: a case's Blender scene, built in a worker with :mod:`scripts.scenekit`;
- ``workers``: the four backends' workers, their JSON-lines protocol and the parent's handle;
- ``timing``: how a call is measured (wall and CPU time, resident and traced memory peaks);
- ``host``: the machine during the run (load average, steal, a speed probe, the CPU's name);
- ``tables``, ``targets``, ``report``, ``plot``: the figures as tables, checked against their
  targets, printed and written into docs/benchmark.md, and drawn;
- ``cli``: the command line and the run (``python -m scripts.benchmark``).
"""
