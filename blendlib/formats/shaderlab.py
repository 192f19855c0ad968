"""ShaderLab import and export: ``.shader`` text <-> Unity material settings.

Import parses the ShaderLab subset that decides render state and returns a
:class:`ShaderLabResult`: the typed :class:`blendlib.core.vocabulary.Material`
(one :class:`~blendlib.core.vocabulary.Pass` per ``Pass { }``, no texture image),
a list of warnings and what else the file says (``extra``):

* ``Shader "name" { ... }``; ``Properties`` (defaults of ``_Color``, ``_MainTex``,
  ``_Cutoff``, ``_AlphaScale``, any attributes such as ``[Enum(...)]``/``[Toggle]``);
  the first ``SubShader`` (``Category`` blocks are flattened, later SubShaders are
  reported and ignored); ``Tags`` (``Queue`` with ``+N``/``-N`` or a number,
  ``RenderType``, ``IgnoreProjector``, ``LightMode``); ``Pass``; ``Name``;
  ``UsePass``/``Fallback`` (recorded).
* State commands ``Cull``, ``ZWrite``, ``ZTest`` (``Off`` = ``Always``), ``Blend``
  (``Off``, two or four factors), ``BlendOp`` (one or two ops), ``ColorMask``,
  ``Offset``, ``AlphaToMask`` (warning), ``Stencil { ... }``; any argument may be a
  ``[_Prop]`` reference, resolved from the property's default value with Unity's
  numbering of the command's enum (``UnityEngine.Rendering.CullMode`` etc.).
  State at SubShader (or Category) level applies to every pass below it; a pass's
  own commands override it.
* Keywords are case-insensitive; ``//`` and ``/* */`` comments; ``CGPROGRAM`` /
  ``HLSLPROGRAM`` / ``CGINCLUDE`` ... blocks are kept as text and inspected:
  ``clip(`` in a pass's program sets that pass's ``alpha_test``; ``_LightColor0`` in
  any program selects ``Lambert`` lighting, none selects ``Unlit``.

A numeric queue (``"Queue"="2450"``) maps to the nearest named queue at or below
it plus an offset (``2450`` → ``AlphaTest+0``, ``2600`` → ``AlphaTest+150``, ``500`` →
``Background-500``), which gives the same render-queue number.

Errors raise :class:`ShaderLabError` (one line: ``FILE:LINE:COL: message``) and
nothing is returned; unknown commands are warnings.

Export (:func:`export_shaderlab`) writes a complete shader in the style of the
book's chapter 8 shaders whose import gives back the same settings (for the
fields a ``.shader`` file holds; the texture image, its tiling/offset and sampler
settings belong to the Unity material and texture asset, not the shader).

This module does not use bpy; ``python -m blendlib shaderlab --export`` opens the
.blend and reads the material through :mod:`blendlib.blender` (``blendlib/cli/shaderlab.py``).
"""

from __future__ import annotations

import bisect
import functools
import json
import math
import re
from dataclasses import dataclass, field, fields, replace
from decimal import Decimal
from typing import Any

from ..core.vocabulary import (
    CHANNELS,
    QUEUE_NUMBERS,
    BlendFactor,
    BlendOp,
    CompareFunction,
    Cull,
    Lighting,
    Material,
    Pass,
    Queue,
    StencilOp,
    color_mask_from_bits,
    float32_text,
    parse_color_mask,
    pass_state_commands,
    pass_to_dict,
    queue_text,
)

__all__ = [
    "ShaderLabError",
    "ShaderLabResult",
    "canonical_pass",
    "export_shaderlab",
    "parse_queue",
    "parse_shaderlab",
    "parse_shaderlab_file",
]


# --------------------------------------------------------------------------- errors


class ShaderLabError(ValueError):
    """A ShaderLab parse error at a position; ``str()`` is one line ``FILE:LINE:COL: message``."""

    def __init__(self, message: str, line: int, column: int, filename: str = "<string>") -> None:
        self.message = " ".join(str(message).split())
        self.line = int(line)
        self.column = int(column)
        self.filename = filename
        super().__init__(str(self))

    def __str__(self) -> str:
        return f"{self.filename}:{self.line}:{self.column}: {self.message}"


# --------------------------------------------------------------------------- scanner


@dataclass(slots=True)  # not frozen: a frozen dataclass's __init__ is several times slower
class Token:
    kind: str  # "ident", "string", "number", "code", "punct", "eof"
    text: str  # identifier / string contents / number text / program text / punctuation
    line: int
    column: int
    end: int  # offset just past the token in the source
    code_kind: str = ""  # CGPROGRAM, HLSLPROGRAM, CGINCLUDE, HLSLINCLUDE, GLSLPROGRAM

    @property
    def lower(self) -> str:
        return self.text.lower()

    def describe(self) -> str:
        if self.kind == "eof":
            return "end of file"
        if self.kind == "string":
            return f'"{self.text}"'
        if self.kind == "code":
            return self.code_kind
        return repr(self.text)


_CODE_BLOCKS = {
    "cgprogram": "ENDCG",
    "cginclude": "ENDCG",
    "hlslprogram": "ENDHLSL",
    "hlslinclude": "ENDHLSL",
    "glslprogram": "ENDGLSL",
    "glslinclude": "ENDGLSL",
}
_PUNCT = "{}()[],=+"
_NUMBER_RE = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_IDENT_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_SPACE_RE = re.compile(r"(?:[\s\ufeff]+|//[^\n]*\n?|/\*.*?\*/)*", re.DOTALL)  # spaces and closed comments

#: ``Category`` blocks nest at most this deep (deeper input is an error, not a RecursionError).
MAX_NESTING = 64
#: A warning with the same text (position aside) is listed this often, then summed up as "and N more".
MAX_REPEATED_WARNINGS = 10


