"""Ctrl+C and SIGTERM at the moments users and farm managers send them (README "Command line":
interrupts), as real signals to real processes (tests/support/processes.py): while Python starts,
while ``import bpy`` runs, while the .blend file loads, while a frame's depth is written,
between frames; twice in a row. Each time: the exit status, the one stderr line saying what was
written, and the files (none half-written, none hidden left over, none replaced by half a frame).
"""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

from tests.support.blender_fixtures import build_blends
from tests.support.processes import appears, finish, mapped, reading, signal_at, start, stderr_lines

MAKE = r"""
from blendlib.core.vocabulary import preset
scene = empty_scene(40, 30)
queue, passes = preset("Alpha Blend")
glass = unlit_material("Glass", (0.2, 0.6, 1.0, 0.5), queue=queue, passes=passes)
cube = add_cube("Cube", 2.0, material=glass)
save("good")
# Large frames: writing a 3000x2000 PNG takes a while, and its depth .npy 24 MB.
scene.render.resolution_x, scene.render.resolution_y = 3000, 2000
save("big")
# Frames that take a moment each (many blended slabs), the cube moving.
scene.render.resolution_x, scene.render.resolution_y = 320, 240
for i in range(60):
    add_cube(f"Slab{i}", 6.0, (0.0, 2.0 + i * 0.01, 0.0), glass)
cube.location = (-3, 0, 0); cube.keyframe_insert("location", frame=1)
cube.location = (3, 0, 0); cube.keyframe_insert("location", frame=40)
save("frames")
for obj in [o for o in bpy.data.objects if o.name.startswith("Slab")]:
    bpy.data.objects.remove(obj)
# A file that takes a while to load: a large mesh, hidden from renders.
bpy.ops.mesh.primitive_grid_add(x_subdivisions=600, y_subdivisions=600, size=1)
bpy.context.active_object.hide_render = True
save("heavy")
"""

KINDS = ("good", "big", "frames", "heavy")


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    return build_blends(tmp_path_factory.mktemp("interrupt_blends"), MAKE, KINDS)


def only_line(err: str, line: str) -> None:
    assert stderr_lines(err) == [line], err
    assert "Traceback" not in err


def ended_writing_nothing(result: tuple[int, str, str], folder, status: int = 130,
                          line: str = "error: interrupted; nothing written") -> None:
    """The command ended by itself with ``status`` and its one ``line``; no output, no file."""
    got, out, err = result
    assert got == status, (got, err)
    only_line(err, line)
    assert out == "" and os.listdir(folder) == []


# --------------------------------------------------------------------------- before the work


def test_sigint_while_python_imports_prints_one_line(blends, tmp_path):
    """numpy mapped: the package is importing (before, python -m blendlib imported numpy before its
    __main__ installed any handling, and a Ctrl+C printed a KeyboardInterrupt traceback)."""
    proc = start("render", str(blends["good"]), "-o", str(tmp_path / "o.png"))
    ended_writing_nothing(signal_at(proc, mapped(proc, "numpy/core/_multiarray_umath"), "numpy is imported"), tmp_path)


@pytest.mark.parametrize("command", ["analyze", "drawlist", "shaderlab", "frames"])
def test_sigint_during_import_bpy_ends_cleanly(blends, tmp_path, command):
    """bpy's module mapped: ``import bpy`` runs. Before, every subcommand but the plain render died
    of a segmentation fault (a KeyboardInterrupt inside Blender's initialisation); ``pixel`` is
    the SIGTERM test's."""
    good = str(blends["good"])
    args = {"analyze": ["analyze", good, "--error", str(tmp_path / "e.png")],
            "drawlist": ["drawlist", good],
            "shaderlab": ["shaderlab", "--export", good, "--material", "Glass", "-o", str(tmp_path / "g.shader")],
            "frames": ["render", good, "-o", str(tmp_path / "f_#.png"), "--frames", "1-3"]}[command]
    proc = start(*args)
    ended_writing_nothing(signal_at(proc, mapped(proc, "bpy/__init__.so"), "import bpy"), tmp_path)


def test_sigterm_is_handled_as_ctrl_c(blends, tmp_path):
    proc = start("pixel", str(blends["good"]), "3", "4")
    result = signal_at(proc, mapped(proc, "bpy/__init__.so"), "import bpy", signal.SIGTERM)
    # not -15: the process ends by itself, with its line
    ended_writing_nothing(result, tmp_path, 128 + signal.SIGTERM, "error: interrupted (SIGTERM); nothing written")


