"""The VRM avatar example (``blend_files/vrm_avatar.blend``): the classic VRM sort problems, from numbers.

A stylised avatar (a head of 0.14 m radius at 1.30 m, facing −Y as VRM 1.0 models do in Blender)
whose materials are the VRM Add-on for Blender's MToon materials — written as the add-on 2.20.61
stores them (``blendlib.blender.vrm_addon.write_addon_mtoon``: ID properties and the output node
group's sockets; the armature's ``spec_version`` is VRM 1.0), their Unity settings off, so every
material renders as UniVRM draws the add-on's export. All four MToon modes and both outline modes:

=================  ===========================  ======================================================
material           mode                         what it shows
=================  ===========================  ======================================================
Skin, Eyes, Top,   Opaque (Skin, Shoes: world   drawn first, front to back; the outlines (4 mm in
Shoes, Frame       outline; Top: screen)        world space, 1 % of the screen height) grow their
                                                silhouettes (the outline pass, Cull Front)
Ribbon             Cutout (0.5, double sided)   holes by the alpha test, queue 2450
Hair               Transparent, double sided    cards overlapping themselves in a scrambled order
Eyebrows           Transparent                  drawn over the nearer bangs (object centre nearer)
Eyelashes          Transparent                  drawn over the nearer lenses: the glasses' centre lies
                                                far back (its temples reach the ears)
Lens               Transparent                  (the glasses' second material)
Stockings          Transparent                  hidden behind the skirt, which wrote depth first
Skirt              Transparent With Z-Write     queue 2501, double sided
=================  ===========================  ======================================================

Two scenes share the avatar: ``Avatar`` (the whole figure) and ``AvatarFace`` (a close-up of the
head). ``scripts/export_vrm_avatar.py`` writes the same avatar as ``tests/fixtures/vrm_avatar.vrm``.
"""

from __future__ import annotations

import math

import bpy
import numpy as np
from mathutils import Vector

from blendlib.blender.vrm_addon import write_addon_mtoon, write_armature_spec_version
from blendlib.formats.gltf.vrm_addon import AddonMToon, AddonTexture
from scripts import scenekit

HEAD = Vector((0.0, 0.0, 1.30))
HEAD_RADIUS = 0.14
FACE_CAMERA = (0.22, -1.02, 1.36)
FULL_CAMERA = (0.0, -3.9, 0.74)


# ---------------------------------------------------------------------------- textures (rows: v = 0 first)


def hair_pixels() -> np.ndarray:
    """32x32: four strands across u (alpha 255 at a strand's middle, 96 at its edges), the tips
    (v < 0.25) fading to 0, chestnut getting lighter towards the root."""
    t = np.zeros((32, 32, 4), np.uint8)
    for j in range(32):
        for i in range(32):
            across = abs(((i + 0.5) / 8.0) % 1.0 - 0.5) * 2.0  # 0 in a strand's middle, 1 at its edge
            tip = min(1.0, (j + 0.5) / 8.0)
            t[j, i, :3] = (round(160 + 50 * j / 31), round(95 + 35 * j / 31), round(55 + 15 * j / 31))
            t[j, i, 3] = round((255 - 159 * across) * tip)
    return t


def lash_pixels() -> np.ndarray:
    """32x8: dark spikes (alpha 255) on a line along the bottom rows, clear between them."""
    t = np.zeros((8, 32, 4), np.uint8)
    t[..., :3] = (25, 18, 20)
    t[0:3, :, 3] = 255
    for i in range(0, 32, 4):
        t[3:8, i:i + 2, 3] = 255
    return t


def brow_pixels() -> np.ndarray:
    """16x4: a soft near-black stroke, alpha 230 in the middle rows, 120 at the top and bottom."""
    t = np.zeros((4, 16, 4), np.uint8)
    t[..., :3] = (30, 22, 20)
    t[..., 3] = 230
    t[0, :, 3] = t[3, :, 3] = 120
    return t


