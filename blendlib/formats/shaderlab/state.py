"""Render state as the parsed commands set it: Unity's enum tables, ``[_Prop]`` values, inheritance.

From the tree of :mod:`.tree`:

* each command's values read as Unity reads them — a word by its name (case-insensitive), a
  ``[_Prop]`` reference as the material's value (:class:`MaterialValues`, from a ``.mat`` file)
  or else the property's default, with Unity's numbering of the command's enum
  (``UnityEngine.Rendering.CullMode``, ``CompareFunction``, ``BlendMode``, ``BlendOp``,
  ``StencilOp``, ``ColorWriteMask``); a name not in Properties is a global, which Unity reads as
  0 (imported as 0, warned) — except ``unity_GUIZTestMode``, which Unity's UI sets to LEqual for
  canvases in camera or world space (SPEC §11.1);
* what Unity accepts and this renderer draws otherwise, each warned: ``Blend N …`` and
  ``ColorMask … N`` for a render target N ≠ 0 are ignored (the frame is render target 0); the
  advanced and logical BlendOps draw as Add (the Unity manual: Vulkan and Metal "fall back to
  Add operations"); ``ZTest Never`` marks a pass that draws nothing;
* the inheritance: state at Category level applies to the SubShaders after it in that Category
  (and its nested Categories), state at SubShader level to every pass of it, a pass's own
  commands override both, command by command (the last of a kind in a block wins);
* the SubShader's tags: those of the Category ``Tags`` read before the first SubShader, then
  its own;
* :func:`parse_queue` (the ``Queue`` tag) and :meth:`PassState.pass_fields` (state → the fields of
  :class:`~blendlib.core.vocabulary.Pass`).

:func:`check_values` raises the first bad value in source order; :func:`resolve` checks, then
combines, collecting the warnings of what a value asks for and this renderer does not do.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from ...core.vocabulary import (
    QUEUE_NUMBERS,
    BlendFactor,
    BlendOp,
    CompareFunction,
    Cull,
    Queue,
    StencilOp,
    color_mask_from_bits,
    parse_color_mask,
)
from .diagnostics import ShaderLabError, SourceWarning
from .lexer import Token
from .tree import (
    CategoryBlock,
    Command,
    GrabPass,
    PassBlock,
    ProgramBlock,
    ShaderBlock,
    SubShaderBlock,
    TagsBlock,
    UsePass,
    Value,
)

# --------------------------------------------------------------------------- Unity enum numbering

# Values of [_Prop] references are floats read with Unity's numbering of the command's enum.
_CULL_BY_NUMBER = {0: Cull.Off, 1: Cull.Front, 2: Cull.Back}  # UnityEngine.Rendering.CullMode
_COMPARE_BY_NUMBER = {  # UnityEngine.Rendering.CompareFunction (0 = Disabled: the test always passes)
    0: CompareFunction.Always, 1: CompareFunction.Never, 2: CompareFunction.Less, 3: CompareFunction.Equal,
    4: CompareFunction.LEqual, 5: CompareFunction.Greater, 6: CompareFunction.NotEqual,
    7: CompareFunction.GEqual, 8: CompareFunction.Always,
}
_FACTOR_BY_NUMBER = {  # UnityEngine.Rendering.BlendMode
    0: BlendFactor.Zero, 1: BlendFactor.One, 2: BlendFactor.DstColor, 3: BlendFactor.SrcColor,
    4: BlendFactor.OneMinusDstColor, 5: BlendFactor.SrcAlpha, 6: BlendFactor.OneMinusSrcColor,
    7: BlendFactor.DstAlpha, 8: BlendFactor.OneMinusDstAlpha, 9: BlendFactor.SrcAlphaSaturate,
    10: BlendFactor.OneMinusSrcAlpha,
}
_BLENDOP_BY_NUMBER = {  # UnityEngine.Rendering.BlendOp (the arithmetic ones)
    0: BlendOp.Add, 1: BlendOp.Sub, 2: BlendOp.RevSub, 3: BlendOp.Min, 4: BlendOp.Max,
}
#: UnityEngine.Rendering.BlendOp 5..35: the logical (DX11.1) and advanced (KHR_blend_equation_advanced)
#: operations, by number; they draw as Add here, as Unity documents for Vulkan and Metal.
OTHER_BLENDOPS = (
    "LogicalClear", "LogicalSet", "LogicalCopy", "LogicalCopyInverted", "LogicalNoop", "LogicalInvert",
    "LogicalAnd", "LogicalNand", "LogicalOr", "LogicalNor", "LogicalXor", "LogicalEquiv", "LogicalAndReverse",
    "LogicalAndInverted", "LogicalOrReverse", "LogicalOrInverted", "Multiply", "Screen", "Overlay", "Darken",
    "Lighten", "ColorDodge", "ColorBurn", "HardLight", "SoftLight", "Difference", "Exclusion", "HSLHue",
    "HSLSaturation", "HSLColor", "HSLLuminosity",
)
_OTHER_BLENDOP_WORDS = {name.lower(): name for name in OTHER_BLENDOPS} | {"logicalequivalence": "LogicalEquiv"}
_STENCILOP_BY_NUMBER = {  # UnityEngine.Rendering.StencilOp
    0: StencilOp.Keep, 1: StencilOp.Zero, 2: StencilOp.Replace, 3: StencilOp.IncrSat,
    4: StencilOp.DecrSat, 5: StencilOp.Invert, 6: StencilOp.IncrWrap, 7: StencilOp.DecrWrap,
}

_ZTEST_WORDS = {c.value.lower(): c for c in CompareFunction} | {"off": CompareFunction.Always}
#: ``AlphaTest`` comparisons; ``Off`` (and the number 0, CompareFunction.Disabled) is None.
_ALPHATEST_WORDS = {c.value.lower(): c for c in CompareFunction} | {"off": None}
_ALPHATEST_BY_NUMBER = {**_COMPARE_BY_NUMBER, 0: None}
_ON_OFF_WORDS = {"on": True, "off": False, "true": True, "false": False}
#: What ``ColorMaterial`` takes the vertex colour for.
_COLOR_MATERIAL_WORDS = {"ambientanddiffuse": "AmbientAndDiffuse", "emission": "Emission"}
_STENCIL_COMP_WORDS = {c.value.lower(): c for c in CompareFunction}
_STENCIL_FIELDS = {"ref": "stencil_ref", "readmask": "stencil_read_mask", "writemask": "stencil_write_mask",
                   "comp": "stencil_comp", "pass": "stencil_pass", "fail": "stencil_fail", "zfail": "stencil_zfail"}


@functools.cache
def _enum_words(cls) -> dict[str, Any]:
    """Lower-case value → member of a vocabulary enum (built once per enum: parsing is per token)."""
    return {m.value.lower(): m for m in cls}


# --------------------------------------------------------------------------- values


@dataclass(frozen=True)
class MaterialValues:
    """What a material (a ``.mat`` file) gives its properties, by name: ``floats`` (Float, Range,
    Int) and ``colors`` (Color, Vector: 4 floats). A ``[_Prop]`` reads these before the
    property's default; a name a material holds needs no declaration in Properties."""

    floats: Mapping[str, float] = field(default_factory=dict)
    colors: Mapping[str, tuple[float, float, float, float]] = field(default_factory=dict)


