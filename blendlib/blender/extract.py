"""Scene extraction: a Blender scene → :class:`blendlib.core.scene.DrawScene`.

Extraction never modifies scene data: evaluated meshes come from
``Object.evaluated_get(depsgraph).to_mesh()`` and are released with
``to_mesh_clear()``; the Unity settings are read through :mod:`.schema`, never written.
bpy is imported inside functions.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..core import colorspace
from ..core.scene import Camera, DrawScene, ForwardLight, Light, Mesh, Renderer, SceneError
from ..core.vocabulary import ColorSpace, LightType, Material, SortMode, Texture, VertexColor
from ..formats.gltf import SHADING_APPROXIMATION
from . import vrm_addon
from .lights import forward_light, is_forward_light
from .schema import material_from_values, material_values, scene_settings

MESH_LIKE = {"MESH", "CURVE", "SURFACE", "META", "FONT"}


MAGENTA = (1.0, 0.0, 1.0, 1.0)
#: Objects whose matrix_world holds a larger entry are not drawn (with a warning).
MAX_TRANSFORM = 1e30


def render_size(scene: Any) -> tuple[int, int]:
    """Render resolution × percentage, as Blender computes it (integer division)."""
    r = scene.render
    return (r.resolution_x * r.resolution_percentage) // 100, (r.resolution_y * r.resolution_percentage) // 100


def _matrix(m: Any) -> np.ndarray:
    return np.array([list(row) for row in m], dtype=np.float64)


class _Extractor:
    def __init__(self, warnings: list[str]):
        self.warnings = warnings
        self.materials: dict[int, Material] = {}
        self.textures: dict[int, Texture] = {}
        self.default_material = Material(name="Default")
        # (object or 'instancer/object', slot) → how many renderers had that empty slot: one warning each
        self.empty_slots: dict[tuple[str, int], int] = {}

    # -- textures -----------------------------------------------------------
    def texture(self, image: Any) -> Texture | None:
        if image is None:
            return None
        image = getattr(image, "original", image) or image
        key = image.as_pointer()
        if key not in self.textures:
            self.textures[key] = self._load_texture(image)
        return self.textures[key]

    def texture_as(self, image: Any, encoding: str) -> Texture | None:
        """:meth:`texture` of ``image`` read with ``encoding`` whatever its colour space (UniVRM imports
        a VRM 1.0 outline-width texture as linear data), kept per image and encoding."""
        texture = self.texture(image)
        if texture is None or texture.encoding == encoding or texture.missing:
            return texture
        key = (texture.name, id(texture), encoding)
        if key not in self.textures:
            self.textures[key] = replace(texture, encoding=encoding)
        return self.textures[key]

    def _load_texture(self, image: Any) -> Texture:
        name = image.name
        try:
            w, h = int(image.size[0]), int(image.size[1])
            ok = w > 0 and h > 0 and image.has_data
        except Exception:  # noqa: BLE001 - an unreadable image is reported, not raised
            ok, w, h = False, 0, 0
        if not ok:
            where = image.filepath or "<no file>"
            self.warnings.append(f"image {name!r}: cannot read {where}; using magenta")
            return Texture(np.array([[MAGENTA]], np.float32), encoding="sRGB", name=name, missing=True)
        pixels = np.empty(w * h * 4, np.float32)
        image.pixels.foreach_get(pixels)
        pixels = pixels.reshape(h, w, 4)
        if image.alpha_mode == "NONE":
            pixels[..., 3] = 1.0
        if image.colorspace_settings.is_data:
            encoding = "Data"
        elif image.is_float:
            encoding = "Linear"
        elif image.colorspace_settings.name in ("sRGB", "sRGB 2.1"):
            encoding = "sRGB"
        else:
            encoding = "Linear"
        return Texture(pixels, encoding=encoding, name=name)

    # -- materials -------------------------------------------------------------
    def material(self, mat: Any) -> Material:
        if mat is None:
            return self.default_material
        mat = getattr(mat, "original", mat) or mat
        key = mat.as_pointer()
        if key not in self.materials:
            self.materials[key] = self._convert_material(mat)
        return self.materials[key]

    def _convert_material(self, mat: Any, with_texture: bool = True) -> Material:
        values = material_values(mat)
        texture = self.texture if with_texture else (lambda image: None)
        if not values["enabled"]:
            derived = vrm_addon.derived_material(mat)  # the VRM Add-on's MToon: as UniVRM draws its export
            if derived is not None:
                imported, image, width_image, _ = derived
                if SHADING_APPROXIMATION not in self.warnings:
                    self.warnings.append(SHADING_APPROXIMATION)
                width = self.texture_as(width_image, imported.outline_width_encoding) if with_texture else None
                return replace(imported.material, name=mat.name, main_tex=texture(image), outline_width_tex=width)
            color, image = principled_inputs(mat)
            return Material(name=mat.name, color=color, main_tex=texture(image))
        return material_from_values(mat.name, values, texture(values["main_tex"]),
                                    outline_width_tex=texture(values["outline_width_tex"]))

    # -- meshes ----------------------------------------------------------------
    def slot_warnings(self) -> list[str]:
        """One warning per object (all its instances together) with an empty material slot."""
        out = []
        for (name, slot), count in self.empty_slots.items():
            times = f" ({count} instances)" if count > 1 else ""
            out.append(f"object {name!r} slot {slot}{times}: empty material slot, using the default material")
        return out

    def renderers(self, obj_eval: Any, matrix_world: np.ndarray, name: str) -> list[Renderer]:
        mesh = obj_eval.to_mesh()
        try:
            return self._mesh_renderers(obj_eval, mesh, matrix_world, name)
        finally:
            obj_eval.to_mesh_clear()

    def _mesh_renderers(self, obj_eval: Any, mesh: Any, matrix_world: np.ndarray, name: str) -> list[Renderer]:
        if mesh is None:
            return []
        slots = obj_eval.material_slots
        mats = [s.material for s in slots] or list(mesh.materials)
        # Vertex colours are read only when a material uses them (extraction runs on every viewport edit).
        reads_colors = any(self.material(m).vertex_color is not VertexColor.Off for m in mats)
        arrays = mesh_arrays(mesh, colors=reads_colors)
        positions = arrays["positions"]
        finite = positions[np.isfinite(positions).all(axis=1)]  # NaN/inf vertices: the core skips their triangles
        if len(finite):
            lo, hi = finite.min(axis=0).astype(np.float64), finite.max(axis=0).astype(np.float64)
            corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            world = corners @ matrix_world.T
            center = (world[:, :3].min(axis=0) + world[:, :3].max(axis=0)) * 0.5
        else:
            center = matrix_world[:3, 3].copy()
        tri_mat = arrays["material_index"]
        if len(mats) > 1:
            used = np.unique(np.clip(tri_mat, 0, len(mats) - 1)) if len(tri_mat) else np.array([0])
            tri_mat = np.clip(tri_mat, 0, len(mats) - 1)
        else:
            used = np.array([0])
            tri_mat = None
        out = []
        for slot in used.tolist():
            if tri_mat is None:
                sel = slice(None)
                loop_tris = None
            else:
                sel = np.flatnonzero(tri_mat == slot)
                loop_tris = sel.astype(np.int32)
            mat = mats[slot] if slot < len(mats) else None
            if mat is None and len(arrays["triangles"]) and mats:
                cause = (name.split("#")[0], int(slot))  # every instance of one object: one cause
                self.empty_slots[cause] = self.empty_slots.get(cause, 0) + 1
            uvs, colors = arrays["uvs"], arrays.get("colors")
            sub = Mesh(
                positions=positions,
                triangles=arrays["triangles"][sel],
                normals=arrays["normals"][sel],
                uvs=None if uvs is None else uvs[sel],
                polygons=arrays["polygons"][sel],
                loop_triangles=loop_tris,
                colors=None if colors is None else colors[sel],
                color_encoding=arrays.get("color_encoding", "sRGB"),
            )
            out.append(Renderer(name=name, slot=int(slot), mesh=sub, matrix_world=matrix_world,
                                material=self.material(mat), bounds_center=center))
        return out


def material_from_blender(mat: Any, with_texture: bool = False) -> Material:
    """The Unity material of a ``bpy.types.Material`` as it renders, with or without its image.

    Reads ``mat.unity`` when the add-on is registered, else the stored properties; a
    disabled material gives the default opaque material from its Principled BSDF.
    """
    return _Extractor([])._convert_material(mat, with_texture=with_texture)


def mesh_arrays(mesh: Any, colors: bool = False) -> dict[str, np.ndarray | None]:
    """Triangles of a (temporary, evaluated) Blender mesh as numpy arrays, via fast ``foreach_get``.

    ``positions`` (V, 3) float32, ``triangles`` (T, 3) int32 vertex indices in loop-triangle
    order, ``normals`` (T, 3, 3) float32 corner normals, ``uvs`` (T, 3, 2) float32 of the
    active UV map or None, ``material_index`` (T,) int32, ``polygons`` (T,) int32 face index.
    With ``colors``: ``colors`` (T, 3, 4) float32 per corner of the active colour attribute, or None
    when the mesh has none, and ``color_encoding`` (:func:`corner_colors`).
    """
    mesh.calc_loop_triangles()
    t = len(mesh.loop_triangles)
    v = len(mesh.vertices)
    n_loops = len(mesh.loops)
    positions = np.empty(v * 3, np.float32)
    if v:
        mesh.attributes["position"].data.foreach_get("vector", positions)
    positions = positions.reshape(v, 3)
    tri_loops = np.empty(t * 3, np.uint32)
    corner_vert = np.empty(n_loops, np.int32)
    if t:
        mesh.loop_triangles.foreach_get("loops", tri_loops)
        mesh.attributes[".corner_vert"].data.foreach_get("value", corner_vert)
    tri_loops = tri_loops.astype(np.intp)
    triangles = np.take(corner_vert, tri_loops).reshape(t, 3)
    normals_c = np.empty(n_loops * 3, np.float32)
    if t:
        mesh.corner_normals.foreach_get("vector", normals_c)
    normals = np.take(normals_c.reshape(n_loops, 3), tri_loops, axis=0).reshape(t, 3, 3)
    uvs = None
    layer = mesh.uv_layers.active
    if layer is not None and t:
        uv_c = np.empty(n_loops * 2, np.float32)
        layer.uv.foreach_get("vector", uv_c)
        uvs = np.take(uv_c.reshape(n_loops, 2), tri_loops, axis=0).reshape(t, 3, 2)
    material_index = np.zeros(t, np.int32)
    tri_poly = np.empty(t, np.int32)
    if t:
        mesh.loop_triangle_polygons.foreach_get("value", tri_poly)
    attr = mesh.attributes.get("material_index")
    if attr is not None and t and attr.domain == "FACE" and attr.data_type == "INT":
        poly_mat = np.empty(len(mesh.polygons), np.int32)
        attr.data.foreach_get("value", poly_mat)
        material_index = np.take(poly_mat, tri_poly)
    out = {"positions": positions, "triangles": triangles, "normals": normals, "uvs": uvs,
           "material_index": material_index, "polygons": tri_poly}
    if colors:
        out["colors"], out["color_encoding"] = corner_colors(mesh, tri_loops, corner_vert)
    return out


def corner_colors(mesh: Any, tri_loops: np.ndarray, corner_vert: np.ndarray) -> tuple[np.ndarray | None, str]:
    """The mesh's active colour attribute per triangle corner, (T, 3, 4) float32, and its encoding:
    a byte attribute (``BYTE_COLOR``) read as its stored sRGB-encoded values (``color_srgb``, k/255:
    ``"sRGB"``), a float one as its linear values (``color``: ``"Linear"``); point-domain values go
    to every corner of their vertex. (None, "sRGB") when the mesh has no colour attribute.
    ``tri_loops`` (3T,) the corners of the loop triangles, ``corner_vert`` (corners,) their vertices."""
    attribute = mesh.color_attributes.active_color
    if attribute is None or not len(tri_loops):
        return None, "sRGB"
    byte = attribute.data_type == "BYTE_COLOR"
    values = np.empty(len(attribute.data) * 4, np.float32)
    # float32 buffers take Blender's fastest path for both kinds (a byte buffer is slower, measured).
    attribute.data.foreach_get("color_srgb" if byte else "color", values)
    values = values.reshape(-1, 4)
    index = tri_loops if attribute.domain == "CORNER" else np.take(corner_vert, tri_loops)
    return np.take(values, index, axis=0).reshape(-1, 3, 4), "sRGB" if byte else "Linear"


def principled_inputs(mat: Any) -> tuple[tuple[float, float, float, float], Any]:
    """(_Color, image) of a material without Unity settings: the Principled BSDF Base Color (linear,
    encoded to sRGB since _Color is COLOR_GAMMA) and Alpha, and an Image Texture linked to Base Color."""
    tree = getattr(mat, "node_tree", None)
    bsdf = None
    if tree is not None:
        for node in tree.nodes:
            if node.type == "BSDF_PRINCIPLED":
                bsdf = node
                if any(link.to_node.type == "OUTPUT_MATERIAL" for out in node.outputs for link in out.links):
                    break
    if bsdf is None:
        r, g, b, a = mat.diffuse_color
        return (colorspace.encode(r), colorspace.encode(g), colorspace.encode(b), float(a)), None
    base = bsdf.inputs["Base Color"]
    r, g, b, _ = base.default_value
    alpha = float(bsdf.inputs["Alpha"].default_value)
    for link in base.links:
        node = link.from_node
        if node.type == "TEX_IMAGE" and node.image is not None:
            return (1.0, 1.0, 1.0, alpha), node.image  # texture x white
    return (colorspace.encode(r), colorspace.encode(g), colorspace.encode(b), alpha), None


def world_ambient(world: Any) -> tuple[float, float, float]:
    """World background colour (linear): the Background node's Color × Strength, or ``world.color``."""
    if world is None:
        return (0.0, 0.0, 0.0)
    tree = getattr(world, "node_tree", None)
    if tree is not None:
        backgrounds = [n for n in tree.nodes if n.type == "BACKGROUND"]
        linked = [n for n in backgrounds
                  if any(link.to_node.type == "OUTPUT_WORLD" for link in n.outputs[0].links)]
        node = (linked or backgrounds or [None])[0]
        if node is not None:
            c = node.inputs["Color"].default_value
            s = float(node.inputs["Strength"].default_value)
            return (c[0] * s, c[1] * s, c[2] * s)
    c = world.color
    return (float(c[0]), float(c[1]), float(c[2]))


