"""The one atomic file writer: a temporary file beside the target, then a rename.

A failed or interrupted write leaves no file behind and an existing target untouched.
The new file gets the mode an ordinary ``open(path, "w")`` would give it (0666 less the
umask), or the existing file's mode when it replaces one.
"""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomic(path: str | os.PathLike, write: bytes | str | Callable[[BinaryIO], None]) -> Path:
    """Write ``path`` atomically. ``write``: the bytes (str: UTF-8 text) or a function that writes
    into the open binary file."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    try:
        mode = stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        mode = 0o666 & ~_umask()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            if callable(write):
                write(fh)
            else:
                fh.write(write.encode("utf-8") if isinstance(write, str) else write)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path
