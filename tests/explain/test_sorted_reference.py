"""docs/sorting.md: the sorted reference equals the scalar reference's sorted mode bit for bit; sort error,
inversions and overdraw have the values their definitions give on scenes where they are known."""

from __future__ import annotations

import threading
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from blendlib import render_scene
from blendlib.core.drawlist import draw_calls
from blendlib.core.merger import Outcome
from blendlib.core.pipeline import FrameObserver
from blendlib.core.vocabulary import BlendFactor, CompareFunction, Cull, Pass, Queue, StencilOp, preset
from blendlib.explain import fragment_store
from blendlib.explain import sorted_reference as sr
from blendlib.explain.sorted_reference import analyze
from tests.reference import scenes as sc
from tests.reference.random_scenes import describe, scenes, seeded_scene
from tests.reference.scalar import render_sorted_reference

BLEND = Pass(blend=True, zwrite=False, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha)


def transparent(scene, every: int = 1):
    """The same scene with every ``every``-th renderer's material moved to the Transparent queue."""
    renderers = tuple(replace(r, material=replace(r.material, queue=Queue.Transparent, queue_offset=k % 3 - 1))
                      if k % every == 0 else r for k, r in enumerate(scene.renderers))
    return replace(scene, renderers=renderers)


def assert_reference(scene):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        result = analyze(scene)
        color, _, _ = render_sorted_reference(scene)
    assert result.reference.dtype == np.float32 and result.reference.shape == color.shape
    if not np.array_equal(result.reference, color):
        ys, xs = np.nonzero((result.reference != color).any(axis=-1))
        where = [(int(y), int(x), result.reference[y, x].tolist(), color[y, x].tolist())
                 for y, x in zip(ys, xs, strict=True)][:4]
        pytest.fail(f"{ys.size} pixels differ: {where}\n{describe(scene)}")
    return result


@pytest.mark.parametrize("seed", range(0, 120, 6))
def test_seeded_scenes_equal_the_scalar_sorted_reference(seed):
    assert_reference(seeded_scene(seed))
    assert_reference(transparent(seeded_scene(seed)))
    assert_reference(transparent(seeded_scene(seed + 1, shared=False), every=2))


