"""Import a ``.vrm`` / ``.glb`` / ``.gltf`` file into the current Blender data with Unity settings (SPEC §11.6).

The geometry, images and node materials come from Blender's own glTF importer (``io_scene_gltf2``,
shipped inside bpy; it reads ``.vrm`` files as the glb files they are). Every material then gets the
state UniVRM / UniGLTF set (:mod:`blendlib.formats.gltf`): an MToon material of a ``.vrm`` as the
VRM Add-on for Blender's MToon settings (:mod:`blendlib.formats.gltf.addon_settings`; its Unity
settings off, the file's spec version on the armature), so that it renders, is advised and is
changed as the add-on's own materials are; every other material (and an MToon material the add-on
cannot state exactly, with a warning) as Unity settings through the schema's writer, with its
``_MainTex`` and outline-width images. Either way the state read back equals the direct import's.

Blender names what it imports after the file and dedupes names (``Skin`` becomes ``Skin.001`` when
the file already has a ``Skin``), so a material's name does not say which glTF material it is. The
importer therefore reads a copy of the file whose materials and images carry unique names (the
JSON chunk rewritten; geometry and images unchanged) and gives the original names back afterwards.

Everything is checked before Blender's data changes: a bad file raises :class:`GltfError` (one
line) and the data stays as it was.
"""

from __future__ import annotations

import contextlib
import copy
import math
import os
import tempfile
import urllib.parse
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..formats.gltf import GltfDocument, GltfError, GltfImport, import_materials, read_document
from ..formats.gltf.addon_settings import addon_mtoon_of, differences, with_images
from ..formats.gltf.container import glb_bytes, read_binary_chunk
from .schema import write_material, write_scene_settings
from .vrm_addon import EXTENSION_KEY, armature_of, derived_material, write_addon_mtoon, write_armature_spec_version

TOKEN = "UnityPassesImport"


@dataclass(frozen=True)
class ImportResult:
    """What :func:`import_gltf` did: the Unity state per material (``result``), the Blender
    materials in glTF index order (None where a glTF material is not used by any mesh), the new
    objects, and the camera and Sun it added (None when it added none); ``addon_materials``: the
    names of the materials that got the VRM Add-on's MToon settings (the others got Unity
    settings), ``warnings``: why an MToon material kept Unity settings."""

    result: GltfImport
    materials: tuple[Any, ...]
    objects: tuple[Any, ...]
    camera: Any = None
    sun: Any = None
    addon_materials: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()


def _token_material(index: int) -> str:
    return f"{TOKEN}M{index}"


def _token_image(index: int) -> str:
    return f"{TOKEN}I{index}"


def _absolute_uri(uri: str, folder: Path) -> str:
    """A relative file URI made absolute (data: URIs and absolute ones as they are)."""
    if uri.startswith("data:") or "://" in uri:
        return uri
    path = Path(urllib.parse.unquote(uri))
    if not path.is_absolute():
        path = folder / path
    return urllib.parse.quote(str(path.resolve()).replace(os.sep, "/"))


@contextlib.contextmanager
def _renamed_copy(document: GltfDocument) -> Iterator[str]:
    """A temporary copy of the file with every material and image named by its index."""
    data = copy.deepcopy(document.json)
    for i, material in enumerate(data.get("materials", [])):
        material["name"] = _token_material(i)
    folder = Path(document.path).resolve().parent
    for i, image in enumerate(data.get("images", [])):
        image["name"] = _token_image(i)
        if isinstance(image.get("uri"), str):
            image["uri"] = _absolute_uri(image["uri"], folder)
    for buffer in data.get("buffers", []):
        if isinstance(buffer, dict) and isinstance(buffer.get("uri"), str):
            buffer["uri"] = _absolute_uri(buffer["uri"], folder)
    with tempfile.TemporaryDirectory(prefix="unity-passes-gltf-") as tmp:
        if document.binary:
            path = os.path.join(tmp, "model.glb")
            with open(path, "wb") as fh:
                fh.write(glb_bytes(data, read_binary_chunk(document.path)))
        else:
            import json

            path = os.path.join(tmp, "model.gltf")
            with open(path, "w", encoding="utf-8") as fh:
                json.dump(data, fh)
        yield path