def ribbon_pixels() -> np.ndarray:
    """16x16: red with round holes (alpha 0) on a 4-texel grid: the Cutout's alpha test cuts them."""
    t = np.zeros((16, 16, 4), np.uint8)
    for j in range(16):
        for i in range(16):
            hole = (i % 4 - 1.5) ** 2 + (j % 4 - 1.5) ** 2 < 1.2
            t[j, i] = (210, 30, 50, 0 if hole else 255)
    return t


# ---------------------------------------------------------------------------- meshes


def sphere(name: str, center, radius: float, segments=32, rings=20):
    verts, uvs, faces, face_uvs = [], [], [], []
    for r in range(rings + 1):
        phi = math.pi * r / rings
        for s in range(segments + 1):
            theta = 2 * math.pi * s / segments + math.pi  # the seam (duplicated vertices) at the back
            verts.append((center[0] + radius * math.sin(phi) * math.sin(theta),
                          center[1] - radius * math.sin(phi) * math.cos(theta),
                          center[2] + radius * math.cos(phi)))
            uvs.append((s / segments, 1 - r / rings))
    for r in range(rings):
        for s in range(segments):
            a, b = r * (segments + 1) + s, (r + 1) * (segments + 1) + s
            if r == 0:
                face = (a, b, b + 1)  # the pole row: triangles (no zero-area corner)
            elif r == rings - 1:
                face = (a, b, a + 1)
            else:
                face = (a, b, b + 1, a + 1)  # outward normals
            faces.append(face)
            face_uvs.append([uvs[k] for k in face])
    return scenekit.mesh(name, verts, faces, face_uvs, smooth=True)


def frustum(name: str, center_xy, z0: float, z1: float, r0: float, r1: float, segments=24, front_first=False):
    """An open tube from radius r0 at z0 to r1 at z1 (outward normals); ``front_first``: its faces
    ordered from the one facing the camera (−Y) round to the back, so the near half comes first."""
    cx, cy = center_xy
    verts = []
    for s in range(segments):
        theta = 2 * math.pi * s / segments
        for z, r in ((z0, r0), (z1, r1)):
            verts.append((cx + r * math.sin(theta), cy - r * math.cos(theta), z))
    order = list(range(segments))
    if front_first:
        order.sort(key=lambda s: min(s, segments - s))
    faces, face_uvs = [], []
    for s in order:
        a, b = 2 * s, 2 * ((s + 1) % segments)
        faces.append((a, b, b + 1, a + 1))
        face_uvs.append([(s / segments, 0), ((s + 1) / segments, 0), ((s + 1) / segments, 1), (s / segments, 1)])
    return scenekit.mesh(name, verts, faces, face_uvs, smooth=True)


def quads(name: str, rects, normal="-Y"):
    """Axis-aligned quads: ``rects`` of (centre, width, height) in the XZ plane facing ``normal``
    (−Y, towards the camera) or in the YZ plane (``"X"`` / ``"-X"``: width along Y)."""
    verts, faces, face_uvs = [], [], []
    for (cx, cy, cz), w, h in rects:
        k = len(verts)
        if normal == "-Y":
            verts += [(cx - w / 2, cy, cz - h / 2), (cx + w / 2, cy, cz - h / 2), (cx + w / 2, cy, cz + h / 2),
                      (cx - w / 2, cy, cz + h / 2)]
        else:
            sign = 1 if normal == "X" else -1
            verts += [(cx, cy + sign * w / 2, cz - h / 2), (cx, cy - sign * w / 2, cz - h / 2),
                      (cx, cy - sign * w / 2, cz + h / 2), (cx, cy + sign * w / 2, cz + h / 2)]
        faces.append((k, k + 1, k + 2, k + 3))
        face_uvs.append([(0, 0), (1, 0), (1, 1), (0, 1)])
    return scenekit.mesh(name, verts, faces, face_uvs)


