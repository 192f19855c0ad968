"""render_scene's ``shaded_cache``: shaded chunks kept across renders of one scene's variants
that draw the same calls in another order (the advice's candidate fixes). A render that reads
the cache must equal one that shades every chunk, bit for bit, and the cache must be read."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core import pipeline, shaded_cache
from blendlib.core.drawlist import draw_calls
from blendlib.core.merger import Outcome
from blendlib.core.shaded_cache import ShadedCache
from blendlib.core.vocabulary import BlendFactor, Pass, Queue
from blendlib.explain.advice import _signature
from tests.core.test_band_renders import _After
from tests.core.test_observer import Recorder
from tests.reference import scenes as sc
from tests.reference.random_scenes import seeded_scene

BLEND = Pass(blend=True, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha, zwrite=False)


def _keys(scene):
    calls = draw_calls(scene)
    return calls, {c.index: entry for c, entry in zip(calls, _signature(scene, calls), strict=True)}


def _assert_same(frame, expected):
    for name in ("color", "depth", "stencil"):
        np.testing.assert_array_equal(getattr(frame, name), getattr(expected, name), err_msg=name)


def _glass_and_screen(glass_first: bool):
    """An opaque wall, a transparent pane (ZWrite Off) in front of it across the frame and a
    nearer transparent screen that writes depth over the left half; ``glass_first``: the pane is
    drawn first (queue offsets). Drawn second, the pane is hidden behind the screen: its chunks
    there are shaded against a depth the screen wrote."""
    cam = sc.screen_camera(24, 16)
    wall = sc.renderer(sc.quad(0, 0, 24, 16, z=-5.0), sc.unlit((0.2, 0.3, 0.4, 1.0), name="Wall"), name="Wall")
    pane = sc.unlit((0.9, 0.6, 0.1, 0.5), queue=Queue.Transparent, queue_offset=0 if glass_first else 2,
                    name="Pane", passes=[BLEND])
    screen = sc.unlit((0.1, 0.4, 0.9, 0.5), queue=Queue.Transparent, queue_offset=1, name="Screen",
                      passes=[replace(BLEND, zwrite=True)])
    return sc.scene(cam, wall, sc.renderer(sc.quad(0, 0, 24, 16, z=-1.0), pane, name="Pane"),
                    sc.renderer(sc.quad(0, 0, 12, 16, z=1.0), screen, name="Screen"))


def test_a_chunk_shaded_before_a_depth_write_is_not_taken_after_it():
    """The pane drawn first, then drawn after the screen wrote depth: the second render must not
    take the pane's chunks of the first (then its depth test was trivially passed, the wall
    being the farthest depth stored), or the pane would cover the screen. The wall's chunks,
    drawn before anything writes depth in either order, are taken."""
    cache = ShadedCache()
    first, second = _glass_and_screen(True), _glass_and_screen(False)
    for scene in (first, second):
        calls, keys = _keys(scene)
        got = render_scene(scene, workers=1, shaded_cache=cache, call_keys=keys, calls=calls)
        _assert_same(got, render_scene(scene, workers=1))
    assert cache.hits >= 1  # the wall's chunk
    # The screen's half shows the screen over the pane, not the pane over the screen.
    expected = render_scene(second, workers=1).color
    assert not np.array_equal(expected, render_scene(first, workers=1).color)


def test_without_the_depth_writes_before_it_in_its_key_a_chunk_would_be_taken_wrongly(monkeypatch):
    """The test above has teeth: with a key that leaves out the calls that wrote depth before a
    chunk, the pane's chunk of the first order is taken in the second, and the frame differs."""
    real = shaded_cache.call_slots

    def without_history(cache, calls, keys, writes, resumed=None):
        return {index: (number, (), origin)
                for index, (number, _history, origin) in real(cache, calls, keys, writes, resumed).items()}

    monkeypatch.setattr(pipeline, "call_slots", without_history)
    cache = ShadedCache()
    for scene in (_glass_and_screen(True), _glass_and_screen(False)):
        calls, keys = _keys(scene)
        got = render_scene(scene, workers=1, shaded_cache=cache, call_keys=keys, calls=calls)
    assert not np.array_equal(got.color, render_scene(_glass_and_screen(False), workers=1).color)


def test_an_observed_render_does_not_take_the_chunks_of_an_unobserved_one():
    """Unobserved, the pane drawn behind the screen drops the fragments the screen hides before
    shading them (an early depth test); an observer told of every fragment must still be told
    of those, with their outcome, when the same chunks were shaded unobserved before."""
    scene = _glass_and_screen(False)
    calls, keys = _keys(scene)
    cache = ShadedCache()
    render_scene(scene, workers=1, shaded_cache=cache, call_keys=keys, calls=calls)
    cached, plain = Recorder(), Recorder()
    got = render_scene(scene, workers=1, shaded_cache=cache, call_keys=keys, calls=calls, observer=cached)
    _assert_same(got, render_scene(scene, workers=1, observer=plain))
    pane = next(c.index for c in calls if c.renderer.name == "Pane")
    assert plain.counts(pane)[Outcome.DEPTH] == 12 * 16  # the pane's fragments behind the screen
    for index in (c.index for c in calls):
        assert cached.counts(index) == plain.counts(index), index
        np.testing.assert_array_equal(np.concatenate(cached.pixels[index]), np.concatenate(plain.pixels[index]))


def _reordered(scene, order):
    """``scene`` with renderer k at queue offset ``order[k]`` (its own queue kept)."""
    return replace(scene, renderers=tuple(replace(r, material=replace(r.material, queue_offset=int(o)))
                                          for r, o in zip(scene.renderers, order, strict=True)))


@pytest.mark.parametrize("seed", [0, 8, 15, 27, 30])
def test_renders_of_reordered_scenes_through_one_cache_equal_renders_without_it(seed):
    """Random scenes (stencil, ZWrite and ZTest variations, alpha test, textures, lights) drawn in
    every order of their renderers' queue offsets, through one cache: whole frames, frames
    resumed from the buffers after the first call, bands, and two threads; every one equal to
    the render without the cache, and chunks taken from it."""
    scene = seeded_scene(seed)
    count = len(scene.renderers)
    cache = ShadedCache()
    after = _After(1)
    render_scene(scene, workers=1, observer=after)
    height = int(scene.camera.height)
    for order in itertools.permutations(range(count)):
        changed = _reordered(scene, order)
        calls, keys = _keys(changed)
        for options in ({"workers": 1}, {"workers": 2}, {"workers": 1, "band": (3, height - 5)},
                        {"workers": 1, "resume": (after.buffers, 1)}):
            got = render_scene(changed, shaded_cache=cache, call_keys=keys, calls=calls, **options)
            _assert_same(got, render_scene(changed, **options))
    assert cache.hits > 0 and cache.nbytes <= cache.max_bytes


def test_a_full_cache_keeps_nothing_more():
    """Past its budget the cache keeps no chunk (renders shade them, and equal those without it)."""
    scene = _glass_and_screen(True)
    calls, keys = _keys(scene)
    cache = ShadedCache(max_bytes=0)
    for _ in range(2):
        _assert_same(render_scene(scene, workers=1, shaded_cache=cache, call_keys=keys, calls=calls),
                     render_scene(scene, workers=1))
    assert cache.hits == 0 and cache.nbytes == 0
