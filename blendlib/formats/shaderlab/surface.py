"""Surface shaders (``#pragma surface surf Model options`` in a SubShader, SPEC §11.3): the passes
Unity generates, with the state its compiled output shows for each option.

Unity replaces the ``CGPROGRAM … #pragma surface … ENDCG`` block, in place inside the SubShader,
by generated ShaderLab: for alpha-blended options a SubShader-level ``ZWrite Off ColorMask RGB``,
then the passes ``FORWARD`` (ForwardBase), ``FORWARD`` (ForwardAdd, unless ``noforwardadd``),
``PREPASS`` (PrePassBase, PrePassFinal), ``DEFERRED``, ``ShadowCaster`` (``addshadow``) and
``Meta`` (unless ``nometa``). :func:`expand_surface_programs` does the same to the syntax tree:
it writes that ShaderLab (:func:`generated_shaderlab`) and parses it into the SubShader where the
program stood, so the generated passes inherit and override state exactly as written ones do.
Each generated pass keeps the program text (the ``surf`` function: its ``clip``, keywords,
vertex colours) plus what Unity generates into it (``clip (o.Alpha - VAR);`` for
``alphatest:VAR``, the forward passes' ``_LightColor0``).

The state per option, and where it was read (docs/unity-shaders.md has the table and quotes):

============== ===================================== ===================================== =========
option         SubShader / ForwardBase               ForwardAdd                            source
============== ===================================== ===================================== =========
(opaque)       — / —                                 ZWrite Off Blend One One              listing
alpha:fade     ZWrite Off ColorMask RGB / Blend      … Blend SrcAlpha One                  listing
               SrcAlpha OneMinusSrcAlpha
alpha:premul   ZWrite Off ColorMask RGB / Blend One  … Blend One One                       listing
               OneMinusSrcAlpha
alpha, :auto   fade (Lambert, BlinnPhong, custom); premul (Standard, StandardSpecular)     manual
alpha:blend    as alpha:fade (no compiled listing found: warned)                           manual
alphatest:VAR  — / ColorMask RGB, clip (o.Alpha-VAR) ZWrite Off Blend One One ColorMask RGB listing
decal:add      — / Blend One One ZWrite Off          ZWrite Off Blend One One              ripped (warned)
decal:blend    — / Blend SrcAlpha OneMinusSrcAlpha   ZWrite Off Blend SrcAlpha One         manual (warned)
               ZWrite Off
============== ===================================== ===================================== =========

Alpha-blended options generate no PREPASS/DEFERRED pass; the PBS models (``Standard``,
``StandardSpecular``) no PREPASS. ``exclude_path:forward|deferred|prepass`` drop those passes.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from .diagnostics import SourceWarning
from .lexer import Scanner, Token
from .parser import Parser
from .programs import strip_comments
from .tree import PassBlock, ProgramBlock, ShaderBlock, SubShaderBlock

_PRAGMA_RE = re.compile(r"^[ \t]*#[ \t]*pragma[ \t]+surface[ \t]+(\w+)[ \t]+(\w+)([^\n]*)$", re.M)
#: Lighting models of UnityPBSLighting.cginc: ``alpha``/``alpha:auto`` premultiply with them.
PBS_MODELS = frozenset(["Standard", "StandardSpecular"])
#: Options that change vertices or the final colour, which this renderer does not run (warned).
_NOT_DRAWN_OPTIONS = {"vertex": "vertex modifier", "finalcolor": "final colour modifier"}


@dataclass(frozen=True)
class SurfacePragma:
    """``#pragma surface FUNCTION MODEL options``: the function, the lighting model, the options
    (``alpha:fade``, ``alphatest:_Cutoff``, ``noforwardadd``, …) in order."""

    function: str
    model: str
    options: tuple[str, ...] = ()

    def option(self, name: str) -> str | None:
        """The value of ``name`` or ``name:value`` (``""`` for the bare option), None when absent."""
        for option in self.options:
            key, _, value = option.partition(":")
            if key == name:
                return value
        return None

    @property
    def blend_mode(self) -> str | None:
        """``fade``, ``premul``, ``blend``, ``decal:add``, ``decal:blend`` or None (opaque, alphatest)."""
        alpha = self.option("alpha")
        if alpha is not None:
            if alpha in ("", "auto"):
                return "premul" if self.model in PBS_MODELS else "fade"
            return alpha
        decal = self.option("decal")
        return f"decal:{decal}" if decal else None

    @property
    def premultiplied(self) -> bool:
        """Whether the lighting function premultiplies the albedo by alpha (UnityPBSLighting.cginc
        ``PreMultiplyAlpha`` under ``_ALPHAPREMULTIPLY_ON``, which alpha:premul defines)."""
        return self.blend_mode == "premul" and self.model in PBS_MODELS


def surface_pragma(code: str) -> SurfacePragma | None:
    """The ``#pragma surface`` of a program (comments removed first), or None."""
    m = _PRAGMA_RE.search(strip_comments(code))
    if m is None:
        return None
    return SurfacePragma(m.group(1), m.group(2), tuple(m.group(3).split()))


