"""``python -m blendlib render``: a .blend file → PNG/EXR/NPY of the frame (and its depth)."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
from pathlib import Path

from ..formats import images
from .common import (
    CliError,
    add_scene_arguments,
    check_blend,
    check_distinct,
    check_output,
    checked_frame,
    open_scene,
    redirect_fds,
    require_bpy,
    warn,
)
from .frames import check_pattern, frame_path, parse_frames
from .progress import Progress

EPILOG_RENDER = """\
examples:
  python -m blendlib render scene.blend -o out.png
  python -m blendlib render scene.blend -o frame.npy --depth depth.npy --frame 12 --scene Scene.001
  python -m blendlib render scene.blend -o out/frame_####.png --frames 1-250:10 --skip-existing

OUT ends in .png (8-bit RGBA of the stored frame values: sRGB-encoded in Gamma mode and in
Linear LDR, exactly what Unity's colour buffer holds), .exr (32-bit float RGBA, exact values)
or .npy (the exact float32 (H, W, 4) array, row 0 = top). The Unity settings come from the
file (Material.unity, Scene.unity); the Unity Passes add-on need not be installed.

--frames A-B[:STEP] renders frames A to B (inclusive) every STEP: the last run of '#' in the
output (and --depth) file name becomes the zero-padded frame number, as in Blender, and each
written file prints "Saved: '<absolute path>'" on stdout.
"""



def add_parser(sub) -> None:
    r = sub.add_parser("render", help="render a .blend file to PNG/EXR/NPY",
                       description="Render the active (or named) scene of a .blend file through its camera.",
                       epilog=EPILOG_RENDER, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(r)
    r.add_argument("-o", "--output", required=True, metavar="OUT", help="output image: .png, .exr or .npy")
    r.add_argument("--depth", metavar="DEPTH.npy", help="also write the depth buffer (H, W) float32, 0..1 window depth")
    r.add_argument("--frames", metavar="A-B[:STEP]",
                   help="render frames A..B (inclusive) every STEP; '#' in OUT becomes the frame number")
    r.add_argument("--skip-existing", action="store_true",
                   help="do not render frames whose output file already exists")
    r.add_argument("--until-draw", type=int, metavar="K",
                   help="stop after draw call K (1-based, as 'drawlist' numbers them; 0 = the cleared frame)")
    r.set_defaults(func=run)


@contextlib.contextmanager
def sigint_cancels():
    """Ctrl+C during the render: Blender's render operator swallows KeyboardInterrupt, so SIGINT
    sets a flag that the render polls (``should_cancel``); KeyboardInterrupt is raised after it."""
    interrupted: list[bool] = []

    def on_sigint(signum, frame):
        interrupted.append(True)

    try:
        previous = signal.signal(signal.SIGINT, on_sigint)
    except ValueError:  # not the main thread: no signal handling to change
        yield lambda: False
        return
    try:
        yield lambda: bool(interrupted)
    finally:
        signal.signal(signal.SIGINT, previous)
    if interrupted:
        raise KeyboardInterrupt


def _save(path: Path, array) -> None:
    """Write an output; errors name the user's path, not the temporary file."""
    try:
        images.save(path, array)
    except images.ImageIOError as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"{path}: cannot write ({exc.strerror or exc})") from None


def run(args: argparse.Namespace) -> int:
    blend = Path(args.file)
    out = Path(args.output)
    check_blend(blend)
    if getattr(args, "until_draw", None) is not None and args.until_draw < 0:
        raise CliError(f"--until-draw must be 0 or more (got {args.until_draw})")
    check_output(out, "-o")
    paths = {"FILE.blend": blend, "-o": out}
    if args.depth:
        check_output(Path(args.depth), "--depth")
        paths["--depth"] = Path(args.depth)
    check_distinct(paths)
    args.frame = checked_frame(args.frame)
    if args.frames is not None or args.skip_existing:
        return run_frames(args, blend, out)
    require_bpy()
    from .. import blender
    from ..core.records import RenderCancelled
    from ..core.scene import SceneError

    with sigint_cancels() as interrupted:
        scene = open_scene(blend, args.scene)
        try:
            with Progress(100, "%") as bar, redirect_fds(2):  # F12's render-mode depsgraph (modifier render levels)
                frame = blender.render_final(scene, frame=args.frame, progress=lambda f: bar.set(100 * f),
                                             until_draw=args.until_draw, should_cancel=interrupted)
        except SceneError as exc:
            raise CliError(str(exc)) from None
        except RenderCancelled:
            frame = None  # interrupted: KeyboardInterrupt on leaving the block
    if frame is None:
        raise CliError("render cancelled")
    for warning in frame.warnings:
        warn(warning)
    _save(out, frame.color)
    if args.depth:
        try:
            _save(Path(args.depth), frame.depth)
        except BaseException:
            out.unlink(missing_ok=True)  # all or nothing
            raise
    print(out)
    if args.depth:
        print(args.depth)
    return 0


def run_frames(args: argparse.Namespace, blend: Path, out: Path) -> int:
    """``--frames`` (or ``--skip-existing``): one render per frame, ``#`` patterns, ``Saved:`` lines."""
    if args.frames is not None and args.frame is not None:
        raise CliError("--frame and --frames cannot be used together (a single frame is --frames N-N)")
    frames = parse_frames(args.frames) if args.frames is not None else None
    depth = Path(args.depth) if args.depth else None
    if frames is not None:
        check_pattern(out, "-o", frames)
        if depth is not None:
            check_pattern(depth, "--depth", frames)
    require_bpy()
    from .. import blender
    from ..core.records import RenderCancelled
    from ..core.scene import SceneError

    scene = open_scene(blend, args.scene)
    if frames is None:
        frames = [args.frame if args.frame is not None else scene.frame_current]
    warned: set[str] = set()
    with Progress(len(frames), "frames") as bar:
        for done, number in enumerate(frames):
            targets = [Path(os.path.abspath(frame_path(out, number)))]
            if depth is not None:
                targets.append(Path(os.path.abspath(frame_path(depth, number))))
            if args.skip_existing and all(t.exists() for t in targets):
                bar.write(f"Skipped: '{targets[0]}'")
                bar.set(done + 1)
                continue
            try:
                with sigint_cancels() as interrupted:  # Ctrl+C: this frame is not written, exit 130
                    try:
                        with redirect_fds(2):  # F12's render-mode depsgraph (modifier render levels)
                            frame = blender.render_final(scene, frame=number, should_cancel=interrupted,
                                                         progress=lambda f, done=done: bar.set(done + f))
                    except RenderCancelled:
                        frame = None
            except SceneError as exc:
                raise CliError(f"frame {number}: {exc}") from None
            if frame is None:
                raise CliError(f"frame {number}: render cancelled")
            for warning in frame.warnings:
                if warning not in warned:  # once per run, not once per frame
                    warned.add(warning)
                    warn(f"frame {number}: {warning}")
            written: list[Path] = []
            try:
                for target, array in zip(targets, (frame.color, frame.depth), strict=False):
                    images.save(target, array)
                    written.append(target)
            except (images.ImageIOError, OSError) as exc:
                for path in written:  # all or nothing per frame
                    path.unlink(missing_ok=True)
                raise CliError(str(exc)) from None
            for target in written:
                bar.write(f"Saved: '{target}'")
            bar.set(done + 1)
    return 0
