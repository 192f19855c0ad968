"""What the CG/HLSL programs of a shader tell the importer, read from their text (not compiled).

The programs (``CGPROGRAM`` … ``ENDCG`` and the like, kept as text by the parser) decide things the
ShaderLab commands do not state: ``clip(`` turns on a pass's alpha test (and ``clip(x - _Prop);``
names the cutoff property), ``_LightColor0`` means the shader is lit (Lambert here), an unlit
program returning one constant colour has that colour as its ``_Color``, ``discard`` is a
condition of its own. Comments are removed first: a commented-out ``clip(`` does nothing.
"""

from __future__ import annotations

import math
import re

_CG_COMMENT_RE = re.compile(r"//[^\n]*|/\*.*?\*/", re.DOTALL)
_CLIP_RE = re.compile(r"\bclip\s*\(")
_CLIP_PROP_RE = re.compile(r"\bclip\s*\(([^;]*?)-\s*(_[A-Za-z0-9_]+)\s*\)\s*;")
_DISCARD_RE = re.compile(r"\bdiscard\b")
# One literal component: a CG float literal (optional f/h suffix). Expressions such as 1-0.5 do not match.
_CG_LITERAL = r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)[fFhH]?"
_RETURN_CONST_RE = re.compile(
    r"\breturn\s+(?:float|half|fixed)4\s*\(\s*" + r"\s*,\s*".join([_CG_LITERAL] * 4) + r"\s*\)\s*;"
)


def strip_comments(code: str) -> str:
    """``code`` with its ``//`` and ``/* */`` comments replaced by a space."""
    return _CG_COMMENT_RE.sub(" ", code)


class ShaderPrograms:
    """A shader's program texts without comments: the ``CGINCLUDE``-like texts shared by the passes
    (``includes``), each pass's programs (``passes``, one list per pass) and all of them (``all_code``)."""

    def __init__(self, includes: list[str], passes: list[list[str]]) -> None:
        self.includes = "\n".join(strip_comments(t) for t in includes)
        self.passes = [[strip_comments(t) for t in programs] for programs in passes]
        self.all_code = self.includes + "\n" + "\n".join(t for programs in self.passes for t in programs)

    def reads_main_light(self) -> bool:
        """Whether any program reads the main light's colour ``_LightColor0`` (a lit shader)."""
        return "_LightColor0" in self.all_code

    def reads_color_or_texture(self) -> bool:
        """Whether any program names ``_Color`` or samples with ``tex2D``."""
        return "_Color" in self.all_code or "tex2D" in self.all_code

    def clip_properties(self) -> set[str]:
        """The properties that ``clip(… - _Prop);`` compares with, in any program."""
        return {m.group(2) for m in _CLIP_PROP_RE.finditer(self.all_code)}

    def constant_colors(self) -> set[tuple[float, float, float, float]]:
        """The finite constant colours ``return float4(r, g, b, a);`` (or half4/fixed4) returns, in any program."""
        constants = {tuple(float(x) for x in m.groups()) for m in _RETURN_CONST_RE.finditer(self.all_code)}
        return {c for c in constants if all(math.isfinite(x) for x in c)}

    def pass_clips(self, index: int) -> bool:
        """``clip(`` in pass ``index``'s programs, or in the shared code when the pass has a program."""
        programs = self.passes[index]
        return bool(_CLIP_RE.search("\n".join(programs))) or (bool(programs) and bool(_CLIP_RE.search(self.includes)))

    def pass_discards(self, index: int) -> bool:
        """``discard`` in pass ``index``'s programs."""
        return bool(_DISCARD_RE.search("\n".join(self.passes[index])))
