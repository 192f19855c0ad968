"""``python -m blendlib render``: a .blend file → PNG/EXR/NPY of the frame (and its depth)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..formats import images
from .common import CliError, check_blend, check_output, open_scene, redirect_fds, require_bpy, warn

EPILOG_RENDER = """\
examples:
  python -m blendlib render scene.blend -o out.png
  python -m blendlib render scene.blend -o frame.npy --depth depth.npy --frame 12 --scene Scene.001

OUT ends in .png (8-bit RGBA of the stored frame values: sRGB-encoded in Gamma mode and in
Linear LDR, exactly what Unity's colour buffer holds), .exr (32-bit float RGBA, exact values)
or .npy (the exact float32 (H, W, 4) array, row 0 = top). The Unity settings come from the
file (Material.unity, Scene.unity); the Unity Passes add-on need not be installed.
"""



def add_parser(sub) -> None:
    r = sub.add_parser("render", help="render a .blend file to PNG/EXR/NPY",
                       description="Render the active (or named) scene of a .blend file through its camera.",
                       epilog=EPILOG_RENDER, formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("file", metavar="FILE.blend", help="the .blend file (it is only read, never saved)")
    r.add_argument("-o", "--output", required=True, metavar="OUT", help="output image: .png, .exr or .npy")
    r.add_argument("--depth", metavar="DEPTH.npy", help="also write the depth buffer (H, W) float32, 0..1 window depth")
    r.add_argument("--frame", type=int, metavar="N", help="frame number to render (default: the file's current frame)")
    r.add_argument("--scene", metavar="NAME", help="scene to render (default: the file's active scene)")
    r.add_argument("--until-draw", type=int, metavar="K",
                   help="stop after draw call K (1-based, as 'drawlist' numbers them; 0 = the cleared frame)")
    r.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    blend = Path(args.file)
    out = Path(args.output)
    check_blend(blend)
    if getattr(args, "until_draw", None) is not None and args.until_draw < 0:
        raise CliError(f"--until-draw must be 0 or more (got {args.until_draw})")
    check_output(out, "-o")
    if args.depth:
        check_output(Path(args.depth), "--depth")
    require_bpy()
    from .. import blender
    from ..core.pipeline import RenderCancelled
    from ..core.scene import SceneError

    scene = open_scene(blend, args.scene)
    try:
        with redirect_fds(2):  # F12's render-mode depsgraph (modifier render levels)
            frame = blender.render_final(scene, frame=args.frame, until_draw=getattr(args, "until_draw", None))
    except SceneError as exc:
        raise CliError(str(exc)) from None
    except RenderCancelled:
        raise CliError("render cancelled") from None
    for warning in frame.warnings:
        warn(warning)
    try:
        images.save(out, frame.color)
    except (images.ImageIOError, OSError) as exc:
        raise CliError(str(exc)) from None
    if args.depth:
        try:
            images.save(args.depth, frame.depth)
        except (images.ImageIOError, OSError) as exc:
            out.unlink(missing_ok=True)  # all or nothing
            raise CliError(str(exc)) from None
    print(out)
    if args.depth:
        print(args.depth)
    return 0