class Scanner:
    """An on-demand tokenizer that also hands out raw text (programs, attributes)."""

    def __init__(self, text: str, filename: str) -> None:
        self.text = text
        self.filename = filename
        self.pos = 0
        # Line starts for offset -> (line, column).
        self._line_starts = [0] + [m.end() for m in re.finditer(r"\r\n|\r|\n", text)]
        self._peeked: Token | None = None

    # positions -------------------------------------------------------------
    def where(self, offset: int) -> tuple[int, int]:
        lo = bisect.bisect_right(self._line_starts, offset) - 1
        return lo + 1, offset - self._line_starts[lo] + 1

    def error(self, message: str, at: Token | int) -> ShaderLabError:
        if isinstance(at, Token):
            line, col = at.line, at.column
        else:
            line, col = self.where(at)
        return ShaderLabError(message, line, col, self.filename)

    # scanning --------------------------------------------------------------
    def _skip_space_and_comments(self) -> None:
        self.pos = _SPACE_RE.match(self.text, self.pos).end()
        if self.text.startswith("/*", self.pos):
            raise self.error("comment '/*' is never closed by '*/'", self.pos)

    def peek(self) -> Token:
        if self._peeked is None:
            self._peeked = self._scan()
        return self._peeked

    def next(self) -> Token:
        tok = self.peek()
        self._peeked = None
        return tok

    def _scan(self) -> Token:
        self._skip_space_and_comments()
        text, start = self.text, self.pos
        line, col = self.where(start)
        if start >= len(text):
            return Token("eof", "", line, col, start)
        c = text[start]
        if c == '"':
            close = start + 1
            while close < len(text) and text[close] not in '"\n\r':
                close += 1
            if close >= len(text) or text[close] != '"':
                raise self.error("string is never closed by '\"'", start)
            self.pos = close + 1
            return Token("string", text[start + 1 : close], line, col, self.pos)
        m = _NUMBER_RE.match(text, start)
        if m and (c.isdigit() or c == "." or (c in "+-" and m.end() > start + 1)):
            if not math.isfinite(float(m.group())):
                raise self.error(f"number {m.group()} is out of range (not a finite float)", start)
            self.pos = m.end()
            return Token("number", m.group(), line, col, self.pos)
        if c in _PUNCT:
            self.pos = start + 1
            return Token("punct", c, line, col, self.pos)
        m = _IDENT_RE.match(text, start)
        if m:
            word = m.group()
            self.pos = m.end()
            end_word = _CODE_BLOCKS.get(word.lower())
            if end_word is not None:
                close = re.compile(r"\b" + end_word + r"\b", re.IGNORECASE).search(text, self.pos)
                if close is None:
                    raise self.error(f"{word} is never closed by {end_word}", start)
                body = text[self.pos : close.start()]
                self.pos = close.end()
                return Token("code", body, line, col, self.pos, code_kind=word.upper())
            return Token("ident", word, line, col, self.pos)
        raise self.error(f"unexpected character {c!r}", start)

    def _skip_string_at(self, i: int) -> int:
        close = i + 1
        while close < len(self.text) and self.text[close] not in '"\n\r':
            close += 1
        if close >= len(self.text) or self.text[close] != '"':
            raise self.error("string is never closed by '\"'", i)
        return close + 1

    def _skip_comment_or_program_at(self, i: int) -> int | None:
        """If a comment or a CGPROGRAM-like block starts at ``i``, the offset after it; else None."""
        text = self.text
        if text.startswith("//", i):
            nl = text.find("\n", i)
            return len(text) if nl < 0 else nl
        if text.startswith("/*", i):
            close = text.find("*/", i + 2)
            if close < 0:
                raise self.error("comment '/*' is never closed by '*/'", i)
            return close + 2
        m = _IDENT_RE.match(text, i)
        if m and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            end_word = _CODE_BLOCKS.get(m.group().lower())
            if end_word is None:
                return m.end()
            close = re.compile(r"\b" + end_word + r"\b", re.IGNORECASE).search(text, m.end())
            if close is None:
                raise self.error(f"{m.group()} is never closed by {end_word}", i)
            return close.end()
        return None

    def skip_raw_block(self, open_tok: Token, owner: str) -> None:
        """Skip to just after the ``}`` matching ``open_tok`` (strings, comments and programs respected)."""
        assert self._peeked is None
        depth, i, text = 1, open_tok.end, self.text
        while i < len(text):
            c = text[i]
            if c == '"':
                i = self._skip_string_at(i)
                continue
            j = self._skip_comment_or_program_at(i)
            if j is not None:
                i = j
                continue
            if c == "{":
                depth += 1
            elif c == "}":
                depth -= 1
                if depth == 0:
                    self.pos = i + 1
                    return
            i += 1
        raise self.error(f"unexpected end of file: '{{' of {owner} is never closed by '}}'", open_tok)

    def skip_rest_of_line(self) -> None:
        """Skip to the end of the line, through a ``{ ... }`` block opening on it; stop before ``}``."""
        assert self._peeked is None
        i, text = self.pos, self.text
        while i < len(text):
            c = text[i]
            if c in "\r\n" or text.startswith("//", i):
                break
            if c == "}":
                break
            if c == '"':
                i = self._skip_string_at(i)
                continue
            if c == "{":
                line, col = self.where(i)
                self.skip_raw_block(Token("punct", "{", line, col, i + 1), "the ignored command")
                return
            j = self._skip_comment_or_program_at(i)
            i = j if j is not None else i + 1
        self.pos = i

    def raw_until_bracket_close(self, open_tok: Token) -> str:
        """Raw text after ``[`` up to the matching ``]`` (attribute text, may hold anything)."""
        assert self._peeked is None
        depth, i, text = 0, open_tok.end, self.text
        while i < len(text):
            c = text[i]
            if c == "(":
                depth += 1
            elif c == ")":
                depth = max(0, depth - 1)
            elif c == "]" and depth == 0:
                self.pos = i + 1
                return text[open_tok.end : i]
            elif c in "\r\n":
                break
            i += 1
        raise self.error("attribute '[' is never closed by ']'", open_tok)


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


# --------------------------------------------------------------------------- result


@dataclass(frozen=True)
class ShaderLabResult:
    """What a ``.shader`` file says: the material (named as the shader, no texture image), warnings, extras.

    ``material.passes`` holds one pass per ``Pass { }`` (empty when the file has no
    SubShader: the material then draws one default pass).
    """

    material: Material
    warnings: tuple[str, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """The ``Shader "name"``."""
        return self.material.name

    @property
    def passes(self) -> tuple[Pass, ...]:
        return self.material.passes

    def to_dict(self) -> dict[str, Any]:
        """The JSON of ``python -m blendlib shaderlab``: ``material`` holds the ``Material.unity``
        fields other than the passes (``enabled`` true: an imported shader is in use)."""
        m = self.material
        material = {"enabled": True} | {f.name: getattr(m, f.name) for f in fields(Material)
                                         if f.name not in ("name", "passes")}
        return {
            "name": self.name,
            "material": _json_ready(material),
            "passes": [pass_to_dict(p) for p in self.passes],
            "warnings": list(self.warnings),
            "extra": _json_ready(self.extra),
        }

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent, ensure_ascii=False)


