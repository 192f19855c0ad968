"""Export: a :class:`~blendlib.core.vocabulary.Material` → a complete built-in-pipeline ShaderLab shader.

The shader is in the style of the book's chapter 8 shaders (Properties, Tags, one Pass per pass
with its LightMode and state, a CG vert/frag doing the same Lambert or Unlit shading and alpha
test) and imports
back to the same settings — for the fields a ``.shader`` file holds: the texture image, its
tiling/offset and sampler settings belong to the Unity material and texture asset, not the
shader. :func:`canonical_pass` is what the round trip gives back for a pass.
"""

from __future__ import annotations

import math
from dataclasses import fields, replace
from decimal import Decimal

from ...core.vocabulary import (
    CompareFunction,
    Lighting,
    Material,
    Pass,
    Queue,
    float32_text,
    pass_state_commands,
    queue_text,
)


def canonical_pass(p: Pass) -> Pass:
    """The pass as a ``.shader`` file can state it: inactive blend/stencil fields at their defaults,
    offsets as the export writes them.

    ``Blend Off`` carries no factors, a non-separate alpha state no alpha factors, a pass
    without an alpha test no comparison (``Always`` tests nothing) and a pass without
    ``Stencil`` no stencil values; offsets are written as the shortest
    text of their float32 (what Blender stores, :func:`float32_text`). So export then
    import gives back ``canonical_pass(p)``; for passes edited in the UI this is ``p``
    itself at float32 precision unless fields hidden by a switched-off option were changed.
    """
    d = Pass()
    p = replace(p, offset_factor=float(float32_text(p.offset_factor)),
                offset_units=float(float32_text(p.offset_units)))
    if p.alpha_test and p.alpha_test_comp is CompareFunction.Always:  # keeps every fragment: no test
        p = replace(p, alpha_test=False)
    if not p.alpha_test:
        p = replace(p, alpha_test_comp=d.alpha_test_comp)
    if not p.blend:
        p = replace(p, src_blend=d.src_blend, dst_blend=d.dst_blend, blend_op=d.blend_op, separate_alpha=False)
    if not p.separate_alpha:
        p = replace(p, src_blend_alpha=d.src_blend_alpha, dst_blend_alpha=d.dst_blend_alpha,
                    blend_op_alpha=d.blend_op_alpha)
    if not p.stencil:
        p = replace(p, **{f.name: getattr(d, f.name) for f in fields(Pass) if f.name.startswith("stencil_")})
    return p


def _num(x: float) -> str:
    """A float as positional decimal text that reads back to the same double (no exponent)."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write the non-finite number {x!r} into a shader")
    if x == int(x) and abs(x) < 1e15:
        return str(int(x))
    text = format(Decimal(repr(x)), "f")
    return text


def _shader_string(text: str) -> str:
    """Text for a ShaderLab string literal (no escapes exist: quotes and line breaks are replaced)."""
    return " ".join(str(text).replace('"', "'").split())


_RENDER_TYPE = {
    Queue.Background: "Opaque", Queue.Geometry: "Opaque", Queue.AlphaTest: "TransparentCutout",
    Queue.Transparent: "Transparent", Queue.Overlay: "Transparent",
}


_CG_HEAD = """\
CGPROGRAM
#pragma vertex vert
#pragma fragment frag

#include "UnityCG.cginc"
#include "Lighting.cginc"

float4 _Color;
sampler2D _MainTex;
float4 _MainTex_ST;
float _Cutoff;
float _AlphaScale;

struct a2v
{
    float4 vertex : POSITION;
    float3 normal : NORMAL;
    float4 texcoord : TEXCOORD0;
};

struct v2f
{
    float4 pos : SV_POSITION;
    float3 worldNormal : TEXCOORD0;
    float3 worldPos : TEXCOORD1;
    float2 uv : TEXCOORD2;
};

v2f vert(a2v v)
{
    v2f o;
    o.pos = UnityObjectToClipPos(v.vertex);
    o.worldNormal = UnityObjectToWorldNormal(v.normal);
    o.worldPos = mul(unity_ObjectToWorld, v.vertex).xyz;
    o.uv = TRANSFORM_TEX(v.texcoord, _MainTex);
    return o;
}

