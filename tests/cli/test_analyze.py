"""``python -m blendlib analyze`` (docs/sorting.md): exact .npy arrays, heat-map PNGs, the JSON summary, bad input."""

from __future__ import annotations

import json

import numpy as np

from blendlib.formats import heatmap, images
from tests.support.blender_fixtures import REPO, one_line_error, run_cli

TWO = REPO / "blend_files" / "two_transparent.blend"

NOCAM = r"""
import sys, bpy
sys.path.insert(0, ".")
from tests.support.blender_fixtures import empty_scene, add_cube
scene = empty_scene(20, 10)
add_cube("Cube", 2.0)
bpy.data.objects.remove(scene.camera)
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[1])
"""


def test_json_and_exact_arrays(tmp_path):
    ref, err, od = tmp_path / "ref.npy", tmp_path / "err.npy", tmp_path / "od.npy"
    proc = run_cli("analyze", str(TWO), "--reference", str(ref), "--error", str(err), "--overdraw", str(od), "--json")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    reference, error, overdraw = np.load(ref), np.load(err), np.load(od)
    h, w = error.shape
    assert reference.shape == (h, w, 4) and reference.dtype == np.float32 and error.dtype == np.float32
    assert overdraw.shape == (h, w, 2) and overdraw.dtype == np.uint32
    assert np.all(overdraw[..., 1] <= overdraw[..., 0]) and overdraw[..., 0].max() == 2
    assert summary["pixels"] == h * w
    assert summary["differing"] == int(np.count_nonzero(error > 1)) > 0
    assert summary["max_error"] == float(error.max()) and np.all(error == np.round(error))
    assert abs(summary["mean_error"] - float(error.mean(dtype=np.float64))) < 1e-9
    assert summary["error_unit"] == "8-bit steps"  # an LDR frame
    # docs/json.md lists every field of the object (error_unit was missing)
    doc = (REPO / "docs" / "json.md").read_text().split("## `python -m blendlib analyze", 1)[1]
    documented = {name for row in doc.splitlines() if row.startswith("| `") for name in
                  (part.strip(" `") for part in row.split("|")[1].split(","))}
    assert set(summary) <= documented, set(summary) - documented
    [inv] = summary["inversions"]
    assert (inv["front"], inv["behind"], inv["front_slot"], inv["behind_slot"]) == ("Near Right", "Far Right", 0, 0)
    assert inv["pixels"] == summary["differing"]  # every inverted pixel differs here, and nothing else
    [item] = summary["advice"]
    assert item["change"]["material"] in ("Near Red", "Far Blue (Transparent+1)")
    assert item["inversions_before"] == inv["pixels"] and item["inversions_after"] == 0
    assert item["differing_before"] == summary["differing"] and item["differing_after"] == 0
    assert item["text"]


def test_heat_maps_with_a_legend(tmp_path):
    ref, err, od = tmp_path / "ref.png", tmp_path / "err.png", tmp_path / "od.png"
    proc = run_cli("analyze", str(TWO), "--reference", str(ref), "--error", str(err), "--overdraw", str(od),
                   "--advice", "0")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[-3:] == [str(ref), str(err), str(od)]
    assert "inversion: Near Right (slot 0) before Far Right (slot 0)" in proc.stdout
    reference, error, overdraw = images.load(ref), images.load(err), images.load(od)
    h, w = reference.shape[:2]
    assert error.shape[0] > h and error.shape[1] == w  # the legend strip below the map
    # the panels' names in a caption strip above them, one legend below
    assert overdraw.shape[1] == 2 * w + 2 and overdraw.shape[0] == error.shape[0] + heatmap.CAPTION_HEIGHT
    legend = error[h:]
    assert legend[..., 0].max() == 1.0 and len(np.unique(legend[..., :3].reshape(-1, 3), axis=0)) > 20


def test_bad_input_writes_nothing(tmp_path):
    out = tmp_path / "err.npy"
    one_line_error(run_cli("analyze", str(TWO), "--error", str(tmp_path / "err.exr")), ".png or .npy")
    one_line_error(run_cli("analyze", str(tmp_path / "missing.blend"), "--error", str(out)), "no such file")
    nocam = tmp_path / "nocam.blend"
    assert run_cli(str(nocam), code=NOCAM).returncode == 0
    one_line_error(run_cli("analyze", str(nocam), "--error", str(out), "--json"), "no camera")
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["nocam.blend"]