#: The global that Unity's UI sets to ``CompareFunction.LessEqual`` (4) for canvases in camera or
#: world space (``ZTest [unity_GUIZTestMode]`` in UI/Default and the other UI shaders).
GUI_ZTEST_GLOBAL = "unity_GUIZTestMode"


class _Values:
    """Reads a command's :class:`~.tree.Value` s; a value Unity would not accept raises at its position.

    ``material``: the values of a ``.mat`` file (None: the defaults). ``warnings``: where the
    reads of globals are listed (None: not listed)."""

    def __init__(self, filename: str, material: MaterialValues | None = None,
                 warnings: list[SourceWarning] | None = None) -> None:
        self.filename = filename
        self.material = material or MaterialValues()
        self.warnings = warnings

    def error(self, message: str, at: Token) -> ShaderLabError:
        return ShaderLabError(message, at.line, at.column, self.filename)

    def warn(self, message: str, at: Token) -> None:
        if self.warnings is not None:
            self.warnings.append(SourceWarning.at(at, message))

    def raw(self, value: Value, kind: str = "float") -> Any:
        """The word or number text as written, or a reference's value: the material's, else the
        property's default (a float; a 4-tuple for ``kind`` "color"), else a global's."""
        if not value.reference:
            return value.token.text
        prop, name = value.declared, value.token.text
        stored = (self.material.floats if kind == "float" else self.material.colors).get(name)
        if stored is not None:
            return stored
        if prop is None:
            if kind == "float" and name == GUI_ZTEST_GLOBAL:
                self.warn(f"[{name}] is a global that Unity's UI sets to LEqual for canvases in camera or world "
                          "space; imported as LEqual", value.token)
                return 4.0
            self.warn(f"{value.what} refers to [{name}], which is not in Properties: a global, which Unity reads "
                      "as 0 unless a script sets it; imported as 0", value.token)
            return 0.0 if kind == "float" else (0.0, 0.0, 0.0, 0.0)
        if kind == "color":
            if not isinstance(prop.default, tuple):
                raise self.error(f"{value.what} refers to [{name}], which is not a Color/Vector property",
                                 value.token)
            return prop.default
        if not isinstance(prop.default, float):
            raise self.error(f"{value.what} refers to [{name}], which is not a Float/Int/Range property", value.token)
        return prop.default

    def number(self, value: Value) -> float:
        raw = self.raw(value)
        if not value.reference and value.token.kind != "number":
            raise self.error(f"expected a number for {value.what}, found {value.token.describe()}", value.token)
        return float(raw)

    def _from(self, value: Value) -> str:
        return "the material" if value.token.text in self.material.floats else "the property"

    def word(self, value: Value, cls, by_number: dict[int, Any], words: dict[str, Any] | None = None) -> Any:
        """An enum member: a word by name, a reference's number by Unity's numbering ``by_number``."""
        raw = self.raw(value)
        if value.reference:
            if raw != int(raw) or int(raw) not in by_number:
                raise self.error(f"{value.what} value {raw:g} from {self._from(value)} is not supported",
                                 value.token)
            return by_number[int(raw)]
        words = words or _enum_words(cls)
        key = str(raw).lower()
        if key not in words:
            choices = ", ".join(dict.fromkeys(str(m) for m in words.values() if m is not None))
            raise self.error(f"unknown {value.what} {raw!r} (expected one of: {choices})", value.token)
        return words[key]

    def on_off(self, value: Value) -> bool:
        raw = self.raw(value)
        if value.reference:
            return raw != 0
        if str(raw).lower() not in _ON_OFF_WORDS:
            raise self.error(f"unknown {value.what} value {raw!r} (expected On or Off)", value.token)
        return _ON_OFF_WORDS[str(raw).lower()]

    def blend_op(self, value: Value) -> BlendOp | str:
        """A BlendOp: the member, or the name of a logical/advanced operation (drawn as Add)."""
        raw = self.raw(value)
        if value.reference and raw == int(raw) and 5 <= int(raw) < 5 + len(OTHER_BLENDOPS):
            return OTHER_BLENDOPS[int(raw) - 5]
        if not value.reference and str(raw).lower() in _OTHER_BLENDOP_WORDS:
            return _OTHER_BLENDOP_WORDS[str(raw).lower()]
        return self.word(value, BlendOp, _BLENDOP_BY_NUMBER)

    def color_mask(self, value: Value) -> frozenset[str]:
        raw = self.raw(value)
        if value.reference:
            if raw != int(raw) or not 0 <= raw <= 15:
                raise self.error(f"ColorMask value {raw:g} from {self._from(value)} is not 0..15", value.token)
            return color_mask_from_bits(int(raw))  # Unity's ColorWriteMask numbering
        try:
            return parse_color_mask(str(raw))
        except ValueError as exc:
            raise self.error(str(exc), value.token) from None

    def stencil_byte(self, value: Value) -> int:
        number = self.number(value)
        if number != int(number) or not 0 <= number <= 255:
            raise self.error(f"{value.what} must be an integer 0..255, got {number:g}", value.token)
        return int(number)

    def color(self, command: Command) -> tuple[float, float, float, float]:
        """A colour argument (``Color``, ``Material``'s): the literal, or the reference's value."""
        if command.color is not None:
            return command.color
        value = command.values[0]
        if not value.reference:  # a word where the colour goes (a stray line's word, say)
            raise self.error(f"expected a colour (r, g, b, a) or a [Property] for {value.what}, "
                             f"found {value.token.describe()}", value.token)
        return tuple(float(c) for c in self.raw(value, "color"))

    def read(self, command: str, value: Value, index: int = 0) -> Any:
        """The value of argument ``index`` of ``command`` (a command's, a Stencil or Material
        command's lower-case name)."""
        if command == "cull":
            return self.word(value, Cull, _CULL_BY_NUMBER)
        if command in ("zwrite", "alphatomask", "lighting", "separatespecular"):
            return self.on_off(value)
        if command == "ztest":
            return self.word(value, CompareFunction, _COMPARE_BY_NUMBER, _ZTEST_WORDS)
        if command == "blend":
            return self.word(value, BlendFactor, _FACTOR_BY_NUMBER)
        if command == "blendop":
            return self.blend_op(value)
        if command == "colormask":
            return self.color_mask(value)
        if command in ("offset", "shininess"):
            return self.number(value)
        if command in ("ref", "readmask", "writemask"):
            return self.stencil_byte(value)
        if command == "comp":
            return self.word(value, CompareFunction, _COMPARE_BY_NUMBER, _STENCIL_COMP_WORDS)
        if command in ("pass", "fail", "zfail"):
            return self.word(value, StencilOp, _STENCILOP_BY_NUMBER)
        if command == "alphatest":
            if index == 0:
                return self.word(value, CompareFunction, _ALPHATEST_BY_NUMBER, _ALPHATEST_WORDS)
            return self.number(value)
        if command == "colormaterial":
            return self.word(value, None, {}, _COLOR_MATERIAL_WORDS)
        if command in ("color", "diffuse", "ambient", "specular", "emission"):
            return self.raw(value, "color")
        return self.raw(value)  # commands that set nothing here: a reference must still name a property


