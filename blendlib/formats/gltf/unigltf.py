"""Plain glTF materials as UniGLTF imports them for Unity's built-in pipeline.

UniGLTF's order (``BuiltInGltfMaterialDescriptorGenerator.cs`` @3317c095): ``KHR_materials_unlit``
→ ``UniGLTF/UniUnlit``, else PBR → ``Standard``.

**UniUnlit** (``BuiltInGltfUnlitMaterialImporter.cs`` @0a7ac08d; ``UniUnlit/Runtime/Utils.cs``
@8eaceb6c; ``UniUnlit.shader``): one untagged pass (LightMode ``Always``)
``Cull [_CullMode] Blend [_SrcBlend] [_DstBlend] ZWrite [_ZWrite] ZTest LEqual BlendOp Add, Max``;
OPAQUE One Zero ZWrite On, queue −1 (the shader has no Queue tag: 2000); MASK One Zero ZWrite On
``_ALPHATEST_ON`` (``clip(col.a - _Cutoff)``, ``_Cutoff`` = ``alphaCutoff``), 2450; BLEND SrcAlpha
OneMinusSrcAlpha ZWrite Off ``_ALPHABLEND_ON``, 3000; ``doubleSided`` → ``_CullMode`` Off (0), else
Back (2); a material whose primitives have ``COLOR_0`` multiplies the vertex colour
(``_VERTEXCOL_MUL``: ``col *= i.color``). Its colour ``tex2D(_MainTex, uv) * _Color`` is exact here
(Unlit); without an alpha keyword it writes alpha 1.

**Standard** (``BuiltInGltfPbrMaterialImporter.cs`` @fcb4f184): BLEND → Fade (``_SrcBlend``
SrcAlpha, ``_DstBlend`` OneMinusSrcAlpha, ``_ZWrite`` 0, ``_ALPHABLEND_ON``, queue 3000); MASK →
Cutout (One, Zero, ``_ZWrite`` 1, ``_Cutoff`` = ``alphaCutoff``, ``_ALPHATEST_ON``, 2450); OPAQUE
(One, Zero, ``_ZWrite`` 1, queue −1 = 2000). ``doubleSided`` is never read, and Standard's passes
have no ``Cull`` line: Cull Back (a warning says so). Passes (corpus
``DefaultResourcesExtra/Standard.shader``, first SubShader): ``FORWARD`` (ForwardBase) ``Blend
[_SrcBlend] [_DstBlend] ZWrite [_ZWrite]``; ``FORWARD_DELTA`` (ForwardAdd) ``Blend [_SrcBlend] One
ZWrite Off ZTest LEqual``; ``ShadowCaster`` ``ZWrite On ZTest LEqual``; ``DEFERRED``; ``META``
``Cull Off``. Cutout clips ``alpha - _Cutoff`` in the forward passes. PBR shading is approximated
by Lambert.
"""

from __future__ import annotations

from typing import Any

from ...core.vocabulary import (
    BlendFactor,
    BlendOp,
    CompareFunction,
    Cull,
    Lighting,
    LightMode,
    Material,
    Pass,
    VertexColor,
)
from .container import GltfDocument
from .records import ImportedMaterial, MaterialError, gamma_color, number, queue_fields
from .textures import sampler_settings, texture_transform_st

ALPHA_MODES = ("OPAQUE", "MASK", "BLEND")


def uniunlit_pass(*, cull: Cull, src: BlendFactor, dst: BlendFactor, zwrite: bool, alpha_test: bool) -> Pass:
    """UniUnlit's one pass for the given ``_CullMode``/``_SrcBlend``/``_DstBlend``/``_ZWrite`` values."""
    return Pass(name="Pass", light_mode=LightMode.Always, cull=cull, zwrite=zwrite, ztest=CompareFunction.LEqual,
                blend=True, src_blend=src, dst_blend=dst, blend_op=BlendOp.Add, separate_alpha=True,
                src_blend_alpha=src, dst_blend_alpha=dst, blend_op_alpha=BlendOp.Max, alpha_test=alpha_test)


def standard_passes(*, src: BlendFactor, dst: BlendFactor, zwrite: bool, alpha_test: bool) -> tuple[Pass, ...]:
    """The five passes of Unity's Standard shader for the given ``_SrcBlend``/``_DstBlend``/``_ZWrite``."""
    return (
        Pass(name="FORWARD", light_mode=LightMode.ForwardBase, blend=True, src_blend=src, dst_blend=dst,
             zwrite=zwrite, alpha_test=alpha_test),
        Pass(name="FORWARD_DELTA", light_mode=LightMode.ForwardAdd, blend=True, src_blend=src,
             dst_blend=BlendFactor.One, zwrite=False, ztest=CompareFunction.LEqual, alpha_test=alpha_test),
        Pass(name="ShadowCaster", light_mode=LightMode.ShadowCaster, zwrite=True, ztest=CompareFunction.LEqual),
        Pass(name="DEFERRED", light_mode=LightMode.Deferred),
        Pass(name="META", light_mode=LightMode.Meta, cull=Cull.Off),
    )


