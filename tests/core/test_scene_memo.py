"""SceneMemo: renders of scenes sharing their renderers check them and convert their textures
once, and give the same frames and warnings as renders without it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core import scene as scene_module
from blendlib.core import shade
from blendlib.core.scene import SceneError, SceneMemo
from tests.reference.random_scenes import seeded_scene


def textured_seed() -> int:
    """The seed of a random scene with at least one texture."""
    for seed in range(200):
        draw = seeded_scene(seed)
        if any(r.material.main_tex is not None for r in draw.renderers):
            return seed
    raise AssertionError("no textured random scene")


def counting(monkeypatch, module, name: str) -> list[int]:
    calls = []
    real = getattr(module, name)

    def wrapper(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, wrapper)
    return calls


def views(draw, count: int = 3):
    """The scene through ``count`` cameras moved sideways, at two sizes (a viewport's frames)."""
    out = []
    for k in range(count):
        view = np.array(draw.camera.view_matrix, dtype=np.float64)
        view[0, 3] += 0.15 * k
        size = (64, 48) if k % 2 else (32, 24)
        out.append(dataclasses.replace(draw, camera=dataclasses.replace(draw.camera, view_matrix=view,
                                                                        width=size[0], height=size[1])))
    return out


def test_memoised_renders_equal_plain_ones_and_check_each_renderer_once(monkeypatch):
    draw = seeded_scene(textured_seed())
    empty = dataclasses.replace(draw.renderers[0], mesh=dataclasses.replace(
        draw.renderers[0].mesh, positions=np.zeros((0, 3), np.float32), triangles=np.zeros((0, 3), np.int32),
        normals=np.zeros((0, 3, 3), np.float32), uvs=None, polygons=None, loop_triangles=None))
    draw = dataclasses.replace(draw, renderers=(*draw.renderers, empty))
    frames = views(draw)
    expected = [render_scene(f) for f in frames]
    checks = counting(monkeypatch, scene_module, "_validate_renderer")
    conversions = counting(monkeypatch, shade, "texture_texels")
    memo = SceneMemo()
    for f, plain in zip(frames, expected, strict=True):
        got = render_scene(f, memo=memo)
        np.testing.assert_array_equal(got.color, plain.color)
        np.testing.assert_array_equal(got.depth, plain.depth)
        np.testing.assert_array_equal(got.stencil, plain.stencil)
        assert got.warnings == plain.warnings
    assert any("empty mesh" in w for w in expected[0].warnings)
    assert len(checks) == len(draw.renderers)  # once each, not once a frame
    textures = {id(r.material.main_tex) for r in draw.renderers if r.material.main_tex is not None}
    assert 0 < len(conversions) == len(textures)


def test_a_renderer_that_fails_its_check_fails_every_time():
    draw = seeded_scene(3)
    broken = dataclasses.replace(draw.renderers[0], matrix_world=np.full((4, 4), np.nan))
    bad = dataclasses.replace(draw, renderers=(broken, *draw.renderers[1:]))
    memo = SceneMemo()
    for _ in range(2):
        with pytest.raises(SceneError, match="matrix_world"):
            render_scene(bad, memo=memo)


def test_lookup_computes_once_per_object_and_keeps_it():
    memo = SceneMemo()
    made = []
    first = object()
    assert memo.lookup("k", first, lambda: made.append(1) or "a") == "a"
    assert memo.lookup("k", first, lambda: made.append(1) or "b") == "a"
    assert memo.lookup("other", first, lambda: made.append(1) or "c") == "c"
    assert len(made) == 2
    assert memo._entries[("k", id(first))][0] is first  # held: its id cannot be reused meanwhile
