"""Helpers for the bpy tests: small scenes built from scratch, and data snapshots.

Every builder starts from ``read_factory_settings(use_empty=True)``; classes registered
directly (the add-on) survive that.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np

REPO = Path(__file__).resolve().parents[2]


def empty_scene(width: int = 64, height: int = 48, percentage: int = 100):
    """An empty factory scene with a perspective camera at (0, -8, 0) looking along +Y."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = percentage
    cam_data = bpy.data.cameras.new("Camera")
    cam = bpy.data.objects.new("Camera", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.0, -8.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.camera = cam
    scene.view_settings.view_transform = "Standard"
    scene.render.dither_intensity = 0.0
    return scene


def add_mesh(name: str, verts, faces, location=(0.0, 0.0, 0.0), material=None, collection=None):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    (collection or bpy.context.scene.collection).objects.link(obj)
    obj.location = location
    if material is not None:
        mesh.materials.append(material)
    return obj


def add_plane(name: str, size: float = 2.0, location=(0.0, 0.0, 0.0), material=None):
    """A quad in the XZ plane whose normal points to -Y (towards the camera)."""
    h = size / 2
    verts = [(-h, 0, -h), (h, 0, -h), (h, 0, h), (-h, 0, h)]
    return add_mesh(name, verts, [(0, 1, 2, 3)], location, material)


def add_cube(name: str, size: float = 2.0, location=(0.0, 0.0, 0.0), material=None):
    h = size / 2
    verts = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return add_mesh(name, verts, faces, location, material)


def unlit_material(name: str, color=(1.0, 0.0, 0.0, 1.0), **unity):
    """A material with Unity settings stored (through the schema's writer); works with the add-on
    registered or not. ``unity``: more ``Material.unity`` values by name."""
    from blendlib.blender import write_material

    mat = bpy.data.materials.new(name)
    write_material(mat, enabled=True, lighting="Unlit", color=tuple(color), **unity)
    return mat


def principled_material(name: str, base_color=(0.8, 0.8, 0.8, 1.0), alpha: float = 1.0):
    """A node material whose Principled BSDF has the given Base Color (linear) and Alpha; returns (mat, bsdf)."""
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    if tree is None:  # Blender < 5.0 creates the node tree on demand
        mat.use_nodes = True
        tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Base Color"].default_value = base_color
    bsdf.inputs["Alpha"].default_value = alpha
    return mat, bsdf


def coverage(frame, clear=None) -> int:
    """Pixels whose colour differs from the clear colour (the top-left pixel by default)."""
    color = frame.color
    ref = color[0, 0] if clear is None else np.asarray(clear, np.float32)
    return int(np.any(np.abs(color - ref) > 1e-6, axis=2).sum())


def snapshot() -> dict:
    """A comparable summary of the user's data: objects, meshes, materials, images, scenes."""
    data = {}
    for obj in bpy.data.objects:
        data[("object", obj.name)] = (tuple(tuple(r) for r in obj.matrix_world), obj.hide_render,
                                     tuple(m.name for m in obj.modifiers), obj.data.name if obj.data else None)
    for mesh in bpy.data.meshes:
        co = np.empty(len(mesh.vertices) * 3, np.float32)
        mesh.vertices.foreach_get("co", co)
        data[("mesh", mesh.name)] = (len(mesh.vertices), len(mesh.polygons), co.tobytes(),
                                     tuple(a.name for a in mesh.attributes), mesh.users)
    for mat in bpy.data.materials:
        data[("material", mat.name)] = (tuple(mat.diffuse_color), mat.users)
    for img in bpy.data.images:
        data[("image", img.name)] = (tuple(img.size), img.filepath, img.users)
    for scene in bpy.data.scenes:
        data[("scene", scene.name)] = (scene.frame_current, scene.camera.name if scene.camera else None,
                                      scene.render.resolution_x, scene.render.resolution_y)
    data["counts"] = tuple(len(c) for c in (bpy.data.objects, bpy.data.meshes, bpy.data.materials,
                                           bpy.data.images, bpy.data.curves, bpy.data.textures))
    return data


def run_cli(*args: str, cwd: Path = REPO, code: str | None = None) -> subprocess.CompletedProcess:
    """``python -m blendlib ARGS`` (or ``python -c CODE ARGS``) in a fresh process."""
    cmd = [sys.executable, "-c", code, *args] if code else [sys.executable, "-m", "blendlib", *args]
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=300)


def one_line_error(proc: subprocess.CompletedProcess, text: str) -> None:
    """The CLI failed with exit status 1 and exactly one ``error: ...`` line containing ``text``."""
    assert proc.returncode == 1, proc.stderr
    lines = [x for x in proc.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and text in lines[0], proc.stderr


#: The start of a scene-building script for :func:`build_blends`: the helpers above imported,
#: ``folder`` (the first argument) and ``save(kind)`` writing ``folder/kind.blend``.
SCENE_SCRIPT = """
import sys, math, bpy
sys.path.insert(0, ".")
from tests.support.blender_fixtures import *
folder = sys.argv[1]

def save(kind):
    bpy.ops.wm.save_as_mainfile(filepath=f"{folder}/{kind}.blend")
"""


def build_blends(folder: Path, body: str, kinds) -> dict[str, Path]:
    """Run :data:`SCENE_SCRIPT` + ``body`` once in a fresh process (it saves ``kind.blend`` for each
    kind into ``folder``); kind → path."""
    proc = run_cli(str(folder), code=SCENE_SCRIPT + body)
    assert proc.returncode == 0, proc.stderr
    return {kind: Path(folder) / f"{kind}.blend" for kind in kinds}


def blends_per_kind(folder: Path, code: str, kinds) -> dict[str, Path]:
    """``code`` run once per kind as ``python -c code KIND PATH`` (it saves the file at PATH); kind → path."""
    out = {}
    for kind in kinds:
        path = Path(folder) / f"{kind}.blend"
        proc = run_cli(kind, str(path), code=code)
        assert proc.returncode == 0, proc.stderr
        out[kind] = path
    return out
