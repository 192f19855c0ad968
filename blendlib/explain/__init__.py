"""Tools that explain a frame, built on the core's records (bpy-free; imports ``core/`` only).

They consume what :func:`blendlib.core.pipeline.render_scene` reports to a
:class:`blendlib.core.records.FrameObserver` — the numbered draw calls and every fragment
with the test that discarded it — rather than forking the pipeline: the frame debugger
(draw list, stop after draw K, pixel history) and the sorted reference (what a per-fragment
sort would show, sort errors, inversions, overdraw) and, on top of it, the advice checked by
re-rendering (:mod:`.advice`, which imports :mod:`.sorted_reference`, never the reverse).
"""
