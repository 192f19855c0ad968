"""SceneMemo: renders of scenes sharing their renderers check them and convert their textures
once, and give the same frames and warnings as renders without it."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core import scene as scene_module
from blendlib.core import shade
from blendlib.core.scene import SceneError, SceneMemo, reuse_unchanged, scene_parts
from tests.reference.random_scenes import seeded_scene
from tests.reference.scenes import translate


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


def extracted_again(draw):
    """``draw`` as the viewport's next extraction gives it: equal content, every object new."""
    return pickle.loads(pickle.dumps(draw))


def with_renderer(draw, k: int, **changes):
    r = draw.renderers[k]
    return dataclasses.replace(draw, renderers=(*draw.renderers[:k], dataclasses.replace(r, **changes),
                                                *draw.renderers[k + 1:]))


def test_reuse_unchanged_shares_an_equal_outline_width_texture_and_the_memo_converts_it_once(monkeypatch):
    """MToon's outline-width texture is a texture part like ``_MainTex``: re-extracted equal, the
    material is the old one; its texels are converted once across frames."""
    from tests.reference.feature_sweeps import outline_sweep

    draw = outline_sweep(width_textures=True)
    same = reuse_unchanged(extracted_again(draw), draw)
    assert all(a is b for a, b in zip(same.renderers, draw.renderers, strict=True))
    widths = {id(r.material.outline_width_tex) for r in draw.renderers if r.material.outline_width_tex is not None}
    assert widths and widths <= {id(p) for p in scene_parts(draw)}
    conversions = counting(monkeypatch, shade, "texture_texels")
    memo = SceneMemo()
    first = render_scene(draw, memo=memo)
    again = render_scene(same, memo=memo)
    np.testing.assert_array_equal(first.color, again.color)
    assert len(conversions) == len(widths)


def test_reuse_unchanged_shares_equal_parts_and_keeps_changed_ones():
    draw = seeded_scene(8)  # four renderers, three textured
    assert len(draw.renderers) == 4
    same = reuse_unchanged(extracted_again(draw), draw)
    assert all(a is b for a, b in zip(same.renderers, draw.renderers, strict=True))
    assert reuse_unchanged(draw, None) is draw

    # One object moved: a new renderer over the old mesh and material.
    matrix = np.array(draw.renderers[0].matrix_world, dtype=np.float64)
    matrix[1, 3] += 0.25
    moved = reuse_unchanged(with_renderer(extracted_again(draw), 0, matrix_world=matrix), draw)
    r0 = moved.renderers[0]
    assert r0 is not draw.renderers[0] and r0.mesh is draw.renderers[0].mesh
    assert r0.material is draw.renderers[0].material
    np.testing.assert_array_equal(r0.matrix_world, matrix)
    assert all(a is b for a, b in zip(moved.renderers[1:], draw.renderers[1:], strict=True))

    # A texel changed: a new texture and material for its renderers, their meshes shared.
    k = next(i for i, r in enumerate(draw.renderers) if r.material.main_tex is not None)
    again = extracted_again(draw)
    material = again.renderers[k].material
    pixels = np.array(material.main_tex.pixels)
    pixels[0, 0, 0] = 1.0 - pixels[0, 0, 0]
    repainted = reuse_unchanged(with_renderer(again, k, material=dataclasses.replace(
        material, main_tex=dataclasses.replace(material.main_tex, pixels=pixels))), draw)
    rk = repainted.renderers[k]
    assert rk.material is not draw.renderers[k].material and rk.mesh is draw.renderers[k].mesh
    np.testing.assert_array_equal(rk.material.main_tex.pixels, pixels)

    # A cutoff changed: a new material holding the old texture.
    recut = reuse_unchanged(with_renderer(again, k, material=dataclasses.replace(material, cutoff=0.123)), draw)
    assert recut.renderers[k].material.cutoff == 0.123
    assert recut.renderers[k].material.main_tex is draw.renderers[k].material.main_tex

    # Equal values with other bytes or types are not the same: -0.0 for 0.0, other dtypes, ints.
    mesh = draw.renderers[1].mesh
    zero = np.array(mesh.positions)
    zero[0, 0] = 0.0
    base = with_renderer(draw, 1, mesh=dataclasses.replace(mesh, positions=zero),
                         material=dataclasses.replace(draw.renderers[1].material, color=(1.0, 0.5, 0.25, 1.0)))
    negative = zero.copy()
    negative[0, 0] = -0.0
    signed = reuse_unchanged(with_renderer(extracted_again(base), 1, mesh=dataclasses.replace(
        mesh, positions=negative)), base)
    assert signed.renderers[1].mesh is not base.renderers[1].mesh
    other_dtype = np.float32 if zero.dtype == np.float64 else np.float64
    wider = reuse_unchanged(with_renderer(extracted_again(base), 1, mesh=dataclasses.replace(
        mesh, positions=zero.astype(other_dtype))), base)
    assert wider.renderers[1].mesh is not base.renderers[1].mesh
    assert reuse_unchanged(extracted_again(base), base).renderers[1].mesh is base.renderers[1].mesh
    whole = reuse_unchanged(with_renderer(extracted_again(base), 1, material=dataclasses.replace(
        base.renderers[1].material, color=(1, 0.5, 0.25, 1))), base)
    assert whole.renderers[1].material is not base.renderers[1].material
    assert whole.renderers[1].mesh is base.renderers[1].mesh

    for changed in (moved, repainted, recut, wider):
        assert_same(render_scene(changed), render_scene(extracted_again(changed)))


