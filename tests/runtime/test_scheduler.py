"""The viewport's worker (blendlib.runtime.scheduler): reduced frame first, then full; stale work cancelled.

bpy-free: the scheduler renders DrawScenes built by hand (the add-on extracts them on the
main thread), with the core renderer or a stand-in that blocks to expose the timing.
"""

from __future__ import annotations

import dataclasses
import threading

import numpy as np
import pytest

from blendlib import RenderCancelled, SceneError, render_scene
from blendlib.runtime import scheduler
from blendlib.runtime.scheduler import ViewportScheduler, reduced_size
from tests.reference.random_scenes import seeded_scene

WAIT = 30.0


def scene_at(width: int, height: int, seed: int = 3):
    draw = seeded_scene(seed)
    return dataclasses.replace(draw, camera=dataclasses.replace(draw.camera, width=width, height=height))


class Recorder:
    """on_ready: the (key, size, full) of each published frame, in order."""

    def __init__(self):
        self.events = []
        self.scheduler = None

    def __call__(self):
        shown = self.scheduler.latest()
        self.events.append((shown.key, shown.frame.color.shape[:2], shown.full))


def make(render=render_scene, **kwargs) -> tuple[ViewportScheduler, Recorder]:
    rec = Recorder()
    sched = ViewportScheduler(on_ready=rec, render=render, **kwargs)
    rec.scheduler = sched
    return sched, rec


def test_reduced_size_rule():
    assert reduced_size(960, 540) == (240, 135)
    assert reduced_size(961, 541) == (241, 136)  # rounded up: never an empty frame
    assert reduced_size(128, 128) is None  # small frames come at full size at once
    assert reduced_size(129, 128) == (33, 32)
    assert reduced_size(960, 540, factor=1) is None


def test_reduced_frame_first_then_full_equal_to_a_direct_render():
    draw = scene_at(200, 120)
    sched, rec = make()
    try:
        sched.submit(draw, "A")
        assert sched.wait_idle(WAIT)
    finally:
        sched.close()
    assert rec.events == [("A", (30, 50), False), ("A", (120, 200), True)]
    latest = sched.latest()
    assert latest.full and latest.key == "A"
    direct = render_scene(draw)
    np.testing.assert_array_equal(latest.frame.color, direct.color)
    np.testing.assert_array_equal(latest.frame.depth, direct.depth)
    # the reduced frame is the same view (same matrices) at a quarter of the size per side
    small = render_scene(dataclasses.replace(draw, camera=dataclasses.replace(draw.camera, width=50, height=30)))
    assert small.color.shape == (30, 50, 4)
    assert sched.error is None and not sched.busy


def test_small_view_renders_full_size_only():
    sched, rec = make()
    try:
        sched.submit(scene_at(64, 48), "S")
        assert sched.wait_idle(WAIT)
    finally:
        sched.close()
    assert rec.events == [("S", (48, 64), True)]


def test_stale_work_is_cancelled_and_never_shown():
    """A render still running when a new request comes sees should_cancel() turn True and stops;
    only the newest request's frames are published."""
    started = threading.Event()
    seen_cancel = []

    def blocking(draw, should_cancel=None, **kw):
        if draw.camera.width == 999:  # the stale request: blocks until cancelled
            started.set()
            for _ in range(2000):
                if should_cancel():
                    seen_cancel.append(True)
                    raise RenderCancelled("render cancelled")
                threading.Event().wait(0.005)
            raise AssertionError("never cancelled")
        return render_scene(draw, should_cancel=should_cancel, **kw)

    sched, rec = make(render=blocking, min_pixels=10**9)  # no reduced frames: one render per request
    try:
        sched.submit(scene_at(999, 10), "old")
        assert started.wait(WAIT)
        sched.submit(scene_at(40, 30), "mid")   # queued behind the running one ...
        sched.submit(scene_at(48, 36), "new")   # ... and replaced before it starts
        assert sched.wait_idle(WAIT)
    finally:
        sched.close()
    assert seen_cancel == [True]
    assert rec.events == [("new", (36, 48), True)]


def test_cancel_between_reduced_and_full():
    """A new request arriving after the reduced frame stops the old request's full frame."""
    gate = threading.Event()
    calls = []

    def gated(draw, should_cancel=None, **kw):
        calls.append((draw.camera.width, draw.camera.height))
        frame = render_scene(draw, **kw)
        if len(calls) == 1:
            gate.wait(WAIT)  # hold the worker after the first (reduced) frame of "A"
        if should_cancel():
            raise RenderCancelled("render cancelled")
        return frame

    sched, rec = make(render=gated)
    try:
        sched.submit(scene_at(200, 120), "A")
        while not calls:
            threading.Event().wait(0.01)
        sched.submit(scene_at(200, 120, seed=5), "B")
        gate.set()
        assert sched.wait_idle(WAIT)
    finally:
        sched.close()
    assert [e[0] for e in rec.events] == ["B", "B"]
    assert [e[2] for e in rec.events] == [False, True]
    assert calls == [(50, 30), (50, 30), (200, 120)]  # A reduced (dropped), then B reduced and full


