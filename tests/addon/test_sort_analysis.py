"""The add-on's sort analysis (docs/sorting.md): F12 passes, the Analyze / Apply Advice operators, registration."""

from __future__ import annotations

import struct
import threading
import zlib

import bpy
import numpy as np
import pytest

import addon
import blendlib
from addon.sort_analysis.ops import UNITY_OT_sort_analyze
from blendlib import RenderCancelled, blender
from blendlib.explain.sorted_reference import analyze
from tests.addon.recording import event, job_context, operator_probe, run_modal
from tests.support.blender_fixtures import add_plane, empty_scene, unlit_material


@pytest.fixture(autouse=True)
def registered():
    addon.register()
    yield
    addon.unregister()


def inverted_scene():
    """Near red plane drawn before the far blue one: blue is Transparent+1."""
    scene = empty_scene(40, 30)
    scene.render.engine = "UNITY_PASSES"
    red = unlit_material("Near Red", (0.9, 0.1, 0.1, 0.5))
    blue = unlit_material("Far Blue", (0.1, 0.2, 0.9, 0.5))
    for mat in (red, blue):
        with bpy.context.temp_override(material=mat):
            bpy.ops.unity.apply_preset(preset="Alpha Blend")
    blue.unity.queue_offset = 1
    add_plane("Near", 2.0, (-0.5, -1.0, 0.0), red)
    add_plane("Far", 2.0, (0.5, 1.0, 0.3), blue)
    return scene


def _zip_block(block: bytes) -> bytes:
    """OpenEXR ZIP/ZIPS: zlib, then the delta predictor, then the two interleaved halves."""
    raw = np.frombuffer(zlib.decompress(block), np.uint8).astype(np.int64)
    raw = (np.cumsum(np.concatenate([raw[:1], raw[1:] - 128])) & 255).astype(np.uint8)
    half = (raw.size + 1) // 2
    out = np.empty(raw.size, np.uint8)
    out[0::2], out[1::2] = raw[:half], raw[half:]
    return out.tobytes()


def exr_planes(path) -> dict[str, np.ndarray]:
    """Every channel of a scanline EXR, single- or multi-part (NONE/ZIPS/ZIP), row 0 = top:
    name → (H, W) float32 (Blender writes multilayer files as multi-part EXR)."""
    data = path.read_bytes()
    (version,) = struct.unpack("<i", data[4:8])
    multipart = bool(version & 0x1000)
    pos, headers = 8, []
    while True:
        attrs = {}
        while data[pos] != 0:
            end = data.index(b"\0", pos)
            tend = data.index(b"\0", end + 1)
            (size,) = struct.unpack("<i", data[tend + 1:tend + 5])
            attrs[data[pos:end].decode()] = data[tend + 5:tend + 5 + size]
            pos = tend + 5 + size
        pos += 1
        headers.append(attrs)
        if not multipart or data[pos] == 0:
            break
    if multipart:
        pos += 1
    parts = []
    for attrs in headers:
        cl, i, channels = attrs["channels"], 0, []
        while cl[i] != 0:
            end = cl.index(b"\0", i)
            ptype = struct.unpack("<i", cl[end + 1:end + 5])[0]
            channels.append((cl[i:end].decode(), np.dtype("<f2") if ptype == 1 else np.dtype("<f4")))
            i = end + 17
        per_block = {0: 1, 2: 1, 3: 16}[attrs["compression"][0]]
        x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"])
        w, h = x1 - x0 + 1, y1 - y0 + 1
        count = (h + per_block - 1) // per_block
        offsets = np.frombuffer(data, "<u8", count, pos)
        pos += 8 * count
        parts.append((channels, per_block, y0, y1, w, h, offsets))
    planes = {}
    for channels, per_block, y0, y1, w, h, offsets in parts:
        line = sum(w * dt.itemsize for _, dt in channels)
        mine = {name: np.empty((h, w), np.float32) for name, _ in channels}
        for off in offsets.tolist():
            off += 4 if multipart else 0  # the part number
            y, size = struct.unpack("<ii", data[off:off + 8])
            n = min(per_block, y1 - y + 1)
            block = data[off + 8:off + 8 + size]
            if size < n * line:
                block = _zip_block(block)
            for k in range(n):
                p = k * line
                for name, dt in channels:
                    mine[name][y - y0 + k] = np.frombuffer(block, dt, w, p)
                    p += w * dt.itemsize
        planes.update(mine)
    return planes