def _run_blender_importer(path: str, where: str, scene: Any, unused_images: bool = False) -> None:
    """Blender's glTF importer into ``scene`` (it links what it makes into the context's collection);
    ``unused_images``: also the images (and materials) no mesh uses."""
    import bpy  # noqa: I001 - bpy before addon_utils

    import addon_utils

    addon_utils.enable("io_scene_gltf2", default_set=False)
    override = {} if scene == bpy.context.scene else {"scene": scene, "view_layer": scene.view_layers[0]}
    try:
        with bpy.context.temp_override(**override):
            result = bpy.ops.import_scene.gltf(filepath=path, import_unused_materials=unused_images)
    except (RuntimeError, TypeError, ValueError, KeyError, IndexError, AttributeError) as exc:
        # Blender's message is a traceback then "Location: ops.py:N": the reason is the last line of neither.
        lines = [line.strip() for line in str(exc).splitlines()
                 if line.strip() and not line.startswith((" ", "\t")) and not line.startswith("Location:")]
        reason = lines[-1].removeprefix("Error: ").strip() if lines else type(exc).__name__
        raise GltfError(f"{where}: Blender's glTF importer failed: {reason}") from None
    if "FINISHED" not in result:
        raise GltfError(f"{where}: Blender's glTF importer did not finish ({', '.join(sorted(result))})")


def _strip_suffix(name: str) -> str:
    """``UnityPassesImportM3.001`` → ``UnityPassesImportM3`` (Blender's dedupe suffix)."""
    head, dot, tail = name.rpartition(".")
    return head if dot and tail.isdigit() else name


#: The kinds of data Blender's glTF importer creates.
_CREATED = ("objects", "meshes", "materials", "images", "armatures", "cameras", "lights", "node_groups",
            "actions", "collections")


def _new(collection: Any, before: set[int]) -> list[Any]:
    return [block for block in collection if block.as_pointer() not in before]


def _remove_new(before: dict[str, set[int]]) -> None:
    """Remove every data-block created since ``before`` (pointers per ``bpy.data`` collection)."""
    import bpy

    for key in _CREATED:
        collection = getattr(bpy.data, key)
        for block in _new(collection, before[key]):
            collection.remove(block)


def import_gltf(path: str | Path, scene: Any = None, *, add_camera: bool = True, add_sun: bool = True
                ) -> ImportResult:
    """Import ``path`` into ``scene`` (default: the context scene): Blender's glTF importer for the
    geometry, then the Unity settings of every material. ``add_camera``: when the file has no camera,
    add one framing the model (the scene's camera when the scene has none); ``add_sun``: when the scene
    has no Sun, add one lighting the model from the front. GltfError (one line): nothing changed."""
    import bpy

    document = read_document(path)
    result = import_materials(document)
    scene = scene or bpy.context.scene
    before = {key: {b.as_pointer() for b in getattr(bpy.data, key)} for key in _CREATED}
    # MToon's outline-width textures are used by no glTF material: Blender's importer makes their
    # images only when told to import unused ones.
    unused = any(m.outline_width_tex is not None for m in result.materials)
    try:
        with _renamed_copy(document) as copy_path:
            _run_blender_importer(copy_path, document.path, scene, unused_images=unused)
    except GltfError:
        _remove_new(before)  # what Blender's importer made before it stopped
        raise
    images: dict[int, Any] = {}
    for image in _new(bpy.data.images, before["images"]):
        token = _strip_suffix(image.name)
        if token.startswith(f"{TOKEN}I") and token[len(TOKEN) + 1:].isdigit():
            index = int(token[len(TOKEN) + 1:])
            images[index] = image
            image.name = document.image_name(index)
    materials: list[Any] = [None] * len(result.materials)
    mtoon: list[tuple[Any, Any, Any]] = []  # (Blender material, imported, the add-on's settings)
    warnings: list[str] = []
    for mat in _new(bpy.data.materials, before["materials"]):
        token = _strip_suffix(mat.name)
        if not (token.startswith(f"{TOKEN}M") and token[len(TOKEN) + 1:].isdigit()):
            continue
        index = int(token[len(TOKEN) + 1:])
        imported = result.materials[index]
        mat.name = imported.material.name
        settings, why = addon_mtoon_of(document, imported, result.vrm)
        if why is not None:
            warnings.append(why)
        if settings is not None:
            mtoon.append((mat, imported, with_images(settings, lambda i: images.get(document.texture_image(i)))))
        else:
            _write_unity_settings(mat, imported, document, images)
        if materials[index] is None:
            materials[index] = mat
    objects = _new(bpy.data.objects, before["objects"])
    addon_materials: list[str] = []
    if mtoon:
        objects += _vrm_armature(objects, result.vrm)
        for mat, imported, settings in mtoon:
            write_addon_mtoon(mat, settings)
            why = _derived_differs(mat, imported)
            if why is None:
                addon_materials.append(mat.name)
                continue
            warnings.append(f"material {mat.name!r}: read back from the VRM Add-on's settings, {why} would differ; "
                            "it keeps Unity settings")
            del mat.bl_system_properties_get()[EXTENSION_KEY]
            _write_unity_settings(mat, imported, document, images)
    camera = sun = None
    if add_camera and not document.list("cameras"):
        camera = frame_model(scene, objects, facing_positive_y=result.vrm == "0.x")
    elif scene.camera is None:  # the file's own first camera
        scene.camera = next((o for o in objects if o.type == "CAMERA"), None)
    if add_sun and not any(o.type == "LIGHT" and o.data.type == "SUN" for o in scene.objects):
        sun = add_front_sun(scene, facing_positive_y=result.vrm == "0.x")
    return ImportResult(result, tuple(materials), tuple(objects), camera, sun, tuple(addon_materials),
                        tuple(warnings))


