"""A case's Blender scene, built inside a worker with :mod:`scripts.scenekit` (bpy).

Every scene is a real Blender scene, so that every backend starts from the same data: the
project extracts a DrawScene from it, OpenGL draws that DrawScene, EEVEE and Workbench render the
scene. Materials carry Unity settings for the first two and a Principled BSDF of the same colour
and alpha for EEVEE (blended when transparent, backface culling as the pass's ``Cull``);
Workbench draws their viewport colour.
"""

from __future__ import annotations

import math

import bpy
import numpy as np

from blendlib.core import colorspace
from scripts import scenekit


def build_case(case: dict):
    """Build the case's Blender scene in this process (a ``blend`` case opens its file, the others
    start from an empty file); returns the scene."""
    if case["kind"] == "blend":
        bpy.ops.wm.open_mainfile(filepath=case["path"], load_ui=False)
        scene = bpy.data.scenes[case["scene"]] if case.get("scene") else bpy.context.scene
        _render_settings(scene, case["width"], case["height"])
        _unity_settings(scene, case)
        return scene

    scene = scenekit.empty_file()
    _render_settings(scene, case["width"], case["height"])
    scene.world.color = (0.05, 0.05, 0.05)
    scenekit.add_sun(scene, energy=2.0, rotation=(0.6, 0.2, 0.8))
    builders = {"sphere": _sphere, "planes": _planes, "planes-perspective": _planes_perspective, "monkey": _monkey,
                "particles": _particles}
    if case["kind"] not in builders:
        raise ValueError(f"unknown case kind {case['kind']!r}")
    builders[case["kind"]](scene, case, case["width"], case["height"])
    _unity_settings(scene, case)
    bpy.context.view_layer.update()
    return scene


def _unity_settings(scene, case: dict) -> None:
    """The case's MSAA samples (``msaa``) and colour space (``color_space``) in the scene's Unity settings."""
    from blendlib import blender

    values = {}
    if case.get("msaa", 1) > 1:
        values["msaa"] = int(case["msaa"])
    if case.get("color_space"):
        values["color_space"] = case["color_space"]
    if values:
        blender.write_scene_settings(scene, **values)


def _render_settings(scene, width: int, height: int) -> None:
    """The frame every backend renders: ``width`` x ``height`` at 100 %, no compositing or
    sequencer (EEVEE and Workbench then do only the render), a World, one EEVEE sample."""
    scenekit.set_resolution(scene, width, height)
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    if scene.world is None:
        scene.world = bpy.data.worlds.new("World")
    scene.eevee.taa_render_samples = 1


def _material(name: str, color_linear, alpha: float, *, transparent: bool, cull: str):
    """Lambert, opaque (Geometry queue) or alpha-blended (Transparent queue) with ``Cull cull``;
    ``_Color`` is ``color_linear`` sRGB-encoded, as Unity stores it."""
    color = tuple(colorspace.encode(c) for c in color_linear) + (alpha,)
    passes = [dict(scenekit.ALPHA_BLEND, cull=cull)] if transparent else [dict(cull=cull)]
    mat = scenekit.unity_material(name, queue="Transparent" if transparent else "Geometry", color=color,
                                  lighting="Lambert", passes=passes)
    # The same look for EEVEE: the Principled BSDF's Base Color and Alpha, blended when transparent.
    mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Base Color"].default_value = (*color_linear, 1.0)
    bsdf.inputs["Alpha"].default_value = alpha
    mat.surface_render_method = "BLENDED" if transparent else "DITHERED"
    mat.use_backface_culling = cull != "Off"
    return mat


def uv_sphere_mesh(name: str, k: int):
    """A unit UV sphere with ``2k`` segments and ``k + 1`` rings (``4k²`` triangles), normals outwards.
    Built from arrays with ``foreach_set`` (``bmesh.ops.create_uvsphere`` is far slower at S1's size)."""
    nlon, nlat = 2 * k, k + 1
    lat = np.pi * np.arange(1, nlat) / nlat  # polar angles of the nlat - 1 vertex rings
    lon = 2 * np.pi * np.arange(nlon) / nlon
    st, ct = np.sin(lat)[:, None], np.cos(lat)[:, None]
    ring = np.stack([st * np.cos(lon), st * np.sin(lon), np.broadcast_to(ct, (nlat - 1, nlon))], -1)
    co = np.concatenate([[[0.0, 0.0, 1.0]], ring.reshape(-1, 3), [[0.0, 0.0, -1.0]]]).astype(np.float32)
    top, bottom = 0, len(co) - 1
    idx = 1 + np.arange((nlat - 1) * nlon).reshape(nlat - 1, nlon)
    nxt = np.roll(idx, -1, axis=1)
    caps_top = np.stack([np.full(nlon, top), idx[0], nxt[0]], -1)
    caps_bottom = np.stack([np.full(nlon, bottom), nxt[-1], idx[-1]], -1)
    quads = np.stack([idx[:-1], idx[1:], nxt[1:], nxt[:-1]], -1).reshape(-1, 4)
    loops = np.concatenate([caps_top.ravel(), quads.ravel(), caps_bottom.ravel()]).astype(np.int32)
    sizes = np.concatenate([np.full(nlon, 3), np.full(len(quads), 4), np.full(nlon, 3)]).astype(np.int32)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int32)
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(co))
    me.vertices.foreach_set("co", co.ravel())
    me.loops.add(len(loops))
    me.loops.foreach_set("vertex_index", loops)
    me.polygons.add(len(sizes))
    me.polygons.foreach_set("loop_start", starts)
    me.update()
    me.validate(verbose=False)
    return me


