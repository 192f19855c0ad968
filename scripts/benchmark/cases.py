"""What a run measures: the benchmark's cases, as plain dicts the parent sends to its workers.

A case names a scene kind (``sphere``, ``planes``, ``planes-perspective``, ``monkey``, or
``blend``: a file of ``blend_files/``), its size and, for the project worker, which series
besides the timed renders it runs (``explain``: the frame debugger and ``analyze``; ``viewport``:
the viewport's frames at that size). :func:`scripts.benchmark.scenes.build_case` turns a case
into a Blender scene inside a worker. No bpy here: the parent process plans without Blender.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
#: The example scenes: S3 is every file there (``--blend-dir``).
BLEND_DIR = REPO / "blend_files"
#: The backends, in the order their timed runs alternate: the project's renderer, the same draw
#: list through OpenGL (Mesa llvmpipe), Blender's EEVEE (1 sample) and Workbench.
BACKENDS = ("project", "opengl", "eevee", "workbench")
#: Every scene group the command line can select (``--scenes``), in run order.
SCENE_GROUPS = ("S1", "S2", "S2p", "S3", "S4", "S5", "S6", "msaa", "linear", "scaling")
#: Scene groups whose project worker also times the frame debugger and the sorted reference
#: against a plain render.
EXPLAIN_GROUPS = ("S1", "S2", "S2p", "S3", "S5", "S6")
#: The viewport series' frame size (every S3 scene through blendlib.blender.viewport), and --quick's.
VIEWPORT_SIZE, VIEWPORT_QUICK = (960, 540), (320, 180)


def sphere_k(triangles: int) -> int:
    """A UV sphere with ``2k`` segments and ``k + 1`` rings has ``2*2k*k = 4k²`` triangles."""
    return max(2, round(math.sqrt(triangles / 4.0)))


def plan_cases(scenes: str, *, quick: bool = False, blend_dir: Path | str = BLEND_DIR,
               explain: bool = True) -> list[dict]:
    """The cases of the comma-separated scene groups ``scenes`` (any of :data:`SCENE_GROUPS`,
    case-insensitive), in run order: full sizes, or ``quick``'s small ones; S3 is every ``.blend``
    in ``blend_dir``; ``explain`` adds the frame-debugger series to :data:`EXPLAIN_GROUPS`."""
    wanted = {s.strip().upper() for s in scenes.split(",") if s.strip()}  # "S2p" -> "S2P"
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
        blend_dir = Path(blend_dir)
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
    if "S5" in wanted:  # the VRM avatar example (issue 28), its first scene
        cases.append(dict(id="S5", group="S5", kind="blend", path=str((BLEND_DIR / "vrm_avatar.blend").resolve()),
                          scene="Avatar", width=full_hd[0], height=full_hd[1],
                          label="VRM avatar: hair cards, outlines, four MToon modes",
                          viewport=list(VIEWPORT_QUICK if quick else VIEWPORT_SIZE)))
    if "S6" in wanted:
        cases.append(dict(id="S6", group="S6", kind="particles", count=2_000 if quick else 20_000,
                          width=full_hd[0], height=full_hd[1],
                          label="particles: camera-facing quads, vertex colours, Alpha Blended + Additive"))
    if "MSAA" in wanted:  # the price of 4x MSAA: S1 and S2 again with 4 samples per pixel
        for base in [c for c in plan_cases("S1,S2", quick=quick, explain=False)]:
            cases.append(dict(base, id=f"{base['id']} 4x", group="msaa", msaa=4, base=base["id"],
                              label=f"{base['label']}, 4x MSAA"))
    if "LINEAR" in wanted:  # Unity's colour space for 3D projects: 8-bit writes sRGB-encode per fragment
        for base in [c for c in plan_cases("S5,S6", quick=quick, explain=False)]:
            base.pop("viewport", None)
            cases.append(dict(base, id=f"{base['id']} linear", group="linear", color_space="Linear",
                              base=base["id"], label=f"{base['label']}, Linear colour space"))
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
    if explain:
        for case in cases:
            if case["group"] in EXPLAIN_GROUPS:
                case["explain"] = True
    return cases
