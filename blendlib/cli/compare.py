"""``python -m blendlib compare``: two images (PNG/EXR/NPY) → max/mean difference, PSNR, share differing."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..formats import images
from . import outputs
from .common import CliError, warn

EPILOG_COMPARE = """\
prints max and mean absolute difference, PSNR (peak 1.0) and the share of differing pixels;
exit status 0 either way (1 only when a file cannot be read or the sizes differ).
example:
  python -m blendlib compare out.png golden.png --diff diff.png
"""




def tolerance_value(text: str) -> float:
    """``--tolerance``: a finite number >= 0 (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"tolerance must be a finite number >= 0, got {text!r}")
    return value


def add_parser(sub) -> None:
    c = sub.add_parser("compare", help="compare two images (PNG/EXR/NPY)",
                       description="Compare two images of the same size over their common channels.",
                       epilog=EPILOG_COMPARE, formatter_class=argparse.RawDescriptionHelpFormatter)
    c.add_argument("a", metavar="A", help="first image (.png, .exr or .npy)")
    c.add_argument("b", metavar="B", help="second image (.png, .exr or .npy)")
    c.add_argument("--diff", metavar="OUT.png", help="write a heat map of the per-pixel difference (legend below)")
    c.add_argument("--tolerance", type=tolerance_value, default=0.0,
                   help="a pixel counts as differing when a channel differs by more than this (default 0)")
    c.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    diff = Path(args.diff) if args.diff else None
    if diff is not None:  # before reading the images: a bad output is an error at once
        outputs.check_target(diff, "--diff", images.FORMATS)
        outputs.check_distinct({"A": Path(args.a), "B": Path(args.b), "--diff": diff})
    try:
        a = images.load(args.a)
        b = images.load(args.b)
        result = images.compare(a, b, tolerance=args.tolerance)
    except images.ImageIOError as exc:
        raise CliError(str(exc)) from None
    if diff is not None:
        outputs.commit([(diff, images.heat_map(result.per_pixel))])
    if a.ndim == 3 and b.ndim == 3 and a.shape[2] != b.shape[2]:
        warn(f"channel counts differ ({a.shape[2]} vs {b.shape[2]}); compared the first {result.channels}")
    for line in result.lines():
        print(line)
    if args.diff:
        print(f"heat map: {args.diff}")
    return 0