@dataclass
class _Generated:
    subshader: list[str] = field(default_factory=list)  # the SubShader-level state line
    passes: list[tuple[str, str, list[str], str]] = field(default_factory=list)  # name, LightMode, state, code


def _generate(pragma: SurfacePragma) -> _Generated:
    out = _Generated()
    mode = pragma.blend_mode
    test = pragma.option("alphatest")
    excluded = {v for o in pragma.options if o.startswith("exclude_path:") for v in [o.partition(":")[2]]}
    blended = mode in ("fade", "premul", "blend")
    base: list[str] = []
    add = ["ZWrite Off", "Blend One One"]
    clip = f"\nclip (o.Alpha - {test});\n" if test else ""
    if blended:
        out.subshader = ["ZWrite Off", "ColorMask RGB"]
        if mode == "premul":
            base, add = ["Blend One OneMinusSrcAlpha"], add + ["Blend One One"]
        else:
            base, add = ["Blend SrcAlpha OneMinusSrcAlpha"], add + ["Blend SrcAlpha One"]
    elif mode == "decal:add":
        base = ["Blend One One", "ZWrite Off"]
    elif mode == "decal:blend":
        base, add = ["Blend SrcAlpha OneMinusSrcAlpha", "ZWrite Off"], add + ["Blend SrcAlpha One"]
    if test:
        base, add = base + ["ColorMask RGB"], add + ["ColorMask RGB"]
    forward = "\n_LightColor0;\n"  # what Unity's generated forward code reads: a lit pass
    if "forward" not in excluded:
        out.passes.append(("FORWARD", "ForwardBase", base, clip + forward))
        if pragma.option("noforwardadd") is None:
            out.passes.append(("FORWARD", "ForwardAdd", add, clip + forward))
    if not blended and mode != "decal:blend":
        if "prepass" not in excluded and pragma.model not in PBS_MODELS:
            out.passes.append(("PREPASS", "PrePassBase", [], clip))
            out.passes.append(("PREPASS", "PrePassFinal", ["ZWrite Off"], clip))
        if "deferred" not in excluded:
            out.passes.append(("DEFERRED", "Deferred", [], clip))
    if pragma.option("addshadow") is not None:
        out.passes.append(("ShadowCaster", "ShadowCaster", ["ZWrite On", "ZTest LEqual"], clip))
    if pragma.option("nometa") is None:
        out.passes.append(("Meta", "Meta", ["Cull Off"], ""))
    return out


def generated_shaderlab(pragma: SurfacePragma) -> str:
    """The ShaderLab Unity generates for ``pragma`` (state and pass structure; programs left out),
    as the body of a SubShader: ``{ state Pass { … } … }``."""
    generated = _generate(pragma)
    lines = ["{", *generated.subshader]
    for name, mode, state, _ in generated.passes:
        lines.append(f'Pass {{ Name "{name}" Tags {{ "LightMode"="{mode}" }} {" ".join(state)} }}')
    lines.append("}")
    return "\n".join(lines)


