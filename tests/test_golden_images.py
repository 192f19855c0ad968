"""Golden images of example scenes through the project's own pytest plugin (blendlib.testing),
exactly as a user's CI test would use it: render the file as F12 does, compare with a PNG.

Regenerate on purpose: ``pytest -p blendlib.testing tests/test_golden_images.py --unity-update-goldens``
(the ``-p`` is not needed once the package is installed: its ``pytest11`` entry point loads the plugin).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from blendlib.testing import assert_frame_matches, unity_render  # noqa: F401 - unity_render is a fixture

ROOT = Path(__file__).resolve().parent.parent
GOLDEN_IMAGES = ROOT / "tests" / "golden" / "images"


@pytest.mark.parametrize("file", ["alpha_blend.blend", "two_sided.blend"])
def test_example_scene_matches_its_golden_image(unity_render, file):  # noqa: F811 - the fixture
    frame = unity_render(ROOT / "blend_files" / file)
    assert frame.color.shape == (360, 640, 4)
    assert_frame_matches(frame, GOLDEN_IMAGES / f"{Path(file).stem}.png", max_steps=1)
