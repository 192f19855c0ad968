"""The README's promises: two set-up commands that CI runs, and a core example that works."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text(encoding="utf-8")


def test_first_code_block_is_exactly_the_two_commands_ci_runs():
    first = re.search(r"```\n(.*?)```", README, re.S).group(1).strip().splitlines()
    assert len(first) == 2, first
    setup, tests = first
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert setup in ci and tests in ci
    assert (ROOT / setup.split()[-1]).exists()


def test_core_example_renders_half_transparent_quad():
    code = re.search(r"## The renderer core.*?```python\n(.*?)```", README, re.S).group(1)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)
    frame = namespace["frame"]
    assert frame.color.shape == (240, 320, 4) and frame.color.dtype == np.float32
    centre = np.round(frame.color[120, 160] * 255).astype(int)
    corner = np.round(frame.color[0, 0] * 255).astype(int)
    # Clear colour (0.19, 0.30, 0.47, 0) → codes (48, 77, 120, 0); the quad is
    # 0.5 * Lambert(glass) + 0.5 * clear, alpha 0.5 * 0.5 + 0 * 0.5 = 0.25 → 64.
    assert corner.tolist() == [48, 77, 120, 0]
    assert centre[3] == 64
    assert centre[2] > corner[2] and centre[0] > corner[0]
    # The preset is ZWrite Off: the depth buffer stays cleared everywhere.
    assert np.all(frame.depth == 1.0)