def test_f12_writes_the_analysis_passes(tmp_path):
    scene = inverted_scene()
    scene.view_layers[0].unity_analysis.use_passes = True
    settings = scene.render.image_settings
    settings.media_type = "MULTI_LAYER_IMAGE"  # Blender 5: multilayer OpenEXR
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"
    scene.render.filepath = str(tmp_path / "still.exr")
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}
    planes = exr_planes(tmp_path / "still.exr")
    layer = scene.view_layers[0].name
    result = analyze(blender.build_draw_scene(scene))
    assert result.differing > 0 and result.inversions
    np.testing.assert_array_equal(planes[f"{layer}.UnitySortError.X"], result.error)
    np.testing.assert_array_equal(planes[f"{layer}.UnityOverdraw.X"], result.overdraw[..., 0].astype(np.float32))
    np.testing.assert_array_equal(planes[f"{layer}.UnityOverdraw.Y"], result.overdraw[..., 1].astype(np.float32))
    assert sorted(n for n in planes if ".UnityOverdraw." in n) == [f"{layer}.UnityOverdraw.{c}" for c in "XY"]
    from dataclasses import replace

    want = blender.linear_rgba(replace(result.frame, color=result.reference))
    got = np.stack([planes[f"{layer}.UnitySortedReference.{c}"] for c in "RGBA"], axis=-1)
    np.testing.assert_array_equal(got, want)
    scene.view_layers[0].unity_analysis.use_passes = False
    settings.media_type = "MULTI_LAYER_IMAGE"
    scene.render.filepath = str(tmp_path / "plain.exr")
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}
    assert not any("UnitySort" in name for name in exr_planes(tmp_path / "plain.exr"))


@pytest.mark.parametrize("crop", [True, False])
def test_the_analysis_passes_of_a_render_region(tmp_path, crop):
    """A Render Region: the analysis runs on the whole frame and each pass hands over the region's
    part, cropped (Crop to Render Region) or placed in the full-size image by Blender, the rest 0."""
    scene = inverted_scene()
    scene.view_layers[0].unity_analysis.use_passes = True
    r = scene.render
    r.use_border, r.use_crop_to_border = True, crop
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.3, 0.8, 0.1, 0.6
    settings = r.image_settings
    settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    r.filepath = str(tmp_path / "region.exr")
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}
    planes = exr_planes(tmp_path / "region.exr")
    layer = scene.view_layers[0].name
    result = analyze(blender.build_draw_scene(scene))
    x0, x1, y0, y1 = blender.border_region(scene, 40, 30)
    assert (x0, x1, y0, y1) == (12, 32, 3, 18)
    rows, cols = slice(30 - y1, 30 - y0), slice(x0, x1)  # row 0 is the top; the region's y from the bottom
    expected = {"UnitySortError.X": result.error, "UnityOverdraw.X": result.overdraw[..., 0].astype(np.float32),
                "UnityOverdraw.Y": result.overdraw[..., 1].astype(np.float32)}
    assert result.error[rows, cols].max() > 0  # the region holds part of the inverted overlap
    for name, full in expected.items():
        got = planes[f"{layer}.{name}"]
        if crop:
            np.testing.assert_array_equal(got, full[rows, cols], err_msg=name)
        else:
            want = np.zeros_like(full)
            want[rows, cols] = full[rows, cols]
            np.testing.assert_array_equal(got, want, err_msg=name)


def test_analyze_and_apply_advice_operators():
    scene = inverted_scene()
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.unity.sort_analyze() == {"FINISHED"}
    results = bpy.context.window_manager.unity_sort_results
    assert [(r.front, r.behind) for r in results.items] == [("Near", "Far")]
    row = results.items[0]
    assert row.pixels > 0 and "checked" in row.text and row.change
    assert "pixels differ" in results.summary
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.unity.sort_apply_advice() == {"FINISHED"}
    changed = (bpy.data.materials["Near Red"].unity.queue_offset, bpy.data.materials["Far Blue"].unity.queue_offset)
    assert changed != (0, 1)
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.unity.sort_analyze() == {"FINISHED"}
    assert len(results.items) == 0 and results.summary.startswith("0 of")


def test_panel_and_properties_are_registered_and_removed():
    assert hasattr(bpy.types.ViewLayer, "unity_analysis") and hasattr(bpy.types, "UNITY_PT_sort_analysis")
    prop = bpy.types.ViewLayer.bl_rna.properties["unity_analysis"]
    assert prop.description
    addon.unregister()
    assert not hasattr(bpy.types.ViewLayer, "unity_analysis") and not hasattr(bpy.types, "UNITY_PT_sort_analysis")
    addon.register()
    addon.register()
    assert bpy.context.view_layer.unity_analysis.use_passes is False


