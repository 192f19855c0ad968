"""Unity's YAML files (``.mat``, ``.meta``) as plain Python values, read exactly.

Unity writes a YAML 1.1 stream whose documents start ``--- !u!<class id> &<file id>`` (a
``stripped`` may follow in prefabs) under one ``%TAG !u! tag:unity3d.com,2011:`` directive, which
YAML applies to the first document only. So each document's body is parsed on its own, its header
read by :data:`_HEADER` (research-surface.md §9.4). The body is *composed* by ruamel.yaml (its pure
Python parser; the extension bundles its wheel) into nodes and converted here, not constructed, so
nothing is typed implicitly: an all-digit guid such as ``00000000000000001000000000000000`` stays
that string (YAML 1.1 would read an octal number), ``Off`` stays ``Off``, ``.5`` stays ``.5``.
A key repeated in one mapping — Unity 4–5.4's ``m_Floats: { data: …, data: … }`` — keeps every
value, in a :class:`Repeated` list.

:func:`load_documents` returns ``[(class id, file id, body)]``; a ``.meta`` file (no header) is one
document with class id and file id None. Errors are :class:`UnityFileError` (one line, with the
position YAML reports).
"""

from __future__ import annotations

import re
from typing import Any

from .diagnostics import ShaderLabError

_HEADER = re.compile(r"^--- !u!(\d+) &(-?\d+)( stripped)?[ \t]*$", re.M)
_DIRECTIVE = re.compile(r"^%[^\n]*$", re.M)


class UnityFileError(ShaderLabError):
    """A Unity file that cannot be read; ``str()`` is one line ``FILE[:LINE:COL]: message``."""

    def __str__(self) -> str:
        if self.line <= 0:
            return f"{self.filename}: {self.message}"
        return super().__str__()


class Repeated(list):
    """The values of a key repeated inside one mapping, in order (the old ``data:`` layout)."""


def _value(node) -> Any:
    """A composed node as a str, list or dict (repeated keys: a :class:`Repeated`)."""
    from ruamel.yaml.nodes import MappingNode, SequenceNode

    if isinstance(node, MappingNode):
        out: dict[str, Any] = {}
        for key_node, value_node in node.value:
            key = _value(key_node)
            key = key if isinstance(key, str) else str(key)
            value = _value(value_node)
            if key in out:
                previous = out[key]
                if not isinstance(previous, Repeated):
                    previous = out[key] = Repeated([previous])
                previous.append(value)
            else:
                out[key] = value
        return out
    if isinstance(node, SequenceNode):
        return [_value(item) for item in node.value]
    return node.value  # a scalar, exactly as written (an empty value is "")


def _compose(text: str, filename: str, line_offset: int) -> Any:
    from ruamel.yaml import YAML
    from ruamel.yaml.error import MarkedYAMLError, YAMLError

    yaml = YAML(typ="safe", pure=True)
    try:
        node = yaml.compose(text)
    except MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, column = (mark.line + 1 + line_offset, mark.column + 1) if mark is not None else (0, 0)
        raise UnityFileError(f"not valid YAML: {exc.problem or exc.context}", line, column, filename) from None
    except YAMLError as exc:
        raise UnityFileError(f"not valid YAML: {exc}", 0, 0, filename) from None
    return {} if node is None else _value(node)


def load_documents(text: str, filename: str = "<string>") -> list[tuple[int | None, int | None, Any]]:
    """``[(class id, file id, body)]`` of each document of a Unity YAML file (see the module docstring)."""
    heads = list(_HEADER.finditer(text))
    if not heads:
        return [(None, None, _compose(_DIRECTIVE.sub("", text), filename, 0))]
    docs = []
    for i, head in enumerate(heads):
        end = heads[i + 1].start() if i + 1 < len(heads) else len(text)
        line_offset = text.count("\n", 0, head.end())
        docs.append((int(head.group(1)), int(head.group(2)), _compose(text[head.end():end], filename, line_offset)))
    return docs
