"""The one job base (addon/jobs.py): work on a worker thread with progress and cancel, and the modal
operator mixin that drives it, with timer and Esc events sent by hand (background mode has no
window to run a modal operator in)."""

from __future__ import annotations

import threading

import pytest

from addon.jobs import Job, JobOperator
from blendlib import RenderCancelled, SceneError
from tests.addon.recording import event, job_context, operator_probe, run_modal

WAIT = 5.0


class Storing(JobOperator):
    """A job operator that keeps what job_done receives."""

    report_prefix = "Test: "

    def job_done(self, context, result) -> None:
        context.stored.append(result)


def probe():
    return operator_probe(Storing)


def gated_work(gate: threading.Event, started: threading.Event, result=42, progress_value=0.5):
    """Work that reports ``progress_value``, then waits for ``gate`` and returns ``result``
    whether or not it was asked to cancel (as work does that finishes before it looks)."""

    def work(progress, should_cancel):
        progress(progress_value)
        started.set()
        assert gate.wait(WAIT)
        return result

    return work


def test_job_runs_in_a_thread_with_progress_and_cancel():
    seen = threading.Event()

    def work(progress, should_cancel):
        assert threading.current_thread() is not threading.main_thread()
        progress(0.5)
        seen.wait(WAIT)
        return should_cancel()

    job = Job(work)
    job.cancel.set()
    seen.set()
    assert job.done.wait(WAIT) and job.result is True and job.progress == 0.5 and job.error is None


def test_job_keeps_the_error_raised_on_the_worker():
    def work(progress, should_cancel):
        raise RenderCancelled("render cancelled")

    job = Job(work)
    assert job.done.wait(WAIT) and isinstance(job.error, RenderCancelled) and job.result is None


def test_operator_shows_progress_then_stores_the_result_on_finish():
    op, ctx = probe(), job_context(stored=[])
    gate, started = threading.Event(), threading.Event()
    assert op.start_job(ctx, gated_work(gate, started, result="frame", progress_value=0.37), "Working") == {
        "RUNNING_MODAL"}
    wm = ctx.window_manager
    assert wm.calls == [("timer_add", 0.1), ("progress_begin", 0, 100), ("modal_handler_add",)]
    assert ctx.workspace.status == ["Working: 0% (Esc to cancel)"]
    assert started.wait(WAIT)
    assert op.modal(ctx, event("MOUSEMOVE")) == {"RUNNING_MODAL"}  # other events wait too
    assert op.modal(ctx, event("TIMER")) == {"RUNNING_MODAL"}  # still working: its progress shown
    assert wm.calls[-1] == ("progress_update", 37) and ctx.workspace.status[-1] == "Working: 37% (Esc to cancel)"
    assert ctx.stored == []
    gate.set()
    assert run_modal(op, ctx) == {"FINISHED"}
    assert ctx.stored == ["frame"] and op.reports == []
    assert wm.calls[-2:] == [("timer_remove", "timer"), ("progress_end",)] and ctx.workspace.status[-1] is None
    assert op._job is None


def test_esc_cancels_and_stores_nothing_even_when_the_work_finished():
    op, ctx = probe(), job_context(stored=[])
    gate, started = threading.Event(), threading.Event()
    op.start_job(ctx, gated_work(gate, started), "Working")
    job = op._job
    assert started.wait(WAIT)
    assert op.modal(ctx, event("ESC")) == {"RUNNING_MODAL"}
    assert job.cancel.is_set()
    gate.set()
    assert run_modal(op, ctx) == {"CANCELLED"}
    assert job.result == 42 and ctx.stored == []
    assert op.reports == [("WARNING", "Test: Cancelled")]
    assert ("progress_end",) in ctx.window_manager.calls and ctx.workspace.status[-1] is None


@pytest.mark.parametrize("error,report", [
    (RenderCancelled("render cancelled"), ("WARNING", "Test: Cancelled")),
    (SceneError("scene 'Scene': no camera"), ("ERROR", "Test: scene 'Scene': no camera")),
    (ValueError("bad value"), ("ERROR", "Test: ValueError: bad value")),
])
def test_errors_are_one_report_and_store_nothing(error, report):
    def failing(progress, should_cancel):
        raise error

    op, ctx = probe(), job_context(stored=[])
    op.start_job(ctx, failing, "Working")
    assert run_modal(op, ctx) == {"CANCELLED"}
    assert op.reports == [report] and ctx.stored == []
    sync, ctx = probe(), job_context(stored=[])
    assert sync.run_now(ctx, failing) == {"CANCELLED"}  # execute's path reports the same
    assert sync.reports == [report] and ctx.stored == []


def test_run_now_runs_on_the_calling_thread_without_progress_or_cancel():
    seen = []

    def work(progress, should_cancel):
        seen.append((threading.current_thread() is threading.main_thread(), progress, should_cancel))
        return "done"

    op, ctx = probe(), job_context(stored=[])
    assert op.run_now(ctx, work) == {"FINISHED"}
    assert seen == [(True, None, None)] and ctx.stored == ["done"] and ctx.window_manager.calls == []


def test_blender_ending_the_operator_cancels_the_work():
    op, ctx = probe(), job_context(stored=[])
    gate, started = threading.Event(), threading.Event()
    op.start_job(ctx, gated_work(gate, started), "Working")
    job = op._job
    op.cancel(ctx)  # e.g. a file is loaded while the job runs
    assert job.cancel.is_set() and op._job is None
    assert ctx.window_manager.calls[-2:] == [("timer_remove", "timer"), ("progress_end",)]
    gate.set()
    assert job.done.wait(WAIT) and ctx.stored == []


def test_read_scene_reports_a_scene_error_and_gives_none():
    op = probe()

    def no_camera():
        raise SceneError("scene 'Scene': no camera")

    assert op.read_scene(no_camera) is None and op.reports == [("ERROR", "Test: scene 'Scene': no camera")]
    assert op.read_scene(lambda: "draw scene") == "draw scene"
