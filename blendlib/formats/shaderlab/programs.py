"""What the CG/HLSL programs of a shader tell the importer, read from their text (not compiled).

The programs (``CGPROGRAM`` … ``ENDCG`` and the like, kept as text by the parser) decide things the
ShaderLab commands do not state. Comments are removed first (a commented-out ``clip(`` does
nothing); then, per pass, the branches of ``#if``/``#ifdef`` on the keywords the programs declare
(``#pragma multi_compile`` / ``shader_feature``, :func:`keyword_sets`) are taken as the material's
keywords choose them (:func:`active_code`), so ``#ifdef UNITY_UI_ALPHACLIP clip(…)`` clips only with
that keyword on. :func:`analyze_pass` then reads, per pass (:class:`PassProgram`):

* the alpha test: ``clip(x - _Prop)`` (the book's, ``GEqual`` at ``_Prop``), ``clip(-(x - _Prop))``
  and ``clip(_Prop - x)`` (``LEqual``), ``clip(x - 0.001)``
  (a constant cutoff), ``clip(-1)`` (``Never``) and ``if (!(x OP _Prop)) discard;`` (the exporter's
  form of the other comparisons);
* vertex colours (``i.color``: :class:`~blendlib.core.vocabulary.VertexColor`): the legacy
  particles' ``2.0f * i.color * _TintColor * tex2D(…)`` is ``Particle``, ``tex2D(…) * i.color``
  and ``OUT.color = v.color * _Color`` are ``Multiply``; any other use of ``i.color`` is the
  nearest of the two, and listed (``vertex_color_exact`` False);
* premultiplied output (``c.rgb *= c.a``), which the importer folds into the blend state;
* the functions of Unity's own include files a pass calls, whose text is not in the shader
  (:data:`KNOWN_ENTRY_POINTS`: the Standard shader's ``FragmentSetup``, ``SpriteFrag``, the
  Standard particles), as those files' 2019.4 source states them;
* ``_LightColor0`` (a lit program: Lambert here), one constant colour an unlit program returns,
  ``discard`` under a condition of its own.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from ...core.vocabulary import CompareFunction, VertexColor

_CG_COMMENT_RE = re.compile(r"//[^\n]*|/\*.*?\*/", re.DOTALL)
_CLIP_CALL_RE = re.compile(r"\bclip\s*\(")
_CLIP_PROP_RE = re.compile(r"\bclip\s*\(([^;]*?)-\s*(_[A-Za-z0-9_]+)\s*(\+\s*([0-9.]+)f?\s*)?\)\s*;")
# clip(-(x - _Prop)) and clip(_Prop - x): the fragment survives when x <= _Prop.
_CLIP_BELOW_RE = re.compile(r"\bclip\s*\(\s*-\s*\(\s*[^;()]*?-\s*(_[A-Za-z0-9_]+)\s*\)\s*\)\s*;"
                            r"|\bclip\s*\(\s*(_[A-Za-z0-9_]+)\s*-[^;]*\)\s*;")
_CLIP_CONST_RE = re.compile(r"\bclip\s*\(([^;]*?)-\s*(\d*\.\d+|\d+\.?)[fh]?\s*\)\s*;")
_CLIP_NEVER_RE = re.compile(r"\bclip\s*\(\s*-\s*(\d*\.\d+|\d+\.?)[fh]?\s*\)\s*;")
_DISCARD_TEST_RE = re.compile(
    r"\bif\s*\(\s*!\s*\(\s*[^;()]*?\s*(>=|<=|==|!=|>|<)\s*(_[A-Za-z0-9_]+)\s*\)\s*\)\s*discard\s*;")
_DISCARD_RE = re.compile(r"\bdiscard\b")
# One literal component: a CG float literal (optional f/h suffix). Expressions such as 1-0.5 do not match.
_CG_LITERAL = r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)[fFhH]?"
_RETURN_CONST_RE = re.compile(
    r"\breturn\s+(?:float|half|fixed)4\s*\(\s*" + r"\s*,\s*".join([_CG_LITERAL] * 4) + r"\s*\)\s*;"
)
#: Unity's shortcut keyword pragmas that declare keywords the importer reads (others declare none it does).
_SHORTCUT_KEYWORDS = {"multi_compile_particles": ("_", "SOFTPARTICLES_ON"),
                      "multi_compile_fog": ("_", "FOG_LINEAR", "FOG_EXP", "FOG_EXP2"),
                      "multi_compile_instancing": ("_", "INSTANCING_ON")}
_SHORTCUT_RE = re.compile(r"^[ \t]*#[ \t]*pragma[ \t]+(multi_compile_\w+)", re.M)
_KEYWORD_PRAGMA_RE = re.compile(r"^[ \t]*#[ \t]*pragma[ \t]+(multi_compile|shader_feature)(_local)?"
                                r"(?:_vertex|_fragment|_geometry|_hull|_domain|_raytracing)?[ \t]+([^\n]*)$", re.M)
_DIRECTIVE_RE = re.compile(r"^[ \t]*#[ \t]*(if|ifdef|ifndef|elif|else|endif)\b([^\n]*)$", re.M)
_INCLUDE_RE = re.compile(r'#[ \t]*include[ \t]+"([^"]+)"')
_FRAGMENT_RE = re.compile(r"#[ \t]*pragma[ \t]+fragment[ \t]+(\w+)")
_COLOR_FIELD_RE = re.compile(r"\b(\w+)\s*:\s*COLOR0?\b")
_STRUCT_RE = re.compile(r"\bstruct\s+(\w+)\s*\{([^}]*)\}")
_INPUT_POSITION_RE = re.compile(r":\s*POSITION\b")
_PREMULTIPLY_RE = re.compile(r"\b(\w+)\.rgb\s*\*=\s*\1\.a\s*;")
_CONSTANT_LERP_RE = re.compile(r"\blerp\s*\(\s*(?:fixed|half|float)[34]\s*\(")
_COMPARISON_BY_OPERATOR = {">": CompareFunction.Greater, ">=": CompareFunction.GEqual, "<": CompareFunction.Less,
                           "<=": CompareFunction.LEqual, "==": CompareFunction.Equal, "!=": CompareFunction.NotEqual}


def strip_comments(code: str) -> str:
    """``code`` with its ``//`` and ``/* */`` comments replaced by a space."""
    return _CG_COMMENT_RE.sub(" ", code)


