"""Build every example scene of ``blend_files/`` from scratch, deterministically.

    .venv/bin/python -m scripts.make_blend_files            # all scenes (from the repository root)
    .venv/bin/python -m scripts.make_blend_files alpha_test # only some

Each ``.blend`` is one experiment of the tutorials ("Unity Shader 入门精要" chapter 8
and the Cg wikibook's blending chapter): open it in Blender, press F12 with the
"Unity Passes" engine, and the phenomenon is in the picture. Everything is made here
from numbers (meshes, packed textures, materials with ``material.unity`` settings),
so running the script twice gives the same scenes. After changing a scene, run
``python -m tests.support.goldens`` to regenerate the golden buffers on purpose.

Scenes are 640x360 at 100 %. Cameras look along +Y from -Y; "up" is +Z; quads and
labels face the camera (normal -Y).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import bpy
import numpy as np
from mathutils import Vector

from blendlib import blender
from scripts import scenekit, unity_builtins, vrm_avatar
from scripts.scenekit import ALPHA_BLEND as BLEND
from scripts.scenekit import QUAD_UV, cube_mesh, quad_mesh, sphere_mesh

ROOT = Path(__file__).resolve().parent.parent

OUT = ROOT / "blend_files"
RES = (640, 360)

#: Whether the add-on is registered (main): the scenes then name the Unity Passes engine.
ADDON = False


# ---------------------------------------------------------------------------
# Scene, camera, light, world
# ---------------------------------------------------------------------------


#: Unity's default camera background, as exact 8-bit codes (no rounding ties), opaque so PNGs are too.
CLEAR = (49 / 255, 77 / 255, 121 / 255, 1.0)


def new_file(name: str, *, distance: float = 10.0, clear=CLEAR, color_space="Gamma",
             sun_dir=(-0.35, -0.75, 0.55), sun_energy=0.8, world=0.04):
    """Empty file with one scene ``name``: camera at (0, -distance, 0) looking +Y, a Sun shining
    from ``sun_dir``, a World of grey ``world``."""
    scene = scenekit.empty_file()
    bpy.context.preferences.filepaths.save_version = 0  # no .blend1 backups
    scene.name = name
    scenekit.set_resolution(scene, *RES)
    if ADDON:
        scene.render.engine = "UNITY_PASSES"
    scene.view_settings.view_transform = "Standard"
    scene.render.dither_intensity = 0.0  # F12 and its saved 8-bit images hold Unity's stored values
    scenekit.add_camera(scene, (0.0, -distance, 0.0), rotation=(math.pi / 2, 0.0, 0.0), clip=(0.5, 50.0), lens=50.0)
    # the unit direction, from which the saved scenes were built (to_track_quat differs in the last bit otherwise)
    scenekit.add_sun(scene, energy=sun_energy, rotation=scenekit.pointing(Vector(sun_dir).normalized(), "Z"),
                     location=(0.0, -6.0, 5.0))
    w = bpy.data.worlds.new("World")
    w.use_nodes = True
    bg = w.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (world, world, world, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    w.color = (world, world, world)
    scene.world = w
    set_scene(scene, color_space=color_space, clear_color=clear)
    return scene


def set_scene(scene, **values) -> None:
    blender.write_scene_settings(scene, **values)


def save(name: str) -> Path:
    OUT.mkdir(exist_ok=True)
    path = OUT / f"{name}.blend"
    for img in bpy.data.images:
        if not img.packed_file:
            img.pack()
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True, relative_remap=False)
    print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size} bytes)")
    return path


# ---------------------------------------------------------------------------
# Textures (byte images, packed; row 0 = bottom = v 0)
# ---------------------------------------------------------------------------


def image(name: str, rgba: np.ndarray):
    """A byte image from an (H, W, 4) array of 8-bit codes, row 0 = bottom."""
    rgba = np.asarray(rgba)
    h, w = rgba.shape[:2]
    img = bpy.data.images.new(name, w, h, alpha=True)
    img.alpha_mode = "STRAIGHT"
    img.pixels.foreach_set((rgba.astype(np.float32) / 255.0).ravel())
    img.pack()
    return img


#: The book's alpha-test texture: four quadrants with alpha 0.2 / 0.45 / 0.7 / 0.95.
QUADRANT_ALPHA = (51, 115, 179, 242)  # codes of 0.2, 0.45, 0.7, 0.95 (u<.5 v<.5, u>=.5 v<.5, u<.5 v>=.5, u>=.5 v>=.5)
QUADRANT_RGB = ((235, 90, 60), (250, 200, 50), (70, 170, 235), (120, 220, 110))


def quadrant_texture():
    """16x16: the four alpha quadrants, each a colour with a 4-texel checker of two shades."""
    t = np.zeros((16, 16, 4), np.uint8)
    for j in range(16):
        for i in range(16):
            q = (1 if i >= 8 else 0) + (2 if j >= 8 else 0)
            shade = 1.0 if ((i // 4) + (j // 4)) % 2 == 0 else 0.78
            t[j, i, :3] = [round(c * shade) for c in QUADRANT_RGB[q]]
            t[j, i, 3] = QUADRANT_ALPHA[q]
    return image("QuadrantAlpha", t)


def stripe_texture():
    """8x8 for the torus: four coloured stripes across v, opaque (alpha comes from _Color)."""
    cols = ((240, 120, 40), (250, 230, 120), (60, 150, 230), (250, 230, 120))
    t = np.zeros((8, 8, 4), np.uint8)
    for j in range(8):
        for i in range(8):
            t[j, i, :3] = cols[(i // 2) % 4]
            t[j, i, 3] = 255
    return image("Stripes", t)


# ---------------------------------------------------------------------------
# Meshes (from numbers; face order = draw order)
# ---------------------------------------------------------------------------


def torus_mesh(name: str, major=1.0, minor=0.38, n_major=40, n_minor=16):
    verts, faces, uvs = [], [], []
    for i in range(n_major):
        a = 2 * math.pi * i / n_major
        for j in range(n_minor):
            b = 2 * math.pi * j / n_minor
            r = major + minor * math.cos(b)
            verts.append((r * math.cos(a), r * math.sin(a), minor * math.sin(b)))
    for i in range(n_major):
        for j in range(n_minor):
            i1, j1 = (i + 1) % n_major, (j + 1) % n_minor
            faces.append((i * n_minor + j, i1 * n_minor + j, i1 * n_minor + j1, i * n_minor + j1))
            u0, u1 = i / n_major, (i + 1) / n_major
            v0, v1 = j / n_minor, (j + 1) / n_minor
            uvs.append(((u0, v0), (u1, v0), (u1, v1), (u0, v1)))
    return scenekit.mesh(name, verts, faces, uvs, smooth=True)


def knot_mesh(name: str, n_path=160, n_ring=12, radius=0.3, scale=0.42):
    """A trefoil-knot tube: the strands cross in front of each other, so one mesh overlaps itself."""

    def curve(t):
        return np.array([math.sin(t) + 2 * math.sin(2 * t), math.cos(t) - 2 * math.cos(2 * t), -math.sin(3 * t)])

    ts = [2 * math.pi * i / n_path for i in range(n_path)]
    pts = [curve(t) * scale for t in ts]
    verts, faces, uvs = [], [], []
    up = np.array([0.0, 0.0, 1.0])
    for i, p in enumerate(pts):
        tangent = pts[(i + 1) % n_path] - pts[i - 1]
        tangent /= np.linalg.norm(tangent)
        side = np.cross(tangent, up)
        if np.linalg.norm(side) < 1e-6:
            side = np.cross(tangent, np.array([1.0, 0.0, 0.0]))
        side /= np.linalg.norm(side)
        other = np.cross(side, tangent)
        for j in range(n_ring):
            b = 2 * math.pi * j / n_ring
            verts.append(tuple(p + radius * (math.cos(b) * side + math.sin(b) * other)))
    for i in range(n_path):
        for j in range(n_ring):
            i1, j1 = (i + 1) % n_path, (j + 1) % n_ring
            faces.append((i * n_ring + j, i * n_ring + j1, i1 * n_ring + j1, i1 * n_ring + j))
            u0, u1 = 3 * i / n_path, 3 * (i + 1) / n_path
            v0, v1 = j / n_ring, (j + 1) / n_ring
            uvs.append(((u0, v0), (u0, v1), (u1, v1), (u1, v0)))
    return scenekit.mesh(name, verts, faces, uvs, smooth=True)


def plank_mesh(name: str, a, b, width: float, rise: float):
    """A flat plank from screen point a to b (XZ), its end b ``rise`` nearer the camera than a."""
    a, b = np.array(a, float), np.array(b, float)
    d = (b - a) / np.linalg.norm(b - a)
    n = np.array([-d[1], d[0]]) * width / 2
    corners = [a - n, b - n, b + n, a + n]
    ys = [rise / 2, -rise / 2, -rise / 2, rise / 2]
    verts = [(c[0], y, c[1]) for c, y in zip(corners, ys, strict=True)]
    # winding so the normal points to -Y (towards the camera)
    v = np.array(verts)
    normal = np.cross(v[1] - v[0], v[2] - v[0])
    face = (0, 1, 2, 3) if normal[1] < 0 else (0, 3, 2, 1)
    return scenekit.mesh(name, verts, [face], [QUAD_UV])


# ---------------------------------------------------------------------------
# Objects and materials
# ---------------------------------------------------------------------------


def obj(name: str, data, location=(0, 0, 0), rotation=(0, 0, 0), scale=(1, 1, 1), material=None, scene=None,
        collection=None):
    """An object linked into ``collection`` (default: the scene's), rotation in degrees; with a
    ``material``, a mesh other objects already use is copied so that each keeps its own."""
    if material is not None and data.users > 0:
        data = data.copy()
        data.name = name
    if collection is None:
        collection = (scene or bpy.context.scene).collection
    ob = scenekit.add_object(collection, name, data, location, rotation, scale)
    if material is not None:
        ob.data.materials.clear()
        ob.data.materials.append(material)
    return ob


def material(name: str, *, queue="Geometry", offset=0, color=(1, 1, 1, 1), tex=None, lighting="Lambert",
             alpha_scale=1.0, cutoff=0.5, passes=(dict(),), filter="Point", wrap="Repeat", **more):
    """A material with ``material.unity`` enabled; ``passes``: dicts of pass properties (``PASS_FIELDS``);
    ``more``: further ``Material.unity`` fields (mipmaps, Preserve Coverage, ...)."""
    return scenekit.unity_material(
        name, queue=queue, queue_offset=offset, color=color, lighting=lighting, alpha_scale=alpha_scale,
        cutoff=cutoff, main_tex_filter=filter, main_tex_wrap=wrap, passes=[dict(p) for p in passes], main_tex=tex,
        **more,
    )


def preset_passes(name: str) -> list[dict]:
    """The passes of a shaderlab preset as dicts of identifiers (color_mask as a letter list)."""
    from blendlib.core.vocabulary import PASS_PRESETS

    out = []
    for p in PASS_PRESETS[name]["passes"]:
        d = {}
        for k, v in p.items():
            d[k] = sorted(v) if k == "color_mask" else (v.value if hasattr(v, "value") else v)
        out.append(d)
    return out


_LABEL_MATS: dict[tuple, object] = {}


def label(text: str, location, size=0.22, color=(1, 1, 1, 1), align="CENTER", name=None, scene=None):
    """A text object facing the camera with an opaque Unlit material (it renders as a mesh)."""
    key = tuple(color)
    if key not in _LABEL_MATS or _LABEL_MATS[key].name not in bpy.data.materials:
        _LABEL_MATS[key] = material("Label {:.2f} {:.2f} {:.2f}".format(*color[:3]), color=color, lighting="Unlit")
    curve = bpy.data.curves.new(name or f"Label {text}", "FONT")
    curve.body = text
    curve.size = size
    curve.align_x = align
    curve.align_y = "CENTER"
    return obj(name or f"Label {text}", curve, location, rotation=(90, 0, 0), material=_LABEL_MATS[key],
               scene=scene)


# ---------------------------------------------------------------------------
# The scenes
# ---------------------------------------------------------------------------

CUTOFFS = (0.1, 0.4, 0.6, 0.9)
CUBE_ROT = (25, 0, 35)


def build_alpha_test():
    """1. Alpha test: the textured cube at four cutoffs; top row Cull Back, bottom row Cull Off."""
    new_file("AlphaTest", distance=11.5)
    tex = quadrant_texture()
    cube = cube_mesh("Cube", 1.0)
    xs = (-2.7, -0.9, 0.9, 2.7)
    for row, (cull, z) in enumerate((("Back", 0.55), ("Off", -1.45))):
        for x, c in zip(xs, CUTOFFS, strict=True):
            m = material(f"AlphaTest {cull} {c}", queue="AlphaTest", tex=tex, cutoff=c,
                         passes=[dict(alpha_test=True, cull=cull)])
            obj(f"Cube {cull} {c}", cube, (x, 0, z), CUBE_ROT, material=m)
            if row == 0:
                label(f"_Cutoff {c}", (x, 0, 1.5), size=0.2)
    label("Alpha Test, Cull Back", (0, 0, 1.95), size=0.2, name="Label row 1")
    label("Alpha Test Both Sided, Cull Off", (0, 0, -0.45), size=0.2, name="Label row 2")
    save("alpha_test")


def build_alpha_blend():
    """2. Alpha blend (ZWrite Off, _AlphaScale 0.5) in front of an opaque cube, in both queue orders."""
    new_file("AlphaBlend", distance=10.0)
    tex = quadrant_texture()
    cube = cube_mesh("Cube", 1.2)
    opaque_ok = material("Opaque B (Geometry)", color=(0.85, 0.85, 0.85, 1))
    opaque_late = material("Opaque B (Transparent+1)", color=(0.85, 0.85, 0.85, 1), queue="Transparent", offset=1)
    glass = material("Alpha Blend A", queue="Transparent", tex=tex, alpha_scale=0.5, passes=[BLEND])
    for side, x, mb, text in ((0, -1.8, opaque_ok, "B then A: correct"),
                              (1, 1.8, opaque_late, "A then B (Transparent+1): B covers A")):
        tag = "Left" if side == 0 else "Right"
        obj(f"B {tag}", cube, (x + 0.35, 1.2, 0.3), (20, 0, 30), material=mb)
        obj(f"A {tag}", cube, (x - 0.35, -0.6, -0.35), (20, 0, -25), material=glass)
        label(text, (x, 0, -1.6), size=0.18)
    save("alpha_blend")


def build_two_transparent():
    """3. Two transparent quads drawn in both orders."""
    new_file("TwoTransparent", distance=10.0)
    q = quad_mesh("Quad", 1.6, 1.6)
    red = (0.95, 0.2, 0.15, 0.5)
    blue = (0.15, 0.35, 0.95, 0.5)
    near_ok = material("Near Red", queue="Transparent", color=red, passes=[BLEND])
    far_ok = material("Far Blue", queue="Transparent", color=blue, passes=[BLEND])
    far_late = material("Far Blue (Transparent+1)", queue="Transparent", offset=1, color=blue, passes=[BLEND])
    for tag, x, far_mat, text in (("Left", -1.8, far_ok, "sorted: far blue, then near red"),
                                  ("Right", 1.8, far_late, "far blue is Transparent+1: inverted")):
        obj(f"Far {tag}", q, (x + 0.45, 1.0, 0.35), (0, 0, 15), material=far_mat)
        obj(f"Near {tag}", q, (x - 0.35, -0.5, -0.25), (0, 0, -10), material=near_ok)
        label(text, (x, 0, -1.6), size=0.17)
    save("two_transparent")


def build_cyclic():
    """4. Three transparent planks overlapping in a cycle: no object order is right."""
    new_file("CyclicOverlap", distance=10.0)
    colors = ((0.95, 0.2, 0.15, 0.6), (0.2, 0.85, 0.25, 0.6), (0.2, 0.4, 0.95, 0.6))
    r = 1.25
    pts = [(r * math.cos(math.radians(90 + 120 * k)), r * math.sin(math.radians(90 + 120 * k)) - 0.15)
           for k in range(3)]
    for k in range(3):
        a, b = np.array(pts[k]), np.array(pts[(k + 1) % 3])
        d = (b - a) / np.linalg.norm(b - a)
        me = plank_mesh(f"Plank {k}", a - 0.55 * d, b + 0.55 * d, 0.55, 1.2)
        m = material(f"Plank {'RGB'[k]}", queue="Transparent", color=colors[k], passes=[BLEND])
        obj(f"Plank {'RGB'[k]}", me, material=m)
    label("each plank is in front of the next one: no order of the three is right", (0, 0, -1.75), size=0.16)
    save("cyclic_overlap")


def build_self_overlap():
    """5. A trefoil knot, ZWrite Off (left) vs with a ZWrite On / ColorMask 0 prepass (right)."""
    new_file("SelfOverlap", distance=10.0)
    tex = stripe_texture()
    knot = knot_mesh("Knot")
    col = (1, 1, 1, 0.55)
    plain = material("Knot ZWrite Off", queue="Transparent", tex=tex, color=col, passes=preset_passes("Alpha Blend"))
    prepass = material("Knot Prepass", queue="Transparent", tex=tex, color=col,
                       passes=preset_passes("Alpha Blend ZWrite"))
    obj("Knot Left", knot, (-1.75, 0, 0.15), (100, 0, 10), material=plain)
    obj("Knot Right", knot, (1.75, 0, 0.15), (100, 0, 10), material=prepass)
    label("ZWrite Off: sorting errors inside the mesh", (-1.75, 0, -1.65), size=0.16)
    label("+ ZWrite On, ColorMask 0 prepass", (1.75, 0, -1.65), size=0.16)
    save("self_overlap")


def build_two_sided():
    """6. Two-sided blending: Cull Front + Cull Back passes | one Cull Off pass | one default pass."""
    new_file("TwoSided", distance=10.0)
    tex = quadrant_texture()
    cube = cube_mesh("Cube", 1.4)
    both = material("Both Sided (2 passes)", queue="Transparent", tex=tex,
                    passes=preset_passes("Alpha Blend Both Sided"))
    off = material("Cull Off (1 pass)", queue="Transparent", tex=tex, passes=[dict(BLEND, cull="Off")])
    back = material("Cull Back (1 pass)", queue="Transparent", tex=tex, passes=[BLEND])
    for x, m, text in ((-2.4, both, "Cull Front, then Cull Back"), (0.0, off, "one pass, Cull Off"),
                       (2.4, back, "one pass, Cull Back")):
        obj(f"Cube {text}", cube, (x, 0, 0.15), (30, 0, 40), material=m)
        label(text, (x, 0, -1.55), size=0.17)
    save("two_sided")


BLEND_MODES = ("Normal", "Premultiplied", "Additive", "Soft Additive", "Multiply",
               "2x Multiply", "Darken", "Lighten", "Screen", "Linear Dodge")


def swatch_texture():
    """8x8: eight colours across u, alpha (row+1)/8 up v."""
    cols = ((230, 60, 50), (240, 150, 40), (240, 230, 60), (90, 210, 80),
            (60, 200, 210), (60, 100, 230), (170, 80, 220), (250, 250, 250))
    t = np.zeros((8, 8, 4), np.uint8)
    for j in range(8):
        for i in range(8):
            t[j, i, :3] = cols[i]
            t[j, i, 3] = 32 * (j + 1) - 1
    return image("Swatches", t)


def background_texture():
    """32x18: a diagonal two-tone checker over a warm-to-cool gradient (opaque)."""
    t = np.zeros((18, 32, 4), np.uint8)
    for j in range(18):
        for i in range(32):
            f = i / 31
            base = np.array([200 - 90 * f, 150 + 40 * math.sin(j / 3), 90 + 140 * f])
            if (i // 2 + j // 2) % 2:
                base = base * 0.55
            t[j, i, :3] = np.clip(np.round(base), 0, 255)
            t[j, i, 3] = 255
    return image("Backdrop", t)


def blend_pass(mode: str) -> dict:
    from blendlib.core.vocabulary import PASS_PRESETS

    name = "Alpha Blend" if mode == "Normal" else mode
    (p,) = PASS_PRESETS[name]["passes"]
    return {k: (v.value if hasattr(v, "value") else v) for k, v in p.items()}


def build_blend_modes():
    """7. The blend-mode catalogue over a textured background, labelled."""
    new_file("BlendModes", distance=10.0)
    back = material("Backdrop", tex=background_texture(), lighting="Unlit")
    obj("Backdrop", quad_mesh("Backdrop", 7.4, 4.2), (0, 1.0, 0), material=back)
    sw = swatch_texture()
    q = quad_mesh("Swatch", 1.15, 1.15)
    for k, mode in enumerate(BLEND_MODES):
        col, row = k % 5, k // 5
        x, z = -2.8 + 1.4 * col, 0.55 - 1.85 * row
        m = material(f"Mode {mode}", queue="Transparent", tex=sw, lighting="Unlit", passes=[blend_pass(mode)])
        obj(f"Mode {k} {mode}", q, (x, 0, z), material=m)
        label(mode, (x, -0.1, z + 0.78), size=0.17, color=(0.02, 0.02, 0.02, 1))
    save("blend_modes")


def build_render_queues():
    """8. Render queues Background..Overlay, an Overlay with ZTest Always, and Transparent+1."""
    new_file("RenderQueues", distance=10.0)
    tex = quadrant_texture()
    sky = material("Background queue (ZWrite Off)", queue="Background", color=(0.33, 0.36, 0.42, 1),
                   lighting="Unlit", passes=[dict(zwrite=False)])
    obj("Backdrop", quad_mesh("Backdrop", 7.6, 3.2), (0, 3.0, 0.15), material=sky)
    solid = material("Geometry queue", color=(0.8, 0.8, 0.8, 1))
    obj("Geometry Cube", cube_mesh("Cube", 1.2), (-2.3, 0.6, 0.2), (25, 0, 35), material=solid)
    cut = material("AlphaTest queue", queue="AlphaTest", tex=tex, cutoff=0.5, passes=[dict(alpha_test=True)])
    obj("AlphaTest Cube", cube_mesh("Cube", 1.2), (-0.55, 0.6, 0.2), (25, 0, 35), material=cut)
    glass = material("Transparent queue", queue="Transparent", color=(0.3, 0.85, 1.0, 0.45), passes=[BLEND])
    obj("Transparent Quad", quad_mesh("Glass", 2.6, 1.0), (-1.45, -1.0, -0.25), material=glass)
    near = material("Transparent (near)", queue="Transparent", color=(0.25, 0.9, 0.3, 0.55), passes=[BLEND])
    far = material("Transparent+1 (far)", queue="Transparent", offset=1, color=(0.95, 0.25, 0.75, 0.55),
                   passes=[BLEND])
    obj("Near Quad", quad_mesh("Small", 1.1, 1.1), (1.35, -0.5, 0.0), (0, 0, 0), material=near)
    obj("Far Quad +1", quad_mesh("Small", 1.1, 1.1), (1.9, 0.5, 0.45), (0, 0, 0), material=far)
    over = material("Overlay queue (ZTest Always)", queue="Overlay", color=(1.0, 0.85, 0.1, 1), lighting="Unlit",
                    passes=[dict(ztest="Always")])
    obj("Overlay Marker", quad_mesh("Marker", 0.5, 0.5), (-1.9, 2.0, 0.25), (0, 0, 0), material=over)
    label("Background (ZWrite Off)", (2.55, 0, 1.45), size=0.15)
    label("Geometry", (-2.3, 0, 1.25), size=0.16)
    label("AlphaTest", (-0.55, 0, 1.25), size=0.16)
    label("Transparent", (-1.45, 0, -1.05), size=0.16)
    label("Overlay, ZTest Always (behind the cubes)", (-1.4, 0, 1.6), size=0.15)
    label("far quad Transparent+1: drawn last", (1.6, 0, -1.05), size=0.15)
    save("render_queues")


def shared_collection(scene, name: str):
    """A new collection ``name`` in ``scene`` holding the scene's objects so far (camera and Sun),
    for a second scene of the file to show too (:func:`second_scene`)."""
    shared = bpy.data.collections.new(name)
    scene.collection.children.link(shared)
    for ob in list(scene.collection.objects):
        scene.collection.objects.unlink(ob)
        shared.objects.link(ob)
    return shared


def second_scene(name: str, first, shared, **settings):
    """Another scene of the file showing collection ``shared`` through ``first``'s camera, world
    and engine, with ``Scene.unity`` ``settings``."""
    scene = bpy.data.scenes.new(name)
    scenekit.set_resolution(scene, *RES)
    scene.render.engine = first.render.engine
    scene.view_settings.view_transform = "Standard"
    scene.render.dither_intensity = 0.0
    scene.world = first.world
    scene.camera = first.camera
    scene.collection.children.link(shared)
    set_scene(scene, **settings)
    return scene


def build_gamma_linear():
    """9. The same semi-transparent stack in Gamma and in Linear colour space (two scenes)."""
    gamma = new_file("Gamma", distance=10.0)
    stack = shared_collection(gamma, "Stack")
    white = material("White", color=(1, 1, 1, 1), lighting="Unlit")
    black = material("Black", color=(0, 0, 0, 1), lighting="Unlit")
    gray = material("Gray 50%", color=(0.5, 0.5, 0.5, 1), lighting="Unlit")

    def put(name, data, loc, mat):
        return obj(name, data, loc, material=mat, collection=stack)

    put("Backdrop White", quad_mesh("Half", 3.4, 3.6), (-1.7, 1.0, 0.0), white)
    put("Backdrop Black", quad_mesh("Half B", 3.4, 3.6), (1.7, 1.0, 0.0), black)
    put("Backdrop Gray", quad_mesh("Strip", 6.8, 0.35), (0, 0.9, -1.6), gray)
    disc = quad_mesh("Disc", 1.5, 1.5)
    cols = ((1, 0, 0, 0.5), (0, 1, 0, 0.5), (0, 0, 1, 0.5))
    offsets = ((-0.45, 0.3), (0.45, 0.3), (0.0, -0.45))
    for k in range(3):
        m = material(f"Stack {'RGB'[k]}", queue="Transparent", color=cols[k], lighting="Unlit", passes=[BLEND])
        for side, cx in (("L", -1.7), ("R", 1.7)):
            put(f"Stack {side}{k} {'RGB'[k]}", disc, (cx + offsets[k][0], -0.2 * (k + 1), offsets[k][1]), m)
    # A black-to-white ramp quad at 50 % over the gray strip: the midtones differ most.
    ramp = image("Ramp", np.array([[[round(255 * i / 15)] * 3 + [255] for i in range(16)]], np.uint8))
    rm = material("Ramp 50%", queue="Transparent", tex=ramp, color=(1, 1, 1, 0.5), lighting="Unlit",
                  passes=[BLEND])
    put("Ramp", quad_mesh("Ramp", 6.8, 0.35), (0, -0.1, -1.6), rm)
    label("Gamma", (0, -0.5, 1.65), size=0.22, name="Label Gamma", scene=gamma)
    linear = second_scene("Linear", gamma, stack, color_space="Linear", clear_color=CLEAR)
    label("Linear", (0, -0.5, 1.65), size=0.22, name="Label Linear", scene=linear)
    save("gamma_linear")


def forward_light(name: str, kind: str, location, color, *, direction=None, power=None, **unity):
    """A Point or Spot light; ``power`` (W) with Unity values derived from it (Light.unity's
    "use Blender values"), else the Unity values ``unity`` stored (intensity, range, spot_angle)."""
    data = bpy.data.lights.new(name, kind)
    data.color = color
    if kind == "SPOT":
        data.spot_size = math.radians(unity.get("spot_angle", 45.0))
    ob = bpy.data.objects.new(name, data)
    ob.location = location
    if direction is not None:
        ob.rotation_euler = scenekit.pointing(Vector(direction).normalized(), "-Z")
    bpy.context.scene.collection.objects.link(ob)
    if power is not None:
        data.energy = power
        data.use_custom_distance, data.cutoff_distance = True, unity["range"]
    else:
        blender.write_light_settings(data, use_blender_values=False, **unity)
    return ob


def build_lights():
    """10. Additional lights: every ForwardAdd pass draws once per per-pixel light, so a transparent
    object under a sun, two point lights and a spot is drawn four times (SPEC §12)."""
    scene = new_file("Lights", distance=10.0, sun_energy=0.35, world=0.05)
    scene.camera.location = (0.0, -8.5, 3.2)
    scene.camera.rotation_euler = (math.radians(70.0), 0.0, 0.0)  # looking down at the floor
    base, add = dict(name="ForwardBase"), dict(name="ForwardAdd", light_mode="ForwardAdd", zwrite=False,
                                               blend=True, src_blend="One", dst_blend="One")
    stone = material("Stone (ForwardBase + ForwardAdd One One)", color=(0.72, 0.72, 0.72, 1), passes=[base, add])
    floor = scenekit.mesh("Floor", [(-6, -4, -1.3), (6, -4, -1.3), (6, 4, -1.3), (-6, 4, -1.3)], [(0, 1, 2, 3)])
    obj("Floor", floor, material=stone)
    obj("Wall", quad_mesh("Wall", 12.0, 6.0), (0, 3.6, 1.7), material=stone)
    glass = material("Glass (SrcAlpha OneMinusSrcAlpha + SrcAlpha One)", queue="Transparent",
                     color=(0.55, 0.75, 1.0, 0.5),
                     passes=[dict(BLEND, name="ForwardBase"), dict(add, src_blend="SrcAlpha", dst_blend="One")])
    obj("Glass Sphere", sphere_mesh("Sphere", 1.0), (-1.6, 0.4, -0.2), material=glass)
    glow = material("Glow (One One + One One)", queue="Transparent", color=(0.45, 0.25, 0.12, 1),
                    passes=[dict(add, name="ForwardBase", light_mode="ForwardBase"), add])
    obj("Glow Torus", torus_mesh("Torus", 0.8, 0.3, 48, 16), (1.7, 0.4, -0.2), (70, 0, 20), material=glow)
    forward_light("Warm Point", "POINT", (-2.6, -0.4, -0.6), (1.0, 0.55, 0.25), power=80.0, range=4.0)
    forward_light("Cool Point", "POINT", (2.7, -0.3, -0.5), (0.35, 0.6, 1.0), intensity=1.8, range=4.0)
    forward_light("Spot", "SPOT", (0.0, -0.6, 3.0), (1.0, 0.95, 0.8), direction=(0.0, 0.4, -1.0), intensity=2.0,
                  range=7.0, spot_angle=40.0)
    label("ForwardAdd: one draw per per-pixel light", (0, 3.4, 1.05), size=0.26)
    save("lights")


#: foliage.blend: the leaf texture's side in texels and the far patches' distance factor.
LEAF_TEXELS, FAR = 64, 8
#: The leaves of the texture: centre (texels), half length, half width (texels), angle (degrees),
#: RGB; narrow, so that box-filtered mip levels lose them (alpha under _Cutoff) within a few levels.
LEAF_SHAPES = (
    ((18, 20), 16, 3.5, 40, (70, 160, 55)), ((44, 16), 15, 3.0, -30, (95, 175, 60)),
    ((30, 44), 18, 4.0, 75, (60, 140, 45)), ((52, 46), 13, 3.0, 20, (110, 185, 70)),
    ((10, 50), 12, 3.0, -55, (80, 165, 50)), ((36, 28), 10, 2.5, 5, (120, 190, 80)),
    ((56, 4), 9, 2.5, 60, (65, 150, 60)), ((4, 30), 11, 3.0, -80, (90, 170, 55)),
)
#: foliage.blend's columns: (label, Material.unity fields, pass fields); every leaf material is Unlit
#: with _Cutoff 0.5 and the Alpha Test queue.
FOLIAGE_COLUMNS = (
    ("no mipmaps", dict(filter="Bilinear"), dict(alpha_test=True)),
    ("mipmaps (Trilinear)", dict(filter="Trilinear", main_tex_mipmaps=True), dict(alpha_test=True)),
    ("+ Preserve Coverage", dict(filter="Trilinear", main_tex_mipmaps=True, main_tex_preserve_coverage=True),
     dict(alpha_test=True)),
    ("AlphaToMask, no clip", dict(filter="Trilinear", main_tex_mipmaps=True, main_tex_preserve_coverage=True),
     dict(alpha_to_mask=True)),
)
FOLIAGE_X = (-2.4, -0.8, 0.8, 2.4)
FOLIAGE_SIZE, NEAR_Z, FAR_Z = 1.4, 0.6, -1.0  # the patches' side and screen heights (at distance 10)


def leaf_texture():
    """LEAF_TEXELS² texels of narrow leaves (:data:`LEAF_SHAPES`, wrapping around so the texture
    tiles): each an ellipse whose alpha is 1 inside and falls linearly to 0 over the outer 35 % of
    its radius (the soft edge AlphaToMask turns into partial coverage); where leaves overlap the
    more opaque one shows; texels outside every leaf are dark green at alpha 0."""
    n = LEAF_TEXELS
    x, y = np.meshgrid(np.arange(n) + 0.5, np.arange(n) + 0.5)
    alpha = np.zeros((n, n))
    rgb = np.broadcast_to(np.array([30.0, 60.0, 25.0]), (n, n, 3)).copy()
    for (cx, cy), length, width, angle, color in LEAF_SHAPES:
        a = math.radians(angle)
        dx, dy = (x - cx + n / 2) % n - n / 2, (y - cy + n / 2) % n - n / 2
        along, across = dx * math.cos(a) + dy * math.sin(a), -dx * math.sin(a) + dy * math.cos(a)
        leaf = np.clip((1.0 - np.sqrt((along / length) ** 2 + (across / width) ** 2)) / 0.35, 0.0, 1.0)
        shade = 0.75 + 0.25 * np.clip(along / length, -1.0, 1.0) ** 2  # lighter towards the tips
        rgb = np.where((leaf > alpha)[..., None], np.array(color, float) * shade[..., None], rgb)
        alpha = np.maximum(alpha, leaf)
    texels = np.concatenate([np.round(rgb), np.round(alpha * 255)[..., None]], axis=-1)
    return image("Leaves", texels.astype(np.uint8))


def leaf_patch_mesh(name: str, size: float, repeats: float):
    """A size x size quad facing the camera whose UVs run 0..``repeats`` (the texture tiled)."""
    x = size / 2
    uv = tuple((u * repeats, v * repeats) for u, v in QUAD_UV)
    return scenekit.mesh(name, [(-x, 0, -x), (x, 0, -x), (x, 0, x), (-x, 0, x)], [(0, 1, 2, 3)], [uv])


def build_foliage():
    """13. Alpha-tested leaves near and far: without mipmaps, with mipmaps, with Preserve Coverage and
    with AlphaToMask, in a scene without MSAA (``Foliage``) and one with MSAA 4x (``FoliageMSAA``)."""
    plain = new_file("Foliage", distance=10.0)
    plain.camera.data.clip_end = 10.0 * FAR + 40.0
    patch = shared_collection(plain, "Leaves")
    tex = leaf_texture()
    near = leaf_patch_mesh("Near Patch", FOLIAGE_SIZE, 1.0)
    # FAR times farther from the camera and FAR times larger, with leaves of the same size in the
    # world: the same screen size, FAR times the texels per pixel.
    far = leaf_patch_mesh("Far Patch", FOLIAGE_SIZE * FAR, FAR)
    for (text, fields, pass_fields), x in zip(FOLIAGE_COLUMNS, FOLIAGE_X, strict=True):
        m = material(f"Leaves {text}", queue="AlphaTest", tex=tex, lighting="Unlit", cutoff=0.5,
                     passes=[pass_fields], **fields)
        obj(f"Near {text}", near, (x, 0.0, NEAR_Z), material=m, collection=patch)
        obj(f"Far {text}", far, (x * FAR, 10.0 * (FAR - 1), FAR_Z * FAR), material=m, collection=patch)
    foliage_labels(plain, "MSAA off")
    msaa = second_scene("FoliageMSAA", plain, patch, color_space="Gamma", clear_color=CLEAR, msaa=4)
    foliage_labels(msaa, "MSAA 4x")
    save("foliage")


def foliage_labels(scene, msaa: str) -> None:
    """The column captions and the bottom line of one foliage scene (labels are per scene)."""
    for (text, _, _), x in zip(FOLIAGE_COLUMNS, FOLIAGE_X, strict=True):
        label(text, (x, -0.5, 1.58), size=0.15, name=f"Label {text} ({msaa})", scene=scene)
    label(f"{msaa} - top: near, bottom: {FAR}x farther and larger (same leaves)", (0, -0.5, -1.85), size=0.15,
          name=f"Label {msaa}", scene=scene)


SCENES = {
    "alpha_test": build_alpha_test,
    "alpha_blend": build_alpha_blend,
    "two_transparent": build_two_transparent,
    "cyclic_overlap": build_cyclic,
    "self_overlap": build_self_overlap,
    "two_sided": build_two_sided,
    "blend_modes": build_blend_modes,
    "render_queues": build_render_queues,
    "gamma_linear": build_gamma_linear,
    "lights": build_lights,
    "vrm_avatar": lambda: vrm_avatar.build(new_file, save, image),  # 11: scripts/vrm_avatar.py
    "unity_builtins": lambda: unity_builtins.build(new_file, save, image, label),  # 12: scripts/unity_builtins.py
    "foliage": build_foliage,
}


def main(argv: list[str]) -> int:
    global ADDON
    ADDON = scenekit.register_addon("make_blend_files")
    names = argv or list(SCENES)
    for name in names:
        if name not in SCENES:
            print(f"unknown scene {name!r}; choose from {', '.join(SCENES)}", file=sys.stderr)
            return 2
        _LABEL_MATS.clear()
        SCENES[name]()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
