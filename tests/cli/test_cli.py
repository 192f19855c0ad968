"""``python -m blendlib``: render/compare outputs, exit codes and one-line errors (README "Command line")."""

from __future__ import annotations

import numpy as np
import pytest

from blendlib.formats import images
from tests.support.blender_fixtures import blends_per_kind, one_line_error, run_cli

MAKE = r"""
import sys, math, bpy
sys.path.insert(0, ".")
from tests.support.blender_fixtures import empty_scene, add_cube
kind, path = sys.argv[1], sys.argv[2]
scene = empty_scene(40, 30)
cube = add_cube("Cube", 2.0)
other = bpy.data.scenes.new("Other")
other.camera = scene.camera
other.collection.objects.link(scene.camera)
other.render.resolution_x, other.render.resolution_y = 20, 10
if kind == "nocam":
    bpy.data.objects.remove(scene.camera)
elif kind == "huge":
    scene.render.resolution_x = scene.render.resolution_y = 60000
elif kind == "anim":
    cube.location = (-3, 0, 0); cube.keyframe_insert("location", frame=1)
    cube.location = (3, 0, 0); cube.keyframe_insert("location", frame=10)
    scene.frame_set(1)
bpy.ops.wm.save_as_mainfile(filepath=path)
"""


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    return blends_per_kind(tmp_path_factory.mktemp("blends"), MAKE, ("good", "nocam", "huge", "anim"))


def test_render_png_npy_exr_and_depth(blends, tmp_path):
    npy, png, exr, depth = (tmp_path / n for n in ("f.npy", "f.png", "f.exr", "d.npy"))
    proc = run_cli("render", str(blends["good"]), "-o", str(npy), "--depth", str(depth))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == [str(npy), str(depth)]
    color = np.load(npy)
    assert color.shape == (30, 40, 4) and color.dtype == np.float32
    d = np.load(depth)
    assert d.shape == (30, 40) and d.dtype == np.float32 and d.min() < 0.99 and d.max() == 1.0
    covered = d < 1.0
    assert covered[15, 20] and not covered[0, 0]  # the cube is in the middle, the corners are cleared
    assert run_cli("render", str(blends["good"]), "-o", str(png)).returncode == 0
    # LDR: the PNG holds the stored 8-bit values with alpha 255, what F12 shows (the Combined pass
    # is opaque); --alpha keeps the frame's own alpha, which .npy and .exr always keep
    shown = images.load(png)
    np.testing.assert_array_equal(shown[..., :3], color[..., :3])
    assert (shown[..., 3] == 1).all() and color[0, 0, 3] == 0  # the cleared corners are transparent
    assert run_cli("render", str(blends["good"]), "-o", str(png), "--alpha").returncode == 0
    np.testing.assert_array_equal(images.load(png), color)
    assert run_cli("render", str(blends["good"]), "-o", str(exr)).returncode == 0
    np.testing.assert_array_equal(images.load(exr), color)


def test_scene_and_frame_options(blends, tmp_path):
    out = tmp_path / "o.npy"
    assert run_cli("render", str(blends["good"]), "-o", str(out), "--scene", "Other").returncode == 0
    assert np.load(out).shape == (10, 20, 4)
    one_line_error(run_cli("render", str(blends["good"]), "-o", str(out), "--scene", "Nope"), "no scene named 'Nope'")
    a, b = tmp_path / "a.npy", tmp_path / "b.npy"
    assert run_cli("render", str(blends["anim"]), "-o", str(a), "--frame", "1").returncode == 0
    assert run_cli("render", str(blends["anim"]), "-o", str(b), "--frame", "10").returncode == 0
    ca, cb = np.load(a), np.load(b)
    cols_a = np.flatnonzero((ca != ca[0, 0]).any(axis=(0, 2)))
    cols_b = np.flatnonzero((cb != cb[0, 0]).any(axis=(0, 2)))
    assert cols_a.mean() < 20 < cols_b.mean()  # the cube moved from left to right


