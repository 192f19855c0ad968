"""Frame hashes: the proof that a refactor or a speed-up left every frame bit for bit as it was.

    python -m scripts.frame_hashes build DIR              # extract the scenes once (needs bpy), pickle into DIR
    python -m scripts.frame_hashes hash DIR -o A.json     # render each (one thread and two) and hash the buffers
    python -m scripts.frame_hashes compare A.json B.json  # every key equal, or the ones that differ

``build`` pickles :class:`~blendlib.core.scene.DrawScene` objects: every scene of every
``blend_files/`` file at 1280x720 (S3) and at the viewport's 960x540 and 240x135 through the
scene camera, and the benchmark's S1, S2, S2p and S4 at 1920x1080. ``hash`` renders each with
one worker thread and two and hashes colour, depth and stencil; for the S3 scenes at 720p it
also hashes what the tools that explain a frame return (the draw list JSON, a few pixel
histories, the sorted reference, sort error, overdraw, inversions and advice). Pickles are
bound to the classes they hold: rebuild them after the data model changes (the hashes of
frames are unaffected by that as long as the rendering is).

Hashes depend on the machine's numpy build; compare runs made on one machine.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import pickle
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
S3_SIZES = ((1280, 720), (960, 540), (240, 135))
BIG_CASES = (dict(id="S1", kind="sphere", k=224, width=1920, height=1080, fill=1 / 3),
             dict(id="S2", kind="planes", count=50, width=1920, height=1080),
             dict(id="S2p", kind="planes-perspective", count=50, width=1920, height=1080),
             dict(id="S4", kind="monkey", levels=5, width=1920, height=1080))


def build(out_dir: Path, blend_dir: Path) -> int:
    import bpy

    from blendlib.blender import build_draw_scene
    from scripts.benchmark.scenes import build_case

    out_dir.mkdir(parents=True, exist_ok=True)
    n = 0
    for path in sorted(blend_dir.glob("*.blend")):
        bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
        for scene in list(bpy.data.scenes):
            if scene.camera is None:
                continue
            for w, h in S3_SIZES:
                scene.render.resolution_x, scene.render.resolution_y = w, h
                scene.render.resolution_percentage = 100
                draw = build_draw_scene(scene)
                name = f"S3-{path.stem}-{scene.name}-{w}x{h}"
                (out_dir / f"{name}.pkl").write_bytes(pickle.dumps(draw, protocol=5))
                n += 1
    for case in BIG_CASES:
        scene = build_case(case)
        (out_dir / f"{case['id']}.pkl").write_bytes(pickle.dumps(build_draw_scene(scene), protocol=5))
        n += 1
    print(f"{n} scenes pickled into {out_dir}")
    return 0


def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:20]


def _json_digest(value) -> str:
    return hashlib.sha256(json.dumps(value, sort_keys=True, default=str).encode()).hexdigest()[:20]


def _explain(draw, key: str, out: dict) -> None:
    from blendlib.explain import advice, framedebug

    stats = framedebug.draw_list(draw)
    out[f"{key} drawlist"] = _json_digest(framedebug.draw_list_json(stats))
    w, h = int(draw.camera.width), int(draw.camera.height)
    pixels = [(w // 2, h // 2), (w // 3, h // 4), (2 * w // 3, 3 * h // 4), (5, 5)]
    histories, frame = framedebug.pixel_histories(draw, pixels)
    out[f"{key} pixels"] = _json_digest([hist.to_json() for hist in histories])
    out[f"{key} pixels frame"] = _digest(frame.color, frame.depth, frame.stencil)
    analysis = advice.analyze_and_advise(draw, max_advice=2)
    out[f"{key} analyze"] = _digest(analysis.frame.color, analysis.reference, analysis.error, analysis.overdraw,
                                    analysis.inverted)
    out[f"{key} analyze summary"] = _json_digest(analysis.summary())


def hash_dir(scene_dir: Path, out_path: Path | None, explain: bool) -> int:
    from blendlib.core.pipeline import render_scene

    out: dict[str, str] = {}
    started = time.perf_counter()
    for path in sorted(scene_dir.glob("*.pkl")):
        draw = pickle.loads(path.read_bytes())
        for workers in (1, 2):
            frame = render_scene(draw, workers=workers)
            out[f"{path.stem} w{workers}"] = _digest(frame.color, frame.depth, frame.stencil)
            out[f"{path.stem} w{workers} warnings"] = _json_digest(frame.warnings)
        if explain and path.stem.startswith("S3-") and path.stem.endswith("1280x720"):
            _explain(draw, path.stem, out)
        print(f"  {path.stem}", file=sys.stderr)
    text = json.dumps(out, indent=1, sort_keys=True)
    if out_path is None:
        print(text)
    else:
        out_path.write_text(text + "\n")
    frames = sum(1 for k in out if k.endswith(("w1", "w2")))
    print(f"{frames} frames, {len(out)} hashes in {time.perf_counter() - started:.0f} s", file=sys.stderr)
    return 0


def compare(a: Path, b: Path) -> int:
    x, y = json.loads(a.read_text()), json.loads(b.read_text())
    differ = sorted(k for k in set(x) | set(y) if x.get(k) != y.get(k))
    for k in differ:
        print(f"differs: {k}: {x.get(k)} vs {y.get(k)}")
    print(f"{len(set(x) & set(y)) - len([k for k in differ if k in x and k in y])} equal, {len(differ)} differ")
    return 1 if differ else 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m scripts.frame_hashes", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    b = sub.add_parser("build", help="pickle the scenes (needs bpy)")
    b.add_argument("dir", type=Path)
    b.add_argument("--blend-dir", type=Path, default=REPO / "blend_files")
    hsh = sub.add_parser("hash", help="render and hash the pickled scenes")
    hsh.add_argument("dir", type=Path)
    hsh.add_argument("-o", "--output", type=Path)
    hsh.add_argument("--no-explain", action="store_true", help="frames only (no draw list, pixel history, analysis)")
    c = sub.add_parser("compare", help="compare two hash files")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    args = parser.parse_args(argv)
    if args.command == "build":
        return build(args.dir, args.blend_dir)
    if args.command == "hash":
        return hash_dir(args.dir, args.output, not args.no_explain)
    return compare(args.a, args.b)


if __name__ == "__main__":
    sys.exit(main())
