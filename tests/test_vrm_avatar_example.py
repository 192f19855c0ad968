"""The VRM avatar example (blend_files/vrm_avatar.blend, scripts/vrm_avatar.py): the classic VRM sort
problems in numbers, and its VRM export (tests/fixtures/vrm_avatar.vrm) drawing as the .blend does.

Every material is a VRM Add-on MToon material (Unity settings off) of a VRM 1.0 armature, so the
states below are MToon's validator's (SPEC §11.6): Opaque 2000, Cutout 2450, Transparent 3000 +
clamp(offset, −9, 0), Transparent With Z-Write 2501 + clamp(offset, 0, 9). Transparent objects
(2501–3000) are drawn back to front by the distance from the camera to their bounds' centre. The
geometry's numbers are the script's: lenses at y = −0.172 and temples to y = +0.019 put the glasses'
centre at y = −0.077, behind the eyelashes at −0.142; the eyebrows (y = −0.125) lie behind the bangs
(radius 0.152–0.166 around the head's centre) but in front of the hair's centre.
"""

from __future__ import annotations

from dataclasses import replace

import bpy
import numpy as np
import pytest

import blendlib
from blendlib import blender
from blendlib.blender import vrm_addon
from blendlib.core import colorspace
from blendlib.core.drawlist import draw_calls
from blendlib.explain.framedebug import pixel_histories
from blendlib.explain.sorted_reference import analyze
from blendlib.formats.gltf import import_file
from tests.support import goldens as mg

FIXTURE = mg.ROOT / "tests" / "fixtures" / "vrm_avatar.vrm"


@pytest.fixture(scope="module")
def scenes():
    return mg.load_draw_scenes(mg.BLEND_DIR / "vrm_avatar.blend")


def project(draw, point) -> tuple[int, int]:
    """The pixel (x from the left, y from the top) a world point falls on."""
    cam = draw.camera
    clip = np.asarray(cam.projection, np.float64) @ np.asarray(cam.view_matrix, np.float64) @ np.array([*point, 1.0])
    ndc = clip[:3] / clip[3]
    return int((ndc[0] * 0.5 + 0.5) * cam.width), int((0.5 - ndc[1] * 0.5) * cam.height)


def around(draw, point, radius=3):
    x0, y0 = project(draw, point)
    return [(x, y) for y in range(y0 - radius, y0 + radius + 1) for x in range(x0 - radius, x0 + radius + 1)]


def first_calls(draw) -> dict[tuple[str, int], object]:
    """Each renderer's first draw call (its FORWARD_BASE pass)."""
    out = {}
    for call in draw_calls(draw):
        out.setdefault((call.renderer.name, call.renderer.slot), call)
    return out


def drawn_over_nearer(history, front: str, behind: str) -> bool:
    """A written fragment of ``front`` followed later by a written, farther fragment of ``behind``."""
    written = [f for f in history.fragments if f.result == "written"]
    for i, near in enumerate(written):
        if near.call.renderer.name != front:
            continue
        if any(f.call.renderer.name == behind and f.depth_code > near.depth_code for f in written[i + 1:]):
            return True
    return False


def test_queues_and_the_object_order_that_makes_the_errors(scenes):
    calls = first_calls(scenes["AvatarFace"])
    queue = {name: call.queue for (name, _), call in calls.items()}
    assert queue["Head"] == queue["Eyes"] == 2000 and queue["Ribbon"] == 2450
    assert queue["Hair"] == queue["Eyebrows"] == queue["Eyelashes"] == queue["Leg.L"] == 3000
    assert calls[("Glasses", 0)].queue == 2000 and calls[("Glasses", 1)].queue == 3000
    assert queue["Skirt"] == 2501  # Transparent With Z-Write, offset 0
    glasses = calls[("Glasses", 1)].renderer
    assert glasses.bounds_center[1] == pytest.approx((-0.173 + 0.019) / 2, abs=1e-4)
    order = [key for key in calls]
    # back to front by the bounds' centres: the hair and the glasses come before what lies behind them
    assert order.index(("Hair", 0)) < order.index(("Eyebrows", 0))
    assert order.index(("Glasses", 1)) < order.index(("Eyelashes", 0))
    assert calls[("Glasses", 1)].distance > calls[("Eyelashes", 0)].distance
    assert calls[("Hair", 0)].distance > calls[("Eyebrows", 0)].distance


