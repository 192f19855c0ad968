"""Files saved by version 0.1 open with the same settings and render the same, add-on registered or not.

``tests/fixtures/v0_1/`` holds the example scenes as 0.1 saved them (``blend_files/`` of
that version) and ``color_masks.blend`` (partial ColorMasks, 0.1's bit order R=1 ... A=8);
``settings.json`` is what 0.1's reader read from them. Each example file also renders
bit-identically to its golden buffers (``tests/golden/``).
"""

from __future__ import annotations

import json
from pathlib import Path

import bpy
import numpy as np
import pytest

import addon
from blendlib import blender
from tests.support import goldens

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "v0_1"
SNAPSHOT = json.loads((FIXTURES / "settings.json").read_text(encoding="utf-8"))["files"]
FILES = sorted(p.name for p in FIXTURES.glob("*.blend"))
#: Settings schema version 3 added (SPEC §12), with the defaults that draw as 0.1 drew.
V3_MATERIAL = {"main_tex_mipmaps": False, "main_tex_preserve_coverage": False, "vertex_color": "Off",
               "tint_color": [0.5, 0.5, 0.5, 0.5]}
V3_PASS = {"alpha_to_mask": False, "alpha_test_comp": "GEqual", "light_mode": "ForwardBase", "outline_mode": "Off",
           "outline_width": 0.0, "outline_formula": "MToon0x", "outline_max_distance": 1.0}
V3_SCENE = {"msaa": 1, "pixel_light_count": 4}
#: Schema version 4 (issue 28): MToon's outline colour per pass and outline-width texture per material,
#: absent from older files: off / none, which draw as before.
V3_MATERIAL |= {"outline_width_tex": None, "outline_width_tex_filter": "Bilinear", "outline_width_tex_wrap": "Repeat"}
V3_PASS |= {"outline_colored": False, "outline_color": [0.0, 0.0, 0.0], "outline_lighting_mix": 0.0}


def _as_read_now(snapshot: dict) -> dict:
    """What 0.1 read, with the fields added since at their version-3 defaults."""
    materials = {name: {**m, **V3_MATERIAL, "passes": [{**p, **V3_PASS} for p in m["passes"]]}
                 for name, m in snapshot["materials"].items()}
    return {"materials": materials, "scenes": {name: {**s, **V3_SCENE} for name, s in snapshot["scenes"].items()}}


def _plain(value):
    if isinstance(value, frozenset):
        return sorted(value)
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, bpy.types.ID):
        return value.name
    return value


def _settings() -> dict:
    materials = sorted(bpy.data.materials, key=lambda m: m.name)
    scenes = sorted(bpy.data.scenes, key=lambda s: s.name)
    return {
        "materials": {m.name: _plain(blender.material_values(m)) for m in materials},
        "scenes": {s.name: _plain(blender.scene_settings(s)) for s in scenes},
    }


@pytest.fixture(params=["registered", "unregistered"])
def mode(request):
    was = hasattr(bpy.types.Material, "unity")
    want = request.param == "registered"
    if want and not was:
        addon.register()
    elif was and not want:
        addon.unregister()
    yield request.param
    if want and not was:
        addon.unregister()
    elif was and not want:
        addon.register()


#: The example scenes 0.1 had (later examples, e.g. vrm_avatar.blend, have no 0.1 file).
EXAMPLES_OF_0_1 = sorted(name for name in FILES if name != "color_masks.blend")


def test_the_fixtures_are_the_examples_of_0_1():
    assert len(EXAMPLES_OF_0_1) == 9
    assert set(EXAMPLES_OF_0_1) <= {p.name for p in goldens.blend_files()}
    assert sorted(SNAPSHOT) == FILES


@pytest.mark.parametrize("name", FILES)
def test_settings_read_as_0_1_read_them(name, mode):
    bpy.ops.wm.open_mainfile(filepath=str(FIXTURES / name), load_ui=False)
    assert _settings() == _as_read_now(SNAPSHOT[name])
    if mode == "registered":  # migrated on load: the add-on's properties show the same values
        for mat in bpy.data.materials:
            want = SNAPSHOT[name]["materials"][mat.name]
            assert [sorted(p.color_mask) for p in mat.unity.passes] == [p["color_mask"] for p in want["passes"]]


@pytest.mark.parametrize("name", EXAMPLES_OF_0_1)
def test_renders_match_the_goldens(name, mode):
    bpy.ops.wm.open_mainfile(filepath=str(FIXTURES / name), load_ui=False)
    golden = np.load(goldens.GOLDEN_DIR / f"{Path(name).stem}.npz")
    scenes = sorted(bpy.data.scenes, key=lambda s: s.name)
    assert sorted({k.split(".")[0] for k in golden.files}) == [s.name for s in scenes]
    for scene in scenes:
        scene.render.resolution_percentage = goldens.GOLDEN_PERCENTAGE
        codes = goldens.render_codes(blender.build_draw_scene(scene))
        for key, value in codes.items():
            assert np.array_equal(value, golden[f"{scene.name}.{key}"]), (name, scene.name, key)
