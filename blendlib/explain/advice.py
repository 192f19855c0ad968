"""Advice for inverted renderer pairs (docs/sorting.md), each checked by re-rendering with the change.

For a pair of different renderers (A drawn before B although A lies in front of B) the
candidates are: a render-queue offset that draws A after B (on A's material) or B before A
(on B's material), and a sort setting of the scene (``CustomAxis`` along the line from A's
sort point to B's, or the other built-in mode). Each candidate is rendered and analysed; the
one that leaves the fewest inverted pixels of the pair (then the fewest differing pixels,
measured against the original sorted reference: the image the artist means) is advised.

For a renderer that overlaps itself no queue or sort setting helps. The measured technique is
the depth prepass (preset "Alpha Blend ZWrite"): it removes the inversions, but it shows only
the front layer, so the frame still differs from the sorted reference — the technique's price,
reported as ``differing_after``. Splitting the mesh or sorting its triangles (Blender's Mesh ›
Sort Elements) are named too; they depend on the view and are not measured.

Advice sits on top of the analysis (:mod:`.sorted_reference` knows nothing of it):
:func:`analyze_and_advise` runs one and then the other, for the callers that want both
(``blendlib.analyze``, ``python -m blendlib analyze``, the add-on's Analyze button).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ..core.drawlist import sort_key_distance
from ..core.scene import DrawScene, Renderer
from ..core.vocabulary import SortMode, preset, queue_text
from .sorted_reference import Analysis, analyze, sort_error

PREPASS_PRESET = "Alpha Blend ZWrite"


def _renderer(scene: DrawScene, key: tuple[str, int]) -> Renderer:
    return next(r for r in scene.renderers if (r.name, r.slot) == key)


def with_queue_offset(scene: DrawScene, material: str, offset: int) -> DrawScene:
    """The scene with every renderer of material ``material`` at queue offset ``offset``."""
    return replace(scene, renderers=tuple(
        replace(r, material=replace(r.material, queue_offset=int(offset))) if r.material.name == material else r
        for r in scene.renderers))


def with_prepass(scene: DrawScene, key: tuple[str, int]) -> DrawScene:
    """The scene with renderer ``key``'s material given the depth-prepass preset's queue and passes."""
    queue, passes = preset(PREPASS_PRESET)
    return replace(scene, renderers=tuple(
        replace(r, material=replace(r.material, queue=queue, passes=passes)) if (r.name, r.slot) == key else r
        for r in scene.renderers))


def _measure(scene: DrawScene, original: Analysis, front, behind, workers) -> tuple[int, int]:
    """(pixels of the pair still inverted, pixels differing from the original sorted reference)."""
    after = analyze(scene, workers=workers)
    error = sort_error(after.frame.color, original.reference, original.hdr)
    return after.pair_pixels(front, behind), int(np.count_nonzero(error > original.step))


def _label(key: tuple[str, int]) -> str:
    return f"'{key[0]}'" if key[1] == 0 else f"'{key[0]}' (slot {key[1]})"


def _pair_candidates(scene: DrawScene, a: Renderer, b: Renderer) -> list[tuple[dict, DrawScene, str]]:
    """(change, changed scene, sentence) for a pair: A is in front but drawn before B."""
    out = []
    qa, qb = a.material.render_queue, b.material.render_queue
    if a.material.name != b.material.name:
        target = qb + 1  # A after B
        if target <= 3999:
            offset = target - a.material.queue.number
            out.append(({"material": a.material.name, "queue_offset": offset},
                        with_queue_offset(scene, a.material.name, offset),
                        f"set material '{a.material.name}' to queue {queue_text(a.material.queue, offset)} "
                        f"({target}) so that {_label((a.name, a.slot))} draws after {_label((b.name, b.slot))}"))
        target = qa - 1  # B before A
        if target >= 2501:
            offset = target - b.material.queue.number
            out.append(({"material": b.material.name, "queue_offset": offset},
                        with_queue_offset(scene, b.material.name, offset),
                        f"set material '{b.material.name}' to queue {queue_text(b.material.queue, offset)} "
                        f"({target}) so that {_label((b.name, b.slot))} draws before {_label((a.name, a.slot))}"))
    if qa == qb:
        axis = np.asarray(b.bounds_center, np.float64) - np.asarray(a.bounds_center, np.float64)
        length = float(np.linalg.norm(axis))
        if length > 0 and np.isfinite(length):
            axis = [round(float(v) / length, 4) for v in axis]
            if any(axis):
                changed = replace(scene, sort_mode=SortMode.CustomAxis, sort_axis=tuple(axis))
                if sort_key_distance(changed, b) > sort_key_distance(changed, a):
                    out.append(({"sort_mode": "CustomAxis", "sort_axis": axis}, changed,
                                f"sort transparent objects along the axis {tuple(axis)} (Sort Mode Custom Axis)"))
        for mode in (SortMode.Perspective, SortMode.Orthographic):
            if mode is not scene.sort_mode:
                out.append(({"sort_mode": mode.value}, replace(scene, sort_mode=mode),
                            f"set the scene's Sort Mode to {mode.value}"))
    return out


def advise(scene: DrawScene, analysis: Analysis, limit: int = 5, workers: int | None = None) -> list[dict]:
    """Advice items for the ``limit`` largest inversion pairs (fields of docs/json.md), each checked."""
    items = []
    before_differing = analysis.differing
    for inv in analysis.inversions[:limit]:
        base = {**inv.as_json(), "inversions_before": inv.pixels, "differing_before": before_differing}
        base.pop("pixels")
        if inv.self_overlap:
            changed = with_prepass(scene, inv.front)
            pairs, differing = _measure(changed, analysis, inv.front, inv.behind, workers)
            items.append({**base, "change": None, "technique": "depth prepass", "preset": PREPASS_PRESET,
                          "inversions_after": pairs, "differing_after": differing,
                          "text": (f"{_label(inv.front)} overlaps itself on {inv.pixels} pixels: a depth prepass "
                                   f"(preset '{PREPASS_PRESET}') leaves {pairs} inverted but shows only the front "
                                   f"layer (then {differing} pixels of the frame differ from the sorted reference, "
                                   f"{before_differing} before); or split "
                                   "the mesh into parts that sort by distance, or order its triangles back to "
                                   "front (Mesh > Sort Elements)")})
            continue
        a, b = _renderer(scene, inv.front), _renderer(scene, inv.behind)
        best = None
        for change, changed, sentence in _pair_candidates(scene, a, b):
            pairs, differing = _measure(changed, analysis, inv.front, inv.behind, workers)
            score = (pairs, differing)
            if best is None or score < best[0]:
                best = (score, change, sentence)
        if best is None:
            items.append({**base, "change": None, "inversions_after": inv.pixels,
                          "differing_after": before_differing,
                          "text": (f"{_label(inv.front)} is in front of {_label(inv.behind)} on {inv.pixels} "
                                   "pixels but drawn first; they share a material and a queue: give one of "
                                   "them its own material and queue offset")})
            continue
        (pairs, differing), change, sentence = best
        items.append({**base, "change": change, "inversions_after": pairs, "differing_after": differing,
                      "text": (f"{_label(inv.front)} is in front of {_label(inv.behind)} on {inv.pixels} pixels "
                               f"but drawn first: {sentence} (checked: {inv.pixels} → {pairs} inverted pixels, "
                               f"{before_differing} → {differing} differing)")})
    return items


def analyze_and_advise(
    scene: DrawScene,
    *,
    max_advice: int = 5,
    workers: int | None = None,
    progress: Callable[[float], None] | None = None,
    should_cancel: Callable[[], bool] | None = None,
) -> Analysis:
    """:func:`~.sorted_reference.analyze` of ``scene``, its ``advice`` filled with a checked fix
    for each of the ``max_advice`` largest inversion pairs (:func:`advise`; 0: none). Raises as
    ``analyze`` does."""
    analysis = analyze(scene, workers=workers, progress=progress, should_cancel=should_cancel)
    if max_advice > 0 and analysis.inversions:
        analysis.advice = advise(scene, analysis, limit=max_advice, workers=workers)
    return analysis
