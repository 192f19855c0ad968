"""Opening .blend files and finding scenes in them (the CLI, the pytest plugin and the ShaderLab
export use these); Blender's C-level output while it works."""

from __future__ import annotations

import contextlib
import faulthandler
import os
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

from ..core.scene import SceneError


@contextlib.contextmanager
def redirected_output(target: int | None) -> Iterator[None]:
    """Blender prints file-loading chatter (and messages such as "ERROR Engine 'UNITY_PASSES' not
    available" for a file saved with an add-on's engine) on stdout/stderr at the C level.
    ``target`` None: silence both (errors come back as exceptions); else send stdout to that fd
    (keep stdout for results)."""
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


# The watcher of :func:`crash_note`: a bare Python (no site, no environment) that waits for the
# pipe to close and prints the note when Python's fault handler wrote into it first.
_WATCHER = """\
import os, sys
data = sys.stdin.buffer.read()
if data:
    fault = data.decode("utf-8", "replace").splitlines()[0].removeprefix("Fatal Python error: ").strip()
    os.write(2, (sys.argv[1].replace("{fault}", fault or "a fatal signal") + "\\n").encode("utf-8", "replace"))
"""


@contextlib.contextmanager
def crash_note(note: str) -> Iterator[None]:
    """While inside, a crash of the process (a segmentation fault in Blender's C code) prints
    ``note`` as one line on the current stderr before the process dies (``{fault}`` in it
    becomes the fault's name, e.g. "Segmentation fault"); the exit status stays the signal's.

    A process cannot run Python after such a fault, so Python's :mod:`faulthandler` writes its
    report into a pipe and a small watcher process, started here with this stderr, prints the
    note when the pipe closes with a report in it (and nothing when it closes empty). Only for
    processes that own their fault handler (the command line): it is turned off on leaving.
    """
    try:
        read_end, write_end = os.pipe()
    except OSError:
        yield
        return
    try:
        watcher = subprocess.Popen([sys.executable, "-I", "-S", "-c", _WATCHER, note], stdin=read_end,
                                   stdout=subprocess.DEVNULL, stderr=2, close_fds=True)
    except OSError:  # no watcher: the crash stays silent, as without this
        os.close(read_end)
        os.close(write_end)
        yield
        return
    os.close(read_end)
    faulthandler.enable(file=write_end, all_threads=False)
    try:
        yield
    finally:
        faulthandler.disable()
        os.close(write_end)
        watcher.wait()


def load_bpy() -> None:
    """Import bpy (loading Blender takes about a second): the command line calls this inside a
    deferred-interrupt block, so a Ctrl+C meanwhile is acted on after it."""
    import bpy  # noqa: F401


def open_blend(path: Any, *, quiet: bool = False, crash: str | None = None) -> Any:
    """Open a .blend file (replacing Blender's current data) and return ``bpy.data``.

    ``quiet``: Blender's messages while loading are not shown (a failure still raises).
    ``crash``: the line to print if Blender's loader crashes the process on a damaged file
    (:func:`crash_note`; ``{fault}`` names the fault), instead of dying without a word.
    Raises :class:`SceneError` with one line naming the file and Blender's reason.
    """
    import bpy

    note = crash_note(crash) if crash is not None else contextlib.nullcontext()
    silence = redirected_output(None) if quiet else contextlib.nullcontext()
    try:
        with note, silence:
            bpy.ops.wm.open_mainfile(filepath=os.path.abspath(str(path)), load_ui=False)
    except RuntimeError as exc:
        lines = str(exc).strip().splitlines()
        reason = lines[-1].removeprefix("Error: ").strip() if lines else "unknown error"
        raise SceneError(f"{path}: cannot open .blend file ({reason})") from None
    return bpy.data


def scene_named(name: str | None, where: Any = "file") -> Any:
    """The scene called ``name`` (the context scene for None); SceneError naming the choices."""
    import bpy

    if name is None:
        return bpy.context.scene
    scene = bpy.data.scenes.get(name)
    if scene is None:
        names = ", ".join(repr(s.name) for s in bpy.data.scenes)
        raise SceneError(f"{where}: no scene named {name!r} (scenes: {names})")
    return scene


def scene_arg(scene: Any) -> Any:
    """The ``scene`` argument of the Python API as a ``bpy.types.Scene``: None is the context
    scene, a string the scene of that name (SceneError naming the scenes there are), a Scene
    itself; anything else is a TypeError."""
    import bpy

    if scene is None or isinstance(scene, str):
        return scene_named(scene, where="bpy.data")
    if not isinstance(scene, bpy.types.Scene):
        raise TypeError(f"scene must be a bpy.types.Scene, a scene's name or None, got {type(scene).__name__}")
    return scene


def material_named(name: str, where: Any = "file") -> Any:
    """The ``bpy.types.Material`` called ``name``; SceneError naming the materials there are."""
    import bpy

    mat = bpy.data.materials.get(name)
    if mat is None:
        names = ", ".join(sorted(m.name for m in bpy.data.materials)) or "none"
        raise SceneError(f"{where}: no material named {name!r} (materials: {names})")
    return mat