def _sphere(scene, case: dict, w: int, h: int) -> None:
    """S1 and the scaling series: the sphere, alpha-blended both sides, filling ``case["fill"]`` of the frame."""
    me = uv_sphere_mesh("Sphere", int(case["k"]))
    me.shade_smooth()
    obj = scenekit.add_object(scene.collection, "Sphere", me)
    obj.data.materials.append(_material("Glass", (0.2, 0.45, 1.0), 0.5, transparent=True, cull="Off"))
    # Silhouette radius r_px = f_px / sqrt(d² - 1) with the 50 mm lens on the 36 mm sensor (width fit).
    f_px = 50.0 / 36.0 * max(w, h)
    r_px = math.sqrt(case["fill"] * w * h / math.pi)
    d = math.sqrt((f_px / r_px) ** 2 + 1.0)
    scenekit.add_camera(scene, (0.0, -d, 0.0), target=(0.0, 0.0, 0.0))


def _lcg(seed: int):
    """The states after ``seed`` of a linear congruential generator (in [0, 2**31)): the same
    numbers on every machine."""
    while True:
        seed = (seed * 1103515245 + 12345) % 2**31
        yield seed


def _planes(scene, case: dict, w: int, h: int) -> None:
    """S2: ``count`` planes, each exactly half of an orthographic frame, stacked towards the camera."""
    # Orthographic camera looking down -Z; frame = 16 x 9 units; each plane 8 x 9 (half the frame).
    me = scenekit.mesh("Plane", [(-4, -4.5, 0), (4, -4.5, 0), (4, 4.5, 0), (-4, 4.5, 0)], [(0, 1, 2, 3)])
    me.materials.append(_material("Veil", (1.0, 0.5, 0.2), 0.1, transparent=True, cull="Back"))
    states = _lcg(12345)
    for i in range(int(case["count"])):
        x = (next(states) / 2**31 - 0.5) * 8.0  # centre in [-4, 4]: the plane stays inside the frame
        scenekit.add_object(scene.collection, f"Plane.{i:03d}", me, location=(x, 0.0, i * 0.05))
    scenekit.add_camera(scene, (0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0),
                        ortho_scale=16.0 * max(1.0, (16 / 9) / (w / h)))


def _planes_perspective(scene, case: dict, w: int, h: int) -> None:
    """S2p: the S2 planes through a 50 mm perspective camera at the origin looking down -Z; each
    plane at a depth in [2, 8], tilted up to 35 degrees about X and Y and turned up to 20 degrees
    about Z, sized to 90 % of the frustum at its depth and shifted by up to 10 %: each covers most
    of the frame, with perspective-correct interpolation."""
    me = scenekit.mesh("Plane", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2, 3)])
    me.materials.append(_material("Veil", (1.0, 0.5, 0.2), 0.1, transparent=True, cull="Back"))
    half_w = 18.0 / 50.0  # frustum half-width per unit of depth (36 mm sensor, width fit)
    aspect = h / w
    states = _lcg(54321)

    def uniform(lo: float, hi: float) -> float:
        return lo + (hi - lo) * next(states) / 2**31

    for i in range(int(case["count"])):
        depth = uniform(2.0, 8.0)
        hw, hh = half_w * depth, half_w * depth * aspect
        scenekit.add_object(scene.collection, f"Plane.{i:03d}", me,
                            location=(uniform(-0.1, 0.1) * hw, uniform(-0.1, 0.1) * hh, -depth),
                            rotation=(uniform(-35, 35), uniform(-35, 35), uniform(-20, 20)),
                            scale=(0.9 * hw, 0.9 * hh, 1.0))
    scenekit.add_camera(scene, (0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0))


def _monkey(scene, case: dict, w: int, h: int) -> None:
    """S4: Suzanne under a Subdivision Surface modifier of ``levels`` (viewport and render), opaque."""
    bpy.ops.mesh.primitive_monkey_add(size=2.0)
    obj = bpy.context.object
    mod = obj.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = mod.render_levels = int(case["levels"])
    obj.data.shade_smooth()
    obj.data.materials.append(_material("Clay", (0.8, 0.6, 0.5), 1.0, transparent=False, cull="Back"))
    scenekit.add_camera(scene, (0.0, -6.5, 0.4), target=(0.0, 0.0, 0.0))