def _json_ready(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, (frozenset, set)):
        return [c for c in CHANNELS if c in value]
    if hasattr(value, "value") and isinstance(value, str):  # str enums
        return value.value
    return value


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


# --------------------------------------------------------------------------- parser


@dataclass
class _Property:
    name: str
    display: str
    type: str
    default: Any
    attributes: list[str]
    token: Token


@dataclass
class _State:
    """Render-state commands seen in one block (Category, SubShader or Pass)."""

    values: dict[str, Any] = field(default_factory=dict)

    def merged_over(self, outer: dict[str, Any]) -> dict[str, Any]:
        return {**outer, **self.values}


@dataclass
class _PassInfo:
    name: str | None
    state: dict[str, Any]
    programs: list[str]
    tags: dict[str, str]
    token: Token


class _Warnings(list):
    """Warnings ``"LINE:COL: message"``; a message repeated more than :data:`MAX_REPEATED_WARNINGS` times
    is listed that often, then one line at the first left-out position says how many more there are."""

    def __init__(self) -> None:
        super().__init__()
        self._counts: dict[str, int] = {}
        self._summary: dict[str, tuple[int, str]] = {}  # message -> (index of its summary line, position)

    def append(self, text: str) -> None:
        position, _, message = text.partition(": ")
        n = self._counts[message] = self._counts.get(message, 0) + 1
        if n <= MAX_REPEATED_WARNINGS:
            super().append(text)
            return
        if n == MAX_REPEATED_WARNINGS + 1:
            self._summary[message] = (len(self), position)
            super().append("")
        index, first = self._summary[message]
        self[index] = f"{first}: {message} (and {n - MAX_REPEATED_WARNINGS - 1} more like this left out)" \
            if n > MAX_REPEATED_WARNINGS + 1 else f"{first}: {message}"


