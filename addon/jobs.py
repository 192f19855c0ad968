"""The one job base of the add-on's long operators (Frame Debugger capture and pixel history, Analyze
Sorting): bpy-free work on a worker thread with progress and cancel, driven by a modal operator.

bpy is not thread-safe, so a job operator reads Blender data on the main thread (``invoke``),
hands the worker a function of plain data (a :class:`~blendlib.DrawScene`), and stores the result
on the main thread again when its modal timer sees the work done (:meth:`JobOperator.job_done`).
Meanwhile the status bar shows the job and its percentage, the window manager's progress
indicator its progress; Esc cancels. Cancelled work stores nothing, even when it finished
before it saw the request. ``execute`` (scripts, background mode) runs the same work
synchronously through :meth:`JobOperator.run_now`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from blendlib import RenderCancelled, SceneError

#: ``work(progress=..., should_cancel=...)``: bpy-free; ``progress(fraction 0..1)`` may be called from
#: the worker thread at any time; ``should_cancel()`` True asks it to raise ``RenderCancelled``.
Work = Callable[..., Any]

#: Seconds between the modal timer's looks at the worker.
POLL_INTERVAL = 0.1


class Job:
    """``work`` running on a daemon worker thread, started at once.

    ``progress``: the last fraction it reported; ``cancel``: set it to ask the work to stop;
    ``done``: set when it returned or raised; then ``result`` or ``error`` holds the outcome."""

    def __init__(self, work: Work):
        self.work = work
        self.progress = 0.0
        self.cancel = threading.Event()
        self.done = threading.Event()
        self.result: Any = None
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, name="Unity Passes job", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        try:
            self.result = self.work(progress=self._progress, should_cancel=self.cancel.is_set)
        except BaseException as exc:  # noqa: BLE001 - reported by the operator on the main thread
            self.error = exc
        finally:
            self.done.set()

    def _progress(self, fraction: float) -> None:
        self.progress = float(fraction)


class JobOperator:
    """Mixin for a ``bpy.types.Operator`` whose work takes long: :meth:`start_job` from ``invoke``,
    :meth:`run_now` from ``execute``; the subclass stores the result in :meth:`job_done`.

    Reports: cancelled (a warning), :class:`SceneError` (its one line), anything else (its type
    and message), each prefixed with :attr:`report_prefix`; nothing is stored then."""

    #: Prefix of every report of the job's outcome.
    report_prefix = ""
    _job: Job | None = None
    _timer = None
    _status = ""

    def job_done(self, context, result) -> None:
        """Store ``result`` (main thread) and report it; runs only when the work succeeded."""
        raise NotImplementedError

    def read_scene(self, extract: Callable[[], Any]) -> Any | None:
        """``extract()`` (main thread: bpy is not thread-safe), usually a :class:`~blendlib.DrawScene` for
        the work; a :class:`SceneError` (no camera, bad input) is reported and gives None."""
        try:
            return extract()
        except SceneError as exc:
            self.report({"ERROR"}, f"{self.report_prefix}{exc}")
            return None

    def modal_without_job(self, context, event) -> set[str]:
        """Events while no job runs (e.g. waiting for a click before starting one)."""
        return {"CANCELLED"}

    def start_job(self, context, work: Work, text: str) -> set[str]:
        """Run ``work`` on a worker thread; ``text`` names it in the status bar."""
        self._job = Job(work)
        self._status = text
        wm = context.window_manager
        self._timer = wm.event_timer_add(POLL_INTERVAL, window=context.window)
        wm.progress_begin(0, 100)
        self._show_status(context, 0)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def run_now(self, context, work: Work) -> set[str]:
        """Run ``work`` on this thread (no progress, no cancel) and finish as a job would."""
        try:
            result = work(progress=None, should_cancel=None)
        except Exception as exc:  # noqa: BLE001 - one message for the user
            return self.finish(context, None, exc)
        return self.finish(context, result, None)

    def modal(self, context, event) -> set[str]:
        job = self._job
        if job is None:
            return self.modal_without_job(context, event)
        if event.type == "ESC":
            job.cancel.set()
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}
        if not job.done.is_set():
            percent = int(100 * min(max(job.progress, 0.0), 1.0))
            context.window_manager.progress_update(percent)
            self._show_status(context, percent)
            return {"RUNNING_MODAL"}
        self._end(context)
        return self.finish(context, job.result, job.error, cancelled=job.cancel.is_set())

    def cancel(self, context) -> None:
        """Blender ends the modal operator (a file is loaded, the window closes): stop the worker."""
        if self._job is not None:
            self._job.cancel.set()
            self._end(context)

    def finish(self, context, result, error: BaseException | None, cancelled: bool = False) -> set[str]:
        """Report the outcome; on success :meth:`job_done` stores ``result``."""
        prefix = self.report_prefix
        if cancelled or isinstance(error, RenderCancelled):
            self.report({"WARNING"}, f"{prefix}Cancelled")
            return {"CANCELLED"}
        if isinstance(error, SceneError):
            self.report({"ERROR"}, f"{prefix}{error}")
            return {"CANCELLED"}
        if error is not None:
            self.report({"ERROR"}, f"{prefix}{type(error).__name__}: {error}")
            return {"CANCELLED"}
        self.job_done(context, result)
        return {"FINISHED"}

    def _show_status(self, context, percent: int) -> None:
        if context.workspace is not None:
            context.workspace.status_text_set(f"{self._status}: {percent}% (Esc to cancel)")

    def _end(self, context) -> None:
        """Remove the timer, the progress indicator and the status text; forget the job."""
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        self._job = None
