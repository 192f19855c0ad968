"""The command line's output files: checked before any work, committed together, counted.

- :func:`check_target`: one output's checks (kind, not a folder, its folder, not read-only),
  run before the .blend file is even opened;
- :func:`check_distinct` / :func:`check_frame_targets`: no two outputs (after ``#`` expansion,
  over every frame) and no output and input are the same file;
- :func:`commit` / :func:`commit_text`: the outputs of one step (a frame's colour and depth,
  the analysis' maps) written as one commit (:func:`blendlib.formats.atomic.write_group`):
  all or none, an existing file replaced only by its complete successor, never broken into by
  Ctrl+C or SIGTERM (:func:`blendlib.cli.interrupts.deferred`);
and records what they wrote (:data:`blendlib.cli.interrupts.WRITTEN`, for the line an
interruption prints).
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from ..formats import images
from ..formats.atomic import write_group
from . import interrupts
from .errors import CliError


def _folder(path: Path) -> Path:
    return path.parent if str(path.parent) else Path(".")


def check_target(path: Path, option: str, kinds: Sequence[str], *, create_folder: bool = False) -> None:
    """One-line CliError unless ``path`` can be written as ``option``'s output: its extension is
    one of ``kinds`` (".png", ...), it is not a folder nor a file without write permission, and
    its folder exists and is writable (``create_folder``: or can be created, as Blender creates
    an animation's output folder)."""
    ext = path.suffix.lower()
    if ext not in kinds:
        if option == "-o" and set(kinds) == set(images.FORMATS):
            raise CliError(f"{path}: unsupported image type {ext or '(none)'!r} (use one of {', '.join(kinds)})")
        raise CliError(f"{path}: {option} writes a {' or '.join(kinds)} file")
    _check_existing(path, option)
    folder = _folder(path)
    if not folder.is_dir():
        if not create_folder:
            raise CliError(f"{path}: output directory {str(folder)!r} does not exist")
        existing = folder
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        if not existing.is_dir():
            raise CliError(f"{path}: cannot create the output directory {str(folder)!r} "
                           f"({str(existing)!r} is not a directory)")
        folder = existing
    if not os.access(folder, os.W_OK):
        raise CliError(f"{path}: output directory {str(folder)!r} is not writable")


def _check_existing(path: Path, option: str) -> None:
    """An existing ``path`` must be a file this user may replace (not a folder, not read-only)."""
    if path.is_dir():
        raise CliError(f"{path}: is a directory; {option} needs a file name")
    if path.exists() or path.is_symlink():
        try:
            st = os.stat(path)
        except OSError as exc:
            raise CliError(f"{path}: cannot write ({exc.strerror})") from None
        if stat.S_ISREG(st.st_mode) and (not os.access(path, os.W_OK) or not st.st_mode & 0o222):
            raise CliError(f"{path}: the file is read-only; {option} does not replace it "
                           "(make it writable or choose another name)")


def _key(path: Path) -> str:
    """A file's identity for collisions: the real path (links followed) when it exists, else its
    real folder and its name."""
    if os.path.lexists(path):
        return os.path.realpath(path)
    return os.path.join(os.path.realpath(_folder(path)), path.name)


def check_distinct(paths: dict[str, Path]) -> None:
    """One-line error when two of the named files (inputs and outputs) are the same file."""
    seen: dict[str, str] = {}
    for option, path in paths.items():
        key = _key(path)
        if key in seen:
            raise CliError(f"{path}: {option} is the same file as {seen[key]}; choose another output")
        seen[key] = option


def check_frame_targets(blend: Path, patterns: dict[str, Path], frames: Iterable[int], expand) -> None:
    """No two outputs of any frames, nor an output and the .blend file, are one file, and no
    frame's output is a folder or a read-only file (:func:`check_target` checked the pattern).

    ``patterns``: option → output path (with its ``#`` run); ``expand(path, frame)`` gives a
    frame's file. One CliError naming the file, before anything is rendered."""
    frames = list(frames)
    seen: dict[str, str] = {_key(blend): "FILE.blend"}
    folders = {option: os.path.realpath(_folder(p)) for option, p in patterns.items()}
    for option, pattern in patterns.items():
        for number in frames:
            path = expand(pattern, number)
            what = option if len(frames) == 1 else f"{option} of frame {number}"
            if os.path.lexists(path):
                _check_existing(path, what)
                key = _key(path)
            else:
                key = os.path.join(folders[option], path.name)
            if key in seen:
                raise CliError(f"{path}: {what} is the same file as {seen[key]}; choose another output")
            seen[key] = what


def commit(items: Sequence[tuple[Path, np.ndarray]], *, create_folders: bool = False) -> list[Path]:
    """Write the ``(path, array)`` outputs of one step as one commit (see the module docstring);
    a failure is a CliError naming the user's file. ``create_folders``: make missing folders."""
    with interrupts.deferred():
        if create_folders:
            for path, _ in items:
                try:
                    os.makedirs(_folder(path), exist_ok=True)
                except OSError as exc:
                    raise CliError(f"{path}: cannot create the output directory ({exc.strerror or exc})") from None
        try:
            written = images.save_all(items, before_commit=_unless_interrupted)
        except images.ImageIOError as exc:
            raise CliError(str(exc)) from None
        except OSError as exc:
            raise CliError(f"{exc.filename}: cannot write ({exc.strerror})") from None
        interrupts.WRITTEN.extend(written)
    return written


def commit_text(path: Path, text: str) -> Path:
    """Write a text output as one commit; CliError naming ``path`` on failure."""
    with interrupts.deferred():
        try:
            write_group([(path, text)], before_commit=_unless_interrupted)
        except OSError as exc:
            raise CliError(f"{exc.filename}: cannot write ({exc.strerror})") from None
        interrupts.WRITTEN.append(path)
    return path


def _unless_interrupted() -> None:
    interrupts.check()