float4 frag(v2f i) : SV_Target
{
    float4 texColor = tex2D(_MainTex, i.uv);
"""

_CG_ALPHA_TEST = """\
    // Alpha test: discard the fragment when alpha - _Cutoff < 0
    clip(texColor.a * _Color.a * _AlphaScale - _Cutoff);
"""
#: The alpha test's other comparisons (what legacy ``AlphaTest <comp> [_Cutoff]`` did), in the CG.
_CG_OPERATORS = {CompareFunction.Greater: ">", CompareFunction.Less: "<", CompareFunction.LEqual: "<=",
                 CompareFunction.Equal: "==", CompareFunction.NotEqual: "!="}


def _cg_alpha_test(comp: CompareFunction) -> str:
    """The CG lines of an alpha test with comparison ``comp`` (GEqual: the book's ``clip``)."""
    if comp is CompareFunction.GEqual:
        return _CG_ALPHA_TEST
    if comp is CompareFunction.Never:
        return "    // Alpha test Never: discard every fragment\n    clip(-1);\n"
    if comp is CompareFunction.Always:
        return ""
    return (f"    // Alpha test: keep the fragment when alpha {_CG_OPERATORS[comp]} _Cutoff\n"
            f"    if (!(texColor.a * _Color.a * _AlphaScale {_CG_OPERATORS[comp]} _Cutoff)) discard;\n")

_CG_LAMBERT = """\
    float3 worldNormal = normalize(i.worldNormal);
    float3 worldLightDir = normalize(UnityWorldSpaceLightDir(i.worldPos));
    float3 albedo = texColor.rgb * _Color.rgb;
    float3 ambient = UNITY_LIGHTMODEL_AMBIENT.xyz * albedo;
    // Lambert diffuse from the main directional light
    float3 diffuse = _LightColor0.rgb * albedo * max(0, dot(worldNormal, worldLightDir));
    return float4(ambient + diffuse, texColor.a * _Color.a * _AlphaScale);
}
ENDCG"""

_CG_UNLIT = """\
    // Unlit: albedo only
    float3 albedo = texColor.rgb * _Color.rgb;
    return float4(albedo, texColor.a * _Color.a * _AlphaScale);
}
ENDCG"""


def export_shaderlab(material: Material, shader_name: str | None = None) -> str:
    """A complete ShaderLab shader (built-in pipeline, CG) with the material's queue, passes and shading.

    ``Properties`` hold ``_Color``, ``_MainTex``, ``_Cutoff`` and ``_AlphaScale`` with the
    material's values as defaults; each pass states its ``LightMode`` tag and Cull/ZWrite/
    ZTest/Blend (and BlendOp, ColorMask, AlphaToMask, Offset, Stencil where they differ from
    the defaults) and runs the book's vertex/fragment program: Lambert (``_LightColor0``) or
    Unlit, with ``clip(texColor.a * _Color.a * _AlphaScale - _Cutoff)`` in alpha-test passes
    (GEqual), ``if (!(… > _Cutoff)) discard;`` for the other comparisons, ``clip(-1)`` for Never.
    """
    name = _shader_string(shader_name if shader_name is not None else f"Unity Passes/{material.name}")
    c = material.color
    q = material.queue
    tags = [f'"Queue"="{queue_text(q, int(material.queue_offset))}"']
    if q in (Queue.Background, Queue.Geometry):
        tags.append('"RenderType"="Opaque"')
    else:
        tags += ['"IgnoreProjector"="True"', f'"RenderType"="{_RENDER_TYPE[q]}"']
    out = [
        f'Shader "{name}"',
        "{",
        "    Properties",
        "    {",
        f'        _Color ("Main Tint", Color) = ({_num(c[0])}, {_num(c[1])}, {_num(c[2])}, {_num(c[3])})',
        '        _MainTex ("Main Tex", 2D) = "white" {}',
        f'        _Cutoff ("Alpha Cutoff", Range(0, 1)) = {_num(material.cutoff)}',
        f'        _AlphaScale ("Alpha Scale", Range(0, 1)) = {_num(material.alpha_scale)}',
        "    }",
        "",
        "    SubShader",
        "    {",
        f"        Tags {{ {' '.join(tags)} }}",
    ]
    body = _CG_LAMBERT if material.lighting == Lighting.Lambert else _CG_UNLIT
    for p in material.draw_passes:
        out += [
            "",
            "        Pass",
            "        {",
            f'            Name "{_shader_string(p.name)}"',
            f'            Tags {{ "LightMode"="{p.light_mode}" }}',
            "",
        ]
        out += ["            " + line for line in pass_state_commands(p)]
        out.append("")
        program = _CG_HEAD + (_cg_alpha_test(p.alpha_test_comp) if p.alpha_test else "") + body
        out += [("            " + line) if line else "" for line in program.splitlines()]
        out.append("        }")
    fallback = {Queue.AlphaTest: "Transparent/Cutout/VertexLit", Queue.Transparent: "Transparent/VertexLit",
                Queue.Overlay: "Transparent/VertexLit"}.get(q)
    out += ["    }", ""]
    out.append(f'    Fallback "{fallback}"' if fallback else "    Fallback Off")
    out += ["}", ""]
    return "\n".join(out)