class _AtOnePlace(Scanner):
    """A scanner whose every token stands where the surface program stands (for messages)."""

    def __init__(self, text: str, filename: str, at: Token) -> None:
        super().__init__(text, filename)
        self._at = (at.line, at.column)

    def where(self, offset: int) -> tuple[int, int]:
        return self._at


def expand_surface_programs(shader: ShaderBlock, subshader: SubShaderBlock) -> list[SourceWarning]:
    """Replace each surface program of ``subshader`` by the commands and passes Unity generates from
    it (see the module docstring); returns the warnings about what is approximated."""
    warnings: list[SourceWarning] = []
    body: list = []
    for item in subshader.body:
        if not isinstance(item, ProgramBlock):
            body.append(item)
            continue
        pragma = surface_pragma(item.text)
        if pragma is None:
            body.append(item)
            continue
        parser = Parser(generated_shaderlab(pragma), shader.filename)
        parser.s = _AtOnePlace(parser.s.text, shader.filename, item.token)
        parser.shader = shader  # [_Prop] names bind to the shader's properties
        generated = SubShaderBlock(item.token)
        parser.parse_subshader(generated)
        code = {(name, mode): extra for name, mode, _, extra in _generate(pragma).passes}
        for node in generated.body:
            if isinstance(node, PassBlock):
                node.surface = pragma
                node.programs = [item.text + code[(node.name, node.tags.get("LightMode"))]]
            body.append(node)
        warnings += _approximations(pragma, item)
    subshader.body[:] = body
    return warnings


_SURF_TEXTURE_COLOR_RE = re.compile(
    r"tex2D\s*\(\s*_MainTex\b[^;]*?\)\s*\*\s*_Color\b|_Color\s*\*\s*tex2D\s*\(\s*_MainTex\b")


def _approximations(pragma: SurfacePragma, program: ProgramBlock) -> list[SourceWarning]:
    """What of ``pragma``'s passes this renderer draws differently from Unity, one warning each."""
    out = []

    def warn(message: str) -> None:
        out.append(SourceWarning.at(program.token, message))

    if pragma.model != "Lambert":
        warn(f"surface lighting model {pragma.model} is drawn as Lambert of the albedo (the lit colour is "
             "approximated; order, coverage and blending are exact)")
    mode = pragma.blend_mode
    if mode == "blend":
        warn("alpha:blend imported as alpha:fade (Blend SrcAlpha OneMinusSrcAlpha, ZWrite Off, ColorMask RGB): "
             "no compiled listing of it was found (docs/unity-shaders.md)")
    elif mode in ("decal:add", "decal:blend"):
        warn(f"{mode} imported as {'Blend One One' if mode == 'decal:add' else 'Blend SrcAlpha OneMinusSrcAlpha'} "
             "with ZWrite Off in the ForwardBase pass: the evidence for its compiled state is weak "
             "(docs/unity-shaders.md)")
    for option in pragma.options:
        key, _, value = option.partition(":")
        if key in _NOT_DRAWN_OPTIONS and value:
            warn(f"{option}: the {_NOT_DRAWN_OPTIONS[key]} {value} is not run here")
    code = strip_comments(program.text)
    body = _function_body(code, pragma.function)
    if body is not None and not _SURF_TEXTURE_COLOR_RE.search(body):
        warn(f"the albedo and alpha of {pragma.function}() are imported as _MainTex × _Color (its body is not of "
             "the form tex2D(_MainTex, …) * _Color)")
    return out


def _function_body(code: str, name: str) -> str | None:
    """The text between the braces of function ``name``'s definition in ``code`` (None: not defined there)."""
    m = re.search(r"\b" + re.escape(name) + r"\s*\([^;{]*\)\s*\{", code)
    if m is None:
        return None
    depth, i = 1, m.end()
    while i < len(code) and depth:
        depth += {"{": 1, "}": -1}.get(code[i], 0)
        i += 1
    return code[m.end():i - 1]
