"""Fixed-function passes (legacy ShaderLab without a program, SPEC §11.4): what they draw.

A pass without a program is drawn by Unity's fixed-function emulation from its commands (Unity
manual, "Legacy ShaderLab": "Material", "SetTexture", "Alpha testing"):

* ``Lighting On`` lights the ``Material { }`` colours (``Diffuse``; left out, a colour is black;
  ``ColorMaterial AmbientAndDiffuse`` takes the vertex colour instead) per vertex — drawn here
  as per-pixel Lambert of the albedo (warned). Its lights and ambient are half those of
  programmable shaders (``UNITY_LIGHTMODEL_AMBIENT`` is ``glstate_lightmodel_ambient * 2``), which
  the legacy shaders' ``combine texture * primary DOUBLE`` undoes: a lit pass's colour is half
  its combiner's scale. ``Lighting Off`` (the default) gives ``primary`` =
  the ``Color`` command's colour, or else the vertex colour (the generated code reads
  ``IN.color`` then: research-surface.md §2.1);
* ``SetTexture [_MainTex] { combine … }`` stages: a formula that is a product of ``texture``,
  ``primary``, ``previous`` and ``constant`` (``constantColor``), with ``Double`` (×2) or ``Quad``
  (×4), maps onto the material — texture × colour (× vertex colour), the constants and the
  scale folded into the colour; the part after the comma is the alpha's formula. Sums, ``lerp``,
  negation and ``alpha`` suffixes are drawn as texture × primary (warned);
* ``AlphaTest comparison value`` → the pass's alpha test (``Always`` and ``Off`` test nothing).

:func:`fixed_function_shading` returns a :class:`FixedShading`; :func:`program_pass_notes` lists
the fixed-function commands a pass with a program ignores.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ...core.vocabulary import CompareFunction, Lighting, VertexColor
from .diagnostics import SourceWarning
from .lexer import Token
from .programs import AlphaTest
from .state import PassState

#: The state keys of the fixed-function commands (:class:`~.state.PassState`), with their command names.
FIXED_FUNCTION_KEYS = {"lighting": "Lighting", "separate_specular": "SeparateSpecular",
                       "color_material": "ColorMaterial", "ff_color": "Color", "ff_material": "Material",
                       "ff_alpha_test": "AlphaTest"}

_COMBINE_RE = re.compile(r"\bcombine\b([^\n}]*)", re.IGNORECASE)
_CONSTANT_RE = re.compile(r"\bconstantColor\s*(?:\(([^)]*)\)|\[\s*(\w+)\s*\])", re.IGNORECASE)
_OPERAND_WORDS = {"texture": "T", "primary": "P", "previous": "prev", "constant": "C"}
_SCALE_WORDS = {"double": 2.0, "quad": 4.0}


@dataclass
class FixedShading:
    """How a fixed-function pass shades, in the material's terms.

    ``color``: the colour that multiplies the texture (``Material { Diffuse … }`` or ``Color …``
    with its constants; a ``[_Prop]`` already read as the material's value); ``scale``:
    ``Double``/``Quad`` on the RGB.
    """

    lighting: Lighting = Lighting.Unlit
    color: tuple[float, float, float, float] | None = None
    scale: float = 1.0
    vertex_color: VertexColor = VertexColor.Off
    alpha_test: AlphaTest | None = None
    texture: str | None = None  # the texture property of the stage(s)
    alpha_constant: float | None = None  # the alpha's formula is a constant (e.g. UNITY_OPAQUE_ALPHA_FFP)
    #: No command states a colour (no Lighting On, Color, SetTexture): Unity draws the vertex colour
    #: (``primary``); imported with the material's ``_Color``, as a pass of state only.
    state_only: bool = False
    warnings: list[SourceWarning] = field(default_factory=list)


@dataclass
class _Product:
    """A combiner result as a product: ``scale × texture^t × primary^p × constant``."""

    scale: float = 1.0
    texture: int = 0
    primary: int = 0
    constant: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    exact: bool = True

    def times(self, other: _Product) -> _Product:
        return _Product(self.scale * other.scale, self.texture + other.texture, self.primary + other.primary,
                        tuple(a * b for a, b in zip(self.constant, other.constant, strict=True)),
                        self.exact and other.exact)


def _split_top_comma(text: str) -> tuple[str, str | None]:
    depth = 0
    for i, c in enumerate(text):
        depth += c == "("
        depth -= c == ")"
        if c == "," and depth == 0:
            return text[:i], text[i + 1:]
    return text, None


def _formula(text: str, previous: _Product, constant: tuple[float, float, float, float]) -> _Product:
    """A combine formula as a product; a formula that is not one is texture × primary, inexact."""
    words = re.findall(r"[A-Za-z]+|[*+\-()]", text)
    scale = 1.0
    while words and words[-1].lower() in _SCALE_WORDS:
        scale *= _SCALE_WORDS[words.pop().lower()]
    operands = words[0::2]
    operators = words[1::2]
    if not operands or any(op != "*" for op in operators) or any(w.lower() not in _OPERAND_WORDS for w in operands):
        return _Product(scale, 1, 1, exact=False)
    out = _Product(scale)
    for word in operands:
        kind = _OPERAND_WORDS[word.lower()]
        if kind == "T":
            out = out.times(_Product(texture=1))
        elif kind == "P":
            out = out.times(_Product(primary=1))
        elif kind == "C":
            out = out.times(_Product(constant=constant))
        else:
            out = out.times(previous)
    return out


def fixed_function_shading(pass_state: PassState, color_of: Callable[[str], tuple[float, float, float, float]],
                           main_texture: str | None) -> FixedShading:
    """How the fixed-function pass ``pass_state`` shades (see the module docstring).

    ``color_of(name)``: a colour property's value (the material's, else its default);
    ``main_texture``: the material's main texture property (``_MainTex``)."""
    state, block = pass_state.state, pass_state.block
    out = FixedShading()

    def warn(at: Token, message: str) -> None:
        out.warnings.append(SourceWarning.at(at, message))

    lit = bool(state.get("lighting", False))
    material_block = state.get("ff_material")
    color_material = state.get("color_material")
    if not (lit or block.stages or "ff_color" in state):
        out.state_only = True  # nothing states a colour: drawn with the material's _Color
        out.alpha_test = _alpha_test(state)
        return out
    vertex = False
    if lit:
        out.lighting = Lighting.Lambert
        warn(pass_state.where["lighting"], "Lighting On: the fixed-function per-vertex lighting is drawn as "
                                           "per-pixel Lambert of the albedo (approximated)")
        if color_material == "AmbientAndDiffuse":
            vertex, out.color = True, (1.0, 1.0, 1.0, 1.0)
        else:
            diffuse = (material_block or {}).get("diffuse", (0.0, 0.0, 0.0, 0.0))
            out.color = tuple(float(c) for c in diffuse)
        for name in ("emission", "specular"):
            value = (material_block or {}).get(name)
            if value is not None and any(value[:3]):
                warn(pass_state.where["ff_material"], f"Material {name.capitalize()} is not drawn (the lit colour "
                                                      "is Lambert of the albedo)")
        if color_material == "Emission":
            warn(pass_state.where["color_material"], "ColorMaterial Emission is not drawn")
    elif "ff_color" in state:
        out.color = tuple(float(c) for c in state["ff_color"])
    else:
        vertex = True  # primary is the vertex colour
        out.color = (1.0, 1.0, 1.0, 1.0)
    rgb = alpha = _Product(primary=1)
    for stage in block.stages:
        constant = (1.0, 1.0, 1.0, 1.0)
        m = _CONSTANT_RE.search(stage.block)
        if m and m.group(1) is not None:
            parts = [float(x) for x in re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)", m.group(1))]
            constant = tuple((parts + [1.0] * 4)[:4]) if len(parts) >= 3 else constant
        elif m:
            constant = color_of(m.group(2))
        texture = stage.texture.token.text
        if out.texture is None:
            out.texture = texture
        elif texture != out.texture:
            warn(stage.head, f"SetTexture [{texture}]: a second texture is not drawn (only {out.texture})")
        if main_texture is not None and texture != main_texture and out.texture == texture:
            warn(stage.head, f"SetTexture [{texture}] is drawn with the material's {main_texture}")
        combine = _COMBINE_RE.search(stage.block)
        if combine is None:
            continue  # a stage without combine passes previous on
        rgb_text, alpha_text = _split_top_comma(combine.group(1))
        new_rgb = _formula(rgb_text, rgb, constant)
        new_alpha = _formula(alpha_text if alpha_text is not None else rgb_text, alpha, constant)
        if alpha_text is None:
            new_alpha.scale = 1.0  # Double/Quad scale the colour; one formula's alpha keeps its product
        if not (new_rgb.exact and new_alpha.exact):
            warn(stage.head, f"combine{combine.group(1).rstrip()}: drawn as texture × primary (approximated)")
        rgb, alpha = new_rgb, new_alpha
    if rgb.texture > 1 or rgb.primary > 1 or alpha.texture > 1 or alpha.primary > 1:
        warn(block.head, "the combiners multiply the texture or primary colour more than once; drawn once")
    if block.stages and rgb.texture == 0:
        warn(block.stages[0].head, "the combiners do not use the texture; drawn with it")
    # The fixed-function lighting inputs are half of the programmable ones (UnityShaderVariables.cginc:
    # "#define UNITY_LIGHTMODEL_AMBIENT (glstate_lightmodel_ambient * 2)"), which is why lit legacy
    # shaders combine "texture * primary DOUBLE": so a lit pass's colour is half its combiner's scale.
    out.scale = rgb.scale * (0.5 if lit else 1.0)
    base = out.color
    out.color = tuple(base[i] * rgb.constant[i] for i in range(3)) + (base[3] * alpha.constant[3],)
    if alpha.texture == 0 and alpha.primary == 0 and block.stages:
        out.alpha_constant = alpha.constant[3]
    if vertex and (rgb.primary or alpha.primary):
        out.vertex_color = VertexColor.Multiply
    elif vertex and block.stages:
        out.vertex_color = VertexColor.Off
    elif vertex:
        out.vertex_color = VertexColor.Multiply  # no stage: the pass outputs primary itself
    out.alpha_test = _alpha_test(state)
    return out


def _alpha_test(state: dict[str, Any]) -> AlphaTest | None:
    test = state.get("ff_alpha_test")
    if test is None or test[0] in (None, CompareFunction.Always):
        return None
    comp, value, prop = test
    return AlphaTest(comp, prop, value if prop is None else None)


def program_pass_notes(pass_state: PassState) -> list[SourceWarning]:
    """The fixed-function commands that a pass with a program ignores, one warning each."""
    out = []
    for key, name in FIXED_FUNCTION_KEYS.items():
        if key in pass_state.state:
            out.append(SourceWarning.at(pass_state.where[key], f"{name} ignored: the pass has a program, which "
                                                               "decides what the fixed-function commands would"))
    return out


def describe(shading: FixedShading) -> dict[str, Any]:
    """What a fixed-function pass draws, for the JSON's ``extra``."""
    return {"lighting": shading.lighting.value, "color": list(shading.color) if shading.color else None,
            "scale": shading.scale, "vertex_color": shading.vertex_color.value, "texture": shading.texture}
