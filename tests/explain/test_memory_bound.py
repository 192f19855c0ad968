"""docs/sorting.md "Cost": the analysis stays within its stated memory bound at any resolution
(issue 30, High 5), keeping transparent fragments within a budget and analysing the rows that do
not fit in further passes; a frame that cannot fit is refused before anything is rendered."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from blendlib.core.scene import SceneError
from blendlib.core.vocabulary import Queue
from blendlib.explain import fragment_store
from blendlib.explain import sorted_reference as sr
from scripts.benchmark.timing import reset_peak
from tests.explain.test_sorted_reference import BLEND, transparent
from tests.reference import scenes as sc
from tests.reference.random_scenes import seeded_scene

REPO = Path(__file__).resolve().parents[2]

#: Run in a fresh process: 60 transparent planes over 640x480 (18.4 million fragments, 221 MB
#: to keep them all; with MSAA 4x over 320x240: as many sample fragments) analysed with a 48 MB
#: budget on one thread; the resident peak during the analysis over the resident size before it
#: (``VmHWM`` reset through ``/proc/self/clear_refs``). Arguments: width, height, samples.
PEAK_SCRIPT = """
import dataclasses, json, sys
from blendlib.core.vocabulary import BlendFactor, Pass, Queue
from blendlib.explain import sorted_reference as sr
from tests.reference import scenes as sc

def status(key):
    for line in open("/proc/self/status"):
        name, _, value = line.partition(":")
        if name == key:
            return int(value.split()[0]) * 1024

width, height, samples = (int(v) for v in sys.argv[1:4])
planes, budget = 60, 48 << 20
blend = Pass(blend=True, zwrite=False, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha)
scene = sc.scene(sc.screen_camera(width, height), *(
    sc.renderer(sc.quad(0, 0, width, height, z=-1.0 + 2.0 * k / planes),
                sc.unlit((k / planes, 0.5, 1 - k / planes, 0.3), queue=Queue.Transparent, passes=[blend], name=f"M{k}"),
                name=f"P{k}") for k in range(planes)))
scene = dataclasses.replace(scene, msaa=samples)
with open("/proc/self/clear_refs", "w") as f:
    f.write("5")
before = status("VmRSS")
analysis = sr.analyze(scene, memory=budget, workers=1)
print(json.dumps({"extra": status("VmHWM") - before,
                  "bound": sr.memory_bound(width, height, False, budget, threads=1, samples=samples),
                  "fragments": int(analysis.overdraw[..., 0].sum())}))
