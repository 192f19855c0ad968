"""Frames split across processes (blendlib.runtime.bandprocs); render_scene's ``band`` itself
is tested in tests/core/test_band_renders.py.

The split frame must equal one render_scene bit for bit, whatever the cut; the helper process
must stop on cancel, survive errors and, when it dies, leave frames to this process.
"""

from __future__ import annotations

import dataclasses
import io
import os
import pickle
import threading
import time
from multiprocessing import Pipe

import numpy as np
import pytest

from blendlib import RenderCancelled, SceneError, render_scene
from blendlib.core.pipeline import CHUNK_CANDIDATES
from blendlib.core.scene import reuse_unchanged, scene_parts
from blendlib.runtime import bandprocs
from blendlib.runtime.bandprocs import BandRenderer, balanced_fraction
from tests.reference.random_scenes import seeded_scene

WAIT = 30.0


def scene_at(seed: int, width: int = 72, height: int = 48):
    draw = seeded_scene(seed)
    return dataclasses.replace(draw, camera=dataclasses.replace(draw.camera, width=width, height=height))


def assert_same_frame(a, b) -> None:
    np.testing.assert_array_equal(a.color, b.color)
    np.testing.assert_array_equal(a.depth, b.depth)
    np.testing.assert_array_equal(a.stencil, b.stencil)
    assert a.warnings == b.warnings
    assert a.encoded == b.encoded


@pytest.fixture(scope="module")
def bands():
    renderer = BandRenderer(min_pixels=0)
    assert renderer.wait_ready(WAIT), renderer.failure
    yield renderer
    renderer.close()


@pytest.mark.parametrize("seed", [1, 3, 4, 7, 9, 12])
def test_split_frames_equal_render_scene(bands, seed):
    draw = scene_at(seed)
    before = bands.split_frames
    assert_same_frame(bands(draw), render_scene(draw))
    assert bands.split_frames == before + 1


def moved(camera, dx: float):
    """The camera moved sideways by ``dx`` (a new view matrix, same projection)."""
    view = np.array(camera.view_matrix, dtype=np.float64)
    view[0, 3] += dx
    return dataclasses.replace(camera, view_matrix=view)


def split_frames_of(renderer: BandRenderer, draw, count: int):
    """Render ``draw`` ``count`` times through ``renderer`` (its helper started): each frame
    equals render_scene and is drawn in two bands. Returns ``draw``."""
    assert renderer.wait_ready(WAIT)
    split = renderer.split_frames
    for _ in range(count):
        assert_same_frame(renderer(draw), render_scene(draw))
    assert renderer.split_frames == split + count
    return draw


def recorded_requests(monkeypatch) -> tuple[list[str], list[int]]:
    """The kinds ("scene", "view") of the requests sent to helpers from now on, and their sizes in bytes."""
    kinds, sizes = [], []
    real = bandprocs._PartsWriter.dumps

    def dumps(self, request, scene):
        data = real(self, request, scene)
        kinds.append(request[0])
        sizes.append(len(data))
        return data

    monkeypatch.setattr(bandprocs._PartsWriter, "dumps", dumps)
    return kinds, sizes


def test_view_changes_send_only_the_camera(bands, monkeypatch):
    """A frame that differs from the last only in its camera sends the camera alone, and its
    pixels are those of the new view; any other change sends the whole scene."""
    sent, _ = recorded_requests(monkeypatch)
    template = scene_at(12)
    views = [template, dataclasses.replace(template, camera=moved(template.camera, 0.3)),
             dataclasses.replace(template, camera=moved(template.camera, -0.2))]
    for view in views:
        assert_same_frame(bands(view), render_scene(view))
    assert sent == ["scene", "view", "view"]
    assert not np.array_equal(render_scene(views[1]).color, render_scene(views[2]).color)
    fewer = dataclasses.replace(views[2], renderers=views[2].renderers[1:])
    assert_same_frame(bands(fewer), render_scene(fewer))
    assert sent[-1] == "scene"