# --------------------------------------------------------------------------- keywords


def keyword_sets(code: str) -> list[tuple[str, tuple[str, ...]]]:
    """The keyword sets the programs declare: ``(directive, keywords)`` per ``#pragma multi_compile``
    or ``shader_feature`` line (``_`` and ``__`` stand for "none of them")."""
    sets = [(m.group(1), tuple(m.group(3).split())) for m in _KEYWORD_PRAGMA_RE.finditer(code)]
    sets += [("multi_compile", _SHORTCUT_KEYWORDS[m.group(1)]) for m in _SHORTCUT_RE.finditer(code)
             if m.group(1) in _SHORTCUT_KEYWORDS]
    return sets


def declared_keywords(sets: list[tuple[str, tuple[str, ...]]]) -> frozenset[str]:
    return frozenset(k for _, words in sets for k in words if k.strip("_"))


def keywords_in_effect(sets: list[tuple[str, tuple[str, ...]]], enabled: frozenset[str]) -> frozenset[str]:
    """The declared keywords that are on: those of ``enabled``, and in each set none of whose
    keywords is enabled, its first one — the variant Unity uses then — unless that is ``_`` or
    ``__`` or the set is a ``shader_feature`` of one keyword (which means ``_ KEYWORD``)."""
    on = set()
    for directive, words in sets:
        chosen = [k for k in words if k in enabled]
        if chosen:
            on.update(chosen)
        elif words and words[0].strip("_") and not (directive == "shader_feature" and len(words) == 1):
            on.add(words[0])
    return frozenset(on)