def render_visible_objects(view_layer: Any) -> set[int]:
    """Pointers of the original objects that a render of ``view_layer`` shows: not ``hide_render``,
    and in at least one collection path that is neither excluded nor hidden for renders."""
    found: set[int] = set()

    def visit(lc: Any) -> None:
        if lc.exclude or lc.collection.hide_render:
            return
        for obj in lc.collection.objects:
            if not obj.hide_render:
                found.add(obj.as_pointer())
        for child in lc.children:
            visit(child)

    visit(view_layer.layer_collection)
    return found


def build_draw_scene(scene: Any = None, depsgraph: Any = None, *, camera: Camera | None = None,
                     visibility: str = "render") -> DrawScene:
    """A :class:`DrawScene` of a ``bpy.types.Scene`` (default: the context scene).

    ``depsgraph``: an evaluated depsgraph of the scene (the render engine passes its
    render depsgraph); default ``bpy.context.evaluated_depsgraph_get()`` for the
    context scene. ``camera``: use this camera instead of the scene's (the viewport's
    own view; the scene needs no camera then). ``visibility``: ``"render"`` (objects as a
    render shows them) or ``"viewport"`` (as the depsgraph's viewport shows them).
    Raises :class:`SceneError` when the scene has no camera and none is given.
    """
    import bpy

    if depsgraph is not None and scene is None:
        scene = depsgraph.scene
    if scene is None:
        scene = bpy.context.scene
    scene = getattr(scene, "original", scene) or scene
    if depsgraph is None:
        depsgraph = _depsgraph_for(scene)
    view_layer = depsgraph.view_layer
    if visibility not in ("render", "viewport"):
        raise ValueError(f"visibility must be 'render' or 'viewport', got {visibility!r}")
    check_visibility = depsgraph.mode != "RENDER" and visibility == "render"
    warnings: list[str] = []
    settings = scene_settings(scene)

    if camera is None:
        cam_obj = scene.camera
        if cam_obj is None:
            raise SceneError(f"scene {scene.name!r} has no camera")
        if cam_obj.type != "CAMERA":
            raise SceneError(f"scene {scene.name!r}: active camera {cam_obj.name!r} is not a camera object")
        cam_data = cam_obj.data
        if cam_data.type == "PANO":
            raise SceneError(f"camera {cam_obj.name!r}: panoramic cameras are not supported (use Perspective or "
                             "Orthographic)")
        if not cam_data.clip_start < cam_data.clip_end:
            raise SceneError(f"camera {cam_obj.name!r}: Clip Start {cam_data.clip_start:g} must be less than "
                             f"Clip End {cam_data.clip_end:g}")
        width, height = render_size(scene)
        if width < 1 or height < 1:
            raise SceneError(f"scene {scene.name!r}: the render size is {width}x{height} pixels "
                             "(resolution x percentage); it must be at least 1x1")
        camera = _camera(cam_obj.evaluated_get(depsgraph), depsgraph, scene, width, height)

    ex = _Extractor(warnings)
    renderers: list[Renderer] = []
    forward: list[ForwardLight] = []  # every Sun, Point and Spot light
    visible = render_visible_objects(view_layer) if check_visibility else set()

    def add(obj: Any, name: str, matrix: Any, instancer: bool = False) -> None:
        mw = _matrix(matrix)
        if obj.type in MESH_LIKE and not (np.all(np.isfinite(mw)) and np.abs(mw).max() < MAX_TRANSFORM):
            # Blender stores an "infinite" scale as FLT_MAX: nothing sensible can be drawn from it.
            warnings.append(f"object {name!r}: its transform is not finite (an infinite scale or location, "
                            f"beyond {MAX_TRANSFORM:g}); not drawn")
            return
        if obj.type == "LIGHT" and is_forward_light(obj.data):
            forward.append(forward_light(name, obj.data, mw))
        elif obj.type in MESH_LIKE:
            found = ex.renderers(obj, mw, name)
            if instancer:  # e.g. geometry nodes that turn all geometry into instances: no "empty mesh"
                found = [r for r in found if r.mesh.triangle_count]
            renderers.extend(found)

    # Curves and text evaluate to a mesh component that the depsgraph lists as an
    # instance of the object itself: draw that, not the curve.
    components: set[int] = set()
    instancers: set[int] = set()  # objects that instance other objects (particles, geometry nodes)
    for inst in depsgraph.object_instances:
        if inst.is_instance and inst.parent is not None:
            own = inst.object.original == inst.parent.original
            (components if own else instancers).add(inst.parent.original.as_pointer())
    seen: set[int] = set()
    for inst in depsgraph.object_instances:
        obj = inst.object
        original = obj.original
        if not inst.is_instance:
            key = original.as_pointer()
            seen.add(key)
            if (check_visibility and key not in visible) or not inst.show_self:
                continue
            if obj.type in ("CURVE", "FONT", "SURFACE") and key in components:
                continue
            add(obj, original.name, inst.matrix_world, instancer=key in instancers)
        else:
            parent = inst.parent.original if inst.parent is not None else original
            if (check_visibility and parent.as_pointer() not in visible) or not inst.show_self:
                continue
            if original == parent:
                name = parent.name
            else:
                name = f"{parent.name}/{original.name}#{inst.random_id & 0xFFFFFFFF:08x}"
            add(obj, name, inst.matrix_world)
    if check_visibility:
        # A viewport depsgraph leaves out objects hidden in the viewport that still render.
        for original in view_layer.objects:
            key = original.as_pointer()
            if key in seen or key not in visible or original.type not in MESH_LIKE | {"LIGHT"}:
                continue
            obj = original.evaluated_get(depsgraph)
            if not obj.is_evaluated:
                warnings.append(f"object {original.name!r} is disabled in viewports: "
                                "rendered without modifiers (enable it, or render with the Unity Passes engine)")
            add(obj, original.name, obj.matrix_world)
    warnings.extend(ex.slot_warnings())

    # The main light (ForwardBase's): the Sun with the largest intensity × max(colour), ties by
    # name; every other light is an additional forward light.
    light = None
    suns = [f for f in forward if f.type is LightType.Directional]
    if suns:
        main = min(suns, key=lambda f: (-f.intensity * max(f.color), f.name))
        light = Light(direction=main.axis, color=main.color, energy=main.intensity, name=main.name)
        forward.remove(main)

    if settings["ambient_from_world"]:
        ambient, ambient_linear = world_ambient(scene.world), True
    else:
        ambient, ambient_linear = tuple(settings["ambient_color"][:3]), False

    return DrawScene(
        camera=camera,
        renderers=tuple(renderers),
        light=light,
        ambient=tuple(float(c) for c in ambient),
        ambient_is_linear=ambient_linear,
        color_space=ColorSpace.parse(settings["color_space"]),
        hdr=settings["hdr"],
        clear_color=tuple(settings["clear_color"]),
        sort_mode=SortMode.parse(settings["sort_mode"]),
        sort_axis=tuple(settings["sort_axis"]),
        warnings=warnings,
        lights=tuple(sorted(forward, key=lambda f: f.name)),
        pixel_light_count=settings["pixel_light_count"],
        msaa=settings["msaa"],
    )