def assert_same(a, b) -> None:
    np.testing.assert_array_equal(a.color, b.color)
    np.testing.assert_array_equal(a.depth, b.depth)
    assert a.warnings == b.warnings


def test_retain_keeps_what_the_shared_parts_derived(monkeypatch):
    """A memo retained for a changed scene checks only its new renderers and converts only its
    new textures, and renders it as a fresh memo would."""
    draw = seeded_scene(8)
    memo = SceneMemo()
    render_scene(draw, memo=memo)
    checks = counting(monkeypatch, scene_module, "_validate_renderer")
    conversions = counting(monkeypatch, shade, "texture_texels")
    matrix = np.array(draw.renderers[0].matrix_world, dtype=np.float64)
    matrix[0, 3] -= 0.2
    moved = reuse_unchanged(with_renderer(extracted_again(draw), 0, matrix_world=matrix), draw)
    memo.retain(moved)
    assert_same(render_scene(moved, memo=memo), render_scene(moved))
    assert len(checks) == 1 + len(moved.renderers)  # the moved renderer here, all in the plain render
    textures = {id(r.material.main_tex) for r in moved.renderers if r.material.main_tex is not None}
    assert len(conversions) == len(textures)  # none here: the plain render's only
    # Entries of parts no scene holds any more are dropped.
    held = {id(p) for p in scene_parts(moved)}
    assert all(id(hit[0]) in held for hit in memo._entries.values())
    assert id(draw.renderers[0]) not in {id(hit[0]) for hit in memo._entries.values()}