def test_changed_scenes_send_only_their_new_parts(bands, monkeypatch):
    """After reuse_unchanged, a changed scene sends the helper its new parts only (the rest by
    number), the helper forgets parts no longer used, and every frame equals render_scene."""
    messages = []
    real = bandprocs._PartsWriter.dumps
    monkeypatch.setattr(bandprocs._PartsWriter, "dumps",
                        lambda self, request, scene: messages.append(real(self, request, scene)) or messages[-1])

    def new_parts() -> tuple[list[int], int]:
        return parts_sent(messages[-1])

    first = scene_at(8)  # four renderers, three textured
    assert len(first.renderers) == 4
    assert_same_frame(bands(first), render_scene(first))
    parts = len(scene_parts(first))
    assert new_parts()[1] == parts  # every part, the earlier tests' parts forgotten
    assert pickle.Unpickler(io.BytesIO(messages[-1])).load()[1] == -1  # in one plain pickle: none held
    # Extracted again (all new objects, equal content), one object moved: one new renderer.
    again = pickle.loads(pickle.dumps(first))
    r0 = again.renderers[0]
    matrix = np.array(r0.matrix_world, dtype=np.float64)
    matrix[0, 3] += 0.05
    moved_scene = reuse_unchanged(dataclasses.replace(again, renderers=(
        dataclasses.replace(r0, matrix_world=matrix), *again.renderers[1:])), first)
    assert moved_scene.renderers[1:] == first.renderers[1:]
    assert_same_frame(bands(moved_scene), render_scene(moved_scene))
    forgotten, sent = new_parts()
    assert sent == 1 and len(forgotten) == 1  # the moved renderer for the old one
    # Read as the helper reads them: the unchanged parts are the very objects it already holds.
    reader = bandprocs._PartsReader()
    held, now = (reader.loads(m)[1] for m in messages[-2:])
    assert all(a is b for a, b in zip(now.renderers[1:], held.renderers[1:], strict=True))
    assert now.renderers[0] is not held.renderers[0] and now.renderers[0].mesh is held.renderers[0].mesh
    assert len(messages[-1]) < len(messages[-2]) // 4
    # One mesh changed: the mesh and its renderer are new, the old ones forgotten.
    r1 = moved_scene.renderers[1]
    mesh = dataclasses.replace(r1.mesh, positions=np.asarray(r1.mesh.positions) * np.float32(1.1))
    reshaped = reuse_unchanged(dataclasses.replace(moved_scene, renderers=(
        moved_scene.renderers[0], dataclasses.replace(r1, mesh=mesh), *moved_scene.renderers[2:])), moved_scene)
    assert_same_frame(bands(reshaped), render_scene(reshaped))
    forgotten, sent = new_parts()
    shared_mesh = any(r.mesh is r1.mesh for r in reshaped.renderers)
    assert sent == 2 and len(forgotten) == (1 if shared_mesh else 2)
    # A renderer dropped and brought back: forgotten, then sent again whole.
    fewer = dataclasses.replace(reshaped, renderers=reshaped.renderers[:-1])
    assert_same_frame(bands(fewer), render_scene(fewer))
    assert new_parts()[1] == 0 and len(new_parts()[0]) >= 1
    assert_same_frame(bands(reshaped), render_scene(reshaped))
    assert new_parts() == ([], len(new_parts_of(reshaped.renderers[-1], fewer)))


def parts_sent(message: bytes) -> tuple[list[int], int]:
    """(numbers the helper may forget, parts sent) of a request message, in either form."""
    stream = io.BytesIO(message)
    forgotten, count = pickle.Unpickler(stream).load()
    if count < 0:  # one plain pickle of (first number, new parts, request)
        count = len(pickle.Unpickler(stream).load()[1])
    return forgotten, count


def new_parts_of(renderer, scene) -> list[object]:
    """The parts of ``renderer`` that ``scene`` does not hold."""
    held = {id(p) for p in scene_parts(scene)}
    return [p for p in scene_parts(dataclasses.replace(scene, renderers=(renderer,))) if id(p) not in held]


