"""Ctrl+C (SIGINT) and SIGTERM for the command line: one handler, installed before bpy is loaded.

:func:`install` is called first thing by ``python -m blendlib`` (``blendlib/__main__.py``, before
numpy or bpy is imported) and by :func:`blendlib.cli.main` for callers that run it in their
own process; it is the one place that changes these signals' handling. SIGTERM, what a farm
manager sends to cancel a task, is handled exactly as Ctrl+C.

The first signal ends the run with :class:`Interrupted` (the command line prints one line and
exits with 128 + the signal's number), never from inside Blender, an import or an output
commit: a ``KeyboardInterrupt`` raised inside ``import bpy`` leaves Blender half initialised
(the process then dies of a segmentation fault at exit), one raised inside Blender's file
loader or render operator is swallowed by Blender (the first Ctrl+C would be lost), one
raised inside an extension module's import comes out as an ImportError, and one raised
between the renames of a frame's outputs would keep a colour image without its depth. So the
handler only records the signal, except inside :func:`interruptible` steps (a command's own
work: the bpy-free renders and analysis, reading images), where it raises at once; inside
those, :func:`deferred` steps (Blender's code, an output commit) record it again, and raise
when they end. Between steps the command line calls :func:`check`, and renders poll
:func:`requested` as their ``should_cancel``. Signals after the first change nothing: the run
is already ending. A SIGINT that is ignored when the process starts (a background job of a
non-interactive shell, ``nohup``) stays ignored, as Python itself does.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

#: The signals handled; each ends the command with exit status 128 + its number.
SIGNALS = (signal.SIGINT, signal.SIGTERM)

#: Every file this run has committed (:mod:`blendlib.cli.outputs`), in order: what an
#: interruption's line reports. Kept here, free of numpy, for an interruption while numpy imports.
WRITTEN: list[Path] = []

_received: list[int] = []  # the first signal received, if any
_installed: dict[int, object] = {}  # signal → the handler it replaced
_state = {"interruptible": 0, "deferred": 0, "raising": True}


class Interrupted(BaseException):
    """The run was interrupted by ``signum`` (a BaseException, as KeyboardInterrupt: no
    ``except Exception`` on the way takes it for an error). ``detail``: what was written, when
    the raiser knows it better than :func:`written_summary`."""

    def __init__(self, signum: int, detail: str | None = None) -> None:
        self.signum = signum
        self.detail = detail
        super().__init__(signal.Signals(signum).name)

    @property
    def exit_status(self) -> int:
        return 128 + self.signum


def _handle(signum: int, frame) -> None:
    if _received:
        return  # a second signal: the run is already ending
    _received.append(signum)
    if _state["raising"] and _state["interruptible"] > 0 and _state["deferred"] == 0:
        raise Interrupted(signum)


def install() -> Callable[[], None]:
    """Handle SIGINT and SIGTERM from now on (idempotent); returns a function that restores what
    this call replaced (nothing when the handlers were installed already, or off the main
    thread, where Python cannot change signal handling)."""
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    replaced: dict[int, object] = {}
    for signum in SIGNALS:
        if signum in _installed:
            continue
        previous = signal.getsignal(signum)
        if signum == signal.SIGINT and previous == signal.SIG_IGN:
            continue
        signal.signal(signum, _handle)
        _installed[signum] = replaced[signum] = previous
    _state["raising"] = True

    def restore() -> None:
        for signum, previous in replaced.items():
            signal.signal(signum, previous if previous is not None else signal.SIG_DFL)
            _installed.pop(signum, None)

    return restore


def finish() -> None:
    """The command has ended (``python -m blendlib`` only): SIGINT and SIGTERM are ignored while
    the interpreter and Blender's exit handlers shut down. Python's own shutdown would put the
    default handling back, and a second Ctrl+C just after the first would then kill the process
    (status -2) after its line was printed."""
    _state["raising"] = False
    for signum in _installed:
        signal.signal(signum, signal.SIG_IGN)


def requested() -> bool:
    """Whether SIGINT or SIGTERM has been received (a render's ``should_cancel``)."""
    return bool(_received)


def check() -> None:
    """Raise :class:`Interrupted` when a signal has been received."""
    if _received:
        raise Interrupted(_received[0])


@contextlib.contextmanager
def interruptible() -> Iterator[None]:
    """A step that a signal ends at once (it raises :class:`Interrupted` wherever the step is, as
    Python's KeyboardInterrupt would); a signal received before raises on entering."""
    check()
    _state["interruptible"] += 1
    try:
        yield
    finally:
        _state["interruptible"] -= 1


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """A step that a signal must not break into (Blender's code, an output commit): the signal
    is recorded meanwhile and :class:`Interrupted` raised when the outermost such step ends
    normally. Nested steps are one step."""
    _state["deferred"] += 1
    try:
        yield
    finally:
        _state["deferred"] -= 1
    if _state["deferred"] == 0:
        check()


def written_summary() -> str:
    """What this run has written: ``nothing written``, or the files' count and the last one."""
    if not WRITTEN:
        return "nothing written"
    if len(WRITTEN) == 1:
        return f"wrote {str(WRITTEN[0])!r} only"
    return f"wrote {len(WRITTEN)} files (the last {str(WRITTEN[-1])!r}) and nothing after them"


def reset() -> None:
    """Forget a received signal (for a caller that runs several commands in one process)."""
    _received.clear()
    _state["deferred"] = _state["interruptible"] = 0