def test_setups_are_kept_per_renderer_and_camera(monkeypatch):
    """A memo keeps each small renderer's vertex setup (and a whole frame's coverage rows) per
    camera: frames through a camera seen before set up only the renderers that changed, a third
    camera evicts the oldest, big meshes are never kept; every frame equals a plain render."""
    from blendlib.core import prepare, vertex

    draw = seeded_scene(8)
    set_up = []
    real = vertex.setup_renderers
    monkeypatch.setattr(vertex, "setup_renderers",
                        lambda items, *a, **k: set_up.append(len(items)) or real(items, *a, **k))
    near, far, side = views(draw, 3)  # three cameras, two sizes
    memo = SceneMemo()

    def frame(scene) -> int:
        set_up.clear()
        assert_same(render_scene(scene, memo=memo), render_scene(scene))
        return sum(set_up[: len(set_up) // 2])  # the memo's render comes first

    n = len(draw.renderers)
    assert frame(near) == n
    assert frame(far) == n
    assert frame(near) == 0 and frame(far) == 0  # both cameras kept
    matrix = np.array(draw.renderers[3].matrix_world, dtype=np.float64)
    matrix[0, 3] += 0.1
    moved = reuse_unchanged(with_renderer(extracted_again(near), 3, matrix_world=matrix), near)
    memo.retain(moved)
    assert frame(moved) == 1  # only the moved renderer
    assert frame(dataclasses.replace(moved, camera=side.camera)) == n
    # Two cameras kept per renderer: far and side for the others, near and side for the moved one.
    assert frame(dataclasses.replace(moved, camera=far.camera)) == 1
    assert frame(moved) == n  # near: evicted everywhere by now
    # Over the memo's budget, or each renderer over the size limit: set up every frame.
    budget = sum(r.mesh.triangle_count for r in moved.renderers[:2])
    monkeypatch.setattr(prepare, "MEMO_SETUP_BUDGET", budget)
    fresh = SceneMemo()
    for _ in range(2):
        set_up.clear()
        render_scene(moved, memo=fresh)
        assert sum(set_up) == (n if _ == 0 else n - 2)  # the first two fit the budget, the rest do not
    monkeypatch.setattr(prepare, "MEMO_SETUP_BUDGET", 1 << 30)
    monkeypatch.setattr(prepare, "MEMO_SETUP_TRIANGLES", 0)
    assert frame(dataclasses.replace(moved, camera=far.camera)) == n
    assert frame(dataclasses.replace(moved, camera=far.camera)) == n


def test_outline_setups_are_kept_per_camera_program_and_colour_space(monkeypatch):
    """An outlined renderer's two setups (the plain vertex stage and its outline program) are both
    kept: the same view sets up nothing again; a new outline width (a new material, so a new
    renderer of the same mesh and placement) sets up that renderer's outline alone, its plain
    vertex stage found by the mesh; another colour space re-converts the outline-width factors,
    so only the outline setups are made again. Every frame equals a plain render."""
    from blendlib.core import vertex
    from blendlib.core.vocabulary import ColorSpace
    from tests.reference.feature_sweeps import outline_sweep

    draw = outline_sweep(width_textures=True)
    outlined = [r for r in draw.renderers if any(p.outline_mode.name != "Off" for p in r.material.passes)]
    assert len(outlined) == 8 and len(draw.renderers) == 9
    set_up = []
    real = vertex.setup_renderers
    monkeypatch.setattr(vertex, "setup_renderers",
                        lambda items, *a, **k: set_up.extend(i.program is not None for i in items)
                        or real(items, *a, **k))
    memo = SceneMemo()

    def frame(scene) -> list[bool]:
        """Whether each setup the memo's render made had a vertex program."""
        set_up.clear()
        got = render_scene(scene, memo=memo)
        made = list(set_up)
        assert_same(got, render_scene(scene))
        return made

    assert sorted(frame(draw)) == [False] * 9 + [True] * 8
    assert frame(draw) == []
    material = outlined[2].material
    wider = replace_outline_width(material, 2.0)
    k = draw.renderers.index(outlined[2])
    changed = with_renderer(draw, k, material=wider)
    memo.retain(changed)
    assert frame(changed) == [True]
    linear = dataclasses.replace(changed, color_space=ColorSpace.Linear)
    assert frame(linear) == [True] * 8  # the factors in the other colour space; plain setups kept
    assert frame(linear) == []


def replace_outline_width(material, factor: float):
    """``material`` with its outline pass's width times ``factor``."""
    passes = tuple(dataclasses.replace(p, outline_width=p.outline_width * factor) if p.outline_mode.name != "Off"
                   else p for p in material.passes)
    return dataclasses.replace(material, passes=passes)


def test_setups_are_kept_per_mesh_placement_and_attributes(monkeypatch):
    """A kept setup serves every renderer of the same mesh, placement and attributes read: a
    renderer whose material changes in what the vertex stage does not read (its queue, as the
    advice's fixes do) sets up nothing again; one placed elsewhere, or whose material reads
    other attributes (normals for Lambert, UVs for a texture), is set up again. Every frame
    equals a plain render."""
    from blendlib.core import vertex
    from blendlib.core.vocabulary import Lighting, Queue

    draw = seeded_scene(8)
    set_up = []
    real = vertex.setup_renderers
    monkeypatch.setattr(vertex, "setup_renderers",
                        lambda items, *a, **k: set_up.append(len(items)) or real(items, *a, **k))
    memo = SceneMemo()

    def frame(scene) -> int:
        set_up.clear()
        assert_same(render_scene(scene, memo=memo), render_scene(scene))
        return sum(set_up[: len(set_up) // 2])  # the memo's render comes first

    assert frame(draw) == len(draw.renderers)
    material = draw.renderers[0].material
    requeued = with_renderer(draw, 0, material=dataclasses.replace(material, queue=Queue.Transparent,
                                                                   queue_offset=material.queue_offset + 7))
    assert frame(requeued) == 0
    other = draw.renderers[2].material
    relit = Lighting.Unlit if other.lighting is not Lighting.Unlit else Lighting.Lambert
    assert frame(with_renderer(draw, 2, material=dataclasses.replace(other, lighting=relit))) == 1
    # The same mesh through another renderer (an instance) at the same place: its setup is found.
    twin = dataclasses.replace(draw.renderers[3], name="twin")
    assert frame(dataclasses.replace(draw, renderers=(*draw.renderers, twin))) == 0
    assert frame(draw) == 0
    matrix = np.array(draw.renderers[1].matrix_world, dtype=np.float64)
    matrix[1, 3] += 0.1
    assert frame(with_renderer(draw, 1, matrix_world=matrix)) == 1
    # A placement no renderer of the scene has is dropped when another is kept: back at its
    # place, the renderer is set up again.
    assert frame(draw) == 1


def test_a_dragged_object_keeps_one_setup_per_placement_the_scene_has(monkeypatch):
    """An object moved frame after frame through one view (a drag in the viewport) keeps the
    setups of its current placement only, not one per position it passed; an instance of
    its mesh placed elsewhere keeps its own. Every frame sets up the moved renderer alone and
    equals a plain render."""
    from blendlib.core import vertex

    draw = seeded_scene(8)
    mesh = draw.renderers[0].mesh
    instance = dataclasses.replace(draw.renderers[0], name="instance",
                                   matrix_world=np.array(draw.renderers[0].matrix_world) @ translate(0.0, 0.3, 0.0))
    draw = dataclasses.replace(draw, renderers=(*draw.renderers, instance))
    placements = {np.asarray(r.matrix_world, dtype=np.float64).tobytes() for r in draw.renderers if r.mesh is mesh}
    set_up = []
    real = vertex.setup_renderers
    monkeypatch.setattr(vertex, "setup_renderers",
                        lambda items, *a, **k: set_up.append(len(items)) or real(items, *a, **k))
    memo = SceneMemo()
    render_scene(draw, memo=memo)
    scene = draw
    for step in range(12):
        matrix = np.array(draw.renderers[0].matrix_world, dtype=np.float64)
        matrix[0, 3] += 0.01 * (step + 1)
        scene = with_renderer(draw, 0, matrix_world=matrix)
        set_up.clear()
        assert_same(render_scene(scene, memo=memo), render_scene(scene))
        assert sum(set_up[: len(set_up) // 2]) == 1  # the moved renderer alone
        kept = memo.lookup("geometry", mesh, dict)
        assert len(kept) <= len(placements)  # the instance's and the moved one's current place
    assert len(memo.lookup("geometry", mesh, dict)) == len(placements)



def test_band_rows_are_kept_for_the_last_band(monkeypatch):
    """A band render through a memo keeps its calls' coverage rows for that band: the same band
    again computes none, another band (or the whole frame) computes them again and replaces them.
    Every band equals a plain band render."""
    from blendlib.core import raster

    draw = seeded_scene(8)
    covered = []
    for name in ("coverage_rows_many", "coverage_rows"):
        real = getattr(raster, name)
        monkeypatch.setattr(raster, name, lambda *a, _real=real, **k: covered.append(1) or _real(*a, **k))
    memo = SceneMemo()
    height = int(draw.camera.height)

    def frame(band) -> int:
        before = len(covered)
        got = render_scene(draw, memo=memo, band=band)
        made = len(covered) - before
        expected = render_scene(draw, band=band)
        np.testing.assert_array_equal(got.color, expected.color)
        np.testing.assert_array_equal(got.depth, expected.depth)
        return made

    low, high = (0, height // 2), (height // 3, height)
    assert frame(low) > 0
    assert frame(low) == 0
    assert frame(high) > 0
    assert frame(high) == 0
    assert frame(None) > 0 and frame(None) == 0
    assert frame(low) > 0
