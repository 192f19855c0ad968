"""The Unity built-in shaders example (``blend_files/unity_builtins.blend``): Unity's own shaders drawn
as Unity draws them, their settings imported from the real shader text.

Every material's Unity settings come from importing Unity's built-in shader source 2019.4
(``shared/corpus/unity-builtin-shaders-2019.4``, MIT) through :mod:`blendlib.formats.shaderlab`, as
the add-on's **Import ShaderLab…** does (:func:`~blendlib.formats.shaderlab.parse_shaderlab_file`,
then the schema's writer); the Standard shader's Fade and Transparent modes come from the two
``.mat`` files of ``blend_files/unity/`` (one in each of Unity's YAML layouts) through
:func:`~blendlib.formats.shaderlab.import_material_file`. Only what Unity keeps on the texture
asset (its image and Filter Mode) or the renderer (vertex colours: a particle's or a sprite's
colour) is set here. Textures are made here from numbers.

==========================================  ==================  ==========================================
object                                      shader              what it shows
==========================================  ==================  ==========================================
Backdrop                                    Unlit/Texture       the opaque background (Geometry)
Alpha Blended / Additive / Multiply         Legacy Shaders/     three particle systems of three quads
Particles                                   Particles/…         each, vertex-coloured, overlapping
Sprite                                      Sprites/Default     premultiplied blend, tinted by its colour
UI Panel                                    UI/Default          a uGUI image, vertex colour × texture
Glass Pane                                  Unlit/Transparent   the texture's own alpha
Transparent Diffuse Cube                    Legacy …/Diffuse    lit, alpha:fade (ColorMask RGB)
Cutout Cube                                 …/Cutout/Diffuse    texels below _Cutoff 0.5 discarded
Standard Fade / Standard Transparent        Standard (.mat)     the same colour blend; the frame's alpha
                                                                a·a + (1 − a) (Fade) vs 1 (Transparent)
==========================================  ==================  ==========================================

Particle quads are one mesh per particle system (one renderer, as a ParticleSystemRenderer draws its
particles in one draw call, in the mesh's order); each quad's four corners share one vertex colour.
"""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np

from blendlib import blender
from blendlib.formats import shaderlab
from scripts import scenekit
from scripts.make_unity_shader_table import default_corpus
from scripts.scenekit import QUAD_UV, cube_mesh, quad_mesh, sphere_mesh

ROOT = Path(__file__).resolve().parent.parent
#: The Standard materials (.mat, Unity's YAML) imported by the scene.
MATERIALS = ROOT / "blend_files" / "unity"

#: Each particle system's quads: (x, z) offset from the system's centre and vertex colour (8-bit RGBA).
PARTICLE_SIZE = 1.0
PARTICLE_OFFSETS = ((-0.22, 0.16), (0.22, 0.16), (0.0, -0.22))
PARTICLE_SYSTEMS = {
    # name: (shader file, centre x, texture, vertex colours of the quads in draw order)
    "Alpha Blended Particles": ("Particle Alpha Blend.shader", -2.9, "disc",
                                ((230, 70, 50, 204), (60, 200, 90, 204), (70, 120, 240, 204))),
    "Additive Particles": ("Particle Add.shader", 0.0, "disc",
                           ((200, 80, 30, 153), (40, 170, 60, 153), (50, 90, 210, 153))),
    "Multiply Particles": ("Particle Multiply.shader", 2.9, "shade",
                           ((255, 205, 185, 255), (200, 255, 215, 255), (205, 220, 255, 255))),
}
PARTICLE_Z = 1.42


def builtin_shaders() -> Path:
    """Unity's built-in shader source (``shared/corpus/unity-builtin-shaders-2019.4`` beside the
    repository, or one level higher from a worktree); SystemExit with one clear line when absent."""
    corpus = default_corpus()
    if not (corpus / "DefaultResourcesExtra").is_dir():
        raise SystemExit(f"unity_builtins: Unity's built-in shader source is not at {corpus} (expected "
                         "shared/corpus/unity-builtin-shaders-2019.4 beside the repository or one level higher)")
    return corpus


# ---------------------------------------------------------------------------- textures (row 0 = bottom)


def _radius(size: int) -> np.ndarray:
    """(size, size) float64: each texel centre's distance from the image centre, in texels."""
    c = (size - 1) / 2.0
    j, i = np.mgrid[0:size, 0:size].astype(np.float64)
    return np.hypot(i - c, j - c)


def disc_pixels() -> np.ndarray:
    """16x16 soft particle: white, alpha 255 to radius 5 texels, falling linearly to 0 at 7.5."""
    t = np.full((16, 16, 4), 255, np.uint8)
    t[..., 3] = np.rint(np.clip((7.5 - _radius(16)) / 2.5, 0.0, 1.0) * 255).astype(np.uint8)
    return t


