"""``python -m blendlib render``: a .blend file → PNG/EXR/NPY of the frame (and its depth), one
frame or a series (``--frames``)."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from ..formats import images
from ..formats.atomic import written_together
from . import interrupts, outputs
from .common import (
    CliError,
    add_scene_arguments,
    check_blend,
    checked_frame,
    open_scene,
    redirect_fds,
    warn,
)
from .frames import check_pattern, frame_path, parse_frames
from .progress import Progress

EPILOG_RENDER = """\
examples:
  python -m blendlib render scene.blend -o out.png
  python -m blendlib render scene.blend -o frame.npy --depth depth.npy --frame 12 --scene Scene.001
  python -m blendlib render scene.blend -o out/frame_####.png --frames 1-250:10 --skip-existing

OUT ends in .png (8-bit of the stored frame values: sRGB-encoded in Gamma mode and in Linear
LDR, exactly what Unity's colour buffer holds; alpha 255, as F12 shows the frame, or the
frame's own alpha with --alpha), .exr (32-bit float RGBA, exact values, alpha kept) or .npy
(the exact float32 (H, W, 4) array, row 0 = top, alpha kept). The Unity settings come from the
file (Material.unity, Scene.unity); the Unity Passes add-on need not be installed.

The last run of '#' in the output (and --depth) file name becomes the zero-padded frame
number, as in Blender. --frames N, A-B or A-B:STEP renders frames A to B (inclusive) every
STEP, each written file printing "Saved: '<absolute path>'" on stdout; the output folder is
created if needed. The outputs of a frame are written together or not at all, and an
existing file is only replaced by its complete successor. Ctrl+C or SIGTERM stops at once;
the error line says which frames were written.
"""


def until_draw_value(text: str) -> int:
    """``--until-draw``: an integer (argparse type); 0 or more is checked by :func:`run`."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"draw call must be an integer, got {text!r}") from None


def add_parser(sub) -> None:
    r = sub.add_parser("render", help="render a .blend file to PNG/EXR/NPY",
                       description="Render the active (or named) scene of a .blend file through its camera.",
                       epilog=EPILOG_RENDER, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(r)
    r.add_argument("-o", "--output", required=True, metavar="OUT", help="output image: .png, .exr or .npy")
    r.add_argument("--depth", metavar="DEPTH.npy", help="also write the depth buffer (H, W) float32, 0..1 window depth")
    r.add_argument("--frames", metavar="A-B[:STEP]",
                   help="render frames A..B (inclusive) every STEP, or frame N; '#' in OUT becomes the frame number")
    r.add_argument("--skip-existing", action="store_true",
                   help="do not render frames whose outputs already exist (all of them, written together)")
    r.add_argument("--until-draw", type=until_draw_value, metavar="K",
                   help="stop after draw call K (1-based, as 'drawlist' numbers them; 0 = the cleared frame)")
    r.add_argument("--alpha", action="store_true",
                   help="PNG: write the frame's own alpha channel (default: alpha 255, as F12 shows the frame)")
    r.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    blend = Path(args.file)
    out = Path(args.output)
    depth = Path(args.depth) if args.depth else None
    check_blend(blend)
    if args.until_draw is not None and args.until_draw < 0:
        raise CliError(f"--until-draw must be 0 or more (got {args.until_draw})")
    if args.frames is not None and args.frame is not None:
        raise CliError("--frame and --frames cannot be used together (a single frame is --frames N)")
    frames = parse_frames(args.frames) if args.frames is not None else None
    outputs.check_target(out, "-o", images.FORMATS, create_folder=frames is not None)
    named = {"-o": out}
    if depth is not None:
        outputs.check_target(depth, "--depth", (".npy",), create_folder=frames is not None)
        named["--depth"] = depth
    if frames is not None:
        for option, path in named.items():
            check_pattern(path, option, frames)
    number = checked_frame(args.frame)
    if frames is None and number is not None:
        frames = [number]
    if frames is not None:
        outputs.check_frame_targets(blend, named, frames, frame_path)
    scene = open_scene(blend, args.scene)
    if frames is None:  # the file's current frame: known now
        frames = [scene.frame_current]
        outputs.check_frame_targets(blend, named, frames, frame_path)
    series = args.frames is not None or args.skip_existing
    Series(args, scene, named, series).run(frames, set_frame=args.frames is not None or number is not None)
    return 0


class Series:
    """The frames of one run: rendered one by one, each frame's outputs committed together."""

    def __init__(self, args: argparse.Namespace, scene, named: dict[str, Path], series: bool) -> None:
        self.args, self.scene, self.named, self.series = args, scene, named, series
        self.written: list[tuple[int, Path]] = []
        self.skipped = 0
        self.last_done: int | None = None  # the last frame written or skipped
        self.warned: set[str] = set()

    def run(self, frames, set_frame: bool) -> None:
        total, unit = (len(frames), "frames") if self.series else (100, "%")
        with Progress(total, unit) as bar:
            for done, number in enumerate(frames):
                try:
                    self.frame(number, set_frame, bar, done)
                except interrupts.Interrupted as exc:
                    if self.series:  # the frame being done, or the next one if it was done
                        rest = frames[done:] if self.last_done != number else frames[done + 1:]
                        exc.detail = self.detail(len(frames), rest[0] if len(rest) else None)
                    raise

    def frame(self, number: int, set_frame: bool, bar: Progress, done: int) -> None:
        from .. import blender
        from ..core.records import RenderCancelled
        from ..core.scene import SceneError

        targets = [frame_path(path, number) for path in self.named.values()]
        if self.series:
            targets = [Path(os.path.abspath(t)) for t in targets]
        if self.args.skip_existing and written_together(targets):
            with interrupts.deferred():  # the line and the count agree with the error line's
                bar.write(f"Skipped: '{targets[0]}'")
                self.skipped += 1
                self.last_done = number
            bar.set(done + 1)
            return
        scale = 1.0 if self.series else 100.0
        try:
            with interrupts.deferred(), redirect_fds(2):  # F12's render-mode depsgraph (modifier render levels)
                try:
                    frame = blender.render_final(self.scene, frame=number if set_frame else None,
                                                 should_cancel=interrupts.requested, until_draw=self.args.until_draw,
                                                 progress=lambda f: bar.set((done + f) * scale))
                except RenderCancelled:
                    frame = None  # interrupted: Interrupted on leaving the deferred step
        except SceneError as exc:
            raise CliError(f"frame {number}: {exc}" if self.series else str(exc)) from None
        if frame is None:
            raise CliError(f"frame {number}: render cancelled" if self.series else "render cancelled")
        for warning in frame.warnings:
            if not self.series:
                warn(warning)
            elif warning not in self.warned:  # once per run, not once per frame
                self.warned.add(warning)
                warn(f"frame {number}: {warning}")
        color = frame.color
        if targets[0].suffix.lower() == ".png" and not self.args.alpha:
            color = color[..., :3]  # alpha 255: what F12 shows (the Combined pass is opaque)
        arrays = [color, frame.depth][:len(targets)]
        with interrupts.deferred():  # committed, printed and counted, or none of them
            outputs.commit(list(zip(targets, arrays, strict=True)), create_folders=self.series)
            for target in targets:
                bar.write(f"Saved: '{target}'" if self.series else str(target))
                self.written.append((number, target))
            self.last_done = number
        bar.set((done + 1) * scale)

    def detail(self, total: int, first_not_done: int | None) -> str:
        """What an interrupted series wrote, for the error line."""
        frames = sorted({n for n, _ in self.written})
        text = "nothing written" if not frames else (
            f"{len(frames)} of {total} frames written (frames {frames[0]} to {frames[-1]}, "
            f"the last file {str(self.written[-1][1])!r})")
        if self.skipped:
            text += f", {self.skipped} skipped as already written"
        return text if first_not_done is None else f"{text}; frame {first_not_done} and later not written"