class _Parser:
    def __init__(self, text: str, filename: str) -> None:
        self.s = Scanner(text, filename)
        self.warnings: list[str] = _Warnings()
        self.properties: dict[str, _Property] = {}
        self.fallback: str | None = None
        self.use_passes: list[str] = []
        self.subshader_tags: dict[str, str] = {}
        self.subshader_count = 0
        self.passes: list[_PassInfo] = []
        self.includes: list[str] = []  # CGINCLUDE/HLSLINCLUDE text that applies to the passes
        self.queue_token: Token | None = None
        self.extra_passes_note: list[str] = []

    # helpers ---------------------------------------------------------------
    def warn(self, message: str, at: Token) -> None:
        self.warnings.append(f"{at.line}:{at.column}: {message}")

    def expect(self, text: str, what: str | None = None) -> Token:
        tok = self.s.next()
        if not (tok.kind == "punct" and tok.text == text):
            raise self.s.error(f"expected '{text}'{' ' + what if what else ''}, found {tok.describe()}", tok)
        return tok

    def expect_string(self, what: str) -> Token:
        tok = self.s.next()
        if tok.kind != "string":
            raise self.s.error(f"expected a quoted {what}, found {tok.describe()}", tok)
        return tok

    def expect_number(self, what: str) -> tuple[float, Token]:
        tok = self.s.next()
        if tok.kind != "number":
            raise self.s.error(f"expected a number for {what}, found {tok.describe()}", tok)
        return float(tok.text), tok

    def at_punct(self, text: str) -> bool:
        tok = self.s.peek()
        return tok.kind == "punct" and tok.text == text

    def open_block(self, owner: Token) -> Token:
        tok = self.s.next()
        if not (tok.kind == "punct" and tok.text == "{"):
            raise self.s.error(f"expected '{{' after {owner.text}, found {tok.describe()}", tok)
        return tok

    def unclosed(self, open_tok: Token, owner: str) -> ShaderLabError:
        return self.s.error(f"unexpected end of file: '{{' of {owner} is never closed by '}}'", open_tok)

    def skip_rest_of_command(self, head: Token) -> None:
        """Skip an unknown command: the rest of its line, or up to the end of a ``{ ... }`` block
        opening on that line. Stops before a ``}`` that closes the enclosing block."""
        self.s.skip_rest_of_line()

    def skip_block(self, open_tok: Token, owner: str) -> None:
        """Skip the rest of a ``{ ... }`` block whose ``{`` was just read (any text, programs included)."""
        self.s.skip_raw_block(open_tok, owner)

    def skip_quiet(self, head: Token) -> None:
        """A known command that does not change what is drawn: skip its argument(s)."""
        if head.lower == "packagerequirements":
            self.skip_block(self.open_block(head), head.text)
        else:
            self.value(head.text)

    # top level -------------------------------------------------------------
    def parse(self) -> tuple[str, Token]:
        head = self.s.next()
        if head.kind != "ident" or head.lower != "shader":
            raise self.s.error(f"expected 'Shader \"name\" {{' at the start, found {head.describe()}", head)
        name = self.expect_string("shader name").text
        open_tok = self.open_block(head)
        self.parse_container(open_tok, "Shader", outer_state={}, in_category=False)
        tail = self.s.next()
        if tail.kind != "eof":
            raise self.s.error(f"unexpected {tail.describe()} after the end of the shader", tail)
        return name, head

    def parse_container(self, open_tok: Token, owner: str, outer_state: dict[str, Any], in_category: bool,
                        depth: int = 0) -> None:
        """The body of ``Shader`` or ``Category`` (``depth``: how many Category blocks enclose it)."""
        if depth > MAX_NESTING:
            raise self.s.error(f"Category blocks nested more than {MAX_NESTING} deep", open_tok)
        state = _State()
        while True:
            tok = self.s.next()
            if tok.kind == "eof":
                raise self.unclosed(open_tok, owner)
            if tok.kind == "punct" and tok.text == "}":
                return
            if tok.kind == "code":
                if tok.code_kind.endswith("INCLUDE"):
                    self.includes.append(tok.text)
                else:
                    self.warn(f"{tok.code_kind} outside a Pass ignored", tok)
                continue
            if tok.kind != "ident":
                raise self.s.error(f"unexpected {tok.describe()} in {owner}", tok)
            word = tok.lower
            if word == "properties":
                if owner != "Shader":
                    self.warn("Properties inside Category ignored", tok)
                    self.skip_rest_of_command(tok)
                else:
                    self.parse_properties(tok)
            elif word == "subshader":
                self.subshader_count += 1
                if self.subshader_count == 1:
                    self.parse_subshader(tok, state.merged_over(outer_state))
                else:
                    self.warn("only the first SubShader is imported; this one is ignored", tok)
                    self.skip_block(self.open_block(tok), "SubShader")
            elif word == "category":
                self.parse_container(self.open_block(tok), "Category", state.merged_over(outer_state), True,
                                     depth + 1)
            elif word == "fallback":
                arg = self.s.next()
                if arg.kind == "string":
                    self.fallback = arg.text
                elif arg.kind == "ident" and arg.lower == "off":
                    self.fallback = "Off"
                else:
                    raise self.s.error(f"expected a quoted shader name or Off after Fallback, found {arg.describe()}",
                                       arg)
            elif word in ("customeditor", "customeditorforrenderpipeline", "dependency"):
                self.skip_rest_of_command(tok)
            elif word in _STATE_COMMANDS and in_category:
                self.parse_state_command(tok, state)
            elif word in _STATE_COMMANDS:
                self.warn(f"{tok.text} outside SubShader/Category ignored", tok)
                self.skip_rest_of_command(tok)
            elif word == "tags" and in_category:
                self.parse_tags(tok, self.subshader_tags if self.subshader_count == 0 else {})
            else:
                self.warn(f"unknown command {tok.text!r} in {owner} ignored", tok)
                self.skip_rest_of_command(tok)

    # Properties ------------------------------------------------------------
    def parse_properties(self, head: Token) -> None:
        open_tok = self.open_block(head)
        while True:
            attributes: list[str] = []
            tok = self.s.next()
            while tok.kind == "punct" and tok.text == "[":
                attributes.append(self.s.raw_until_bracket_close(tok).strip())
                tok = self.s.next()
            if tok.kind == "eof":
                raise self.unclosed(open_tok, "Properties")
            if tok.kind == "punct" and tok.text == "}":
                if attributes:
                    raise self.s.error("attribute without a property", tok)
                return
            if tok.kind != "ident":
                raise self.s.error(f"expected a property name, found {tok.describe()}", tok)
            self.parse_property(tok, attributes)

    def parse_property(self, name_tok: Token, attributes: list[str]) -> None:
        self.expect("(", f"after property {name_tok.text}")
        display = self.expect_string(f"display name of {name_tok.text}").text
        self.expect(",", f"after the display name of {name_tok.text}")
        type_tok = self.s.next()
        if type_tok.kind not in ("ident", "number"):
            raise self.s.error(f"expected the type of {name_tok.text}, found {type_tok.describe()}", type_tok)
        # 2D/3D are scanned as a number followed by an identifier.
        ptype = type_tok.text
        if type_tok.kind == "number":
            nxt = self.s.next()
            if nxt.kind != "ident" or nxt.line != type_tok.line:
                raise self.s.error(f"bad property type for {name_tok.text}", type_tok)
            ptype = type_tok.text + nxt.text
        ptype_l = ptype.lower()
        range_args: tuple[float, float] | None = None
        if ptype_l == "range":
            self.expect("(", "after Range")
            lo, _ = self.expect_number("Range minimum")
            self.expect(",", "in Range(min, max)")
            hi, _ = self.expect_number("Range maximum")
            self.expect(")", "after Range(min, max")
            range_args = (lo, hi)
        self.expect(")", f"after the type of {name_tok.text}")
        self.expect("=", f"before the default value of {name_tok.text}")
        default: Any
        if ptype_l in ("color", "vector"):
            self.expect("(", f"before the {ptype} default of {name_tok.text}")
            values = []
            while True:
                v, _ = self.expect_number(f"a component of {name_tok.text}")
                values.append(v)
                tok = self.s.next()
                if tok.kind == "punct" and tok.text == ")":
                    break
                if not (tok.kind == "punct" and tok.text == ","):
                    raise self.s.error(f"expected ',' or ')' in the default of {name_tok.text}, "
                                       f"found {tok.describe()}", tok)
            if not 2 <= len(values) <= 4:
                raise self.s.error(f"{ptype} default of {name_tok.text} needs 2 to 4 components", name_tok)
            while len(values) < 4:
                values.append(1.0 if ptype_l == "color" and len(values) == 3 else 0.0)
            default = tuple(values)
        elif ptype_l in ("float", "int", "integer", "range"):
            default, _ = self.expect_number(f"the default of {name_tok.text}")
        elif ptype_l in ("2d", "3d", "cube", "2darray", "3darray", "cubearray", "any", "rect"):
            default = self.expect_string(f"texture default of {name_tok.text}").text
            if self.at_punct("{"):  # the optional (legacy) texture options block
                self.skip_block(self.s.next(), name_tok.text)
        else:
            raise self.s.error(f"unknown property type {ptype!r} for {name_tok.text}", type_tok)
        if range_args is not None and not (min(range_args) <= default <= max(range_args)):
            self.warn(f"default {default:g} of {name_tok.text} is outside its Range{range_args}", name_tok)
        self.properties[name_tok.text] = _Property(name_tok.text, display, ptype, default, attributes, name_tok)

    # SubShader / Pass --------------------------------------------------------
    def parse_tags(self, head: Token, into: dict[str, str], owner: str = "Tags") -> dict[str, Token]:
        open_tok = self.open_block(head)
        positions: dict[str, Token] = {}
        while True:
            tok = self.s.next()
            if tok.kind == "eof":
                raise self.unclosed(open_tok, owner)
            if tok.kind == "punct" and tok.text == "}":
                return positions
            if tok.kind != "string":
                raise self.s.error(f'expected a tag "Name"="Value" in {owner}, found {tok.describe()}', tok)
            self.expect("=", f'after tag "{tok.text}"')
            value = self.expect_string(f'value of tag "{tok.text}"')
            into[tok.text] = value.text
            positions[tok.text.lower()] = value

    def parse_subshader(self, head: Token, outer_state: dict[str, Any]) -> None:
        open_tok = self.open_block(head)
        state = _State()
        raw_passes: list[tuple[Token, _State, str | None, list[str], dict[str, str]]] = []
        while True:
            tok = self.s.next()
            if tok.kind == "eof":
                raise self.unclosed(open_tok, "SubShader")
            if tok.kind == "punct" and tok.text == "}":
                break
            if tok.kind == "code":
                if tok.code_kind.endswith("INCLUDE"):
                    self.includes.append(tok.text)
                else:
                    self.warn(f"{tok.code_kind} directly in the SubShader (a surface shader?): "
                              "the passes Unity generates from it are not imported", tok)
                continue
            if tok.kind != "ident":
                raise self.s.error(f"unexpected {tok.describe()} in SubShader", tok)
            word = tok.lower
            if word in ("subshader", "category"):
                raise self.s.error(f"{tok.text} inside a SubShader: is the '}}' closing the SubShader at "
                                   f"{head.line}:{head.column} missing?", tok)
            if word == "tags":
                positions = self.parse_tags(tok, self.subshader_tags)
                if "queue" in positions:
                    self.queue_token = positions["queue"]
                if "lightmode" in positions:
                    self.warn("LightMode is a Pass tag; in the SubShader's Tags it is ignored", positions["lightmode"])
            elif word == "pass":
                raw_passes.append(self.parse_pass(tok))
            elif word == "usepass":
                arg = self.expect_string("pass path after UsePass")
                self.use_passes.append(arg.text)
                self.warn(f'UsePass "{arg.text}" recorded, not imported (the other shader is not available)', tok)
            elif word == "grabpass":
                self.warn("GrabPass ignored", tok)
                self.skip_rest_of_command(tok)
            elif word in _STATE_COMMANDS:
                self.parse_state_command(tok, state)
            elif word in _QUIET_COMMANDS:
                self.skip_quiet(tok)
            else:
                self.warn(f"unknown command {tok.text!r} in SubShader ignored", tok)
                self.skip_rest_of_command(tok)
        sub_state = state.merged_over(outer_state)
        for pass_tok, pass_state, name, programs, tags in raw_passes:
            self.passes.append(_PassInfo(name, pass_state.merged_over(sub_state), programs, tags, pass_tok))

    def parse_pass(self, head: Token):
        open_tok = self.open_block(head)
        state = _State()
        name: str | None = None
        programs: list[str] = []
        tags: dict[str, str] = {}
        while True:
            tok = self.s.next()
            if tok.kind == "eof":
                raise self.unclosed(open_tok, "Pass")
            if tok.kind == "punct" and tok.text == "}":
                return head, state, name, programs, tags
            if tok.kind == "code":
                programs.append(tok.text)
                continue
            if tok.kind != "ident":
                raise self.s.error(f"unexpected {tok.describe()} in Pass", tok)
            word = tok.lower
            if word in ("pass", "subshader", "category"):
                raise self.s.error(f"{tok.text} inside a Pass: is the '}}' closing the Pass at "
                                   f"{head.line}:{head.column} missing?", tok)
            if word == "name":
                name = self.expect_string("pass name after Name").text
            elif word == "tags":
                positions = self.parse_tags(tok, tags)
                if "queue" in positions:
                    self.warn("Queue is a SubShader tag; in a Pass's Tags it is ignored", positions["queue"])
            elif word in _STATE_COMMANDS:
                self.parse_state_command(tok, state)
            elif word in _QUIET_COMMANDS:
                self.skip_quiet(tok)
            else:
                self.warn(f"unknown command {tok.text!r} in Pass ignored", tok)
                self.skip_rest_of_command(tok)

    # state commands -----------------------------------------------------------
    def value(self, what: str) -> tuple[Any, Token, bool]:
        """A command argument: (value, token, is_property_reference)."""
        tok = self.s.next()
        if tok.kind == "punct" and tok.text == "[":
            name_tok = self.s.next()
            if name_tok.kind != "ident":
                raise self.s.error(f"expected a property name in [ ] for {what}, found {name_tok.describe()}",
                                   name_tok)
            self.expect("]", f"after [{name_tok.text}")
            prop = self.properties.get(name_tok.text)
            if prop is None:
                raise self.s.error(f"{what} refers to [{name_tok.text}], which is not in Properties", name_tok)
            if not isinstance(prop.default, float):
                raise self.s.error(f"{what} refers to [{name_tok.text}], which is not a Float/Int/Range property",
                                   name_tok)
            return prop.default, name_tok, True
        if tok.kind in ("ident", "number"):
            return tok.text, tok, False
        raise self.s.error(f"expected a value for {what}, found {tok.describe()}", tok)

    def by_number(self, table: dict, number: float, tok: Token, what: str):
        if number != int(number) or int(number) not in table:
            raise self.s.error(f"{what} value {number:g} from the property is not supported", tok)
        return table[int(number)]

    def word_value(self, cls, what: str, table: dict, words: dict | None = None):
        raw, tok, is_ref = self.value(what)
        if is_ref:
            return self.by_number(table, raw, tok, what), tok
        words = words or _enum_words(cls)
        member = words.get(str(raw).lower())
        if member is None:
            choices = ", ".join(dict.fromkeys(m.value for m in words.values()))
            raise self.s.error(f"unknown {what} {raw!r} (expected one of: {choices})", tok)
        return member, tok

    def parse_state_command(self, head: Token, state: _State) -> None:
        word = head.lower
        v = state.values
        if word == "cull":
            v["cull"], _ = self.word_value(Cull, "Cull mode", _CULL_BY_NUMBER)
        elif word == "zwrite":
            raw, tok, is_ref = self.value("ZWrite")
            if is_ref:
                v["zwrite"] = raw != 0
            elif str(raw).lower() in ("on", "off"):
                v["zwrite"] = str(raw).lower() == "on"
            else:
                raise self.s.error(f"unknown ZWrite value {raw!r} (expected On or Off)", tok)
        elif word == "ztest":
            ztest, tok = self.word_value(CompareFunction, "ZTest function", _COMPARE_BY_NUMBER, _ZTEST_WORDS)
            if ztest is CompareFunction.Never:
                raise self.s.error("ZTest Never is not supported (nothing would be drawn)", tok)
            v["ztest"] = ztest
        elif word == "blend":
            self.parse_blend(head, v)
        elif word == "blendop":
            ops = [self.word_value(BlendOp, "BlendOp", _BLENDOP_BY_NUMBER)[0]]
            if self.at_punct(","):
                self.s.next()
                ops.append(self.word_value(BlendOp, "BlendOp", _BLENDOP_BY_NUMBER)[0])
            v["blend_ops"] = tuple(ops)
        elif word == "colormask":
            raw, tok, is_ref = self.value("ColorMask")
            if is_ref:
                if raw != int(raw) or not 0 <= raw <= 15:
                    raise self.s.error(f"ColorMask value {raw:g} from the property is not 0..15", tok)
                v["color_mask"] = color_mask_from_bits(int(raw))  # Unity's ColorWriteMask numbering
            else:
                try:
                    v["color_mask"] = parse_color_mask(str(raw))
                except ValueError as exc:
                    raise self.s.error(str(exc), tok) from None
            nxt = self.s.peek()
            if nxt.kind == "number" and nxt.line == tok.line:  # render-target index
                self.s.next()
                if float(nxt.text) != 0:
                    self.warn(f"ColorMask for render target {nxt.text} applied to the only colour buffer", nxt)
        elif word == "offset":
            factor, _ = self.number_value("Offset factor")
            self.expect(",", "between the Offset factor and units")
            units, _ = self.number_value("Offset units")
            v["offset"] = (factor, units)
        elif word == "alphatomask":
            raw, tok, is_ref = self.value("AlphaToMask")
            on = (raw != 0) if is_ref else str(raw).lower() == "on"
            if not is_ref and str(raw).lower() not in ("on", "off"):
                raise self.s.error(f"unknown AlphaToMask value {raw!r} (expected On or Off)", tok)
            if on:
                self.warn("AlphaToMask On is not supported (no MSAA); the pass is imported without it", head)
        elif word == "stencil":
            v["stencil"] = self.parse_stencil(head)

    def number_value(self, what: str) -> tuple[float, Token]:
        raw, tok, is_ref = self.value(what)
        if is_ref:
            return float(raw), tok
        if tok.kind != "number":
            raise self.s.error(f"expected a number for {what}, found {tok.describe()}", tok)
        return float(raw), tok

    def parse_blend(self, head: Token, v: dict[str, Any]) -> None:
        first = self.s.peek()
        if first.kind == "ident" and first.lower == "off":
            self.s.next()
            v["blend"] = None
            return
        if first.kind == "number" and first.line == head.line:
            nxt_text = first.text
            self.s.next()
            if float(nxt_text) != 0:
                self.warn(f"Blend for render target {nxt_text} applied to the only colour buffer", first)
            if self.s.peek().kind == "ident" and self.s.peek().lower == "off":
                self.s.next()
                v["blend"] = None
                return
        src, _ = self.word_value(BlendFactor, "blend factor", _FACTOR_BY_NUMBER)
        dst, _ = self.word_value(BlendFactor, "blend factor", _FACTOR_BY_NUMBER)
        if self.at_punct(","):
            self.s.next()
            src_a, _ = self.word_value(BlendFactor, "blend factor", _FACTOR_BY_NUMBER)
            dst_a, _ = self.word_value(BlendFactor, "blend factor", _FACTOR_BY_NUMBER)
            v["blend"] = (src, dst, src_a, dst_a)
        else:
            v["blend"] = (src, dst)

    def parse_stencil(self, head: Token) -> dict[str, Any]:
        open_tok = self.open_block(head)
        st: dict[str, Any] = {}
        while True:
            tok = self.s.next()
            if tok.kind == "eof":
                raise self.unclosed(open_tok, "Stencil")
            if tok.kind == "punct" and tok.text == "}":
                return st
            if tok.kind != "ident":
                raise self.s.error(f"unexpected {tok.describe()} in Stencil", tok)
            word = tok.lower
            if word in ("ref", "readmask", "writemask"):
                number, ntok = self.number_value(f"Stencil {tok.text}")
                if number != int(number) or not 0 <= number <= 255:
                    raise self.s.error(f"Stencil {tok.text} must be an integer 0..255, got {number:g}", ntok)
                st[{"ref": "stencil_ref", "readmask": "stencil_read_mask",
                    "writemask": "stencil_write_mask"}[word]] = int(number)
            elif word == "comp":
                st["stencil_comp"], _ = self.word_value(CompareFunction, "Stencil Comp", _COMPARE_BY_NUMBER,
                                                        _STENCIL_COMP_WORDS)
            elif word in ("pass", "fail", "zfail"):
                st["stencil_" + word], _ = self.word_value(StencilOp, f"Stencil {tok.text} operation",
                                                           _STENCILOP_BY_NUMBER)
            elif word in _STENCIL_FACE_COMMANDS:
                self.warn(f"Stencil {tok.text} (per-face stencil) is not supported and ignored", tok)
                self.value(f"Stencil {tok.text}")
            else:
                raise self.s.error(f"unknown Stencil command {tok.text!r}", tok)