def active_code(code: str, declared: frozenset[str], on: frozenset[str]) -> str:
    """``code`` without the ``#if`` branches that the keywords ``on`` rule out.

    A condition is decided only when it names declared keywords alone (``KW``, ``defined(KW)``,
    ``!``, ``&&``, ``||``, parentheses); any other condition keeps all its branches, as if the
    compiler might take either (the importer then reads both)."""
    out: list[str] = []
    # Stack of (keep this branch, a branch of this #if was taken, decided).
    stack: list[tuple[bool, bool, bool]] = []
    pos = 0
    for m in _DIRECTIVE_RE.finditer(code):
        if all(keep for keep, _, _ in stack):
            out.append(code[pos:m.start()])
        pos = m.end()
        word, rest = m.group(1), m.group(2).strip()
        if word in ("if", "ifdef", "ifndef"):
            if word == "ifdef":
                value = _condition(f"defined({rest.split()[0] if rest else ''})", declared, on)
            elif word == "ifndef":
                value = _condition(f"!defined({rest.split()[0] if rest else ''})", declared, on)
            else:
                value = _condition(rest, declared, on)
            stack.append((value is not False, value is True, value is not None))
        elif word == "elif" and stack:
            _, taken, decided = stack.pop()
            value = _condition(rest, declared, on)
            if decided and value is not None:
                stack.append((not taken and value, taken or value, True))
            else:
                stack.append((not taken, taken, False))
        elif word == "else" and stack:
            _, taken, decided = stack.pop()
            stack.append((not (decided and taken), True, decided))
        elif word == "endif" and stack:
            stack.pop()
    if all(keep for keep, _, _ in stack):
        out.append(code[pos:])
    return "\n".join(out)


_CONDITION_TOKEN_RE = re.compile(r"\s*(defined|\|\||&&|!|\(|\)|[A-Za-z_]\w*|\S)")


def _condition(text: str, declared: frozenset[str], on: frozenset[str]) -> bool | None:
    """The value of a preprocessor condition over declared keywords; None when it names anything
    else or is not well formed. Grammar: ``or := and ('||' and)*``, ``and := unary ('&&' unary)*``,
    ``unary := '!' unary | '(' or ')' | 'defined' ['('] NAME [')'] | NAME``."""
    tokens = _CONDITION_TOKEN_RE.findall(text)
    pos = 0

    class Undecided(Exception):
        pass

    def peek() -> str | None:
        return tokens[pos] if pos < len(tokens) else None

    def take(expected: str | None = None) -> str:
        nonlocal pos
        tok = peek()
        if tok is None or (expected is not None and tok != expected):
            raise Undecided
        pos += 1
        return tok

    def keyword(name: str) -> bool:
        if name not in declared:
            raise Undecided
        return name in on

    def unary() -> bool:
        tok = take()
        if tok == "!":
            return not unary()
        if tok == "(":
            value = either()
            take(")")
            return value
        if tok == "defined":
            if peek() == "(":
                take("(")
                value = keyword(take())
                take(")")
                return value
            return keyword(take())
        return keyword(tok)

    def both() -> bool:
        value = unary()
        while peek() == "&&":
            take()
            value = unary() and value  # evaluated first: an undecidable operand stays undecided
        return value

    def either() -> bool:
        value = both()
        while peek() == "||":
            take()
            value = both() or value
        return value

    try:
        value = either()
        return value if pos == len(tokens) else None
    except Undecided:
        return None


# --------------------------------------------------------------------------- Unity's include files


@dataclass(frozen=True)
class EntryPoint:
    """What a function of one of Unity's include files does, per its 2019.4 source."""

    source: str  # the file and function, for messages and docs
    clip: tuple[str, str] | None = None  # (keyword, cutoff property) of its alpha test under that keyword
    clip_offset: float = 0.0  # clip(alpha - _Cutoff + offset)
    premultiply: str | None = None  # the keyword under which it premultiplies, "" = always
    vertex_color: VertexColor = VertexColor.Off
    lit: str = ""  # the lighting it computes (drawn as Lambert here, warned); "" = unlit
    notes: tuple[tuple[str, str], ...] = ()  # (keyword, what it does that is not drawn here)