"""


@pytest.mark.skipif(not reset_peak(), reason="needs Linux /proc/self/clear_refs to reset the resident peak")
@pytest.mark.parametrize(("width", "height", "samples"), [(640, 480, 1), (320, 240, 4)])
def test_the_analysis_stays_within_its_stated_bound(width, height, samples):
    out = subprocess.run([sys.executable, "-c", PEAK_SCRIPT, str(width), str(height), str(samples)], cwd=REPO,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout.strip().splitlines()[-1])
    # pixel fragments (with MSAA each keeps N samples): with MSAA the pixels on a quad's diagonal
    # have one of each triangle
    assert 60 * width * height <= result["fragments"] <= 60 * (width * height + (samples > 1) * (width + height))
    # Below what keeping every fragment (as compactly as the analysis does) would take beside the
    # per-pixel memory: an analysis that kept them all could not stay within the bound.
    keeping_all = (result["fragments"] * samples * fragment_store.FRAGMENT_BYTES
                   + width * height * (sr.PIXEL_BYTES + (samples - 1) * sr.SAMPLE_BYTES))
    assert result["bound"] < keeping_all
    assert 0 < result["extra"] <= result["bound"], result


def _planes(width, height, planes):
    return sc.scene(sc.screen_camera(width, height), *(
        sc.renderer(sc.quad(0, 0, width, height, z=-1.0 + 2.0 * k / planes),
                    sc.unlit((k / planes, 0.5, 1 - k / planes, 0.3), queue=Queue.Transparent, passes=[BLEND],
                             name=f"M{k}"), name=f"P{k}") for k in range(planes)))


def test_kept_fragments_stay_within_the_budget(monkeypatch):
    """Each pass keeps at most the budget (beyond it only the chunk that crossed it, dropped at
    once), and the passes together analyse every row: the same result as one pass."""
    scene = _planes(96, 80, 12)
    whole = sr.analyze(scene)
    collectors = []
    real = fragment_store.FragmentCollector.__init__

    def recorded(self, *args, **kwargs):
        real(self, *args, **kwargs)
        collectors.append(self)

    monkeypatch.setattr(fragment_store.FragmentCollector, "__init__", recorded)
    monkeypatch.setattr(fragment_store, "BLOCK_PIXELS", 96 * 4)  # 4 rows a block
    budget = 96 * 80 * 3 * fragment_store.FRAGMENT_BYTES  # a quarter of the 12 layers
    banded = sr.analyze(scene, memory=budget)
    chunk = 96 * 80 * fragment_store.FRAGMENT_BYTES + 1024  # one plane's fragments (and palette): one chunk
    assert len(collectors) > 3
    assert all(c.peak_bytes <= budget + chunk for c in collectors)
    for name in ("reference", "error", "overdraw", "inverted"):
        assert np.array_equal(getattr(whole, name), getattr(banded, name)), name
    assert whole.inversions == banded.inversions


def test_a_frame_that_cannot_fit_is_refused_before_rendering(monkeypatch):
    scene = _planes(8000, 8000, 2)

    def no_render(*args, **kwargs):
        raise AssertionError("rendered")

    monkeypatch.setattr(sr, "render_scene", no_render)
    with pytest.raises(SceneError) as error:
        sr.analyze(scene, memory_limit=2 << 30)
    message = str(error.value)
    need = sr.memory_bound(8000, 8000, False, sr.SMALLEST_BUDGET, threads=sr.processing_threads(None)) / 2**30
    assert "\n" not in message and message.startswith("analyze: a 8000x8000 frame needs about ")
    assert f"{need:.1f} GiB" in message and "2.0 GiB is available" in message


def test_the_budget_shrinks_to_the_memory_left_and_grows_no_larger():
    pixels_only = sr.memory_bound(1000, 1000, False, 0)  # and two threads' work
    assert sr.fragment_budget(1000, 1000, False, None, None) <= sr.FRAGMENT_BUDGET
    assert sr.fragment_budget(1000, 1000, False, None, pixels_only + (100 << 20)) == 100 << 20
    assert sr.fragment_budget(1000, 1000, False, None, 1 << 40) == sr.FRAGMENT_BUDGET
    assert sr.fragment_budget(1000, 1000, False, 5 << 20, 1 << 40) == 5 << 20  # asked for: kept
    hdr = sr.memory_bound(1000, 1000, True, 0)
    assert hdr - pixels_only == 1000 * 1000 * (sr.PIXEL_BYTES_HDR - sr.PIXEL_BYTES)
    with pytest.raises(SceneError, match="must be positive"):
        sr.fragment_budget(10, 10, False, 0, None)


def test_a_seeded_scene_analysed_one_block_a_pass_equals_one_pass():
    scene = transparent(seeded_scene(19))
    whole = sr.analyze(scene)
    banded = sr.analyze(scene, memory=1)
    assert np.array_equal(whole.reference, banded.reference) and whole.inversions == banded.inversions
    assert np.array_equal(whole.overdraw, banded.overdraw) and np.array_equal(whole.inverted, banded.inverted)
    assert whole.summary() == banded.summary()


def test_msaa_blocks_hold_whole_rows_of_samples_within_16_bits(monkeypatch):
    """With MSAA a block's pixels are its rows' samples: a 640-pixel row at 4x is 2560 of them, so
    a block has a twelfth of the rows it has without MSAA (its sample index must fit 16 bits);
    the analysis equals one with a row per block."""
    scene = replace(_planes(640, 60, 3), msaa=4)
    collector = fragment_store.FragmentCollector([], 640, 60, 1 << 20, samples=4)
    assert collector.block_pixels <= fragment_store.BLOCK_PIXELS and collector.block_pixels % (640 * 4) == 0
    whole = sr.analyze(scene)
    monkeypatch.setattr(fragment_store, "BLOCK_PIXELS", 1)
    rows = sr.analyze(scene)
    for name in ("reference", "error", "overdraw", "inverted"):
        assert np.array_equal(getattr(whole, name), getattr(rows, name)), name
    assert whole.inversions == rows.inversions
    assert (whole.overdraw[..., 1] >= 3).all()  # every plane blended everywhere
