"""Progress and cancel through every phase of an analysis with advice: the render, step 2 and the
inversion count (every pass), the Overlay render and each advice measurement report one
fraction that never decreases and ends at 1; a cancel request stops any of them."""

from __future__ import annotations

from dataclasses import replace

import pytest

from blendlib.core.records import RenderCancelled
from blendlib.core.vocabulary import Queue
from blendlib.explain import advice, fragment_store
from blendlib.explain import sorted_reference as sr
from blendlib.explain.advice import analyze_and_advise
from blendlib.explain.sorted_reference import analyze
from tests.explain.test_sorted_reference import BLEND, layered_scene
from tests.reference import scenes as sc


def _with_overlay(scene):
    hud = sc.renderer(sc.quad(-1, -1, 1, 1), sc.unlit((1, 1, 1, 0.5), queue=Queue.Overlay, passes=[BLEND]),
                      name="Hud")
    return replace(scene, renderers=(*scene.renderers, hud))


def _share(max_advice: int) -> float:
    return 1.0 / (1.0 + advice.ADVICE_WEIGHT * max_advice)


@pytest.mark.parametrize("memory", [None, 1])  # one pass, or one block a pass
def test_one_fraction_over_every_phase(monkeypatch, memory):
    monkeypatch.setattr(fragment_store, "BLOCK_PIXELS", 32)  # two rows a block: seven blocks,
    monkeypatch.setattr(sr, "WORK_FRAGMENTS", 40)  # processed a few at a time
    monkeypatch.setattr(sr, "UNIT_FRAGMENTS", 1)
    scene = _with_overlay(layered_scene(3))
    fractions = []
    result = analyze_and_advise(scene, max_advice=3, progress=fractions.append, memory=memory)
    assert result.advice and len(result.advice) == min(3, len(result.inversions))
    assert fractions == sorted(fractions) and fractions[0] >= 0.0 and fractions[-1] == 1.0
    share = _share(3)
    render = [f for f in fractions if f <= 0.4 * share * (1 + 1e-9)]
    blocks = [f for f in fractions if 0.4 * share < f < 0.9 * share]
    measured = [f for f in fractions if share < f < 1.0]
    assert render and len(blocks) > 2 and measured  # the render, step 2 and the advice each move the bar
    alone = []
    analyze(scene, progress=alone.append, memory=memory)
    assert alone == sorted(alone) and alone[-1] == 1.0 and any(0.4 < f < 0.95 for f in alone)


def _cancel_after(limit: float):
    """(the fractions reported, a ``should_cancel`` that answers True once one reaches ``limit``)."""
    fractions = []

    def should_cancel():
        return bool(fractions) and fractions[-1] >= limit

    return fractions, should_cancel


@pytest.mark.parametrize("phase", ["blocks", "advice"])
def test_cancel_stops_step_two_and_the_advice(monkeypatch, phase):
    monkeypatch.setattr(fragment_store, "BLOCK_PIXELS", 32)  # two rows a block: seven blocks,
    monkeypatch.setattr(sr, "WORK_FRAGMENTS", 40)  # processed a few at a time
    monkeypatch.setattr(sr, "UNIT_FRAGMENTS", 1)
    scene = layered_scene(1)
    share = _share(2)
    # After the first of seven blocks; or once the analysis is done (the advice has started).
    fractions, should_cancel = _cancel_after(0.41 * share if phase == "blocks" else share)
    measured = []
    real = advice._Measurer.measure

    def counted(self, changed):
        measured.append(changed)
        return real(self, changed)

    monkeypatch.setattr(advice._Measurer, "measure", counted)
    with pytest.raises(RenderCancelled):
        analyze_and_advise(scene, max_advice=2, progress=fractions.append, should_cancel=should_cancel)
    assert fractions[-1] < 1.0
    if phase == "blocks":
        assert fractions[-1] < 0.9 * share and not measured  # stopped between two blocks
    else:
        assert len(measured) == 1 and fractions[-1] == pytest.approx(share)  # stopped at the first measurement