def discs(name: str, centers, radius_x: float, radius_z: float, sides=12):
    """Flat elliptic discs facing −Y (triangle fans)."""
    verts, faces, face_uvs = [], [], []
    for cx, cy, cz in centers:
        k = len(verts)
        verts.append((cx, cy, cz))
        for s in range(sides):
            a = 2 * math.pi * s / sides
            verts.append((cx + radius_x * math.cos(a), cy, cz + radius_z * math.sin(a)))
        for s in range(sides):
            face = (k, k + 1 + s, k + 1 + (s + 1) % sides)
            faces.append(face)
            face_uvs.append([(0.5, 0.5), (0.5, 0.5), (0.5, 0.5)])
    return scenekit.mesh(name, verts, faces, face_uvs)


def facing_quad(name: str, center, normal, width: float, height: float):
    """One quad at ``center`` facing ``normal``, its height along the projection of +Z."""
    n = Vector(normal).normalized()
    up = (Vector((0, 0, 1)) - n * n.z).normalized()
    side = up.cross(n)
    c = Vector(center)
    corners = [c - side * width / 2 - up * height / 2, c + side * width / 2 - up * height / 2,
               c + side * width / 2 + up * height / 2, c - side * width / 2 + up * height / 2]
    return scenekit.mesh(name, [tuple(v) for v in corners], [(0, 1, 2, 3)], [[(0, 0), (1, 0), (1, 1), (0, 1)]])


def hair_cards(name: str, cards=24):
    """Cards from the crown down the head: bangs (within 50 degrees of the front) end above the eyes,
    the others fall past the ears to the neck. Neighbouring cards overlap at different radii; the
    faces come card by card in a scrambled order (7k mod 24), so farther cards are often drawn later."""
    verts, faces, face_uvs = [], [], []
    for k in ((7 * c) % cards for c in range(cards)):
        theta = 2 * math.pi * k / cards
        front = abs(math.degrees(math.atan2(math.sin(theta), math.cos(theta)))) < 50
        radius = 0.152 + 0.007 * (k % 3)
        d = Vector((math.sin(theta), -math.cos(theta), 0.0))
        t = Vector((math.cos(theta), math.sin(theta), 0.0))
        path = [HEAD + radius * (math.sin(p) * d + Vector((0, 0, math.cos(p))))
                for p in np.linspace(0.2, 1.2 if front else math.pi / 2, 8)]
        if not front:
            path += [HEAD + radius * d - Vector((0, 0, z)) for z in (0.06, 0.12, 0.18, 0.24)]
        start = len(verts)
        for n, p in enumerate(path):
            half = (0.040 - 0.012 * n / (len(path) - 1))
            verts += [tuple(p - half * t), tuple(p + half * t)]
        for n in range(len(path) - 1):
            a = start + 2 * n
            faces.append((a, a + 1, a + 3, a + 2))
            v0, v1 = 1 - n / (len(path) - 1), 1 - (n + 1) / (len(path) - 1)
            face_uvs.append([(0, v0), (1, v0), (1, v1), (0, v1)])
    return scenekit.mesh(name, verts, faces, face_uvs)


def glasses_mesh(name: str):
    """Two lenses (material slot 1) in a frame with temples back to the ears (slot 0): the object's
    centre lies far behind the lenses."""
    y, z = -0.172, 1.322
    lenses = [((x, y, z), 0.070, 0.048) for x in (-0.052, 0.052)]
    frame = []
    for x in (-0.052, 0.052):
        frame += [((x, y - 0.001, z + 0.027), 0.076, 0.006), ((x, y - 0.001, z - 0.027), 0.076, 0.006),
                  ((x - 0.038, y - 0.001, z), 0.006, 0.05), ((x + 0.038, y - 0.001, z), 0.006, 0.05)]
    frame.append(((0.0, y - 0.001, z + 0.01), 0.03, 0.006))
    temples = [((sx * 0.148, -0.076, z + 0.01), 0.19, 0.006) for sx in (-1, 1)]
    me = quads(name, frame + lenses)
    side = quads(name + " temples", temples, normal="X")
    verts = [v.co[:] for v in me.vertices] + [v.co[:] for v in side.vertices]
    offset = len(me.vertices)
    faces = [tuple(p.vertices) for p in me.polygons] + [tuple(i + offset for i in p.vertices) for p in side.polygons]
    slots = [0] * len(frame) + [1] * len(lenses) + [0] * len(temples)
    uv = [(0, 0), (1, 0), (1, 1), (0, 1)]
    out = scenekit.mesh(name, verts, faces, [uv] * len(faces))
    out.polygons.foreach_set("material_index", slots)
    bpy.data.meshes.remove(me)
    bpy.data.meshes.remove(side)
    return out