_STATE_COMMANDS = frozenset(
    ["cull", "zwrite", "ztest", "blend", "blendop", "colormask", "offset", "alphatomask", "stencil"]
)
# Known commands that do not change what this renderer draws: skipped without a warning.
_QUIET_COMMANDS = frozenset(["lod", "lighting", "zclip", "conservative", "packagerequirements"])
_STENCIL_FACE_COMMANDS = frozenset(
    ["compfront", "passfront", "failfront", "zfailfront", "compback", "passback", "failback", "zfailback"]
)


@functools.cache
def _enum_words(cls) -> dict[str, Any]:
    """Lower-case value → member of a vocabulary enum (built once per enum: parsing is per token)."""
    return {m.value.lower(): m for m in cls}


# --------------------------------------------------------------------------- program inspection

_CG_COMMENT_RE = re.compile(r"//[^\n]*|/\*.*?\*/", re.DOTALL)
_CLIP_RE = re.compile(r"\bclip\s*\(")
_CLIP_PROP_RE = re.compile(r"\bclip\s*\(([^;]*?)-\s*(_[A-Za-z0-9_]+)\s*\)\s*;")
# One literal component: a CG float literal (optional f/h suffix). Expressions such as 1-0.5 do not match.
_CG_LITERAL = r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)[fFhH]?"
_RETURN_CONST_RE = re.compile(
    r"\breturn\s+(?:float|half|fixed)4\s*\(\s*" + r"\s*,\s*".join([_CG_LITERAL] * 4) + r"\s*\)\s*;"
)