@pytest.mark.parametrize("case", ["nocam", "huge", "missing", "notblend", "fakeblend", "outdir", "ext", "directory"])
def test_bad_input_one_line_error_and_no_file(blends, tmp_path, case):
    out = tmp_path / "out.png"
    blend = blends["good"]
    text = {"nocam": "no camera", "huge": "too large", "missing": "no such file", "notblend": "not a .blend file",
            "fakeblend": "cannot open", "outdir": "does not exist", "ext": "unsupported image type",
            "directory": "not a file"}[case]
    if case in ("nocam", "huge"):
        blend = blends[case]
    elif case == "missing":
        blend = tmp_path / "nope.blend"
    elif case == "notblend":
        blend = tmp_path / "x.blend"
        blend.write_text("hello")
    elif case == "fakeblend":
        blend = tmp_path / "y.blend"
        blend.write_bytes(b"BLENDER-v405" + b"\0" * 20)
    elif case == "outdir":
        out = tmp_path / "missing_dir" / "out.png"
    elif case == "ext":
        out = tmp_path / "out.jpg"
    elif case == "directory":
        blend = tmp_path
    one_line_error(run_cli("render", str(blend), "-o", str(out)), text)
    assert [p.name for p in tmp_path.iterdir() if p.suffix not in (".blend",)] == []


def test_cancel_writes_nothing(blends, tmp_path):
    code = ("import sys, blendlib.core.pipeline as p\n"
            "orig = p.render_scene\n"
            "p.render_scene = lambda s, **k: orig(s, should_cancel=lambda: True)\n"
            "from blendlib.cli import main\n"
            "sys.exit(main(sys.argv[1:]))\n")
    out = tmp_path / "c.png"
    one_line_error(run_cli("render", str(blends["good"]), "-o", str(out), "--depth", str(tmp_path / "d.npy"),
                           code=code), "render cancelled")
    assert list(tmp_path.iterdir()) == []


def test_compare(tmp_path):
    a = np.zeros((4, 5, 4), np.float32)
    b = a.copy()
    b[1, 2, 0] = 0.5
    np.save(tmp_path / "a.npy", a)
    np.save(tmp_path / "b.npy", b)
    images.save(tmp_path / "a.png", a)
    proc = run_cli("compare", str(tmp_path / "a.npy"), str(tmp_path / "a.png"))
    assert proc.returncode == 0 and "PSNR: inf" in proc.stdout and "differing pixels: 0.0000%" in proc.stdout
    proc = run_cli("compare", str(tmp_path / "a.npy"), str(tmp_path / "b.npy"), "--diff", str(tmp_path / "d.png"))
    assert proc.returncode == 0, proc.stderr
    assert "max abs diff: 0.5" in proc.stdout and "differing pixels: 5.0000%" in proc.stdout
    heat = images.load(tmp_path / "d.png")
    assert heat[1, 2, :3].tolist() == [1, 1, 1] and heat[0, 0, :3].tolist() == [0, 0, 0]
    np.save(tmp_path / "c.npy", np.zeros((3, 5, 4), np.float32))
    one_line_error(run_cli("compare", str(tmp_path / "a.npy"), str(tmp_path / "c.npy")), "sizes differ")
    one_line_error(run_cli("compare", str(tmp_path / "a.npy"), str(tmp_path / "zz.png")), "no such file")


def test_help_and_usage():
    proc = run_cli("--help")
    assert proc.returncode == 0 and "render" in proc.stdout and "compare" in proc.stdout
    proc = run_cli("render", "--help")
    assert proc.returncode == 0 and "--depth" in proc.stdout and ".png" in proc.stdout and "--scene" in proc.stdout
    assert run_cli().returncode == 2
    assert run_cli("render", "x.blend").returncode == 2  # -o is required
    assert run_cli("shaderlab", "--help").returncode == 0  # delegated to blendlib.formats.shaderlab