# ---------------------------------------------------------------------------- materials


def srgb_to_linear(codes) -> tuple[float, ...]:
    """8-bit sRGB codes → the linear factor the add-on stores (glTF's baseColorFactor is linear)."""
    from blendlib.core import colorspace

    return tuple(colorspace.decode(c / 255) for c in codes)


def mtoon_material(name: str, **settings):
    mat = bpy.data.materials.new(name)
    texture = settings.pop("texture", None)
    if texture is not None:
        settings["base_color_texture"] = AddonTexture(image=texture)  # NEAREST filters: Point, no mipmaps
    mtoon = AddonMToon(name=name, **settings)
    write_addon_mtoon(mat, mtoon)
    return mat


def materials(image) -> dict:
    skin = srgb_to_linear((250, 214, 192)) + (1.0,)
    return {
        "Skin": mtoon_material("Skin", base_color_factor=skin, outline_width_mode="worldCoordinates",
                               outline_width_factor=0.004, outline_color_factor=srgb_to_linear((120, 70, 60))),
        "Eyes": mtoon_material("Eyes", base_color_factor=srgb_to_linear((40, 60, 120)) + (1.0,)),
        "Top": mtoon_material("Top", base_color_factor=srgb_to_linear((50, 60, 110)) + (1.0,),
                              outline_width_mode="screenCoordinates", outline_width_factor=0.01,
                              outline_color_factor=srgb_to_linear((20, 25, 50))),
        "Shoes": mtoon_material("Shoes", base_color_factor=srgb_to_linear((80, 45, 30)) + (1.0,),
                                outline_width_mode="worldCoordinates", outline_width_factor=0.004),
        "Frame": mtoon_material("Frame", base_color_factor=srgb_to_linear((30, 30, 35)) + (1.0,)),
        "Ribbon": mtoon_material("Ribbon", alpha_mode="MASK", alpha_cutoff=0.5, double_sided=True,
                                 texture=image("Ribbon", ribbon_pixels()), mtoon0_render_queue=2450),
        "Hair": mtoon_material("Hair", alpha_mode="BLEND", double_sided=True, texture=image("Hair", hair_pixels()),
                               mtoon0_render_queue=3000),
        "Eyebrows": mtoon_material("Eyebrows", alpha_mode="BLEND", texture=image("Eyebrows", brow_pixels()),
                                   mtoon0_render_queue=3000),
        "Eyelashes": mtoon_material("Eyelashes", alpha_mode="BLEND", texture=image("Eyelashes", lash_pixels()),
                                    mtoon0_render_queue=3000),
        "Lens": mtoon_material("Lens", alpha_mode="BLEND", base_color_factor=(0.25, 0.55, 1.0, 0.35),
                               mtoon0_render_queue=3000),
        "Stockings": mtoon_material("Stockings", alpha_mode="BLEND", base_color_factor=(0.01, 0.01, 0.015, 0.8),
                                    mtoon0_render_queue=3000),
        "Skirt": mtoon_material("Skirt", alpha_mode="BLEND", transparent_with_z_write=True, double_sided=True,
                                base_color_factor=srgb_to_linear((235, 120, 160)) + (0.55,),
                                mtoon0_render_queue=2501),
    }


