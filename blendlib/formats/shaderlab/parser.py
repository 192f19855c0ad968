"""The ShaderLab parser: text → the syntax tree of :mod:`.tree`, with the warnings of what it skipped.

It knows ShaderLab's grammar — which blocks may hold which commands, how many arguments each
command takes (``Blend`` two or four factors after an optional render target, ``Stencil`` a block
of its own commands, ...) — but not what the arguments mean: a value is any word, number or
``[_Prop]`` reference, checked later by :mod:`.state`. A reference is bound to the property of
that name declared before it, the way a compiler binds a name to its declaration.

Read: ``Shader "name" { … }``; ``Properties`` (with attributes such as ``[Enum(…)]``); ``Category``
blocks, nested up to :data:`MAX_NESTING` deep; the first ``SubShader`` (later ones are counted and
skipped); ``Tags``, ``Pass``, ``Name``, ``UsePass``, ``GrabPass`` and ``Fallback``; the state
commands of :data:`STATE_COMMANDS` and the fixed-function ones of :data:`FIXED_FUNCTION_COMMANDS`
(``SetTexture`` in a Pass) at Category, SubShader and Pass level; program blocks (``CGPROGRAM``
… ``ENDCG``) as text, in a Pass or — a surface shader — in the SubShader.

Commands that do not change what this renderer draws (:data:`IGNORED_COMMANDS`: ``Fog { }``,
``BindChannels { }``, ``LOD``, ``ZClip``, ``Conservative``, ``Name`` outside a Pass) are consumed
exactly — their arguments and blocks, nothing after them, so ``Cull Off Fog { Mode Off } ZWrite
Off`` still sets ZWrite — and listed as warnings. An unknown command is skipped with a warning up
to the next known command on its line (or through a ``{ … }`` block opening on it).
``PackageRequirements { }``, ``CustomEditor`` and ``Dependency`` are skipped silently.

Malformed text raises :class:`~.diagnostics.ShaderLabError` at the first problem; the tree read up
to it stays in :attr:`Parser.shader` (see :mod:`.tree`).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from .diagnostics import ShaderLabError, SourceWarning
from .lexer import Scanner, Token
from .tree import (
    CategoryBlock,
    Command,
    GrabPass,
    PassBlock,
    ProgramBlock,
    Property,
    SetTexture,
    ShaderBlock,
    SubShaderBlock,
    TagsBlock,
    UsePass,
    Value,
)

#: ``Category`` blocks nest at most this deep (deeper input is an error, not a RecursionError).
MAX_NESTING = 64

#: The commands that set render state (read by :mod:`.state`).
STATE_COMMANDS = frozenset(
    ["cull", "zwrite", "ztest", "blend", "blendop", "colormask", "offset", "alphatomask", "stencil"]
)
#: The fixed-function commands (legacy passes without a program, :mod:`.fixed_function`); like the
#: state commands they may stand at Category, SubShader or Pass level. ``SetTexture`` is a Pass's.
FIXED_FUNCTION_COMMANDS = frozenset(["lighting", "material", "color", "colormaterial", "separatespecular",
                                     "alphatest"])
#: Commands that do not change what this renderer draws, by what follows them: consumed exactly, warned.
IGNORED_COMMANDS = {"fog": "block", "bindchannels": "block", "lod": "value", "zclip": "value",
                    "conservative": "value", "name": "string"}
#: Why each ignored command changes nothing here (the warning's reason).
_IGNORED_WHY = {
    "fog": "fog is not drawn", "bindchannels": "vertex data is bound by name here",
    "lod": "the first SubShader is used, as under Unity's default unlimited maximum LOD",
    "zclip": "depth is clamped to the far plane here", "conservative": "conservative rasterization is not drawn",
    "name": "only a Pass has a name",
}
#: Per-face stencil commands inside ``Stencil { }`` (not supported: :mod:`.state` warns).
STENCIL_FACE_COMMANDS = frozenset(
    ["compfront", "passfront", "failfront", "zfailfront", "compback", "passback", "failback", "zfailback"]
)
#: The commands inside ``Material { }`` (their values: a colour, Shininess a number).
MATERIAL_BLOCK_COMMANDS = frozenset(["diffuse", "ambient", "specular", "shininess", "emission"])
#: Every word that starts a command, for skipping an unknown one up to the next command on its line.
COMMAND_WORDS = STATE_COMMANDS | FIXED_FUNCTION_COMMANDS | frozenset(IGNORED_COMMANDS) | frozenset(
    ["settexture", "tags", "pass", "usepass", "grabpass", "packagerequirements"])

#: What may stand in a Category (and, with SetTexture, in a Pass).
COMMANDS_ANYWHERE = STATE_COMMANDS | FIXED_FUNCTION_COMMANDS | frozenset(IGNORED_COMMANDS) | frozenset(
    ["packagerequirements"])

# What each one-value command's argument is, for messages.
_VALUE_WHAT = {"cull": "Cull mode", "zwrite": "ZWrite", "ztest": "ZTest function", "alphatomask": "AlphaToMask",
               "lighting": "Lighting", "separatespecular": "SeparateSpecular", "colormaterial": "ColorMaterial"}


class Parser:
    """One use: ``Parser(text, filename).parse()`` returns the :class:`~.tree.ShaderBlock`."""

    def __init__(self, text: str, filename: str) -> None:
        self.s = Scanner(text, filename)
        self.warnings: list[SourceWarning] = []
        #: The tree, from the moment the shader's name is read (complete up to an error).
        self.shader: ShaderBlock | None = None

    # helpers ---------------------------------------------------------------
    def warn(self, message: str, at: Token) -> None:
        self.warnings.append(SourceWarning.at(at, message))

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

    def expect_number(self, what: str) -> float:
        tok = self.s.next()
        if tok.kind != "number":
            raise self.s.error(f"expected a number for {what}, found {tok.describe()}", tok)
        return float(tok.text)

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

    def block_tokens(self, open_tok: Token, owner: str) -> Iterator[Token]:
        """The tokens of the block ``open_tok`` opens, one at a time, up to its closing ``}``
        (consumed, not given); the loop's body may read further tokens itself."""
        while True:
            tok = self.s.next()
            if tok.kind == "eof":
                raise self.unclosed(open_tok, owner)
            if tok.kind == "punct" and tok.text == "}":
                return
            yield tok

    def skip_command(self, head: Token, warning: str | None) -> None:
        """Skip a command not read: the rest of its line up to the next known command on it, or
        up to the end of a ``{ ... }`` block opening on that line (stops before a ``}`` that
        closes the enclosing block)."""
        if warning is not None:
            self.warn(warning, head)
        self.s.skip_line_until(COMMAND_WORDS)

    # top level -------------------------------------------------------------
    def parse(self) -> ShaderBlock:
        head = self.s.next()
        if head.kind != "ident" or head.lower != "shader":
            raise self.s.error(f"expected 'Shader \"name\" {{' at the start, found {head.describe()}", head)
        name = self.expect_string("shader name").text
        self.shader = ShaderBlock(head, name=name, filename=self.s.filename)
        open_tok = self.open_block(head)
        self.parse_container(self.shader, open_tok, "Shader")
        tail = self.s.next()
        if tail.kind != "eof":
            raise self.s.error(f"unexpected {tail.describe()} after the end of the shader", tail)
        return self.shader

    def parse_container(self, block: CategoryBlock, open_tok: Token, owner: str, depth: int = 0) -> None:
        """The body of ``Shader`` or ``Category`` (``depth``: how many Category blocks enclose it)."""
        if depth > MAX_NESTING:
            raise self.s.error(f"Category blocks nested more than {MAX_NESTING} deep", open_tok)
        shader = self.shader
        in_category = owner == "Category"
        for tok in self.block_tokens(open_tok, owner):
            if tok.kind == "code":
                if tok.code_kind.endswith("INCLUDE"):
                    shader.includes.append(tok.text)
                else:
                    self.warn(f"{tok.code_kind} outside a Pass ignored", tok)
                continue
            if tok.kind != "ident":
                raise self.s.error(f"unexpected {tok.describe()} in {owner}", tok)
            word = tok.lower
            if word == "properties":
                if owner != "Shader":
                    self.skip_command(tok, "Properties inside Category ignored")
                else:
                    self.parse_properties(tok)
            elif word == "subshader":
                shader.subshader_count += 1
                if shader.subshader_count == 1:
                    subshader = SubShaderBlock(tok)
                    block.body.append(subshader)
                    self.parse_subshader(subshader)
                else:
                    self.warn("only the first SubShader is imported; this one is ignored", tok)
                    self.s.skip_raw_block(self.open_block(tok), "SubShader")
            elif word == "category":
                category = CategoryBlock(tok)
                block.body.append(category)
                self.parse_container(category, self.open_block(tok), "Category", depth + 1)
            elif word == "fallback":
                arg = self.s.next()
                if arg.kind == "string":
                    shader.fallback = arg.text
                elif arg.kind == "ident" and arg.lower == "off":
                    shader.fallback = "Off"
                else:
                    raise self.s.error(f"expected a quoted shader name or Off after Fallback, found {arg.describe()}",
                                       arg)
            elif word in ("customeditor", "customeditorforrenderpipeline", "dependency"):
                self.skip_command(tok, None)
            elif word in COMMANDS_ANYWHERE and in_category:
                self.parse_any_command(tok, block.body, owner)
            elif word in STATE_COMMANDS or word in FIXED_FUNCTION_COMMANDS:
                self.skip_command(tok, f"{tok.text} outside SubShader/Category ignored")
            elif word == "tags" and in_category:
                tags = TagsBlock(tok)
                block.body.append(tags)
                self.parse_tags(tok, tags.tags)
            else:
                self.skip_command(tok, f"unknown command {tok.text!r} in {owner} ignored")

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
            lo = self.expect_number("Range minimum")
            self.expect(",", "in Range(min, max)")
            hi = self.expect_number("Range maximum")
            self.expect(")", "after Range(min, max")
            range_args = (lo, hi)
        self.expect(")", f"after the type of {name_tok.text}")
        self.expect("=", f"before the default value of {name_tok.text}")
        default: Any
        if ptype_l in ("color", "vector"):
            self.expect("(", f"before the {ptype} default of {name_tok.text}")
            values = []
            while True:
                values.append(self.expect_number(f"a component of {name_tok.text}"))
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
            default = self.expect_number(f"the default of {name_tok.text}")
        elif ptype_l in ("2d", "3d", "cube", "2darray", "3darray", "cubearray", "any", "rect"):
            default = self.expect_string(f"texture default of {name_tok.text}").text
            if self.at_punct("{"):  # the optional (legacy) texture options block
                self.s.skip_raw_block(self.s.next(), name_tok.text)
        else:
            raise self.s.error(f"unknown property type {ptype!r} for {name_tok.text}", type_tok)
        if range_args is not None and not (min(range_args) <= default <= max(range_args)):
            self.warn(f"default {default:g} of {name_tok.text} is outside its Range{range_args}", name_tok)
        self.shader.properties[name_tok.text] = Property(name_tok.text, display, ptype, default, attributes, name_tok)

    # SubShader / Pass --------------------------------------------------------
    def parse_tags(self, head: Token, into: dict[str, str], owner: str = "Tags") -> dict[str, Token]:
        """Read ``{ "Name"="Value" … }`` into ``into``; returns the value tokens by lower-case name."""
        open_tok = self.open_block(head)
        positions: dict[str, Token] = {}
        for tok in self.block_tokens(open_tok, owner):
            if tok.kind != "string":
                raise self.s.error(f'expected a tag "Name"="Value" in {owner}, found {tok.describe()}', tok)
            self.expect("=", f'after tag "{tok.text}"')
            value = self.expect_string(f'value of tag "{tok.text}"')
            into[tok.text] = value.text
            positions[tok.text.lower()] = value
        return positions

    def parse_subshader(self, subshader: SubShaderBlock) -> None:
        head = subshader.head
        open_tok = self.open_block(head)
        for tok in self.block_tokens(open_tok, "SubShader"):
            if tok.kind == "code":
                if tok.code_kind.endswith("INCLUDE"):
                    self.shader.includes.append(tok.text)
                else:
                    subshader.body.append(ProgramBlock(tok, tok.text))
                continue
            if tok.kind != "ident":
                raise self.s.error(f"unexpected {tok.describe()} in SubShader", tok)
            word = tok.lower
            if word in ("subshader", "category"):
                raise self.s.error(f"{tok.text} inside a SubShader: is the '}}' closing the SubShader at "
                                   f"{head.line}:{head.column} missing?", tok)
            if word == "tags":
                positions = self.parse_tags(tok, subshader.tags)
                if "queue" in positions:
                    subshader.queue_token = positions["queue"]
                if "lightmode" in positions:
                    self.warn("LightMode is a Pass tag; in the SubShader's Tags it is ignored", positions["lightmode"])
            elif word == "pass":
                pass_block = PassBlock(tok)
                subshader.body.append(pass_block)
                self.parse_pass(pass_block)
            elif word == "usepass":
                arg = self.expect_string("pass path after UsePass")
                subshader.body.append(UsePass(tok, arg.text))
            elif word == "grabpass":
                subshader.body.append(GrabPass(tok))
                self.s.skip_raw_block(self.open_block(tok), "GrabPass")
            else:
                self.parse_any_command(tok, subshader.body, "SubShader")

    def parse_pass(self, pass_block: PassBlock) -> None:
        head = pass_block.head
        open_tok = self.open_block(head)
        for tok in self.block_tokens(open_tok, "Pass"):
            if tok.kind == "code":
                pass_block.programs.append(tok.text)
                continue
            if tok.kind != "ident":
                raise self.s.error(f"unexpected {tok.describe()} in Pass", tok)
            word = tok.lower
            if word in ("pass", "subshader", "category"):
                raise self.s.error(f"{tok.text} inside a Pass: is the '}}' closing the Pass at "
                                   f"{head.line}:{head.column} missing?", tok)
            if word == "name":
                pass_block.name = self.expect_string("pass name after Name").text
            elif word == "tags":
                positions = self.parse_tags(tok, pass_block.tags)
                if "queue" in positions:
                    self.warn("Queue is a SubShader tag; in a Pass's Tags it is ignored", positions["queue"])
            elif word == "settexture":
                texture = self.value("SetTexture texture")
                open_block = self.open_block(tok)
                pass_block.stages.append(SetTexture(tok, texture, self.s.raw_block(open_block, "SetTexture"),
                                                    open_block))
            else:
                self.parse_any_command(tok, pass_block.commands, "Pass")

    # commands -----------------------------------------------------------------
    def value(self, what: str) -> Value:
        """A command argument: a word, a number or a ``[_Prop]`` reference."""
        tok = self.s.next()
        if tok.kind == "punct" and tok.text == "[":
            name_tok = self.s.next()
            if name_tok.kind != "ident":
                raise self.s.error(f"expected a property name in [ ] for {what}, found {name_tok.describe()}",
                                   name_tok)
            self.expect("]", f"after [{name_tok.text}")
            return Value(name_tok, what, reference=True, declared=self.shader.properties.get(name_tok.text))
        if tok.kind in ("ident", "number"):
            return Value(tok, what)
        raise self.s.error(f"expected a value for {what}, found {tok.describe()}", tok)

    def parse_any_command(self, head: Token, into: list, owner: str) -> None:
        """A command in a Category, SubShader or Pass: a state or fixed-function command joins
        ``into``, an ignored one is consumed with a warning, another is skipped."""
        word = head.lower
        if word in STATE_COMMANDS or word in FIXED_FUNCTION_COMMANDS:
            self.parse_command(head, into)
        elif word in IGNORED_COMMANDS:
            self.parse_ignored(head)
        elif word == "packagerequirements":
            self.s.skip_raw_block(self.open_block(head), head.text)
        else:
            self.skip_command(head, f"unknown command {head.text!r} in {owner} ignored")

    def parse_ignored(self, head: Token) -> None:
        """A command of :data:`IGNORED_COMMANDS`: its argument or block consumed, a warning listed
        (a ``[_Prop]`` argument is read, so it must still be well formed)."""
        word = head.lower
        shape = IGNORED_COMMANDS[word]
        if shape == "block":
            self.s.skip_raw_block(self.open_block(head), head.text)
        elif shape == "string":
            self.expect_string(f"name after {head.text}")
        else:
            self.value(head.text)
        self.warn(f"{head.text} ignored: {_IGNORED_WHY[word]}", head)

    def parse_command(self, head: Token, into: list) -> None:
        """A command of :data:`STATE_COMMANDS`, appended to ``into`` before its arguments are read."""
        command = Command(head)
        into.append(command)
        values = command.values
        word = head.lower
        if word in _VALUE_WHAT:
            values.append(self.value(_VALUE_WHAT[word]))
        elif word == "color":
            self.parse_color(command, "Color")
        elif word == "material":
            self.parse_material_block(command)
        elif word == "alphatest":
            values.append(self.value("AlphaTest comparison"))
            nxt = self.s.peek()
            if nxt.line == head.line and (nxt.kind == "number" or (nxt.kind == "punct" and nxt.text == "[")):
                values.append(self.value("AlphaTest value"))
        elif word == "blend":
            self.parse_blend(command)
        elif word == "blendop":
            values.append(self.value("BlendOp"))
            if self.at_punct(","):
                self.s.next()
                values.append(self.value("BlendOp"))
        elif word == "colormask":
            mask = self.value("ColorMask")
            values.append(mask)
            nxt = self.s.peek()
            if nxt.kind == "number" and nxt.line == mask.token.line:  # render-target index
                command.render_target = self.s.next()
        elif word == "offset":
            values.append(self.value("Offset factor"))
            self.expect(",", "between the Offset factor and units")
            values.append(self.value("Offset units"))
        elif word == "stencil":
            self.parse_stencil(command)

    def parse_blend(self, command: Command) -> None:
        """``Blend [N] Off`` (no values) or ``Blend [N] src dst[, src_alpha dst_alpha]``."""
        first = self.s.peek()
        if first.kind == "ident" and first.lower == "off":
            self.s.next()
            return
        if first.kind == "number" and first.line == command.head.line:
            command.render_target = self.s.next()
            if self.s.peek().kind == "ident" and self.s.peek().lower == "off":
                self.s.next()
                return
        for _ in range(2):  # one at a time: the tree holds each factor read before a later error
            command.values.append(self.value("blend factor"))
        if self.at_punct(","):
            self.s.next()
            for _ in range(2):
                command.values.append(self.value("blend factor"))

    def parse_color(self, command: Command, what: str) -> None:
        """A colour argument: ``(r, g, b[, a])`` (alpha 1 when left out) or a ``[_Prop]`` reference."""
        if not self.at_punct("("):
            command.values.append(self.value(what))
            return
        self.s.next()
        parts = [self.expect_number(f"a component of {what}")]
        while self.at_punct(","):
            self.s.next()
            parts.append(self.expect_number(f"a component of {what}"))
        self.expect(")", f"after the {what} colour")
        if not 3 <= len(parts) <= 4:
            raise self.s.error(f"{what} colour needs 3 or 4 components", command.head)
        command.color = (*parts, 1.0)[:4] if len(parts) == 3 else tuple(parts)

    def parse_material_block(self, material: Command) -> None:
        """``Material { Diffuse C Ambient C Specular C Shininess N Emission C }``."""
        open_tok = self.open_block(material.head)
        for tok in self.block_tokens(open_tok, "Material"):
            if tok.kind != "ident" or tok.lower not in MATERIAL_BLOCK_COMMANDS:
                raise self.s.error(f"unknown Material command {tok.describe()} (expected Diffuse, Ambient, "
                                   "Specular, Shininess or Emission)", tok)
            command = Command(tok)
            material.commands.append(command)
            if tok.lower == "shininess":
                command.values.append(self.value("Material Shininess"))
            else:
                self.parse_color(command, f"Material {tok.text}")

    def parse_stencil(self, stencil: Command) -> None:
        open_tok = self.open_block(stencil.head)
        for tok in self.block_tokens(open_tok, "Stencil"):
            if tok.kind != "ident":
                raise self.s.error(f"unexpected {tok.describe()} in Stencil", tok)
            word = tok.lower
            if word in ("ref", "readmask", "writemask") or word in STENCIL_FACE_COMMANDS:
                what = f"Stencil {tok.text}"
            elif word == "comp":
                what = "Stencil Comp"
            elif word in ("pass", "fail", "zfail"):
                what = f"Stencil {tok.text} operation"
            else:
                raise self.s.error(f"unknown Stencil command {tok.text!r}", tok)
            command = Command(tok)
            stencil.commands.append(command)
            command.values.append(self.value(what))
