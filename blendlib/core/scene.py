"""Plain data the renderer core takes: a draw scene of renderers, camera, light and frame settings.

Nothing here imports bpy; the Blender layer (:mod:`blendlib.blender`) builds these from a
Blender scene, tests build them by hand. Arrays are numpy; shapes and dtypes are
stated per field and checked by :func:`validate_scene`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .vocabulary import MSAA_SAMPLES, ColorSpace, LightRenderMode, LightType, Material, SortMode, Texture


class SceneError(ValueError):
    """Bad input to the core: the message is one line naming the object and what is wrong."""


@dataclass(frozen=True, eq=False)
class Mesh:
    """Triangles of one renderer, in object space.

    - ``positions``: (V, 3) float32/float64 vertex positions.
    - ``triangles``: (T, 3) integer vertex indices, in Blender's loop-triangle order
      (the draw order of the triangles).
    - ``normals``: (T, 3, 3) float32 object-space normals per triangle corner.
    - ``uvs``: (T, 3, 2) float32 texture coordinates per corner, or None (all zero).
    - ``polygons``: (T,) integer face index of each triangle (Blender's
      ``loop_triangle_polygons``), or None (a synthetic mesh: no faces).
    - ``loop_triangles``: (T,) integer index of each triangle in the evaluated mesh's
      ``loop_triangles`` (a material slot takes a subset), or None (the triangle's own index).

    - ``colors``: (T, 3, 4) float32 vertex colours (``i.color``) per corner, RGBA, or None (white):
      the mesh's active colour attribute. ``color_encoding`` says what the RGB values are, as
      :class:`~.vocabulary.Texture`'s ``encoding``: ``"sRGB"`` (encoded values: a Blender byte
      colour attribute, k/255) or ``"Linear"`` (a float colour attribute). Alpha is never converted.

    ``polygons`` and ``loop_triangles`` only name triangles for the frame debugger.
    """

    positions: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray | None = None
    polygons: np.ndarray | None = None
    loop_triangles: np.ndarray | None = None
    colors: np.ndarray | None = None
    color_encoding: str = "sRGB"

    @property
    def triangle_count(self) -> int:
        return int(self.triangles.shape[0])

    @functools.cached_property
    def half_size(self) -> np.ndarray:
        """(3,) float64: half the size of the local (object-space) bounding box of ``positions``,
        zero for a mesh without vertices; computed once per mesh (the draw list asks for it per
        light and frame: :func:`.drawlist.world_half_extent`)."""
        positions = np.asarray(self.positions, dtype=np.float64)
        if positions.size == 0:
            return np.zeros(3, dtype=np.float64)
        return (positions.max(axis=0) - positions.min(axis=0)) / 2.0


@dataclass(frozen=True, eq=False)
class Renderer:
    """One Unity renderer: one object's triangles that use one material slot.

    ``matrix_world`` (4, 4) float64 object → world. ``bounds_center`` (3,) float64:
    centre of the object's world-space bounding box (the sort point of docs/pipeline.md §0).
    ``name`` is the object name and ``slot`` the material slot index (sort ties).
    """

    name: str
    slot: int
    mesh: Mesh
    matrix_world: np.ndarray
    material: Material
    bounds_center: np.ndarray


@dataclass(frozen=True, eq=False)
class Camera:
    """The render camera.

    - ``view_matrix`` (4, 4) float64: world → camera (Blender camera looks down its −Z).
    - ``projection`` (4, 4) float64: camera → OpenGL clip space, as
      ``Object.calc_matrix_camera(depsgraph, x=W, y=H, scale_x, scale_y)`` gives it.
    - ``width``, ``height``: the frame size in pixels (resolution × percentage).
    - ``orthographic``: True for orthographic cameras (the Default sort mode follows it).
    """

    view_matrix: np.ndarray
    projection: np.ndarray
    width: int
    height: int
    orthographic: bool = False

    @functools.cached_property
    def position(self) -> np.ndarray:
        """World-space camera position (3,) float64 (computed once per camera)."""
        return affine_inverse(self.view_matrix)[:3, 3]

    @functools.cached_property
    def forward(self) -> np.ndarray:
        """World-space unit view direction (3,) float64 (the camera's −Z axis)."""
        axis = -affine_inverse(self.view_matrix)[:3, 2]
        return axis / math.sqrt(float(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]))


