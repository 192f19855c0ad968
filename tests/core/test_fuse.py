"""Fused draw calls (blendlib.core.fuse) must draw exactly what the calls draw one after another.

Consecutive constant-colour calls drawn as one, and calls sharing their shading shaded once and
merged call by call: each against the scalar reference of tests/reference/scalar.py, with one
thread and two, with chunks that cut a call's rows, and without fusion.
"""

from __future__ import annotations

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core import merger
from blendlib.core.scene import DrawScene
from blendlib.core.vocabulary import (
    BlendFactor,
    ColorSpace,
    CompareFunction,
    Cull,
    Lighting,
    Material,
    Pass,
    Queue,
    TextureFilter,
)
from tests.reference import scenes as sc
from tests.reference.scalar import render_reference


def _fused_frames(scene: DrawScene, fuser: str, monkeypatch) -> tuple[list, list]:
    """Frames of ``scene`` by one thread, two, and chunks of 97 candidates, with the groups
    ``pipeline.<fuser>`` (the driver's name for :mod:`blendlib.core.fuse`'s) made recorded as
    (calls in, calls out) per batch."""
    from blendlib.core import pipeline

    groups = []
    original = getattr(pipeline, fuser)

    def recording(prepared, memo=None):
        out = original(prepared, memo)
        groups.append((len(prepared), len(out)))
        return out

    monkeypatch.setattr(pipeline, fuser, recording)
    merger.RECENT_TABLES.clear()
    return groups, [render_scene(scene, workers=1), render_scene(scene, workers=2),
                    render_scene(scene, workers=1, chunk_candidates=97)]


@pytest.mark.parametrize("hdr,color_space", [(False, ColorSpace.Gamma), (False, ColorSpace.Linear),
                                             (True, ColorSpace.Linear)])
def test_constant_colour_draw_calls_fused_equal_reference(hdr, color_space, monkeypatch):
    """Consecutive Unlit untextured draw calls with one pass state (text labels) are drawn as
    one: overlapping blended quads, ZWrite On with Offset and a stencil op, equal colours in
    different calls, a textured call and an alpha-tested one between groups. The frame equals
    the reference, one thread and two, with blend tables (large chunks) and per-fragment
    blending (small chunks), and equals the frame drawn call by call."""
    from blendlib.core import fuse
    from blendlib.core.vocabulary import StencilOp, Texture

    blend = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
                 dst_blend=BlendFactor.OneMinusSrcAlpha)
    stamp = Pass(offset_factor=-1.0, offset_units=-1.0, stencil=True, stencil_ref=3,
                 stencil_pass=StencilOp.IncrSat, stencil_zfail=StencilOp.Invert)
    colors = [(0.9, 0.2, 0.1, 0.5), (0.1, 0.8, 0.3, 0.35), (0.9, 0.2, 0.1, 0.5), (0.2, 0.3, 0.95, 0.7),
              (0.5, 0.5, 0.5, 0.25)]
    renderers = []
    for k, color in enumerate(colors):
        mat = sc.unlit(color, queue=Queue.Transparent, passes=(blend,), name=f"Glass{k}")
        renderers.append(sc.renderer(sc.fan((0.25 * k - 0.5, 0.1 * k, 0.15 * k), 0.9, 9, 0.2 * k), mat,
                                     name=f"Glass{k}"))
    texture = Texture(np.random.default_rng(3).uniform(0, 1, (4, 4, 4)).astype(np.float32), name="t")
    for k in range(6):
        if k == 3:  # a textured call splits the opaque group
            mat = Material(name="Textured", lighting=Lighting.Unlit, main_tex=texture, passes=(stamp,))
        elif k == 4:  # so does an alpha-tested one
            mat = sc.unlit((0.3, 0.6, 0.9, 0.4), passes=(Pass(alpha_test=True),), cutoff=0.3, name="Cut")
        else:
            mat = sc.unlit((0.1 + 0.15 * k, 0.7, 0.2, 1.0), passes=(stamp,), name=f"Stamp{k}")
        renderers.append(sc.renderer(sc.quad(-1.2 + 0.35 * k, -1.0 + 0.2 * k, 0.2 + 0.35 * k, 0.6 + 0.1 * k,
                                             z=-0.2 * k), mat, name=f"Quad{k}"))
    scene = DrawScene(camera=sc.camera(120, 96, eye=(0.3, 0.4, 4.0)), renderers=tuple(renderers),
                      color_space=color_space, hdr=hdr)
    groups, frames = _fused_frames(scene, "fuse_constant_calls", monkeypatch)
    # 5 blended calls -> 1; the opaque ones: 3 fused, then the textured, the alpha-tested, 1 alone.
    assert groups[0] == (11, 5)
    monkeypatch.setattr(fuse, "FUSE_TRIANGLES", 0)
    frames.append(render_scene(scene, workers=1))
    assert groups[-1] == (11, 11)
    color, depth, stencil = render_reference(scene)
    assert len(np.unique(stencil)) > 2 and len(np.unique(color.reshape(-1, 4), axis=0)) > 8
    for frame in frames:
        np.testing.assert_array_equal(frame.color, color)
        np.testing.assert_array_equal(frame.depth, depth)
        np.testing.assert_array_equal(frame.stencil, stencil)


