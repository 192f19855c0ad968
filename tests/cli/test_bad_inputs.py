"""A corpus of bad input to the CLI: each case gives its exact outcome.

For every case: the exit status, the one stderr line's gist (no traceback, no "internal
error", no leaked numpy warning), no output file left, the inputs unchanged (sha256) and,
where a file is replaced, its mode bits.
"""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from tests.support.blender_fixtures import REPO, build_blends, run_cli

MAKE = r"""
scene = empty_scene(40, 30)
add_cube("Cube", 2.0)
save("good")
scene.camera.scale = (0.0, 1.0, 1.0)
save("camscale0")
scene.camera.scale = (1.0, 1.0, 1.0)
scene.render.resolution_x = scene.render.resolution_y = 4
scene.render.resolution_percentage = 1
save("zerosize")
scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 40, 30, 100
scene.camera.data.type = "PANO"
save("pano")
scene.camera.data.type = "PERSP"
scene.camera.data.clip_start, scene.camera.data.clip_end = 5.0, 5.0
save("nearfar")
scene.camera.data.clip_start, scene.camera.data.clip_end = 0.1, 100.0
nan = float("nan")
add_mesh("Broken", [(1.2, -2, 0), (2.0, -2, 0), (1.2, -2, 0.8), (nan, -2, 0), (2.1, -2, 0.8)], [(0, 1, 2), (1, 3, 4)],
         material=unlit_material("Red", (1.0, 0.0, 0.0, 1.0)))
save("nanvertex")
bpy.data.objects.remove(bpy.data.objects["Broken"])
huge = add_cube("Huge", 1.0)
huge.scale = (1e39, 1.0, 1.0)
save("infscale")
bpy.data.objects.remove(huge)
# A frame that takes long enough to interrupt: 150 big blended quads at 1200x900.
scene.render.resolution_x, scene.render.resolution_y = 1200, 900
glass = unlit_material("Glass", (0.2, 0.6, 1.0, 0.5))
if hasattr(glass, "unity"):
    glass.unity.passes[0].blend = True
for i in range(150):
    add_cube(f"Slab{i}", 6.0, (0.0, 2.0 + i * 0.01, 0.0), glass)
save("slow")
"""

BLENDS = ("good", "camscale0", "zerosize", "pano", "nearfar", "nanvertex", "infscale", "slow")


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    return build_blends(tmp_path_factory.mktemp("bad_blends"), MAKE, BLENDS)


def sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def lines(proc) -> list[str]:
    return [x for x in proc.stderr.splitlines() if x.strip()]


def one_error(proc, gist: str, code: int = 1) -> None:
    got = lines(proc)
    assert proc.returncode == code, proc.stderr
    assert len(got) == 1 and gist in got[0], proc.stderr
    assert "internal error" not in got[0] and "Traceback" not in proc.stderr


def clean_warnings(proc) -> list[str]:
    """The stderr lines, all of them ``warning: ...`` (nothing leaked from numpy or Blender)."""
    got = lines(proc)
    assert all(x.startswith("warning: ") for x in got), proc.stderr
    return got


# --------------------------------------------------------------------------- data loss


def test_output_equal_to_depth_is_refused_and_leaves_the_file(blends, tmp_path):
    target = tmp_path / "same.npy"
    np.save(target, np.arange(6.0))
    before = sha(target)
    one_error(run_cli("render", str(blends["good"]), "-o", str(target), "--depth", str(target)),
              "--depth is the same file as -o")
    assert sha(target) == before and os.listdir(tmp_path) == ["same.npy"]


def test_output_equal_to_the_blend_is_refused(blends, tmp_path):
    blend = tmp_path / "scene.npy"  # a .blend under an image name: -o would overwrite it
    blend.write_bytes(blends["good"].read_bytes())
    before = sha(blend)
    one_error(run_cli("render", str(blend), "-o", str(blend)), "-o is the same file as FILE.blend")
    assert sha(blend) == before and os.listdir(tmp_path) == ["scene.npy"]
    link = tmp_path / "link.npy"
    link.symlink_to(blend)
    one_error(run_cli("render", str(blend), "-o", str(link)), "is the same file as FILE.blend")
    assert sha(blend) == before