def _strip_cg_comments(text: str) -> str:
    return _CG_COMMENT_RE.sub(" ", text)


# --------------------------------------------------------------------------- building the result


def parse_shaderlab(text: str, filename: str = "<string>") -> ShaderLabResult:
    """Parse ShaderLab source; raise :class:`ShaderLabError` on malformed input."""
    parser = _Parser(text, filename)
    name, head = parser.parse()
    warnings = parser.warnings
    props = parser.properties
    material: dict[str, Any] = {}  # Material fields the file states; the others keep their defaults

    # Queue.
    tags = parser.subshader_tags
    queue_value = next((v for k, v in tags.items() if k.lower() == "queue"), None)
    if queue_value is not None:
        try:
            material["queue"], material["queue_offset"] = parse_queue(queue_value)
        except ValueError as exc:
            raise parser.s.error(str(exc), parser.queue_token or head) from None

    # Property defaults.
    color_prop = next((p for p in props.values() if any(a.lower() == "maincolor" for a in p.attributes)),
                      props.get("_Color"))
    if color_prop is not None:
        if not isinstance(color_prop.default, tuple):
            raise parser.s.error(f"{color_prop.name} must be a Color property", color_prop.token)
        material["color"] = tuple(float(c) for c in color_prop.default)
    tex_prop = next((p for p in props.values() if any(a.lower() == "maintexture" for a in p.attributes)),
                    props.get("_MainTex"))
    main_tex_default = None
    if tex_prop is not None:
        main_tex_default = str(tex_prop.default)
        if main_tex_default.lower() != "white":
            parser.warn(f'{tex_prop.name} default "{main_tex_default}" imported as no texture (white); '
                        "assign an image to match it", tex_prop.token)
    for prop_name, key in (("_AlphaScale", "alpha_scale"), ("_Cutoff", "cutoff")):
        prop = props.get(prop_name)
        if prop is not None:
            if not isinstance(prop.default, float):
                raise parser.s.error(f"{prop_name} must be a Float or Range property", prop.token)
            material[key] = prop.default

    # Programs.
    includes = "\n".join(_strip_cg_comments(t) for t in parser.includes)
    programs = [[_strip_cg_comments(t) for t in info.programs] for info in parser.passes]
    all_code = includes + "\n" + "\n".join(t for progs in programs for t in progs)
    material["lighting"] = Lighting.Lambert if "_LightColor0" in all_code else Lighting.Unlit

    cutoff_property = "_Cutoff" if "_Cutoff" in props else None
    clip_props = {m.group(2) for m in _CLIP_PROP_RE.finditer(all_code)}
    if clip_props and "_Cutoff" not in clip_props:
        used = sorted(clip_props)
        prop = props.get(used[0])
        if prop is not None and isinstance(prop.default, float):
            material["cutoff"] = prop.default
            cutoff_property = prop.name
            warnings.append(f"{prop.token.line}:{prop.token.column}: clip() compares with {prop.name}; "
                            f"imported as the cutoff ({prop.default:g})")

    # An unlit program without _Color/_MainTex that returns one constant colour: that colour is _Color.
    constant_color = None
    if (material["lighting"] is Lighting.Unlit and color_prop is None and tex_prop is None
            and "_Color" not in all_code and "tex2D" not in all_code):
        constants = {tuple(float(x) for x in m.groups()) for m in _RETURN_CONST_RE.finditer(all_code)}
        constants = {c for c in constants if all(math.isfinite(x) for x in c)}
        if len(constants) == 1:
            constant_color = constants.pop()
            material["color"] = constant_color
            warnings.append(f"{head.line}:{head.column}: the fragment program returns the constant colour "
                            f"{constant_color}; imported as _Color")
        elif len(constants) > 1:
            warnings.append(f"{head.line}:{head.column}: the passes return different constant colours "
                            f"{sorted(constants)}; one _Color cannot hold them, _Color stays white")

    passes: list[Pass] = []
    light_modes: list[str | None] = []
    pass_tags: list[dict[str, str]] = []
    for index, (info, progs) in enumerate(zip(parser.passes, programs, strict=True)):
        name_ = info.name
        if name_ is None:
            name_ = "Pass" if len(parser.passes) == 1 else f"Pass {index + 1}"
        code = "\n".join(progs)
        # clip( in the pass's program, or in CGINCLUDE code that a pass with a program shares.
        alpha_test = bool(_CLIP_RE.search(code)) or (bool(progs) and bool(_CLIP_RE.search(includes)))
        if re.search(r"\bdiscard\b", code):
            warnings.append(f"{info.token.line}:{info.token.column}: pass {name_!r} discards fragments with "
                            "its own condition; only clip(alpha - cutoff) is imported")
        passes.append(_build_pass(name_, info.state, alpha_test))
        light_modes.append(next((v for k, v in info.tags.items() if k.lower() == "lightmode"), None))
        pass_tags.append(dict(info.tags))
    for lm, info in zip(light_modes, parser.passes, strict=True):
        if lm is not None and lm.lower() not in ("forwardbase", "always"):
            warnings.append(f"{info.token.line}:{info.token.column}: LightMode {lm!r} is imported as ForwardBase")
    if parser.subshader_count == 0:
        warnings.append(f"{head.line}:{head.column}: no SubShader; the material gets one default pass")

    extra = {
        "render_type": next((v for k, v in tags.items() if k.lower() == "rendertype"), None),
        "ignore_projector": _bool_tag(next((v for k, v in tags.items() if k.lower() == "ignoreprojector"), None)),
        "light_modes": light_modes,
        "use_pass": list(parser.use_passes),
        "fallback": parser.fallback,
        "subshader_tags": dict(tags),
        "pass_tags": pass_tags,
        "subshader_count": parser.subshader_count,
        "main_tex_default": main_tex_default,
        "cutoff_property": cutoff_property,
        "properties": [
            {"name": p.name, "display": p.display, "type": p.type,
             "default": list(p.default) if isinstance(p.default, tuple) else p.default,
             "attributes": list(p.attributes)}
            for p in props.values()
        ],
    }
    return ShaderLabResult(Material(name=name, **material, passes=tuple(passes)), tuple(warnings), extra)