def test_large_requests_wait_in_the_shared_file_and_the_connection_carries_their_length(monkeypatch):
    """A request of SHARED_REQUEST_BYTES or more is written into the shared file, where the band's
    rows will go, and the connection carries only its length: the helper reads it from there
    (the file grown, and the helper's mapping with it, when the request is larger than the
    band) before it draws over it. Frames equal render_scene, a final renderer's drops between
    them; below the limit requests go through the connection again."""
    wire = []
    real = BandRenderer._write
    monkeypatch.setattr(BandRenderer, "_write", lambda self, helper, message: wire.append(message) or real(
        self, helper, message))
    monkeypatch.setattr(bandprocs, "SHARED_REQUEST_BYTES", 1)
    renderer = BandRenderer(min_pixels=0, keep_scene=False)
    try:
        assert renderer.wait_ready(WAIT)
        tiny = scene_at(5, 16, 8)  # a whole frame of a few thousand bytes: the scene is larger
        larger = scene_at(8, 16, 8)  # four renderers, three textured: a larger request again
        for draw in (tiny, larger, scene_at(11, 240, 160)):
            grown = renderer._helper.size
            assert_same_frame(renderer(draw), render_scene(draw))
            assert renderer.split_frames and renderer.failure is None  # drawn by the helper too
            scene_request = wire[-2]  # then the drop
            assert scene_request.startswith(bandprocs._SHARED_REQUEST)
            assert len(scene_request) == len(bandprocs._SHARED_REQUEST) + 8
            if draw is not tiny and draw.camera.width == 16:
                assert renderer._helper.size > max(grown, bandprocs._band_bytes(8, 16))
        assert renderer.split_frames == 3
        monkeypatch.setattr(bandprocs, "SHARED_REQUEST_BYTES", 1 << 40)
        assert_same_frame(renderer(tiny), render_scene(tiny))
        assert renderer.split_frames == 4 and wire[-2][:1] == b"\x80"  # a pickle, through the connection
    finally:
        renderer.close()


def test_a_request_that_could_not_be_sent_leaves_the_helper_whole(monkeypatch):
    """A request made and never sent (here the shared file cannot grow) raises, and the writer
    forgets which parts the helper holds: the next request sends the scene whole and the helper
    draws it. Kept counting the unsent parts as held, it would send them by number and the
    helper, lacking them, would stop."""
    renderer = BandRenderer(min_pixels=0)
    try:
        assert renderer.wait_ready(WAIT)
        first = scene_at(8)
        assert_same_frame(renderer(first), render_scene(first))
        r0 = first.renderers[0]
        matrix = np.array(r0.matrix_world, dtype=np.float64)
        matrix[0, 3] += 0.05
        moved_scene = dataclasses.replace(first, renderers=(dataclasses.replace(r0, matrix_world=matrix),
                                                            *first.renderers[1:]))  # one new part, the rest held
        helper = renderer._helper

        def no_room(size):
            raise OSError("no room for the shared file")

        monkeypatch.setattr(helper, "reserve", no_room)
        with pytest.raises(OSError, match="no room"):
            renderer(moved_scene)
        monkeypatch.undo()
        assert_same_frame(renderer(moved_scene), render_scene(moved_scene))
        assert renderer.split_frames == 2 and renderer.failure is None and renderer._helper is helper
    finally:
        renderer.close()


def test_after_a_refused_scene_the_next_view_sends_the_scene_again(bands, monkeypatch):
    sent, _ = recorded_requests(monkeypatch)
    template = scene_at(3)
    bad = dataclasses.replace(template, camera=dataclasses.replace(template.camera,
                                                                   view_matrix=np.full((4, 4), np.nan)))
    with pytest.raises(SceneError, match="view_matrix"):
        bands(bad)
    good = dataclasses.replace(bad, camera=template.camera)  # the same renderers, a good camera
    assert_same_frame(bands(good), render_scene(good))
    assert sent == ["scene", "scene"]


