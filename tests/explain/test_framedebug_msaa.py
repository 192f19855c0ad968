"""The frame debugger with MSAA (docs/json.md): draw statistics per pixel fragment and per sample,
pixel histories with coverage masks and per-sample results, replayed through the scalar reference."""

from __future__ import annotations

import json

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core import msaa
from blendlib.core.drawlist import draw_calls
from blendlib.core.vocabulary import Cull, Pass
from blendlib.explain import framedebug as fd
from tests.reference import scalar
from tests.reference import scenes as sc
from tests.reference.random_scenes import describe, seeded_scene

DMAX = 2**24 - 1
CASES = [(seed, samples) for seed in (0, 2, 5, 9, 13) for samples in (2, 4, 8)]


def _reference(scene):
    log = scalar.FragmentLog()
    frame = scalar.render_reference(scene, log=log)
    return frame, log


def _sample(buf, x, y, s):
    """Sample ``s`` of the scalar buffers' pixel in frame units: (rgba float32 (4,), depth, stencil)."""
    c = buf.get(buf.color, x, y, s)
    rgba = np.array(c, dtype=np.float32) if buf.hdr else (np.array(c, dtype=np.int64) / 255.0).astype(np.float32)
    return rgba, np.float32(buf.get(buf.depth, x, y, s) / DMAX), buf.get(buf.stencil, x, y, s)


@pytest.mark.parametrize(("seed", "samples"), CASES)
def test_every_msaa_pixel_history_replays_through_the_scalar_reference(seed, samples):
    scene = seeded_scene(seed, msaa=samples)
    w, h = scene.camera.width, scene.camera.height
    histories, frame = fd.pixel_histories(scene, [(x, y) for y in range(h) for x in range(w)])
    (color, depth, _), log = _reference(scene)
    assert np.array_equal(frame.color, color) and np.array_equal(frame.depth, depth)
    by_pixel: dict[tuple[int, int], list] = {}
    for rec in log.fragments:
        by_pixel.setdefault((rec[1], rec[2]), []).append(rec)
    replay = scalar.Buffers(scene)
    calls = {c.index: c for c in draw_calls(scene)}
    total = 0
    for hist in histories:
        x, wy = hist.x, h - 1 - hist.y
        assert hist.msaa == samples and hist.to_json()["msaa"] == samples
        ref = by_pixel.get((x, wy), [])
        # the same fragments in order: draw, triangle, coverage, each covered sample's depth and result
        got = [(f.call.index, f.triangle, f.coverage, [(r.sample, r.depth_code, r.result) for r in f.samples])
               for f in hist.fragments]
        want = [(r[0], r[3], r[7], [(k, r[4][k], r[6][k]) for k in sorted(r[4])]) for r in ref]
        assert got == want, (seed, samples, x, hist.y, describe(scene))
        for f, r in zip(hist.fragments, ref, strict=True):
            assert list(f.source) == list(r[5])
            assert f.result == ("written" if "written" in r[6].values() else r[6][min(r[6])])
            assert f.depth_code == r[4][min(r[4])]
        # replay: every covered sample through the reference's own merger
        for f in hist.fragments:
            assert np.array_equal(np.float32(f.before), replay.resolved(x, wy) if replay.hdr
                                  else np.float32(np.array(replay.resolved(x, wy)) / 255.0))
            for r in f.samples:
                rgba, d, s = _sample(replay, x, wy, r.sample)
                assert np.array_equal(np.float32(r.before), rgba) and r.depth_before == d and r.stencil_before == s
                if r.result not in ("alpha_test", "alpha_to_mask"):
                    assert scalar.merge_fragment(x, wy, r.depth_code, list(f.source), calls[f.call.index].state,
                                                 replay, r.sample) == r.result
                rgba, d, s = _sample(replay, x, wy, r.sample)
                assert np.array_equal(np.float32(r.after), rgba) and r.depth_after == d and r.stencil_after == s
            _, d0, s0 = _sample(replay, x, wy, 0)
            assert f.depth_after == d0 and f.stencil_after == s0  # the frame's depth and stencil: sample 0
        assert np.array_equal(np.float32(hist.final), frame.color[hist.y, x])
        if hist.fragments:
            assert np.array_equal(np.float32(hist.fragments[-1].after), frame.color[hist.y, x])
        total += len(hist.fragments)
    assert total == len(log.fragments)