def test_eyebrows_over_bangs_and_eyelashes_over_lenses(scenes):
    face = scenes["AvatarFace"]
    brows = around(face, (0.05, -0.125, 1.378))
    lashes = around(face, (-0.05, -0.142, 1.338))
    histories, frame = pixel_histories(face, brows + lashes)
    brow_hits = [h for h in histories[:len(brows)] if drawn_over_nearer(h, "Hair", "Eyebrows")]
    lash_hits = [h for h in histories[len(brows):] if drawn_over_nearer(h, "Glasses", "Eyelashes")]
    assert len(brow_hits) >= 5 and len(lash_hits) >= 10
    analysis = analyze(face)
    # The sorted reference blends those fragments far to near: the frame differs there.
    for h in brow_hits + lash_hits:
        assert np.abs(analysis.frame.color[h.y, h.x] - analysis.reference[h.y, h.x]).max() > 0
    assert analysis.pair_pixels(("Hair", 0), ("Eyebrows", 0)) >= len(brow_hits)
    assert analysis.pair_pixels(("Glasses", 1), ("Eyelashes", 0)) >= len(lash_hits)
    # The hair cards overlap themselves: farther cards blended over nearer ones of the same draw.
    assert analysis.pair_pixels(("Hair", 0), ("Hair", 0)) > 1000


def test_the_skirt_writes_depth_first_and_hides_the_stockings(scenes):
    full = scenes["Avatar"]
    pixels = around(full, (0.085, -0.06, 0.60), radius=2)
    histories, frame = pixel_histories(full, pixels)
    analysis = analyze(full)
    for h in histories:
        skirt = [f for f in h.fragments if f.call.renderer.name == "Skirt" and f.result == "written"]
        leg = [f for f in h.fragments if f.call.renderer.name == "Leg.L" and f.call.state.name == "FORWARD_BASE"]
        assert skirt and leg, (h.x, h.y)
        # queue 2501 before 3000: the skirt's nearer fragment wrote depth, the stocking behind it fails
        assert h.fragments.index(skirt[0]) < h.fragments.index(leg[0])
        assert all(f.result == "depth" for f in leg if f.depth_code > skirt[0].depth_code)
        # the stockings have no outline (outlineWidthMode none: MToon's outline pass clips everything)
        assert {f.call.state.name for f in h.fragments if f.call.renderer.name == "Leg.L"} == {"FORWARD_BASE"}
        assert np.abs(analysis.frame.color[h.y, h.x] - analysis.reference[h.y, h.x]).max() > 0


def test_the_vrm_export_draws_as_the_blend():
    """tests/fixtures/vrm_avatar.vrm (scripts/export_vrm_avatar.py) gives every material the Unity state
    the .blend's VRM Add-on settings give it."""
    exported = {m.material.name: m for m in import_file(FIXTURE).materials}
    blender.open_blend(mg.BLEND_DIR / "vrm_avatar.blend")
    names = [m.name for m in bpy.data.materials if vrm_addon.addon_mtoon(m) is not None]
    assert sorted(names) == sorted(exported)
    modes = set()
    for name in names:
        imported, image, _width, mtoon = vrm_addon.derived_material(bpy.data.materials[name])
        assert imported.material == exported[name].material, name
        assert (image is None) == (exported[name].main_tex is None)
        modes.add(mtoon.render_mode)
        assert imported.extra["outline"]["mode"] == exported[name].extra["outline"]["mode"]
    assert modes == {"Opaque", "Cutout", "Transparent", "Transparent With Z-Write"}
    outlines = {exported[n].extra["outline"]["mode"] for n in names}
    assert outlines == {"none", "world", "screen"}


# ---------------------------------------------------------------------------- MToon's outlines


def pixel_ray(draw, x: float, y: float) -> tuple[np.ndarray, np.ndarray]:
    """The camera ray (origin, unit direction) through the point (x from the left, y from the top, in pixels)."""
    cam = draw.camera
    inverse = np.linalg.inv(np.asarray(cam.projection, np.float64) @ np.asarray(cam.view_matrix, np.float64))
    ndc = np.array([x / cam.width * 2 - 1, 1 - y / cam.height * 2, 1.0, 1.0])
    far = inverse @ ndc
    origin = np.asarray(cam.position, np.float64)
    direction = far[:3] / far[3] - origin
    return origin, direction / np.linalg.norm(direction)


def silhouette_x(draw, y: float, center, radius: float, x_inside: float) -> float:
    """Where, going right along row ``y`` from ``x_inside`` (inside the disc), the camera rays stop
    meeting the sphere (``center``, ``radius``): bisection on the ray's distance from the centre."""
    def distance(x):
        origin, direction = pixel_ray(draw, x, y)
        to_center = np.asarray(center, np.float64) - origin
        return float(np.linalg.norm(to_center - (to_center @ direction) * direction))

    lo, hi = x_inside, float(draw.camera.width)
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if distance(mid) < radius else (lo, mid)
    return lo


def coverage(histories, renderer: str, outline: bool) -> list[bool]:
    """Per pixel: whether ``renderer``'s outline pass (or its other passes) put a fragment there."""
    return [any(f.call.renderer.name == renderer and (f.call.state.outline_mode.value != "Off") is outline
                for f in h.fragments) for h in histories]


