"""docs/sorting.md advice: a checked change per inverted pair; the prepass for self-overlap, with its price.

Advice is computed on top of an analysis (blendlib.explain.advice.analyze_and_advise), never by it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from blendlib.core.drawlist import draw_calls
from blendlib.core.vocabulary import Cull, Queue
from blendlib.explain.advice import analyze_and_advise, with_queue_offset
from blendlib.explain.sorted_reference import analyze
from tests.explain.test_sorted_reference import BLEND, _two_quads
from tests.reference import scenes as sc


def _named(scene):
    return replace(scene, renderers=tuple(replace(r, material=replace(r.material, name="M" + r.name))
                                          for r in scene.renderers))


def test_queue_offset_advice_is_checked_by_rendering():
    scene = _named(_two_quads(False))
    assert analyze(scene).advice == []  # the analysis alone advises nothing
    result = analyze_and_advise(scene)
    assert len(result.advice) == 1
    item = result.advice[0]
    assert (item["front"], item["front_slot"], item["behind"], item["behind_slot"]) == ("Red", 0, "Blue", 0)
    assert item["change"] == {"material": "MRed", "queue_offset": 1}
    assert item["inversions_before"] == 48 and item["inversions_after"] == 0
    assert item["differing_before"] == 48 and item["differing_after"] == 0
    assert "Transparent+1" in item["text"] and "48 → 0" in item["text"]
    fixed = with_queue_offset(scene, "MRed", 1)
    assert [c.renderer.name for c in draw_calls(fixed)] == ["Blue", "Red"]
    again = analyze(fixed)
    assert again.inversions == [] and again.differing == 0


def test_a_shared_material_gets_a_sort_setting():
    result = analyze_and_advise(_two_quads(False))  # both quads use the material called "Material"
    item = result.advice[0]
    assert item["change"]["sort_mode"] == "CustomAxis" and item["inversions_after"] == 0
    assert item["differing_after"] == 0


def test_self_overlap_advice_is_the_prepass_with_its_price():
    cam = sc.camera(24, 24, eye=(0, 0, 4))
    ball = sc.renderer(sc.uv_sphere(1.0, 12, 8), sc.unlit((0.9, 0.6, 0.1, 0.4), queue=Queue.Transparent,
                                                           passes=[replace(BLEND, cull=Cull.Off)]), name="Ball")
    result = analyze_and_advise(sc.scene(cam, ball))
    [item] = result.advice
    assert item["front"] == item["behind"] == "Ball" and item["change"] is None
    assert item["technique"] == "depth prepass" and item["preset"] == "Alpha Blend ZWrite"
    assert item["inversions_before"] == result.inversions[0].pixels > 0 and item["inversions_after"] == 0
    assert item["differing_after"] > 0  # only the front layer shows
    assert "Sort Elements" in item["text"] and "front layer" in item["text"]
    assert np.all(result.inverted[result.inverted > 0] == 1)
