"""Driving the command line as a user's terminal or a farm manager does: a process started, watched
until it reaches a given moment, then sent SIGINT or SIGTERM (tests/cli/test_interrupts.py).

The moments are observed from outside, as they happen, rather than guessed from elapsed time:
a shared library mapped into the process (bpy's ``__init__.so`` while ``import bpy`` runs,
numpy's while the package imports), the .blend file open or mapped (Blender's loader reading
it), a file appearing in a folder (an output's temporary ``.part`` file), a line on stdout.
Linux only (``/proc``).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

#: How often the watched moment is looked for (seconds).
POLL = 0.0005


def start(*args: str, cwd: Path = REPO) -> subprocess.Popen:
    """``python -m blendlib ARGS`` with pipes for stdout and stderr, unbuffered."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen([sys.executable, "-m", "blendlib", *args], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def wait_until(proc: subprocess.Popen, moment: Callable[[], bool], what: str, timeout: float = 120.0,
               poll: float = POLL) -> None:
    """Poll ``moment()`` every ``poll`` seconds (0: without pause, for a moment that lasts a few
    milliseconds) until it is true; AssertionError if the process ends first or the time runs out."""
    deadline = time.monotonic() + timeout
    while not moment():
        if proc.poll() is not None:
            out, err = proc.communicate()
            raise AssertionError(f"the process ended (status {proc.returncode}) before {what}: {err[-2000:]}")
        if time.monotonic() > deadline:
            proc.kill()
            proc.communicate()
            raise AssertionError(f"{what} did not happen within {timeout} s")
        time.sleep(poll)


def maps(proc: subprocess.Popen) -> str:
    try:
        return Path(f"/proc/{proc.pid}/maps").read_text()
    except OSError:
        return ""


def mapped(proc: subprocess.Popen, fragment: str) -> Callable[[], bool]:
    """The moment a file whose path contains ``fragment`` is mapped into the process."""
    return lambda: fragment in maps(proc)


def reading(proc: subprocess.Popen, path: Path) -> Callable[[], bool]:
    """The moment the process has ``path`` open or mapped (Blender's loader reading it)."""
    target = os.path.realpath(path)

    def moment() -> bool:
        if target in maps(proc):
            return True
        try:
            fds = os.listdir(f"/proc/{proc.pid}/fd")
        except OSError:
            return False
        for fd in fds:
            try:
                if os.readlink(f"/proc/{proc.pid}/fd/{fd}") == target:
                    return True
            except OSError:
                pass
        return False

    return moment


def appears(folder: Path, prefix: str, suffix: str = "") -> Callable[[], bool]:
    """The moment a file named ``prefix…suffix`` exists in ``folder``."""
    return lambda: any(n.startswith(prefix) and n.endswith(suffix) for n in os.listdir(folder))


def finish(proc: subprocess.Popen, timeout: float = 120.0) -> tuple[int, str, str]:
    """Wait for the end; (exit status, stdout, stderr)."""
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out, err


def stderr_lines(text: str) -> list[str]:
    return [x for x in text.splitlines() if x.strip()]


def signal_at(proc: subprocess.Popen, moment: Callable[[], bool], what: str, signum: int = signal.SIGINT,
              poll: float = POLL) -> tuple[int, str, str]:
    """Wait for ``moment``, send ``signum``, wait for the end: (exit status, stdout, stderr)."""
    wait_until(proc, moment, what, poll=poll)
    proc.send_signal(signum)
    return finish(proc)
