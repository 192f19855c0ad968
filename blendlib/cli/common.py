"""Helpers shared by the subcommands: the one-line error, warnings, file checks, loading a scene."""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

from ..blender.files import redirected_output as redirect_fds
from ..formats import images
from . import interrupts
from .errors import CliError, warn
from .frames import MAX_FRAME
from .outputs import check_distinct, check_target, commit_text

__all__ = [
    "CliError", "MAX_FRAME", "add_scene_arguments", "check_blend", "check_distinct", "check_output", "checked_frame",
    "frame_number", "load_draw_scene", "open_scene", "redirect_fds", "require_bpy", "warn", "write_text_atomic",
]


def check_blend(path: Path) -> None:
    if not path.exists():
        raise CliError(f"{path}: no such file")
    if not path.is_file():
        raise CliError(f"{path}: not a file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(7)
    except OSError as exc:
        raise CliError(f"{path}: cannot read ({exc.strerror})") from None
    # Plain, gzip- or zstd-compressed .blend files.
    if not (head.startswith(b"BLENDER") or head.startswith(b"\x1f\x8b") or head.startswith(b"\x28\xb5\x2f\xfd")):
        raise CliError(f"{path}: not a .blend file")


def check_output(path: Path, option: str) -> None:
    """``-o`` (an image: .png, .exr or .npy) or another option's .npy output, checked before any
    work (:func:`blendlib.cli.outputs.check_target`)."""
    check_target(path, option, images.FORMATS if option == "-o" else (".npy",))


def require_bpy() -> None:
    """Import bpy (a one-line error when it is not installed); a Ctrl+C meanwhile is acted on
    after the import (:func:`blendlib.cli.interrupts.deferred`)."""
    if importlib.util.find_spec("bpy") is None:
        raise CliError("the bpy module is not installed (pip install bpy==5.0.1, or run bash scripts/setup.sh)")
    with interrupts.deferred():
        from ..blender.files import load_bpy

        load_bpy()


def open_scene(blend: Path, scene_name: str | None):
    """Open ``blend`` (Blender's loading chatter silenced; a crash of Blender's loader prints one
    line naming the file) and return the named or active scene."""
    from .. import blender
    from ..core.scene import SceneError

    require_bpy()
    crash = f"error: {blend}: Blender crashed while reading this file ({{fault}}); is the file damaged?"
    with interrupts.deferred():
        try:
            blender.open_blend(blend, quiet=True, crash=crash)
        except SceneError as exc:
            raise CliError(str(exc)) from None
    try:
        return blender.scene_named(scene_name, where=blend)
    except SceneError as exc:
        raise CliError(str(exc)) from None


def write_text_atomic(path: Path, text: str) -> None:
    """Write a text output as one commit (:func:`blendlib.cli.outputs.commit_text`)."""
    commit_text(path, text)


def frame_number(text: str) -> int:
    """``--frame``: an integer (argparse type)."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"frame must be an integer, got {text!r}") from None


def add_scene_arguments(parser: argparse.ArgumentParser, *, after_file=()) -> None:
    """``FILE.blend`` (then the positionals in ``after_file``: (name, kwargs) pairs), ``--scene``, ``--frame``."""
    parser.add_argument("file", metavar="FILE.blend", help="the .blend file (it is only read, never saved)")
    for name, kwargs in after_file:
        parser.add_argument(name, **kwargs)
    parser.add_argument("--scene", metavar="NAME", help="scene (default: the file's active scene)")
    parser.add_argument("--frame", type=frame_number, metavar="N",
                        help="frame number (default: the file's current frame)")


def checked_frame(frame: int | None) -> int | None:
    """A ``--frame`` inside Blender's frame range (clamped with a warning, as Blender would clamp it)."""
    if frame is not None and abs(frame) > MAX_FRAME:
        clamped = max(-MAX_FRAME, min(MAX_FRAME, frame))
        warn(f"--frame {frame} is outside Blender's frame range; rendering frame {clamped}")
        return clamped
    return frame


def load_draw_scene(args: argparse.Namespace):
    """The checked ``args.file``'s scene (``args.scene``, ``args.frame``) as F12 evaluates it: a
    DrawScene, its warnings printed; errors as CliError."""
    blend = Path(args.file)
    check_blend(blend)
    frame = checked_frame(args.frame)
    from .. import blender
    from ..core.scene import SceneError

    scene = open_scene(blend, args.scene)
    try:
        with interrupts.deferred(), redirect_fds(2):
            draw = blender.draw_scene_final(scene, frame=frame)
    except SceneError as exc:
        raise CliError(str(exc)) from None
    for warning in draw.warnings:
        warn(warning)
    return draw
