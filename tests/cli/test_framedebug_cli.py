"""``drawlist``, ``pixel`` and ``render --until-draw`` (docs/framedebugger.md) on a small .blend file: an opaque
plane behind a Cull Off alpha-blended cube, so the centre pixel sees two faces of the cube blended
in the mesh's triangle order inside one draw call."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.support.blender_fixtures import blends_per_kind, one_line_error, run_cli

MAKE = r"""
import sys, bpy
sys.path.insert(0, ".")
import addon
addon.register()
from tests.support.blender_fixtures import empty_scene, add_cube, add_plane, unlit_material
from addon.material_settings.ops import apply_preset
kind, path = sys.argv[1], sys.argv[2]
scene = empty_scene(40, 30)
wall = unlit_material("Wall", (0.9, 0.2, 0.1, 1.0))
add_plane("Wall", 12.0, location=(0, 4, 0), material=wall)
glass = unlit_material("Glass", (0.1, 0.4, 0.9, 0.5))
apply_preset(glass, "Alpha Blend")
glass.unity.passes[0].cull = "Off"
add_cube("Cube", 2.0, material=glass)
if kind == "nocam":
    bpy.data.objects.remove(scene.camera)
bpy.ops.wm.save_as_mainfile(filepath=path)
"""


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    return blends_per_kind(tmp_path_factory.mktemp("blends"), MAKE, ("good", "nocam"))


def test_drawlist_json_and_table(blends):
    proc = run_cli("drawlist", str(blends["good"]), "--json")
    assert proc.returncode == 0, proc.stderr
    items = json.loads(proc.stdout)
    assert [(i["index"], i["object"], i["queue"], i["pass"], i["pass_name"]) for i in items] == [
        (1, "Wall", 2000, 0, "Pass"), (2, "Cube", 3000, 0, "Pass")]
    wall, cube = items
    assert wall["fragments"] == wall["written"] == 40 * 30 and wall["triangles"] == 2
    assert wall["distance"] == pytest.approx(12.0) and cube["distance"] == pytest.approx(8.0)
    assert cube["triangles"] == 12 and cube["written"] == cube["fragments"] > 0  # Cull Off, no depth writes
    assert cube["state"] == "Cull Off ZWrite Off ZTest LEqual Blend SrcAlpha OneMinusSrcAlpha"
    assert cube["material"] == "Glass" and cube["slot"] == 0
    proc = run_cli("drawlist", str(blends["good"]))
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].split()[:4] == ["#", "queue", "distance", "object"] and "Cull Off ZWrite Off" in lines[2]


def test_pixel_history_matches_until_draw_frames(blends, tmp_path):
    x, y = 20, 15
    proc = run_cli("pixel", str(blends["good"]), str(x), str(y), "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    frags = data["fragments"]
    assert (data["x"], data["y"]) == (x, y)
    assert [(f["draw"], f["object"]) for f in frags] == [(1, "Wall"), (2, "Cube"), (2, "Cube")]
    assert all(f["result"] == "written" for f in frags)
    first, second = frags[1], frags[2]  # the cube's front and back face, in the mesh's triangle order
    assert first["triangle"] < second["triangle"] < 12 and first["depth"] != second["depth"]
    assert first["polygon"] != second["polygon"] and {first["polygon"], second["polygon"]} <= set(range(6))
    assert frags[0]["before"] == data["clear"]
    assert all(a["after"] == b["before"] for a, b in zip(frags, frags[1:], strict=False))
    assert frags[-1]["after"] == data["final"]
    for k in range(3):
        out, depth = tmp_path / f"k{k}.npy", tmp_path / f"d{k}.npy"
        proc = run_cli("render", str(blends["good"]), "-o", str(out), "--depth", str(depth), "--until-draw", str(k))
        assert proc.returncode == 0, proc.stderr
        color = np.load(out)
        last = [f for f in frags if f["draw"] <= k]
        expect = last[-1]["after"] if last else data["clear"]
        assert np.array_equal(color[y, x], np.float32(expect)), k  # JSON floats read back exactly
        expect_depth = last[-1]["depth_after"] if last else 1.0
        assert np.load(depth)[y, x] == np.float32(expect_depth)
    assert np.all(np.load(tmp_path / "k0.npy") == np.float32(data["clear"]))
    proc = run_cli("pixel", str(blends["good"]), str(x), str(y))
    assert proc.returncode == 0 and "Cube" in proc.stdout and "written" in proc.stdout, proc.stderr


@pytest.mark.parametrize("case", ["x", "y", "negative", "k", "nocam-pixel", "nocam-drawlist"])
def test_bad_input_one_line_error_nothing_written(blends, tmp_path, case):
    out = tmp_path / "out.npy"
    good, nocam = str(blends["good"]), str(blends["nocam"])
    args = {"x": ["pixel", good, "40", "0"], "y": ["pixel", good, "0", "30"], "negative": ["pixel", good, "-1", "0"],
            "k": ["render", good, "-o", str(out), "--until-draw", "-2"],
            "nocam-pixel": ["pixel", nocam, "0", "0"], "nocam-drawlist": ["drawlist", nocam, "--json"]}[case]
    text = {"x": "outside the 40x30 image", "y": "outside", "negative": "outside", "k": "--until-draw",
            "nocam-pixel": "no camera", "nocam-drawlist": "no camera"}[case]
    proc = run_cli(*args)
    one_line_error(proc, text)
    assert proc.stdout == "" and not out.exists()