def test_cut_follows_the_measured_times(bands):
    """Whatever the cut, the frame is the same; the cut moves towards where both bands end together."""
    draw = scene_at(9)
    expected = render_scene(draw)
    for fraction in (0.02, 0.3, 0.97):
        bands.fraction = fraction
        assert_same_frame(bands(draw), expected)
    bands.fraction = 0.5
    # 24 of 48 rows each: 30 ms here, 10 ms in the helper -> 1.25 and 0.42 ms a row; both end
    # together at 12 rows here; half way from 24 rows is 18.
    assert balanced_fraction(0.5, 24, 48, own_s=0.030, helper_s=0.010) == pytest.approx(18 / 48)
    assert balanced_fraction(0.5, 24, 48, own_s=0.010, helper_s=0.030) == pytest.approx(30 / 48)
    # The helper started 10 ms earlier (its band begun during another frame): 0.625 ms a row
    # each, 10 ms are 16 rows of head start, so 16 fewer here: 16 rows, half way 20.
    assert balanced_fraction(0.5, 24, 48, own_s=0.015, helper_s=0.015, lead_s=0.010) == pytest.approx(20 / 48)
    assert balanced_fraction(0.95, 24, 48, own_s=0.001, helper_s=0.300) == 0.95  # clamped
    assert balanced_fraction(0.05, 24, 48, own_s=0.015, helper_s=0.015, lead_s=1.0) == 0.05
    assert balanced_fraction(0.3, 24, 48, own_s=0.0, helper_s=0.0) == 0.3  # nothing measured


def test_a_begun_band_is_collected_by_the_call_for_its_frame(bands):
    """begin() starts the helper on a frame's band; smaller frames render here meanwhile; the
    call for that very scene joins the bands (as the viewport does with its reduced frame)."""
    full = scene_at(7, 96, 64)
    small = scene_at(7, 24, 16)
    bands.min_pixels = 1000
    try:
        before_split, before_begun = bands.split_frames, bands.begun_frames
        assert bands.begin(full)
        assert_same_frame(bands(small), render_scene(small))  # in this process, the band still pending
        assert bands._pending is not None and bands._pending.scene is full
        assert_same_frame(bands(full), render_scene(full))
        assert (bands.split_frames, bands.begun_frames) == (before_split + 1, before_begun + 1)
        assert not bands.begin(small)  # too small to split
    finally:
        bands.min_pixels = 0


def test_a_begun_band_of_another_frame_is_dropped(bands):
    first, second, third = scene_at(3, 80, 60), scene_at(4, 80, 60), scene_at(12, 80, 60)
    before_begun = bands.begun_frames
    assert bands.begin(first)
    assert_same_frame(bands(second), render_scene(second))  # another large frame: first's band dropped
    assert bands.begin(first)
    assert bands.begin(third)  # a later begin drops the earlier one
    assert_same_frame(bands(third), render_scene(third))
    assert bands.begun_frames == before_begun + 1
    assert_same_frame(bands(first), render_scene(first))  # the helper serves on


def test_close_stops_a_begun_band():
    renderer = BandRenderer(min_pixels=0)
    assert renderer.wait_ready(WAIT)
    assert renderer.begin(scene_at(7, 640, 480))
    proc = renderer._helper.proc
    renderer.close()
    assert proc.wait(timeout=WAIT) == 0
    assert renderer._pending is None


def test_small_frames_and_other_options_stay_in_this_process():
    renderer = BandRenderer(min_pixels=10_000, start=False)
    try:
        draw = scene_at(3)  # 72x48 < 10000 pixels
        assert_same_frame(renderer(draw), render_scene(draw))
        assert renderer._helper is None and renderer.split_frames == 0
        renderer.min_pixels = 0
        assert_same_frame(renderer(draw, until_draw=1), render_scene(draw, until_draw=1))
        assert renderer.split_frames == 0
    finally:
        renderer.close()


