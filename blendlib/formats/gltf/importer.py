"""A checked glTF document → every material as UniVRM / UniGLTF set it (:func:`import_materials`).

Which importer takes a material, in UniVRM's order:

* VRM 0.x files (``extensions.VRM``): ``materialProperties[i]`` through the legacy loader
  (:mod:`.vrm0`; ``VRM_USE_GLTFSHADER`` and materials without an entry through UniGLTF);
* a material with ``VRMC_materials_mtoon`` (VRM 1.0): MToon's validator (:mod:`.vrm1`);
* everything else: UniGLTF (:mod:`.unigltf`; ``KHR_materials_unlit`` → UniUnlit, else Standard).
"""

from __future__ import annotations

from pathlib import Path

from .container import GltfDocument, GltfError, read_document
from .records import SHADING_APPROXIMATION, GltfImport, ImportedMaterial, MaterialError
from .unigltf import gltf_material
from .vrm0 import vrm0_material
from .vrm1 import EXTENSION as MTOON1_EXTENSION
from .vrm1 import vrm1_material


def vrm_version(document: GltfDocument) -> str | None:
    """``"0.x"`` (``extensions.VRM``), ``"1.0"`` (``extensions.VRMC_vrm``) or None (plain glTF)."""
    extensions = document.json.get("extensions")
    if not isinstance(extensions, dict):
        return None
    if isinstance(extensions.get("VRMC_vrm"), dict):
        return "1.0"
    if isinstance(extensions.get("VRM"), dict):
        return "0.x"
    return None


def import_material(document: GltfDocument, index: int, vrm: str | None) -> ImportedMaterial:
    """Material ``index`` of ``document`` (a file of VRM version ``vrm``) as Unity draws it;
    :class:`GltfError` (one line naming the file and the material) for a value Unity cannot take."""
    material = document.list("materials")[index]
    try:
        if vrm == "0.x":
            entries = document.json["extensions"]["VRM"].get("materialProperties") or []
            entry = entries[index] if index < len(entries) else None
            imported = vrm0_material(document, index, entry, lambda i: gltf_material(document, i))
        elif MTOON1_EXTENSION in (material.get("extensions") or {}):
            imported = vrm1_material(document, index)
        else:
            imported = gltf_material(document, index)
    except MaterialError as exc:
        raise GltfError(f"{document.path}: {exc}") from None
    image = document.texture_image(imported.main_tex) if imported.main_tex is not None else None
    if image is not None:  # which image _MainTex is (the record's main_tex is a file path: none here)
        imported.extra["main_tex_image"] = document.image_name(image)
    return imported


def import_materials(document: GltfDocument) -> GltfImport:
    """Every material of ``document``, in index order, with the import's warnings (the shading
    approximation once, then each material's)."""
    vrm = vrm_version(document)
    materials = tuple(import_material(document, i, vrm) for i in range(len(document.list("materials"))))
    warnings = [SHADING_APPROXIMATION] if materials else []
    warnings += [w for m in materials for w in m.warnings]
    return GltfImport(document.path, vrm, materials, tuple(warnings))


def import_file(path: str | Path) -> GltfImport:
    """:func:`read_document` then :func:`import_materials`; :class:`GltfError` on bad input."""
    return import_materials(read_document(path))
