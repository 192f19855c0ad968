"""``render --frames A-B[:STEP]``: Blender's ``#`` padding, ``Saved:`` lines, ``--skip-existing``,
one-line errors, and the progress bar (quiet off a terminal) (README: Viewport, animations, render farms)."""

from __future__ import annotations

import io
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from blendlib.cli.common import CliError
from blendlib.cli.frames import frame_path, parse_frames
from blendlib.cli.progress import Progress
from blendlib.formats import images
from tests.cli.test_cli import MAKE
from tests.support.blender_fixtures import one_line_error, run_cli


@pytest.fixture(scope="module")
def anim(tmp_path_factory):
    path = tmp_path_factory.mktemp("blends") / "anim.blend"
    proc = run_cli("anim", str(path), code=MAKE)
    assert proc.returncode == 0, proc.stderr
    return path


def saved(path: Path) -> str:
    return f"Saved: '{os.path.abspath(path)}'"


def test_frame_path_and_range_rules():
    assert frame_path(Path("out/f_####.png"), 7) == Path("out/f_0007.png")
    assert frame_path(Path("out/a##_b###.exr"), 42) == Path("out/a##_b042.exr")  # the last run
    assert frame_path(Path("f_#.png"), 123) == Path("f_123.png")  # a longer number is not cut
    assert frame_path(Path("f_###.png"), -5) == Path("f_-005.png")  # printf %.3d, as Blender
    assert frame_path(Path("still.png"), 3) == Path("still.png")
    assert frame_path(Path("dir#/x.png"), 3) == Path("dir#/x.png")  # only the file name
    assert list(parse_frames("1-10")) == list(range(1, 11))
    assert list(parse_frames("1-10:4")) == [1, 5, 9]
    assert list(parse_frames("5-5")) == [5]
    assert list(parse_frames("-3--1")) == [-3, -2, -1]
    assert list(parse_frames("3")) == [3] and list(parse_frames("-7")) == [-7]  # one frame: N
    assert list(parse_frames("1048570-1048574:2")) == [1048570, 1048572, 1048574]  # Blender's last frame
    for bad, text in (("10-1", "after the last"), ("1-10:0", "STEP"), ("1-10:-2", "STEP"),
                      ("1..10", "expected N, A-B"), ("a-b", "expected N, A-B"), ("1-2:1.5", "expected N, A-B"),
                      ("1-1048575", "Blender's frame range"), ("-1048575--1048570", "Blender's frame range")):
        with pytest.raises(CliError, match=text):
            parse_frames(bad)


def test_frames_write_every_frame_with_saved_lines(anim, tmp_path):
    out, depth = tmp_path / "f_####.png", tmp_path / "d_##.npy"
    proc = run_cli("render", str(anim), "-o", str(out), "--depth", str(depth), "--frames", "1-10:4")
    assert proc.returncode == 0, proc.stderr
    frames = (1, 5, 9)
    expected = []
    for n in frames:
        expected += [saved(tmp_path / f"f_{n:04d}.png"), saved(tmp_path / f"d_{n:02d}.npy")]
    assert proc.stdout.splitlines() == expected
    assert proc.stderr == ""  # no progress bar when stderr is not a terminal
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [f"f_{n:04d}.png" for n in frames] + [f"d_{n:02d}.npy" for n in frames])
    pngs = [images.to_uint8(images.load(tmp_path / f"f_{n:04d}.png")) for n in frames]
    assert not np.array_equal(pngs[0], pngs[1]) and not np.array_equal(pngs[1], pngs[2])  # the cube moves
    # each frame equals a single-frame render of that frame
    single = tmp_path / "single5.npy"
    assert run_cli("render", str(anim), "-o", str(single), "--frame", "5").returncode == 0
    np.testing.assert_array_equal(pngs[1][..., :3], images.to_uint8(np.load(single))[..., :3])
    assert (pngs[1][..., 3] == 255).all()  # a PNG shows what F12 shows: opaque
    assert np.load(tmp_path / "d_05.npy").shape == (30, 40)


def test_skip_existing(anim, tmp_path):
    out = tmp_path / "f_#.png"
    assert run_cli("render", str(anim), "-o", str(out), "--frames", "9-11").returncode == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f_10.png", "f_11.png", "f_9.png"]
    (tmp_path / "f_10.png").unlink()
    os.utime(tmp_path / "f_9.png", (1_000_000, 1_000_000))
    proc = run_cli("render", str(anim), "-o", str(out), "--frames", "9-11", "--skip-existing")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [f"Skipped: '{tmp_path / 'f_9.png'}'", saved(tmp_path / "f_10.png"),
                                        f"Skipped: '{tmp_path / 'f_11.png'}'"]
    assert (tmp_path / "f_9.png").stat().st_mtime == 1_000_000  # not rewritten


def test_single_frame_range_needs_no_hash(anim, tmp_path):
    out = tmp_path / "still.npy"
    proc = run_cli("render", str(anim), "-o", str(out), "--frames", "10-10")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [saved(out)]
    ref = tmp_path / "ref.npy"
    assert run_cli("render", str(anim), "-o", str(ref), "--frame", "10").returncode == 0
    np.testing.assert_array_equal(np.load(out), np.load(ref))


@pytest.mark.parametrize("args,text", [
    (["-o", "{tmp}/f_#.png", "--frames", "5-1"], "after the last frame"),
    (["-o", "{tmp}/f_#.png", "--frames", "1-5:0"], "STEP must be 1 or more"),
    (["-o", "{tmp}/f.png", "--frames", "1-5"], "needs a '#'"),
    (["-o", "{tmp}/f_#.png", "--depth", "{tmp}/d.npy", "--frames", "1-2"], "--depth needs a '#'"),
    (["-o", "{tmp}/f_#.png", "--frames", "1-2", "--frame", "3"], "--frame and --frames"),
])
def test_frame_range_errors(anim, tmp_path, args, text):
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    one_line_error(run_cli("render", str(anim), *args), text)
    assert not list(tmp_path.iterdir())


def test_progress_bar_only_on_a_terminal(monkeypatch, capsys):
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    term = Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    with Progress(3, "frames") as bar:
        assert bar.enabled
        bar.set(1.5)
        bar.write("Saved: 'x'")
    assert "frames" in term.getvalue() and "50%" in term.getvalue()
    assert capsys.readouterr().out == "Saved: 'x'\n"
    pipe = io.StringIO()
    monkeypatch.setattr(sys, "stderr", pipe)
    with Progress(3, "frames") as bar:
        assert not bar.enabled
        bar.set(2)
        bar.write("Saved: 'y'")
    assert pipe.getvalue() == "" and capsys.readouterr().out == "Saved: 'y'\n"