def test_a_changed_scene_keeps_the_memo_of_its_unchanged_parts(monkeypatch):
    """Frames of a changed template (reuse_unchanged) check only the renderers that changed."""
    from blendlib.core import scene as scene_module

    renderer = BandRenderer(min_pixels=10**9, start=False)  # every frame in this process
    checked = []
    real = scene_module._validate_renderer
    monkeypatch.setattr(scene_module, "_validate_renderer", lambda r: checked.append(r) or real(r))
    try:
        draw = scene_at(8)
        renderer(draw)
        assert len(checked) == len(draw.renderers)
        matrix = np.array(draw.renderers[2].matrix_world, dtype=np.float64)
        matrix[2, 3] += 0.1
        again = pickle.loads(pickle.dumps(draw))
        moved_scene = reuse_unchanged(dataclasses.replace(again, renderers=(
            *again.renderers[:2], dataclasses.replace(again.renderers[2], matrix_world=matrix), *again.renderers[3:])),
            draw)
        assert_same_frame(renderer(moved_scene), render_scene(moved_scene))
        assert checked[len(draw.renderers):-len(moved_scene.renderers)] == [moved_scene.renderers[2]]
    finally:
        renderer.close()


def test_scene_errors_come_back_as_scene_errors(bands):
    draw = scene_at(4)
    broken = dataclasses.replace(draw.renderers[0], matrix_world=np.full((4, 4), np.nan))
    bad = dataclasses.replace(draw, renderers=(broken, *draw.renderers[1:]))
    with pytest.raises(SceneError) as direct:
        render_scene(bad)
    with pytest.raises(SceneError) as split:
        bands(bad)
    assert str(split.value) == str(direct.value)
    assert_same_frame(bands(draw), render_scene(draw))  # the helper serves on


class _NaNWhenUnpickled(np.ndarray):
    """A finite matrix here that arrives as NaN in the helper: a scene only the helper refuses."""

    def __reduce__(self):
        return np.full, (self.shape, np.nan)


def test_an_error_answer_from_the_helper_alone_is_raised_and_the_scene_sent_again(bands, monkeypatch):
    """The helper refuses a scene this process accepted: the frame raises the helper's SceneError,
    the helper is not failed, and it holds no scene after the refusal — the same scene through
    another camera is sent whole (refused again, not a view of a scene it never took), and a good
    frame after splits and equals render_scene."""
    sent, _ = recorded_requests(monkeypatch)
    draw = scene_at(7)
    poisoned = dataclasses.replace(draw.renderers[0],
                                   matrix_world=np.asarray(draw.renderers[0].matrix_world).view(_NaNWhenUnpickled))
    bad = dataclasses.replace(draw, renderers=(poisoned, *draw.renderers[1:]))
    render_scene(bad)  # this process accepts it
    with pytest.raises(SceneError, match="matrix_world"):
        bands(bad)
    moved_bad = dataclasses.replace(bad, camera=moved(bad.camera, 0.05))
    with pytest.raises(SceneError, match="matrix_world"):
        bands(moved_bad)
    assert sent == ["scene", "scene"] and bands.failure is None
    before = bands.split_frames
    assert_same_frame(bands(draw), render_scene(draw))
    assert bands.split_frames == before + 1


def test_cancel_stops_both_bands_and_the_helper_serves_on(bands):
    draw = scene_at(7, 160, 120)
    calls = []

    def should_cancel() -> bool:  # True from this process's first check in its own band (so
        calls.append(1)  # always before the frame ends, however fast the helper is)
        return True

    with pytest.raises(RenderCancelled):
        bands(draw, should_cancel=should_cancel)
    assert calls
    before = bands.split_frames
    assert_same_frame(bands(draw), render_scene(draw))
    assert bands.split_frames == before + 1


def test_a_dead_helper_leaves_frames_to_this_process():
    renderer = BandRenderer(min_pixels=0)
    try:
        assert renderer.wait_ready(WAIT)
        draw = scene_at(12)
        renderer._helper.proc.kill()
        renderer._helper.proc.wait()
        assert_same_frame(renderer(draw), render_scene(draw))
        assert renderer.failure is not None and "exited" in renderer.failure
        assert renderer._helper is None
        assert_same_frame(renderer(draw), render_scene(draw))
        assert renderer.split_frames == 0
    finally:
        renderer.close()


