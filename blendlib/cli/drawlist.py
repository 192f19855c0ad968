"""``python -m blendlib drawlist``: the draw calls of a frame with their statistics (docs/framedebugger.md)."""

from __future__ import annotations

import argparse
import json

from .common import CliError, add_scene_arguments, load_draw_scene

EPILOG = """\
examples:
  python -m blendlib drawlist scene.blend
  python -m blendlib drawlist scene.blend --json --frame 12 --scene Scene.001

Each draw call is one pass of one renderer (an object's material slot), numbered from 1 in the
order Unity draws them. triangles: drawn after culling; fragments: rasterised (before any test);
written: passed alpha test, stencil and depth (what an occlusion query counts). The file is only
read; the scene is rendered once.
"""


def add_parser(sub) -> None:
    r = sub.add_parser("drawlist", help="list the draw calls of a frame with their statistics",
                       description="The draw calls of the active (or named) scene, in draw order.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(r)
    r.add_argument("--json", action="store_true", help="one JSON list on stdout instead of a table")
    r.set_defaults(func=run)


def table(rows: list[list[str]], right: set[int]) -> str:
    """Rows of cells as aligned text (columns in ``right`` aligned right)."""
    widths = [max(len(r[c]) for r in rows) for c in range(len(rows[0]))]
    lines = []
    for r in rows:
        cells = [cell.rjust(w) if c in right else cell.ljust(w)
                 for c, (cell, w) in enumerate(zip(r, widths, strict=True))]
        lines.append("  ".join(cells).rstrip())
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from ..core.records import RenderCancelled
    from ..core.scene import SceneError
    from ..explain import framedebug as fd

    draw = load_draw_scene(args)
    try:
        stats = fd.draw_list(draw)
    except SceneError as exc:
        raise CliError(str(exc)) from None
    except RenderCancelled:
        raise CliError("cancelled") from None
    items = fd.draw_list_json(stats)
    if args.json:
        print(json.dumps(items))
        return 0
    rows = [["#", "queue", "distance", "object", "slot", "material", "pass", "triangles", "fragments", "written",
             "state"]]
    for i in items:
        rows.append([str(i["index"]), str(i["queue"]), f"{i['distance']:.3f}", i["object"], str(i["slot"]),
                     i["material"], f"{i['pass']} {i['pass_name']}", str(i["triangles"]), str(i["fragments"]),
                     str(i["written"]), i["state"]])
    print(table(rows, right={0, 1, 2, 4, 7, 8, 9}))
    if not items:
        print("(no draw calls)")
    return 0
