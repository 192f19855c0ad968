"""Helpers shared by the subcommands: the one-line error, warnings, file checks, Blender's chatter."""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import os
import sys
from pathlib import Path

from ..formats import images
from ..formats.atomic import write_atomic


class CliError(Exception):
    """A one-line error for the user."""


def warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)


@contextlib.contextmanager
def redirect_fds(target: int | None):
    """Blender prints file-loading chatter on stdout/stderr at the C level. ``target`` None: silence
    both (errors come back as exceptions); else send stdout to that fd (keep stdout for results)."""
    sys.stdout.flush()
    sys.stderr.flush()
    fds = (1, 2) if target is None else (1,)
    try:
        saved = [os.dup(fd) for fd in fds]
    except OSError:
        yield
        return
    sink = os.open(os.devnull, os.O_WRONLY) if target is None else target
    try:
        for fd in fds:
            os.dup2(sink, fd)
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        for fd, old in zip(fds, saved, strict=True):
            os.dup2(old, fd)
            os.close(old)
        if target is None:
            os.close(sink)


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
    try:
        images.file_format(path) if option == "-o" else None
    except images.ImageIOError as exc:
        raise CliError(str(exc)) from None
    if option != "-o" and path.suffix.lower() != ".npy":
        raise CliError(f"{path}: {option} writes a .npy file")
    if path.is_dir():
        raise CliError(f"{path}: is a directory; {option} needs a file name")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise CliError(f"{path}: output directory {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise CliError(f"{path}: output directory {str(folder)!r} is not writable")


def require_bpy() -> None:
    if importlib.util.find_spec("bpy") is None:
        raise CliError("the bpy module is not installed (pip install bpy==5.0.1, or run bash scripts/setup.sh)")


def open_scene(blend: Path, scene_name: str | None):
    """Open ``blend`` (Blender's loading chatter silenced) and return the named or active scene."""
    from .. import blender
    from ..core.scene import SceneError

    with redirect_fds(None):
        try:
            blender.open_blend(blend)
        except SceneError as exc:
            raise CliError(str(exc)) from None
    try:
        return blender.scene_named(scene_name, where=blend)
    except SceneError as exc:
        raise CliError(str(exc)) from None


def write_text_atomic(path: Path, text: str) -> None:
    """Write a text output atomically; one-line error naming the user's path."""
    try:
        write_atomic(path, text)
    except OSError as exc:
        raise CliError(f"{path}: cannot write ({exc.strerror or exc})") from None


#: Blender's frame range (MAXFRAME); frame_set clamps to it.
MAX_FRAME = 1048574


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
    require_bpy()
    from .. import blender
    from ..core.scene import SceneError

    scene = open_scene(blend, args.scene)
    try:
        with redirect_fds(2):
            draw = blender.draw_scene_final(scene, frame=frame)
    except SceneError as exc:
        raise CliError(str(exc)) from None
    for warning in draw.warnings:
        warn(warning)
    return draw


def check_distinct(paths: dict[str, Path]) -> None:
    """One-line error when two of the named files (inputs and outputs) are the same file."""
    seen: dict[Path, str] = {}
    for option, path in paths.items():
        key = path.resolve()
        if key in seen:
            raise CliError(f"{path}: {option} is the same file as {seen[key]}; choose another output")
        seen[key] = option
