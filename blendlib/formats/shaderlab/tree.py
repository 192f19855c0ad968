"""The syntax tree the parser builds: a shader's blocks and commands as written, nothing resolved.

``Shader "name" { Properties { } Category { SubShader { Pass { } } } Fallback "…" }`` becomes a
:class:`ShaderBlock` whose ``body`` holds, in source order, the blocks and commands of each level:

* :class:`CategoryBlock` — state :class:`Command` s, :class:`TagsBlock` s, nested Categories and SubShaders;
* :class:`SubShaderBlock` — commands, :class:`PassBlock` s and :class:`UsePass` es (its Tags are
  kept as one dictionary with the position of the Queue tag);
* :class:`PassBlock` — its name, tags, commands (the fixed-function ones too, and its
  :class:`SetTexture` stages) and program texts;
* :class:`ProgramBlock` — a program written directly in a SubShader (a surface shader: Unity
  generates passes in its place) and :class:`GrabPass` — both kept where they stand.

A :class:`Command` keeps each argument as a :class:`Value` (a word, a number or a ``[_Prop]``
reference with the declaration it names); what the words and numbers mean, and how Category,
SubShader and Pass state combine, is :mod:`.state`'s business. Only the first SubShader is
parsed; the others are counted (``subshader_count``). Unknown commands (and the known ones that
carry nothing, such as ``CustomEditor`` or ``Fog { }``) have no node.

The parser builds the tree top-down — a node joins its parent before its own contents are read —
so when it stops at a syntax error, the tree read so far is complete up to that point.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .lexer import Token


@dataclass
class Property:
    """A declaration of ``Properties``: ``[attributes] name ("display", type) = default``.

    ``default``: a float (Float, Int, Range), a 4-tuple of floats (Color, Vector; missing
    components filled as Unity does) or the texture's default name (``"white"``).
    """

    name: str
    display: str
    type: str  # as written: "Color", "Range", "2D", ...
    default: Any
    attributes: list[str]
    token: Token  # the name


@dataclass
class Value:
    """One argument of a command as written: a word or number, or a ``[_Prop]`` reference."""

    token: Token  # the word or number; for a reference, the property name inside the brackets
    what: str  # what the argument is, for messages ("blend factor", "Stencil Ref")
    reference: bool = False
    #: For a reference: the property of that name declared before it (None: none is).
    declared: Property | None = None


@dataclass
class Command:
    """A command with its arguments, e.g. ``Cull Off``, ``Blend 1 SrcAlpha OneMinusSrcAlpha, One Zero``.

    ``values`` in order: one for most commands; ``Blend`` none (``Off``), two or four factors;
    ``BlendOp`` one or two ops; ``Offset`` factor and units. ``render_target`` is the ``N`` of
    ``Blend N …`` / ``ColorMask … N``. ``Stencil { … }`` holds its commands (one value each) in
    ``commands``.
    """

    head: Token
    values: list[Value] = field(default_factory=list)
    render_target: Token | None = None
    commands: list[Command] = field(default_factory=list)
    #: ``Color (r, g, b, a)`` and the colours of ``Material { }``: the literal, 4 floats (None: a
    #: ``[_Prop]`` in ``values`` or no colour).
    color: tuple[float, float, float, float] | None = None

    @property
    def name(self) -> str:
        """The command's keyword, lower case (``"blend"``)."""
        return self.head.lower


@dataclass
class TagsBlock:
    """``Tags { "Name"="Value" … }`` in a Category (a SubShader's and a Pass's are dictionaries)."""

    head: Token
    tags: dict[str, str] = field(default_factory=dict)


@dataclass
class UsePass:
    """``UsePass "Shader/NAME"``: a pass of another shader, recorded where it stands."""

    head: Token
    path: str


@dataclass
class SetTexture:
    """``SetTexture [_Tex] { combine … constantColor … }`` (a fixed-function texture stage): the
    texture reference and the block's text as written (read by :mod:`.fixed_function`)."""

    head: Token
    texture: Value
    block: str
    block_token: Token  # the '{' (positions of what the block says)


@dataclass
class PassBlock:
    """``Pass { … }``: its ``Name``, ``Tags``, state commands, fixed-function texture stages and
    ``CGPROGRAM``-like program texts."""

    head: Token
    name: str | None = None
    tags: dict[str, str] = field(default_factory=dict)
    commands: list[Command] = field(default_factory=list)
    programs: list[str] = field(default_factory=list)
    stages: list[SetTexture] = field(default_factory=list)
    #: Made by Unity from a surface shader's program (``SubShader``-level ``#pragma surface``), not
    #: written: the :class:`~.surface.SurfacePragma` it was generated from (None: written).
    surface: Any = None


@dataclass
class ProgramBlock:
    """A ``CGPROGRAM`` … ``ENDCG`` (or HLSL) written directly in a SubShader: a surface shader,
    whose passes Unity generates in its place."""

    token: Token
    text: str


@dataclass
class GrabPass:
    """``GrabPass { … }``: copies the frame into a texture; it draws nothing itself."""

    head: Token


@dataclass
class SubShaderBlock:
    """``SubShader { … }``: state commands, passes, UsePasses, programs and GrabPasses in source
    order, and its tags."""

    head: Token
    body: list[Command | PassBlock | UsePass | ProgramBlock | GrabPass] = field(default_factory=list)
    tags: dict[str, str] = field(default_factory=dict)
    queue_token: Token | None = None  # the value of its last "Queue" tag


@dataclass
class CategoryBlock:
    """``Category { … }``: state commands, Tags, Categories and SubShaders in source order."""

    head: Token
    body: list[Command | TagsBlock | CategoryBlock | SubShaderBlock] = field(default_factory=list)


@dataclass
class ShaderBlock(CategoryBlock):
    """``Shader "name" { … }``: the root. ``body`` as a Category's (the parser accepts state
    commands and Tags only inside a Category); ``includes`` are the ``CGINCLUDE``/``HLSLINCLUDE``
    texts outside the passes, in order."""

    name: str = ""
    filename: str = "<string>"
    properties: dict[str, Property] = field(default_factory=dict)
    includes: list[str] = field(default_factory=list)
    fallback: str | None = None
    subshader_count: int = 0  # every SubShader read, the skipped ones included
