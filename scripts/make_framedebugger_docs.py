"""Write docs/framedebugger.md and its pictures (docs/framedebugger/*.png) from blend_files/self_overlap.blend.

    .venv/bin/python scripts/make_framedebugger_docs.py [--out docs]

Everything shown is computed here by the frame debugger (blendlib.explain.framedebug): the draw
list, the frames after draw calls, the picked pixel and its history.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from blendlib import blender  # noqa: E402
from blendlib.blender.framedebug import buffer_rgba  # noqa: E402
from blendlib.core.pipeline import FrameObserver  # noqa: E402
from blendlib.explain import framedebug as fd  # noqa: E402
from blendlib.formats import images  # noqa: E402

BLEND = ROOT / "blend_files" / "self_overlap.blend"


class _Depths(FrameObserver):
    """Fragments per pixel of one draw call (to find candidate pixels where strands overlap)."""

    def __init__(self, draw: int, size: int):
        import threading

        self.draw, self.lock = draw, threading.Lock()
        self.count = np.zeros(size, dtype=np.int64)

    def fragments(self, call, frags, outcome):
        if call.index == self.draw:
            with self.lock:
                np.add.at(self.count, frags.pix, 1)


def _mark(rgba: np.ndarray, x: int, y: int, r: int = 6) -> np.ndarray:
    """A magenta square outline of radius ``r`` around (x, y) (row 0 = top)."""
    out = rgba.copy()
    h, w = out.shape[:2]
    for d in range(-r, r + 1):
        for px, py in ((x + d, y - r), (x + d, y + r), (x - r, y + d), (x + r, y + d)):
            if 0 <= px < w and 0 <= py < h:
                out[py, px] = (1.0, 0.0, 1.0, 1.0)
    return out


def _rgba(values) -> str:
    return " ".join(f"{v:.3f}" for v in values)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs"), help="docs folder (default: docs/)")
    args = parser.parse_args()
    docs = Path(args.out)
    pictures = docs / "framedebugger"
    pictures.mkdir(parents=True, exist_ok=True)

    blender.open_blend(BLEND)
    scene = blender.scene_named(None, where=BLEND)
    draw_scene = blender.draw_scene_final(scene)
    cap = fd.FrameCapture.capture(draw_scene)
    w, h = draw_scene.camera.width, draw_scene.camera.height
    blend = next(s for s in cap.stats if s.call.renderer.name == "Knot Left")
    k = blend.call.index

    # Candidate pixels: the most overlapped pixels of the blend pass; the first whose history shows a
    # farther fragment of the knot blended after a nearer one is the example.
    watch = _Depths(k, w * h)
    from blendlib.core.pipeline import render_scene

    render_scene(draw_scene, observer=watch)
    overlapped = np.flatnonzero(watch.count >= 2)
    picks = overlapped[np.linspace(0, overlapped.size - 1, min(1500, overlapped.size)).astype(np.int64)]
    candidates = [(int(p % w), int(h - 1 - p // w)) for p in picks]
    histories, _ = fd.pixel_histories(draw_scene, candidates)
    chosen, pair, gap = None, None, 0
    for hist in histories:
        own = [f for f in hist.fragments if f.call.index == k and f.result == "written"]
        for i, near in enumerate(own):
            for far in own[i + 1:]:
                if far.depth_code - near.depth_code > gap:
                    chosen, pair, gap = hist, (near, far), far.depth_code - near.depth_code
    if chosen is None:
        raise SystemExit("error: no pixel of the blend pass shows a far strand blended over a near one")
    x, y = chosen.x, chosen.y

    before, _ = cap.frame_after(k - 1)
    after, mask = cap.frame_after(k, highlight=True)
    files = {
        "before.png": buffer_rgba(before, "COLOR")[0],
        "highlight.png": buffer_rgba(after, "COLOR", mask)[0],
        "after.png": _mark(buffer_rgba(after, "COLOR")[0], x, y),
        "depth.png": buffer_rgba(cap.frame, "DEPTH")[0],
    }
    for name, rgba in files.items():
        images.save(pictures / name, rgba)

    table = ["| # | queue | object | pass | triangles | fragments | written | state |",
             "|---|---|---|---|---|---|---|---|"]
    for s in cap.stats:
        j = s.to_json()
        table.append(f"| {j['index']} | {j['queue']} | {j['object']} | {j['pass']} {j['pass_name']} | "
                     f"{j['triangles']} | {j['fragments']} | {j['written']} | `{j['state']}` |")
    hist_rows = ["| draw | object | triangle | face | depth | source | before | after | result |",
                 "|---|---|---|---|---|---|---|---|---|"]
    for f in chosen.fragments:
        face = "-" if f.polygon is None else f.polygon
        hist_rows.append(f"| {f.call.index} | {f.call.renderer.name} | {f.triangle} | {face} | {f.depth:.6f} | "
                         f"{_rgba(f.source)} | {_rgba(f.before)} | {_rgba(f.after)} | {f.result} |")
    near, far = pair
    text = f"""# Frame debugger walkthrough: why does the knot look wrong?

