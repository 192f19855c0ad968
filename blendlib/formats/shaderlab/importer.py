"""Import: a ``.shader`` (optionally with a ``.mat``'s values) → :class:`ShaderLabResult`.

:func:`parse_shaderlab` runs the steps of the package in order:

1. :mod:`.parser` — the tree; a shader without a SubShader takes its ``Fallback``'s (found on the
   search path, :mod:`.assets`), as Unity does;
2. :mod:`.surface` — a SubShader's ``#pragma surface`` program replaced by the passes Unity
   generates from it;
3. :mod:`.state` — values (the material's, else the property defaults) and inheritance;
   ``UsePass "Shader/NAME"`` inserts the passes of that name (names upper-cased, as Unity does:
   every pass of the name, the 2019.4 manual's "Inserts all passes with a given name") of the
   other shader's first SubShader, with their own state;
4. per pass, :mod:`.programs` (a pass with a program) or :mod:`.fixed_function` (one without):
   the alpha test and its comparison, premultiplied output, vertex colours, lighting;
5. the :class:`~blendlib.core.vocabulary.Material`: the queue (a ``.mat``'s custom render queue
   over the ``Queue`` tag), ``_Color``/``_MainTex``/``_Cutoff``/``_AlphaScale``/``_TintColor``
   from the material's values or the property defaults (``[MainColor]``/``[MainTexture]`` name
   others), and the shading of the first pass that draws (the material has one shading; passes
   that shade otherwise are warned). Each pass gets its ``LightMode`` (untagged: ``Always``;
   unknown: ``Other``); a premultiplying pass (``c.rgb *= c.a``) gets ``Blend SrcAlpha …`` for its
   ``Blend One …`` with the alpha factors kept apart, which draws the same. Passes that never
   draw (``ZTest Never``, a ``.mat``'s ``disabledShaderPasses``) are listed, not in the material.

The one error raised is the first of the text: when the parser stops at a syntax error, a bad
value read before it (``Blend SrcAlfa {``) is reported instead. Warnings are listed in the order
of the text, then the importer's own; a warning repeated at one place is listed once.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from ...core.vocabulary import (
    BlendFactor,
    CompareFunction,
    Lighting,
    LightMode,
    Material,
    Pass,
    StencilOp,
    VertexColor,
    pass_draws,
)
from .assets import AssetSearch
from .diagnostics import Positioned, ShaderLabError, SourceWarning, WarningList
from .fixed_function import fixed_function_shading, program_pass_notes
from .parser import Parser
from .programs import AlphaTest, ShaderPrograms, keyword_sets
from .record import material_record, record_json
from .state import MaterialValues, ResolvedShader, check_values, parse_queue, resolve
from .surface import expand_surface_programs
from .tree import CategoryBlock, Property, ShaderBlock, SubShaderBlock, UsePass

#: UsePass and Fallback chains stop this deep (a shader that uses itself is an error of the file).
MAX_INDIRECTION = 8
_LIGHT_MODES = {m.value.lower(): m for m in LightMode if m is not LightMode.Other}
#: The LightModes of passes that may draw in the forward path (the others are never drawn here).
_COLOUR_PASSES = (LightMode.Always, LightMode.ForwardBase, LightMode.ForwardAdd, LightMode.Vertex)


@dataclass(frozen=True)
class ShaderLabResult:
    """What a ``.shader`` (and ``.mat``) file says: the material (named as the shader, or as the
    ``.mat``'s material; no texture image), warnings, extras.

    ``material.passes`` holds the passes that may draw, in order (empty when the file has no
    SubShader and no Fallback: the material then draws one default pass); ``listed`` every pass
    with None or the reason it is left out; ``main_tex_file`` the ``.mat``'s ``_MainTex`` image.
    """

    material: Material
    warnings: tuple[str, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)
    listed: tuple[tuple[Pass, str | None], ...] | None = None
    main_tex_file: str | None = None

    @property
    def name(self) -> str:
        """The ``Shader "name"`` (a ``.mat``: its material's name)."""
        return self.material.name

    @property
    def passes(self) -> tuple[Pass, ...]:
        return self.material.passes

    def to_dict(self) -> dict[str, Any]:
        """The material record (:func:`.record.material_record`): the JSON of ``python -m blendlib shaderlab``."""
        return material_record(self.name, self.material, self.warnings, self.extra, self.listed, self.main_tex_file)

    def to_json(self, indent: int | None = 2) -> str:
        return record_json(self.to_dict(), indent)


@dataclass
class _PassInfo:
    """One pass on its way into the material."""

    pass_: Pass
    excluded: str | None
    light_mode_text: str | None
    tags: dict[str, str]
    lit: bool
    lit_approximation: str
    color: tuple[float, float, float, float] | None  # a fixed-function pass's own colour
    scale: float
    vertex_color: VertexColor
    alpha_test: AlphaTest | None
    head: Positioned


@dataclass
class _Imported:
    """An imported shader before it becomes a result (UsePass takes passes from one)."""

    shader: ShaderBlock
    resolved: ResolvedShader
    passes: list[_PassInfo]
    tags: dict[str, str]
    queue_token: Positioned | None


class _Context:
    """What one import shares: the warnings, the search path, the material's values and keywords."""

    def __init__(self, filename: str, search: AssetSearch, values: MaterialValues | None,
                 keywords: frozenset[str] | None, disabled: tuple[str, ...], within: tuple[str, ...] = ()) -> None:
        self.filename = filename
        #: The files being imported around this one (UsePass, Fallback): one of them again is a cycle.
        self.within = (*within, str(Path(filename).resolve()))
        self.search = search
        self.values = values
        self.keywords = keywords
        self.disabled = {d.lower() for d in disabled}
        self.warnings: list[SourceWarning] = []
        self.notes: list[str] = []  # warnings about other files (UsePass, Fallback), without a position here

    def warn(self, at: Positioned, message: str) -> None:
        self.warnings.append(SourceWarning.at(at, message))


def _parse(text: str, filename: str, values: MaterialValues | None) -> tuple[ShaderBlock, list[SourceWarning]]:
    parser = Parser(text, filename)
    try:
        shader = parser.parse()
    except ShaderLabError as exc:
        if parser.shader is not None:
            check_values(parser.shader, values)  # raises a bad value that stands before the syntax error
        raise exc from None
    return shader, list(parser.warnings)


def _first_subshader(block: CategoryBlock) -> SubShaderBlock | None:
    for item in block.body:
        if isinstance(item, SubShaderBlock):
            return item
        if isinstance(item, CategoryBlock):
            found = _first_subshader(item)
            if found is not None:
                return found
    return None


def _defaults(props: dict[str, Property]) -> MaterialValues:
    """The property defaults as material values (what a new material of the shader holds)."""
    return MaterialValues({p.name: p.default for p in props.values() if isinstance(p.default, float)},
                          {p.name: p.default for p in props.values() if isinstance(p.default, tuple)})


def _merged(base: MaterialValues, over: MaterialValues | None) -> MaterialValues:
    if over is None:
        return base
    return MaterialValues({**base.floats, **over.floats}, {**base.colors, **over.colors})


def _default_keywords(props: dict[str, Property], values: MaterialValues) -> frozenset[str]:
    """The keywords a new material of the shader has on: those its ``[Toggle]``, ``[ToggleOff]`` and
    ``[KeywordEnum]`` properties set from their values (Unity's MaterialPropertyDrawers)."""
    on = set()
    for prop in props.values():
        value = values.floats.get(prop.name, prop.default)
        if not isinstance(value, float):
            continue
        for attribute in prop.attributes:
            head, _, arg = attribute.partition("(")
            head, arg = head.strip().lower(), arg.rstrip(")").strip()
            if head in ("toggle", "materialtoggle") and value != 0:
                on.add(arg or f"{prop.name.upper()}_ON")
            elif head == "toggleoff" and value == 0:
                on.add(arg or f"{prop.name.upper()}_OFF")
            elif head == "keywordenum":
                options = [o.strip() for o in arg.split(",") if o.strip()]
                if 0 <= int(value) < len(options):
                    on.add(f"{prop.name.upper()}_{options[int(value)].upper().replace(' ', '_')}")
    return frozenset(on)


def _light_mode(tags: dict[str, str]) -> tuple[LightMode, str | None]:
    text = next((v for k, v in tags.items() if k.lower() == "lightmode"), None)
    if text is None:
        return LightMode.Always, None
    return _LIGHT_MODES.get(text.strip().lower(), LightMode.Other), text


def _fold_premultiplied(p: Pass) -> Pass | None:
    """A premultiplying pass's state with the multiplication in the blend: ``Blend One X`` →
    ``Blend SrcAlpha X, One X`` (the colour takes alpha × the shader's colour, exactly the
    premultiplied colour; the alpha keeps its factors). None when that is not the same drawing."""
    if not p.blend:
        return p  # Blend Off writes the premultiplied colour itself: not representable either way
    alpha_dependent = {BlendFactor.SrcColor, BlendFactor.OneMinusSrcColor, BlendFactor.SrcAlphaSaturate}
    if p.src_blend is not BlendFactor.One or p.dst_blend in alpha_dependent:
        return None
    src_a, dst_a, op_a = p.alpha_factors
    return replace(p, src_blend=BlendFactor.SrcAlpha, separate_alpha=True, src_blend_alpha=src_a,
                   dst_blend_alpha=dst_a, blend_op_alpha=op_a)


def _pass_infos(ctx: _Context, shader: ShaderBlock, resolved: ResolvedShader, values: MaterialValues,
                depth: int) -> list[_PassInfo]:
    programs = ShaderPrograms(shader.includes, [s.block.programs for s in resolved.passes])
    keywords = ctx.keywords if ctx.keywords is not None else _default_keywords(shader.properties, values)
    main_texture = _main_texture_name(shader.properties)
    written = len(resolved.passes)
    own: list[_PassInfo] = []  # the written passes; then the UsePasses are put in their places
    for index, item in enumerate(resolved.passes):
        block = item.block
        name = block.name or ("Pass" if written == 1 else f"Pass {index + 1}")
        light_mode, light_mode_text = _light_mode(block.tags)
        fields = item.pass_fields()
        analysis = programs.analyze(index, keywords)
        color, scale, lit, lit_note = None, 1.0, analysis.lit, analysis.lit_approximation
        if analysis.has_program:
            vertex_color, test = analysis.vertex_color, analysis.alpha_test
            ctx.warnings += program_pass_notes(item)
            for note in analysis.notes:
                ctx.warn(block.head, f"pass {name!r}: {note}")
            if not analysis.vertex_color_exact:
                ctx.warn(block.head, f"pass {name!r}: its use of the vertex colour ({analysis.vertex_color_use}) is "
                                     f"drawn as {analysis.vertex_color.value} (approximated)")
            if analysis.discards_otherwise:
                ctx.warn(block.head, f"pass {name!r} discards fragments with its own condition; only its alpha "
                                     "test is imported")
        else:
            shading = fixed_function_shading(item, lambda n: tuple(values.colors.get(n, (1.0, 1.0, 1.0, 1.0))),
                                             main_texture)
            ctx.warnings += shading.warnings
            vertex_color, test, color, scale = shading.vertex_color, shading.alpha_test, shading.color, shading.scale
            lit = shading.lighting is Lighting.Lambert
            if shading.state_only and fields.get("color_mask", True) and light_mode in _COLOUR_PASSES:
                ctx.warn(block.head, f"pass {name!r} has no program and no colour command: Unity draws its vertex "
                                     "colour (fixed-function primary); imported with _Color")
            if scale != 1.0:
                ctx.warn(block.head, f"pass {name!r}: its colour scale ×{scale:g} is applied to the colour's stored "
                                     "(sRGB-encoded) value: exact in Gamma colour space")
        p = Pass(name=name, light_mode=light_mode, **fields)
        if test is not None and test.comp is not CompareFunction.Always:
            p = replace(p, alpha_test=True, alpha_test_comp=test.comp)
        # A PBS surface shader's lighting function premultiplies under alpha:premul (UnityPBSLighting.cginc).
        premultiplied = analysis.premultiplied or (block.surface is not None and block.surface.premultiplied)
        if analysis.has_program and premultiplied:
            folded = _fold_premultiplied(p)
            if folded is None:
                ctx.warn(block.head, f"pass {name!r} premultiplies its colour by alpha, which its Blend "
                                     f"{p.src_blend} {p.dst_blend} cannot take over: drawn without (approximated)")
            elif folded is not p:
                ctx.warn(block.head, f"pass {name!r} premultiplies its colour by alpha in the shader: Blend "
                                     f"{p.src_blend} {p.dst_blend} imported as Blend SrcAlpha {p.dst_blend}, "
                                     f"{p.src_blend} {p.dst_blend}, which draws the same")
                p = folded
        excluded = None
        if item.draws_nothing:
            excluded = "ZTest Never: no fragment passes the depth test"
            if p.stencil and p.stencil_zfail is not StencilOp.Keep:
                ctx.warn(block.head, f"pass {name!r}: ZTest Never with a Stencil ZFail operation writes stencil "
                                     "only; not drawn here")
        elif light_mode_text is not None and light_mode_text.strip().lower() in ctx.disabled:
            excluded = f"disabled by the material (disabledShaderPasses: {light_mode_text})"
        required = next((v for k, v in block.tags.items() if k.lower() == "requireoption"), None)
        if required is not None:
            ctx.warn(block.head, f"pass {name!r} draws only with the Quality option {required} on: assumed on "
                                 "(Unity's higher default quality levels)")
        if light_mode is LightMode.Other:
            ctx.warn(block.head, f"pass {name!r}: LightMode {light_mode_text!r} is not a pass of the built-in "
                                 "forward path: never drawn")
        own.append(_PassInfo(p, excluded, light_mode_text, dict(block.tags), lit, lit_note, color, scale,
                             vertex_color, test, block.head))
    out: list[_PassInfo] = []
    written_infos = iter(own)
    for item in resolved.items:
        if isinstance(item, UsePass):
            out += _use_pass(ctx, item, values, depth, shader.name, own)
        else:
            out.append(next(written_infos))
    return out


def _use_pass(ctx: _Context, use: UsePass, values: MaterialValues, depth: int, own_name: str,
              own: list[_PassInfo]) -> list[_PassInfo]:
    """The passes ``UsePass "Shader/NAME"`` inserts — of this shader (``own_name``: its written
    passes ``own``) or another on the search path; warned when the shader or pass is not found."""
    shader_name, _, pass_name = use.path.rpartition("/")
    if shader_name in (own_name, own_name.removeprefix("Legacy Shaders/")):
        return _named(ctx, use, shader_name, pass_name, own)
    path = ctx.search.shader_path(shader_name) if shader_name else None
    if path is None:
        ctx.warn(use.head, f'UsePass "{use.path}": no shader named {shader_name!r} on the search path '
                           f"({ctx.search.describe()}); not imported")
        return []
    if depth >= MAX_INDIRECTION or str(Path(path).resolve()) in ctx.within:
        ctx.warn(use.head, f'UsePass "{use.path}": {path} uses itself (or UsePass/Fallback nest more than '
                           f"{MAX_INDIRECTION} deep); not imported")
        return []
    try:
        other = _import_file(ctx, path, values, depth + 1)
    except (ShaderLabError, OSError, UnicodeDecodeError) as exc:
        ctx.warn(use.head, f'UsePass "{use.path}": {path}: {_reason(exc)}; not imported')
        return []
    return _named(ctx, use, shader_name, pass_name, other.passes)


def _named(ctx: _Context, use: UsePass, shader_name: str, pass_name: str, passes: list[_PassInfo]) -> list[_PassInfo]:
    """The passes of ``passes`` named ``pass_name`` (upper-cased, as Unity names them), placed at ``use``."""
    found = [info for info in passes if info.pass_.name.upper() == pass_name.upper()]
    if not found:
        names = ", ".join(repr(i.pass_.name.upper()) for i in passes) or "none"
        ctx.warn(use.head, f'UsePass "{use.path}": {shader_name} has no pass named {pass_name!r} (its passes: '
                           f"{names}); not imported")
    elif len(found) > 1:
        ctx.warn(use.head, f'UsePass "{use.path}": {len(found)} passes have that name; all are inserted, as the '
                           "2019.4 manual says (later manuals: the last one)")
    return [replace(info, head=use.head) for info in found]


def _reason(exc: Exception) -> str:
    """Why another file did not import, in one line."""
    if isinstance(exc, ShaderLabError):
        return str(exc)
    if isinstance(exc, UnicodeDecodeError):
        return f"not UTF-8 text ({exc.reason})"
    return str(getattr(exc, "strerror", None) or exc)


def _import_file(ctx: _Context, path: str, values: MaterialValues, depth: int) -> _Imported:
    """Another shader file (UsePass, Fallback) imported with this material's ``values``; its
    warnings are not this file's (positions elsewhere), so they are left out."""
    with open(path, encoding="utf-8-sig") as fh:
        text = fh.read()
    inner = _Context(path, ctx.search, values, ctx.keywords, tuple(ctx.disabled), ctx.within)
    return _import(inner, text, depth)


def _import(ctx: _Context, text: str, depth: int = 0) -> _Imported:
    own_values = ctx.values
    shader, parse_warnings = _parse(text, ctx.filename, own_values)
    ctx.warnings += parse_warnings
    values = _merged(_defaults(shader.properties), own_values)
    if shader.subshader_count == 0 and shader.fallback not in (None, "Off"):
        fallback = _fallback(ctx, shader, values, depth)
        if fallback is not None:
            return fallback
    subshader = _first_subshader(shader)
    if subshader is not None:
        ctx.warnings += expand_surface_programs(shader, subshader)
    resolved = resolve(shader, own_values)  # the defaults through the declarations, bound in text order
    ctx.warnings += resolved.warnings
    passes = _pass_infos(ctx, shader, resolved, values, depth)
    return _Imported(shader, resolved, passes, resolved.tags, resolved.queue_token)


def _fallback(ctx: _Context, shader: ShaderBlock, values: MaterialValues, depth: int) -> _Imported | None:
    """A shader without a SubShader draws with its Fallback's first SubShader (Unity: "if no
    subshader can run, try the fallback shader"), with this material's values."""
    path = ctx.search.shader_path(shader.fallback)
    if path is None or depth >= MAX_INDIRECTION or str(Path(path).resolve()) in ctx.within:
        ctx.warn(shader.head, f'no SubShader, and the Fallback "{shader.fallback}" is not on the search path '
                              f"({ctx.search.describe()}); the material gets one default pass")
        return None
    try:
        other = _import_file(ctx, path, values, depth + 1)
    except (ShaderLabError, OSError, UnicodeDecodeError) as exc:
        ctx.warn(shader.head, f'no SubShader, and the Fallback "{shader.fallback}" does not import ({path}: '
                              f"{_reason(exc)}); the material gets one default pass")
        return None
    ctx.warn(shader.head, f'no SubShader: drawn with the Fallback "{shader.fallback}" ({path}), as Unity does')
    return _Imported(shader, other.resolved, [replace(i, head=shader.head) for i in other.passes], other.tags,
                     None)


def _main_texture_name(props: dict[str, Property]) -> str | None:
    prop = next((p for p in props.values() if any(a.lower() == "maintexture" for a in p.attributes)),
                props.get("_MainTex"))
    return prop.name if prop is not None else None


def parse_shaderlab(text: str, filename: str = "<string>", *, search: AssetSearch | None = None,
                    values: MaterialValues | None = None, keywords: frozenset[str] | None = None,
                    disabled_passes: tuple[str, ...] = (), material_name: str | None = None,
                    custom_render_queue: int = -1) -> ShaderLabResult:
    """Parse ShaderLab source; raise :class:`ShaderLabError` on malformed input.

    ``search``: where UsePass and Fallback shaders are found (default: none); ``values``,
    ``keywords``, ``disabled_passes``, ``material_name`` and ``custom_render_queue``: a ``.mat``
    file's (:func:`.project.import_material_file` passes them)."""
    ctx = _Context(filename, search or AssetSearch(()), values, keywords, disabled_passes)
    imported = _import(ctx, text)
    return _result(ctx, imported, material_name, custom_render_queue)


def _result(ctx: _Context, imported: _Imported, material_name: str | None, custom_queue: int) -> ShaderLabResult:
    shader = imported.shader
    props = shader.properties
    values = _merged(_defaults(props), ctx.values)

    def error(at: Positioned, message: str) -> ShaderLabError:
        return ShaderLabError(message, at.line, at.column, ctx.filename)

    material: dict[str, Any] = {}  # Material fields the file states; the others keep their defaults
    tags = imported.tags
    queue_value = next((v for k, v in tags.items() if k.lower() == "queue"), None)
    if custom_queue != -1:
        material["queue"], material["queue_offset"] = parse_queue(str(custom_queue))
    elif queue_value is not None:
        try:
            material["queue"], material["queue_offset"] = parse_queue(queue_value)
        except ValueError as exc:
            raise error(imported.queue_token or shader.head, str(exc)) from None

    color_prop = next((p for p in props.values() if any(a.lower() == "maincolor" for a in p.attributes)),
                      props.get("_Color"))
    if color_prop is not None:
        if not isinstance(color_prop.default, tuple):
            raise error(color_prop.token, f"{color_prop.name} must be a Color property")
        material["color"] = tuple(float(c) for c in values.colors.get(color_prop.name, color_prop.default))
    tex_name = _main_texture_name(props)
    main_tex_default = None
    if tex_name is not None:
        main_tex_default = str(props[tex_name].default)
        if main_tex_default.lower() != "white" and ctx.values is None:
            ctx.warn(props[tex_name].token, f'{tex_name} default "{main_tex_default}" imported as no texture '
                                            "(white); assign an image to match it")
    for prop_name, key in (("_AlphaScale", "alpha_scale"), ("_Cutoff", "cutoff")):
        prop = props.get(prop_name)
        if prop is not None:
            if not isinstance(prop.default, float):
                raise error(prop.token, f"{prop_name} must be a Float or Range property")
            material[key] = float(values.floats.get(prop_name, prop.default))
    if "_TintColor" in props or "_TintColor" in values.colors:
        material["tint_color"] = tuple(float(c) for c in values.colors.get("_TintColor", (0.5, 0.5, 0.5, 0.5)))

    infos = imported.passes
    kept = [i for i in infos if i.excluded is None]
    kept_passes = tuple(i.pass_ for i in kept)
    drawn = [i for i in kept if pass_draws(i.pass_, kept_passes)[0] != "never"]
    # The material's one shading is that of the first pass that draws colour (else of one that would).
    candidates = ([i for i in drawn if i.pass_.color_mask] or [i for i in kept if i.pass_.color_mask] or drawn
                  or kept)
    main = candidates[0] if candidates else None
    cutoff_property = "_Cutoff" if "_Cutoff" in props else None
    if main is not None:
        material["lighting"] = Lighting.Lambert if main.lit else Lighting.Unlit
        if main.lit_approximation:
            ctx.warn(main.head, f"{main.lit_approximation} is drawn as Lambert of the albedo (the lit colour is "
                                "approximated; order, coverage and blending are exact)")
        material["vertex_color"] = main.vertex_color
        if main.color is not None:
            base = main.color
            material["color"] = tuple(c * main.scale for c in base[:3]) + (base[3],)
        for other in (i for i in drawn if i.pass_.color_mask):
            if (other.lit, other.vertex_color, other.color, other.scale) != (main.lit, main.vertex_color, main.color,
                                                                           main.scale):
                ctx.warn(other.head, f"pass {other.pass_.name!r} shades differently from pass {main.pass_.name!r}; "
                                     "the material has one shading, pass "
                                     f"{main.pass_.name!r}'s")
                break
    else:
        material["lighting"] = Lighting.Unlit
    # The passes whose alpha test reads a cutoff (Never and clip(-1) read none).
    tested = [i for i in (drawn or kept) if i.alpha_test is not None and i.pass_.alpha_test
              and i.alpha_test.comp is not CompareFunction.Never]
    if tested:
        test = tested[0].alpha_test
        if test.cutoff_property is not None and test.cutoff_property != "_Cutoff":
            prop = props.get(test.cutoff_property)
            value = values.floats.get(test.cutoff_property, prop.default if prop is not None else None)
            if isinstance(value, float):
                material["cutoff"] = value
                cutoff_property = test.cutoff_property
                ctx.warn(prop.token if prop is not None else shader.head,
                         f"the alpha test compares with {test.cutoff_property}; imported as the cutoff ({value:g})")
        elif test.cutoff_value is not None:
            material["cutoff"] = test.cutoff_value
            cutoff_property = None
            ctx.warn(tested[0].head, f"the alpha test compares with the constant {test.cutoff_value:g}; imported as "
                                     "the cutoff")
        if test.offset:
            material["cutoff"] = float(material.get("cutoff", 0.5)) - test.offset
            ctx.warn(tested[0].head, f"the alpha test keeps alpha >= _Cutoff - {test.offset:g}; imported as the "
                                     "cutoff")
        for other in tested[1:]:
            if (other.alpha_test.cutoff_property, other.alpha_test.cutoff_value) != (
                    test.cutoff_property, test.cutoff_value):
                ctx.warn(other.head, f"pass {other.pass_.name!r} tests alpha against another cutoff; the material "
                                     "has one cutoff")
                break

    if main is None and shader.subshader_count == 0 and not infos:
        ctx.warn(shader.head, "no SubShader; the material gets one default pass")
    elif main is None and kept == [] and infos:
        ctx.warn(shader.head, "no pass of the shader draws; the material draws nothing of it")

    _constant_color(ctx, shader, imported, material, color_prop, tex_name)

    warnings = WarningList()
    seen = set()
    for w in sorted(ctx.warnings, key=lambda w: (w.line, w.column)):
        if str(w) not in seen:
            seen.add(str(w))
            warnings.append(str(w))
    extra = {
        "shader": shader.name,
        "render_type": next((v for k, v in tags.items() if k.lower() == "rendertype"), None),
        "ignore_projector": _bool_tag(next((v for k, v in tags.items() if k.lower() == "ignoreprojector"), None)),
        "light_modes": [i.light_mode_text for i in infos],
        "use_pass": list(imported.resolved.use_passes),
        "fallback": shader.fallback,
        "subshader_tags": dict(tags),
        "pass_tags": [i.tags for i in infos],
        "subshader_count": shader.subshader_count,
        "main_tex_default": main_tex_default,
        "main_tex_property": tex_name,
        "cutoff_property": cutoff_property,
        "keywords": sorted(ctx.keywords if ctx.keywords is not None
                           else _default_keywords(props, values) & _declared(imported)),
        "properties": [
            {"name": p.name, "display": p.display, "type": p.type,
             "default": list(p.default) if isinstance(p.default, tuple) else p.default,
             "attributes": list(p.attributes)}
            for p in props.values()
        ],
    }
    name = material_name if material_name is not None else shader.name
    listed = tuple((i.pass_, i.excluded) for i in infos)
    result_material = Material(name=name, **material, passes=kept_passes)
    return ShaderLabResult(result_material, tuple(warnings), extra, listed)


def _declared(imported: _Imported) -> frozenset[str]:
    code = "\n".join(imported.shader.includes + [t for s in imported.resolved.passes for t in s.block.programs])
    return frozenset(k for _, words in keyword_sets(code) for k in words)


def _constant_color(ctx: _Context, shader: ShaderBlock, imported: _Imported, material: dict[str, Any],
                    color_prop: Property | None, tex_name: str | None) -> None:
    """An unlit program without _Color/_MainTex that returns one constant colour: that colour is _Color."""
    programs = ShaderPrograms(shader.includes, [s.block.programs for s in imported.resolved.passes])
    if (material.get("lighting") is not Lighting.Unlit or color_prop is not None or tex_name is not None
            or programs.reads_color_or_texture()):
        return
    constants = programs.constant_colors()
    if len(constants) == 1:
        constant_color = constants.pop()
        material["color"] = constant_color
        ctx.warn(shader.head, f"the fragment program returns the constant colour {constant_color}; imported as _Color")
    elif len(constants) > 1:
        ctx.warn(shader.head, f"the passes return different constant colours {sorted(constants)}; "
                              "one _Color cannot hold them, _Color stays white")


def _bool_tag(value: str | None) -> bool | None:
    if value is None:
        return None
    return value.strip().lower() == "true"


def parse_shaderlab_file(path: str, search_folders: tuple[str, ...] = ()) -> ShaderLabResult:
    """Read and parse a ``.shader`` file (UTF-8, BOM allowed); OSError/ShaderLabError on failure.
    UsePass and Fallback shaders are found in the file's folder and ``search_folders`` (recursively)."""
    with open(path, encoding="utf-8-sig") as fh:
        text = fh.read()
    search = AssetSearch([Path(path).parent, *search_folders])
    return parse_shaderlab(text, filename=str(path), search=search)
