"""The opaque queue's order proved free (docs/sorting.md "Cost"): advice resumes a reordered opaque
queue from the analysed step-1 buffers only where no order of its draw calls could leave others.

The claim checked here directly: when the analysis proves it, every reordering of the opaque
calls (by queue offsets, as advice's candidates reorder them) leaves the buffers step 1 holds, bit
for bit; the blend semantics that make the proof need their conditions (a tie at the nearest
depth, an alpha that ``BlendOp Max`` keeps) are shown to change the buffers when broken."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from blendlib.core.drawlist import draw_calls
from blendlib.core.pipeline import render_scene
from blendlib.core.vocabulary import BlendFactor, BlendOp, CompareFunction, Pass, Queue
from blendlib.explain import advice
from blendlib.explain.fragment_store import alpha_extreme, writes_nearest
from blendlib.explain.sorted_reference import LastBuffers, analyze
from tests.explain.test_advice import _candidates, _full_measure
from tests.explain.test_sorted_reference import BLEND
from tests.reference import scenes as sc

#: MToon's opaque pass (UniVRM's MToon.shader: ``Blend One Zero``, ``BlendOp Add, Max``).
MTOON_OPAQUE = Pass(blend=True, src_blend=BlendFactor.One, dst_blend=BlendFactor.Zero, separate_alpha=True,
                    src_blend_alpha=BlendFactor.One, dst_blend_alpha=BlendFactor.Zero, blend_op_alpha=BlendOp.Max)
ONE_ZERO = Pass(blend=True, src_blend=BlendFactor.One, dst_blend=BlendFactor.Zero)


@pytest.mark.parametrize("p, hdr, expected", [
    (Pass(), False, True),
    (Pass(ztest=CompareFunction.Less), True, True),
    (ONE_ZERO, False, True),
    (ONE_ZERO, True, False),  # an HDR destination may be infinite: inf * 0 is NaN
    (MTOON_OPAQUE, False, True),
    (replace(MTOON_OPAQUE, blend_op_alpha=BlendOp.Min), False, True),
    (replace(ONE_ZERO, blend_op=BlendOp.Max), False, False),
    (replace(ONE_ZERO, dst_blend=BlendFactor.One), False, False),
    (Pass(blend=True, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha), False, False),
    (Pass(zwrite=False), False, False),
    (Pass(ztest=CompareFunction.Always), False, False),
    (Pass(ztest=CompareFunction.GEqual), False, False),
    (Pass(stencil=True), False, False),
])
def test_passes_that_leave_what_the_nearest_fragment_carries(p, hdr, expected):
    assert writes_nearest(p, hdr) is expected


def test_alpha_extreme_is_the_alpha_operation_max_or_min():
    assert alpha_extreme(MTOON_OPAQUE) is BlendOp.Max
    assert alpha_extreme(replace(MTOON_OPAQUE, blend_op_alpha=BlendOp.Min)) is BlendOp.Min
    assert alpha_extreme(ONE_ZERO) is None and alpha_extreme(Pass()) is None
    assert alpha_extreme(replace(MTOON_OPAQUE, blend=False)) is None  # Blend Off: the op is unused


def _tilted_quad(rng, width, height, flat_z=None):
    x0, y0 = rng.integers(0, width - 6), rng.integers(0, height - 6)
    x1, y1 = x0 + rng.integers(5, width // 2 + 6), y0 + rng.integers(5, height // 2 + 6)
    z = [flat_z] * 4 if flat_z is not None else rng.uniform(-5, 5, 4)
    pos = [(x0, y0, z[0]), (x1, y0, z[1]), (x1, y1, z[2]), (x0, y1, z[3])]
    return sc.make_mesh(pos, [(0, 1, 2), (0, 2, 3)])


def _opaque_scene(seed: int, pass_of=lambda k, rng: Pass(), alpha_of=lambda k, rng: 1.0, one_queue=False):
    """Opaque quads, each its own material in queue Geometry + k (``one_queue``: all in Geometry,
    ordered by random sort points), some tilted, some flat on two shared planes (ties where two of
    them are the nearest), under a transparent quad (step 1)."""
    rng = np.random.default_rng(seed)
    width, height = 40, 32
    renderers = []
    for k in range(6):
        flat = rng.random() < 0.4
        mesh = _tilted_quad(rng, width, height, flat_z=float(rng.choice([-1.0, 2.0])) if flat else None)
        material = sc.unlit(tuple(rng.uniform(0.05, 0.95, 3)) + (alpha_of(k, rng),), name=f"M{k}",
                            queue_offset=0 if one_queue else k, passes=[pass_of(k, rng)])
        r = sc.renderer(mesh, material, name=f"O{k}")
        if one_queue:
            r = replace(r, bounds_center=rng.uniform(-8, 8, 3))
        renderers.append(r)
    glass = sc.unlit((0.9, 0.9, 0.9, 0.4), queue=Queue.Transparent, name="Glass", passes=[BLEND])
    renderers.append(sc.renderer(sc.quad(0, 0, width, height, z=8.0), glass, name="Glass"))
    return sc.scene(sc.screen_camera(width, height), *renderers, clear_color=(0.1, 0.2, 0.3, 0.0))


def _reordered(scene, order):
    """``scene`` with opaque renderer k drawn at place ``order[k]`` (its material's queue offset)."""
    out = []
    for r in scene.renderers:
        if r.material.queue == Queue.Geometry:
            k = int(r.name[1:])
            r = replace(r, material=replace(r.material, queue_offset=int(order[k])))
        out.append(r)
    return replace(scene, renderers=tuple(out))


def _opaque_buffers(scene):
    last = max(c.index for c in draw_calls(scene) if c.queue <= 2500)
    snapshot = LastBuffers()
    render_scene(scene, until_draw=last, observer=snapshot)
    return snapshot.buffers


def _same(a, b) -> bool:
    return all(np.array_equal(getattr(a, name), getattr(b, name)) for name in ("color", "depth", "stencil"))


def _passes(seed_pass):
    def pass_of(k, rng):
        if seed_pass == "mixed":
            return [Pass(), Pass(ztest=CompareFunction.Less), ONE_ZERO][k % 3]
        return MTOON_OPAQUE
    return pass_of


@pytest.mark.parametrize("kind", ["mixed", "mtoon"])
def test_every_reordering_leaves_the_step1_buffers_where_the_order_is_proved_free(kind):
    proved = unproved = changed_when_unproved = 0
    for seed in range(14):
        scene = _opaque_scene(seed, _passes(kind))
        analysis = analyze(scene, keep_step1=True)
        rng = np.random.default_rng(100 + seed)
        orders = [rng.permutation(6) for _ in range(4)] + [np.arange(6)[::-1]]
        same = [_same(_opaque_buffers(_reordered(scene, order)), analysis.step1) for order in orders]
        if analysis.opaque_order_free:
            proved += 1
            assert all(same), seed
        else:
            unproved += 1
            changed_when_unproved += not all(same)
    # The random scenes hold both: coplanar quads tying at the nearest depth, and none.
    assert proved >= 3 and unproved >= 3
    assert changed_when_unproved >= 1  # a tie at the nearest depth does change the buffers


def test_a_tie_hidden_behind_a_nearer_quad_does_not_bar_the_proof():
    """Two coplanar quads tie everywhere they overlap, but a nearer quad covers all of it: the
    nearest depth is one call's at every pixel, and the order is free."""
    cam = sc.screen_camera(24, 16)
    tie_a = sc.renderer(sc.quad(0, 0, 14, 16, z=-2.0), sc.unlit((1, 0, 0, 1), name="MA"), name="A")
    tie_b = sc.renderer(sc.quad(6, 0, 20, 16, z=-2.0), sc.unlit((0, 1, 0, 1), name="MB", queue_offset=1), name="B")
    cover = sc.renderer(sc.quad(4, 0, 16, 16, z=1.0), sc.unlit((0, 0, 1, 1), name="MC", queue_offset=2), name="C")
    glass = sc.renderer(sc.quad(0, 0, 24, 16, z=5.0), sc.unlit((1, 1, 1, 0.5), queue=Queue.Transparent,
                                                               passes=[BLEND], name="MG"), name="G")
    assert analyze(sc.scene(cam, tie_a, tie_b, cover, glass), keep_step1=True).opaque_order_free
    uncovered = replace(cover, mesh=sc.quad(4, 0, 10, 16, z=1.0))  # leaves the tie at x 10..14 nearest
    assert not analyze(sc.scene(cam, tie_a, tie_b, uncovered, glass), keep_step1=True).opaque_order_free


def test_blendop_max_alpha_needs_one_alpha_value():
    """``BlendOp Add, Max``: the stored alpha is the largest written. A near quad of alpha 0.2 over a
    far one of 0.9 leaves 0.9 drawn far first (both written) but 0.2 drawn near first (the far one
    fails the depth test): not provable. With one alpha for both, the order is free."""
    cam = sc.screen_camera(16, 8)

    def scene(near_alpha, far_first):
        far = sc.renderer(sc.quad(0, 0, 16, 8, z=-1.0), sc.unlit((0, 0, 1, 0.9), name="MF", passes=[MTOON_OPAQUE],
                                                                 queue_offset=0 if far_first else 1), name="F")
        near = sc.renderer(sc.quad(0, 0, 16, 8, z=1.0), sc.unlit((1, 0, 0, near_alpha), name="MN",
                                                                 passes=[MTOON_OPAQUE],
                                                                 queue_offset=1 if far_first else 0), name="N")
        glass = sc.renderer(sc.quad(0, 0, 16, 8, z=5.0), sc.unlit((1, 1, 1, 0.5), queue=Queue.Transparent,
                                                                  passes=[BLEND], name="MG"), name="G")
        return sc.scene(cam, far, near, glass, clear_color=(0, 0, 0, 0))

    far_first, near_first = _opaque_buffers(scene(0.2, True)), _opaque_buffers(scene(0.2, False))
    alpha = lambda buf: np.unique(buf.color.view(np.uint8).reshape(-1, 4)[:, 3])  # noqa: E731
    assert alpha(far_first).tolist() == [round(0.9 * 255)] and alpha(near_first).tolist() == [round(0.2 * 255)]
    assert not analyze(scene(0.2, True), keep_step1=True).opaque_order_free
    assert analyze(scene(0.9, True), keep_step1=True).opaque_order_free
    assert _same(_opaque_buffers(scene(0.9, True)), _opaque_buffers(scene(0.9, False)))


def test_advice_resumes_a_proved_reordering_from_step1_and_measures_as_a_full_analysis(monkeypatch):
    """Sort-setting candidates reorder a tie-free opaque queue: every candidate's render resumes
    from the analysed step 1 (none draws the opaque queue again), and every measurement equals a
    full analysis."""
    renders = []  # the keyword arguments of each render the measurements make
    plain = advice.render_scene
    monkeypatch.setattr(advice, "render_scene", lambda s, **kw: renders.append(kw) or plain(s, **kw))
    checked = 0
    for seed in range(14):
        scene = _opaque_scene(seed, _passes("mixed"), one_queue=True)
        # Two transparent quads sharing a material in the wrong order: their fix is a sort setting,
        # which reorders the opaque queue too (one distance for both queues).
        wrong = [sc.renderer(sc.quad(0, 0, 30, 32, z=z), sc.unlit((r, 0.3, 0.6, 0.5), queue=Queue.Transparent,
                                                                  passes=[BLEND], name="Shared"), name=name)
                 for z, r, name in ((6.0, 0.9, "Near"), (4.0, 0.2, "Far"))]
        wrong[0] = replace(wrong[0], bounds_center=np.array([0.0, 0.0, -9.0]))
        wrong[1] = replace(wrong[1], bounds_center=np.array([0.0, 0.0, 9.0]))
        scene = replace(scene, renderers=scene.renderers + tuple(wrong))
        original = analyze(scene, keep_step1=True)
        if not original.opaque_order_free:
            continue
        pairs = [(inv.front, inv.behind) for inv in original.inversions[:5]]
        measurer = advice._Measurer(scene, original, pairs, None, None)
        full = _full_measure(original, pairs)  # analyses of their own, not through advice
        candidates = [changed for inv in original.inversions[:5] for changed in _candidates(scene, inv)]
        measurer.expect(candidates)
        reordered = 0
        for changed in candidates:
            calls = draw_calls(changed)
            reordered += measurer._opaque_prefix(advice._signature(changed, calls), calls) != measurer.opaque
            assert measurer.measure(changed) == full(changed), seed
        checked += reordered
    # Every render resumed from the analysed step 1: none drew an opaque queue.
    assert renders and all(kw.get("resume") is not None and kw.get("until_draw") is None for kw in renders)
    assert checked >= 3