Generated by `scripts/make_framedebugger_docs.py` from `blend_files/self_overlap.blend`
({w}x{h}); every number and picture below is computed by the frame debugger
(`blendlib.explain.framedebug`, SPEC §8).

The file shows two copies of a self-overlapping knot with a semi-transparent material. The left
one ("Knot ZWrite Off", the plain *Alpha Blend* preset) looks wrong: strands that lie behind
others show through on top of them. The right one ("Knot Prepass") draws a depth-only pass first.

## 1. The draw list

`python -m blendlib drawlist blend_files/self_overlap.blend` (or Capture in the Image Editor's
sidebar, tab *Unity*, panel *Unity Frame Debugger*) lists every draw call:

{chr(10).join(table)}

Draw {k} is the left knot's only pass: `{blend.call.state.shaderlab()}`. It writes all of its
{blend.fragments} fragments ({blend.written} written): nothing is rejected, because the pass does not
write depth, so every layer of the knot lands on the frame in the order of its triangles.

## 2. Step to the blend pass

Moving the draw slider to {k - 1} shows the frame before the knot (left), then {k} with *Highlight
Draw* on (right): the magenta pixels are those draw {k} rasterised.

| after draw {k - 1} | after draw {k}, highlighted |
|---|---|
| ![before](framedebugger/before.png) | ![highlight](framedebugger/highlight.png) |

The slider does not re-render from scratch: the capture keeps snapshots of the buffers every
{cap.interval} draw(s) (at most {fd.SNAPSHOT_MEMORY // 2**20} MB) and replays from the nearest one.

## 3. Pick a pixel where a far strand is blended over a near one

Pixel ({x}, {y}) (X from the left, Y from the top; the magenta square below) lies where two strands
of the left knot overlap (of 1500 overlapped pixels sampled, the one where a later fragment lies
farthest behind an earlier one). Its history
(`python -m blendlib pixel blend_files/self_overlap.blend {x} {y}`, or *Pick Pixel* in the panel):

![the picked pixel](framedebugger/after.png)

{chr(10).join(hist_rows)}

Clear colour {_rgba(chosen.clear)}; final colour {_rgba(chosen.final)} (equal to the frame's pixel).

## 4. Read the history

Draw {k} reaches this pixel {len([f for f in chosen.fragments if f.call.index == k])} times. Its
triangle {near.triangle} (face {near.polygon}, depth {near.depth:.6f}) belongs to the near strand;
triangle {far.triangle} (face {far.polygon}, depth {far.depth:.6f}) — the strand *behind* it — comes
later in the mesh's triangle order, and with `ZWrite Off` nothing stops it: it is blended *over*
the nearer strand (compare its `before` and `after`). That is the sorting error
inside one draw call that Unity's own Frame Debugger cannot show (it stops only between draw
calls), and that a GPU pixel history has trouble with when several primitives of one draw call
hit one pixel. Here the order is exact: draw order, then primitive order.

Fixes: a depth prepass (the right knot: its first pass writes depth with `ColorMask 0`, so the
blend pass's far fragments fail the depth test — `result` `depth` in its pixel histories), or split
the mesh, or reorder its triangles. The depth buffer after the frame (near dark, far white) shows the
prepass's depth on the right and none for the left knot:

![depth](framedebugger/depth.png)
"""
    (docs / "framedebugger.md").write_text(text, encoding="utf-8")
    print(docs / "framedebugger.md")
    for name in files:
        print(pictures / name)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