def test_render_errors_are_kept_and_the_worker_lives_on():
    def failing(draw, **kw):
        if draw.camera.width == 7:
            raise SceneError("object 'X' slot 0: triangles must be integer")
        return render_scene(draw, **kw)

    sched, rec = make(render=failing)
    try:
        sched.submit(scene_at(7, 7), "bad")
        assert sched.wait_idle(WAIT)
        assert sched.error == "object 'X' slot 0: triangles must be integer" and sched.latest() is None
        sched.submit(scene_at(20, 10), "good")
        assert sched.wait_idle(WAIT)
        assert sched.error is None and sched.latest().key == "good"
    finally:
        sched.close()
    assert not sched._thread.is_alive()
    with pytest.raises(RuntimeError):
        sched.submit(scene_at(20, 10), "closed")


@pytest.mark.parametrize("begin_after_work_s", [0.0, 60.0])
def test_the_helper_begins_heavy_full_frames_while_the_reduced_frame_renders(begin_after_work_s):
    """With a reduced stage, once a split frame took ``begin_after_work_s`` or more the
    scheduler starts the helper on the next full frame's band first (BandRenderer.begin); the
    reduced frame renders in this process; every frame is exact."""
    frames = []
    sched = ViewportScheduler(on_ready=lambda: frames.append(sched.latest()), factor=4, min_pixels=0,
                              begin_after_work_s=begin_after_work_s)
    draw = scene_at(96, 64, seed=7)
    view = np.array(draw.camera.view_matrix, dtype=np.float64)
    view[0, 3] += 0.2  # the view moved sideways
    moved = dataclasses.replace(draw, camera=dataclasses.replace(draw.camera, view_matrix=view))
    try:
        sched.bands.min_pixels = 1000  # the 24x16 reduced frames stay here, the 96x64 full ones split
        assert sched.bands.wait_ready(WAIT)
        for key, scene in enumerate((draw, moved)):
            sched.submit(scene, key=key)
            assert sched.wait_idle(WAIT)
        assert [f.full for f in frames] == [False, True, False, True]
        # The first full frame has no time to go by; the second begins when the first was heavy.
        assert sched.bands.split_frames == 2
        assert sched.bands.begun_frames == (1 if begin_after_work_s == 0.0 else 0)
        assert sched.bands.last_work_s > 0.0
        for scene, (small, full) in zip((draw, moved), (frames[:2], frames[2:]), strict=True):
            expected = render_scene(scene)
            np.testing.assert_array_equal(full.frame.color, expected.color)
            np.testing.assert_array_equal(full.frame.depth, expected.depth)
            reduced = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, width=24, height=16))
            np.testing.assert_array_equal(small.frame.color, render_scene(reduced).color)
    finally:
        sched.close()


def test_the_scheduler_splits_large_frames_in_two_processes_and_ends_its_helper():
    """By default the scheduler renders through a BandRenderer of its own (blendlib.runtime.bandprocs):
    a large frame comes out split and equal to render_scene; close() ends the helper."""
    done = threading.Event()
    sched = ViewportScheduler(on_ready=done.set, min_pixels=1 << 30)  # full frames only
    assert sched.bands is not None
    draw = scene_at(72, 48, seed=9)
    try:
        sched.bands.min_pixels = 0
        assert sched.bands.wait_ready(WAIT)
        sched.submit(draw, key=1)
        assert sched.wait_idle(WAIT) and done.is_set()
        assert sched.bands.split_frames == 1
        frame, expected = sched.latest().frame, render_scene(draw)
        np.testing.assert_array_equal(frame.color, expected.color)
        np.testing.assert_array_equal(frame.depth, expected.depth)
        np.testing.assert_array_equal(frame.stencil, expected.stencil)
        proc = sched.bands._helper.proc
    finally:
        sched.close()
    assert proc.wait(timeout=WAIT) == 0


def test_begins_early_only_after_a_heavy_split_frame():
    class Bands:
        last_work_s = None

    bands = Bands()
    assert not scheduler.begins_early(bands, 0.1)  # no split frame measured yet
    assert not scheduler.begins_early(None, 0.0)  # no helper (a stand-in renderer)
    bands.last_work_s = 0.0999
    assert not scheduler.begins_early(bands, 0.1)
    bands.last_work_s = 0.1
    assert scheduler.begins_early(bands, 0.1)
    assert scheduler.begins_early(bands) == (0.1 >= scheduler.BEGIN_AFTER_WORK_S)
