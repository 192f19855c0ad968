"""The one writer of a pass's state text, and the float32 number text it uses."""

from __future__ import annotations

import struct

from hypothesis import given
from hypothesis import strategies as st

from blendlib.core.vocabulary import (
    BlendFactor,
    BlendOp,
    CompareFunction,
    Cull,
    Pass,
    float32_text,
    pass_state_commands,
    pass_state_text,
    preset,
)


def f32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", float(x)))[0]


def test_float32_text_examples():
    assert float32_text(f32(0.1234567)) == "0.1234567"  # the panel wrote 0.123457, the export 0.12345670163631439
    assert float32_text(0.1234567) == "0.1234567"
    assert float32_text(f32(0.1)) == "0.1" and float32_text(-2.0) == "-2" and float32_text(0.0) == "0"
    assert float32_text(1e-7) == "0.0000001" and float32_text(-1.5) == "-1.5"
    assert float32_text(123456789.0) == "123456792"  # the float32 nearest to it


@given(st.floats(width=32, allow_nan=False, allow_infinity=False, min_value=-1e9, max_value=1e9))
def test_float32_text_reads_back_and_is_shortest(x):
    text = float32_text(x)
    assert "e" not in text.lower()
    assert f32(float(text)) == f32(x)
    digits = len(text.lstrip("-").replace(".", "").lstrip("0").rstrip("0"))
    if digits > 1 and "." in text:  # one significant digit fewer does not read back
        assert f32(float(f"{f32(x):.{digits - 1}g}")) != f32(x)


def test_pass_state_text():
    assert pass_state_text(Pass()) == "Cull Back ZWrite On ZTest LEqual Blend Off"
    _, (blend,) = preset("Alpha Blend")
    assert pass_state_text(blend) == "Cull Back ZWrite Off ZTest LEqual Blend SrcAlpha OneMinusSrcAlpha"
    p = Pass(cull=Cull.Off, blend=True, separate_alpha=True, src_blend=BlendFactor.One, dst_blend=BlendFactor.One,
             src_blend_alpha=BlendFactor.Zero, dst_blend_alpha=BlendFactor.One, blend_op=BlendOp.Add,
             blend_op_alpha=BlendOp.Max, ztest=CompareFunction.Always, offset_units=-1.0, alpha_test=True)
    assert pass_state_commands(p) == ["Cull Off", "ZWrite On", "ZTest Always", "Blend One One, Zero One",
                                      "BlendOp Add, Max", "Offset 0, -1"]
    assert pass_state_text(p) == " ".join(pass_state_commands(p)) + " clip(a - _Cutoff)"
    assert pass_state_commands(Pass(blend=True, blend_op=BlendOp.Min))[-1] == "BlendOp Min"
    assert pass_state_commands(Pass(stencil=True, stencil_ref=1))[-1] == (
        "Stencil { Ref 1 ReadMask 255 WriteMask 255 Comp Always Pass Keep Fail Keep ZFail Keep }")