def test_shaderlab_export_refuses_its_input_and_other_extensions(blends, tmp_path):
    blend = tmp_path / "scene.blend"
    blend.write_bytes(blends["good"].read_bytes())
    before = sha(blend)
    one_error(run_cli("shaderlab", "--export", str(blend), "--material", "M", "-o", str(blend)),
              "the export writes a .shader file")
    shader_named = tmp_path / "scene.shader"  # a .blend named .shader
    shader_named.write_bytes(blend.read_bytes())
    one_error(run_cli("shaderlab", "--export", str(shader_named), "--material", "M", "-o", str(shader_named)),
              "is the input file")
    assert sha(blend) == before and sha(shader_named) == before
    assert sorted(os.listdir(tmp_path)) == ["scene.blend", "scene.shader"]


def test_output_that_is_a_directory_is_an_error_before_rendering(blends, tmp_path):
    folder = tmp_path / "out.png"
    folder.mkdir()
    start = time.monotonic()
    proc = run_cli("render", str(blends["slow"]), "-o", str(folder))
    one_error(proc, f"{folder}: is a directory")
    assert ".part" not in proc.stderr
    assert os.listdir(folder) == []
    depth_folder = tmp_path / "depth.npy"
    depth_folder.mkdir()
    one_error(run_cli("render", str(blends["good"]), "-o", str(tmp_path / "d.npy"), "--depth", str(depth_folder)),
              f"{depth_folder}: is a directory")
    assert os.listdir(depth_folder) == [] and sorted(os.listdir(tmp_path)) == ["depth.npy", "out.png"]
    assert time.monotonic() - start < 120  # (a generous bound: the point is that it fails before rendering)


# --------------------------------------------------------------------------- scenes that cannot render


@pytest.mark.parametrize("kind, gist", [
    ("camscale0", "transform cannot be inverted"),
    ("zerosize", "render size is 0x0 pixels"),
    ("pano", "panoramic cameras are not supported"),
    ("nearfar", "Clip Start 5 must be less than Clip End 5"),
])
def test_scenes_that_cannot_render_give_one_line(blends, tmp_path, kind, gist):
    before = sha(blends[kind])
    one_error(run_cli("render", str(blends[kind]), "-o", str(tmp_path / "o.png")), gist)
    assert os.listdir(tmp_path) == [] and sha(blends[kind]) == before