def _depsgraph_for(scene: Any) -> Any:
    """The evaluated (viewport) depsgraph of ``scene`` and its first render-enabled view layer."""
    import bpy

    if scene == bpy.context.scene:
        return bpy.context.evaluated_depsgraph_get()
    layer = next((v for v in scene.view_layers if v.use), scene.view_layers[0])
    with bpy.context.temp_override(scene=scene, view_layer=layer):
        return bpy.context.evaluated_depsgraph_get()


def _camera(cam_eval: Any, depsgraph: Any, scene: Any, width: int, height: int) -> Camera:
    r = scene.render
    proj = cam_eval.calc_matrix_camera(depsgraph, x=width, y=height,
                                       scale_x=float(r.pixel_aspect_x), scale_y=float(r.pixel_aspect_y))
    try:
        view = _matrix(cam_eval.matrix_world.inverted())
    except ValueError:
        raise SceneError(f"camera {cam_eval.name!r}: its transform cannot be inverted (a scale of 0?)") from None
    if not np.all(np.isfinite(view)):
        raise SceneError(f"camera {cam_eval.name!r}: its transform is not finite")
    return Camera(view_matrix=view, projection=_matrix(proj), width=int(width), height=int(height),
                  orthographic=cam_eval.data.type == "ORTHO")