def _rotation(axis: int, degrees: float) -> np.ndarray:
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    m = np.eye(4)
    i, j = [k for k in range(3) if k != axis]
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


@pytest.mark.parametrize("hdr,color_space", [(False, ColorSpace.Gamma), (False, ColorSpace.Linear),
                                             (True, ColorSpace.Linear)])
def test_draw_calls_sharing_shading_fused_equal_reference(hdr, color_space, monkeypatch):
    """Consecutive draw calls whose materials differ only in pass and cutoff are shaded as one
    and merged call by call (``fuse.fuse_shared_shading``). Two groups: lit quads with a Point
    texture (texel palettes) under different object matrices (one mirrored, one crossing the
    near plane: clipped), overlapping, with blend modes the tables serve and one they cannot
    (DstAlpha), alpha tests with different cutoffs, stencil, ColorMask, and two passes of one
    renderer; before them smooth-lit spheres with a Bilinear texture (shaded per fragment), Cull
    and cutoff per call; after them two calls without ZWrite, whose rows' depth floors apply.
    The frame equals the reference with one thread and two and with chunks
    that cut a call's rows, and equals the frame drawn call by call."""
    import dataclasses

    from blendlib.core import fuse
    from blendlib.core.scene import Light
    from blendlib.core.vocabulary import StencilOp, Texture

    rng = np.random.default_rng(5)
    texture = Texture(rng.uniform(0, 1, (4, 4, 4)).astype(np.float32), name="cells")
    over = Pass(cull=Cull.Off, zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha,
                dst_blend=BlendFactor.OneMinusSrcAlpha)
    passes = [
        (over,),
        (Pass(zwrite=False, blend=True, src_blend=BlendFactor.DstAlpha, dst_blend=BlendFactor.One),),
        (Pass(alpha_test=True, stencil=True, stencil_ref=2, stencil_pass=StencilOp.Replace),),
        (Pass(alpha_test=True, color_mask=frozenset("RG"), ztest=CompareFunction.Greater),),
        (Pass(zwrite=False, blend=True, src_blend=BlendFactor.One, dst_blend=BlendFactor.One),
         Pass(offset_factor=0.0, stencil=True, stencil_comp=CompareFunction.NotEqual, stencil_ref=2,
              stencil_pass=StencilOp.IncrSat, blend=True, src_blend=BlendFactor.DstColor,
              dst_blend=BlendFactor.Zero)),
    ]
    matrices = [_rotation(2, 20) @ sc.translate(-0.6, 0.2, 0.3), sc.scale(-1.0, 1.0, 1.0) @ _rotation(1, 35),
                _rotation(1, -50) @ sc.translate(0.4, -0.3, -0.2),
                sc.translate(0.0, -0.4, 0.0) @ _rotation(0, -90) @ sc.scale(1.5, 4.0, 1.0),  # through the near plane
                _rotation(0, 30) @ sc.translate(0.5, 0.5, 0.5)]
    renderers = []
    for k, (own, matrix) in enumerate(zip(passes, matrices, strict=True)):
        mat = Material(name=f"Cell{k}", queue=Queue.Transparent, color=(0.9, 0.8, 0.7, 0.8), main_tex=texture,
                       main_tex_filter=TextureFilter.Point, main_tex_tiling=(3.0, 2.0), lighting=Lighting.Lambert,
                       cutoff=0.2 * k, passes=own)
        renderers.append(sc.renderer(sc.quad(-1, -1, 1, 1), mat, name=f"Cell{k}", matrix=matrix))
    sphere = sc.uv_sphere(0.6, 10, 6)
    corners = np.asarray(sphere.positions, dtype=np.float64)[np.asarray(sphere.triangles)]
    sphere = dataclasses.replace(sphere, uvs=(corners[..., :2] * 0.8 + 0.5).astype(np.float32))
    for k, own in enumerate([Pass(), Pass(cull=Cull.Front), Pass(alpha_test=True)]):
        mat = Material(name=f"Ball{k}", color=(0.6, 0.9, 0.8, 1.0), main_tex=texture, cutoff=0.45,
                       main_tex_filter=TextureFilter.Bilinear, lighting=Lighting.Lambert, passes=(own,))
        renderers.append(sc.renderer(sphere, mat, name=f"Ball{k}", matrix=sc.translate(-0.9 + 0.8 * k, 0.6, -1.0)))
    # Unlit passes without ZWrite before and after the quads: the rows' depth floors they test
    # against (DrawState.zfloor) must be taken again after the quads write depth.
    behind = Pass(zwrite=False, blend=True, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha)
    renderers.append(sc.renderer(sc.quad(-0.2, -1.5, 0.4, 1.5, z=-3.0), sc.unlit(
        (0.2, 0.9, 0.1, 0.5), queue=Queue.AlphaTest, passes=(behind,), name="Marker"), name="Marker"))
    renderers.append(sc.renderer(sc.quad(-3, -3, 3, 3, z=-2.5), sc.unlit(
        (0.9, 0.1, 0.8, 0.6), queue=Queue.Overlay, passes=(behind,), name="Veil"), name="Veil"))
    # Then two textured calls without ZWrite (ZTest Less, LEqual): depth floors prove some rows.
    for k, ztest in enumerate([CompareFunction.Less, CompareFunction.LEqual]):
        glaze = Pass(zwrite=False, ztest=ztest, blend=True, src_blend=BlendFactor.One,
                     dst_blend=BlendFactor.OneMinusSrcColor)
        mat = Material(name=f"Glaze{k}", queue=Queue.Overlay, main_tex=texture, main_tex_filter=TextureFilter.Point,
                       lighting=Lighting.Unlit, passes=(glaze,))
        renderers.append(sc.renderer(sc.quad(-2.2 + 1.6 * k, -2.0, -0.2 + 1.6 * k, 0.3, z=-0.4 + 0.5 * k), mat,
                                     name=f"Glaze{k}"))
    scene = DrawScene(camera=sc.camera(120, 96, eye=(0.3, 0.4, 4.0), near=0.5), renderers=tuple(renderers),
                      color_space=color_space, hdr=hdr, light=Light(direction=(0.36, 0.48, 0.8)),
                      ambient=(0.3, 0.2, 0.1))
    groups, frames = _fused_frames(scene, "fuse_shared_shading", monkeypatch)
    # The spheres (3 calls), the marker, the quads (6 calls), the veil, the glazes (2 calls).
    assert groups[0] == (13, 5)
    monkeypatch.setattr(fuse, "FUSE_FRAGMENTS", 1500)  # smaller groups
    frames.append(render_scene(scene, workers=1))
    assert 5 < groups[-1][1] < 13
    monkeypatch.setattr(fuse, "FUSE_TRIANGLES", 0)
    frames.append(render_scene(scene, workers=1))
    assert groups[-1] == (13, 13)
    color, depth, stencil = render_reference(scene)
    assert len(np.unique(stencil)) >= 3 and len(np.unique(color.reshape(-1, 4), axis=0)) > 200
    for frame in frames:
        np.testing.assert_array_equal(frame.color, color)
        np.testing.assert_array_equal(frame.depth, depth)
        np.testing.assert_array_equal(frame.stencil, stencil)