def test_a_helper_that_dies_while_its_begun_band_is_collected_leaves_the_frame_to_this_process(monkeypatch):
    """A band begun for one frame, then a frame of another scene: the helper, alive when the frame
    starts, dies while its begun band is being collected. The frame renders here: no request goes
    to the closed helper (whose shared file is closed: writing the stop flag raised)."""
    renderer = BandRenderer(min_pixels=0)
    try:
        assert renderer.wait_ready(WAIT)
        begun, other = scene_at(12), scene_at(3)
        assert renderer.begin(begun)
        collect = renderer._drop_pending

        def dying(helper):
            helper.proc.kill()
            helper.proc.wait()
            collect(helper)

        monkeypatch.setattr(renderer, "_drop_pending", dying)
        assert_same_frame(renderer(other), render_scene(other))
        assert renderer.failure is not None and renderer._helper is None and renderer.split_frames == 0
    finally:
        renderer.close()


def test_close_ends_the_helper_and_frames_go_on_here():
    renderer = BandRenderer(min_pixels=0)
    assert renderer.wait_ready(WAIT)
    proc = renderer._helper.proc
    helper = renderer._helper
    renderer.close()
    renderer.close()  # idempotent
    assert proc.wait(timeout=WAIT) == 0
    spare = os.open(os.devnull, os.O_RDONLY)  # may take the shared file's old descriptor number
    try:
        helper.close()  # what the finalizer does at exit: must not close a reused descriptor
        os.fstat(spare)
    finally:
        os.close(spare)
    draw = scene_at(1)
    assert_same_frame(renderer(draw), render_scene(draw))
    assert renderer.split_frames == 0


def test_final_renders_split_and_leave_no_scene_in_either_process(monkeypatch):
    """A renderer that keeps no scene (final renders): the frame equals render_scene, then the
    memo is gone here and the helper has dropped the scene, so the same scene again is sent
    whole and a bare view request is refused by the helper."""
    sent, _ = recorded_requests(monkeypatch)
    renderer = BandRenderer(min_pixels=0, keep_scene=False)
    try:
        draw = split_frames_of(renderer, scene_at(9, 96, 64), 2)
        assert sent == ["scene", "drop", "scene", "drop"]
        assert renderer._memo is None and not renderer._helper.holding
        helper = renderer._helper
        helper.conn.send_bytes(helper.parts.dumps(("view", draw.camera, 1, 64, 4096, False), None))
        assert helper.conn.poll(WAIT)
        assert bandprocs._receive(helper.conn) == ("failed", "RuntimeError: a view request before any scene")
    finally:
        renderer.close()


def test_waiting_after_a_drop_gives_the_freed_heap_back_only_when_idle(monkeypatch):
    """_await_request: a request that arrives within the idle time finds the freed heap kept;
    once that time passes without one, the heap goes back to the system, once; without a drop
    before the wait (no idle time given), never."""
    trims = []
    monkeypatch.setattr(bandprocs.allocator, "give_back_freed_memory", lambda: trims.append(1) or True)
    ours, theirs = Pipe()
    try:
        theirs.send_bytes(b"waiting")
        bandprocs._await_request(ours, 30.0)  # a request already there: at once, nothing given back
        assert trims == [] and ours.recv_bytes() == b"waiting"
        for message, idle, trimmed in ((b"late", 0.05, [1]), (b"no drop before", None, [1])):
            timer = threading.Timer(0.3, theirs.send_bytes, (message,))
            timer.start()
            bandprocs._await_request(ours, idle)
            timer.join()
            assert trims == trimmed and ours.recv_bytes() == message
    finally:
        ours.close()
        theirs.close()


