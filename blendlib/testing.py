"""Golden-image tests of your own scenes, GPU-free: a pytest plugin (public, stable API).

Installing the package registers this module as a pytest plugin (``pytest11`` entry point), which
gives every test:

- the ``unity_render`` fixture: a callable ``unity_render(path, scene=None, frame=None) -> Frame``
  that opens a .blend file and renders it as F12 does (``blendlib.blender.render_final``);
- :func:`assert_frame_matches` (also a fixture of that name):
  ``assert_frame_matches(frame, golden, max_steps=1)``;
- the option ``pytest --unity-update-goldens``: every golden the run asks for is (re)written and
  nothing is compared.

A relative path, of a scene or of a golden alike, is taken from the running test file's folder
when it exists there, else from the working directory when it exists there, else (a golden not
written yet) from the test file's folder; outside a test, from the working directory.

The golden's extension picks its format: ``.png`` holds the frame's 8-bit stored values;
``.npy`` and ``.exr`` hold exact float32 values. ``max_steps`` counts 8-bit steps (1/255 for float
goldens and HDR frames). On failure a heat map of the difference (with its legend below) is
written beside the golden and named in the message: ``<golden stem>.diff.png`` for a ``.png``
golden, ``<golden name>.diff.png`` for the others (``glass.npy.diff.png``), so goldens of one
stem keep their own; it is removed when the frame matches again.

Example (``tests/test_my_shaders.py``)::

    from blendlib.testing import assert_frame_matches

    def test_glass(unity_render):
        frame = unity_render("scenes/glass.blend", scene="Scene", frame=1)
        assert_frame_matches(frame, "goldens/glass.png", max_steps=1)
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from .formats import heatmap, images

__all__ = ["assert_frame_matches", "frame_values", "update_goldens"]

#: Set by ``--unity-update-goldens`` (or by scripts): :func:`assert_frame_matches` writes goldens.
_UPDATE = {"goldens": False}
#: The folder of the test file running now (set by the plugin's hooks), where relative paths start.
_RUNNING: dict[str, Path] = {}

STEP = 1.0 / 255.0


def update_goldens(enabled: bool | None = None) -> bool:
    """Whether :func:`assert_frame_matches` writes goldens instead of comparing; ``enabled`` sets it."""
    if enabled is not None:
        _UPDATE["goldens"] = bool(enabled)
    return _UPDATE["goldens"]


def frame_values(frame: Any) -> np.ndarray:
    """The (H, W, 4) float32 stored values of a :class:`blendlib.Frame` (or such an array itself)."""
    color = np.asarray(getattr(frame, "color", frame), dtype=np.float32)
    if color.ndim != 3 or color.shape[2] not in (3, 4):
        raise TypeError(f"expected a Frame or an (H, W, 4) array, got shape {color.shape}")
    return color


def resolve(path: str | os.PathLike, base: Path | None = None) -> Path:
    """A scene's or golden's path as the plugin takes it (module docstring): absolute as it is;
    relative from ``base`` (default: the running test file's folder) when it exists there, else
    from the working directory when it exists there, else from ``base``."""
    path = Path(path)
    base = base if base is not None else _RUNNING.get("folder")
    if path.is_absolute() or base is None:
        return path
    if (base / path).exists() or not path.exists():
        return base / path
    return path


def _shown(path: Path) -> str:
    """``path`` for a message: relative to the working directory when inside it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _diff_path(golden: Path) -> Path:
    """Where the heat map of a failing comparison with ``golden`` goes (one per golden)."""
    name = golden.stem if golden.suffix.lower() == ".png" else golden.name
    return golden.with_name(f"{name}.diff.png")


def _steps(got: np.ndarray, want: np.ndarray, png: bool) -> np.ndarray:
    """Per-pixel largest difference over the channels, in 8-bit steps (H, W) float64."""
    if png:
        return np.abs(images.to_uint8(got).astype(np.int64) - images.to_uint8(want).astype(np.int64)).max(axis=2) \
            .astype(np.float64)
    a, b = got.astype(np.float64), want.astype(np.float64)
    diff = np.abs(a - b)
    diff = np.where(np.isnan(a) & np.isnan(b), 0.0, np.where(np.isnan(diff), np.inf, diff))
    return diff.max(axis=2) / STEP


def assert_frame_matches(frame: Any, golden: str | os.PathLike, max_steps: float = 1) -> None:
    """Assert that ``frame`` equals the golden image within ``max_steps`` 8-bit steps per channel.

    ``frame``: a :class:`blendlib.Frame` or an (H, W, 4) float array of stored values.
    ``golden``: ``.png`` (compared on 8-bit codes), ``.npy`` or ``.exr`` (exact floats,
    ``max_steps / 255`` absolute). With ``--unity-update-goldens`` the golden is written instead.
    Raises AssertionError naming the golden, how many pixels differ and by how much, and the heat
    map written beside the golden; a missing golden fails with how to create it.
    """
    golden = resolve(golden)
    fmt = images.file_format(golden)  # ImageIOError for an unknown extension
    got = frame_values(frame)
    diff_path = _diff_path(golden)
    if update_goldens():
        golden.parent.mkdir(parents=True, exist_ok=True)
        images.save(golden, got)
        diff_path.unlink(missing_ok=True)
        return
    if not golden.exists():
        raise AssertionError(f"golden image {_shown(golden)} does not exist: run pytest --unity-update-goldens to "
                             "write it from this frame, then look at it and commit it")
    want = images.load(golden)
    if want.ndim == 2:
        want = want[..., None]
    if want.shape[:2] != got.shape[:2]:
        raise AssertionError(f"frame is {got.shape[1]}x{got.shape[0]} but golden {_shown(golden)} is "
                             f"{want.shape[1]}x{want.shape[0]} (rewrite it with pytest --unity-update-goldens)")
    channels = min(want.shape[2], got.shape[2])
    steps = _steps(got[..., :channels], want[..., :channels], png=fmt == ".png")
    bad = steps > max_steps + 1e-9
    if not bad.any():
        diff_path.unlink(missing_ok=True)
        return
    images.save(diff_path, heatmap.heat_image(np.where(np.isfinite(steps), steps, 255.0), "difference in 8-bit steps",
                                              floor=0.1))
    worst = float(steps.max())
    worst_text = "inf" if not np.isfinite(worst) else f"{worst:.6g}"
    y, x = np.unravel_index(int(np.argmax(np.where(np.isfinite(steps), steps, np.inf))), steps.shape)
    raise AssertionError(
        f"frame differs from golden {_shown(golden)}: {int(bad.sum())} of {bad.size} pixels "
        f"({bad.mean():.3%}) by more than {max_steps:g} step(s), up to {worst_text} step(s) "
        f"(first worst at x={x}, y={y} from the top); heat map: {_shown(diff_path)}")


# ---------------------------------------------------------------------------------------------
# pytest plugin hooks and fixtures
# ---------------------------------------------------------------------------------------------


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("unity-passes", "Unity Passes golden images")
    group.addoption("--unity-update-goldens", action="store_true", default=False,
                    help="write every golden image the tests ask for (assert_frame_matches) instead of comparing")


def pytest_configure(config: pytest.Config) -> None:
    if config.getoption("unity_update_goldens", default=False):
        update_goldens(True)


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    _RUNNING["folder"] = Path(str(item.path)).parent


def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> None:
    _RUNNING.pop("folder", None)


def pytest_unconfigure(config: pytest.Config) -> None:
    if config.getoption("unity_update_goldens", default=False):
        update_goldens(False)


def _render_file(path: Path, scene: str | None, frame: int | None):
    from . import blender
    from .core.scene import SceneError

    if not path.exists():
        raise FileNotFoundError(f"{_shown(path)}: no such .blend file")
    # quiet: Blender's loading messages (e.g. "Engine 'UNITY_PASSES' not available" for a file
    # saved with the add-on's engine) are not the user's test output; a failure still raises.
    blender.open_blend(path, quiet=True)
    target = blender.scene_named(scene, where=path)
    try:
        return blender.render_final(target, frame=frame)
    except SceneError as exc:
        raise SceneError(f"{path}: {exc}") from None


@pytest.fixture
def unity_render(request: pytest.FixtureRequest) -> Callable[..., Any]:
    """``unity_render(path, scene=None, frame=None) -> Frame``: render a .blend file as F12 does
    (the file's active scene and current frame by default; the file on disk is never changed)."""
    base = Path(str(request.path)).parent

    def render(path: str | os.PathLike, scene: str | None = None, frame: int | None = None):
        return _render_file(resolve(path, base), scene, frame)

    return render


@pytest.fixture(name="assert_frame_matches")
def assert_frame_matches_fixture() -> Callable[..., None]:
    """:func:`assert_frame_matches` as a fixture."""
    return assert_frame_matches
