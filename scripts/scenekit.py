"""Building Blender scenes from numbers: the bpy helpers the example scenes and the benchmark share.

``scripts/make_blend_files.py`` (the files of ``blend_files/``) and ``scripts/benchmark/scenes.py``
(the benchmark's generated scenes) build every scene here: an empty file, its resolution, a
camera, a Sun, objects, meshes and materials with Unity settings, written through
``blendlib.blender``'s schema writers (the same stored values whether or not the add-on is
registered). Each helper sets only what it is given, so a scene built twice is the same scene.
Run from the repository root (``python -m scripts.NAME``): :func:`register_addon` imports ``addon``
from there.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterable, Sequence

import bpy
import numpy as np
from mathutils import Euler, Vector

from blendlib import blender
from blendlib.core import colorspace

#: The pass of Unity's alpha blending (``ZWrite Off``, ``Blend SrcAlpha OneMinusSrcAlpha``) as pass values.
ALPHA_BLEND = dict(blend=True, zwrite=False, src_blend="SrcAlpha", dst_blend="OneMinusSrcAlpha")


def register_addon(who: str) -> bool:
    """Register the add-on (``Material.unity``, ``Scene.unity``, the Unity Passes engine); True when
    Blender has the settings' types afterwards. Without it a note naming ``who`` goes to stderr and
    the schema writers store the settings as ID properties, which read back the same."""
    try:
        import addon

        addon.register()
    except Exception as exc:  # noqa: BLE001 - any failure leaves the stored-property path, which works
        print(f"{who}: add-on not available ({exc}); writing stored properties", file=sys.stderr)
        return False
    return hasattr(bpy.types.Material, "unity") and hasattr(bpy.types.Scene, "unity")


def empty_file():
    """Blender's factory settings with no data (``read_factory_settings(use_empty=True)``): the scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def set_resolution(scene, width: int, height: int) -> None:
    """Render at ``width`` x ``height`` pixels, 100 %."""
    scene.render.resolution_x, scene.render.resolution_y = int(width), int(height)
    scene.render.resolution_percentage = 100


def pointing(direction, axis: str = "-Z") -> Euler:
    """The rotation that turns an object's ``axis`` (``"-Z"``: where a camera looks; ``"Z"``: where
    a Sun's light comes from) along ``direction``, keeping its Y axis up. The direction is used as
    given: ``to_track_quat`` of a vector and of its normalised copy can differ in the last bit."""
    return Vector(direction).to_track_quat(axis, "Y").to_euler()


def add_camera(scene, location, *, rotation=None, target=None, clip=(0.1, 100.0), lens: float | None = None,
               ortho_scale: float | None = None):
    """A camera object "Camera" at ``location``, turned by ``rotation`` (radians) or looking at
    ``target``, linked into the scene and made its camera; orthographic with ``ortho_scale``."""
    data = bpy.data.cameras.new("Camera")
    if lens is not None:
        data.lens = lens
    data.clip_start, data.clip_end = clip
    if ortho_scale is not None:
        data.type = "ORTHO"
        data.ortho_scale = ortho_scale
    cam = bpy.data.objects.new("Camera", data)
    cam.location = location
    cam.rotation_euler = rotation if rotation is not None else pointing(Vector(target) - cam.location)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return cam


def add_sun(scene, *, energy: float, rotation, location=None):
    """A Sun object "Sun" of ``energy``, turned by ``rotation`` (radians; see :func:`pointing`)."""
    data = bpy.data.lights.new("Sun", "SUN")
    data.energy = energy
    sun = bpy.data.objects.new("Sun", data)
    sun.rotation_euler = rotation
    if location is not None:
        sun.location = location
    scene.collection.objects.link(sun)
    return sun


def add_object(collection, name: str, data, location=(0, 0, 0), rotation=(0, 0, 0), scale=(1, 1, 1)):
    """An object ``name`` of ``data`` linked into ``collection`` (e.g. ``scene.collection``), at
    ``location``, turned by the Euler angles ``rotation`` in **degrees**, scaled by ``scale``."""
    ob = bpy.data.objects.new(name, data)
    ob.location = location
    ob.rotation_euler = Euler(tuple(math.radians(r) for r in rotation))
    ob.scale = scale
    collection.objects.link(ob)
    return ob


