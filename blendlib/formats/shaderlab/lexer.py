"""The ShaderLab lexer: tokens on demand, and the raw text the parser takes without tokenizing.

ShaderLab cannot be tokenized ahead of the parser: a ``[`` opens a property reference in a
command (``Cull [_Cull]``) but free attribute text in Properties (``[Enum(UnityEngine.Rendering.
CullMode)]``), and blocks the importer skips (a second SubShader, an unknown command's ``{ }``)
may hold anything. So :class:`Scanner` hands out one :class:`Token` at a time (``peek``/``next``)
and, where the parser asks, skips or returns raw text: a balanced ``{ ... }`` block, the rest of
a line, an attribute up to its ``]``. ``CGPROGRAM`` … ``ENDCG`` (and the HLSL/GLSL and
``…INCLUDE`` forms) is one ``code`` token holding the program text.

Keywords are case-insensitive; ``//`` and ``/* */`` comments are skipped everywhere.
"""

from __future__ import annotations

import bisect
import math
import re
from dataclasses import dataclass

from .diagnostics import ShaderLabError


@dataclass(slots=True)  # not frozen: a frozen dataclass's __init__ is several times slower
class Token:
    """One token with its 1-based position; ``describe()`` names it in messages."""

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
            self.pos = self._skip_string_at(start)
            return Token("string", text[start + 1 : self.pos - 1], line, col, self.pos)
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
            if word.lower() in _CODE_BLOCKS:
                close = self._program_close(word, start, self.pos)
                body = text[self.pos : close.start()]
                self.pos = close.end()
                return Token("code", body, line, col, self.pos, code_kind=word.upper())
            return Token("ident", word, line, col, self.pos)
        raise self.error(f"unexpected character {c!r}", start)

    def _program_close(self, word: str, start: int, body_start: int) -> re.Match:
        """The ``ENDCG``-like word closing the program that ``word`` (at ``start``) opens."""
        end_word = _CODE_BLOCKS[word.lower()]
        close = re.compile(r"\b" + end_word + r"\b", re.IGNORECASE).search(self.text, body_start)
        if close is None:
            raise self.error(f"{word} is never closed by {end_word}", start)
        return close

    def _skip_string_at(self, i: int) -> int:
        """The offset after the string literal whose ``"`` is at ``i`` (strings end on their line)."""
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
            if m.group().lower() not in _CODE_BLOCKS:
                return m.end()
            return self._program_close(m.group(), i, m.end()).end()
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
        self.skip_line_until(frozenset())

    def skip_line_until(self, words: frozenset[str]) -> None:
        """Skip the rest of the line like :meth:`skip_rest_of_line`, but stop before a word of
        ``words`` (lower case) that starts there: the next command on the same line."""
        assert self._peeked is None
        i, text = self.pos, self.text
        while i < len(text):
            c = text[i]
            if c in "\r\n" or text.startswith("//", i) or c == "}":
                break
            if c == '"':
                i = self._skip_string_at(i)
                continue
            if c == "{":
                line, col = self.where(i)
                self.skip_raw_block(Token("punct", "{", line, col, i + 1), "the ignored command")
                return
            if words:
                m = _IDENT_RE.match(text, i)
                if m and m.group().lower() in words and not (i and (text[i - 1].isalnum() or text[i - 1] == "_")):
                    break
            j = self._skip_comment_or_program_at(i)
            i = j if j is not None else i + 1
        self.pos = i

    def raw_block(self, open_tok: Token, owner: str) -> str:
        """The raw text inside the ``{ … }`` that ``open_tok`` opens; the scanner moves past its ``}``."""
        self.skip_raw_block(open_tok, owner)
        return self.text[open_tok.end : self.pos - 1]

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


