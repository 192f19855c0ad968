"""Test set-up shared by every test module.

Blender and Mesa write caches and configuration under HOME and XDG_*: point them at a
throw-away folder before anything imports bpy or creates a GL context.
"""

import os
import sys
import tempfile
from pathlib import Path

_SANDBOX = Path(tempfile.mkdtemp(prefix="unity-passes-tests-"))
for _var in ("HOME", "XDG_CACHE_HOME", "XDG_CONFIG_HOME", "XDG_DATA_HOME"):
    os.environ[_var] = str(_SANDBOX / _var.lower())
    Path(os.environ[_var]).mkdir(parents=True, exist_ok=True)

REPO_ROOT = Path(__file__).resolve().parent.parent
if str(REPO_ROOT) not in sys.path:
    sys.path.insert(0, str(REPO_ROOT))


import pytest  # noqa: E402


@pytest.fixture(autouse=True)
def _bands_in_small_frames(monkeypatch):
    """Test frames are small: with two workers, draw every batch in screen bands as large frames
    do (``pipeline.BAND_PIXELS``), so each test that asks for two workers exercises the bands.
    tests/core/test_fastpaths.py checks the production choice itself."""
    from blendlib.core import pipeline

    monkeypatch.setattr(pipeline, "BAND_PIXELS", 0)