def shade_pixels() -> np.ndarray:
    """16x16 multiply particle, opaque: grey 160 to radius 4.5 texels, rising linearly to white at
    6.5 (alpha 255 everywhere, so Particles/Multiply's ``lerp(1, prev, prev.a)`` is ``prev``)."""
    t = np.full((16, 16, 4), 255, np.uint8)
    rise = np.clip((_radius(16) - 4.5) / 2.0, 0.0, 1.0)
    t[..., :3] = np.rint(160 + 95 * rise)[..., None].astype(np.uint8)
    return t


def sprite_pixels() -> np.ndarray:
    """16x16 diamond: a white-to-grey gradient inside (alpha 255), a one-texel rim of alpha 128, clear outside."""
    t = np.zeros((16, 16, 4), np.uint8)
    j, i = np.mgrid[0:16, 0:16]
    d = np.abs(i - 7.5) + np.abs(j - 7.5)
    inside, rim = d <= 6.0, (d > 6.0) & (d <= 7.0)
    t[..., :3] = (135 + 8 * j)[..., None].astype(np.uint8)
    t[..., 3] = np.where(inside, 255, np.where(rim, 128, 0))
    return t


def panel_pixels() -> np.ndarray:
    """16x16 uGUI panel: a white two-texel border (alpha 255), a grey interior of alpha 150."""
    t = np.zeros((16, 16, 4), np.uint8)
    t[...] = (230, 230, 230, 150)
    t[:2, :], t[-2:, :], t[:, :2], t[:, -2:] = 255, 255, 255, 255
    return t


def glass_pixels() -> np.ndarray:
    """16x16 glass: cyan, alpha in four horizontal bands 64 / 128 / 192 / 255 (bottom to top)."""
    t = np.zeros((16, 16, 4), np.uint8)
    t[..., :3] = (90, 210, 230)
    t[..., 3] = np.repeat(np.array([64, 128, 192, 255], np.uint8), 4)[:, None]
    return t


