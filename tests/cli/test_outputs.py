"""The command line's outputs (README "Command line", "Animations"): ``--until-draw`` in every mode,
frame numbers, ``#`` expansion, collisions, errors naming the user's file, checks before the
work, ``--skip-existing``'s rule, the frames' folder. Checks that fail before the .blend file
is opened run ``main()`` in this process (no Blender needed); the rest run the CLI as users do.
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from blendlib.cli import main
from tests.cli.test_cli import MAKE
from tests.support.blender_fixtures import REPO, blends_per_kind, one_line_error, run_cli


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    return blends_per_kind(tmp_path_factory.mktemp("output_blends"), MAKE, ("good", "anim"))


def early_error(capsys, args: list[str], gist: str) -> None:
    """``main(args)`` fails with one error line containing ``gist``, before any work."""
    assert main([str(a) for a in args]) == 1
    err = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert len(err) == 1 and err[0].startswith("error: ") and gist in err[0], err
    assert "internal error" not in err[0] and ".part" not in err[0]


# --------------------------------------------------------------------------- --until-draw


@pytest.mark.parametrize("mode", [["--frames", "1-1"], ["--skip-existing"]])
def test_until_draw_applies_to_frames_and_skip_existing(blends, tmp_path, mode):
    """Before, --until-draw was ignored with --frames and --skip-existing: the full frame was written."""
    out = tmp_path / "k_#.npy"
    proc = run_cli("render", str(blends["good"]), "-o", str(out), "--until-draw", "0", *mode)
    assert proc.returncode == 0, proc.stderr
    [written] = tmp_path.iterdir()
    cleared = np.load(written)
    assert (cleared == cleared[0, 0]).all() and cleared[0, 0, 3] == 0  # the cleared frame: no cube
    full = tmp_path / "full.npy"
    assert run_cli("render", str(blends["good"]), "-o", str(full)).returncode == 0
    assert (np.load(full) != cleared).any(axis=2).sum() > 50  # the cube


def test_until_draw_beyond_the_last_draw_call_is_an_error(blends, tmp_path):
    """Before, 50 (or 10^20) silently rendered the whole frame. The good scene has one draw call."""
    for k in ("50", str(10 ** 20)):
        one_line_error(run_cli("render", str(blends["good"]), "-o", str(tmp_path / "o.npy"), "--until-draw", k),
                       f"until_draw {k} is beyond the last draw call: the frame has 1")
    assert os.listdir(tmp_path) == []


# --------------------------------------------------------------------------- frame numbers


@pytest.mark.parametrize("frames", ["1-99999999999999999999", "2147483647-2147483649", "1048574-1048575",
                                    "-1048575--1048574"])
def test_frames_outside_blenders_range_are_refused_before_rendering(blends, tmp_path, capsys, frames):
    """Before: OverflowError, a ValueError after one frame, or frames beyond ±1048574 written under
    their own numbers with frame 1048574's content."""
    early_error(capsys, ["render", blends["good"], "-o", tmp_path / "f_#.png", f"--frames={frames}"],
                "Blender's frame range -1048574 to 1048574")
    assert os.listdir(tmp_path) == []


def test_frames_n_and_hash_in_a_single_render(blends, tmp_path):
    """--frames 3 was refused; '#' in a single render's name stayed literal."""
    proc = run_cli("render", str(blends["anim"]), "-o", str(tmp_path / "n_#.npy"), "--frames", "3")
    assert proc.returncode == 0 and proc.stdout.splitlines() == [f"Saved: '{tmp_path / 'n_3.npy'}'"], proc.stderr
    proc = run_cli("render", str(blends["anim"]), "-o", str(tmp_path / "s_###.npy"), "--frame", "3")
    assert proc.returncode == 0 and proc.stdout.splitlines() == [str(tmp_path / "s_003.npy")], proc.stderr
    np.testing.assert_array_equal(np.load(tmp_path / "s_003.npy"), np.load(tmp_path / "n_3.npy"))
    proc = run_cli("render", str(blends["anim"]), "-o", str(tmp_path / "c_##.npy"))  # the file's frame: 1
    assert proc.returncode == 0 and proc.stdout.splitlines() == [str(tmp_path / "c_01.npy")], proc.stderr
    assert sorted(os.listdir(tmp_path)) == ["c_01.npy", "n_3.npy", "s_003.npy"]


# --------------------------------------------------------------------------- collisions and early checks


@pytest.mark.parametrize("args, gist", [
    (["-o", "a_#.npy", "--depth", "a_1.npy", "--frames", "1-1"], "a_1.npy: --depth is the same file as -o"),
    (["-o", "x#.npy", "--depth", "x1#.npy", "--frames", "0-10"],
     "x10.npy: --depth of frame 0 is the same file as -o of frame 10"),
    (["-o", "b_##.npy", "--depth", "b_#.npy", "--frame", "12"], "b_12.npy: --depth is the same file as -o"),
])
def test_outputs_that_collide_after_hash_expansion_are_refused(blends, tmp_path, capsys, args, gist):
    """Before: 'Saved:' printed twice, the colour file overwritten by the depth."""
    args = [str(tmp_path / a) if a.endswith(".npy") else a for a in args]
    early_error(capsys, ["render", blends["good"], *args], gist)
    assert os.listdir(tmp_path) == []