def _rows(results) -> tuple:
    return results.summary, [(r.front, r.behind, r.pixels, r.text, r.change) for r in results.items]


class GatedAnalysis:
    """``blendlib.analyze`` that waits for ``gate`` before (or, ``after=True``, after) the real
    analysis, recording the progress fractions it reports."""

    def __init__(self, after: bool = False):
        self.real = blendlib.analyze
        self.after = after
        self.gate, self.reached = threading.Event(), threading.Event()
        self.fractions: list[float] = []

    def __call__(self, draw, progress=None, should_cancel=None, **kwargs):
        def record(fraction):
            self.fractions.append(fraction)
            progress(fraction)

        if not self.after:
            self.reached.set()
            assert self.gate.wait(30)
        result = self.real(draw, progress=record, should_cancel=should_cancel, **kwargs)
        if self.after:
            self.reached.set()
            assert self.gate.wait(30)
        return result


def _invoke(scene):
    op = operator_probe(UNITY_OT_sort_analyze)
    ctx = job_context(scene=scene)
    assert op.invoke(ctx, event("LEFTMOUSE")) == {"RUNNING_MODAL"}
    return op, ctx


def test_analyze_as_a_job_reports_progress_and_stores_what_execute_stores(monkeypatch):
    scene = inverted_scene()
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.unity.sort_analyze() == {"FINISHED"}  # execute: synchronous
    results = bpy.context.window_manager.unity_sort_results
    synchronous = _rows(results)
    assert synchronous[1] and synchronous[1][0][:2] == ("Near", "Far")
    results.items.clear()
    results.summary = ""
    gated = GatedAnalysis(after=True)
    monkeypatch.setattr(blendlib, "analyze", gated)
    op, ctx = _invoke(scene)
    assert ctx.workspace.status == ["Analysing the sorting: 0% (Esc to cancel)"]
    assert gated.reached.wait(30)  # the render is done, the job is not
    assert op.modal(ctx, event("TIMER")) == {"RUNNING_MODAL"}
    percent = int(100 * gated.fractions[-1])
    assert gated.fractions and percent > 0
    assert ctx.window_manager.calls[-1] == ("progress_update", percent)
    assert ctx.workspace.status[-1] == f"Analysing the sorting: {percent}% (Esc to cancel)"
    assert _rows(results) == ("", [])  # stored only when done, on the main thread
    gated.gate.set()
    assert run_modal(op, ctx) == {"FINISHED"}
    assert _rows(results) == synchronous
    assert op.reports == [("INFO", f"Unity Passes: {synchronous[0]}; 1 inverted pairs")]


def test_esc_cancels_the_analysis_and_keeps_the_previous_results(monkeypatch):
    scene = inverted_scene()
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.unity.sort_analyze() == {"FINISHED"}
        assert bpy.ops.unity.sort_apply_advice() == {"FINISHED"}  # a new analysis would find no inversion
    results = bpy.context.window_manager.unity_sort_results
    previous = _rows(results)
    assert len(previous[1]) == 1
    gated = GatedAnalysis()
    monkeypatch.setattr(blendlib, "analyze", gated)
    op, ctx = _invoke(scene)
    job = op._job
    assert gated.reached.wait(30)
    assert op.modal(ctx, event("ESC")) == {"RUNNING_MODAL"}
    gated.gate.set()  # the analysis starts after Esc: its render stops at the first check
    assert run_modal(op, ctx) == {"CANCELLED"}
    assert isinstance(job.error, RenderCancelled)
    assert op.reports == [("WARNING", "Unity Passes: Cancelled")]
    assert _rows(results) == previous
    assert ("progress_end",) in ctx.window_manager.calls and ctx.workspace.status[-1] is None


def test_analyze_without_camera_reports_one_error_and_starts_nothing():
    scene = inverted_scene()
    scene.camera = None
    op = operator_probe(UNITY_OT_sort_analyze)
    ctx = job_context(scene=scene)
    assert op.invoke(ctx, event("LEFTMOUSE")) == {"CANCELLED"}
    assert len(op.reports) == 1 and op.reports[0][0] == "ERROR" and "no camera" in op.reports[0][1]
    assert ctx.window_manager.calls == [] and op._job is None
    with bpy.context.temp_override(scene=scene), pytest.raises(RuntimeError, match="no camera"):
        bpy.ops.unity.sort_analyze()