def _commands(items: Iterable) -> Iterator[Command]:
    """Every command among ``items`` and the blocks inside them, in source order (Stencil's and
    Material's included)."""
    for item in items:
        if isinstance(item, Command):
            yield item
            yield from item.commands
        elif isinstance(item, PassBlock):
            yield from _commands(item.commands)
        elif isinstance(item, (CategoryBlock, SubShaderBlock)):
            yield from _commands(item.body)


def check_values(shader: ShaderBlock, material: MaterialValues | None = None) -> None:
    """Raise :class:`~.diagnostics.ShaderLabError` for the first value in ``shader`` (in source order)
    that Unity would not accept; the tree may be one a syntax error cut short."""
    values = _Values(shader.filename, material)
    for command in _commands(shader.body):
        for index, value in enumerate(command.values):
            values.read(command.name, value, index)


# --------------------------------------------------------------------------- inheritance


@dataclass
class PassState:
    """A pass with the state that applies to it: its own commands over its SubShader's over the Categories'.

    ``state`` keys (absent = not stated): ``cull``, ``zwrite``, ``ztest``, ``color_mask``,
    ``alpha_to_mask`` (Pass values; ``ztest`` may be Never: :attr:`draws_nothing`); ``blend``
    (None = Off, or 2 or 4 factors); ``blend_ops`` (1 or 2 ops); ``offset`` (factor, units);
    ``stencil`` (the ``stencil_*`` Pass fields its ``Stencil { }`` states); the fixed-function
    ``lighting``, ``separate_specular`` (bools), ``color_material`` ("AmbientAndDiffuse" or
    "Emission"), ``ff_color`` (``Color``: 4 floats), ``ff_material`` (``Material { }``: lower-case
    name → colour or Shininess number), ``ff_alpha_test`` (``AlphaTest``: comparison or None for
    Off, the value or None, and the property the value came from or None). ``where``: the command
    that set each key.
    """

    block: PassBlock
    state: dict[str, Any]
    where: dict[str, Token] = field(default_factory=dict)

    @property
    def draws_nothing(self) -> bool:
        """``ZTest Never``: no fragment passes the depth test."""
        return self.state.get("ztest") is CompareFunction.Never

    def pass_fields(self) -> dict[str, Any]:
        """The :class:`~blendlib.core.vocabulary.Pass` fields the state sets (name, light mode
        and alpha test aside)."""
        state = self.state
        kwargs: dict[str, Any] = {key: state[key] for key in ("cull", "zwrite", "ztest", "color_mask", "alpha_to_mask")
                                  if key in state}
        if self.draws_nothing:
            del kwargs["ztest"]
        blend = state.get("blend")
        ops = state.get("blend_ops")
        if blend is not None:
            kwargs.update(blend=True, src_blend=blend[0], dst_blend=blend[1])
            if len(blend) == 4:
                kwargs.update(separate_alpha=True, src_blend_alpha=blend[2], dst_blend_alpha=blend[3])
        if ops is not None:
            kwargs["blend_op"] = ops[0]
            if len(ops) == 2:  # BlendOp colour, alpha: a separate alpha state
                kwargs["blend_op_alpha"] = ops[1]
                if not kwargs.get("separate_alpha"):
                    kwargs["separate_alpha"] = True
                    kwargs["src_blend_alpha"] = kwargs.get("src_blend", BlendFactor.One)
                    kwargs["dst_blend_alpha"] = kwargs.get("dst_blend", BlendFactor.Zero)
            elif kwargs.get("separate_alpha"):  # Blend A B, C D with one BlendOp: the op applies to both
                kwargs["blend_op_alpha"] = ops[0]
        if "offset" in state:
            kwargs["offset_factor"], kwargs["offset_units"] = state["offset"]
        if "stencil" in state:
            kwargs["stencil"] = True
            kwargs.update(state["stencil"])
        return kwargs