def test_world_outline_of_the_head_is_outline_width_factor_metres_wide(scenes):
    """VRM 1.0 world mode (MToon_GetOutlineVertex): ``worldPos + worldNormal * outlineWidthFactor``; the
    skin's factor is 0.004, so the outline is the head sphere grown from 0.14 m to 0.144 m, drawn with
    Cull Front: around the head a ring where only the outline pass reaches, as wide on screen as the two
    spheres' silhouettes are apart."""
    face = scenes["AvatarFace"]
    head = (0.0, 0.0, 1.30)
    x0, y = project(face, head)
    row = [(x, y) for x in range(x0, face.camera.width)]
    histories, _ = pixel_histories(face, row)
    base, line = coverage(histories, "Head", False), coverage(histories, "Head", True)
    last_base = max(i for i, hit in enumerate(base) if hit)
    last_line = max(i for i, hit in enumerate(line) if hit)
    assert all(line[: last_line + 1])  # the outline covers the head and the ring
    ring = last_line - last_base  # pixels only the outline reaches
    width = silhouette_x(face, y + 0.5, head, 0.144, x0 + 0.5) - silhouette_x(face, y + 0.5, head, 0.14, x0 + 0.5)
    assert 1.0 < width < 3.0 and abs(ring - width) < 1.0, (ring, width)
    # visible: the outermost outline fragment is written (nothing opaque over it, FORWARD_BASE's colour)
    outer = [f for f in histories[last_line].fragments if f.call.renderer.name == "Head"]
    assert [f.result for f in outer] == ["written"] and outer[0].call.state.name == "FORWARD_BASE_OUTLINE"
    # ... in MToon 1.0's outline colour: outlineColorFactor × lerp(1, lit, outlineLightingMixFactor), the
    # skin's factor the linear value of the codes (120, 70, 60), the mix the add-on's default 1: the
    # lit colour of the same fragment (drawn without the outline colour) times that colour.
    assert outer[0].call.state.outline_color is not None and outer[0].call.state.outline_lighting_mix == 1.0
    plain = replace(face, renderers=tuple(replace(r, material=replace(r.material, passes=tuple(
        replace(p, outline_color=None) for p in r.material.passes))) for r in face.renderers))
    lit = [f for f in pixel_histories(plain, [row[last_line]])[0][0].fragments if f.call.renderer.name == "Head"]
    colour = np.array([colorspace.decode(c / 255) for c in (120, 70, 60)]) if face.color_space.value == "Linear" \
        else np.array([120, 70, 60]) / 255
    assert np.allclose(np.asarray(outer[0].source[:3]), colour * np.asarray(lit[0].source[:3]), rtol=1e-5)
    assert outer[0].source[3] == lit[0].source[3]  # alpha: the base pass's


def test_screen_outline_of_the_top_is_a_constant_share_of_the_screen_height(scenes):
    """VRM 1.0 screen mode: ``clip.xy += normalize(n_clip.xy) * 2 * outlineWidthFactor * min(w, P[1][1])``
    with x scaled by the aspect (H/W) and ``saturate(1 - n_view.z²)``. Nearer than ``P[1][1]`` the NDC offset
    is ``2 * 0.01`` of the half height: 0.01 x the height in pixels at the top's sides (n_view.z ~ 0)."""
    full = scenes["Avatar"]
    cam = full.camera
    assert float(np.linalg.norm(np.asarray(cam.position) - np.array([0.0, 0.0, 0.95]))) < cam.projection[1][1]
    x0, y = project(full, (0.0, 0.0, 0.95))
    row = [(x, y) for x in range(x0, x0 + 60)]
    histories, _ = pixel_histories(full, row)
    base, line = coverage(histories, "Top", False), coverage(histories, "Top", True)
    ring = max(i for i, hit in enumerate(line) if hit) - max(i for i, hit in enumerate(base) if hit)
    assert abs(ring - 0.01 * cam.height) < 1.0, ring
    # no outline on the materials whose outlineWidthMode is none (the skirt, the hair, the lenses)
    names = {(c.renderer.name, c.state.name) for c in draw_calls(full)}
    assert {n for n, p in names if p == "FORWARD_BASE_OUTLINE"} == {"Head", "Neck", "Arm.L", "Arm.R", "Top",
                                                                     "Shoe.L", "Shoe.R"}


# ---------------------------------------------------------------------------- advice in VRM terms