def _bool_tag(value: str | None) -> bool | None:
    if value is None:
        return None
    return value.strip().lower() == "true"


def _build_pass(name: str, state: dict[str, Any], alpha_test: bool) -> Pass:
    kwargs: dict[str, Any] = {"name": name, "alpha_test": alpha_test}
    for key in ("cull", "zwrite", "ztest", "color_mask"):
        if key in state:
            kwargs[key] = state[key]
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
    return Pass(**kwargs)


def parse_shaderlab_file(path: str) -> ShaderLabResult:
    """Read and parse a ``.shader`` file (UTF-8, BOM allowed); OSError/ShaderLabError on failure."""
    with open(path, encoding="utf-8-sig") as fh:
        text = fh.read()
    return parse_shaderlab(text, filename=str(path))


def canonical_pass(p: Pass) -> Pass:
    """The pass as a ``.shader`` file can state it: inactive blend/stencil fields at their defaults,
    offsets as the export writes them.

    ``Blend Off`` carries no factors, a non-separate alpha state no alpha factors and
    a pass without ``Stencil`` no stencil values; offsets are written as the shortest
    text of their float32 (what Blender stores, :func:`float32_text`). So export then
    import gives back ``canonical_pass(p)``; for passes edited in the UI this is ``p``
    itself at float32 precision unless fields hidden by a switched-off option were changed.
    """
    d = Pass()
    p = replace(p, offset_factor=float(float32_text(p.offset_factor)),
                offset_units=float(float32_text(p.offset_units)))
    if not p.blend:
        p = replace(p, src_blend=d.src_blend, dst_blend=d.dst_blend, blend_op=d.blend_op, separate_alpha=False)
    if not p.separate_alpha:
        p = replace(p, src_blend_alpha=d.src_blend_alpha, dst_blend_alpha=d.dst_blend_alpha,
                    blend_op_alpha=d.blend_op_alpha)
    if not p.stencil:
        p = replace(p, **{f.name: getattr(d, f.name) for f in fields(Pass) if f.name.startswith("stencil_")})
    return p


