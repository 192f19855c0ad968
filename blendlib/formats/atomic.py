"""The one atomic file writer: temporary files beside the targets, then renames.

A failed or interrupted write leaves no file behind and every existing target untouched: a
target is only ever replaced by a rename of a complete file. :func:`write_group` commits the
outputs of one frame (a colour image and its depth) together: every file is written to its
temporary first and only then are they renamed, one after the other, so an error or an
interruption before the renames changes none of them. The renames of one group follow each
other at once; only a process killed between two of them (SIGKILL, a power cut) can leave a
new file beside an old one, and :func:`written_together` tells such a pair apart: the files of
one group share one modification time.

A new file gets the mode an ordinary ``open(path, "w")`` would give it (0666 less the umask),
or the existing file's mode when it replaces one. Errors are :class:`OSError` naming the
target (never the temporary file) with a readable reason.
"""

from __future__ import annotations

import os
import stat
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import BinaryIO

#: What a file's content is given as: the bytes, UTF-8 text, or a function writing into the open file.
Content = bytes | str | Callable[[BinaryIO], None]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_error(exc: OSError, path: str | os.PathLike) -> OSError:
    """``exc`` as an OSError about ``path`` (the user's file, not a temporary one): same errno,
    a one-line reason. numpy reports a short write without an errno ("N requested and M
    written"), which on a local disk means it is full."""
    reason = exc.strerror or " ".join(str(exc).split()) or type(exc).__name__
    if exc.errno is None and "requested and" in reason:
        reason = f"only part of the data was written ({reason}); is the disk full?"
    return OSError(exc.errno, reason, os.fspath(path))


def _write_temporary(path: Path, content: Content) -> str:
    folder = path.parent if str(path.parent) else Path(".")
    try:
        mode = stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        mode = 0o666 & ~_umask()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            if callable(content):
                content(fh)
            else:
                fh.write(content.encode("utf-8") if isinstance(content, str) else content)
        os.chmod(tmp, mode)
    except BaseException:
        _unlink(tmp)
        raise
    return tmp


def _unlink(tmp: str) -> None:
    try:
        os.unlink(tmp)
    except OSError:
        pass


def write_group(items: Sequence[tuple[str | os.PathLike, Content]],
                before_commit: Callable[[], None] | None = None) -> list[Path]:
    """Write every ``(path, content)`` of ``items`` as one commit; returns the paths.

    ``before_commit()`` is called before each file is written and once more before the
    renames; whatever it raises (e.g. the command line's "interrupted") abandons the group:
    the temporary files are removed and no target changes. An OSError while writing does the
    same and is raised as :func:`write_error` names it.
    """
    paths = [Path(p) for p, _ in items]
    temporaries: list[str] = []
    try:
        for path, (_, content) in zip(paths, items, strict=True):
            if before_commit is not None:
                before_commit()
            try:
                temporaries.append(_write_temporary(path, content))
            except OSError as exc:
                raise write_error(exc, path) from None
        if before_commit is not None:
            before_commit()
        stamp = time.time_ns()
        for tmp in temporaries:
            try:
                os.utime(tmp, ns=(stamp, stamp))
            except OSError:  # a file system that keeps its own times: written_together says False
                pass
    except BaseException:
        for tmp in temporaries:
            _unlink(tmp)
        raise
    for k, (path, tmp) in enumerate(zip(paths, temporaries, strict=True)):
        try:
            os.replace(tmp, path)
        except OSError as exc:
            for rest in temporaries[k:]:
                _unlink(rest)
            raise write_error(exc, path) from None
    return paths


def write_atomic(path: str | os.PathLike, write: Content) -> Path:
    """Write ``path`` atomically. ``write``: the bytes (str: UTF-8 text) or a function that writes
    into the open binary file."""
    return write_group([(path, write)])[0]


def written_together(paths: Sequence[str | os.PathLike]) -> bool:
    """Whether every path is a non-empty regular file and all share one modification time, as
    :func:`write_group` leaves the files of one commit (one path: whether it is such a file)."""
    times = set()
    for path in paths:
        try:
            st = os.stat(path)
        except OSError:
            return False
        if not stat.S_ISREG(st.st_mode) or st.st_size == 0:
            return False
        times.add(st.st_mtime_ns)
    return len(times) <= 1