def mesh(name: str, verts: Iterable[Sequence[float]], faces: Iterable[Sequence[int]], uvs=None, smooth=False):
    """A mesh from vertex positions and faces (vertex indices; face order = draw order), with one
    UV layer "UVMap" when ``uvs`` (per face, one (u, v) per corner) is given, validated."""
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(map(float, v)) for v in verts], [], [tuple(f) for f in faces])
    if uvs is not None:
        layer = me.uv_layers.new(name="UVMap")
        flat = [c for face_uv in uvs for uv in face_uv for c in uv]
        layer.uv.foreach_set("vector", [float(c) for c in flat])
    if smooth:
        me.shade_smooth()
    me.validate()
    me.update()
    return me


def unity_material(name: str, **settings):
    """A material with Unity settings enabled, then ``settings`` written by ``Material.unity`` field
    name in the order given (``color``: ``_Color`` as Unity stores it, sRGB-encoded RGB and alpha,
    default white; ``passes``: dicts of pass values). Its viewport colour (``diffuse_color``, what
    Workbench and the solid viewport draw) is ``_Color`` decoded to linear."""
    color = tuple(settings.get("color", (1.0, 1.0, 1.0, 1.0)))
    mat = bpy.data.materials.new(name)
    mat.diffuse_color = tuple(colorspace.decode_fast(np.array(color[:3])).tolist()) + (color[3],)
    if "color" in settings:
        settings["color"] = color
    blender.write_material(mat, enabled=True, **settings)
    return mat


# ---------------------------------------------------------------------------- meshes the example scenes share

QUAD_UV = ((0, 0), (1, 0), (1, 1), (0, 1))


def quad_mesh(name: str, w: float = 1.0, h: float = 1.0):
    """A w x h quad in the XZ plane facing -Y (towards the camera), UV 0..1."""
    x, z = w / 2, h / 2
    return mesh(name, [(-x, 0, -z), (x, 0, -z), (x, 0, z), (-x, 0, z)], [(0, 1, 2, 3)], [QUAD_UV])


#: Cube faces (outward winding), each mapped to the whole texture.
CUBE_FACES = (
    (0, 1, 5, 4),  # -Y front
    (1, 3, 7, 5),  # +X
    (4, 5, 7, 6),  # +Z top
    (2, 0, 4, 6),  # -X
    (3, 2, 6, 7),  # +Y back
    (2, 3, 1, 0),  # -Z bottom
)


def cube_mesh(name: str, size: float = 1.0):
    """A cube of edge ``size`` centred on the origin, each face mapped to the whole texture."""
    s = size / 2
    verts = [(x, y, z) for z in (-s, s) for y in (-s, s) for x in (-s, s)]
    return mesh(name, verts, CUBE_FACES, [QUAD_UV] * 6)


def sphere_mesh(name: str, radius=1.0, segments=32, rings=16):
    """A smooth UV sphere (poles single vertices, outward winding)."""
    verts = [(0.0, 0.0, radius)]
    for r in range(1, rings):
        t = math.pi * r / rings
        verts += [(radius * math.sin(t) * math.cos(2 * math.pi * k / segments),
                   radius * math.sin(t) * math.sin(2 * math.pi * k / segments), radius * math.cos(t))
                  for k in range(segments)]
    verts.append((0.0, 0.0, -radius))

    def ring(r, k):
        return 1 + (r - 1) * segments + k % segments

    faces = [(0, ring(1, k), ring(1, k + 1)) for k in range(segments)]
    faces += [(ring(r, k), ring(r + 1, k), ring(r + 1, k + 1), ring(r, k + 1))
              for r in range(1, rings - 1) for k in range(segments)]
    faces += [(len(verts) - 1, ring(rings - 1, k + 1), ring(rings - 1, k)) for k in range(segments)]
    return mesh(name, verts, faces, smooth=True)