@dataclass
class ResolvedShader:
    """The first SubShader's tags, its passes with their state and its UsePasses in order (``items``),
    the UsePass paths; the warnings about the state commands."""

    tags: dict[str, str] = field(default_factory=dict)
    queue_token: Token | None = None  # where the SubShader's Queue tag's value stands
    items: list[PassState | UsePass] = field(default_factory=list)
    use_passes: list[str] = field(default_factory=list)
    warnings: list[SourceWarning] = field(default_factory=list)

    @property
    def passes(self) -> list[PassState]:
        """The passes written in the SubShader (UsePasses aside)."""
        return [item for item in self.items if isinstance(item, PassState)]


def resolve(shader: ShaderBlock, material: MaterialValues | None = None) -> ResolvedShader:
    """Check every value (:func:`check_values`), then combine the state of each pass of the first
    SubShader, with ``material``'s values for ``[_Prop]`` references."""
    check_values(shader, material)
    return _Resolver(shader.filename, material).resolve(shader)


class _Resolver:
    def __init__(self, filename: str, material: MaterialValues | None) -> None:
        self.out = ResolvedShader()
        self.values = _Values(filename, material, self.out.warnings)
        self.seen_subshader = False

    def resolve(self, shader: ShaderBlock) -> ResolvedShader:
        self.container(shader, {}, {})
        return self.out

    def warn(self, message: str, at: Token) -> None:
        self.out.warnings.append(SourceWarning.at(at, message))

    def container(self, block: CategoryBlock, outer: dict[str, Any], outer_where: dict[str, Token]) -> None:
        """A Shader or Category body: its state so far applies to each SubShader and Category in it."""
        own: dict[str, Any] = {}
        where: dict[str, Token] = {}
        for item in block.body:
            if isinstance(item, Command):
                self.apply(item, own, where)
            elif isinstance(item, TagsBlock):
                if not self.seen_subshader:
                    self.out.tags.update(item.tags)
            elif isinstance(item, SubShaderBlock):
                self.seen_subshader = True
                self.subshader(item, {**outer, **own}, {**outer_where, **where})
            else:
                self.container(item, {**outer, **own}, {**outer_where, **where})

    def subshader(self, subshader: SubShaderBlock, outer: dict[str, Any], outer_where: dict[str, Token]) -> None:
        """Its state (all of it, wherever it stands among the passes) applies to every pass."""
        own: dict[str, Any] = {}
        where: dict[str, Token] = {}
        items: list[tuple[PassBlock, dict[str, Any], dict[str, Token]] | UsePass] = []
        for item in subshader.body:
            if isinstance(item, Command):
                self.apply(item, own, where)
            elif isinstance(item, PassBlock):
                pass_state: dict[str, Any] = {}
                pass_where: dict[str, Token] = {}
                for command in item.commands:
                    self.apply(command, pass_state, pass_where)
                items.append((item, pass_state, pass_where))
            elif isinstance(item, UsePass):
                self.out.use_passes.append(item.path)
                items.append(item)
            elif isinstance(item, GrabPass):
                self.warn("GrabPass ignored: it copies the frame into a texture and draws nothing; a pass that "
                          "samples the texture draws without it here", item.head)
            elif isinstance(item, ProgramBlock):
                self.warn("a program directly in the SubShader without '#pragma surface' generates no pass; "
                          "ignored", item.token)
        subshader_state = {**outer, **own}
        subshader_where = {**outer_where, **where}
        for item in items:
            if isinstance(item, UsePass):
                self.out.items.append(item)
            else:
                block, state, pass_where = item
                self.out.items.append(PassState(block, {**subshader_state, **state},
                                                {**subshader_where, **pass_where}))
        self.out.tags.update(subshader.tags)
        self.out.queue_token = subshader.queue_token

    def apply(self, command: Command, state: dict[str, Any], where: dict[str, Token]) -> None:
        """Update ``state`` with what ``command`` sets, ``where`` with the command for each key."""
        settings = self.settings(command)
        state.update(settings)
        where.update(dict.fromkeys(settings, command.head))

    def settings(self, command: Command) -> dict[str, Any]:
        """What one command sets (see :class:`PassState` for the keys); nothing for commands that set nothing."""
        name = command.name
        values = [self.values.read(name, value, index) for index, value in enumerate(command.values)]
        if name in ("cull", "zwrite", "ztest", "lighting"):
            return {name: values[0]}
        if name == "blend":
            if self.other_render_target(command, "Blend"):
                return {}
            return {"blend": tuple(values) if values else None}
        if name == "blendop":
            for op in values:
                if not isinstance(op, BlendOp):
                    self.warn(f"BlendOp {op} (a logical or advanced blend operation) draws as Add, as Unity "
                              "documents for Vulkan and Metal", command.head)
            return {"blend_ops": tuple(op if isinstance(op, BlendOp) else BlendOp.Add for op in values)}
        if name == "colormask":
            if self.other_render_target(command, "ColorMask"):
                return {}
            return {"color_mask": values[0]}
        if name == "offset":
            return {"offset": tuple(values)}
        if name == "alphatomask":
            return {"alpha_to_mask": values[0]}
        if name == "stencil":
            return {"stencil": self.stencil(command)}
        if name == "separatespecular":
            return {"separate_specular": values[0]}
        if name == "colormaterial":
            return {"color_material": values[0]}
        if name == "color":
            return {"ff_color": self.values.color(command)}
        if name == "material":
            return {"ff_material": {c.name: (self.values.number(c.values[0]) if c.name == "shininess"
                                             else self.values.color(c)) for c in command.commands}}
        if name == "alphatest":
            cutoff = command.values[1] if len(command.values) > 1 else None
            return {"ff_alpha_test": (values[0], values[1] if cutoff is not None else None,
                                      cutoff.token.text if cutoff is not None and cutoff.reference else None)}
        return {}

    def other_render_target(self, command: Command, keyword: str) -> bool:
        """Whether the command is for a render target other than 0 (ignored, warned)."""
        target = command.render_target
        if target is not None and float(target.text) != 0:
            self.warn(f"{keyword} for render target {target.text} ignored: the frame is render target 0", target)
            return True
        return False

    def stencil(self, stencil: Command) -> dict[str, Any]:
        fields: dict[str, Any] = {}
        for command in stencil.commands:
            value = self.values.read(command.name, command.values[0])
            if command.name in _STENCIL_FIELDS:
                fields[_STENCIL_FIELDS[command.name]] = value
                if command.values[0].reference:  # the binding itself is not kept
                    self.warn(f"Stencil {command.head.text} [{command.values[0].token.text}]: imported as the "
                              f"property's default {getattr(value, 'value', value)!s}; a material's own value "
                              "is not applied and an export writes this number", command.values[0].token)
            else:
                self.warn(f"Stencil {command.head.text} (per-face stencil) is not supported and ignored",
                          command.head)
        return fields


# --------------------------------------------------------------------------- the Queue tag


def parse_queue(text: str) -> tuple[Queue, int]:
    """``"Transparent+1"`` → (Transparent, 1); ``"2450"`` → (AlphaTest, 0); ValueError if unknown.

    A number maps to the nearest named queue at or below it (Background for numbers
    below 1000) plus the difference, so the render-queue number is kept.
    """
    word = "".join(str(text).split())
    m = re.fullmatch(r"([A-Za-z]+)(?:([+-])(\d+))?", word)
    if m:
        queue = Queue.parse(m.group(1))
        offset = int(m.group(3) or 0) * (-1 if m.group(2) == "-" else 1)
        return queue, offset
    if re.fullmatch(r"\d+", word):
        number = int(word)
        below = [q for q in Queue if QUEUE_NUMBERS[q] <= number]
        queue = max(below, key=lambda q: QUEUE_NUMBERS[q]) if below else Queue.Background
        return queue, number - QUEUE_NUMBERS[queue]
    raise ValueError(f"bad queue {text!r} (expected e.g. Transparent, Transparent+1, Geometry-10 or 2450)")