#: Per alphaMode: (src, dst, zwrite, alpha test, queue number) of UniUnlit and of Standard (the same numbers).
MODE_STATE = {
    "OPAQUE": (BlendFactor.One, BlendFactor.Zero, True, False, 2000),
    "MASK": (BlendFactor.One, BlendFactor.Zero, True, True, 2450),
    "BLEND": (BlendFactor.SrcAlpha, BlendFactor.OneMinusSrcAlpha, False, False, 3000),
}


def alpha_mode(material: dict[str, Any], where: str, warnings: list[str]) -> str:
    """glTF ``alphaMode`` (default OPAQUE); an unknown value is OPAQUE with a warning, as UniVRM reads it."""
    mode = material.get("alphaMode", "OPAQUE")
    if mode not in ALPHA_MODES:
        warnings.append(f"{where}: unknown alphaMode {mode!r}; imported as OPAQUE")
        return "OPAQUE"
    return mode


def alpha_cutoff(material: dict[str, Any], where: str) -> float:
    """glTF ``alphaCutoff`` (default 0.5)."""
    return number(material.get("alphaCutoff", 0.5), f"{where}.alphaCutoff")


def base_color_texture(document: GltfDocument, material: dict[str, Any], where: str,
                       warnings: list[str]) -> tuple[int | None, dict[str, Any]]:
    """(texture index or None, the ``_MainTex`` Material fields) of ``pbrMetallicRoughness.baseColorTexture``:
    its sampler and its ``KHR_texture_transform`` as ``_MainTex_ST``."""
    info = (material.get("pbrMetallicRoughness") or {}).get("baseColorTexture")
    if not isinstance(info, dict):
        return None, {}
    texture = info["index"]
    fields = sampler_settings(document.texture_sampler(texture), f"{where}: texture {texture}", warnings)
    try:
        tiling, offset = texture_transform_st(info, f"{where}.baseColorTexture", warnings)
    except ValueError as exc:
        raise MaterialError(str(exc)) from None
    return texture, fields | {"main_tex_tiling": tiling, "main_tex_offset": offset}


def uses_vertex_color(document: GltfDocument, index: int) -> bool:
    """Whether a primitive drawn with material ``index`` has ``COLOR_0`` (UniGLTF's ``MaterialHasVertexColor``)."""
    for mesh in document.list("meshes"):
        for primitive in mesh.get("primitives", ()):
            if primitive.get("material") == index and "COLOR_0" in (primitive.get("attributes") or {}):
                return True
    return False


def gltf_material(document: GltfDocument, index: int, importer_prefix: str = "glTF") -> ImportedMaterial:
    """Material ``index`` of ``document`` as UniGLTF imports it (UniUnlit or Standard)."""
    material = document.list("materials")[index]
    name = material.get("name") if isinstance(material.get("name"), str) else f"Material_{index}"
    where = f"material {name!r}"
    warnings: list[str] = []
    mode = alpha_mode(material, where, warnings)
    src, dst, zwrite, clips, queue = MODE_STATE[mode]
    texture, fields = base_color_texture(document, material, where, warnings)
    color = gamma_color((material.get("pbrMetallicRoughness") or {}).get("baseColorFactor"),
                        f"{where}.baseColorFactor")
    extra: dict[str, Any] = {"alpha_mode": mode, "double_sided": bool(material.get("doubleSided", False)),
                             "render_queue": queue, "_Color": list(color)}
    if mode == "OPAQUE":
        color = color[:3] + (1.0,)  # both shaders write alpha 1 without an alpha keyword
    cutoff = alpha_cutoff(material, where) if mode == "MASK" else 0.5
    unlit = "KHR_materials_unlit" in (material.get("extensions") or {})
    if unlit:
        cull = Cull.Off if extra["double_sided"] else Cull.Back
        passes: tuple[Pass, ...] = (uniunlit_pass(cull=cull, src=src, dst=dst, zwrite=zwrite, alpha_test=clips),)
        shader, lighting = "UniGLTF/UniUnlit", Lighting.Unlit
        vertex_color = VertexColor.Multiply if uses_vertex_color(document, index) else VertexColor.Off
    else:
        passes = standard_passes(src=src, dst=dst, zwrite=zwrite, alpha_test=clips)
        shader, lighting, vertex_color = "Standard", Lighting.Lambert, VertexColor.Off
        if extra["double_sided"]:
            warnings.append(f"{where}: doubleSided is ignored by UniGLTF's PBR importer (Standard has no Cull "
                            "property): drawn with Cull Back")
    extra["shader"] = shader
    out = Material(name=name, color=color, cutoff=cutoff, lighting=lighting, passes=passes,
                   vertex_color=vertex_color, **queue_fields(queue, f"{where}: render queue"), **fields)
    return ImportedMaterial(index, out, texture, f"{importer_prefix} {shader}", tuple(warnings), extra)
