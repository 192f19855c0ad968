"""Which passes draw and for which lights: the forward rendering path's rules (SPEC §11.2, §12),
with expected values from Unity's manual ("Pass tags", "Forward Rendering Path Details")."""

from __future__ import annotations

import numpy as np
import pytest

from blendlib.core.drawlist import draw_calls, light_falloff, light_reaches, pixel_lights
from blendlib.core.scene import Camera, DrawScene, ForwardLight, Mesh, Renderer, SceneError, validate_scene
from blendlib.core.vocabulary import (
    NEVER,
    ONCE,
    PER_LIGHT,
    LightMode,
    LightRenderMode,
    LightType,
    Material,
    Pass,
    pass_draws,
)


def _cube_renderer(name: str, material: Material, center=(0.0, 0.0, 0.0), size: float = 1.0) -> Renderer:
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float32) * (size / 2)
    tris = np.array([[0, 1, 2]], np.int32)
    mesh = Mesh(corners, tris, np.zeros((1, 3, 3), np.float32))
    m = np.eye(4)
    m[:3, 3] = center
    return Renderer(name, 0, mesh, m, material, bounds_center=np.array(center, np.float64))


def _scene(renderers, lights=(), pixel_light_count=4) -> DrawScene:
    view = np.eye(4)
    view[2, 3] = -10.0
    proj = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1.02, -0.202], [0, 0, -1, 0]], np.float64)
    return DrawScene(Camera(view, proj, 8, 8), tuple(renderers), lights=tuple(lights),
                     pixel_light_count=pixel_light_count)


def _point(name, position, intensity=1.0, range_=10.0, mode=LightRenderMode.Auto) -> ForwardLight:
    return ForwardLight(name, LightType.Point, position=position, intensity=intensity, range=range_,
                        render_mode=mode)


def test_pass_draws_follows_the_light_mode_rules_of_the_manual():
    base, add = Pass(light_mode=LightMode.ForwardBase), Pass(light_mode=LightMode.ForwardAdd)
    vertex, always = Pass(light_mode=LightMode.Vertex), Pass(light_mode=LightMode.Always)
    forward = (base, add, vertex, Pass(light_mode=LightMode.ShadowCaster))
    assert pass_draws(base, forward)[0] == ONCE
    assert pass_draws(add, forward)[0] == PER_LIGHT
    assert pass_draws(always, forward)[0] == ONCE
    # "Vertex: used in legacy Vertex Lit rendering": only when the SubShader has no forward passes.
    assert pass_draws(vertex, forward)[0] == NEVER
    assert pass_draws(vertex, (vertex, Pass(light_mode=LightMode.VertexLM)))[0] == ONCE
    assert pass_draws(vertex, (always, vertex))[0] == ONCE
    for mode in (LightMode.VertexLM, LightMode.VertexLMRGBM, LightMode.ShadowCaster, LightMode.ShadowCollector,
                 LightMode.Meta, LightMode.Deferred, LightMode.PrepassBase, LightMode.PrepassFinal,
                 LightMode.MotionVectors, LightMode.Other):
        how, why = pass_draws(Pass(light_mode=mode), (Pass(light_mode=mode),))
        assert how == NEVER and why, mode


def test_draw_calls_leave_out_passes_that_do_not_draw_and_repeat_forward_add_per_light():
    mat = Material(name="MToon", passes=(Pass(name="Base"), Pass(name="Add", light_mode=LightMode.ForwardAdd),
                                         Pass(name="Shadow", light_mode=LightMode.ShadowCaster)))
    lights = [_point("A", (1.0, 0.0, 0.0)), _point("B", (3.0, 0.0, 0.0))]
    calls = draw_calls(_scene([_cube_renderer("Cube", mat)], lights))
    assert [(c.index, c.state.name, None if c.light is None else c.light.name) for c in calls] == [
        (1, "Base", None), (2, "Add", "A"), (3, "Add", "B")]  # A is nearer: brighter at the object
    assert [c.pass_index for c in calls] == [0, 1, 1]
    # One directional light (the main one) and nothing else: ForwardAdd draws nothing.
    assert [c.state.name for c in draw_calls(_scene([_cube_renderer("Cube", mat)]))] == ["Base"]


