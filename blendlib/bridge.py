"""The bpy bridge: a Blender scene → :class:`blendlib.scene.DrawScene`, and a Frame → a Blender image.

This is the only module of :mod:`blendlib` that imports ``bpy``, and it does so
inside functions, so that the property schema below (plain data, shared with the
add-on) can be imported anywhere.

The bridge never modifies scene data: evaluated meshes come from
``Object.evaluated_get(depsgraph).to_mesh()`` and are released with
``to_mesh_clear()``; the add-on properties are read, never written. When the
add-on is not registered, ``Material.unity`` / ``Scene.unity`` are read from the
stored ID properties (``bl_system_properties_get()``); absent values take the
defaults of shared/SPEC.md §3.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import colorspace, pipeline
from .scene import Camera, DrawScene, Light, Mesh, Renderer, SceneError
from .shaderlab import (
    CHANNELS,
    BlendFactor,
    BlendOp,
    ColorSpace,
    CompareFunction,
    Cull,
    Lighting,
    Material,
    Pass,
    Queue,
    SortMode,
    StencilOp,
    Texture,
    TextureFilter,
    TextureWrap,
    pass_from_dict,
)

# ---------------------------------------------------------------------------
# Property schema (SPEC §3). The add-on builds its bpy properties from these
# tables, and the bridge reads stored values through them, so the two agree on
# names, defaults and the integers Blender stores for enum items.
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Field:
    """One add-on property.

    ``kind``: ``bool``, ``int``, ``float``, ``enum``, ``flags``, ``color``, ``vector``,
    ``string``, ``image`` or ``passes``. Enum items are stored by Blender as the index
    of the member in its :mod:`blendlib.shaderlab` enum class (``enum_items`` may
    list a subset, e.g. ZTest without ``Never``); ``flags`` (ColorMask) as bits
    R=1, G=2, B=4, A=8.
    """

    name: str
    kind: str
    default: Any
    label: str
    description: str
    enum: Any = None
    enum_items: tuple = ()
    size: int = 0
    subtype: str = "NONE"
    min: float | None = None
    max: float | None = None
    soft_min: float | None = None
    soft_max: float | None = None

    def items(self):
        """``(identifier, number)`` pairs of an enum field, in display order."""
        members = self.enum_items or tuple(self.enum)
        return [(m.value, list(self.enum).index(m)) for m in members]


FLAG_BITS = {c: 1 << i for i, c in enumerate(CHANNELS)}

_FACTOR_DOC = "Blend factor"

PASS_FIELDS: tuple[Field, ...] = (
    Field("name", "string", "Pass", "Name", "Pass name (ShaderLab Name \"...\"); for your reference only"),
    Field("cull", "enum", "Back", "Cull",
          "Cull: which faces are not drawn (front = the side Blender's normal points to)", enum=Cull),
    Field("zwrite", "bool", True, "ZWrite", "ZWrite On/Off: write the fragment depth to the depth buffer"),
    Field("ztest", "enum", "LEqual", "ZTest", "ZTest: depth comparison that a fragment must pass",
          enum=CompareFunction, enum_items=tuple(c for c in CompareFunction if c is not CompareFunction.Never)),
    Field("blend", "bool", False, "Blend", "Blend on (factors below) or Blend Off (write the shader colour)"),
    Field("src_blend", "enum", "One", "Src", "Blend source factor (multiplies the shader colour)", enum=BlendFactor),
    Field("dst_blend", "enum", "Zero", "Dst", "Blend destination factor (multiplies the frame colour)",
          enum=BlendFactor),
    Field("blend_op", "enum", "Add", "BlendOp", "BlendOp: how source and destination terms are combined",
          enum=BlendOp),
    Field("separate_alpha", "bool", False, "Separate Alpha",
          "Use separate blend factors and op for the alpha channel (Blend A B, C D)"),
    Field("src_blend_alpha", "enum", "One", "Src Alpha", "Alpha blend source factor", enum=BlendFactor),
    Field("dst_blend_alpha", "enum", "Zero", "Dst Alpha", "Alpha blend destination factor", enum=BlendFactor),
    Field("blend_op_alpha", "enum", "Add", "BlendOp Alpha", "Alpha BlendOp", enum=BlendOp),
    Field("color_mask", "flags", frozenset(CHANNELS), "ColorMask",
          "ColorMask: channels written to the colour buffer (none = ColorMask 0)"),
    Field("offset_factor", "float", 0.0, "Offset Factor", "Offset factor (glPolygonOffset factor: slope scale)",
          soft_min=-10.0, soft_max=10.0),
    Field("offset_units", "float", 0.0, "Offset Units", "Offset units (glPolygonOffset units of 2^-24 depth)",
          soft_min=-100.0, soft_max=100.0),
    Field("alpha_test", "bool", False, "Alpha Test", "clip(alpha - _Cutoff) in this pass"),
    Field("stencil", "bool", False, "Stencil", "Enable the Stencil { } block of this pass"),
    Field("stencil_ref", "int", 0, "Ref", "Stencil Ref value", min=0, max=255),
    Field("stencil_read_mask", "int", 255, "ReadMask", "Stencil ReadMask", min=0, max=255),
    Field("stencil_write_mask", "int", 255, "WriteMask", "Stencil WriteMask", min=0, max=255),
    Field("stencil_comp", "enum", "Always", "Comp", "Stencil Comp: (Ref & ReadMask) Comp (stencil & ReadMask)",
          enum=CompareFunction),
    Field("stencil_pass", "enum", "Keep", "Pass", "Stencil operation when stencil and depth tests pass",
          enum=StencilOp),
    Field("stencil_fail", "enum", "Keep", "Fail", "Stencil operation when the stencil test fails", enum=StencilOp),
    Field("stencil_zfail", "enum", "Keep", "ZFail", "Stencil operation when the depth test fails", enum=StencilOp),
)

MATERIAL_FIELDS: tuple[Field, ...] = (
    Field("enabled", "bool", False, "Unity Material",
          "Render with these Unity settings; off: a default opaque material from the Principled BSDF"),
    Field("queue", "enum", "Geometry", "Queue", "Render queue (Tags { \"Queue\"=... })", enum=Queue),
    Field("queue_offset", "int", 0, "Offset", "Added to the queue number (\"Transparent+1\")",
          soft_min=-100, soft_max=100),
    Field("color", "color", (1.0, 1.0, 1.0, 1.0), "_Color", "_Color (sRGB-encoded, like a Unity colour property)",
          size=4, subtype="COLOR_GAMMA", min=0.0, soft_max=1.0),
    Field("main_tex", "image", None, "_MainTex", "_MainTex (none = white)"),
    Field("main_tex_tiling", "vector", (1.0, 1.0), "Tiling", "_MainTex tiling (_MainTex_ST.xy)", size=2,
          soft_min=-100.0, soft_max=100.0),
    Field("main_tex_offset", "vector", (0.0, 0.0), "Offset", "_MainTex offset (_MainTex_ST.zw)", size=2,
          soft_min=-10.0, soft_max=10.0),
    Field("main_tex_filter", "enum", "Bilinear", "Filter", "Sampler filter mode (no mipmaps)", enum=TextureFilter),
    Field("main_tex_wrap", "enum", "Repeat", "Wrap", "Sampler wrap mode", enum=TextureWrap),
    Field("alpha_scale", "float", 1.0, "_AlphaScale", "_AlphaScale: multiplies the alpha", min=0.0, max=1.0,
          subtype="FACTOR"),
    Field("cutoff", "float", 0.5, "_Cutoff", "_Cutoff: alpha-tested passes discard alpha < _Cutoff", min=0.0,
          max=1.0, subtype="FACTOR"),
    Field("lighting", "enum", "Lambert", "Lighting",
          "Lambert: the book's ForwardBase fragment (ambient + main light); Unlit: albedo only", enum=Lighting),
    Field("passes", "passes", (), "Passes", "Passes drawn in order (none = one default pass)"),
)

SCENE_FIELDS: tuple[Field, ...] = (
    Field("color_space", "enum", "Gamma", "Color Space",
          "Unity's Player colour space: Gamma blends encoded values, Linear blends in linear space", enum=ColorSpace),
    Field("hdr", "bool", False, "HDR", "HDR float colour buffer; off: 8-bit UNORM buffer"),
    Field("clear_color", "color", (0.19, 0.30, 0.47, 0.0), "Clear Color",
          "Camera background colour (sRGB-encoded, Solid Color clear)", size=4, subtype="COLOR_GAMMA",
          min=0.0, soft_max=1.0),
    Field("ambient_from_world", "bool", True, "Ambient from World",
          "Ambient = the World background colour (Background Color x Strength)"),
    Field("ambient_color", "color", (0.2, 0.2, 0.2), "Ambient Color",
          "Ambient colour (sRGB-encoded) when not taken from the World", size=3, subtype="COLOR_GAMMA",
          min=0.0, soft_max=1.0),
    Field("sort_mode", "enum", "Default", "Sort Mode",
          "Transparency sort: camera distance (Perspective), view depth (Orthographic) or along an axis",
          enum=SortMode),
    Field("sort_axis", "vector", (0.0, 0.0, 1.0), "Sort Axis", "Axis for the CustomAxis sort mode", size=3,
          soft_min=-1.0, soft_max=1.0, subtype="XYZ"),
)


def _stored_value(f: Field, raw: Any) -> Any:
    """A stored ID-property value (or an RNA value) → the identifier form used by the core."""
    if f.kind == "enum":
        if isinstance(raw, str):
            return raw
        members = list(f.enum)
        idx = int(raw)
        return members[idx].value if 0 <= idx < len(members) else f.default
    if f.kind == "flags":
        if isinstance(raw, (set, frozenset)):
            return frozenset(raw)
        bits = int(raw)
        return frozenset(c for c, b in FLAG_BITS.items() if bits & b)
    if f.kind in ("color", "vector"):
        return tuple(float(v) for v in raw)
    if f.kind == "bool":
        return bool(raw)
    if f.kind == "int":
        return int(raw)
    if f.kind == "float":
        return float(raw)
    if f.kind == "string":
        return str(raw)
    return raw


def _as_float32(value: Any) -> Any:
    if isinstance(value, tuple):
        return tuple(float(np.float32(v)) for v in value)
    return float(np.float32(value))


def read_group(source: Any, fields: tuple[Field, ...]) -> dict[str, Any]:
    """Plain dict of a property group: ``source`` is an RNA PropertyGroup, a stored IDPropertyGroup,
    a dict, or None (all defaults). Passes come back as a list of dicts."""
    out: dict[str, Any] = {}
    for f in fields:
        raw = None
        if source is not None:
            if hasattr(source, "bl_rna"):
                raw = getattr(source, f.name, None)
            else:
                try:
                    raw = source.get(f.name)
                except AttributeError:
                    raw = None
        if f.kind == "passes":
            out[f.name] = [read_group(item, PASS_FIELDS) for item in (raw or ())]
        elif f.kind == "image":
            out[f.name] = raw
        elif raw is None:  # never set: the default, as Blender would store it (float32)
            out[f.name] = _stored_value(f, _as_float32(f.default)) if f.kind in ("float", "color", "vector") \
                else f.default
        else:
            out[f.name] = _stored_value(f, raw)
    return out


def unity_props(id_block: Any) -> Any:
    """``id_block.unity`` when the add-on is registered, else its stored group (or None)."""
    group = getattr(id_block, "unity", None)
    if group is not None and hasattr(group, "bl_rna"):
        return group
    getter = getattr(id_block, "bl_system_properties_get", None)
    if getter is not None:
        store = getter()
        return None if store is None else store.get("unity")
    try:  # Blender < 5.0 keeps add-on properties with the custom properties
        return id_block.get("unity")
    except (AttributeError, TypeError):
        return None


def pass_from_values(values: dict[str, Any]) -> Pass:
    """A :class:`Pass` from a dict of :data:`PASS_FIELDS` values (identifiers, set colour mask)."""
    return pass_from_dict({k: (sorted(v) if k == "color_mask" else v) for k, v in values.items()})


# ---------------------------------------------------------------------------
# Colour helpers (docs/pipeline.md §7)
# ---------------------------------------------------------------------------


# ---------------------------------------------------------------------------
# Scene extraction
# ---------------------------------------------------------------------------

MESH_LIKE = {"MESH", "CURVE", "SURFACE", "META", "FONT"}
MAGENTA = (1.0, 0.0, 1.0, 1.0)


def render_size(scene: Any) -> tuple[int, int]:
    """Render resolution × percentage, as Blender computes it (integer division)."""
    r = scene.render
    return (r.resolution_x * r.resolution_percentage) // 100, (r.resolution_y * r.resolution_percentage) // 100


def _matrix(m: Any) -> np.ndarray:
    return np.array([list(row) for row in m], dtype=np.float64)


class _Extractor:
    def __init__(self, depsgraph: Any, warnings: list[str]):
        self.dg = depsgraph
        self.warnings = warnings
        self.materials: dict[int, Material] = {}
        self.textures: dict[int, Texture] = {}
        self.default_material = Material(name="Default")

    # -- textures -----------------------------------------------------------
    def texture(self, image: Any) -> Texture | None:
        if image is None:
            return None
        image = getattr(image, "original", image) or image
        key = image.as_pointer()
        if key not in self.textures:
            self.textures[key] = self._load_texture(image)
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
        values = read_group(unity_props(mat), MATERIAL_FIELDS)
        texture = self.texture if with_texture else (lambda image: None)
        if not values["enabled"]:
            color, image = principled_inputs(mat)
            return Material(name=mat.name, color=color, main_tex=texture(image))
        passes = tuple(pass_from_values(p) for p in values["passes"])
        return Material(
            name=mat.name,
            queue=Queue.parse(values["queue"]),
            queue_offset=values["queue_offset"],
            color=tuple(values["color"]),
            main_tex=texture(values["main_tex"]),
            main_tex_tiling=tuple(values["main_tex_tiling"]),
            main_tex_offset=tuple(values["main_tex_offset"]),
            main_tex_filter=TextureFilter.parse(values["main_tex_filter"]),
            main_tex_wrap=TextureWrap.parse(values["main_tex_wrap"]),
            alpha_scale=values["alpha_scale"],
            cutoff=values["cutoff"],
            lighting=Lighting.parse(values["lighting"]),
            passes=passes or (Pass(),),
        )

    # -- meshes ----------------------------------------------------------------
    def renderers(self, obj_eval: Any, matrix_world: np.ndarray, name: str) -> list[Renderer]:
        mesh = obj_eval.to_mesh()
        try:
            return self._mesh_renderers(obj_eval, mesh, matrix_world, name)
        finally:
            obj_eval.to_mesh_clear()

    def _mesh_renderers(self, obj_eval: Any, mesh: Any, matrix_world: np.ndarray, name: str) -> list[Renderer]:
        if mesh is None:
            return []
        arrays = mesh_arrays(mesh)
        positions = arrays["positions"]
        slots = obj_eval.material_slots
        mats = [s.material for s in slots] or list(mesh.materials)
        if len(positions):
            lo, hi = positions.min(axis=0).astype(np.float64), positions.max(axis=0).astype(np.float64)
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
            else:
                sel = np.flatnonzero(tri_mat == slot)
            mat = mats[slot] if slot < len(mats) else None
            if mat is None and len(arrays["triangles"]):
                if mats:
                    self.warnings.append(
                        f"object {name!r} slot {slot}: empty material slot, using the default material")
            uvs = arrays["uvs"]
            sub = Mesh(
                positions=positions,
                triangles=arrays["triangles"][sel],
                normals=arrays["normals"][sel],
                uvs=None if uvs is None else uvs[sel],
            )
            out.append(Renderer(name=name, slot=int(slot), mesh=sub, matrix_world=matrix_world,
                                material=self.material(mat), bounds_center=center))
        return out


def open_blend(path: Any) -> Any:
    """Open a .blend file (replacing Blender's current data) and return ``bpy.data``.

    Raises :class:`SceneError` with one line naming the file and Blender's reason.
    """
    import os

    import bpy

    try:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(str(path)), load_ui=False)
    except RuntimeError as exc:
        lines = str(exc).strip().splitlines()
        reason = lines[-1].removeprefix("Error: ").strip() if lines else "unknown error"
        raise SceneError(f"{path}: cannot open .blend file ({reason})") from None
    return bpy.data


def scene_named(name: str | None, where: Any = "file") -> Any:
    """The scene called ``name`` (the context scene for None); SceneError naming the choices."""
    import bpy

    if name is None:
        return bpy.context.scene
    scene = bpy.data.scenes.get(name)
    if scene is None:
        names = ", ".join(repr(s.name) for s in bpy.data.scenes)
        raise SceneError(f"{where}: no scene named {name!r} (scenes: {names})")
    return scene


def material_from_blender(mat: Any, with_texture: bool = False) -> Material:
    """The Unity material of a ``bpy.types.Material`` as it renders (SPEC §3), with or without its image.

    Reads ``mat.unity`` when the add-on is registered, else the stored properties; a
    disabled material gives the default opaque material from its Principled BSDF.
    """
    return _Extractor(None, [])._convert_material(mat, with_texture=with_texture)


def mesh_arrays(mesh: Any) -> dict[str, np.ndarray | None]:
    """Triangles of a (temporary, evaluated) Blender mesh as numpy arrays, via fast ``foreach_get``.

    ``positions`` (V, 3) float32, ``triangles`` (T, 3) int32 vertex indices in loop-triangle
    order, ``normals`` (T, 3, 3) float32 corner normals, ``uvs`` (T, 3, 2) float32 of the
    active UV map or None, ``material_index`` (T,) int32.
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
    attr = mesh.attributes.get("material_index")
    if attr is not None and t and attr.domain == "FACE" and attr.data_type == "INT":
        poly_mat = np.empty(len(mesh.polygons), np.int32)
        attr.data.foreach_get("value", poly_mat)
        tri_poly = np.empty(t, np.int32)
        mesh.loop_triangle_polygons.foreach_get("value", tri_poly)
        material_index = np.take(poly_mat, tri_poly)
    return {"positions": positions, "triangles": triangles, "normals": normals, "uvs": uvs,
            "material_index": material_index}


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


def scene_settings(scene: Any) -> dict[str, Any]:
    """``Scene.unity`` as a dict of identifiers (defaults where absent)."""
    return read_group(unity_props(scene), SCENE_FIELDS)


def build_draw_scene(scene: Any = None, depsgraph: Any = None) -> DrawScene:
    """A :class:`DrawScene` of a ``bpy.types.Scene`` (default: the context scene).

    ``depsgraph``: an evaluated depsgraph of the scene (the render engine passes its
    render depsgraph); default ``bpy.context.evaluated_depsgraph_get()`` for the
    context scene. Raises :class:`SceneError` when the scene has no camera.
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
    check_visibility = depsgraph.mode != "RENDER"
    warnings: list[str] = []
    settings = scene_settings(scene)

    cam_obj = scene.camera
    if cam_obj is None:
        raise SceneError(f"scene {scene.name!r} has no camera")
    if cam_obj.type != "CAMERA":
        raise SceneError(f"scene {scene.name!r}: active camera {cam_obj.name!r} is not a camera object")
    width, height = render_size(scene)
    camera = _camera(cam_obj.evaluated_get(depsgraph), depsgraph, scene, width, height)

    ex = _Extractor(depsgraph, warnings)
    renderers: list[Renderer] = []
    suns: list[tuple[float, str, Any, np.ndarray]] = []
    visible = render_visible_objects(view_layer) if check_visibility else set()

    def add(obj: Any, name: str, matrix: Any) -> None:
        mw = _matrix(matrix)
        if obj.type == "LIGHT" and obj.data.type == "SUN":
            energy = float(obj.data.energy)
            suns.append((energy * max(float(c) for c in obj.data.color), name, obj, mw))
        elif obj.type in MESH_LIKE:
            renderers.extend(ex.renderers(obj, mw, name))

    # Curves and text evaluate to a mesh component that the depsgraph lists as an
    # instance of the object itself: draw that, not the curve.
    components: set[int] = set()
    for inst in depsgraph.object_instances:
        if inst.is_instance and inst.parent is not None and inst.object.original == inst.parent.original:
            components.add(inst.parent.original.as_pointer())
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
            add(obj, original.name, inst.matrix_world)
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

    light = None
    if suns:
        best = max(s[0] for s in suns)
        _, name, obj, mw = min((s for s in suns if s[0] == best), key=lambda s: s[1])
        axis = mw[:3, :3] @ np.array([0.0, 0.0, 1.0])
        norm = float(np.linalg.norm(axis))
        direction = tuple(float(v) for v in (axis / norm if norm > 0 else np.array([0.0, 0.0, 1.0])))
        light = Light(direction=direction, color=tuple(float(c) for c in obj.data.color),
                      energy=float(obj.data.energy), name=name)

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
    view = _matrix(cam_eval.matrix_world.inverted())
    return Camera(view_matrix=view, projection=_matrix(proj), width=int(width), height=int(height),
                  orthographic=cam_eval.data.type == "ORTHO")


def render(scene: Any = None, depsgraph: Any = None, progress: Callable[[float], None] | None = None,
           should_cancel: Callable[[], bool] | None = None) -> pipeline.Frame:
    """Render a Blender scene with the Unity pipeline; see :func:`blendlib.render`.

    The Frame's ``warnings`` hold the extraction warnings followed by the core's.
    Raises :class:`SceneError` (no camera, bad input) or :class:`pipeline.RenderCancelled`.
    """
    draw = build_draw_scene(scene, depsgraph)
    frame = pipeline.render_scene(draw, progress=progress, should_cancel=should_cancel)
    extra = [w for w in draw.warnings if w not in frame.warnings]
    frame.warnings[:0] = extra
    return frame


_CAPTURE_ENGINE_ID = "UNITY_PASSES_CAPTURE"
_capture: dict[str, Any] = {}
_capture_engine: list = []


def _capture_engine_class() -> Any:
    """A minimal render engine that renders with the Unity pipeline and keeps the Frame in memory.

    Registered on first use (not listed for users: the add-on's engine is ``UNITY_PASSES``).
    """
    import bpy

    if _capture_engine:
        return _capture_engine[0]

    class UnityPassesCaptureEngine(bpy.types.RenderEngine):
        bl_idname = _CAPTURE_ENGINE_ID
        bl_label = "Unity Passes (capture)"
        bl_use_preview = False

        def render(self, depsgraph):
            try:
                _capture["frame"] = render(depsgraph.scene, depsgraph, progress=_capture.get("progress"),
                                           should_cancel=_capture.get("should_cancel"))
            except Exception as exc:  # noqa: BLE001 - handed back to render_final's caller
                _capture["error"] = exc

    bpy.utils.register_class(UnityPassesCaptureEngine)
    _capture_engine.append(UnityPassesCaptureEngine)
    return UnityPassesCaptureEngine


def render_final(scene: Any = None, progress: Callable[[float], None] | None = None,
                 should_cancel: Callable[[], bool] | None = None, frame: int | None = None) -> pipeline.Frame:
    """Render as F12 does: through Blender's render-mode depsgraph.

    :func:`render` uses the viewport depsgraph (Python cannot make a render-mode one), so
    modifiers evaluate with their viewport settings there. This runs ``bpy.ops.render.render``
    with a capture engine instead, so modifier render levels and render visibility apply
    exactly as for F12 and ``blender -b -E UNITY_PASSES``. The scene's render engine is set
    for the call and restored; no image is written. ``frame``: the frame to set first.
    Raises like :func:`render`.
    """
    import bpy

    scene = scene or bpy.context.scene
    if scene.camera is None:  # checked here: the operator would fail with its own wording
        raise SceneError(f"scene {scene.name!r} has no camera")
    engine = _capture_engine_class()
    previous = scene.render.engine
    _capture.clear()
    _capture.update(progress=progress, should_cancel=should_cancel)
    scene.render.engine = engine.bl_idname
    try:
        with bpy.context.temp_override(scene=scene):
            if frame is not None:
                scene.frame_set(frame)
            bpy.ops.render.render(scene=scene.name)
    finally:
        scene.render.engine = previous
    if "error" in _capture:
        raise _capture.pop("error")
    if "frame" not in _capture:
        raise SceneError(f"scene {scene.name!r}: Blender did not render it (no view layer enabled for rendering?)")
    result = _capture.pop("frame")
    _capture.clear()
    return result


def linear_rgba(frame: pipeline.Frame, encoded: bool | None = None, opaque: bool = False) -> np.ndarray:
    """The frame as linear RGBA float32 (row 0 top): encoded frame values are decoded to linear.
    ``opaque``: alpha 1 (what a screen shows, the Combined pass)."""
    if encoded is None:
        encoded = frame.encoded
    color = np.array(frame.color, dtype=np.float32, copy=True)
    if encoded:
        color[..., :3] = colorspace.decode_fast(color[..., :3]).astype(np.float32)
    if opaque:
        color[..., 3] = 1.0
    return color


def write_image(frame: pipeline.Frame, name: str, *, encoded: bool | None = None, opaque: bool = False) -> Any:
    """Write a frame into the ``bpy.types.Image`` called ``name`` (created, or resized, as a float image).

    The image holds linear RGB (encoded frame values decoded; ``encoded`` overrides what the
    frame says) and the frame's alpha (or 1 with ``opaque``), bottom row first as Blender stores it,
    so that the Image Editor with the Standard view transform shows the frame values.
    """
    import bpy

    h, w = frame.color.shape[:2]
    image = bpy.data.images.get(name)
    if image is not None and (not image.is_float or image.source != "GENERATED"):
        bpy.data.images.remove(image)
        image = None
    if image is None:
        image = bpy.data.images.new(name, width=w, height=h, alpha=True, float_buffer=True)
    elif tuple(image.size) != (w, h):
        image.scale(w, h)
    rgba = linear_rgba(frame, encoded=encoded, opaque=opaque)
    image.pixels.foreach_set(np.ascontiguousarray(rgba[::-1]).ravel())
    image.update()
    return image

