"""Helpers shared by the subcommands: the one-line error, warnings, file checks, Blender's chatter."""

from __future__ import annotations

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
