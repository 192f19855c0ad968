"""Import: ShaderLab text → :class:`ShaderLabResult`, the typed material with warnings and extras.

:func:`parse_shaderlab` runs the steps of the package in order — :mod:`.parser` (the tree),
:mod:`.state` (values and inheritance), :mod:`.programs` (what the CG says) — and builds the
:class:`~blendlib.core.vocabulary.Material`: the queue from the ``Queue`` tag, ``_Color`` /
``_MainTex`` / ``_Cutoff`` / ``_AlphaScale`` from the property defaults (``[MainColor]`` /
``[MainTexture]`` attributes name other properties), lighting from the programs, one
:class:`~blendlib.core.vocabulary.Pass` per ``Pass { }`` of the first SubShader.

The one error raised is the first of the text: when the parser stops at a syntax error, a bad
value read before it (``Blend SrcAlfa {``) is reported instead. Warnings are listed in the order
of the text, then the importer's own (about the properties and programs).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, fields
from typing import Any

from ...core.vocabulary import CHANNELS, Lighting, Material, Pass, pass_to_dict
from .diagnostics import Positioned, ShaderLabError, SourceWarning, WarningList
from .parser import Parser
from .programs import ShaderPrograms
from .state import check_values, parse_queue, resolve


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


def parse_shaderlab(text: str, filename: str = "<string>") -> ShaderLabResult:
    """Parse ShaderLab source; raise :class:`ShaderLabError` on malformed input."""
    parser = Parser(text, filename)
    try:
        shader = parser.parse()
    except ShaderLabError as exc:
        syntax_error = exc
    else:
        syntax_error = None
    if syntax_error is not None:
        if parser.shader is not None:
            check_values(parser.shader)  # raises a bad value that stands before the syntax error
        raise syntax_error
    resolved = resolve(shader)
    head = shader.head
    props = shader.properties
    warnings = WarningList()
    for w in sorted([*parser.warnings, *resolved.warnings], key=lambda w: (w.line, w.column)):
        warnings.append(str(w))

    def warn(at: Positioned, message: str) -> None:
        warnings.append(str(SourceWarning.at(at, message)))

    def error(at: Positioned, message: str) -> ShaderLabError:
        return ShaderLabError(message, at.line, at.column, filename)

    material: dict[str, Any] = {}  # Material fields the file states; the others keep their defaults

    # Queue.
    tags = resolved.tags
    queue_value = next((v for k, v in tags.items() if k.lower() == "queue"), None)
    if queue_value is not None:
        try:
            material["queue"], material["queue_offset"] = parse_queue(queue_value)
        except ValueError as exc:
            raise error(resolved.queue_token or head, str(exc)) from None

    # Property defaults.
    color_prop = next((p for p in props.values() if any(a.lower() == "maincolor" for a in p.attributes)),
                      props.get("_Color"))
    if color_prop is not None:
        if not isinstance(color_prop.default, tuple):
            raise error(color_prop.token, f"{color_prop.name} must be a Color property")
        material["color"] = tuple(float(c) for c in color_prop.default)
    tex_prop = next((p for p in props.values() if any(a.lower() == "maintexture" for a in p.attributes)),
                    props.get("_MainTex"))
    main_tex_default = None
    if tex_prop is not None:
        main_tex_default = str(tex_prop.default)
        if main_tex_default.lower() != "white":
            warn(tex_prop.token, f'{tex_prop.name} default "{main_tex_default}" imported as no texture (white); '
                                 "assign an image to match it")
    for prop_name, key in (("_AlphaScale", "alpha_scale"), ("_Cutoff", "cutoff")):
        prop = props.get(prop_name)
        if prop is not None:
            if not isinstance(prop.default, float):
                raise error(prop.token, f"{prop_name} must be a Float or Range property")
            material[key] = prop.default

    # Programs.
    programs = ShaderPrograms(shader.includes, [p.block.programs for p in resolved.passes])
    material["lighting"] = Lighting.Lambert if programs.reads_main_light() else Lighting.Unlit

    cutoff_property = "_Cutoff" if "_Cutoff" in props else None
    clip_props = programs.clip_properties()
    if clip_props and "_Cutoff" not in clip_props:
        used = sorted(clip_props)
        prop = props.get(used[0])
        if prop is not None and isinstance(prop.default, float):
            material["cutoff"] = prop.default
            cutoff_property = prop.name
            warn(prop.token, f"clip() compares with {prop.name}; imported as the cutoff ({prop.default:g})")

    # An unlit program without _Color/_MainTex that returns one constant colour: that colour is _Color.
    if (material["lighting"] is Lighting.Unlit and color_prop is None and tex_prop is None
            and not programs.reads_color_or_texture()):
        constants = programs.constant_colors()
        if len(constants) == 1:
            constant_color = constants.pop()
            material["color"] = constant_color
            warn(head, f"the fragment program returns the constant colour {constant_color}; imported as _Color")
        elif len(constants) > 1:
            warn(head, f"the passes return different constant colours {sorted(constants)}; "
                       "one _Color cannot hold them, _Color stays white")

    passes: list[Pass] = []
    light_modes: list[str | None] = []
    pass_tags: list[dict[str, str]] = []
    for index, pass_state in enumerate(resolved.passes):
        block = pass_state.block
        name = block.name
        if name is None:
            name = "Pass" if len(resolved.passes) == 1 else f"Pass {index + 1}"
        if programs.pass_discards(index):
            warn(block.head, f"pass {name!r} discards fragments with its own condition; "
                             "only clip(alpha - cutoff) is imported")
        passes.append(Pass(name=name, alpha_test=programs.pass_clips(index), **pass_state.pass_fields()))
        light_modes.append(next((v for k, v in block.tags.items() if k.lower() == "lightmode"), None))
        pass_tags.append(dict(block.tags))
    for light_mode, pass_state in zip(light_modes, resolved.passes, strict=True):
        if light_mode is not None and light_mode.lower() not in ("forwardbase", "always"):
            warn(pass_state.block.head, f"LightMode {light_mode!r} is imported as ForwardBase")
    if shader.subshader_count == 0:
        warn(head, "no SubShader; the material gets one default pass")

    extra = {
        "render_type": next((v for k, v in tags.items() if k.lower() == "rendertype"), None),
        "ignore_projector": _bool_tag(next((v for k, v in tags.items() if k.lower() == "ignoreprojector"), None)),
        "light_modes": light_modes,
        "use_pass": list(resolved.use_passes),
        "fallback": shader.fallback,
        "subshader_tags": dict(tags),
        "pass_tags": pass_tags,
        "subshader_count": shader.subshader_count,
        "main_tex_default": main_tex_default,
        "cutoff_property": cutoff_property,
        "properties": [
            {"name": p.name, "display": p.display, "type": p.type,
             "default": list(p.default) if isinstance(p.default, tuple) else p.default,
             "attributes": list(p.attributes)}
            for p in props.values()
        ],
    }
    return ShaderLabResult(Material(name=shader.name, **material, passes=tuple(passes)), tuple(warnings), extra)


def _bool_tag(value: str | None) -> bool | None:
    if value is None:
        return None
    return value.strip().lower() == "true"


def parse_shaderlab_file(path: str) -> ShaderLabResult:
    """Read and parse a ``.shader`` file (UTF-8, BOM allowed); OSError/ShaderLabError on failure."""
    with open(path, encoding="utf-8-sig") as fh:
        text = fh.read()
    return parse_shaderlab(text, filename=str(path))