@settings(max_examples=40, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(scenes())
def test_random_scenes_equal_the_scalar_sorted_reference(scene):
    assert_reference(transparent(scene, every=2))


@pytest.mark.parametrize("runs", [fragment_store.SPLIT_RUNS, 1 << 30], ids=["sorted", "runs"])
@pytest.mark.parametrize("msaa", [1, 4])
@pytest.mark.parametrize("seed", [42, 7])
def test_small_blocks_ranges_and_budgets_give_the_same_result(monkeypatch, seed, msaa, runs):
    """One row per block, a few fragments per working range, and a budget so small that every
    pass keeps one block (the rows above are rendered again, alone): the same analysis (with
    MSAA too: a block's pixels are its rows' samples), a chunk's pieces found by sorting its
    fragments by block or as runs of consecutive ones (``runs``)."""
    scene = transparent(seeded_scene(seed, msaa=msaa))
    whole = analyze(scene)
    monkeypatch.setattr(fragment_store, "SPLIT_RUNS", runs)
    monkeypatch.setattr(fragment_store, "BLOCK_PIXELS", 1)
    monkeypatch.setattr(sr, "WORK_FRAGMENTS", 5)
    monkeypatch.setattr(sr, "UNIT_FRAGMENTS", 1)
    passes = []
    real = fragment_store.FragmentCollector.__init__

    def counted(self, *args, **kwargs):
        passes.append(kwargs.get("first_block", 0))
        real(self, *args, **kwargs)

    monkeypatch.setattr(fragment_store.FragmentCollector, "__init__", counted)
    banded = analyze(scene, memory=1)
    assert len(passes) > 2 and passes == sorted(passes)  # pass k starts where pass k - 1 stopped
    for name in ("reference", "error", "overdraw", "inverted"):
        assert np.array_equal(getattr(whole, name), getattr(banded, name)), name
    assert whole.inversions == banded.inversions and np.array_equal(whole.frame.color, banded.frame.color)


@pytest.mark.parametrize("by_pass", [0, 1 << 16], ids=["sorted", "by-comparison"])
@pytest.mark.parametrize("seed", [18, 30, 60])
def test_layers_of_several_state_groups_split_either_way_equal_the_scalar_reference(monkeypatch, seed, by_pass):
    """Step 2 applies a layer's fragments state group by state group (a group: one pass state),
    split by one comparison per group or by a stable sort of their groups: the scalar sorted
    reference either way, on scenes whose layers hold several groups."""
    from blendlib.explain import layering

    monkeypatch.setattr(layering.ReferenceBlender, "GROUPS_BY_PASS", by_pass)
    groups = []
    real = layering.ReferenceBlender._apply

    def spy(self, g, *args):
        groups.append(g)
        return real(self, g, *args)

    monkeypatch.setattr(layering.ReferenceBlender, "_apply", spy)
    assert_reference(transparent(seeded_scene(seed)))
    assert len(set(groups)) >= 3


def test_colour_tables_of_consecutive_pieces_equal_each_piece_tabled_alone():
    """``fragment_store._color_tables``: pieces of kept colours tabled together equal each piece
    tabled by the definition (its distinct consecutive rows; a row's code ``-1 - entry``): a row
    repeating across a piece's start opens the piece's own table; empty pieces (also at the
    end) get empty tables; NaN never equals itself."""
    rng = np.random.default_rng(8)
    rows = rng.integers(0, 3, (40, 4)).astype(np.float64) / 2.0
    rows[10:14] = rows[9]  # a run crossing the start of the piece at 12
    rows[20, 1] = np.nan
    rows[21] = rows[20]
    starts = np.array([0, 5, 12, 12, 13, 30, 40, 40], dtype=np.int64)
    tables, codes, bounds = fragment_store._color_tables(rows, starts)
    ends = [*starts[1:].tolist(), rows.shape[0]]
    assert bounds.shape == (starts.size + 1,) and bounds[-1] == tables.shape[0]
    for k, (a, b) in enumerate(zip(starts.tolist(), ends, strict=True)):
        expected_table, expected_codes = [], []
        for r in range(a, b):
            if r == a or not np.array_equal(rows[r], rows[r - 1]):
                expected_table.append(rows[r])
            expected_codes.append(-len(expected_table))
        table = tables[bounds[k]:bounds[k + 1]]
        assert table.shape[0] == len(expected_table), k
        if expected_table:
            np.testing.assert_array_equal(table, np.array(expected_table))
        np.testing.assert_array_equal(codes[a:b], np.array(expected_codes, dtype=np.int32))


@pytest.mark.parametrize("runs", [fragment_store.SPLIT_RUNS, 1 << 30], ids=["sorted", "runs"])
def test_a_call_of_tabled_and_own_colours_kept_over_passes_equals_the_scalar_reference(monkeypatch, runs):
    """A transparent call whose triangles alternate one colour at every corner (kept as palette
    entries) and varying vertex colours (kept as their own rows), over rows of one block each and
    a budget of one block a pass, so that later passes keep a chunk from its middle: the scalar
    sorted reference, with the chunk's pieces sorted by block or taken as runs."""
    from blendlib.core.vocabulary import Lighting, Material, VertexColor

    rng = np.random.default_rng(4)
    cam = sc.screen_camera(40, 32)
    meshes = []
    for k in range(4):  # frame-wide quads: 640 fragments a triangle, enough for a blend table
        mesh = sc.quad(-3.0 * k, 0.0, 40.0 + 3.0 * k, 32.0, z=0.1 * k)
        colors = rng.uniform(0.1, 0.9, (2, 3, 4)).astype(np.float32)
        colors[k % 2] = colors[k % 2, :1]  # one triangle of one colour at its three corners
        meshes.append(replace(mesh, colors=colors))
    material = Material(name="Tinted", queue=Queue.Transparent, lighting=Lighting.Unlit,
                        vertex_color=VertexColor.Multiply, color=(1.0, 1.0, 1.0, 0.6), passes=(BLEND,))
    scene = sc.scene(cam, *(sc.renderer(m, material, name=f"Layer{k}") for k, m in enumerate(meshes)))
    whole = assert_reference(scene)
    monkeypatch.setattr(fragment_store, "SPLIT_RUNS", runs)
    monkeypatch.setattr(fragment_store, "BLOCK_PIXELS", 1)
    monkeypatch.setattr(sr, "UNIT_FRAGMENTS", 1)
    banded = analyze(scene, memory=1)
    assert np.array_equal(whole.reference, banded.reference) and whole.inversions == banded.inversions


def _two_quads(order_right: bool):
    """A red quad nearer than a blue one; ``order_right``: the blue (far) one drawn first."""
    cam = sc.screen_camera(16, 12)
    far = sc.renderer(sc.quad(0, 0, 10, 12, z=-1.0), sc.unlit((0, 0, 1, 0.5), queue=Queue.Transparent,
                                                              passes=[BLEND]), name="Blue")
    near = sc.renderer(sc.quad(6, 0, 16, 12, z=1.0), sc.unlit((1, 0, 0, 0.5), queue=Queue.Transparent,
                                                              passes=[BLEND]), name="Red")
    if not order_right:  # sort points that put the near quad behind the far one
        far = replace(far, bounds_center=np.array([0.0, 0.0, 9.0]))
        near = replace(near, bounds_center=np.array([0.0, 0.0, -9.0]))
    return sc.scene(cam, far, near)


def test_a_scene_in_correct_order_has_no_error_and_no_inversions():
    result = analyze(_two_quads(True))
    assert np.array_equal(result.reference, result.frame.color)
    assert result.differing == 0 and float(result.error.max()) == 0.0 and result.inversions == []
    assert result.advice == []


def test_two_quads_in_the_wrong_order():
    result = analyze(_two_quads(False))
    overlap = 4 * 12  # columns 6..9, all 12 rows
    assert [inv.as_json() for inv in result.inversions] == [
        {"front": "Red", "front_slot": 0, "behind": "Blue", "behind_slot": 0, "pixels": overlap}]
    assert np.array_equal(result.inverted > 0, np.pad(np.ones((12, 4), bool), ((0, 0), (6, 6))))
    # blue over red vs red over blue, alpha 0.5 on the (0.19, 0.30, 0.47, 0) clear colour: whole steps
    assert result.differing == overlap and np.all(result.error[:, 6:10] > 1)
    assert np.all(result.error[:, :6] == 0) and np.all(result.error[:, 10:] == 0)
    assert np.all(result.error == np.round(result.error))
    summary = result.summary()
    assert summary["pixels"] == 16 * 12 and summary["differing"] == overlap
    assert summary["max_error"] == float(result.error.max())
    assert summary["mean_error"] == pytest.approx(float(result.error.sum()) / (16 * 12))


@pytest.mark.parametrize("mask", ["depth", "stencil"])
def test_a_colourless_pass_in_the_sorted_queues_hides_only_the_frame(mask):
    """A ``ColorMask 0`` pass at queue 2990 (sorted, nearer) writes depth (or stencil 1, which the
    blue quad's ``Stencil Comp Equal`` asks for) where the blue quad, drawn after it, is alone.
    In the frame it hides the blue quad there (or shows it only there); in the reference it writes
    nothing (docs/sorting.md): the lone fragment must not take the frame's colour
    (:func:`sorted_reference.lone_fragments_as_frame`)."""
    cam = sc.screen_camera(16, 8)
    if mask == "depth":
        writer = Pass(color_mask=frozenset(), zwrite=True)
        blue_pass = BLEND
    else:
        writer = Pass(color_mask=frozenset(), zwrite=False, stencil=True, stencil_ref=1,
                      stencil_pass=StencilOp.Replace)
        blue_pass = replace(BLEND, stencil=True, stencil_ref=1, stencil_comp=CompareFunction.Equal)
    masker = sc.renderer(sc.quad(0, 0, 8, 8, z=2.0), sc.unlit((1, 1, 1, 1), queue=Queue.Transparent,
                                                               queue_offset=-10, passes=[writer]), name="Mask")
    blue = sc.renderer(sc.quad(4, 0, 16, 8, z=-2.0), sc.unlit((0, 0, 1, 0.5), queue=Queue.Transparent,
                                                               passes=[blue_pass]), name="Blue")
    scene = sc.scene(cam, masker, blue)
    assert sr.lone_fragments_as_frame(draw_calls(scene), 1) is False
    result = assert_reference(scene)
    # Only where the two quads overlap (columns 4..7) does the frame hide blue (depth) or show it
    # (stencil 1 written there); the reference tests blue against step 1's depth and stencil.
    assert np.array_equal((result.error > 1).any(axis=0), np.arange(16) // 4 == 1)


@pytest.mark.parametrize("hdr", [False, True])
def test_pixels_of_one_transparent_fragment_take_the_frame_colour(hdr):
    """Two overlapping blended quads: where one is alone, the reference takes the frame's own
    colour (8-bit codes or HDR floats) instead of blending it again; everything the analysis
    gives equals the scalar reference and the analysis without the shortcut."""
    scene = replace(_two_quads(False), hdr=hdr)
    assert sr.lone_fragments_as_frame(draw_calls(scene), 1) is True
    result = assert_reference(scene)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(sr, "lone_fragments_as_frame", lambda calls, samples: False)
        plain = analyze(scene)
    for name in ("reference", "error", "inverted", "overdraw"):
        assert np.array_equal(getattr(plain, name), getattr(result, name)), name
    assert plain.inversions == result.inversions


def test_units_wider_than_16_bits_of_pixels_give_the_same_analysis(monkeypatch):
    """Few fragments over many rows: one unit holds blocks of more than 65536 pixels in all (its
    pixels numbered in 32 bits, grouped without the radix sort). The same analysis as units of
    one block each, and the scalar reference."""
    cam = sc.screen_camera(320, 240)
    quads = []
    for k, y in enumerate((10, 120, 220)):  # one pair in each of three blocks of rows, in the wrong order
        far = sc.renderer(sc.quad(20 + 40 * k, y, 70 + 40 * k, y + 12, z=-1.0),
                          sc.unlit((0, 0, 1, 0.5), queue=Queue.Transparent, passes=[BLEND]), name=f"Far{k}")
        near = sc.renderer(sc.quad(40 + 40 * k, y + 4, 90 + 40 * k, y + 16, z=1.0),
                           sc.unlit((1, 0, 0, 0.5), queue=Queue.Transparent, passes=[BLEND]), name=f"Near{k}")
        quads += [replace(far, bounds_center=np.array([0.0, 0.0, 9.0])),
                  replace(near, bounds_center=np.array([0.0, 0.0, -9.0]))]
    scene = sc.scene(cam, *quads)
    widths = []
    real_take = fragment_store.FragmentCollector.take

    def take(self, unit, most):
        for block in real_take(self, unit, most):
            widths.append(block.local.dtype)
            yield block

    monkeypatch.setattr(fragment_store.FragmentCollector, "take", take)
    wide = assert_reference(scene)
    assert np.dtype(np.int32) in widths
    widths.clear()
    monkeypatch.setattr(fragment_store, "UNIT_PIXELS", 1)  # one block a unit
    narrow = analyze(scene)
    assert widths and set(widths) == {np.dtype(np.uint16)}
    for name in ("reference", "error", "inverted", "overdraw"):
        assert np.array_equal(getattr(wide, name), getattr(narrow, name)), name
    assert wide.inversions == narrow.inversions and len(wide.inversions) == 3 and wide.differing > 0


def _depth_alone(renderer, cam):
    opaque = replace(renderer, material=replace(renderer.material, queue=Queue.Geometry, passes=(Pass(),)))
    return render_scene(sc.scene(cam, opaque)).depth


def test_two_crossing_quads_give_exactly_the_crossing_pixels():
    """Two quads crossing in depth (an X seen from above): the one drawn first is nearer on one side."""
    cam = sc.screen_camera(16, 8)
    mat = sc.unlit((0.2, 0.9, 0.3, 0.4), queue=Queue.Transparent, passes=[BLEND])
    rising = sc.make_mesh([(0, 0, -4), (16, 0, 4), (16, 8, 4), (0, 8, -4)], [(0, 1, 2), (0, 2, 3)])
    falling = sc.make_mesh([(0, 0, 4), (16, 0, -4), (16, 8, -4), (0, 8, 4)], [(0, 1, 2), (0, 2, 3)])
    a, b = sc.renderer(rising, mat, name="A"), sc.renderer(falling, mat, name="B")
    scene = sc.scene(cam, a, b)
    assert [c.renderer.name for c in draw_calls(scene)] == ["A", "B"]  # same sort point: by name
    result = analyze(scene)
    da, db = _depth_alone(a, cam), _depth_alone(b, cam)
    expected = da < db  # A drawn first and nearer: (A, B) inverted
    assert 0 < expected.sum() < expected.size
    assert np.array_equal(result.inverted > 0, expected)
    assert [(i.front, i.behind, i.pixels) for i in result.inversions] == [(("A", 0), ("B", 0), int(expected.sum()))]


class _Counts(FrameObserver):
    def __init__(self, n):
        self.lock = threading.Lock()
        self.per_call: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.n = n

    def fragments(self, call, frags, outcome):
        with self.lock:
            r, w = self.per_call.setdefault(call.index, (np.zeros(self.n, np.int64), np.zeros(self.n, np.int64)))
            np.add.at(r, frags.pix, 1)
            np.add.at(w, frags.pix[outcome == Outcome.WRITTEN], 1)


@pytest.mark.parametrize("seed", [4, 9, 17])
def test_overdraw_equals_the_per_draw_fragment_counts(seed):
    scene = transparent(seeded_scene(seed), every=2)
    cam = scene.camera
    counts = _Counts(cam.width * cam.height)
    render_scene(scene, observer=counts)
    result = analyze(scene)
    assert result.overdraw.dtype == np.uint32 and result.overdraw.shape == (cam.height, cam.width, 2)
    for k in (0, 1):
        total = sum(v[k] for v in counts.per_call.values()) if counts.per_call else np.zeros(cam.width * cam.height)
        assert np.array_equal(result.overdraw[..., k], total.reshape(cam.height, cam.width)[::-1])
    assert result.overdraw[..., 0].sum() > 0 or not counts.per_call


def test_no_transparent_draws_reference_is_the_frame():
    cam = sc.screen_camera(8, 8)
    scene = sc.scene(cam, sc.renderer(sc.quad(0, 0, 8, 8), sc.unlit((1, 0, 0, 1))),
                     sc.renderer(sc.quad(2, 2, 6, 6, z=1), sc.unlit((0, 1, 0, 0.5), queue=Queue.Overlay,
                                                                       passes=[BLEND]), name="Hud"))
    result = analyze(scene)
    assert np.array_equal(result.reference, result.frame.color)
    assert result.differing == 0 and result.inversions == [] and result.advice == []
    assert np.array_equal(result.overdraw[..., 0], np.where(np.pad(np.ones((4, 4)), 2) > 0, 2, 1))


def test_overlay_tests_against_step_one_depth_and_its_own_writes():
    """An Overlay quad behind an opaque one is hidden; a transparent quad (no depth in step 2) is not."""
    cam = sc.screen_camera(8, 4)
    wall = sc.renderer(sc.quad(0, 0, 4, 4, z=0.0), sc.unlit((1, 1, 1, 1)), name="Wall")
    glass = sc.renderer(sc.quad(0, 0, 8, 4, z=2.0), sc.unlit((1, 0, 0, 0.5), queue=Queue.Transparent,
                                                             passes=[replace(BLEND, zwrite=True)]), name="Glass")
    hud = sc.renderer(sc.quad(0, 0, 8, 4, z=-1.0), sc.unlit((0, 0, 1, 1), queue=Queue.Overlay), name="Hud")
    scene = sc.scene(cam, wall, glass, hud)
    result = analyze(scene)
    color, _, _ = render_sorted_reference(scene)
    assert np.array_equal(result.reference, color)
    # the frame: Glass wrote depth, so Hud (farther than Glass) is hidden everywhere; in the
    # reference Glass writes no depth: Hud covers the right half, the wall hides it on the left
    assert np.all(result.frame.color[:, :, 2] < 1)
    assert np.all(result.reference[:, 4:, :3] == (0, 0, 1)) and np.all(result.reference[:, :4, 2] < 1)


def test_hdr_error_is_absolute():
    scene = replace(_two_quads(False), hdr=True)
    result = analyze(scene)
    diff = np.abs(result.frame.color.astype(np.float64) - result.reference.astype(np.float64)).max(axis=-1)
    assert np.array_equal(result.error, diff.astype(np.float32))
    assert 0 < float(result.error.max()) < 1 and result.differing == 4 * 12


def test_self_overlap_and_the_prepass():
    """A sphere drawn in one Cull Off call: self-overlap (A, A); the prepass removes the inversions."""
    cam = sc.camera(24, 24, eye=(0, 0, 4))
    ball = sc.renderer(sc.uv_sphere(1.0, 12, 8), sc.unlit((0.9, 0.6, 0.1, 0.4), queue=Queue.Transparent,
                                                           passes=[replace(BLEND, cull=Cull.Off)]),
                       name="Ball")
    result = analyze(sc.scene(cam, ball))
    assert result.inversions and all(i.self_overlap for i in result.inversions)
    queue, passes = preset("Alpha Blend ZWrite")
    prepass = replace(ball, material=replace(ball.material, queue=queue, passes=passes))
    fixed = analyze(sc.scene(cam, prepass))
    assert fixed.inversions == []
    # the price: only the front layer shows, unlike the sorted reference of the two-sided material
    price = sr.sort_error(fixed.frame.color, result.reference, False)
    assert np.count_nonzero(price > 1) > 0


def test_ztest_against_step_one_depth():
    cam = sc.screen_camera(8, 4)
    wall = sc.renderer(sc.quad(0, 0, 4, 4, z=0.0), sc.unlit((1, 1, 1, 1)), name="Wall")
    glass = sc.renderer(sc.quad(0, 0, 8, 4, z=-1.0), sc.unlit(
        (1, 0, 0, 1), queue=Queue.Transparent, passes=[replace(BLEND, ztest=CompareFunction.Greater)]), name="G")
    result = analyze(sc.scene(cam, wall, glass))
    assert np.all(result.reference[:, :4, :3] == (1, 0, 0))  # behind the wall: Greater passes there


class _Written(FrameObserver):
    """Every written fragment of queues 2501..3999 (ColorMask not 0) in the order applied."""

    def __init__(self):
        self.lock = threading.Lock()
        self.items = []

    def fragments(self, call, frags, outcome):
        if not (2500 < call.queue < 4000 and call.state.color_mask):
            return
        with self.lock:
            for pix, depth, out in zip(frags.pix.tolist(), frags.depth.tolist(), outcome.tolist(), strict=True):
                if out == Outcome.WRITTEN:
                    self.items.append((call.index, pix, depth, (call.renderer.name, call.renderer.slot)))


def layered_scene(seed: int):
    """Big overlapping transparent shapes (tilted quads, Cull Off spheres) at random depths, drawn
    in a random order (shuffled sort points): many layers and inversions per pixel."""
    rng = np.random.default_rng(seed)
    cam = sc.camera(16, 14, eye=(0, 0, 6))
    renderers = []
    for k in range(int(rng.integers(2, 6))):
        passes = []
        for _ in range(int(rng.integers(1, 3))):
            passes.append(replace(BLEND, cull=Cull.Off if rng.random() < 0.5 else Cull.Back,
                                  zwrite=bool(rng.random() < 0.3),
                                  ztest=CompareFunction.Always if rng.random() < 0.2 else CompareFunction.LEqual))
        color = tuple(float(v) for v in rng.random(3)) + (float(rng.uniform(0.2, 0.8)),)
        mat = sc.unlit(color, queue=Queue.Transparent, passes=passes, queue_offset=int(rng.integers(0, 2)))
        if rng.random() < 0.5:
            z0, z1 = rng.uniform(-1.5, 1.5, 2)
            mesh = sc.make_mesh([(-2, -2, z0), (2, -2, z1), (2, 2, z1), (-2, 2, z0)], [(0, 1, 2), (0, 2, 3)])
        else:
            mesh = sc.uv_sphere(float(rng.uniform(0.8, 1.6)), 10, 6)
        m = sc.translate(*rng.uniform(-0.8, 0.8, 3))
        r = sc.renderer(mesh, mat, name=f"R{k}", slot=int(rng.integers(0, 2)), matrix=m)
        renderers.append(replace(r, bounds_center=rng.uniform(-3, 3, 3)))
    return sc.scene(cam, *renderers)


@pytest.mark.parametrize("seed", range(6))
def test_layered_scenes_equal_the_scalar_sorted_reference(seed):
    result = assert_reference(layered_scene(seed))
    assert result.inversions and result.differing > 0


@pytest.mark.parametrize("seed", [*range(1, 60, 4), *(1000 + k for k in range(8))])
def test_inversions_equal_a_plain_pairwise_count(seed):
    scene = transparent(seeded_scene(seed), every=1) if seed < 1000 else layered_scene(seed)
    cam = scene.camera
    written = _Written()
    render_scene(scene, observer=written, workers=1)
    per_pixel: dict[int, list] = {}
    for _index, pix, depth, who in sorted(written.items, key=lambda t: t[0]):  # draw order (stable)
        per_pixel.setdefault(pix, []).append((depth, who))
    pairs: dict[tuple, int] = {}
    inverted = np.zeros(cam.width * cam.height, np.int64)
    for pix, seq in per_pixel.items():
        found = {(a[1], b[1]) for i, a in enumerate(seq) for b in seq[i + 1:] if a[0] < b[0]}
        inverted[pix] = len(found)
        for pair in found:
            pairs[pair] = pairs.get(pair, 0) + 1
    result = analyze(scene)
    assert {(i.front, i.behind): i.pixels for i in result.inversions} == pairs
    assert np.array_equal(result.inverted, inverted.reshape(cam.height, cam.width)[::-1])


@pytest.mark.parametrize("space", ["Gamma", "Linear"])
def test_the_reference_and_error_from_stored_codes_equal_those_of_the_float_outputs(space):
    """Every pair of 8-bit codes in every channel (and pixels where the codes agree):
    reference_from_codes (the analysis' LDR path) equals the reference buffers' float output and
    sort_error of the two outputs."""
    from blendlib.core.merger import FrameBuffers
    from blendlib.core.vocabulary import ColorSpace

    cs = ColorSpace[space]
    a = FrameBuffers(256, 260, False, cs, (0, 0, 0, 0))
    b = FrameBuffers(256, 260, False, cs, (0, 0, 0, 0))
    first, second = np.meshgrid(np.arange(256, dtype=np.uint8), np.arange(256, dtype=np.uint8))
    for c in range(4):  # each channel holds every pair once, in a different arrangement
        a.color[:65536, c] = np.roll(first.reshape(-1), 257 * c)
        b.color[:65536, c] = np.roll(second.reshape(-1), 257 * c)
    a.color[65536:] = b.color[65536:] = 77  # four rows where the codes agree
    frame, reference = a.output()[0], b.output()[0]
    expected = sr.sort_error(frame, reference, False)
    assert float(expected.max()) == 255.0 and not expected[:4].any()
    with ThreadPoolExecutor(max_workers=2) as pool:
        for parts in (1, 2):  # in one range, and in row ranges on two threads
            out, error = sr.reference_from_codes(frame, a, b, pool, parts)
            assert np.array_equal(out, reference) and out.dtype == np.float32
            assert np.array_equal(error, expected) and error.dtype == np.float32
            assert np.array_equal(sr.sort_error(frame, reference, False, pool, parts), expected)
    # Few pixels differ (the frame's values copied, those replaced): every 97th of the first rows.
    sparse = b.color.copy()
    sparse[:65536:97] = a.color[:65536:97]
    sparse[1::97, 2] ^= 1  # their neighbours differ by one step, in one channel
    a.color[:] = sparse
    frame = a.output()[0]
    expected = sr.sort_error(frame, reference, False)
    assert 0 < np.count_nonzero(expected) * sr.DIFFER_SHARE < expected.size
    out, error = sr.reference_from_codes(frame, a, b)
    assert np.array_equal(out, reference) and np.array_equal(error, expected)


def test_overdraw_and_inverted_images_in_row_ranges_equal_the_whole_frame_flipped():
    """The analysis' per-pixel images taken in row ranges on two threads (and in one range) are the
    counts' rows top first: rasterised, rasterised minus unwritten, inverted pairs."""
    from types import SimpleNamespace

    rng = np.random.default_rng(5)
    width, height = 37, 3 * sr.ERROR_ROWS + 5
    rasterised = rng.integers(0, 1000, width * height).astype(np.uint32)
    unwritten = (rasterised * rng.random(width * height)).astype(np.uint32)
    inverted = rng.integers(0, 60000, width * height).astype(np.uint16)
    for pool in (None, ThreadPoolExecutor(max_workers=2)):
        counts = SimpleNamespace(rasterised=rasterised.copy(), unwritten=unwritten.copy())
        overdraw, flipped = sr._overdraw_and_inverted(counts, inverted, height, width, pool, 2)
        assert np.array_equal(overdraw[..., 0], rasterised.reshape(height, width)[::-1])
        assert np.array_equal(overdraw[..., 1], (rasterised - unwritten).reshape(height, width)[::-1])
        assert np.array_equal(flipped, inverted.reshape(height, width)[::-1]) and flipped.dtype == np.uint16
        if pool is not None:
            pool.shutdown()


@pytest.mark.parametrize("msaa", [1, 4])
def test_step1_snapshot_holds_the_opaque_buffers_sharing_depth_only_when_nothing_later_writes_it(msaa):
    """The step-1 snapshot (the buffers after the opaque queue, which step 2 and the advice
    resume from) equals a render stopped there, colour, depth and stencil, in random scenes.
    It shares the frame's depth and stencil arrays exactly when no later call has ZWrite On
    or a stencil block; a later call that writes depth leaves it a copy of its own (sharing
    then would hand step 2 and the advice the frame's final depth)."""
    shared = own = 0
    for seed in range(40):
        scene = seeded_scene(seed, msaa=msaa)
        calls = draw_calls(scene)
        firsts = [c.index for c in calls if c.queue > 2500]
        if not firsts or not any(c.queue <= 2500 for c in calls):
            continue
        last_opaque = max(c.index for c in calls if c.queue <= 2500)
        snapshot = sr.LastBuffers()
        render_scene(scene, until_draw=last_opaque, observer=snapshot)
        expected = snapshot.buffers
        later_writes = any(c.state.zwrite or c.state.stencil for c in calls if c.index >= min(firsts))
        cam = scene.camera
        collector = fragment_store.FragmentCollector(calls, int(cam.width), int(cam.height), 1 << 30, samples=msaa)
        render_scene(scene, observer=collector, calls=calls)
        step1 = collector.step1
        assert collector.step1_shares_depth == (not later_writes)
        assert np.shares_memory(step1.depth, collector.final.depth) == (not later_writes)
        for name in ("color", "depth", "stencil"):
            np.testing.assert_array_equal(getattr(step1, name), getattr(expected, name), err_msg=f"seed {seed} {name}")
        kept = analyze(scene, keep_step1=True).step1  # None without sorted calls: nothing to resume
        for name in ("color", "depth", "stencil") if kept is not None else ():
            np.testing.assert_array_equal(getattr(kept, name), getattr(expected, name), err_msg=f"seed {seed} {name}")
        shared += not later_writes
        own += later_writes
    assert shared >= 3 and own >= 3