# --------------------------------------------------------------------------- export


def _num(x: float) -> str:
    """A float as positional decimal text that reads back to the same double (no exponent)."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write the non-finite number {x!r} into a shader")
    if x == int(x) and abs(x) < 1e15:
        return str(int(x))
    text = format(Decimal(repr(x)), "f")
    return text


def _shader_string(text: str) -> str:
    """Text for a ShaderLab string literal (no escapes exist: quotes and line breaks are replaced)."""
    return " ".join(str(text).replace('"', "'").split())


_RENDER_TYPE = {
    Queue.Background: "Opaque", Queue.Geometry: "Opaque", Queue.AlphaTest: "TransparentCutout",
    Queue.Transparent: "Transparent", Queue.Overlay: "Transparent",
}


_CG_HEAD = """\
CGPROGRAM
#pragma vertex vert
#pragma fragment frag

#include "UnityCG.cginc"
#include "Lighting.cginc"

float4 _Color;
sampler2D _MainTex;
float4 _MainTex_ST;
float _Cutoff;
float _AlphaScale;

struct a2v
{
    float4 vertex : POSITION;
    float3 normal : NORMAL;
    float4 texcoord : TEXCOORD0;
};

struct v2f
{
    float4 pos : SV_POSITION;
    float3 worldNormal : TEXCOORD0;
    float3 worldPos : TEXCOORD1;
    float2 uv : TEXCOORD2;
};

v2f vert(a2v v)
{
    v2f o;
    o.pos = UnityObjectToClipPos(v.vertex);
    o.worldNormal = UnityObjectToWorldNormal(v.normal);
    o.worldPos = mul(unity_ObjectToWorld, v.vertex).xyz;
    o.uv = TRANSFORM_TEX(v.texcoord, _MainTex);
    return o;
}

float4 frag(v2f i) : SV_Target
{
    float4 texColor = tex2D(_MainTex, i.uv);
"""

_CG_ALPHA_TEST = """\
    // Alpha test: discard the fragment when alpha - _Cutoff < 0
    clip(texColor.a * _Color.a * _AlphaScale - _Cutoff);
"""

_CG_LAMBERT = """\
    float3 worldNormal = normalize(i.worldNormal);
    float3 worldLightDir = normalize(UnityWorldSpaceLightDir(i.worldPos));
    float3 albedo = texColor.rgb * _Color.rgb;
    float3 ambient = UNITY_LIGHTMODEL_AMBIENT.xyz * albedo;
    // Lambert diffuse from the main directional light
    float3 diffuse = _LightColor0.rgb * albedo * max(0, dot(worldNormal, worldLightDir));
    return float4(ambient + diffuse, texColor.a * _Color.a * _AlphaScale);
}
ENDCG"""

_CG_UNLIT = """\
    // Unlit: albedo only
    float3 albedo = texColor.rgb * _Color.rgb;
    return float4(albedo, texColor.a * _Color.a * _AlphaScale);
}
ENDCG"""


def export_shaderlab(material: Material, shader_name: str | None = None) -> str:
    """A complete ShaderLab shader (built-in pipeline, CG) with the material's queue, passes and shading.

    ``Properties`` hold ``_Color``, ``_MainTex``, ``_Cutoff`` and ``_AlphaScale`` with the
    material's values as defaults; each pass states Cull/ZWrite/ZTest/Blend (and
    BlendOp, ColorMask, Offset, Stencil where they differ from the defaults) and runs
    the book's ForwardBase vertex/fragment program: Lambert (``_LightColor0``) or
    Unlit, with ``clip(texColor.a * _Color.a * _AlphaScale - _Cutoff)`` in alpha-test
    passes.
    """
    name = _shader_string(shader_name if shader_name is not None else f"Unity Passes/{material.name}")
    c = material.color
    q = material.queue
    tags = [f'"Queue"="{queue_text(q, int(material.queue_offset))}"']
    if q in (Queue.Background, Queue.Geometry):
        tags.append('"RenderType"="Opaque"')
    else:
        tags += ['"IgnoreProjector"="True"', f'"RenderType"="{_RENDER_TYPE[q]}"']
    out = [
        f'Shader "{name}"',
        "{",
        "    Properties",
        "    {",
        f'        _Color ("Main Tint", Color) = ({_num(c[0])}, {_num(c[1])}, {_num(c[2])}, {_num(c[3])})',
        '        _MainTex ("Main Tex", 2D) = "white" {}',
        f'        _Cutoff ("Alpha Cutoff", Range(0, 1)) = {_num(material.cutoff)}',
        f'        _AlphaScale ("Alpha Scale", Range(0, 1)) = {_num(material.alpha_scale)}',
        "    }",
        "",
        "    SubShader",
        "    {",
        f"        Tags {{ {' '.join(tags)} }}",
    ]
    body = _CG_LAMBERT if material.lighting == Lighting.Lambert else _CG_UNLIT
    for p in material.draw_passes:
        out += [
            "",
            "        Pass",
            "        {",
            f'            Name "{_shader_string(p.name)}"',
            '            Tags { "LightMode"="ForwardBase" }',
            "",
        ]
        out += ["            " + line for line in pass_state_commands(p)]
        out.append("")
        program = _CG_HEAD + (_CG_ALPHA_TEST if p.alpha_test else "") + body
        out += [("            " + line) if line else "" for line in program.splitlines()]
        out.append("        }")
    fallback = {Queue.AlphaTest: "Transparent/Cutout/VertexLit", Queue.Transparent: "Transparent/VertexLit",
                Queue.Overlay: "Transparent/VertexLit"}.get(q)
    out += ["    }", ""]
    out.append(f'    Fallback "{fallback}"' if fallback else "    Fallback Off")
    out += ["}", ""]
    return "\n".join(out)