# ---------------------------------------------------------------------------- the avatar


def build_avatar(collection, image) -> None:
    """Every object of the avatar into ``collection``, parented to a VRM 1.0 armature."""
    mats = materials(image)
    arm_data = bpy.data.armatures.new("Armature")
    write_armature_spec_version(arm_data, "1.0")
    armature = scenekit.add_object(collection, "Armature", arm_data)

    def add(name, mesh, *slots):
        ob = scenekit.add_object(collection, name, mesh)
        for slot in slots:
            ob.data.materials.append(mats[slot])
        ob.parent = armature
        return ob

    add("Head", sphere("Head", HEAD, HEAD_RADIUS), "Skin")
    add("Eyes", discs("Eyes", [(x, -0.1385, 1.318) for x in (-0.05, 0.05)], 0.016, 0.019), "Eyes")
    add("Eyelashes", quads("Eyelashes", [((x, -0.142, 1.338), 0.05, 0.014) for x in (-0.05, 0.05)]), "Eyelashes")
    add("Eyebrows", quads("Eyebrows", [((x, -0.125, 1.378), 0.05, 0.012) for x in (-0.05, 0.05)]), "Eyebrows")
    add("Hair", hair_cards("Hair"), "Hair")
    ribbon_dir = Vector((0.62, -0.3, 0.72)).normalized()
    add("Ribbon", facing_quad("Ribbon", HEAD + 0.176 * ribbon_dir, ribbon_dir, 0.08, 0.055), "Ribbon")
    add("Glasses", glasses_mesh("Glasses"), "Frame", "Lens")
    add("Neck", frustum("Neck", (0, 0), 1.08, 1.20, 0.045, 0.045, 16), "Skin")
    add("Top", frustum("Top", (0, 0), 0.76, 1.12, 0.15, 0.12), "Top")
    for side, sx in (("L", 1), ("R", -1)):
        arm = frustum(f"Arm.{side}", (0, 0), 0.72, 1.08, 0.032, 0.036, 12)
        add(f"Arm.{side}", arm, "Skin").location = (sx * 0.19, 0.0, 0.0)
        add(f"Leg.{side}", frustum(f"Leg.{side}", (sx * 0.085, 0.0), 0.06, 0.74, 0.045, 0.058, 16), "Stockings")
        add(f"Shoe.{side}", frustum(f"Shoe.{side}", (sx * 0.085, -0.02), 0.0, 0.07, 0.06, 0.05, 12), "Shoes")
    add("Skirt", frustum("Skirt", (0, 0), 0.46, 0.80, 0.33, 0.155, 32, front_first=True), "Skirt")


def build(new_file, save, image) -> None:
    """Build and save ``blend_files/vrm_avatar.blend`` with ``make_blend_files``' ``new_file``, ``save``
    and ``image`` helpers (its resolution, clear colour, Sun and World)."""
    full = new_file("Avatar", distance=3.9)
    camera = full.camera
    camera.location = FULL_CAMERA
    sun = next(o for o in full.collection.objects if o.type == "LIGHT")
    avatar = bpy.data.collections.new("Avatar")
    full.collection.children.link(avatar)
    build_avatar(avatar, image)
    face = bpy.data.scenes.new("AvatarFace")
    scenekit.set_resolution(face, full.render.resolution_x, full.render.resolution_y)
    face.render.engine = full.render.engine
    face.view_settings.view_transform = "Standard"
    face.render.dither_intensity = 0.0  # F12 and its saved 8-bit images hold Unity's stored values
    face.world = full.world
    face.collection.children.link(avatar)
    face.collection.objects.link(sun)
    scenekit.add_camera(face, FACE_CAMERA, target=HEAD + Vector((0.0, 0.0, 0.02)), clip=(0.05, 20.0), lens=50.0)
    from blendlib import blender

    blender.write_scene_settings(face, **blender.scene_settings(full))
    save("vrm_avatar")