def test_a_read_only_output_is_not_replaced(blends, tmp_path, capsys):
    out = tmp_path / "o.npy"
    out.write_bytes(b"keep")
    out.chmod(0o444)
    early_error(capsys, ["render", blends["good"], "-o", out], "the file is read-only; -o does not replace it")
    assert out.read_bytes() == b"keep" and os.listdir(tmp_path) == ["o.npy"]


def test_a_frame_output_that_is_a_directory_is_refused_before_rendering(blends, tmp_path):
    """Before: the render ran, then '[Errno 21] Is a directory: '.dd_5.png.vtltkvb0.part''."""
    (tmp_path / "dd_5.png").mkdir()
    for extra in ([], ["--skip-existing"]):  # --skip-existing skipped a directory
        proc = run_cli("render", str(blends["good"]), "-o", str(tmp_path / "dd_#.png"), "--frames", "5-5", *extra)
        one_line_error(proc, f"{tmp_path / 'dd_5.png'}: is a directory")
        assert ".part" not in proc.stderr and proc.stdout == ""
    assert os.listdir(tmp_path) == ["dd_5.png"] and os.listdir(tmp_path / "dd_5.png") == []


def test_analyze_checks_its_outputs_before_the_analysis(blends, tmp_path, capsys):
    """--error dir.png failed after the whole analysis (the early check tested dir.npy)."""
    (tmp_path / "dir.png").mkdir()
    early_error(capsys, ["analyze", blends["good"], "--error", tmp_path / "dir.png"], "dir.png: is a directory")
    early_error(capsys, ["analyze", blends["good"], "--overdraw", tmp_path / "no" / "od.npy"], "does not exist")


@pytest.mark.parametrize("frames", [False, True])
def test_a_full_disk_names_the_users_file(blends, tmp_path, frames):
    """A write cut short (here by a file-size limit, as a full disk cuts it): before, --frames said
    numpy's '4147200 requested and 47072 written' or 'No space left on device' without a file name."""
    out = tmp_path / ("big_#.npy" if frames else "big.npy")
    extra = ["--frames", "1-1"] if frames else []

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails instead of killing
        resource.setrlimit(resource.RLIMIT_FSIZE, (10_000, 10_000))

    proc = subprocess.run([sys.executable, "-m", "blendlib", "render", str(blends["good"]), "-o", str(out), *extra],
                          cwd=REPO, capture_output=True, text=True, timeout=300, preexec_fn=limit)
    one_line_error(proc, f"{tmp_path / 'big_1.npy' if frames else out}: cannot write (")
    assert "is the disk full?" in proc.stderr
    assert ".part" not in proc.stderr and os.listdir(tmp_path) == []


# --------------------------------------------------------------------------- --skip-existing, folders


def test_skip_existing_keeps_only_complete_pairs(blends, tmp_path):
    """A frame is skipped when all its outputs exist, not empty, written together (one mtime, as a
    commit leaves them); an empty file or a pair from different runs is rendered again."""
    out, depth = tmp_path / "f_#.npy", tmp_path / "d_#.npy"
    proc = run_cli("render", str(blends["anim"]), "-o", str(out), "--depth", str(depth), "--frames", "1-3")
    assert proc.returncode == 0, proc.stderr
    (tmp_path / "f_2.npy").write_bytes(b"")  # an empty file (before, it was skipped)
    t = time.time() - 1000
    os.utime(tmp_path / "d_3.npy", (t, t))  # a depth older than its colour image: a mismatched pair
    kept = (tmp_path / "f_1.npy").stat().st_mtime_ns
    proc = run_cli("render", str(blends["anim"]), "-o", str(out), "--depth", str(depth), "--frames", "1-3",
                   "--skip-existing")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [f"Skipped: '{tmp_path / 'f_1.npy'}'"] + [
        f"Saved: '{tmp_path / name}'" for name in ("f_2.npy", "d_2.npy", "f_3.npy", "d_3.npy")]
    assert (tmp_path / "f_1.npy").stat().st_mtime_ns == kept
    assert np.load(tmp_path / "f_2.npy").shape == (30, 40, 4)
    stamps = {(tmp_path / n).stat().st_mtime_ns for n in ("f_3.npy", "d_3.npy")}
    assert len(stamps) == 1  # one commit, one modification time


def test_the_frames_output_folder_is_created(blends, tmp_path):
    """As Blender creates it; a single render still needs an existing folder."""
    out = tmp_path / "new" / "deeper" / "f_#.npy"
    proc = run_cli("render", str(blends["anim"]), "-o", str(out), "--frames", "1-2")
    assert proc.returncode == 0, proc.stderr
    assert sorted(os.listdir(out.parent)) == ["f_1.npy", "f_2.npy"]