def _write_unity_settings(mat: Any, imported: Any, document: GltfDocument, images: dict[int, Any]) -> None:
    """``imported``'s Unity settings on ``mat`` (on), with its ``_MainTex`` and outline-width images."""
    image = width = None
    if imported.main_tex is not None:
        image = images.get(document.texture_image(imported.main_tex))
    if imported.outline_width_tex is not None:
        width = images.get(document.texture_image(imported.outline_width_tex))
        if width is not None and imported.outline_width_encoding == "Data" and width is not image:
            width.colorspace_settings.name = "Non-Color"  # UniVRM reads VRM 1.0's as linear data
    write_material(mat, imported.material, enabled=True, main_tex=image, outline_width_tex=width)


def _derived_differs(mat: Any, imported: Any) -> str | None:
    """What of the state read back from ``mat``'s VRM Add-on settings differs from ``imported`` (None:
    nothing): the armature's spec version and the images included."""
    derived = derived_material(mat)
    if derived is None:
        return "the whole material"
    differ = differences(derived[0], imported)
    if derived[2] is not None and derived[0].outline_width_encoding == "Data":
        derived[2].colorspace_settings.name = "Non-Color"  # as the Unity settings path sets it
    return ", ".join(differ) if differ else None


def _vrm_armature(objects: list[Any], vrm: str) -> list[Any]:
    """Where the VRM Add-on keeps the spec version that picks a material's export: the armature of
    the objects using it (:func:`.vrm_addon.spec_version`). Every armature the import made gets
    ``vrm``; when it made none, one is added (returned); meshes outside every armature are parented
    (their top object, world transform kept) to the first, so that each finds its version."""
    import bpy

    armatures = [o for o in objects if o.type == "ARMATURE"]
    added = []
    if not armatures:
        collection = objects[0].users_collection[0] if objects and objects[0].users_collection else \
            bpy.context.scene.collection
        armature = bpy.data.objects.new("VRM Armature", bpy.data.armatures.new("VRM Armature"))
        collection.objects.link(armature)
        armatures = added = [armature]
    for armature in armatures:
        write_armature_spec_version(armature.data, vrm)
    root = armatures[0]
    for obj in objects:
        if obj.type != "MESH" or armature_of(obj) is not None:
            continue
        top = obj
        while top.parent is not None:
            top = top.parent
        world = top.matrix_world.copy()
        top.parent = root
        top.matrix_world = world
    return added


