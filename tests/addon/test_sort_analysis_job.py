"""The Analyze Sorting job through the advice: its progress passes the analysis and goes on while
the advice is checked, and Esc during the advice cancels the job and stores nothing."""

from __future__ import annotations

import threading

import bpy
import pytest

import addon
from blendlib import RenderCancelled
from blendlib.explain import advice
from tests.addon.recording import event, run_modal
from tests.addon.test_sort_analysis import _invoke, _rows, inverted_scene


@pytest.fixture(autouse=True)
def registered():
    addon.register()
    yield
    addon.unregister()


class GatedAdvice:
    """``_Measurer.measure`` (:attr:`measure`) that waits for ``gate`` before measuring: the
    advice has started (``reached``)."""

    def __init__(self):
        real = advice._Measurer.measure
        self.reached, self.gate = threading.Event(), threading.Event()

        def measure(measurer, changed):
            self.reached.set()
            assert self.gate.wait(30)
            return real(measurer, changed)

        self.measure = measure


def test_esc_during_the_advice_cancels_and_keeps_the_previous_results(monkeypatch):
    scene = inverted_scene()
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.unity.sort_analyze() == {"FINISHED"}
    results = bpy.context.window_manager.unity_sort_results
    previous = _rows(results)
    assert previous[1] and previous[1][0][4]  # an inverted pair with a checked change
    gated = GatedAdvice()
    monkeypatch.setattr(advice._Measurer, "measure", gated.measure)
    op, ctx = _invoke(scene)
    job = op._job
    assert gated.reached.wait(30)  # the analysis is done; the advice is being checked
    assert op.modal(ctx, event("TIMER")) == {"RUNNING_MODAL"}
    percent = ctx.window_manager.calls[-1][1]
    assert ctx.window_manager.calls[-1][0] == "progress_update" and 0 < percent < 100
    assert op.modal(ctx, event("ESC")) == {"RUNNING_MODAL"}
    gated.gate.set()  # the measurement's render sees the request and stops
    assert run_modal(op, ctx) == {"CANCELLED"}
    assert isinstance(job.error, RenderCancelled)
    assert op.reports == [("WARNING", "Unity Passes: Cancelled")]
    assert _rows(results) == previous
    assert ("progress_end",) in ctx.window_manager.calls and ctx.workspace.status[-1] is None