def _sprite_texture():
    """32 x 32 soft round particle sprite: white, alpha falling from 1 at the centre to 0 at the rim."""
    n = 32
    c = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    r = np.sqrt(c[None, :] ** 2 + c[:, None] ** 2)
    alpha = np.clip(1.0 - r, 0.0, 1.0) ** 1.5
    img = bpy.data.images.new("ParticleSprite", n, n, alpha=True)
    img.alpha_mode = "STRAIGHT"
    rgba = np.ones((n, n, 4), np.float32)
    rgba[..., 3] = np.round(alpha * 255.0) / 255.0
    img.pixels.foreach_set(rgba.ravel())
    img.pack()
    return img


def _particle_material(name: str, dst_blend: str, sprite):
    """Unity's legacy Particles/Alpha Blended (``Blend SrcAlpha OneMinusSrcAlpha``) or Particles/Additive
    (``Blend SrcAlpha One``): ``Cull Off Lighting Off ZWrite Off``, Transparent queue,
    ``2 * i.color * _TintColor * tex`` (the shaders' text)."""
    mat = scenekit.unity_material(name, queue="Transparent", main_tex=sprite, vertex_color="Particle",
                                  lighting="Unlit", tint_color=(0.5, 0.5, 0.5, 0.5),
                                  passes=[dict(blend=True, zwrite=False, cull="Off", src_blend="SrcAlpha",
                                               dst_blend=dst_blend)])
    mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Alpha"].default_value = 0.5
    mat.surface_render_method = "BLENDED"
    mat.use_backface_culling = False
    return mat


def particle_quads_mesh(name: str, count: int, seed: int, eye, size_range=(0.05, 0.2)):
    """``count`` quads facing the point ``eye`` (camera-facing billboards, as a particle system's
    renderer builds them), centred at random in a 6 x 4 x 4 box around the origin, with UVs over
    the whole sprite and random vertex colours (a "Col" byte colour attribute, alpha 0.3-1).
    Positions from :func:`_lcg` (the same on every machine)."""
    states = _lcg(seed)
    r = np.array([next(states) for _ in range(count * 8)], np.float64).reshape(count, 8) / 2**31
    centre = np.stack([(r[:, 0] - 0.5) * 6.0, (r[:, 1] - 0.5) * 4.0, (r[:, 2] - 0.5) * 4.0], -1)
    half = (size_range[0] + (size_range[1] - size_range[0]) * r[:, 3]) * 0.5
    to_eye = np.asarray(eye, np.float64) - centre
    to_eye /= np.linalg.norm(to_eye, axis=1, keepdims=True)
    right = np.cross(np.array([0.0, 0.0, 1.0]), to_eye)
    right /= np.linalg.norm(right, axis=1, keepdims=True)
    up = np.cross(to_eye, right)
    corners = np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)], np.float64)
    co = (centre[:, None, :] + half[:, None, None] * (corners[None, :, 0, None] * right[:, None, :]
                                                       + corners[None, :, 1, None] * up[:, None, :]))
    me = bpy.data.meshes.new(name)
    me.vertices.add(count * 4)
    me.vertices.foreach_set("co", co.astype(np.float32).ravel())
    me.loops.add(count * 4)
    me.loops.foreach_set("vertex_index", np.arange(count * 4, dtype=np.int32))
    me.polygons.add(count)
    me.polygons.foreach_set("loop_start", np.arange(0, count * 4, 4, dtype=np.int32))
    uv = me.uv_layers.new(name="UVMap")
    uv.uv.foreach_set("vector", np.tile(np.array([0, 0, 1, 0, 1, 1, 0, 1], np.float32), count))
    col = me.color_attributes.new("Col", "BYTE_COLOR", "CORNER")
    rgba = np.stack([0.2 + 0.8 * r[:, 4], 0.2 + 0.8 * r[:, 5], 0.2 + 0.8 * r[:, 6], 0.3 + 0.7 * r[:, 7]], -1)
    col.data.foreach_set("color", np.repeat(rgba, 4, axis=0).astype(np.float32).ravel())
    me.color_attributes.active_color = col
    me.update()
    me.validate(verbose=False)
    return me


def _particles(scene, case: dict, w: int, h: int) -> None:
    """S6: ``count`` camera-facing particle quads with vertex colours, half Particles/Alpha Blended,
    half Particles/Additive (two draw calls, as two particle systems), overlapping heavily."""
    eye = (0.0, -9.0, 0.0)
    sprite = _sprite_texture()
    half = int(case["count"]) // 2
    for k, (label, dst) in enumerate((("AlphaBlended", "OneMinusSrcAlpha"), ("Additive", "One"))):
        me = particle_quads_mesh(f"Particles{label}", half, 777 + k, eye)
        me.materials.append(_particle_material(f"Particles/{label}", dst, sprite))
        scenekit.add_object(scene.collection, f"Particles {label}", me)
    scenekit.add_camera(scene, eye, target=(0.0, 0.0, 0.0))