def test_default_passes_draw_as_before():
    mat = Material(passes=(Pass(name="One"), Pass(name="Two")))
    assert [c.state.name for c in draw_calls(_scene([_cube_renderer("Cube", mat)]))] == ["One", "Two"]


def test_pixel_light_count_keeps_the_closest_of_equal_lights():
    # The manual's example: lights A to H of equal colour and intensity, sorted for the object in
    # this order (by closeness); with the Pixel Light Count of 4, A to D are per-pixel.
    names = "ABCDEFGH"
    lights = [_point(n, (1.0 + k, 0.0, 0.0), range_=20.0) for k, n in enumerate(names)]
    r = _cube_renderer("Sphere", Material())
    assert [light.name for light in pixel_lights(_scene([r], lights[::-1]), r)] == list("ABCD")
    assert [light.name for light in pixel_lights(_scene([r], lights, pixel_light_count=2), r)] == list("AB")
    assert pixel_lights(_scene([r], lights, pixel_light_count=0), r) == ()


def test_important_lights_are_always_per_pixel_and_not_important_never():
    r = _cube_renderer("Cube", Material())
    lights = [_point("Near", (1.0, 0.0, 0.0), intensity=5.0, mode=LightRenderMode.NotImportant),
              _point("Dim", (5.0, 0.0, 0.0), intensity=0.1, mode=LightRenderMode.Important),
              _point("Dim2", (6.0, 0.0, 0.0), intensity=0.1, mode=LightRenderMode.Important),
              _point("Auto", (2.0, 0.0, 0.0), intensity=1.0)]
    got = [light.name for light in pixel_lights(_scene([r], lights, pixel_light_count=1), r)]
    assert got == ["Dim", "Dim2"]  # Important ones beyond the count; no room left for Auto ones
    got = [light.name for light in pixel_lights(_scene([r], lights, pixel_light_count=3), r)]
    assert got == ["Dim", "Dim2", "Auto"]


def test_a_point_light_reaches_a_renderer_when_its_range_meets_the_bounds():
    r = _cube_renderer("Cube", Material(), center=(0.0, 0.0, 0.0), size=2.0)  # box from -1 to 1
    assert light_reaches(_point("P", (3.0, 0.0, 0.0), range_=2.5), r)      # 2 from the box's face
    assert not light_reaches(_point("P", (3.0, 0.0, 0.0), range_=1.9), r)
    assert not light_reaches(_point("P", (3.0, 3.0, 0.0), range_=2.5), r)  # 2.83 from the corner edge
    sun = ForwardLight("Sun2", LightType.Directional)
    assert light_reaches(sun, r)


def test_falloff_is_unitys_quadratic_with_the_fade_to_range():
    # 1 / (1 + 25 r²), faded linearly to 0 from r² = 0.64 (80 % of the range) to 1.
    assert light_falloff(0.0) == 1.0
    assert light_falloff(0.04) == pytest.approx(0.5)
    assert light_falloff(0.64) == pytest.approx(1 / 17)
    assert light_falloff(0.82) == pytest.approx(1 / (1 + 25 * 0.82) * 0.5)
    assert light_falloff(1.0) == 0.0 and light_falloff(4.0) == 0.0


def test_bad_lights_and_msaa_are_one_line_scene_errors():
    r = _cube_renderer("Cube", Material())
    with pytest.raises(SceneError, match="MSAA must be 1, 2, 4 or 8"):
        validate_scene(DrawScene(_scene([r]).camera, (r,), msaa=3))
    with pytest.raises(SceneError, match="light 'P'"):
        validate_scene(_scene([r], [_point("P", (0.0, 0.0, float("nan")))]))
    with pytest.raises(SceneError, match="range"):
        validate_scene(_scene([r], [_point("P", (0.0, 0.0, 0.0), range_=0.0)]))