def test_a_nan_vertex_skips_its_triangles_with_one_warning(blends, tmp_path):
    out = tmp_path / "o.npy"
    proc = run_cli("render", str(blends["nanvertex"]), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    got = clean_warnings(proc)
    assert len(got) == 1 and "'Broken'" in got[0] and "skipped 1 triangles with non-finite vertices" in got[0]
    color = np.load(out)
    assert np.isfinite(color).all()
    ref = tmp_path / "ref.npy"
    assert run_cli("render", str(blends["good"]), "-o", str(ref)).returncode == 0
    drawn = (color != np.load(ref)).any(axis=2)
    assert drawn.sum() > 10 and drawn[:, :20].sum() == 0  # the finite triangle is drawn, right of the cube


def test_an_infinite_scale_warns_and_draws_nothing_of_that_object(blends, tmp_path):
    out, ref = tmp_path / "o.npy", tmp_path / "ref.npy"
    proc = run_cli("render", str(blends["infscale"]), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    got = clean_warnings(proc)
    assert got == ["warning: object 'Huge': its transform is not finite (an infinite scale or location, "
                   "beyond 1e+30); not drawn"]
    assert run_cli("render", str(blends["good"]), "-o", str(ref)).returncode == 0
    np.testing.assert_array_equal(np.load(out), np.load(ref))


# --------------------------------------------------------------------------- frame numbers


def test_frame_that_is_not_an_integer_is_a_usage_error(blends, tmp_path):
    proc = run_cli("render", str(blends["good"]), "-o", str(tmp_path / "o.png"), "--frame", "1e14")
    assert proc.returncode == 2 and "frame must be an integer, got '1e14'" in proc.stderr
    assert "Traceback" not in proc.stderr and os.listdir(tmp_path) == []


@pytest.mark.parametrize("frame, clamped", [("2000000000", 1048574), ("-100000000000000", -1048574)])
def test_frame_outside_blenders_range_is_clamped_with_a_warning(blends, tmp_path, frame, clamped):
    out = tmp_path / "o.npy"
    proc = run_cli("render", str(blends["good"]), "-o", str(out), "--frame", frame)
    assert proc.returncode == 0, proc.stderr
    assert clean_warnings(proc) == [f"warning: --frame {frame} is outside Blender's frame range; "
                                    f"rendering frame {clamped}"]
    assert np.load(out).shape == (30, 40, 4)


# --------------------------------------------------------------------------- compare


@pytest.mark.parametrize("dtype, gist", [("<U3", "got dtype <U3"), ("complex64", "got dtype complex64")])
def test_compare_refuses_arrays_that_are_not_real_numbers(tmp_path, dtype, gist):
    a = tmp_path / "a.npy"
    b = tmp_path / "b.npy"
    np.save(a, np.zeros((2, 2, 4), np.float32))
    np.save(b, np.zeros((2, 2, 4), dtype=dtype))
    one_error(run_cli("compare", str(a), str(b)), gist)


@pytest.mark.parametrize("tolerance", ["nan", "inf", "-1", "x"])
def test_compare_tolerance_must_be_finite_and_not_negative(tmp_path, tolerance):
    a = tmp_path / "a.npy"
    np.save(a, np.zeros((2, 2, 4), np.float32))
    proc = run_cli("compare", str(a), str(a), f"--tolerance={tolerance}")
    assert proc.returncode == 2 and f"tolerance must be a finite number >= 0, got '{tolerance}'" in proc.stderr


def test_compare_of_infinities_leaks_no_numpy_warning(tmp_path):
    a, b = tmp_path / "a.npy", tmp_path / "b.npy"
    np.save(a, np.array([[[np.inf, 1e300, 0, 1]]], np.float64))
    np.save(b, np.array([[[np.inf, -1e300, np.nan, 1]]], np.float64))
    proc = run_cli("compare", str(a), str(b))
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert "max abs" in proc.stdout.lower() or proc.stdout


# --------------------------------------------------------------------------- file modes


def test_a_replaced_output_keeps_its_mode_and_a_new_one_follows_the_umask(blends, tmp_path):
    out = tmp_path / "o.npy"
    out.write_bytes(b"old")
    out.chmod(0o640)
    assert run_cli("render", str(blends["good"]), "-o", str(out)).returncode == 0
    assert (out.stat().st_mode & 0o777) == 0o640 and np.load(out).shape == (30, 40, 4)
    new = tmp_path / "new.npy"
    code = ("import os, sys\nos.umask(0o027)\nfrom blendlib.cli import main\nsys.exit(main(sys.argv[1:]))\n")
    assert run_cli("render", str(blends["good"]), "-o", str(new), code=code).returncode == 0
    assert (new.stat().st_mode & 0o777) == 0o640
    assert sorted(os.listdir(tmp_path)) == ["new.npy", "o.npy"]  # no temporary file left


# --------------------------------------------------------------------------- Ctrl+C


def test_one_sigint_mid_render_cancels_promptly_and_writes_nothing(blends, tmp_path):
    out, depth = tmp_path / "o.png", tmp_path / "d.npy"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    # How long the start (imports, opening the file) takes here: interrupt well after it.
    t0 = time.monotonic()
    assert run_cli("render", str(blends["good"]), "-o", str(tmp_path / "warm.npy")).returncode == 0
    startup = time.monotonic() - t0
    (tmp_path / "warm.npy").unlink()
    proc = subprocess.Popen([sys.executable, "-m", "blendlib", "render", str(blends["slow"]), "-o", str(out),
                             "--depth", str(depth)], cwd=REPO, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    time.sleep(startup + 2.0)
    assert proc.poll() is None, "the render finished before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    sent = time.monotonic()
    stdout, stderr = proc.communicate(timeout=120)
    waited = time.monotonic() - sent
    assert proc.returncode == 130, stderr
    got = [x for x in stderr.splitlines() if x.strip()]
    assert got == ["error: interrupted; nothing written"], stderr
    assert stdout == "" and os.listdir(tmp_path) == []
    assert waited < 30  # promptly: not after the whole render


# --------------------------------------------------------------------------- a damaged file


DAMAGED = REPO / "tests" / "fixtures" / "damaged" / "loader_crash.blend"


def test_a_file_that_crashes_blenders_loader_is_named(tmp_path):
    """tests/fixtures/damaged/loader_crash.blend: a saved scene with one pointer of its mesh redirected
    to another block; Blender's own loader dies of a segmentation fault reading it. Before, the CLI
    ended with status 139 and nothing on stderr (stderr is silenced while Blender loads)."""
    out = tmp_path / "o.png"
    proc = run_cli("render", str(DAMAGED), "-o", str(out))
    assert proc.returncode != 0
    assert lines(proc) == [f"error: {DAMAGED}: Blender crashed while reading this file (Segmentation fault); "
                           "is the file damaged?"], proc.stderr
    assert os.listdir(tmp_path) == [] and proc.stdout == ""


# --------------------------------------------------------------------------- ShaderLab input


def test_shaderlab_error_lines_shorten_a_huge_token():
    """Before, a 10 MB bad token made a 10 MB error line."""
    text = 'Shader "x" { SubShader { Pass { Blend ' + "A" * 200_000 + " One } } }"
    proc = subprocess.run([sys.executable, "-m", "blendlib", "shaderlab", "-"], input=text, cwd=REPO,
                          capture_output=True, text=True, timeout=120)
    one_error(proc, "<stdin>:1:39: unknown blend factor 'AAAAAAAAAA")
    assert "…(200002 characters)" in proc.stderr and len(proc.stderr) < 400


def test_shaderlab_standard_input_must_be_utf8_as_a_file_must(tmp_path):
    """Before, ``shaderlab -`` accepted bytes that are not UTF-8 (a file with them is refused)."""
    data = b'Shader "x\xff" { SubShader { Pass { } } }'
    (tmp_path / "bad.shader").write_bytes(data)
    one_error(run_cli("shaderlab", str(tmp_path / "bad.shader")), "bad.shader: not UTF-8 text")
    proc = subprocess.run([sys.executable, "-m", "blendlib", "shaderlab", "-"], input=data, cwd=REPO,
                          capture_output=True, timeout=120)
    assert proc.returncode == 1 and proc.stdout == b""
    assert proc.stderr.decode().splitlines() == ["error: <stdin>: not UTF-8 text (invalid start byte)"]


def test_a_stencil_value_from_a_property_is_imported_with_a_warning():
    """Ref [_StencilRef] takes the property's default; before, the binding was dropped without a
    word (a material's own value is not applied, and an export writes the number)."""
    from blendlib.formats.shaderlab import parse_shaderlab

    result = parse_shaderlab('Shader "S" { Properties { _StencilRef ("r", Int) = 3 } '
                             "SubShader { Pass { Stencil { Ref [_StencilRef] Comp Always Pass Replace } } } }")
    assert result.material.passes[0].stencil_ref == 3
    assert [w for w in result.warnings if "_StencilRef" in w] == [  # at the property name
        "1:90: Stencil Ref [_StencilRef]: imported as the property's default 3; a material's own value is not "
        "applied and an export writes this number"]
