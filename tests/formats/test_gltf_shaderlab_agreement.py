"""The importers' pass tables agree with the ShaderLab importer reading the shaders' own state lines.

MToon's pass headers are written below as the shaders state them (MToon.shader @1499e25a and
vrmc_materials_mtoon.shader @5d116ee8, research-vrm §1.3 / §2.3), with the properties set to the
values under test; Standard and the Unlit shaders come from the corpus
(``shared/corpus/unity-builtin-shaders-2019.4``). Compared: every field the state lines set (Cull,
ZWrite, ZTest, Blend and BlendOp with the separate alpha state, Offset, AlphaToMask), the LightMode
tags and the pass names. The clip is decided by keywords and is checked in test_gltf*.py.
"""

from __future__ import annotations

import re

import pytest

from blendlib.core.vocabulary import BlendFactor, Cull
from blendlib.formats.gltf.mtoon import OUTLINE_WORLD, mtoon_passes
from blendlib.formats.gltf.unigltf import standard_passes
from blendlib.formats.shaderlab import parse_shaderlab
from blendlib.formats.shaderlab.state import _CULL_BY_NUMBER, _FACTOR_BY_NUMBER
from tests.support.gltf_docs import corpus_dir

STATE_FIELDS = ("name", "light_mode", "cull", "zwrite", "ztest", "blend", "src_blend", "dst_blend", "blend_op",
                "separate_alpha", "src_blend_alpha", "dst_blend_alpha", "blend_op_alpha", "offset_factor",
                "offset_units", "alpha_to_mask")

MTOON0 = """Shader "VRM/MToon" {
Properties {
    _CullMode ("_CullMode", Float) = %(cull)s
    _OutlineCullMode ("_OutlineCullMode", Float) = %(outline_cull)s
    _SrcBlend ("_SrcBlend", Float) = %(src)s
    _DstBlend ("_DstBlend", Float) = %(dst)s
    _ZWrite ("_ZWrite", Float) = %(zwrite)s
    _AlphaToMask ("_AlphaToMask", Float) = %(a2m)s
}
SubShader {
    Tags { "RenderType" = "Opaque"  "Queue" = "Geometry" }
    Pass { Name "FORWARD_BASE" Tags { "LightMode" = "ForwardBase" }
        Cull [_CullMode] Blend [_SrcBlend] [_DstBlend] ZWrite [_ZWrite] ZTest LEqual BlendOp Add, Max
        AlphaToMask [_AlphaToMask] }
    Pass { Name "FORWARD_BASE_ONLY_OUTLINE" Tags { "LightMode" = "ForwardBase" }
        Cull [_OutlineCullMode] Blend [_SrcBlend] [_DstBlend] ZWrite [_ZWrite] ZTest LEqual Offset 1, 1
        BlendOp Add, Max AlphaToMask [_AlphaToMask] }
    Pass { Name "FORWARD_ADD" Tags { "LightMode" = "ForwardAdd" }
        Cull [_CullMode] Blend [_SrcBlend] One ZWrite Off ZTest LEqual BlendOp Add, Max
        AlphaToMask [_AlphaToMask] }
    Pass { Name "ShadowCaster" Tags { "LightMode" = "ShadowCaster" }
        Cull [_CullMode] ZWrite On ZTest LEqual }
}
}"""


def _state(p):
    return {name: getattr(p, name) for name in STATE_FIELDS}


@pytest.mark.parametrize("cull,outline_cull,src,dst,zwrite,a2m", [
    (2, 1, 1, 0, 1, 0), (0, 1, 5, 10, 0, 0), (1, 2, 5, 10, 1, 1), (2, 0, 1, 1, 0, 1),
])
def test_mtoon0_passes_read_like_the_shader_text(cull, outline_cull, src, dst, zwrite, a2m):
    parsed = parse_shaderlab(MTOON0 % dict(cull=cull, outline_cull=outline_cull, src=src, dst=dst, zwrite=zwrite,
                                           a2m=a2m))
    ours = mtoon_passes(version="0.x", cull=_CULL_BY_NUMBER[cull], outline_cull=_CULL_BY_NUMBER[outline_cull],
                        src=_FACTOR_BY_NUMBER[src], dst=_FACTOR_BY_NUMBER[dst], zwrite=bool(zwrite),
                        alpha_to_mask=bool(a2m), alpha_test=False, outline_mode=OUTLINE_WORLD)
    assert parsed.material.render_queue == 2000
    assert [_state(p) for p in ours] == [_state(p) for p in parsed.passes]


def test_mtoon1_outline_pass_is_always_cull_front():
    text = MTOON0.replace("Cull [_OutlineCullMode]", "Cull Front").replace("FORWARD_BASE_ONLY_OUTLINE",
                                                                            "FORWARD_BASE_OUTLINE")
    parsed = parse_shaderlab(text % dict(cull=0, outline_cull=2, src=5, dst=10, zwrite=0, a2m=0))
    ours = mtoon_passes(version="1.0", cull=Cull.Off, outline_cull=Cull.Front, src=BlendFactor.SrcAlpha,
                        dst=BlendFactor.OneMinusSrcAlpha, zwrite=False, alpha_to_mask=False, alpha_test=False,
                        outline_mode=OUTLINE_WORLD)
    assert [_state(p) for p in ours] == [_state(p) for p in parsed.passes]


CORPUS = corpus_dir()


@pytest.mark.skipif(CORPUS is None, reason="shared/corpus not found beside the repository")
@pytest.mark.parametrize("src,dst,zwrite", [(1, 0, 1), (5, 10, 0)])  # Opaque/Cutout and Fade (UniGLTF's modes)
def test_standard_passes_read_like_the_corpus_shader(src, dst, zwrite):
    text = (CORPUS / "unity-builtin-shaders-2019.4/DefaultResourcesExtra/Standard.shader").read_text()
    for name, value in (("_SrcBlend", src), ("_DstBlend", dst), ("_ZWrite", zwrite)):
        text, count = re.subn(rf'({name} \("[^"]*", Float\) = )[0-9.]+', rf"\g<1>{value}.0", text)
        assert count == 1
    parsed = parse_shaderlab(text)
    ours = standard_passes(src=_FACTOR_BY_NUMBER[src], dst=_FACTOR_BY_NUMBER[dst], zwrite=bool(zwrite),
                           alpha_test=False)
    assert [_state(p) for p in ours] == [_state(p) for p in parsed.passes]