def test_advice_speaks_vrm_and_apply_fixes_the_eyebrows_as_measured():
    """The hair and the eyebrows are both Transparent at 3000 + clamp(offset, -9, 0) = 3000 (MToonValidator):
    the hair cannot go above 3000, so the advice lowers the eyebrows' Render Queue Offset Number to -1
    (queue 2999: drawn before every hair card); the eyelashes likewise before the lenses. The hair's
    self-overlap gets Transparent With Z-Write (2501 + clamp(0, 0, 9) = 2501, ZWrite On). Applied to the
    VRM Add-on's settings, the eyebrows' pair is gone and the frame differs on the pixels the advice
    measured."""
    blender.open_blend(mg.BLEND_DIR / "vrm_avatar.blend")
    scene = bpy.data.scenes["AvatarFace"]
    scene.render.resolution_percentage = mg.GOLDEN_PERCENTAGE
    analysis = blendlib.analyze(scene)
    items = {(a["front"], a["behind"]): a for a in analysis.advice}
    brows, lashes, hair = items["Hair", "Eyebrows"], items["Glasses", "Eyelashes"], items["Hair", "Hair"]
    assert brows["change"] == {"material": "Eyebrows", "vrm": {"render_queue_offset_number": -1}, "vrm_spec": "1.0"}
    assert lashes["change"] == {"material": "Eyelashes", "vrm": {"render_queue_offset_number": -1},
                                "vrm_spec": "1.0"}
    assert hair["change"] == {"material": "Hair", "vrm": {"transparent_with_z_write": True}, "vrm_spec": "1.0"}
    assert "Render Queue Offset Number of VRM material 'Eyebrows' to -1 (queue 2999)" in brows["text"]
    assert brows["inversions_after"] == 0 < brows["inversions_before"]
    assert brows["differing_after"] < brows["differing_before"] == analysis.differing
    assert hair["inversions_after"] == 0
    vrm_addon.apply_settings(bpy.data.materials["Eyebrows"], brows["change"]["vrm"])
    after = blendlib.analyze(scene)
    assert after.pair_pixels(("Hair", 0), ("Eyebrows", 0)) == 0
    assert after.differing == brows["differing_after"]
    # the VRM export of the fixed material: renderQueueOffsetNumber -1, which UniVRM draws at 2999
    exported = vrm_addon.derived_material(bpy.data.materials["Eyebrows"])[0]
    assert exported.extra["render_queue_offset_number"] == -1 and exported.material.render_queue == 2999


def test_the_imported_vrm_goes_the_vrm_addons_way_advised_and_fixed_in_vrm_terms():
    """Importing the avatar's .vrm: every MToon material gets the VRM Add-on's MToon settings with its
    Unity settings off (the lead's decision), and the state read back from them equals the direct
    import (queue, passes with cull, ZWrite, blend, alpha test, the outline and its colour). The sort
    advice on the imported scene is in VRM terms: a Render Queue Offset Number within MToon's clamp for
    Transparent (-9..0, MToonValidator), and Apply writes the add-on's setting (its ID properties: what
    its exporter writes), after which the pair is gone and the frame differs as measured."""
    from blendlib.blender import gltf_import, schema
    from tests.support.blender_fixtures import empty_scene

    exported = {m.material.name: m for m in import_file(FIXTURE).materials}
    scene = empty_scene(320, 180)
    done = gltf_import.import_gltf(FIXTURE, scene)
    assert sorted(done.addon_materials) == sorted(exported) and not done.warnings
    for name, imported in exported.items():
        mat = bpy.data.materials[name]
        assert not schema.material_values(mat)["enabled"] and vrm_addon.spec_version(mat) == "1.0"
        assert vrm_addon.derived_material(mat)[0].material == imported.material, name
    analysis = blendlib.analyze(scene)
    offsets = [a for a in analysis.advice if "render_queue_offset_number" in a["change"].get("vrm", {})]
    assert offsets and all(a["change"]["vrm_spec"] == "1.0" for a in offsets)
    assert all(-9 <= a["change"]["vrm"]["render_queue_offset_number"] <= 0 for a in offsets)  # Transparent's clamp
    brows = next(a for a in offsets if a["change"]["material"] == "Eyebrows")
    assert brows["change"]["vrm"] == {"render_queue_offset_number": -1} and brows["inversions_after"] == 0
    mat = bpy.data.materials["Eyebrows"]
    vrm_addon.apply_settings(mat, brows["change"]["vrm"])
    stored = mat.bl_system_properties_get()["vrm_addon_extension"]["mtoon1"]["extensions"]["vrmc_materials_mtoon"]
    assert stored["render_queue_offset_number"] == -1 and not schema.material_values(mat)["enabled"]
    assert vrm_addon.derived_material(mat)[0].material.render_queue == 2999
    after = blendlib.analyze(scene)
    assert after.pair_pixels((brows["front"], 0), ("Eyebrows", 0)) == 0
    assert after.differing == brows["differing_after"]