#: Functions of Unity's include files that decide the alpha test, premultiplication or vertex
#: colours, keyed by (include file, function). Sources: Unity's built-in shader source 2019.4,
#: ``CGIncludes/`` (the same download as ``shared/corpus/unity-builtin-shaders-2019.4``).
KNOWN_ENTRY_POINTS: dict[tuple[str, str], EntryPoint] = {
    # UnityStandardCore.cginc FragmentSetup: "#if defined(_ALPHATEST_ON) clip (alpha - _Cutoff);" and
    # "o.diffColor = PreMultiplyAlpha (o.diffColor, alpha, ...)" (UnityStandardUtils.cginc: diffColor *=
    # alpha under _ALPHAPREMULTIPLY_ON, and the output alpha raised by the reflectivity).
    ("UnityStandardCoreForward.cginc", ""): EntryPoint(
        "UnityStandardCore.cginc FragmentSetup", clip=("_ALPHATEST_ON", "_Cutoff"), premultiply="_ALPHAPREMULTIPLY_ON",
        lit="the Standard shader's physically based lighting",
        notes=(("_ALPHAPREMULTIPLY_ON", "the Standard shader's Transparent mode raises the output alpha by the "
                "reflectivity (1 - oneMinusReflectivity + alpha * oneMinusReflectivity, UnityStandardUtils.cginc "
                "PreMultiplyAlpha); imported with the material's alpha"),)),
    # UnitySprites.cginc: "fixed4 c = SampleSpriteTexture (IN.texcoord) * IN.color; c.rgb *= c.a;" with
    # "OUT.color = IN.color * _Color * _RendererColor;" in SpriteVert.
    ("UnitySprites.cginc", "SpriteFrag"): EntryPoint(
        "UnitySprites.cginc SpriteFrag", premultiply="", vertex_color=VertexColor.Multiply),
    # UnityStandardParticles.cginc fragParticleUnlit / surf: "albedo *= _Color; fragColorMode(IN);" (by
    # default "albedo *= i.color"), "#if defined(_ALPHATEST_ON) clip (albedo.a - _Cutoff + 0.0001);".
    ("UnityStandardParticles.cginc", ""): EntryPoint(
        "UnityStandardParticles.cginc fragParticleUnlit/surf", clip=("_ALPHATEST_ON", "_Cutoff"), clip_offset=0.0001,
        vertex_color=VertexColor.Multiply,
        notes=(("_ALPHAMODULATE_ON", "Modulate mode's lerp(1, albedo, albedo.a) is not drawn"),
               ("_COLOROVERLAY_ON", "the Overlay colour mode is drawn as Multiply"),
               ("_COLORCOLOR_ON", "the Color colour mode is drawn as Multiply"),
               ("_COLORADDSUBDIFF_ON", "the Additive/Subtractive/Difference colour modes are drawn as Multiply"))),
}


def entry_point(code: str) -> EntryPoint | None:
    """The known include function a pass's program runs (see :data:`KNOWN_ENTRY_POINTS`)."""
    includes = [name.rsplit("/", 1)[-1] for name in _INCLUDE_RE.findall(code)]
    fragment = _FRAGMENT_RE.search(code)
    for include in includes:
        for key in ((include, fragment.group(1) if fragment else ""), (include, "")):
            if key in KNOWN_ENTRY_POINTS:
                return KNOWN_ENTRY_POINTS[key]
    return None


# --------------------------------------------------------------------------- one pass


@dataclass(frozen=True)
class AlphaTest:
    """A pass's alpha test as its program states it: ``alpha <comp> cutoff``, the cutoff a
    property (``cutoff_property``) or a constant (``cutoff_value``), plus ``offset`` (a clip of
    ``alpha - _Cutoff + offset`` keeps alpha >= cutoff - offset)."""

    comp: CompareFunction
    cutoff_property: str | None = None
    cutoff_value: float | None = None
    offset: float = 0.0


