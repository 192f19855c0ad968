"""``python -m blendlib pixel``: every fragment that touched one pixel, in order (docs/framedebugger.md)."""

from __future__ import annotations

import argparse
import json

from .common import CliError, add_scene_arguments, load_draw_scene
from .drawlist import table

EPILOG = """\
examples:
  python -m blendlib pixel scene.blend 120 64
  python -m blendlib pixel scene.blend 120 64 --json --frame 12

X is the column from the left, Y the row from the top (as in the rendered image). Every fragment
rasterised at the pixel is listed in the order the pipeline applies it (draw order, then the
mesh's triangle order) with its depth, the shader's colour, the pixel before and after it (stored
values: 8-bit codes / 255 in LDR), and its result: written, or the test that discarded it
(alpha_test, stencil, depth). A pixel nothing touched has an empty history.
"""


def add_parser(sub) -> None:
    r = sub.add_parser("pixel", help="the history of one pixel: every fragment, each test, before and after",
                       description="The history of pixel (X, Y) of the active (or named) scene.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(r, after_file=(
        ("x", dict(type=int, metavar="X", help="column, from the left (0-based)")),
        ("y", dict(type=int, metavar="Y", help="row, from the top (0-based)"))))
    r.add_argument("--json", action="store_true", help="one JSON object on stdout instead of a table")
    r.set_defaults(func=run)


def _rgba(values) -> str:
    return "(" + " ".join(f"{v:.4f}" for v in values) + ")"


def run(args: argparse.Namespace) -> int:
    from ..core.records import RenderCancelled
    from ..core.scene import SceneError
    from ..explain import framedebug as fd

    draw = load_draw_scene(args)
    try:
        history = fd.pixel_history(draw, args.x, args.y)
    except SceneError as exc:
        raise CliError(str(exc)) from None
    except RenderCancelled:
        raise CliError("cancelled") from None
    data = history.to_json()
    if args.json:
        print(json.dumps(data))
        return 0
    print(f"pixel X={data['x']} Y={data['y']} (from the top-left) of {draw.camera.width}x{draw.camera.height}: "
          f"clear {_rgba(data['clear'])}, final {_rgba(data['final'])}")
    if not data["fragments"]:
        print("no fragment touched this pixel")
        return 0
    rows = [["draw", "object", "slot", "pass", "triangle", "polygon", "depth", "source", "before", "after",
             "depth after", "stencil", "result"]]
    for f in data["fragments"]:
        rows.append([str(f["draw"]), f["object"], str(f["slot"]), f"{f['pass']} {f['pass_name']}", str(f["triangle"]),
                     "-" if f["polygon"] is None else str(f["polygon"]), f"{f['depth']:.6f}", _rgba(f["source"]),
                     _rgba(f["before"]), _rgba(f["after"]), f"{f['depth_after']:.6f}",
                     f"{f['stencil_before']}->{f['stencil_after']}", f["result"]])
    print(table(rows, right={0, 2, 4, 5, 6, 10}))
    return 0
