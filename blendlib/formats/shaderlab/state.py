"""Render state as the parsed commands set it: Unity's enum tables, ``[_Prop]`` values, inheritance.

From the tree of :mod:`.tree`:

* each command's values read as Unity reads them — a word by its name (case-insensitive), a
  ``[_Prop]`` reference as the property's default value with Unity's numbering of the command's
  enum (``UnityEngine.Rendering.CullMode``, ``CompareFunction``, ``BlendMode``, ``BlendOp``,
  ``StencilOp``, ``ColorWriteMask``);
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
from collections.abc import Iterable, Iterator
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
from .tree import CategoryBlock, Command, PassBlock, ShaderBlock, SubShaderBlock, TagsBlock, UsePass, Value

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
_STENCILOP_BY_NUMBER = {  # UnityEngine.Rendering.StencilOp
    0: StencilOp.Keep, 1: StencilOp.Zero, 2: StencilOp.Replace, 3: StencilOp.IncrSat,
    4: StencilOp.DecrSat, 5: StencilOp.Invert, 6: StencilOp.IncrWrap, 7: StencilOp.DecrWrap,
}

_ZTEST_WORDS = {c.value.lower(): c for c in CompareFunction} | {"off": CompareFunction.Always}
_STENCIL_COMP_WORDS = {c.value.lower(): c for c in CompareFunction}
_STENCIL_FIELDS = {"ref": "stencil_ref", "readmask": "stencil_read_mask", "writemask": "stencil_write_mask",
                   "comp": "stencil_comp", "pass": "stencil_pass", "fail": "stencil_fail", "zfail": "stencil_zfail"}


@functools.cache
def _enum_words(cls) -> dict[str, Any]:
    """Lower-case value → member of a vocabulary enum (built once per enum: parsing is per token)."""
    return {m.value.lower(): m for m in cls}


# --------------------------------------------------------------------------- values


class _Values:
    """Reads a command's :class:`~.tree.Value` s; a value Unity would not accept raises at its position."""

    def __init__(self, filename: str) -> None:
        self.filename = filename

    def error(self, message: str, at: Token) -> ShaderLabError:
        return ShaderLabError(message, at.line, at.column, self.filename)

    def raw(self, value: Value) -> Any:
        """The word or number text as written, or a reference's property default (a float)."""
        if not value.reference:
            return value.token.text
        prop, name = value.declared, value.token.text
        if prop is None:
            raise self.error(f"{value.what} refers to [{name}], which is not in Properties", value.token)
        if not isinstance(prop.default, float):
            raise self.error(f"{value.what} refers to [{name}], which is not a Float/Int/Range property", value.token)
        return prop.default

    def number(self, value: Value) -> float:
        raw = self.raw(value)
        if not value.reference and value.token.kind != "number":
            raise self.error(f"expected a number for {value.what}, found {value.token.describe()}", value.token)
        return float(raw)

    def word(self, value: Value, cls, by_number: dict[int, Any], words: dict[str, Any] | None = None) -> Any:
        """An enum member: a word by name, a reference's number by Unity's numbering ``by_number``."""
        raw = self.raw(value)
        if value.reference:
            if raw != int(raw) or int(raw) not in by_number:
                raise self.error(f"{value.what} value {raw:g} from the property is not supported", value.token)
            return by_number[int(raw)]
        words = words or _enum_words(cls)
        member = words.get(str(raw).lower())
        if member is None:
            choices = ", ".join(dict.fromkeys(m.value for m in words.values()))
            raise self.error(f"unknown {value.what} {raw!r} (expected one of: {choices})", value.token)
        return member

    def on_off(self, value: Value) -> bool:
        raw = self.raw(value)
        if value.reference:
            return raw != 0
        if str(raw).lower() not in ("on", "off"):
            raise self.error(f"unknown {value.what} value {raw!r} (expected On or Off)", value.token)
        return str(raw).lower() == "on"

    def ztest(self, value: Value) -> CompareFunction:
        ztest = self.word(value, CompareFunction, _COMPARE_BY_NUMBER, _ZTEST_WORDS)
        if ztest is CompareFunction.Never:
            raise self.error("ZTest Never is not supported (nothing would be drawn)", value.token)
        return ztest

    def color_mask(self, value: Value) -> frozenset[str]:
        raw = self.raw(value)
        if value.reference:
            if raw != int(raw) or not 0 <= raw <= 15:
                raise self.error(f"ColorMask value {raw:g} from the property is not 0..15", value.token)
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

    def read(self, command: str, value: Value) -> Any:
        """The value of an argument of ``command`` (a command's or a Stencil command's lower-case name)."""
        if command == "cull":
            return self.word(value, Cull, _CULL_BY_NUMBER)
        if command in ("zwrite", "alphatomask"):
            return self.on_off(value)
        if command == "ztest":
            return self.ztest(value)
        if command == "blend":
            return self.word(value, BlendFactor, _FACTOR_BY_NUMBER)
        if command == "blendop":
            return self.word(value, BlendOp, _BLENDOP_BY_NUMBER)
        if command == "colormask":
            return self.color_mask(value)
        if command == "offset":
            return self.number(value)
        if command in ("ref", "readmask", "writemask"):
            return self.stencil_byte(value)
        if command == "comp":
            return self.word(value, CompareFunction, _COMPARE_BY_NUMBER, _STENCIL_COMP_WORDS)
        if command in ("pass", "fail", "zfail"):
            return self.word(value, StencilOp, _STENCILOP_BY_NUMBER)
        return self.raw(value)  # commands that set nothing here: a reference must still name a property


