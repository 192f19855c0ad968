"""``blendlib.testing``: the pytest plugin for golden-image tests of users' own scenes
(README: "Viewport, animations, render farms").

The comparison rules directly, and the plugin as users run it, through pytest's own ``pytester``.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import bpy
import hypothesis  # noqa: F401 - imported before pytester's module snapshot (see the pytester test)
import numpy as np
import pytest

import blendlib.blender  # noqa: F401
from blendlib import testing
from blendlib.formats import heatmap, images
from blendlib.testing import assert_frame_matches

pytest_plugins = ["pytester"]

ROOT = Path(__file__).resolve().parent.parent


def ramp(h=6, w=8) -> np.ndarray:
    codes = (np.arange(h * w * 4).reshape(h, w, 4) * 7 % 256).astype(np.float32)
    return codes / 255.0


@pytest.fixture(autouse=True)
def no_update():
    testing.update_goldens(False)
    yield
    testing.update_goldens(False)


@pytest.mark.parametrize("ext", [".png", ".npy", ".exr"])
def test_steps_tolerance_and_heat_map(tmp_path, ext):
    golden = tmp_path / f"g{ext}"
    color = ramp()
    images.save(golden, color)
    assert_frame_matches(color, golden, max_steps=0)
    off = color.copy()
    off[2, 3, 1] += 1 / 255  # one 8-bit step
    assert_frame_matches(off, golden, max_steps=1)
    with pytest.raises(AssertionError) as info:
        assert_frame_matches(off, golden, max_steps=0)
    # one heat map per golden: g.png's is g.diff.png (the golden's stem), g.npy's g.npy.diff.png
    diff = tmp_path / ("g.diff.png" if ext == ".png" else f"g{ext}.diff.png")
    message = str(info.value)
    assert str(golden) in message and f"heat map: {diff}" in message
    assert "1 of 48 pixels" in message and "x=3, y=2" in message
    heat = images.load(diff)
    others = np.delete(heat[:6].reshape(-1, 4), 2 * 8 + 3, 0)
    assert heat.shape == (6 + heatmap.LEGEND_HEIGHT, 8, 4)  # the map, then its legend
    assert heat[2, 3, 0] > 0 and (others[:, :3] == 0).all()
    off[0, 0, 0] += 3 / 255
    with pytest.raises(AssertionError, match="1 of 48 pixels .* up to 3 step.*x=0, y=0"):
        assert_frame_matches(off, golden, max_steps=1)
    assert_frame_matches(color, golden)  # matches again: the heat map is removed
    assert not diff.exists()


def test_float_goldens_are_exact_and_png_compares_codes(tmp_path):
    hdr = ramp() * 4.0  # HDR values above 1: one step is 1/255 absolute
    images.save(tmp_path / "h.npy", hdr)
    nudged = hdr.copy()
    nudged[1, 1, 0] += 0.9 / 255
    assert_frame_matches(nudged, tmp_path / "h.npy", max_steps=1)
    nudged[1, 1, 0] += 0.2 / 255
    with pytest.raises(AssertionError, match="up to 1.1 step"):
        assert_frame_matches(nudged, tmp_path / "h.npy", max_steps=1)
    # a PNG golden holds 8-bit codes: a value change within the same code is no difference
    images.save(tmp_path / "c.png", ramp())
    assert_frame_matches(ramp() + 0.4 / 255, tmp_path / "c.png", max_steps=0)


def test_missing_golden_wrong_size_and_update(tmp_path):
    golden = tmp_path / "sub" / "new.png"
    with pytest.raises(AssertionError, match="does not exist: run pytest --unity-update-goldens"):
        assert_frame_matches(ramp(), golden)
    testing.update_goldens(True)
    assert_frame_matches(ramp(), golden)  # written, not compared
    testing.update_goldens(False)
    np.testing.assert_array_equal(images.to_uint8(images.load(golden)), images.to_uint8(ramp()))
    with pytest.raises(AssertionError, match="frame is 4x3 but golden .* is 8x6"):
        assert_frame_matches(ramp(3, 4), golden)
    with pytest.raises(images.ImageIOError):
        assert_frame_matches(ramp(), tmp_path / "x.jpg")


def test_pytest11_entry_point_names_the_plugin():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["entry-points"]["pytest11"] == {"blendlib.testing": "blendlib.testing"}
    assert "build-backend" in tomllib.loads((ROOT / "pyproject.toml").read_text())["build-system"]


MAKE_SCENE = """
import sys, bpy
sys.path.insert(0, {root!r})
from tests.support.blender_fixtures import add_cube, empty_scene
scene = empty_scene(40, 30)
cube = add_cube("Cube", 2.0)
cube.location = (-1, 0, 0); cube.keyframe_insert("location", frame=1)
cube.location = (1, 0, 0); cube.keyframe_insert("location", frame=2)
other = bpy.data.scenes.new("Other")
other.camera = scene.camera
other.collection.objects.link(scene.camera)
other.render.resolution_x, other.render.resolution_y = 20, 10
bpy.ops.wm.save_as_mainfile(filepath={path!r})
"""

USER_TEST = """
from blendlib.testing import assert_frame_matches

def test_cube(unity_render):
    frame = unity_render("scenes/cube.blend", frame=2)
    assert_frame_matches(frame, "goldens/cube.png", max_steps=1)

def test_other_scene_as_fixture(unity_render, assert_frame_matches):
    frame = unity_render("scenes/cube.blend", scene="Other")
    assert frame.color.shape == (10, 20, 4)
    assert_frame_matches(frame, "goldens/other.npy")