@dataclass
class PassProgram:
    """What a pass's programs say (:func:`analyze_pass`); ``notes``: what they do that is not drawn."""

    has_program: bool = False
    alpha_test: AlphaTest | None = None
    premultiplied: bool = False
    vertex_color: VertexColor = VertexColor.Off
    vertex_color_exact: bool = True
    vertex_color_use: str = ""  # the statement that uses i.color, when approximated
    lit: bool = False
    lit_approximation: str = ""  # what lighting a known include computes (drawn as Lambert)
    discards_otherwise: bool = False
    notes: list[str] = field(default_factory=list)


_PARTICLE_FORMS = [re.compile(p) for p in (
    r"\w+=2\.0f?\*\w+\.color\*(_TintColor\*)?tex2D\(_MainTex,\w+\.\w+\)",
    r"\w+\.color=\w+\.color\*_TintColor",
)]
_MULTIPLY_FORMS = [re.compile(p) for p in (
    r"\w+=\w+\.color\*tex2D\(_MainTex,\w+\.\w+\)",
    r"\w+=tex2D\(_MainTex,\w+\.\w+\)\*\w+\.color",
    r"\w+=\(tex2D\(_MainTex,\w+\.\w+\)\+_TextureSampleAdd\)\*\w+\.color",  # UI: _TextureSampleAdd is 0 for RGBA
    r"\w+\.color=\w+\.color\*_Color",
)]
_TYPE_PREFIX_RE = re.compile(r"^(?:fixed|half|float)[234]?(?=\w)")


def _vertex_color_fields(code: str) -> set[str]:
    """The struct fields that hold the mesh's vertex colour: the ``: COLOR`` field of a vertex input
    struct (one with a ``: POSITION`` field, or a surface shader's ``Input``), and the fields a
    program copies it into (``o.color = v.color…``). A ``: COLOR`` interpolator of the vertex
    program's own output is not one."""
    fields = set()
    for m in _STRUCT_RE.finditer(code):
        if _INPUT_POSITION_RE.search(m.group(2)) or m.group(1) == "Input":  # Input: a surface shader's
            fields.update(_COLOR_FIELD_RE.findall(m.group(2)))
    if not fields:
        return fields
    source = "|".join(sorted(fields))
    fields.update(re.findall(r"\b\w+\.(\w+)\s*=\s*[^;]*\b\w+\.(?:" + source + r")\b", code))
    return fields


def _vertex_color(code: str) -> tuple[VertexColor, bool, str]:
    """(mode, exact, first statement not of a known form) of the program's use of the vertex colour."""
    fields = _vertex_color_fields(code)
    if not fields:
        return VertexColor.Off, True, ""
    use = re.compile(r"\b\w+\.(?:" + "|".join(sorted(fields)) + r")\b")
    uses = []
    for statement in code.split(";"):
        compact = "".join(statement.split())
        if not use.search(statement) or "*" not in statement:
            continue
        compact = _TYPE_PREFIX_RE.sub("", compact.rsplit("}", 1)[-1].rsplit("{", 1)[-1])
        uses.append(compact)
    if not uses:
        return VertexColor.Off, True, ""
    particle = any("_TintColor" in u for u in uses) and any(
        re.search(r"(?<![\w.])2(?:\.0*)?f?\*|\*2(?:\.0*)?f?(?![\w.])", u) for u in uses)
    forms = _PARTICLE_FORMS if particle else _MULTIPLY_FORMS
    odd = [u for u in uses if not any(f.fullmatch(u) for f in forms)]
    lerp = _CONSTANT_LERP_RE.search(code)
    if lerp and not odd:
        odd = [code[lerp.start():code.find(";", lerp.start())].strip()]
    return (VertexColor.Particle if particle else VertexColor.Multiply), not odd, odd[0] if odd else ""