def _bounds(objects: list[Any]) -> tuple[Any, Any] | None:
    """World-space bounding box of the meshes among ``objects`` as evaluated (skinned meshes included:
    a new object's ``bound_box`` is empty until the depsgraph has evaluated it)."""
    import bpy
    from mathutils import Vector

    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = [obj.evaluated_get(depsgraph) for obj in objects if obj.type == "MESH"]
    corners = [obj.matrix_world @ Vector(corner) for obj in evaluated for corner in obj.bound_box]
    if not corners:
        return None
    lo = Vector((min(c.x for c in corners), min(c.y for c in corners), min(c.z for c in corners)))
    hi = Vector((max(c.x for c in corners), max(c.y for c in corners), max(c.z for c in corners)))
    return lo, hi


def frame_model(scene: Any, objects: list[Any], *, facing_positive_y: bool, margin: float = 1.1) -> Any:
    """A camera "VRM Camera" looking at the front of the meshes among ``objects`` and framing them.

    The front: glTF's +Z (VRM 1.0 and glTF's convention), which Blender's importer turns into −Y;
    VRM 0.x models face glTF's −Z (UniVRM 0.x flips Z), Blender's +Y (``facing_positive_y``)."""
    import bpy
    from mathutils import Vector

    bounds = _bounds(objects) or (Vector((-1, -1, -1)), Vector((1, 1, 1)))
    lo, hi = bounds
    center = (lo + hi) / 2
    size = hi - lo
    data = bpy.data.cameras.new("VRM Camera")
    cam = bpy.data.objects.new("VRM Camera", data)
    scene.collection.objects.link(cam)
    sign = 1.0 if facing_positive_y else -1.0
    # Half-angles of the view at this scene's aspect (Blender's sensor fit), from the camera's own frame.
    frame = data.view_frame(scene=scene)
    tan_x = max(abs(v.x) for v in frame) / abs(frame[0].z)
    tan_y = max(abs(v.y) for v in frame) / abs(frame[0].z)
    distance = margin * max(size.x / 2 / tan_x, size.z / 2 / tan_y) + size.y / 2
    distance = max(distance, 1e-3)
    cam.location = center + Vector((0.0, sign * distance, 0.0))
    cam.rotation_euler = (math.pi / 2, 0.0, math.pi if facing_positive_y else 0.0)
    data.clip_start = max(1e-3, min(0.1, distance * 0.05))
    data.clip_end = distance + 2 * size.y + 10.0
    if scene.camera is None:
        scene.camera = cam
    return cam


def add_front_sun(scene: Any, *, facing_positive_y: bool) -> Any:
    """A Sun "VRM Sun" (strength 1, Unity's default directional light intensity) shining on the
    model's front from above and to its side."""
    import bpy
    from mathutils import Vector

    sign = 1.0 if facing_positive_y else -1.0
    data = bpy.data.lights.new("VRM Sun", "SUN")
    data.energy = 1.0
    sun = bpy.data.objects.new("VRM Sun", data)
    towards_light = Vector((0.35, sign * 1.0, 0.6))  # from the model towards the light
    sun.rotation_euler = towards_light.to_track_quat("Z", "Y").to_euler()
    scene.collection.objects.link(sun)
    return sun


def prepare_new_scene(scene: Any, width: int = 768, height: int = 1024) -> None:
    """The scene of a new file made by ``python -m blendlib import``: a portrait render size and an
    ambient colour of its own (Unity's ambient, not the empty file's missing World)."""
    scene.render.resolution_x, scene.render.resolution_y = int(width), int(height)
    scene.render.resolution_percentage = 100
    write_scene_settings(scene, ambient_from_world=False)


def import_into_new_file(path: str | Path) -> ImportResult:
    """Replace Blender's data with an empty file (:func:`prepare_new_scene`) and import ``path`` into it
    with a camera and a Sun; the images are packed so that a saved ``.blend`` carries them, as the
    ``.vrm`` does. GltfError (one line) for a bad file."""
    import bpy

    document = read_document(path)  # checked before Blender's data is replaced
    import_materials(document)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    prepare_new_scene(scene)
    done = import_gltf(path, scene)
    for image in bpy.data.images:
        if image.packed_file is None and image.source == "FILE" and image.filepath:
            image.pack()
    return done


def save_blend(path: str | Path) -> None:
    """Save Blender's data as ``path`` (uncompressed; no ``.blend1`` backup is made of a missing file)."""
    import bpy

    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(str(path)), check_existing=False, compress=False)