"""


@pytest.fixture
def blender_started():
    """Blender's own add-ons (cycles and its _cycles module) loaded before pytester's module snapshot."""
    bpy.ops.wm.read_factory_settings(use_empty=True)


def test_plugin_through_pytester(blender_started, pytester):
    """A user's test folder: goldens written with --unity-update-goldens, then compared; a changed
    golden fails naming the heat map beside it; the heat map goes when the frame matches again."""
    # In-process runs (fast: bpy is imported once) drop the modules first imported while the pytester
    # fixture is alive: bpy, hypothesis and the Blender layer are imported at the top of this module,
    # Blender's add-ons by the blender_started fixture.
    scenes = pytester.path / "scenes"
    scenes.mkdir()
    exec(MAKE_SCENE.format(root=str(ROOT), path=str(scenes / "cube.blend")), {})
    pytester.makepyfile(test_user=USER_TEST)
    goldens = pytester.path / "goldens"

    result = pytester.runpytest("-p", "blendlib.testing", "-q")
    result.assert_outcomes(failed=2)
    result.stdout.fnmatch_lines(["*goldens/cube.png does not exist: run pytest --unity-update-goldens*"])

    result = pytester.runpytest("-p", "blendlib.testing", "-q", "--unity-update-goldens")
    result.assert_outcomes(passed=2)
    cube = images.load(goldens / "cube.png")
    assert cube.shape == (30, 40, 4) and np.load(goldens / "other.npy").shape == (10, 20, 4)

    result = pytester.runpytest("-p", "blendlib.testing", "-q")
    result.assert_outcomes(passed=2)

    changed = cube.copy()
    changed[10:14, 5:9, :3] = 1.0 - changed[10:14, 5:9, :3]
    images.save(goldens / "cube.png", changed)
    result = pytester.runpytest("-p", "blendlib.testing", "-q")
    result.assert_outcomes(passed=1, failed=1)
    diff = goldens / "cube.diff.png"
    shown = diff.relative_to(pytester.path)
    result.stdout.fnmatch_lines([f"*frame differs from golden goldens/cube.png: 16 of 1200 pixels*heat map: {shown}*"])
    assert diff.exists()

    images.save(goldens / "cube.png", cube)
    result = pytester.runpytest("-p", "blendlib.testing", "-q")
    result.assert_outcomes(passed=2)
    assert not diff.exists()


USER_TEST_IN_A_FOLDER = """
import numpy as np
from blendlib.testing import assert_frame_matches

def test_png(unity_render):
    assert_frame_matches(unity_render("scenes/cube.blend"), "goldens/glass.png", max_steps=0)

def test_npy(unity_render):
    assert_frame_matches(unity_render("scenes/cube.blend"), "goldens/glass.npy", max_steps=0)
"""


def test_goldens_of_one_stem_keep_their_heat_maps_and_resolve_from_the_test_file(blender_started, pytester, capfd):
    """Goldens resolve like scenes, from the test file's folder (before: from the working directory,
    so a run from another folder looked for them elsewhere); glass.png and glass.npy each keep
    their heat map (before, both wrote glass.diff.png and the passing one deleted it); opening a
    file saved with the add-on's engine prints nothing (before: "ERROR Engine 'UNITY_PASSES' not
    available" in the user's test output)."""
    folder = pytester.path / "suite"
    (folder / "scenes").mkdir(parents=True)
    exec(MAKE_SCENE.format(root=str(ROOT), path=str(folder / "scenes" / "cube.blend")), {})
    import addon

    addon.register()
    bpy.data.scenes[0].render.engine = "UNITY_PASSES"
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "scenes" / "cube.blend"))
    addon.unregister()
    (folder / "test_user.py").write_text(USER_TEST_IN_A_FOLDER)
    capfd.readouterr()

    result = pytester.runpytest("-p", "blendlib.testing", "-q", "-s", "--unity-update-goldens", "suite")
    result.assert_outcomes(passed=2)
    goldens = folder / "goldens"
    assert sorted(p.name for p in goldens.iterdir()) == ["glass.npy", "glass.png"]
    assert not (pytester.path / "goldens").exists()
    shown = capfd.readouterr()
    assert "not available" not in shown.out + shown.err  # Blender's reports go to stdout here

    frame = images.load(goldens / "glass.png")
    changed = frame.copy()
    changed[3:5, 3:5, :3] = 1.0 - changed[3:5, 3:5, :3]
    images.save(goldens / "glass.png", changed)
    np.save(goldens / "glass.npy", np.load(goldens / "glass.npy") + np.float32(0.5))
    result = pytester.runpytest("-p", "blendlib.testing", "-q", "suite")
    result.assert_outcomes(failed=2)
    result.stdout.fnmatch_lines(["*heat map: suite/goldens/glass.diff.png*"])
    result.stdout.fnmatch_lines(["*heat map: suite/goldens/glass.npy.diff.png*"])
    assert (goldens / "glass.diff.png").exists() and (goldens / "glass.npy.diff.png").exists()

    images.save(goldens / "glass.png", frame)  # the PNG golden passes again: only its own map goes
    result = pytester.runpytest("-p", "blendlib.testing", "-q", "suite")
    result.assert_outcomes(passed=1, failed=1)
    assert not (goldens / "glass.diff.png").exists() and (goldens / "glass.npy.diff.png").exists()
