"""``python -m blendlib analyze``: the sorted reference, sort error, inversions, overdraw and advice
(docs/sorting.md)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from ..formats import heatmap, images
from . import outputs
from .common import CliError, add_scene_arguments, check_blend, load_draw_scene, warn

EPILOG_ANALYZE = """\
examples:
  python -m blendlib analyze scene.blend --json
  python -m blendlib analyze scene.blend --reference ref.png --error err.png --overdraw od.png
  python -m blendlib analyze scene.blend --error err.npy --overdraw od.npy --frame 12 --json > report.json

The sorted reference is what a perfect per-fragment sort would show: queues up to 2500 as
Unity draws them, every surviving fragment of queues 2501-3999 applied per pixel far to near
with its own pass state (no depth writes), Overlay last. .npy outputs are the exact arrays:
the reference (H, W, 4) float32 in the frame's units, the error (H, W) float32 (8-bit steps
for LDR frames, absolute for HDR), overdraw (H, W, 2) uint32 (fragments rasterised, written).
.png outputs are heat maps with a legend (the reference as an image); the reference may also
be .exr. With --json, stdout is one JSON object: pixels, differing (pixels whose error exceeds
one step), max_error, mean_error, inversions (renderer pairs drawn out of order, most pixels
first) and advice (a checked change for each pair). See docs/sorting.md.
"""


def add_parser(sub) -> None:
    r = sub.add_parser("analyze", help="sorted reference, sort errors, inversions, overdraw and advice",
                       description="Compare the frame Unity draws with the per-fragment sorted reference.",
                       epilog=EPILOG_ANALYZE, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(r)
    r.add_argument("--reference", metavar="REF", help="write the sorted reference: .png, .exr or .npy")
    r.add_argument("--error", metavar="ERR", help="write the sort error: .png (heat map) or .npy")
    r.add_argument("--overdraw", metavar="OD", help="write the overdraw: .png (heat maps) or .npy")
    r.add_argument("--json", action="store_true", help="print the summary as one JSON object on stdout")
    r.add_argument("--advice", type=int, default=5, metavar="N",
                   help="check advice for the N largest inversion pairs (default 5; 0: none)")
    r.set_defaults(func=run)


def output_arrays(result, reference: Path | None, error: Path | None,
                  overdraw: Path | None) -> list[tuple[Path, object]]:
    """(path, array) of every requested output, in order."""
    todo = []
    if reference is not None:
        todo.append((reference, result.reference))
    if error is not None:
        if error.suffix.lower() == ".npy":
            todo.append((error, result.error))
        else:
            unit = "absolute error (HDR)" if result.hdr else "error in 8-bit steps"
            todo.append((error, heatmap.heat_image(result.error, unit)))
    if overdraw is not None:
        if overdraw.suffix.lower() == ".npy":
            todo.append((overdraw, result.overdraw))
        else:
            todo.append((overdraw, heatmap.heat_panels([(result.overdraw[..., 0], "rasterised"),
                                                        (result.overdraw[..., 1], "written")], "fragments per pixel",
                                                       integer=True)))
    return todo


def text_summary(summary: dict) -> str:
    unit = "" if summary["error_unit"] == "absolute" else " steps"
    lines = [f"differing pixels: {summary['differing']} of {summary['pixels']} "
             f"(max error {summary['max_error']:g}{unit}, mean {summary['mean_error']:.4g}{unit})"]
    for inv in summary["inversions"][:10]:
        who = (f"{inv['front']} over itself" if (inv["front"], inv["front_slot"]) == (inv["behind"], inv["behind_slot"])
               else f"{inv['front']} (slot {inv['front_slot']}) before {inv['behind']} (slot {inv['behind_slot']})")
        lines.append(f"inversion: {who}: {inv['pixels']} pixels")
    lines += [f"advice: {item['text']}" for item in summary["advice"]]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    blend = Path(args.file)
    check_blend(blend)
    reference = Path(args.reference) if args.reference else None
    error = Path(args.error) if args.error else None
    overdraw = Path(args.overdraw) if args.overdraw else None
    if reference is not None:
        outputs.check_target(reference, "--reference", images.FORMATS)
    if error is not None:
        outputs.check_target(error, "--error", (".png", ".npy"))
    if overdraw is not None:
        outputs.check_target(overdraw, "--overdraw", (".png", ".npy"))
    if args.advice < 0:
        raise CliError("--advice must be 0 or more")
    named = {"--reference": reference, "--error": error, "--overdraw": overdraw}
    outputs.check_distinct({"FILE.blend": blend, **{k: v for k, v in named.items() if v is not None}})
    from ..blender.vrm_addon import advice_settings
    from ..core.records import RenderCancelled
    from ..core.scene import SceneError
    from ..explain.advice import analyze_and_advise
    from ..runtime.forked import ForkedMap

    draw = load_draw_scene(args)
    try:
        result = analyze_and_advise(draw, max_advice=args.advice, settings=advice_settings(), measure_map=ForkedMap())
    except SceneError as exc:
        raise CliError(str(exc)) from None
    except RenderCancelled:
        raise CliError("render cancelled") from None
    for warning in dict.fromkeys(w for w in result.frame.warnings if w not in draw.warnings):
        warn(warning)
    todo = output_arrays(result, reference, error, overdraw)
    outputs.commit(todo)  # every output or none
    summary = result.summary()
    if args.json:
        print(json.dumps(summary, indent=1, allow_nan=False, default=_plain))
    else:
        print(text_summary(summary))
        for path, _ in todo:
            print(path)
    return 0


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
