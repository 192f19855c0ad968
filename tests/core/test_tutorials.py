"""The tutorials' numbers (shared/seeds: the book's chapter 8 and the Cg wikibook's blending chapter).

Hand-computed 8-bit results of the blend-mode catalogue on known inputs, the
render-order experiments, the ZWrite prepass fixing self-overlap, and two-sided
blending as Cull Front then Cull Back. Each check runs on the core and on the
scalar reference.

Inputs of the catalogue (Gamma, LDR, Unlit, one full-frame quad over the clear):
source S = (0.8, 0.6, 0.32, 0.4), i.e. 255*S = (204, 153, 81.6, 102); destination
= the clear colour stored as the codes D = (50, 100, 150, 120). A result v is
stored as floor(255*v + 0.5); below, every number is in units of 1/255.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from blendlib import render_scene
from blendlib.core.vocabulary import ColorSpace, Cull, Lighting, Material, Queue, preset
from tests.reference import scenes as sc
from tests.reference.scalar import render_reference


def _core(scene):
    f = render_scene(scene)
    return f.color, f.depth, f.stencil


IMPLS = {"core": _core, "reference": render_reference}
impl = pytest.fixture(params=list(IMPLS))(lambda request: IMPLS[request.param])

S = (0.8, 0.6, 0.32, 0.4)
D_CODES = (50, 100, 150, 120)
CLEAR = tuple(c / 255 for c in D_CODES)

# preset -> expected codes, computed by hand (units of 1/255):
CATALOGUE = {
    # Blend SrcAlpha OneMinusSrcAlpha: S*0.4 + D*0.6
    # r 204*.4+50*.6 = 111.6, g 61.2+60 = 121.2, b 32.64+90 = 122.64, a 40.8+72 = 112.8
    "Alpha Blend": (112, 121, 123, 113),
    # Blend One OneMinusSrcAlpha: S + D*0.6: 204+30, 153+60, 81.6+90 = 171.6, 102+72
    "Premultiplied": (234, 213, 172, 174),
    # Blend One One: S + D: 254, 253, 231.6, 222
    "Additive": (254, 253, 232, 222),
    "Linear Dodge": (254, 253, 232, 222),
    # Blend OneMinusDstColor One: S*(1-D) + D: 204*205/255+50 = 214, 153*155/255+100 = 193,
    # 81.6*105/255+150 = 183.6, alpha 102*135/255+120 = 174
    "Soft Additive": (214, 193, 184, 174),
    # Blend DstColor Zero: S*D: 204*50/255 = 40, 153*100/255 = 60, 81.6*150/255 = 48, 102*120/255 = 48
    "Multiply": (40, 60, 48, 48),
    # Blend DstColor SrcColor: 2*S*D
    "2x Multiply": (80, 120, 96, 96),
    # BlendOp Min: min(S, D)
    "Darken": (50, 100, 82, 102),
    # BlendOp Max: max(S, D)
    "Lighten": (204, 153, 150, 120),
    # Blend One OneMinusSrcColor: S + D*(1-S): 204+10, 153+40, 81.6+102, 102+72 (= Soft Additive here,
    # the book's "equivalently")
    "Screen": (214, 193, 184, 174),
}


def _catalogue_scene(name, hdr=False):
    queue, passes = preset(name)
    mat = Material(color=S, queue=queue, passes=passes, lighting=Lighting.Unlit)
    return sc.scene(sc.screen_camera(4, 4), sc.renderer(sc.quad(0, 0, 4, 4, z=0.2), mat), clear_color=CLEAR, hdr=hdr)


@pytest.mark.parametrize("name", list(CATALOGUE))
def test_blend_catalogue_8bit(impl, name):
    color, _, _ = impl(_catalogue_scene(name))
    codes = np.rint(color * 255).astype(int)
    assert np.all(codes == np.array(CATALOGUE[name])), f"{name}: {codes[0, 0].tolist()}"
    assert np.all(color == np.float32(np.array(CATALOGUE[name]) / 255.0))


def test_blend_catalogue_hdr_is_unclamped(impl):
    """HDR: Additive keeps 0.8 + 50/255 = 0.99607..., and 2x Multiply stores float32(2*S*D) exactly."""
    color, _, _ = impl(_catalogue_scene("Additive", hdr=True))
    assert np.all(color[..., 0] == np.float32(0.8 + np.float32(50 / 255)))
    scene = _catalogue_scene("Additive", hdr=True)
    scene = type(scene)(camera=scene.camera, renderers=scene.renderers, hdr=True,
                        clear_color=(0.7, 0.9, 0.95, 0.8))
    color, _, _ = impl(scene)
    assert np.allclose(color[0, 0], [1.5, 1.5, 1.27, 1.2], atol=1e-6)  # above 1: no clamp


def test_blend_linear_space_normal(impl):
    """Linear, LDR: blending happens on decoded values and is encoded on write (an sRGB framebuffer).
    Clear 0.5 (encoded) -> linear 0.21404; source _Color (1,1,1,0.5) -> linear 1; Normal blend:
    0.5*1 + 0.5*0.21404 = 0.60702 linear -> encoded 0.80272 -> code 205 (204.69). In Gamma the
    same inputs give 0.5*1 + 0.5*(128/255) = 0.75098 -> 192 (191.5 + 0.5 floors to 192)."""
    queue, passes = preset("Alpha Blend")
    mat = Material(color=(1, 1, 1, 0.5), queue=queue, passes=passes, lighting=Lighting.Unlit)
    for space, expected in (("Linear", 205), ("Gamma", 192)):
        scene = sc.scene(sc.screen_camera(2, 2), sc.renderer(sc.quad(0, 0, 2, 2), mat),
                         clear_color=(0.5, 0.5, 0.5, 1.0), color_space=ColorSpace(space))
        color, _, _ = impl(scene)
        assert np.all(np.rint(color[..., :3] * 255) == expected), (space, color[0, 0] * 255)


# --------------------------------------------------------------------- render order (chapter 8)

RED = (1.0, 0.0, 0.0, 0.5)
BLUE = (0.0, 0.0, 1.0, 0.5)


def _two(first_queue_offset, near_mat, far_mat):
    cam = sc.screen_camera(6, 6)
    return sc.scene(cam, sc.renderer(sc.quad(0, 0, 6, 6, z=1.0), near_mat, name="A_near"),
                    sc.renderer(sc.quad(0, 0, 6, 6, z=-1.0), far_mat, name="B_far"),
                    clear_color=(0, 0, 0, 0))


def test_transparent_in_front_of_opaque(impl):
    """Opaque B (queue Geometry) is drawn first whatever the list order; transparent A blends over it:
    0.5*red + 0.5*blue -> (128, 0, 128); alpha 0.5*0.5 + 1*0.5 = 0.75 -> 191 (191.25)."""
    _, passes = preset("Alpha Blend")
    a = Material(name="A", color=RED, queue=Queue.Transparent, passes=passes, lighting=Lighting.Unlit)
    b = Material(name="B", color=(0, 0, 1, 1), lighting=Lighting.Unlit)
    color, _, _ = impl(_two(0, a, b))
    assert np.all(np.rint(color * 255) == [128, 0, 128, 191])


def test_transparent_drawn_before_opaque_is_overwritten(impl):
    """The book's wrong order: A (ZWrite Off) drawn first, then opaque B behind it: B's depth test
    passes (A wrote no depth) and B overwrites A: pure blue."""
    _, passes = preset("Alpha Blend")
    a = Material(name="A", color=RED, queue=Queue.Background, passes=passes, lighting=Lighting.Unlit)
    b = Material(name="B", color=(0, 0, 1, 1), lighting=Lighting.Unlit)
    color, _, _ = impl(_two(0, a, b))
    assert np.all(np.rint(color * 255) == [0, 0, 255, 255])


def test_two_transparent_surfaces_both_orders(impl):
    """Back to front (B then A): after B (0, 0, 128, 64); after A r = 0.5 -> 128, b = 64/255*... -> 64,
    a = 0.25 + 64/255*0.5 -> 96 (95.75): (128, 0, 64, 96). Forced front to back (A's queue lower):
    (64, 0, 128, 96) — the sorting artefact."""
    _, passes = preset("Alpha Blend")
    a = Material(name="A", color=RED, queue=Queue.Transparent, passes=passes, lighting=Lighting.Unlit)
    b = Material(name="B", color=BLUE, queue=Queue.Transparent, passes=passes, lighting=Lighting.Unlit)
    color, _, _ = impl(_two(0, a, b))
    assert np.all(np.rint(color * 255) == [128, 0, 64, 96])
    b_later = Material(name="B", color=BLUE, queue=Queue.Transparent, queue_offset=1, passes=passes,
                       lighting=Lighting.Unlit)
    color, _, _ = impl(_two(0, a, b_later))
    assert np.all(np.rint(color * 255) == [64, 0, 128, 96])


# --------------------------------------------------------------------- ZWrite prepass


def _self_overlapping(preset_name):
    """One mesh, two overlapping layers in triangle order near then far (the drawing order the
    tutorial's "knot" produces). Colour red alpha 0.4 over a blue clear."""
    near = sc.quad(1, 1, 7, 7, z=1.0)
    far = sc.quad(1, 1, 7, 7, z=-1.0)
    pos = np.concatenate([near.positions, far.positions])
    tri = np.concatenate([near.triangles, far.triangles + 4])
    mesh = sc.make_mesh(pos, tri)
    queue, passes = preset(preset_name)
    mat = Material(color=(1, 0, 0, 0.4), queue=queue, passes=passes, lighting=Lighting.Unlit)
    return sc.scene(sc.screen_camera(8, 8), sc.renderer(mesh, mat), clear_color=(0, 0, 1, 1))


def test_zwrite_off_self_overlap_blends_twice(impl):
    """Alpha Blend (ZWrite Off): both layers blend. Once: r 0.4 -> 102, b 0.6 -> 153, a 0.16+0.6 -> 194
    (193.8). Twice: r 102 + 102*0.6 = 163.2 -> 163, b 153*0.6 = 91.8 -> 92, a 40.8 + 194*0.6 = 157.2 -> 157."""
    color, _, _ = impl(_self_overlapping("Alpha Blend"))
    assert np.all(np.rint(color[2:6, 2:6] * 255) == [163, 0, 92, 157])


def test_zwrite_prepass_removes_self_overlap(impl):
    """Alpha Blend ZWrite: the ColorMask 0 prepass writes the nearest depth, the blend pass (LEqual)
    only draws the nearest layer: blended exactly once, (102, 0, 153, 194); the prepass changed no colour."""
    color, depth, _ = impl(_self_overlapping("Alpha Blend ZWrite"))
    assert np.all(np.rint(color[1:7, 1:7] * 255) == [102, 0, 153, 194])
    assert np.all(np.rint(color[0] * 255) == [0, 0, 255, 255])
    # the depth of the near layer (z = 1: window depth (10 - 1) / 20 = 0.45)
    assert np.all(np.abs(depth[1:7, 1:7] - 0.45) < 1e-6)


# --------------------------------------------------------------------- two-sided blending


def test_cull_front_then_back_equals_back_faces_then_front_faces(impl):
    """Alpha Blend Both Sided on a closed cube == drawing its back faces, then its front faces, in two
    renderers; inside the silhouette every pixel is front over (back over clear):
    back: (112, 121, 123, 113) as in the catalogue; front over it: 204*.4 + 112*.6 = 148.8 -> 149,
    61.2 + 72.6 = 133.8 -> 134, 32.64 + 73.8 = 106.44 -> 106, 40.8 + 67.8 = 108.6 -> 109."""
    cam = sc.camera(20, 20, eye=(2.2, 1.7, 3.0))
    cube = sc.cube(1.6)
    queue, passes = preset("Alpha Blend Both Sided")
    assert [p.cull for p in passes] == [Cull.Front, Cull.Back]
    both = Material(color=S, queue=queue, passes=passes, lighting=Lighting.Unlit)
    color, _, _ = impl(sc.scene(cam, sc.renderer(cube, both), clear_color=CLEAR))

    # The same by hand: split the cube's triangles by their facing towards the camera (the cube is
    # convex, so a triangle faces the camera iff its outward normal points to the eye).
    pos = np.asarray(cube.positions)
    tri = np.asarray(cube.triangles)
    normals = np.cross(pos[tri[:, 1]] - pos[tri[:, 0]], pos[tri[:, 2]] - pos[tri[:, 0]])
    facing = np.einsum("ij,ij->i", normals, np.array([2.2, 1.7, 3.0]) - pos[tri[:, 0]]) > 0
    _, (blend,) = preset("Alpha Blend")
    off = replace(blend, cull=Cull.Off)
    mat = Material(color=S, queue=queue, passes=(off,), lighting=Lighting.Unlit)
    back = sc.make_mesh(pos, tri[~facing])
    front = sc.make_mesh(pos, tri[facing])
    manual = sc.scene(cam, sc.renderer(back, mat, name="a_back"),
                      sc.renderer(front, Material(color=S, queue=queue, queue_offset=1, passes=(off,),
                                                  lighting=Lighting.Unlit), name="b_front"),
                      clear_color=CLEAR)
    color2, _, _ = impl(manual)
    assert np.array_equal(color, color2)
    codes = np.rint(color * 255).astype(int)
    inside = np.any(codes != np.array(D_CODES), axis=-1)
    assert inside.sum() > 60
    assert np.all(codes[inside] == [149, 134, 106, 109])
