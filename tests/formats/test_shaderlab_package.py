"""The seams of the ShaderLab package: module order, the syntax tree, the first error, warning order."""

from __future__ import annotations

import re

import pytest

from blendlib.core.vocabulary import Cull
from blendlib.formats.shaderlab import ShaderLabError, parse_shaderlab
from blendlib.formats.shaderlab.parser import Parser
from blendlib.formats.shaderlab.tree import (
    CategoryBlock,
    Command,
    PassBlock,
    SubShaderBlock,
    TagsBlock,
    UsePass,
)
from tests.test_layers import ROOT, project_imports

PACKAGE = ROOT / "blendlib" / "formats" / "shaderlab"
#: The package's modules, each importing only those before it (the order of its docstring).
ORDER = ["diagnostics", "lexer", "tree", "parser", "state", "programs", "surface", "fixed_function", "assets",
         "unity_yaml", "material_file", "record", "importer", "project", "exporter"]


def test_each_module_imports_only_the_modules_before_it():
    assert sorted(p.stem for p in PACKAGE.glob("*.py")) == sorted([*ORDER, "__init__"])
    bad = []
    for index, name in enumerate(ORDER):
        for line, module in project_imports(PACKAGE / f"{name}.py"):
            parts = module.split(".")
            if parts[:3] == ["blendlib", "formats", "shaderlab"] and parts[3] not in ORDER[:index]:
                bad.append(f"{name}.py:{line} imports {module}")
    assert not bad, "\n".join(bad)


def _at(text: str, needle: str) -> tuple[int, int]:
    """1-based (line, column) of the first ``needle`` in ``text``."""
    offset = text.index(needle)
    line = text.count("\n", 0, offset) + 1
    return line, offset - (text.rfind("\n", 0, offset) + 1) + 1


TREE_TEXT = """Shader "T" {
Properties { _Mode ("Mode", Float) = 2 }
Category {
    Tags { "Queue"="Transparent" }
    ZWrite Off
    SubShader {
        Cull [_Mode]
        Pass { Name "A" Blend 1 SrcAlpha OneMinusSrcAlpha, One Zero Stencil { Ref 2 Comp Equal } CGPROGRAM x ENDCG }
        UsePass "Other/PASS"
    }
    SubShader { Pass { } }
}
}"""


def test_the_parser_keeps_blocks_and_commands_as_written():
    shader = Parser(TREE_TEXT, "t.shader").parse()
    assert (shader.name, shader.filename, list(shader.properties), shader.subshader_count) == (
        "T", "t.shader", ["_Mode"], 2)
    (category,) = shader.body
    assert isinstance(category, CategoryBlock)
    assert [type(item) for item in category.body] == [TagsBlock, Command, SubShaderBlock]  # 2nd SubShader skipped
    tags, zwrite, subshader = category.body
    assert tags.tags == {"Queue": "Transparent"}
    assert (zwrite.name, [v.token.text for v in zwrite.values]) == ("zwrite", ["Off"])
    assert [type(item) for item in subshader.body] == [Command, PassBlock, UsePass]
    cull, pass_block, use_pass = subshader.body
    (mode,) = cull.values
    assert mode.reference and mode.token.text == "_Mode" and mode.declared is shader.properties["_Mode"]
    assert (mode.token.line, mode.token.column) == _at(TREE_TEXT, "_Mode]")
    assert pass_block.name == "A" and pass_block.programs == [" x "]
    blend, stencil = pass_block.commands
    assert [v.token.text for v in blend.values] == ["SrcAlpha", "OneMinusSrcAlpha", "One", "Zero"]
    assert blend.render_target.text == "1"
    assert [(c.name, c.values[0].token.text) for c in stencil.commands] == [("ref", "2"), ("comp", "Equal")]
    assert use_pass.path == "Other/PASS"


def test_a_reference_names_the_property_declared_before_it():
    """A name not declared before it is a global (SPEC §11.1): Unity reads it as 0 (Cull Off)."""
    text = 'Shader "T" { SubShader { Pass { Cull [_C] } } Properties { _C ("c", Float) = 2 } }'
    shader = Parser(text, "t.shader").parse()
    (cull,) = shader.body[0].body[0].commands
    assert cull.values[0].declared is None and "_C" in shader.properties
    result = parse_shaderlab(text, "t.shader")
    assert result.passes[0].cull is Cull.Off  # 0, not the later declaration's 2 (Back)
    assert "{}:{}: Cull mode refers to [_C], which is not in Properties: a global, which Unity reads as 0 unless " \
           "a script sets it; imported as 0".format(*_at(text, "_C]")) in result.warnings


_PASS = 'Shader "T" {\nProperties { _P ("p", Float) = 7 }\nSubShader { Pass {\n%s\n} } }'


@pytest.mark.parametrize("body, bad, syntax, message", [
    # A bad value before a syntax error is the first error of the text.
    ("Blend SrcAlfa { }", "SrcAlfa", "expected a value for blend factor, found '{'",
     "unknown blend factor 'SrcAlfa' (expected one of: One, Zero, SrcColor, SrcAlpha, DstColor, DstAlpha, "
     "OneMinusSrcColor, OneMinusSrcAlpha, OneMinusDstColor, OneMinusDstAlpha, SrcAlphaSaturate)"),
    ("Stencil { Ref 300 Foo }", "300", "unknown Stencil command 'Foo'",
     "Stencil Ref must be an integer 0..255, got 300"),
    ("Cull [_P] Pass { }", "_P]", "Pass inside a Pass",
     "Cull mode value 7 from the property is not supported"),
    ("Offset [_P], { } Blend SrcAlfa One", "{ } Blend", "expected a value for Offset units",
     "expected a value for Offset units, found '{'"),
    # A syntax error before a bad value is.
    ("ZWrite { } Blend SrcAlfa One", "{ } Blend", "expected a value for ZWrite, found '{'",
     "expected a value for ZWrite, found '{'"),
])
def test_the_first_error_of_the_text_is_reported(body, bad, syntax, message):
    text = _PASS % body
    with pytest.raises(ShaderLabError, match=re.escape(syntax)):  # what the parser alone stops at
        Parser(text, "t.shader").parse()
    with pytest.raises(ShaderLabError) as err:
        parse_shaderlab(text, "t.shader")
    assert (err.value.line, err.value.column) == _at(text, bad)
    assert err.value.message == message


def test_warnings_of_the_parser_and_of_the_state_are_in_text_order():
    text = ('Shader "T" { SubShader { Pass { ZTest [_Global] Foo 1\nBlend 1 One One Stencil { CompBack Less } '
            "CGPROGRAM\nENDCG } } }")
    warnings = parse_shaderlab(text, "t.shader").warnings

    def at(needle):
        return "{}:{}: ".format(*_at(text, needle))

    assert list(warnings) == [
        at("_Global") + "ZTest function refers to [_Global], which is not in Properties: a global, which Unity "
                        "reads as 0 unless a script sets it; imported as 0",  # state
        at("Foo") + "unknown command 'Foo' in Pass ignored",  # parser
        at("1 One") + "Blend for render target 1 ignored: the frame is render target 0",  # state
        at("CompBack") + "Stencil CompBack (per-face stencil) is not supported and ignored",  # state
    ]
