"""The ShaderLab vocabulary shared by every layer: enums and frozen dataclasses.

Every enum member is named exactly as ShaderLab spells it (``Blend SrcAlpha
OneMinusSrcAlpha``, ``ZTest LEqual``, ``Cull Off``); its ``value`` is the same
string, which is also the Blender EnumProperty identifier (README "Data model").
Field names of :class:`Pass` and :class:`Material` are the Blender property
names of ``Material.unity`` (``blendlib/blender/schema.py``), so the Blender
layer, the ShaderLab importer/exporter and the JSON output all map one to one.

This module knows nothing of Blender and nothing of numpy. It is longer than the project's
~600 lines because it is the one vocabulary every layer imports (enums, the two dataclasses,
their text and dict forms, presets): split, each part would import the others.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field, fields, replace
from decimal import Decimal
from enum import Enum, StrEnum
from typing import Any


class _Named(StrEnum):
    """A string enum whose value is its ShaderLab spelling."""

    def __str__(self) -> str:  # so f"{Cull.Off}" reads "Off"
        return self.value

    @classmethod
    def parse(cls, text: str):
        """Member from a ShaderLab word, case-insensitively; ValueError names the choices."""
        for member in cls:
            if member.value.lower() == str(text).lower():
                return member
        choices = ", ".join(m.value for m in cls)
        raise ValueError(f"unknown {cls.__name__} {text!r} (expected one of: {choices})")


class Queue(_Named):
    """``Tags {"Queue"=...}``: the named render queues and their numbers."""

    Background = "Background"
    Geometry = "Geometry"
    AlphaTest = "AlphaTest"
    Transparent = "Transparent"
    Overlay = "Overlay"

    @property
    def number(self) -> int:
        return QUEUE_NUMBERS[self]


QUEUE_NUMBERS: dict[Queue, int] = {
    Queue.Background: 1000,
    Queue.Geometry: 2000,
    Queue.AlphaTest: 2450,
    Queue.Transparent: 3000,
    Queue.Overlay: 4000,
}

#: Queues up to this number are drawn front to back, later ones back to front.
LAST_OPAQUE_QUEUE = 2500


class Cull(_Named):
    Back = "Back"
    Front = "Front"
    Off = "Off"


class CompareFunction(_Named):
    """``ZTest`` and ``Stencil { Comp }``; ZTest never uses ``Never``."""

    Never = "Never"
    Less = "Less"
    Greater = "Greater"
    LEqual = "LEqual"
    GEqual = "GEqual"
    Equal = "Equal"
    NotEqual = "NotEqual"
    Always = "Always"


ZTEST_FUNCTIONS = tuple(c for c in CompareFunction if c is not CompareFunction.Never)


class BlendFactor(_Named):
    One = "One"
    Zero = "Zero"
    SrcColor = "SrcColor"
    SrcAlpha = "SrcAlpha"
    DstColor = "DstColor"
    DstAlpha = "DstAlpha"
    OneMinusSrcColor = "OneMinusSrcColor"
    OneMinusSrcAlpha = "OneMinusSrcAlpha"
    OneMinusDstColor = "OneMinusDstColor"
    OneMinusDstAlpha = "OneMinusDstAlpha"
    SrcAlphaSaturate = "SrcAlphaSaturate"


class BlendOp(_Named):
    Add = "Add"
    Sub = "Sub"
    RevSub = "RevSub"
    Min = "Min"
    Max = "Max"


class StencilOp(_Named):
    Keep = "Keep"
    Zero = "Zero"
    Replace = "Replace"
    IncrSat = "IncrSat"
    DecrSat = "DecrSat"
    Invert = "Invert"
    IncrWrap = "IncrWrap"
    DecrWrap = "DecrWrap"


class TextureFilter(_Named):
    """Sampler filter. ``Trilinear`` is bilinear within two mip levels, blended by the LOD; with
    mipmaps off it samples like ``Bilinear`` (as Unity's sampler does on a texture without mips)."""

    Bilinear = "Bilinear"
    Point = "Point"
    Trilinear = "Trilinear"  # appended: the numbers Blender stores for the others stay


class TextureWrap(_Named):
    Repeat = "Repeat"
    Clamp = "Clamp"


class Lighting(_Named):
    Lambert = "Lambert"
    Unlit = "Unlit"


class VertexColor(_Named):
    """How the shader uses the vertex colour ``i.color`` (white when the mesh has none):
    ``Multiply``: albedo and alpha × ``i.color`` (Sprites, UI, fixed-function ``primary``);
    ``Particle``: ``2 × i.color × _TintColor × tex`` (the legacy particle shaders)."""

    Off = "Off"
    Multiply = "Multiply"
    Particle = "Particle"


class LightMode(_Named):
    """A pass's ``Tags { "LightMode"=... }`` (untagged = ``Always``); ``Other`` stands for a name
    Unity's forward path does not know. Which of them draw: :func:`blendlib.core.drawlist.pass_draws`."""

    Always = "Always"
    ForwardBase = "ForwardBase"
    ForwardAdd = "ForwardAdd"
    Vertex = "Vertex"
    VertexLM = "VertexLM"
    VertexLMRGBM = "VertexLMRGBM"
    ShadowCaster = "ShadowCaster"
    ShadowCollector = "ShadowCollector"
    Meta = "Meta"
    Deferred = "Deferred"
    PrepassBase = "PrepassBase"
    PrepassFinal = "PrepassFinal"
    MotionVectors = "MotionVectors"
    Other = "Other"


class LightType(_Named):
    """A Unity forward light's type (Blender Sun, Point, Spot)."""

    Directional = "Directional"
    Point = "Point"
    Spot = "Spot"


class LightRenderMode(_Named):
    """``Light.renderMode``: Important lights are always per-pixel, NotImportant never; Auto ones
    fill the Pixel Light Count by importance."""

    Auto = "Auto"
    Important = "Important"
    NotImportant = "NotImportant"


class OutlineMode(_Named):
    """A pass's outline vertex program (MToon's outline pass, SPEC §11.6): vertices pushed out along
    their normal before projection. ``Off``: the vertices as they are (every pass that is not an
    outline); ``World``: by a width in scene units; ``Screen``: in clip space, by a share of the
    screen height (docs/pipeline.md §1, "Outline vertex program")."""

    Off = "Off"
    World = "World"
    Screen = "Screen"


class OutlineFormula(_Named):
    """Which MToon's outline arithmetic :class:`OutlineMode` follows: ``MToon0x`` (VRM 0.x's
    ``VRM/MToon``: world offsets of ``0.01 × width`` in object space, screen offsets capped by
    ``_OutlineScaledMaxDistance``) or ``MToon10`` (VRM 1.0's ``VRM10/MToon10``: world offsets of
    ``width`` metres along the world normal, screen offsets of ``2 × width`` capped by the
    projection's ``P[1][1]``)."""

    MToon0x = "MToon0x"
    MToon10 = "MToon10"


#: The MSAA sample counts of Unity's Quality settings (Disabled, 2x, 4x, 8x).
MSAA_SAMPLES = (1, 2, 4, 8)


class ColorSpace(_Named):
    Gamma = "Gamma"
    Linear = "Linear"


class SortMode(_Named):
    Default = "Default"
    Perspective = "Perspective"
    Orthographic = "Orthographic"
    CustomAxis = "CustomAxis"


#: ColorMask channels in ShaderLab order.
CHANNELS = ("R", "G", "B", "A")
ALL_CHANNELS = frozenset(CHANNELS)


#: ColorMask channels as bits, numbered as Unity's ``ColorWriteMask`` (A=1, B=2, G=4, R=8). This is
#: the one bit order: a ShaderLab ``ColorMask [_Prop]`` value holds it, and so does the integer
#: Blender stores for the add-on's ColorMask (schema version 2; version 1 stored R=1, G=2, B=4, A=8).
COLOR_MASK_BITS: dict[str, int] = {"R": 8, "G": 4, "B": 2, "A": 1}


def color_mask_bits(mask: frozenset[str]) -> int:
    """The ``ColorWriteMask`` integer of a channel set: {R, G, B, A} → 15, {A} → 1, {R} → 8."""
    return sum(COLOR_MASK_BITS[c] for c in mask)


def color_mask_from_bits(bits: int) -> frozenset[str]:
    """Inverse of :func:`color_mask_bits`; ValueError outside 0..15."""
    if bits != int(bits) or not 0 <= bits <= 15:
        raise ValueError(f"ColorMask bits must be an integer 0..15, got {bits!r}")
    return frozenset(c for c, bit in COLOR_MASK_BITS.items() if int(bits) & bit)


def color_mask_text(mask: frozenset[str]) -> str:
    """ShaderLab spelling of a colour mask: ``"RGBA"``, ``"RB"``, or ``"0"`` for the empty set."""
    text = "".join(c for c in CHANNELS if c in mask)
    return text or "0"


def parse_color_mask(text: str) -> frozenset[str]:
    """``"0"`` → empty set, ``"rgb"`` → {R, G, B}; ValueError on anything else."""
    word = str(text).strip().upper()
    if word == "0":
        return frozenset()
    if not word or any(c not in CHANNELS for c in word) or len(set(word)) != len(word):
        raise ValueError(f"bad ColorMask {text!r} (expected 0 or a subset of RGBA such as RGB or A)")
    return frozenset(word)


def float32_text(x: float) -> str:
    """The shortest positional decimal text that reads back to the same float32 as ``x``.

    Blender stores pass offsets as float32: ``0.1234567`` (not ``0.123457``, which is
    another float32, nor ``0.12345670163631439``). No exponent, as ShaderLab writes numbers.
    """
    x = float(x)
    try:
        (f32,) = struct.unpack("<f", struct.pack("<f", x))
    except OverflowError:
        f32 = math.inf
    if not math.isfinite(f32):
        raise ValueError(f"cannot write {x!r} as a float32 number")
    if f32 == int(f32) and abs(f32) < 1e15:
        return str(int(f32))
    for digits in range(1, 10):  # 9 significant digits always round-trip a float32
        text = f"{f32:.{digits}g}"
        if struct.unpack("<f", struct.pack("<f", float(text)))[0] == f32:
            break
    out = format(Decimal(text), "f")
    return out.rstrip("0").rstrip(".") if "." in out else out


@dataclass(frozen=True)
class Pass:
    """One ``Pass { ... }``: the fixed-function state of one draw call."""

    name: str = "Pass"
    cull: Cull = Cull.Back
    zwrite: bool = True
    ztest: CompareFunction = CompareFunction.LEqual
    blend: bool = False
    src_blend: BlendFactor = BlendFactor.One
    dst_blend: BlendFactor = BlendFactor.Zero
    blend_op: BlendOp = BlendOp.Add
    separate_alpha: bool = False
    src_blend_alpha: BlendFactor = BlendFactor.One
    dst_blend_alpha: BlendFactor = BlendFactor.Zero
    blend_op_alpha: BlendOp = BlendOp.Add
    color_mask: frozenset[str] = ALL_CHANNELS
    offset_factor: float = 0.0
    offset_units: float = 0.0
    alpha_test: bool = False
    stencil: bool = False
    stencil_ref: int = 0
    stencil_read_mask: int = 255
    stencil_write_mask: int = 255
    stencil_comp: CompareFunction = CompareFunction.Always
    stencil_pass: StencilOp = StencilOp.Keep
    stencil_fail: StencilOp = StencilOp.Keep
    stencil_zfail: StencilOp = StencilOp.Keep
    #: ``AlphaToMask On``: with MSAA, the fragment covers the share of its pixel's samples its alpha
    #: gives (docs/pipeline.md); no effect without MSAA.
    alpha_to_mask: bool = False
    #: The alpha test's comparison: a fragment survives when ``alpha <comp> _Cutoff`` (the book's
    #: ``clip(a - _Cutoff)`` is ``GEqual``; legacy ``AlphaTest Greater [_Cutoff]`` is ``Greater``).
    alpha_test_comp: CompareFunction = CompareFunction.GEqual
    #: The pass's ``LightMode`` tag: which passes draw (SPEC §11.2).
    light_mode: LightMode = LightMode.ForwardBase
    #: The outline vertex program (MToon's outline pass); ``Off`` draws the vertices as they are.
    outline_mode: OutlineMode = OutlineMode.Off
    #: MToon's ``_OutlineWidth`` (0.x: centimetres in World mode, % of the screen height in Screen
    #: mode; 1.0's ``outlineWidthFactor``: metres, or a share of the screen height).
    outline_width: float = 0.0
    outline_formula: OutlineFormula = OutlineFormula.MToon0x
    #: MToon 0.x's ``_OutlineScaledMaxDistance`` (Screen mode: the clip w beyond which the outline
    #: stops growing with distance).
    outline_max_distance: float = 1.0
    #: MToon's outline colour (0.x ``_OutlineColor``, 1.0 ``outlineColorFactor`` as UniVRM sets
    #: ``_OutlineColor``: COLOR_GAMMA rgb), which replaces the lit colour of the pass's fragments:
    #: ``rgb = outline_color * lerp(1, lit, outline_lighting_mix)`` (docs/pipeline.md §7). None: the
    #: pass draws the material's lit colour (every pass that is not an MToon outline).
    outline_color: tuple[float, float, float] | None = None
    #: MToon's ``_OutlineLightingMix`` / ``outlineLightingMixFactor``: 0 the outline colour alone
    #: (0.x's ``MTOON_OUTLINE_COLOR_FIXED``), 1 the outline colour times the lit colour.
    outline_lighting_mix: float = 0.0

    def __post_init__(self) -> None:
        if self.ztest is CompareFunction.Never:
            raise ValueError("ZTest Never does not exist in ShaderLab")
        for name in ("stencil_ref", "stencil_read_mask", "stencil_write_mask"):
            value = getattr(self, name)
            if not (isinstance(value, int) and 0 <= value <= 255):
                raise ValueError(f"{name} must be an integer 0..255, got {value!r}")
        object.__setattr__(self, "color_mask", frozenset(self.color_mask))
        if self.outline_color is not None:
            object.__setattr__(self, "outline_color", tuple(float(c) for c in self.outline_color))
            if len(self.outline_color) != 3:
                raise ValueError(f"outline_color must be three numbers (rgb), got {self.outline_color!r}")
        if not self.color_mask <= ALL_CHANNELS:
            raise ValueError(f"color_mask must be a subset of RGBA, got {sorted(self.color_mask)}")

    # The effective alpha blend state (separate or the colour one).
    @property
    def alpha_factors(self) -> tuple[BlendFactor, BlendFactor, BlendOp]:
        if self.separate_alpha:
            return self.src_blend_alpha, self.dst_blend_alpha, self.blend_op_alpha
        return self.src_blend, self.dst_blend, self.blend_op


def pass_state_commands(p: Pass) -> list[str]:
    """The ShaderLab state commands of a pass, one per item, as the exporter writes them.

    Always ``Cull``, ``ZWrite``, ``ZTest`` and ``Blend``; ``BlendOp``, ``ColorMask``,
    ``AlphaToMask On``, ``Offset`` (shortest float32 text, :func:`float32_text`) and
    ``Stencil { ... }`` (on one line) only where they differ from the defaults.
    """
    commands = [f"Cull {p.cull}", f"ZWrite {'On' if p.zwrite else 'Off'}", f"ZTest {p.ztest}"]
    if not p.blend:
        commands.append("Blend Off")
    else:
        blend = f"Blend {p.src_blend} {p.dst_blend}"
        if p.separate_alpha:
            blend += f", {p.src_blend_alpha} {p.dst_blend_alpha}"
        commands.append(blend)
        if p.separate_alpha and p.blend_op_alpha != p.blend_op:
            commands.append(f"BlendOp {p.blend_op}, {p.blend_op_alpha}")
        elif p.blend_op != BlendOp.Add:
            commands.append(f"BlendOp {p.blend_op}")
    if p.color_mask != ALL_CHANNELS:
        commands.append(f"ColorMask {color_mask_text(p.color_mask)}")
    if p.alpha_to_mask:
        commands.append("AlphaToMask On")
    if p.offset_factor or p.offset_units:
        commands.append(f"Offset {float32_text(p.offset_factor)}, {float32_text(p.offset_units)}")
    if p.stencil:
        commands.append(
            f"Stencil {{ Ref {p.stencil_ref} ReadMask {p.stencil_read_mask} WriteMask {p.stencil_write_mask} "
            f"Comp {p.stencil_comp} Pass {p.stencil_pass} Fail {p.stencil_fail} ZFail {p.stencil_zfail} }}"
        )
    return commands


def pass_state_text(p: Pass) -> str:
    """A pass's state on one line, e.g. ``Cull Off ZWrite Off ZTest LEqual Blend SrcAlpha OneMinusSrcAlpha``.

    The commands of :func:`pass_state_commands`, then the alpha test of an alpha-tested pass
    (:func:`alpha_test_text`: ``clip(a - _Cutoff)``, its program's test, for the book's GEqual). The panel's pass
    preview, the exporter and the draw list all write a pass with this.
    """
    words = pass_state_commands(p)
    if p.alpha_test:
        words.append(alpha_test_text(p.alpha_test_comp))
    return " ".join(words)


def alpha_test_text(comp: CompareFunction) -> str:
    """The alpha test as the state line writes it: the book's ``clip(a - _Cutoff)`` for ``GEqual``,
    the legacy command (``AlphaTest Greater [_Cutoff]``) for the other comparisons."""
    return "clip(a - _Cutoff)" if comp is CompareFunction.GEqual else f"AlphaTest {comp} [_Cutoff]"




@dataclass(frozen=True, eq=False)
class Texture:
    """An image for ``_MainTex``.

    ``pixels``: numpy array (H, W, 4) float32, straight (not premultiplied)
    alpha, row 0 = the bottom of the image (v = 0), as Blender and OpenGL store
    it. ``encoding`` says what the RGB values are: ``"sRGB"`` (encoded values,
    e.g. a Blender byte image), ``"Linear"`` (linear values of a colour image,
    e.g. a Blender float image) or ``"Data"`` (non-colour: never converted).
    ``missing`` marks a stand-in for an image file that could not be read.
    """

    pixels: Any
    encoding: str = "sRGB"
    name: str = ""
    missing: bool = False

    def __post_init__(self) -> None:
        if self.encoding not in ("sRGB", "Linear", "Data"):
            raise ValueError(f"texture {self.name!r}: encoding must be sRGB, Linear or Data")
        shape = getattr(self.pixels, "shape", None)
        if shape is None or len(shape) != 3 or shape[2] != 4 or shape[0] < 1 or shape[1] < 1:
            raise ValueError(f"texture {self.name!r}: pixels must be an (H>=1, W>=1, 4) array, got shape {shape}")


@dataclass(frozen=True)
class Material:
    """The Unity material (``Material.unity``, README "Data model"), resolved for rendering.

    ``color`` is ``_Color`` as authored (COLOR_GAMMA: sRGB-encoded values).
    ``passes`` are drawn in order; an empty tuple means one default pass.
    """

    name: str = "Material"
    queue: Queue = Queue.Geometry
    queue_offset: int = 0
    color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    main_tex: Texture | None = None
    main_tex_tiling: tuple[float, float] = (1.0, 1.0)
    main_tex_offset: tuple[float, float] = (0.0, 0.0)
    main_tex_filter: TextureFilter = TextureFilter.Bilinear
    main_tex_wrap: TextureWrap = TextureWrap.Repeat
    alpha_scale: float = 1.0
    cutoff: float = 0.5
    lighting: Lighting = Lighting.Lambert
    passes: tuple[Pass, ...] = field(default_factory=lambda: (Pass(),))
    #: Sample ``_MainTex`` through its mip chain (2x2 box downsampling, as Unity's importer makes it).
    main_tex_mipmaps: bool = False
    #: "Mip Maps Preserve Coverage": each mip level's alpha scaled so that its coverage at
    #: ``cutoff`` equals level 0's.
    main_tex_preserve_coverage: bool = False
    vertex_color: VertexColor = VertexColor.Off
    #: ``_TintColor`` (COLOR_GAMMA) of the particle shaders (``vertex_color`` Particle).
    tint_color: tuple[float, float, float, float] = (0.5, 0.5, 0.5, 0.5)
    #: MToon's outline-width texture (0.x ``_OutlineWidthTexture``, 1.0 ``outlineWidthMultiplyTexture``):
    #: an outline pass's width is multiplied per vertex by its red channel, sampled at level 0 at the
    #: vertex's ``_MainTex`` coordinates (:mod:`.outline`). None: ×1 (MToon's default, white).
    outline_width_tex: Texture | None = None
    outline_width_tex_filter: TextureFilter = TextureFilter.Bilinear
    outline_width_tex_wrap: TextureWrap = TextureWrap.Repeat

    @property
    def render_queue(self) -> int:
        """The queue number, e.g. 3001 for ``"Transparent+1"``."""
        return self.queue.number + int(self.queue_offset)

    @property
    def draw_passes(self) -> tuple[Pass, ...]:
        return self.passes or (Pass(),)


def queue_text(queue: Queue, offset: int) -> str:
    """``"Transparent"``, ``"Transparent+1"``, ``"Geometry-10"``."""
    if offset == 0:
        return queue.value
    return f"{queue.value}{offset:+d}"


#: What a pass does in the forward rendering path (:func:`pass_draws`).
ONCE, PER_LIGHT, NEVER = "once", "per light", "never"
_FORWARD = (LightMode.ForwardBase, LightMode.ForwardAdd)
_NEVER_REASONS = {
    LightMode.VertexLM: "VertexLM: drawn only for lightmapped objects in the legacy Vertex Lit path",
    LightMode.VertexLMRGBM: "VertexLMRGBM: drawn only for lightmapped objects in the legacy Vertex Lit path",
    LightMode.ShadowCaster: "ShadowCaster: renders shadow maps and the depth texture, not the frame",
    LightMode.ShadowCollector: "ShadowCollector: collects shadows (legacy), not the frame",
    LightMode.Meta: "Meta: used only when baking lightmaps",
    LightMode.Deferred: "Deferred: the deferred path's pass; this renders the forward path",
    LightMode.PrepassBase: "PrepassBase: the legacy deferred path's pass; this renders the forward path",
    LightMode.PrepassFinal: "PrepassFinal: the legacy deferred path's pass; this renders the forward path",
    LightMode.MotionVectors: "MotionVectors: renders the motion-vector texture, not the frame",
    LightMode.Other: "a LightMode the forward path does not know: never drawn",
}


def pass_draws(p: Pass, passes: tuple[Pass, ...]) -> tuple[str, str]:
    """How pass ``p`` of a material whose passes are ``passes`` draws in the forward rendering path
    (Unity manual, "Pass tags" and "Forward Rendering Path"), and why, as ``(how, reason)``:
    ``ONCE`` (Always, ForwardBase; Vertex when the material has no ForwardBase/ForwardAdd pass),
    ``PER_LIGHT`` (ForwardAdd: once per additional per-pixel light) or ``NEVER``."""
    mode = p.light_mode
    if mode is LightMode.Always:
        return ONCE, "Always: drawn once"
    if mode is LightMode.ForwardBase:
        return ONCE, "ForwardBase: drawn once, with the main directional light"
    if mode is LightMode.ForwardAdd:
        return PER_LIGHT, "ForwardAdd: drawn once per additional per-pixel light"
    if mode is LightMode.Vertex:
        if any(q.light_mode in _FORWARD for q in passes):
            return NEVER, "Vertex: the material has forward passes, which draw instead"
        return ONCE, "Vertex: drawn once (legacy Vertex Lit: the material has no forward passes)"
    return NEVER, _NEVER_REASONS[mode]


def pass_to_dict(p: Pass) -> dict[str, Any]:
    """JSON-ready dict with the pass property names of ``Material.unity``; enums as identifiers,
    color_mask as a sorted RGBA list."""
    out: dict[str, Any] = {}
    for f in fields(p):
        value = getattr(p, f.name)
        if isinstance(value, Enum):
            value = value.value
        elif f.name == "color_mask":
            value = [c for c in CHANNELS if c in value]
        out[f.name] = value
    return out


_PASS_ENUMS = {f.name: f.type for f in fields(Pass)}


def pass_from_dict(data: dict[str, Any]) -> Pass:
    """Inverse of :func:`pass_to_dict`; unknown keys raise ValueError."""
    kwargs: dict[str, Any] = {}
    defaults = Pass()
    for key, value in data.items():
        if key not in _PASS_ENUMS:
            raise ValueError(f"unknown pass property {key!r}")
        default = getattr(defaults, key)
        if isinstance(default, Enum):
            value = type(default).parse(value)
        elif key == "color_mask":
            value = frozenset(value)
        kwargs[key] = value
    return replace(defaults, **kwargs)


#: Pass-state presets of the tutorials; the add-on's presets menu and the tests use these.
_BLEND = dict(blend=True, zwrite=False)
PASS_PRESETS: dict[str, dict[str, Any]] = {
    "Opaque": dict(queue=Queue.Geometry, passes=[dict()]),
    "Alpha Test": dict(queue=Queue.AlphaTest, passes=[dict(alpha_test=True)]),
    "Alpha Test Both Sided": dict(queue=Queue.AlphaTest, passes=[dict(alpha_test=True, cull=Cull.Off)]),
    "Alpha Blend": dict(
        queue=Queue.Transparent,
        passes=[dict(**_BLEND, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha)],
    ),
    "Alpha Blend ZWrite": dict(
        queue=Queue.Transparent,
        passes=[
            dict(name="Depth Prepass", zwrite=True, color_mask=frozenset()),
            dict(name="Blend", **_BLEND, src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha),
        ],
    ),
    "Alpha Blend Both Sided": dict(
        queue=Queue.Transparent,
        passes=[
            dict(name="Back Faces", cull=Cull.Front, **_BLEND,
                 src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha),
            dict(name="Front Faces", cull=Cull.Back, **_BLEND,
                 src_blend=BlendFactor.SrcAlpha, dst_blend=BlendFactor.OneMinusSrcAlpha),
        ],
    ),
    "Premultiplied": dict(
        queue=Queue.Transparent,
        passes=[dict(**_BLEND, src_blend=BlendFactor.One, dst_blend=BlendFactor.OneMinusSrcAlpha)],
    ),
    "Additive": dict(
        queue=Queue.Transparent,
        passes=[dict(**_BLEND, src_blend=BlendFactor.One, dst_blend=BlendFactor.One)],
    ),
    "Soft Additive": dict(
        queue=Queue.Transparent,
        passes=[dict(**_BLEND, src_blend=BlendFactor.OneMinusDstColor, dst_blend=BlendFactor.One)],
    ),
    "Multiply": dict(
        queue=Queue.Transparent,
        passes=[dict(**_BLEND, src_blend=BlendFactor.DstColor, dst_blend=BlendFactor.Zero)],
    ),
    "2x Multiply": dict(
        queue=Queue.Transparent,
        passes=[dict(**_BLEND, src_blend=BlendFactor.DstColor, dst_blend=BlendFactor.SrcColor)],
    ),
    "Darken": dict(
        queue=Queue.Transparent,
        passes=[dict(**_BLEND, src_blend=BlendFactor.One, dst_blend=BlendFactor.One, blend_op=BlendOp.Min)],
    ),
    "Lighten": dict(
        queue=Queue.Transparent,
        passes=[dict(**_BLEND, src_blend=BlendFactor.One, dst_blend=BlendFactor.One, blend_op=BlendOp.Max)],
    ),
    "Screen": dict(
        queue=Queue.Transparent,
        passes=[dict(**_BLEND, src_blend=BlendFactor.One, dst_blend=BlendFactor.OneMinusSrcColor)],
    ),
    "Linear Dodge": dict(
        queue=Queue.Transparent,
        passes=[dict(**_BLEND, src_blend=BlendFactor.One, dst_blend=BlendFactor.One)],
    ),
}
# The book writes Screen as "Blend OneMinusDstColor One" "or equivalently" "Blend One OneMinusSrcColor";
# we use the second spelling so Screen differs from Soft Additive. Linear Dodge is "Blend One One",
# the same state as Additive: the book's catalogue lists them apart, so the presets do too.


def preset(name: str) -> tuple[Queue, tuple[Pass, ...]]:
    """The queue and passes of a named preset from :data:`PASS_PRESETS`."""
    spec = PASS_PRESETS[name]
    return spec["queue"], tuple(Pass(**p) for p in spec["passes"])
