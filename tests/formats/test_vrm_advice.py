"""VRM advice options (blendlib.formats.gltf.vrm_advice): queue settings only within MToon's clamps.

Clamps from the validator's text (MToonValidator.SetUnityShaderPassSettings): Transparent
``renderQueueOffset = Mathf.Clamp(renderQueueOffset, -9, 0)`` over 3000; Transparent With Z-Write
``Mathf.Clamp(renderQueueOffset, 0, +9)`` over ``RenderQueue.GeometryLast + 1`` (2501). MToon 0.x's
ranges (vrm-specification #36): Transparent 2951–3000, Transparent With Z-Write 2501–2550.
"""

from __future__ import annotations

import pytest

from blendlib.formats.gltf.vrm_addon import AddonMToon, addon_material
from blendlib.formats.gltf.vrm_advice import VrmSettings


def _options(spec, **settings):
    mtoon = AddonMToon(name="M", alpha_mode="BLEND", **settings)
    source = VrmSettings(mtoon, spec)
    return source, addon_material(mtoon, spec).material


def _queue_changes(options):
    return [(change["vrm"], material.render_queue) for change, material, _ in options
            if set(change["vrm"]) <= {"render_queue_offset_number", "mtoon0_render_queue"}]


@pytest.mark.parametrize("wanted,expected", [
    ({"after": 2995}, [({"render_queue_offset_number": -4}, 2996)]),
    ({"after": 3000}, []),  # 3001 would need offset +1: clamped back to 0
    ({"before": 3000}, [({"render_queue_offset_number": -1}, 2999)]),
    ({"before": 2991}, []),  # 2990 would need -10: clamped to -9
    ({"before": 2992}, [({"render_queue_offset_number": -9}, 2991)]),
])
def test_vrm1_transparent_offsets_stay_within_the_clamp(wanted, expected):
    source, old = _options("1.0")
    assert _queue_changes(source.options(old, **wanted)) == expected


def test_vrm1_transparent_with_z_write_offsets_and_modes():
    source, old = _options("1.0", transparent_with_z_write=True, render_queue_offset_number=3)
    assert old.render_queue == 2504
    assert _queue_changes(source.options(old, after=2508)) == [({"render_queue_offset_number": 8}, 2509)]
    assert _queue_changes(source.options(old, after=2510)) == []  # +10 is clamped to +9
    assert _queue_changes(source.options(old, before=2501)) == []  # -1 is clamped to 0
    modes = [change["vrm"] for change, _, _ in source.options(old)]
    assert modes == [{"alpha_mode": "MASK"}]  # already writes depth: Cutout is the other way out


def test_vrm1_render_modes_draw_as_the_validator_says():
    source, old = _options("1.0", render_queue_offset_number=-3)
    (tzw, tzw_mat, tzw_text), (cutout, cutout_mat, _) = source.options(old)
    assert tzw["vrm"] == {"transparent_with_z_write": True}
    # 2501 + clamp(-3, 0, 9) = 2501; ZWrite On, Blend SrcAlpha OneMinusSrcAlpha
    assert tzw_mat.render_queue == 2501 and tzw_mat.passes[0].zwrite and tzw_mat.passes[0].blend
    assert tzw_text == "set VRM material 'M' to Transparent With Z-Write (it writes depth) (queue 2501)"
    # MASK: 2450, One Zero, ZWrite On, AlphaToMask On, clip at the alpha cutoff
    assert cutout["vrm"] == {"alpha_mode": "MASK"}
    assert (cutout_mat.render_queue, cutout_mat.cutoff, cutout_mat.passes[0].blend,
            cutout_mat.passes[0].alpha_to_mask) == (2450, 0.5, True, True)
    assert cutout_mat.passes[0].src_blend.value == "One" and cutout_mat.passes[0].dst_blend.value == "Zero"


def test_vrm0_render_queue_stays_in_mtoon0_ranges():
    source, old = _options("0.x", mtoon0_render_queue=2960)
    assert old.render_queue == 2960  # renderQueue as stored
    assert _queue_changes(source.options(old, after=2970)) == [({"mtoon0_render_queue": 2971}, 2971)]
    assert _queue_changes(source.options(old, before=2951)) == []  # 2950 is outside 2951..3000
    assert _queue_changes(source.options(old, after=3000)) == []
    (tzw, tzw_mat, _), (cutout, cutout_mat, _) = source.options(old)
    assert tzw["vrm"] == {"transparent_with_z_write": True, "mtoon0_render_queue": 2501}
    assert tzw_mat.render_queue == 2501 and tzw_mat.passes[0].zwrite
    assert cutout["vrm"] == {"alpha_mode": "MASK", "mtoon0_render_queue": 2450} and cutout_mat.render_queue == 2450


def test_opaque_materials_have_nothing_to_sort():
    mtoon = AddonMToon(name="M")
    source = VrmSettings(mtoon, "1.0")
    assert source.options(addon_material(mtoon, "1.0").material, after=2000, before=2000) == []