def analyze_pass(programs: list[str], includes: str, enabled: frozenset[str]) -> PassProgram:
    """What pass programs ``programs`` (comments removed) say, with the shared ``includes`` text,
    under the material's ``enabled`` keywords (see the module docstring)."""
    out = PassProgram(has_program=bool(programs))
    if not programs:
        return out
    code = includes + "\n" + "\n".join(programs)
    sets = keyword_sets(code)
    declared = declared_keywords(sets)
    on = keywords_in_effect(sets, enabled)
    code = active_code(code, declared, on)
    out.lit = "_LightColor0" in code
    known = entry_point(code)
    out.alpha_test = _alpha_test(code)
    if known is not None:
        if known.clip is not None and known.clip[0] in on and out.alpha_test is None:
            out.alpha_test = AlphaTest(CompareFunction.GEqual, known.clip[1], offset=known.clip_offset)
        if known.premultiply is not None and (known.premultiply == "" or known.premultiply in on):
            out.premultiplied = True
        out.vertex_color = known.vertex_color
        if known.lit:
            out.lit, out.lit_approximation = True, f"{known.lit} ({known.source})"
        out.notes += [f"{note} ({known.source})" for keyword, note in known.notes if keyword in on]
    else:
        out.vertex_color, out.vertex_color_exact, out.vertex_color_use = _vertex_color(code)
    if _PREMULTIPLY_RE.search(code):
        out.premultiplied = True
    discards = _DISCARD_RE.findall(code)
    out.discards_otherwise = len(discards) > len(_DISCARD_TEST_RE.findall(code))
    return out


def _alpha_test(code: str) -> AlphaTest | None:
    """The program's alpha test (the first form found, in the order of the module docstring)."""
    m = _CLIP_BELOW_RE.search(code)
    if m:
        return AlphaTest(CompareFunction.LEqual, m.group(1) or m.group(2))
    m = _CLIP_PROP_RE.search(code)
    if m:
        return AlphaTest(CompareFunction.GEqual, m.group(2), offset=float(m.group(4) or 0.0))
    m = _CLIP_NEVER_RE.search(code)
    if m and float(m.group(1)) > 0:
        return AlphaTest(CompareFunction.Never)
    m = _CLIP_CONST_RE.search(code)
    if m and m.group(1).strip():
        return AlphaTest(CompareFunction.GEqual, cutoff_value=float(m.group(2)))
    m = _DISCARD_TEST_RE.search(code)
    if m:
        return AlphaTest(_COMPARISON_BY_OPERATOR[m.group(1)], m.group(2))
    if _CLIP_CALL_RE.search(code):
        return AlphaTest(CompareFunction.GEqual)  # clip(expression): the book's test at the material's cutoff
    return None


# --------------------------------------------------------------------------- the whole shader


class ShaderPrograms:
    """A shader's program texts without comments: the ``CGINCLUDE``-like texts shared by the passes
    (``includes``), each pass's programs (``passes``, one list per pass) and all of them (``all_code``)."""

    def __init__(self, includes: list[str], passes: list[list[str]]) -> None:
        self.includes = "\n".join(strip_comments(t) for t in includes)
        self.passes = [[strip_comments(t) for t in programs] for programs in passes]
        self.all_code = self.includes + "\n" + "\n".join(t for programs in self.passes for t in programs)

    def reads_color_or_texture(self) -> bool:
        """Whether any program names ``_Color`` or samples with ``tex2D``."""
        return "_Color" in self.all_code or "tex2D" in self.all_code

    def constant_colors(self) -> set[tuple[float, float, float, float]]:
        """The finite constant colours ``return float4(r, g, b, a);`` (or half4/fixed4) returns, in any program."""
        constants = {tuple(float(x) for x in m.groups()) for m in _RETURN_CONST_RE.finditer(self.all_code)}
        return {c for c in constants if all(math.isfinite(x) for x in c)}

    def keyword_sets(self) -> list[tuple[str, tuple[str, ...]]]:
        return keyword_sets(self.all_code)

    def analyze(self, index: int, enabled: frozenset[str]) -> PassProgram:
        """:func:`analyze_pass` of pass ``index``."""
        return analyze_pass(self.passes[index], self.includes, enabled)