def _resident_mib(pid: int) -> float:
    """Resident memory of process ``pid`` (MiB), from /proc."""
    with open(f"/proc/{pid}/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("VmRSS:")) / 1024


@pytest.mark.skipif(not os.path.exists("/proc/self/status") or bandprocs.allocator._glibc() is None,
                    reason="reads the helper's resident memory from /proc; glibc's allocator gives it back")
def test_a_final_frames_helper_keeps_its_freed_heap_while_frames_follow_then_gives_it_back():
    """After a final frame the helper drops its scene but keeps the heap it freed for
    IDLE_TRIM_S, so that a frame following soon reuses its pages (instead of faulting zeroed ones
    in): half a second after the frame its resident memory has not fallen. Idle past that time,
    the heap goes back to the system: it falls."""
    renderer = BandRenderer(min_pixels=0, keep_scene=False)
    try:
        split_frames_of(renderer, scene_at(9, 960, 540), 2)
        pid = renderer.helper_pid
        held = _resident_mib(pid)
        time.sleep(0.5)
        assert _resident_mib(pid) > held - 5.0, held
        deadline = time.monotonic() + bandprocs.IDLE_TRIM_S + 10.0
        while _resident_mib(pid) > held - 5.0 and time.monotonic() < deadline:
            time.sleep(0.1)
        assert _resident_mib(pid) <= held - 5.0, (held, _resident_mib(pid))
    finally:
        renderer.close()


def test_both_bands_draw_chunks_of_the_renderers_size(monkeypatch):
    sizes, requests = [], []
    real_render, real_dumps = bandprocs.pipeline.render_scene, bandprocs._PartsWriter.dumps
    monkeypatch.setattr(bandprocs.pipeline, "render_scene",
                        lambda scene, **kw: sizes.append(kw.get("chunk_candidates")) or real_render(scene, **kw))
    monkeypatch.setattr(bandprocs._PartsWriter, "dumps",
                        lambda self, request, scene: requests.append(request) or real_dumps(self, request, scene))
    renderer = BandRenderer(min_pixels=0, chunk_candidates=5000)
    try:
        assert renderer.wait_ready(WAIT)
        draw = scene_at(6, 96, 64)
        assert_same_frame(renderer(draw), render_scene(draw))
        assert renderer.split_frames == 1 and sizes == [5000] and requests[0][4] == 5000
    finally:
        renderer.close()


def test_scenes_over_the_triangle_limit_render_in_this_process():
    draw = scene_at(12, 96, 64)
    triangles = sum(r.mesh.triangle_count for r in draw.renderers)
    renderer = BandRenderer(min_pixels=0, max_triangles=triangles - 1)
    try:
        assert renderer.wait_ready(WAIT)
        assert_same_frame(renderer(draw), render_scene(draw))
        assert renderer.split_frames == 0
        renderer.max_triangles = triangles  # at the limit: split
        assert_same_frame(renderer(draw), render_scene(draw))
        assert renderer.split_frames == 1
    finally:
        renderer.close()


def test_forget_tables_clears_them_here_and_asks_the_helper_once(bands, monkeypatch):
    from blendlib.core import merger

    requests = []
    real = bandprocs._PartsWriter.dumps
    monkeypatch.setattr(bandprocs._PartsWriter, "dumps",
                        lambda self, request, scene: requests.append(request) or real(self, request, scene))
    draw = scene_at(1)
    bands(draw)
    bands.forget_tables()
    assert not merger.RECENT_TABLES._tables
    for _ in range(2):
        assert_same_frame(bands(draw), render_scene(draw))
    assert [r[-1] for r in requests] == [False, True, False]


def test_an_interrupted_wait_collects_the_helpers_answer(bands, monkeypatch):
    """KeyboardInterrupt while waiting for the helper's band: its answer is read then, so the
    next frame joins its own band, not the interrupted one's."""
    draw = scene_at(7, 160, 120)
    real_wait = bandprocs.wait
    interrupts = [1]

    def interrupted(connections, timeout):
        if interrupts:
            interrupts.pop()
            raise KeyboardInterrupt
        return real_wait(connections, timeout)

    monkeypatch.setattr(bandprocs, "wait", interrupted)
    with pytest.raises(KeyboardInterrupt):
        bands(draw)
    assert bands.failure is None
    assert_in_step_after_an_interrupt(bands)


def assert_in_step_after_an_interrupt(bands) -> None:
    """The next frames are split and equal render_scene, and no answer is left unread."""
    before = bands.split_frames
    for seed in (3, 5):
        other = scene_at(seed, 160, 120)
        assert_same_frame(bands(other), render_scene(other))
        assert not bands._helper.conn.poll(0.2)
    assert bands.split_frames == before + 2


def test_an_interrupt_between_sending_a_band_and_joining_it_collects_the_answer(bands, monkeypatch):
    real_join = BandRenderer._join
    interrupts = [1]

    def interrupted(self, *args):
        if interrupts:
            interrupts.pop()
            raise KeyboardInterrupt
        return real_join(self, *args)

    monkeypatch.setattr(BandRenderer, "_join", interrupted)
    with pytest.raises(KeyboardInterrupt):
        bands(scene_at(7, 160, 120))
    assert bands.failure is None and not bands._helper.in_flight
    assert_in_step_after_an_interrupt(bands)


def test_a_second_interrupt_while_collecting_the_answer_ends_the_helper(monkeypatch):
    """Interrupted while waiting, then again while the answer is collected: the answer is unread,
    so the helper is ended and later frames render here."""
    renderer = BandRenderer(min_pixels=0)
    try:
        assert renderer.wait_ready(WAIT)
        proc = renderer._helper.proc
        conn_class = type(renderer._helper.conn)

        def interrupt(*args, **kwargs):
            raise KeyboardInterrupt

        monkeypatch.setattr(bandprocs, "wait", interrupt)
        monkeypatch.setattr(conn_class, "poll", interrupt)
        draw = scene_at(7, 160, 120)
        with pytest.raises(KeyboardInterrupt):
            renderer(draw)
        monkeypatch.undo()
        assert renderer._helper is None and "interrupted" in renderer.failure
        assert proc.wait(timeout=WAIT) is not None
        assert_same_frame(renderer(draw), render_scene(draw))
        assert renderer.split_frames == 0
    finally:
        renderer.close()


def test_the_helper_runs_in_its_own_session_and_ignores_sigint(bands):
    import signal

    pid = bands.helper_pid
    assert os.getsid(pid) != os.getsid(0)  # a terminal's Ctrl+C reaches this process group only
    os.kill(pid, signal.SIGINT)
    draw = scene_at(4, 160, 120)
    before = bands.split_frames
    assert_same_frame(bands(draw), render_scene(draw))
    assert bands.split_frames == before + 1 and bands.helper_pid == pid


def test_close_from_another_call_during_a_frame_stops_it_and_the_frame_ends_the_helper(monkeypatch):
    """close() while a frame holds the renderer (here from the frame's own should_cancel, as a
    second thread would): it returns at once, the helper's band stops, the frame fails as
    cancelled and ends the helper. The helper is paused from before its request until close()
    has returned, so its band cannot have ended first (on a loaded machine it sometimes had)."""
    import signal

    renderer = BandRenderer(min_pixels=0)
    assert renderer.wait_ready(WAIT)
    proc = renderer._helper.proc
    calls = []
    request = renderer._request

    def paused_request(helper, *args, **kwargs):
        os.kill(helper.proc.pid, signal.SIGSTOP)
        return request(helper, *args, **kwargs)

    monkeypatch.setattr(renderer, "_request", paused_request)

    def closing() -> bool:
        if not calls:
            renderer.close(timeout=0.0)
            os.kill(proc.pid, signal.SIGCONT)
        calls.append(1)
        return False

    with pytest.raises(RenderCancelled):
        renderer(scene_at(7, 640, 480), should_cancel=closing)
    assert renderer._helper is None
    assert proc.wait(timeout=WAIT) == 0


def test_final_renderer_is_one_per_process_until_closed():
    renderer = bandprocs.final_renderer()
    try:
        assert bandprocs.final_renderer() is renderer
        assert renderer.max_triangles == bandprocs.FINAL_MAX_TRIANGLES and not renderer.keep_scene
        assert renderer.chunk_candidates == CHUNK_CANDIDATES  # render_scene's, not the viewport's
        assert BandRenderer(start=False).chunk_candidates == bandprocs.BAND_CHUNK_CANDIDATES < CHUNK_CANDIDATES
        assert renderer.min_pixels == bandprocs.MIN_PIXELS
    finally:
        bandprocs.close_final_renderer()
    assert renderer._closed
    again = bandprocs.final_renderer()
    try:
        assert again is not renderer and not again._closed
    finally:
        bandprocs.close_final_renderer()