@pytest.mark.parametrize(("seed", "samples"), CASES)
def test_msaa_draw_list_counts_equal_the_scalar_reference(seed, samples):
    scene = seeded_scene(seed, msaa=samples)
    stats = fd.draw_list(scene)
    _, log = _reference(scene)
    counts, written = log.counts(), log.samples_written()
    for s in stats:
        assert (s.fragments, s.written) == counts.get(s.call.index, (0, 0)), (seed, s)
        assert s.samples_written == written.get(s.call.index, 0) == s.to_json()["samples_written"]
        assert s.triangles == log.triangles.get(s.call.index, 0)


def test_msaa_json_keys_only_with_msaa():
    scene = seeded_scene(2)
    single = fd.pixel_history(scene, 5, 5).to_json()
    assert "msaa" not in single and all("coverage" not in f and "samples" not in f for f in single["fragments"])
    assert all("samples_written" not in s.to_json() for s in fd.draw_list(scene))
    multi = json.loads(json.dumps(fd.pixel_histories(seeded_scene(2, msaa=4),
                                                     [(x, 5) for x in range(12)])[0][6].to_json()))
    assert multi["msaa"] == 4
    for f in multi["fragments"]:
        assert isinstance(f["coverage"], int) and 0 < f["coverage"] < 16
        assert [s["sample"] for s in f["samples"]] == [k for k in range(4) if f["coverage"] >> k & 1]


def test_coverage_masks_name_the_standard_samples_y_up():
    """A quad's right edge at x = 3 + 8.5/16 and top edge at y = 5 + 4.5/16 (window units, y up): in
    pixel (3, 5) the covered 4x samples are those left of and below both — sample 0 at (6/16, 2/16)
    only; pixel (3, 2): samples 0 and 2 (x 6/16 and 2/16); pixel (1, 5): sample 0 (y 2/16). The
    table read with Direct3D's y down would give sample 3 in (1, 5) and none in (3, 5)."""
    p = Pass(cull=Cull.Off)
    quad = sc.renderer(sc.quad(0.0, 0.0, 3 + 8.5 / 16, 5 + 4.5 / 16), sc.unlit((1, 1, 1, 1), passes=(p,)))
    scene = sc.scene(sc.screen_camera(8, 8), quad, msaa=4)
    histories, _ = fd.pixel_histories(scene, [(3, 8 - 1 - 5), (3, 8 - 1 - 2), (1, 8 - 1 - 5)])
    positions = msaa.sample_offsets(4) / 256
    left, low = positions[:, 0] < 8.5 / 16, positions[:, 1] < 4.5 / 16
    for hist, covered in zip(histories, (left & low, left, low), strict=True):
        (f,) = hist.fragments
        assert f.coverage == sum(1 << k for k in np.flatnonzero(covered))
    assert [h.fragments[0].coverage for h in histories] == [0b0001, 0b0101, 0b0001]


@pytest.mark.parametrize("samples", [2, 4, 8])
def test_msaa_capture_steps_through_draws_from_snapshots(samples):
    """FrameCapture with MSAA: snapshots of every sample (within the memory bound, which counts
    them), each frame_after(k) equal to a render stopped after draw k."""
    scene = seeded_scene(9, msaa=samples)
    per = fd.snapshot_bytes(scene.camera.width, scene.camera.height, scene.hdr, samples)
    cap = fd.FrameCapture.capture(scene, memory=2 * per)
    assert cap.snapshots and cap.snapshot_memory <= 2 * per
    for k in range(len(cap.stats) + 1):
        frame, _ = cap.frame_after(k)
        direct = render_scene(scene, until_draw=k)
        assert np.array_equal(frame.color, direct.color) and np.array_equal(frame.stencil, direct.stencil)