def cofactors3(matrix) -> tuple[list[list[float]], float]:
    """Cofactor matrix (3x3 nested lists of Python floats) of ``matrix``'s upper-left 3x3 and its
    determinant, with the explicit sums of docs/pipeline.md §1."""
    c, det = cofactors3_many(np.asarray(matrix, dtype=np.float64)[None])
    return c[0].tolist(), float(det[0])


#: For each index i of 0..2: (i + 1) % 3 and (i + 2) % 3 (a 3x3 matrix's other rows, a triangle
#: edge's two vertices).
CYCLIC_NEXT = np.array([1, 2, 0])
CYCLIC_AFTER = np.array([2, 0, 1])


def cofactors3_many(matrices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`cofactors3` of each of ``matrices`` (R, >=3, >=3): cofactors (R, 3, 3) and
    determinants (R,) float64. Element by element ``c[i][j] = a[i+1][j+1]*a[i+2][j+2] -
    a[i+1][j+2]*a[i+2][j+1]`` (indices mod 3) and ``det = (a00*c00 + a01*c01) + a02*c02``."""
    m = np.asarray(matrices, dtype=np.float64)[:, :3, :3]
    i1, i2, j1, j2 = CYCLIC_NEXT[:, None], CYCLIC_AFTER[:, None], CYCLIC_NEXT[None, :], CYCLIC_AFTER[None, :]
    c = m[:, i1, j1] * m[:, i2, j2] - m[:, i1, j2] * m[:, i2, j1]
    det = (m[:, 0, 0] * c[:, 0, 0] + m[:, 0, 1] * c[:, 0, 1]) + m[:, 0, 2] * c[:, 0, 2]
    return c, det


def matmul4_many(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The 4x4 products of docs/pipeline.md §1 of ``a`` (4, 4) with each of ``b`` (R, 4, 4):
    (R, 4, 4) float64, element
    ``[k, i, j] = ((a[i,0]*b[k,0,j] + a[i,1]*b[k,1,j]) + a[i,2]*b[k,2,j]) + a[i,3]*b[k,3,j]``
    (one multiply or add per array operation: the same roundings as written out)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    out = a[None, :, 0, None] * b[:, None, 0, :]
    for t in (1, 2, 3):
        out = out + a[None, :, t, None] * b[:, None, t, :]
    return out


def normal_matrices(matrices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The normal matrices of docs/pipeline.md §1 of ``matrices`` (R, 4, 4): sign-corrected
    cofactors of the upper 3x3 (R, 3, 3) and determinants (R,) float64."""
    c, det = cofactors3_many(matrices)
    return np.where((det < 0)[:, None, None], -c, c), det


def affine_inverse(matrix) -> np.ndarray:
    """Inverse (4, 4) float64 of an affine 4x4 matrix (last row 0 0 0 1), by cofactors.

    Written out rather than ``np.linalg.inv``: a LAPACK call wakes OpenBLAS's worker threads,
    which then spin for a while on the CPU the render's own threads need (a one-thread render
    used about twice its wall time in CPU). Non-affine matrices go to ``np.linalg.inv``.
    """
    m = np.asarray(matrix, dtype=np.float64)
    if not np.array_equal(m[3], (0.0, 0.0, 0.0, 1.0)):
        return np.linalg.inv(m)
    c, det = cofactors3(m)
    if det == 0.0 or not math.isfinite(det):
        raise np.linalg.LinAlgError("Singular matrix")
    out = np.eye(4, dtype=np.float64)
    out[:3, :3] = np.array(c, dtype=np.float64).T / det
    t = [float(v) for v in m[:3, 3]]
    for i in range(3):
        r = out[i, :3]
        out[i, 3] = -((r[0] * t[0] + r[1] * t[1]) + r[2] * t[2])
    return out


@dataclass(frozen=True)
class Light:
    """The main directional light (docs/pipeline.md §7): the render-visible Sun with the largest energy × max(colour).

    ``direction`` (3,) unit vector from the surface towards the light (the lamp's
    local +Z in world space). ``color`` is Blender's linear lamp colour; ``energy``
    its strength. The light colour in shading is ``color × energy`` (``color``
    sRGB-encoded first in Gamma mode).
    """

    direction: tuple[float, float, float]
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    energy: float = 1.0
    name: str = "Sun"


@dataclass(frozen=True)
class ForwardLight:
    """A Unity forward light other than the main directional one (SPEC §12): another Sun, a Point or
    a Spot light, with its ``Light.unity`` values (derived from the Blender light by default).

    ``position`` (3,) world-space location; ``axis`` (3,) unit vector, the lamp's local +Z in world
    space (a directional light shines from ``axis``, a spot along ``-axis``); ``color`` Blender's
    linear lamp colour (encoded to sRGB before the intensity multiplies it in Gamma mode, as the main
    light's); ``intensity`` Unity's ``Light.intensity``; ``range`` in scene units (point, spot);
    ``spot_angle`` the full cone angle in degrees; ``render_mode`` Auto / Important / NotImportant.
    """

    name: str
    type: LightType
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    range: float = 10.0
    spot_angle: float = 30.0
    render_mode: LightRenderMode = LightRenderMode.Auto


@dataclass(frozen=True, eq=False)
class DrawScene:
    """Everything one frame needs.

    ``ambient`` is an RGB colour; ``ambient_is_linear`` says whether it is a
    linear Blender colour (the World background) or COLOR_GAMMA (sRGB-encoded,
    ``Scene.unity.ambient_color``). ``clear_color`` is COLOR_GAMMA (encoded).
    """

    camera: Camera
    renderers: tuple[Renderer, ...] = ()
    light: Light | None = None
    ambient: tuple[float, float, float] = (0.2, 0.2, 0.2)
    ambient_is_linear: bool = False
    color_space: ColorSpace = ColorSpace.Gamma
    hdr: bool = False
    clear_color: tuple[float, float, float, float] = (0.19, 0.30, 0.47, 0.0)
    sort_mode: SortMode = SortMode.Default
    sort_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    warnings: list[str] = field(default_factory=list)
    #: Forward lights besides ``light`` (SPEC §12), in a stable order (by name).
    lights: tuple[ForwardLight, ...] = ()
    #: Unity's Quality "Pixel Light Count": per renderer, at most this many of ``lights`` are
    #: per-pixel (draw the ForwardAdd passes), Important ones always.
    pixel_light_count: int = 4
    #: Samples per pixel (``Scene.unity.msaa``): 1, 2, 4 or 8.
    msaa: int = 1


#: Refuse frames whose buffers alone would exceed this many pixels (about 1 GB of float32 RGBA).
MAX_PIXELS = 64 * 1024 * 1024


class SceneMemo:
    """What renders derive from a scene's renderers and materials alone, kept across renders of
    scenes that share those objects (the viewport's frames of one template: reduced and full,
    every view change): checked renderers, converted textures.

    Entries are keyed by the objects themselves, which the memo keeps alive (an id is never
    reused while its entry exists); they stay valid while nobody writes into those objects'
    arrays, so build a new scene for a changed one. A changed scene that shares parts with the
    last (:func:`reuse_unchanged`) keeps their entries through :meth:`retain`. One render at a time.
    """

    def __init__(self) -> None:
        self._entries: dict[tuple, tuple[object, object]] = {}

    def entries(self, kind) -> list[tuple[object, object]]:
        """The (object, value) entries of ``kind``."""
        return [hit for (k, _), hit in self._entries.items() if k == kind]

    def retain(self, scene: DrawScene) -> None:
        """Forget the entries of objects that are not parts of ``scene`` (:func:`scene_parts`):
        a new scene keeps what was derived from the parts it shares with the last one."""
        alive = {id(part) for part in scene_parts(scene)}
        self._entries = {key: hit for key, hit in self._entries.items() if id(hit[0]) in alive}

    def lookup(self, kind, obj, compute: Callable[[], object]):
        """``compute()`` for (``kind``, ``obj``), computed once."""
        key = (kind, id(obj))
        hit = self._entries.get(key)
        if hit is None or hit[0] is not obj:
            hit = (obj, compute())
            self._entries[key] = hit
        return hit[1]


def validate_scene(scene: DrawScene, memo: SceneMemo | None = None) -> list[str]:
    """Check a draw scene; raise :class:`SceneError` for what cannot render, return warnings.

    Fatal: bad camera matrices or size, absurd resolutions, non-finite matrices,
    mismatched array shapes. Warned (and rendered around): empty meshes.
    Non-finite or degenerate triangles are skipped by the rasterizer with a warning.
    With a ``memo``, renderers checked before are not checked again.
    """
    cam = scene.camera
    warnings: list[str] = []
    if scene.msaa not in MSAA_SAMPLES:
        raise SceneError(f"scene: MSAA must be 1, 2, 4 or 8 samples, got {scene.msaa!r}")
    if not (isinstance(scene.pixel_light_count, (int, np.integer)) and scene.pixel_light_count >= 0):
        raise SceneError(f"scene: pixel light count must be an integer 0 or more, got {scene.pixel_light_count!r}")
    for light in scene.lights:
        _validate_light(light)
    w, h = cam.width, cam.height
    if not (isinstance(w, (int, np.integer)) and isinstance(h, (int, np.integer))) or w < 1 or h < 1:
        raise SceneError(f"camera: resolution must be positive integers, got {w}x{h}")
    if int(w) * int(h) > MAX_PIXELS or w > 65536 or h > 65536:
        raise SceneError(
            f"camera: resolution {w}x{h} is too large ({w * h * 20 / 2**30:.1f} GiB of buffers; "
            f"the limit is {MAX_PIXELS} pixels and 65536 per side)"
        )
    for name in ("view_matrix", "projection"):
        m = np.asarray(getattr(cam, name), dtype=np.float64)
        if m.shape != (4, 4) or not np.isfinite(m).all():
            raise SceneError(f"camera: {name} must be a finite 4x4 matrix")
    if not all(math.isfinite(c) for c in scene.clear_color):
        raise SceneError("scene: clear_color is not finite")
    for r in scene.renderers:
        if memo is None:
            warnings += _validate_renderer(r)
        else:
            warnings += memo.lookup("valid", r, lambda r=r: _validate_renderer(r))
    return warnings


def _validate_light(light: ForwardLight) -> None:
    numbers = np.array([*light.position, *light.axis, *light.color, light.intensity, light.range,
                        light.spot_angle], dtype=np.float64)
    if not np.isfinite(numbers).all():
        raise SceneError(f"light {light.name!r}: its position, direction, colour and values must be finite")
    if light.intensity < 0 or light.range <= 0 or not 0 < light.spot_angle < 180:
        raise SceneError(f"light {light.name!r}: intensity must be 0 or more, range more than 0 and the spot "
                         f"angle between 0 and 180 degrees (got {light.intensity:g}, {light.range:g}, "
                         f"{light.spot_angle:g})")
    if float(np.dot(light.axis, light.axis)) == 0.0:
        raise SceneError(f"light {light.name!r}: its direction is a zero vector")


def _validate_renderer(r: Renderer) -> list[str]:
    """:func:`validate_scene`'s checks of one renderer: raises SceneError, returns warnings."""
    warnings: list[str] = []
    label = f"object {r.name!r} slot {r.slot}"
    mesh = r.mesh
    m = np.asarray(r.matrix_world, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise SceneError(f"{label}: matrix_world must be a finite 4x4 matrix")
    center = np.asarray(r.bounds_center, dtype=np.float64)
    if center.shape != (3,) or not np.isfinite(center).all():
        raise SceneError(f"{label}: bounds_center must be a finite 3-vector (it is the sort point)")
    pos, tri = np.asarray(mesh.positions), np.asarray(mesh.triangles)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise SceneError(f"{label}: positions must be (V, 3), got {pos.shape}")
    if tri.ndim != 2 or tri.shape[1] != 3 or not np.issubdtype(tri.dtype, np.integer):
        raise SceneError(f"{label}: triangles must be integer (T, 3), got {tri.dtype} {tri.shape}")
    t = tri.shape[0]
    if t and (tri.min() < 0 or tri.max() >= pos.shape[0]):
        raise SceneError(f"{label}: triangle indices out of range 0..{pos.shape[0] - 1}")
    if np.asarray(mesh.normals).shape != (t, 3, 3):
        raise SceneError(f"{label}: normals must be (T, 3, 3), got {np.asarray(mesh.normals).shape}")
    if mesh.uvs is not None and np.asarray(mesh.uvs).shape != (t, 3, 2):
        raise SceneError(f"{label}: uvs must be (T, 3, 2), got {np.asarray(mesh.uvs).shape}")
    if mesh.colors is not None and np.asarray(mesh.colors).shape != (t, 3, 4):
        raise SceneError(f"{label}: vertex colours must be (T, 3, 4), got {np.asarray(mesh.colors).shape}")
    if mesh.color_encoding not in ("sRGB", "Linear"):
        raise SceneError(f"{label}: vertex colour encoding must be sRGB or Linear, got {mesh.color_encoding!r}")
    for k, p in enumerate(r.material.draw_passes):
        if not (math.isfinite(p.outline_width) and math.isfinite(p.outline_max_distance)):
            raise SceneError(f"{label}: pass {k} ({p.name!r}): the outline width and max distance must be finite")
        if p.outline_color is not None and not all(math.isfinite(c) and c >= 0.0 for c in p.outline_color):
            raise SceneError(f"{label}: pass {k} ({p.name!r}): the outline colour must be finite and not "
                             f"negative, got {p.outline_color}")
        if not (0.0 <= p.outline_lighting_mix <= 1.0):
            raise SceneError(f"{label}: pass {k} ({p.name!r}): the outline lighting mix must be in 0..1, "
                             f"got {p.outline_lighting_mix}")
    for name in ("polygons", "loop_triangles"):
        ids = getattr(mesh, name)
        if ids is not None and np.asarray(ids).shape != (t,):
            raise SceneError(f"{label}: {name} must be (T,), got {np.asarray(ids).shape}")
    if t == 0:
        warnings.append(f"{label}: empty mesh, nothing drawn")
    return warnings


# ---------------------------------------------------------------------------------------------
# Unchanged parts of successive scenes (the viewport re-extracts the scene after every change)
# ---------------------------------------------------------------------------------------------


#: The :class:`Material` fields that hold a :class:`Texture`.
_TEXTURE_FIELDS = ("main_tex", "outline_width_tex")


def scene_parts(scene: DrawScene) -> list[object]:
    """The objects of ``scene`` that memos and the band helper key by, each once, parts before
    what holds them: per renderer its texture (if any), material, mesh, then the renderer."""
    parts: dict[int, object] = {}
    for r in scene.renderers:
        for part in (*(getattr(r.material, name) for name in _TEXTURE_FIELDS), r.material, r.mesh, r):
            if part is not None:
                parts.setdefault(id(part), part)
    return list(parts.values())


def _same_array(a, b) -> bool:
    """Both None, or arrays of one dtype and shape with the same bytes (so -0.0 is not 0.0,
    which could flip an infinity's sign downstream, and a NaN equals only the same NaN)."""
    if a is None or b is None:
        return a is b
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    if a.nbytes <= 1 << 16:  # small: bytes objects compare in a fifth of array_equal's call
        return a.tobytes() == b.tobytes()
    bits = f"u{a.itemsize}" if a.itemsize in (1, 2, 4, 8) else "u1"
    return bool(np.array_equal(a.view(bits), b.view(bits)))


def _same_texture(a: Texture, b: Texture) -> bool:
    return (a.name == b.name and a.encoding == b.encoding and a.missing == b.missing
            and _same_array(a.pixels, b.pixels))


def _same_mesh(a: Mesh, b: Mesh) -> bool:
    return a.color_encoding == b.color_encoding and all(
        _same_array(getattr(a, name), getattr(b, name))
        for name in ("positions", "triangles", "normals", "uvs", "polygons", "loop_triangles", "colors"))


def _same_value(x, y) -> bool:
    """Equal and of one type, in tuples too (an int 1 is not 1.0, nor -0.0 0.0; NaN never equals)."""
    if type(x) is not type(y):
        return False
    if isinstance(x, tuple):
        return len(x) == len(y) and all(_same_value(p, q) for p, q in zip(x, y, strict=True))
    if isinstance(x, float):
        return x == y and math.copysign(1.0, x) == math.copysign(1.0, y)
    return x == y


def _same_material(a: Material, b: Material) -> bool:
    """Equal fields of equal types (textures: the very same object)."""
    for f in dataclasses.fields(Material):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if not (x is y if f.name in _TEXTURE_FIELDS else _same_value(x, y)):
            return False
    return True


def reuse_unchanged(scene: DrawScene, previous: DrawScene | None) -> DrawScene:
    """``scene`` with every texture, material, mesh and renderer that equals its counterpart in
    ``previous`` replaced by that very object.

    The viewport extracts the whole scene again after any change, as new objects; most of it
    is usually unchanged (an object moved: one new matrix). Sharing the unchanged objects lets
    what is keyed by them carry over: a :class:`SceneMemo`'s entries (:meth:`SceneMemo.retain`)
    and the band helper's copy of them (sent once). Counterparts are found by name (textures,
    materials) and by object name and slot (meshes, renderers); equal means equal arrays
    (dtype, shape, elements) and equal fields of equal types, so the frame is the same whichever
    object is used. ``previous`` None: ``scene`` as is.
    """
    if previous is None:
        return scene
    textures: dict[str, list[Texture]] = {}
    materials: dict[str, list[Material]] = {}
    for r in previous.renderers:
        for tex in (getattr(r.material, name) for name in _TEXTURE_FIELDS):
            if tex is not None and all(t is not tex for t in textures.get(tex.name, [])):
                textures.setdefault(tex.name, []).append(tex)
        if all(m is not r.material for m in materials.get(r.material.name, [])):
            materials.setdefault(r.material.name, []).append(r.material)
    old_renderers = {(r.name, r.slot): r for r in previous.renderers}
    chosen: dict[int, object] = {}  # id of a new part -> the part to use

    def texture_for(tex: Texture | None) -> Texture | None:
        if tex is None:
            return None
        if id(tex) not in chosen:
            chosen[id(tex)] = next((t for t in textures.get(tex.name, []) if _same_texture(t, tex)), tex)
        return chosen[id(tex)]

    def material_for(mat: Material) -> Material:
        if id(mat) not in chosen:
            found = {name: texture_for(getattr(mat, name)) for name in _TEXTURE_FIELDS}
            changed = {name: tex for name, tex in found.items() if tex is not getattr(mat, name)}
            mine = dataclasses.replace(mat, **changed) if changed else mat
            chosen[id(mat)] = next((m for m in materials.get(mat.name, []) if _same_material(m, mine)), mine)
        return chosen[id(mat)]

    renderers = []
    for r in scene.renderers:
        material = material_for(r.material)
        old = old_renderers.get((r.name, r.slot))
        mesh = r.mesh
        if old is not None and (old.mesh is mesh or _same_mesh(old.mesh, mesh)):
            mesh = old.mesh
        if (old is not None and old.mesh is mesh and old.material is material
                and _same_array(old.matrix_world, r.matrix_world) and _same_array(old.bounds_center, r.bounds_center)):
            renderers.append(old)
        elif mesh is r.mesh and material is r.material:
            renderers.append(r)
        else:
            renderers.append(dataclasses.replace(r, mesh=mesh, material=material))
    return dataclasses.replace(scene, renderers=tuple(renderers))