@pytest.mark.parametrize("command", ["frames", "drawlist"])
def test_the_first_sigint_while_the_file_loads_is_not_lost(blends, tmp_path, command):
    """Before, Blender's loader swallowed the KeyboardInterrupt: all 20 frames were rendered and
    saved, the draw list printed in full."""
    heavy = blends["heavy"]
    args = (["render", str(heavy), "-o", str(tmp_path / "f_##.png"), "--frames", "1-20"] if command == "frames"
            else ["drawlist", str(heavy)])
    proc = start(*args)
    ended_writing_nothing(signal_at(proc, reading(proc, heavy), "Blender reads the .blend file"), tmp_path)


# --------------------------------------------------------------------------- while writing


def old_pair(folder, colour: str, depth: str) -> tuple[bytes, bytes]:
    """Existing outputs with known content: a 2x2 PNG and a (2, 2) depth."""
    from blendlib.formats import images

    images.save(folder / colour, np.full((2, 2, 4), 0.5, np.float32))
    np.save(folder / depth, np.full((2, 2), 0.25, np.float32))
    return (folder / colour).read_bytes(), (folder / depth).read_bytes()


@pytest.mark.parametrize("frames", [False, True])
def test_sigint_while_the_depth_is_written_keeps_both_old_files(blends, tmp_path, frames):
    """The depth's temporary file appeared: the colour image is written, the depth is being
    written. Before, a single render then deleted the old out_1.png (neither old nor new was
    left) and --frames kept the new colour image beside the old depth, a pair --skip-existing
    then kept. Now neither is replaced: a frame's outputs are committed together."""
    before = old_pair(tmp_path, "out_1.png", "depth_1.npy")
    args = ["render", str(blends["big"])]
    args += (["-o", str(tmp_path / "out_#.png"), "--depth", str(tmp_path / "depth_#.npy"), "--frames", "1-1"]
             if frames else ["-o", str(tmp_path / "out_1.png"), "--depth", str(tmp_path / "depth_1.npy")])
    proc = start(*args)
    status, out, err = signal_at(proc, appears(tmp_path, ".depth_1.npy."), "the depth is being written",
                                 poll=0)  # a write of some 20 ms
    assert sorted(os.listdir(tmp_path)) == ["depth_1.npy", "out_1.png"]  # no temporary file left
    assert (tmp_path / "out_1.png").read_bytes() == before[0], "the colour image was replaced"
    assert (tmp_path / "depth_1.npy").read_bytes() == before[1], "the depth was replaced"
    assert status == 130, (status, err)
    only_line(err, "error: interrupted; nothing written" + ("; frame 1 and later not written" if frames else ""))


def test_sigterm_between_frames_says_what_was_written_and_leaves_no_part_file(blends, tmp_path):
    """A farm manager cancelling a task: before, the process died of SIGTERM (-15) without a word and
    left hidden .part files; an interrupted series said "nothing written" after frames were saved."""
    proc = start("render", str(blends["frames"]), "-o", str(tmp_path / "f_##.png"), "--depth",
                 str(tmp_path / "d_##.npy"), "--frames", "1-40")
    saved = [proc.stdout.readline() for _ in range(4)]  # two frames: colour and depth each
    proc.send_signal(signal.SIGTERM)
    status, out, err = finish(proc)
    assert status == 143, (status, err)
    lines = saved + out.splitlines(keepends=True)
    written = sorted(int(line.split("_")[-1][:2]) for line in lines if line.startswith("Saved:") and "f_" in line)
    n = len(written)
    assert 2 <= n < 40 and written == list(range(1, n + 1))
    last = tmp_path / f"d_{n:02d}.npy"
    only_line(err, f"error: interrupted (SIGTERM); {n} of 40 frames written (frames 1 to {n}, "
                   f"the last file '{last}'); frame {n + 1} and later not written")
    assert sorted(os.listdir(tmp_path)) == sorted([f"f_{k:02d}.png" for k in written] +
                                                  [f"d_{k:02d}.npy" for k in written])


def test_a_second_sigint_right_after_the_first_changes_nothing(blends, tmp_path):
    """Before, a second Ctrl+C 50 ms after the first killed the process (-2) without its line."""
    proc = start("render", str(blends["frames"]), "-o", str(tmp_path / "f_##.npy"), "--frames", "1-40")
    first = proc.stdout.readline()
    assert first.startswith("Saved:")
    proc.send_signal(signal.SIGINT)
    time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    status, out, err = finish(proc)
    assert status == 130, (status, err)
    lines = stderr_lines(err)
    assert len(lines) == 1 and lines[0].startswith("error: interrupted; ") and "frames written" in lines[0], err
    assert not [n for n in os.listdir(tmp_path) if n.endswith(".part")]