def _commands(items: Iterable) -> Iterator[Command]:
    """Every command among ``items`` and the blocks inside them, in source order (Stencil's included)."""
    for item in items:
        if isinstance(item, Command):
            yield item
            yield from item.commands
        elif isinstance(item, PassBlock):
            yield from _commands(item.commands)
        elif isinstance(item, (CategoryBlock, SubShaderBlock)):
            yield from _commands(item.body)


def check_values(shader: ShaderBlock) -> None:
    """Raise :class:`~.diagnostics.ShaderLabError` for the first value in ``shader`` (in source order)
    that Unity would not accept; the tree may be one a syntax error cut short."""
    values = _Values(shader.filename)
    for command in _commands(shader.body):
        for value in command.values:
            values.read(command.name, value)


# --------------------------------------------------------------------------- inheritance


@dataclass
class PassState:
    """A pass with the state that applies to it: its own commands over its SubShader's over the Categories'.

    ``state`` keys (absent = not stated): ``cull``, ``zwrite``, ``ztest``, ``color_mask`` (Pass values);
    ``blend`` (None = Off, or 2 or 4 factors); ``blend_ops`` (1 or 2 ops); ``offset`` (factor, units);
    ``stencil`` (the ``stencil_*`` Pass fields its ``Stencil { }`` states).
    """

    block: PassBlock
    state: dict[str, Any]

    def pass_fields(self) -> dict[str, Any]:
        """The :class:`~blendlib.core.vocabulary.Pass` fields the state sets (name and alpha test aside)."""
        state = self.state
        kwargs: dict[str, Any] = {key: state[key] for key in ("cull", "zwrite", "ztest", "color_mask") if key in state}
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
    """The first SubShader's tags, passes with their state and UsePass paths; the warnings about the
    state commands."""

    tags: dict[str, str] = field(default_factory=dict)
    queue_token: Token | None = None  # where the SubShader's Queue tag's value stands
    passes: list[PassState] = field(default_factory=list)
    use_passes: list[str] = field(default_factory=list)
    warnings: list[SourceWarning] = field(default_factory=list)


def resolve(shader: ShaderBlock) -> ResolvedShader:
    """Check every value (:func:`check_values`), then combine the state of each pass of the first SubShader."""
    check_values(shader)
    return _Resolver(shader.filename).resolve(shader)


class _Resolver:
    def __init__(self, filename: str) -> None:
        self.values = _Values(filename)
        self.out = ResolvedShader()
        self.seen_subshader = False

    def resolve(self, shader: ShaderBlock) -> ResolvedShader:
        self.container(shader, {})
        return self.out

    def warn(self, message: str, at: Token) -> None:
        self.out.warnings.append(SourceWarning.at(at, message))

    def container(self, block: CategoryBlock, outer: dict[str, Any]) -> None:
        """A Shader or Category body: its state so far applies to each SubShader and Category in it."""
        own: dict[str, Any] = {}
        for item in block.body:
            if isinstance(item, Command):
                own.update(self.settings(item))
            elif isinstance(item, TagsBlock):
                if not self.seen_subshader:
                    self.out.tags.update(item.tags)
            elif isinstance(item, SubShaderBlock):
                self.seen_subshader = True
                self.subshader(item, {**outer, **own})
            else:
                self.container(item, {**outer, **own})

    def subshader(self, subshader: SubShaderBlock, outer: dict[str, Any]) -> None:
        """Its state (all of it, wherever it stands among the passes) applies to every pass."""
        own: dict[str, Any] = {}
        passes: list[tuple[PassBlock, dict[str, Any]]] = []
        for item in subshader.body:
            if isinstance(item, Command):
                own.update(self.settings(item))
            elif isinstance(item, PassBlock):
                pass_state: dict[str, Any] = {}
                for command in item.commands:
                    pass_state.update(self.settings(command))
                passes.append((item, pass_state))
            elif isinstance(item, UsePass):
                self.out.use_passes.append(item.path)
        subshader_state = {**outer, **own}
        self.out.passes += [PassState(block, {**subshader_state, **state}) for block, state in passes]
        self.out.tags.update(subshader.tags)
        self.out.queue_token = subshader.queue_token

    def settings(self, command: Command) -> dict[str, Any]:
        """What one command sets (see :class:`PassState` for the keys); nothing for commands that set nothing."""
        name = command.name
        values = [self.values.read(name, value) for value in command.values]
        if name in ("cull", "zwrite", "ztest"):
            return {name: values[0]}
        if name == "blend":
            self.render_target_warning(command, "Blend")
            return {"blend": tuple(values) if values else None}
        if name == "blendop":
            return {"blend_ops": tuple(values)}
        if name == "colormask":
            self.render_target_warning(command, "ColorMask")
            return {"color_mask": values[0]}
        if name == "offset":
            return {"offset": tuple(values)}
        if name == "alphatomask" and values[0]:
            self.warn("AlphaToMask On is not supported (no MSAA); the pass is imported without it", command.head)
        if name == "stencil":
            return {"stencil": self.stencil(command)}
        return {}

    def render_target_warning(self, command: Command, keyword: str) -> None:
        target = command.render_target
        if target is not None and float(target.text) != 0:
            self.warn(f"{keyword} for render target {target.text} applied to the only colour buffer", target)

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