def cutout_pixels() -> np.ndarray:
    """16x16 leaf-like: green, alpha 230 on a checker of 4-texel cells, 64 on the others (below 0.5)."""
    t = np.zeros((16, 16, 4), np.uint8)
    j, i = np.mgrid[0:16, 0:16]
    t[..., :3] = (110, 200, 80)
    t[..., 3] = np.where(((i // 4) + (j // 4)) % 2 == 0, 230, 64)
    return t


def crate_pixels() -> np.ndarray:
    """16x16 tinted glass crate: orange, alpha 153, with an opaque two-texel frame."""
    t = np.zeros((16, 16, 4), np.uint8)
    t[...] = (120, 70, 30, 255)
    t[2:-2, 2:-2] = (250, 170, 90, 153)
    return t


def backdrop_pixels() -> np.ndarray:
    """8x4 opaque blocks: a mid and a dark grey, a brick red and a teal (Point filtered, so each block is flat)."""
    palette = np.array([(150, 150, 150), (60, 62, 70), (150, 64, 56), (40, 110, 120)], np.uint8)
    j, i = np.mgrid[0:4, 0:8]
    t = np.full((4, 8, 4), 255, np.uint8)
    t[..., :3] = palette[(i + 2 * j) % 4]
    return t


# ---------------------------------------------------------------------------- meshes


def colored_quads(name: str, rects, colors):
    """One mesh of quads facing −Y: ``rects`` (x, z, width, height) centres and sizes, each quad's
    corners the vertex colour ``colors[k]`` (8-bit RGBA, a byte corner attribute read as k/255); faces
    (and so triangles) in the order given."""
    verts, faces = [], []
    for x, z, w, h in rects:
        n = len(verts)
        verts += [(x - w / 2, 0.0, z - h / 2), (x + w / 2, 0.0, z - h / 2), (x + w / 2, 0.0, z + h / 2),
                  (x - w / 2, 0.0, z + h / 2)]
        faces.append((n, n + 1, n + 2, n + 3))
    me = scenekit.mesh(name, verts, faces, [QUAD_UV] * len(faces))
    attribute = me.color_attributes.new("Col", "BYTE_COLOR", "CORNER")
    values = np.repeat(np.asarray(colors, np.float32) / 255.0, 4, axis=0)
    attribute.data.foreach_set("color_srgb", values.ravel())
    me.color_attributes.active_color = attribute
    return me


# ---------------------------------------------------------------------------- materials


def shader_material(corpus: Path, relative: str, name: str, **texture):
    """A material whose Unity settings are those of importing ``relative`` (a file of Unity's built-in
    shader source) as the add-on's Import ShaderLab does, then ``texture`` (``main_tex`` and what
    Unity keeps on the texture asset: ``main_tex_filter``)."""
    result = shaderlab.parse_shaderlab_file(str(corpus / relative), (str(corpus),))
    mat = bpy.data.materials.new(name)
    blender.write_material(mat, enabled=True, **(blender.material_fields(result.material) | texture))
    return mat


def mat_file_material(corpus: Path, file_name: str, name: str):
    """A material whose Unity settings are those of importing ``blend_files/unity/FILE`` (a ``.mat``)
    as the add-on's Import ShaderLab does (no texture: the files name none)."""
    result = shaderlab.import_material_file(MATERIALS / file_name, (str(corpus),))
    mat = bpy.data.materials.new(name)
    blender.write_material(mat, enabled=True, **(blender.material_fields(result.material) | {"main_tex": None}))
    return mat


# ---------------------------------------------------------------------------- the scene


def build(new_file, save, image, label) -> None:
    """Build and save ``blend_files/unity_builtins.blend`` with ``make_blend_files``' ``new_file``,
    ``save``, ``image`` and ``label`` helpers (resolution, clear colour, Sun and World; labels)."""
    corpus = builtin_shaders()
    extra = "DefaultResourcesExtra"
    scene = new_file("UnityBuiltins", distance=12.0, sun_energy=0.9)
    collection = scene.collection

    def put(name, data, location, material, rotation=(0, 0, 0)):
        ob = scenekit.add_object(collection, name, data, location, rotation)
        ob.data.materials.append(material)
        return ob

    backdrop = shader_material(corpus, f"{extra}/Unlit/Unlit-Normal.shader", "Backdrop (Unlit/Texture)",
                               main_tex=image("Backdrop Blocks", backdrop_pixels()), main_tex_filter="Point")
    put("Backdrop", quad_mesh("Backdrop", 10.4, 5.8), (0, 1.5, 0), backdrop)

    textures = {"disc": image("Particle Disc", disc_pixels()), "shade": image("Particle Shade", shade_pixels())}
    for name, (file, x, tex, colors) in PARTICLE_SYSTEMS.items():
        mat = shader_material(corpus, f"{extra}/{file}", f"{name} ({file[:-7]})", main_tex=textures[tex])
        rects = [(dx, dz, PARTICLE_SIZE, PARTICLE_SIZE) for dx, dz in PARTICLE_OFFSETS]
        put(name, colored_quads(name, rects, colors), (x, 0.0, PARTICLE_Z), mat)
        label(mat.name.split(" (")[0].replace(" Particles", ""), (x, -0.2, 0.62), size=0.17)

    row = -0.05
    sprite = shader_material(corpus, f"{extra}/Sprites-Default.shader", "Sprite (Sprites/Default)",
                             main_tex=image("Sprite Diamond", sprite_pixels()), main_tex_filter="Point")
    put("Sprite", colored_quads("Sprite", [(0, 0, 1.1, 1.1)], [(255, 196, 90, 230)]), (-2.9, 0, row), sprite)
    panel = shader_material(corpus, f"{extra}/UI/UI-Default.shader", "UI Panel (UI/Default)",
                            main_tex=image("UI Panel", panel_pixels()), main_tex_filter="Point")
    put("UI Panel", colored_quads("UI Panel", [(0, 0, 1.5, 0.9)], [(120, 190, 255, 230)]), (0.0, 0, row), panel)
    glass = shader_material(corpus, f"{extra}/Unlit/Unlit-Alpha.shader", "Glass Pane (Unlit/Transparent)",
                            main_tex=image("Glass Bands", glass_pixels()), main_tex_filter="Point")
    put("Glass Pane", quad_mesh("Glass Pane", 1.1, 1.1), (2.9, 0, row), glass)
    for text, x in (("Sprites/Default", -2.9), ("UI/Default", 0.0), ("Unlit/Transparent", 2.9)):
        label(text, (x, -0.2, row - 0.72), size=0.17)

    low = -1.5
    diffuse = shader_material(corpus, f"{extra}/Alpha-Diffuse.shader", "Crate (Legacy Transparent/Diffuse)",
                              main_tex=image("Glass Crate", crate_pixels()), main_tex_filter="Point")
    put("Transparent Diffuse Cube", cube_mesh("Crate", 0.72), (-3.15, 0, low), diffuse, rotation=(25, 0, 35))
    cutout = shader_material(corpus, f"{extra}/AlphaTest-Diffuse.shader", "Leaves (Legacy Transparent/Cutout/Diffuse)",
                             main_tex=image("Leaf Checker", cutout_pixels()), main_tex_filter="Point")
    put("Cutout Cube", cube_mesh("Leaves", 0.72), (-1.05, 0, low), cutout, rotation=(25, 0, 35))
    fade = mat_file_material(corpus, "Standard Fade.mat", "Standard Fade")
    put("Standard Fade", sphere_mesh("Fade Sphere", 0.5), (1.05, 0, low), fade)
    transparent = mat_file_material(corpus, "Standard Transparent.mat", "Standard Transparent")
    put("Standard Transparent", sphere_mesh("Transparent Sphere", 0.5), (3.15, 0, low), transparent)
    for text, x in (("Transparent/Diffuse", -3.15), ("Cutout/Diffuse", -1.05), ("Standard Fade", 1.05),
                    ("Standard Transparent", 3.15)):
        label(text, (x, -0.6, low - 0.68), size=0.16)
    save("unity_builtins")
