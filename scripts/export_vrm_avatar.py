"""Write the avatar example as a VRM 1.0 file: ``tests/fixtures/vrm_avatar.vrm``.

    .venv/bin/python -m scripts.export_vrm_avatar            # from the repository root

The geometry, UVs and textures come from Blender's own glTF exporter (the ``Avatar`` scene of
``blend_files/vrm_avatar.blend``); each material is then rewritten as the VRM Add-on's VRM 1.0
exporter writes it from the material's MToon settings
(:func:`blendlib.formats.gltf.vrm_addon.vrm1_material_json`: ``alphaMode``, ``alphaCutoff``,
``doubleSided``, ``baseColorFactor``, ``KHR_materials_unlit`` and ``VRMC_materials_mtoon``), keeping
the exporter's base colour texture with the add-on's sampler, and ``VRMC_vrm`` marks the file as
VRM 1.0. The test ``tests/blender/test_vrm_avatar.py`` checks that importing this file gives every
material the Unity state the ``.blend`` renders with.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BLEND = ROOT / "blend_files" / "vrm_avatar.blend"
OUT = ROOT / "tests" / "fixtures" / "vrm_avatar.vrm"


def export(blend: Path = BLEND, out: Path = OUT) -> Path:
    import json

    import bpy

    from blendlib.blender import vrm_addon
    from blendlib.formats.gltf.container import glb_bytes, split_glb
    from blendlib.formats.gltf.vrm_addon import vrm1_material_json

    bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
    import addon_utils  # Blender's module: importable once bpy is

    addon_utils.enable("io_scene_gltf2", default_set=False)
    with tempfile.TemporaryDirectory() as tmp, bpy.context.temp_override(scene=bpy.data.scenes["Avatar"]):
        path = Path(tmp) / "avatar.glb"
        bpy.ops.export_scene.gltf(filepath=str(path), export_format="GLB", use_active_scene=True,
                                  export_cameras=False, export_lights=False, export_extras=False,
                                  export_yup=True, export_apply=True)
        data, binary = split_glb(path.read_bytes(), str(path))
    doc = json.loads(data)
    samplers = doc.setdefault("samplers", [])
    for material in doc.get("materials", []):
        mtoon = vrm_addon.addon_mtoon(bpy.data.materials[material["name"]])
        info = (material.get("pbrMetallicRoughness") or {}).get("baseColorTexture")
        rewritten = vrm1_material_json(mtoon, {"base": 0} if mtoon.base_color_texture is not None else {})
        if info is not None and mtoon.base_color_texture is not None:
            texture = mtoon.base_color_texture
            rewritten["pbrMetallicRoughness"]["baseColorTexture"]["index"] = info["index"]
            samplers.append({"magFilter": texture.mag_filter, "minFilter": texture.min_filter,
                             "wrapS": texture.wrap_s, "wrapT": texture.wrap_t})
            doc["textures"][info["index"]]["sampler"] = len(samplers) - 1
        material.clear()
        material.update(rewritten)
    used = set(doc.get("extensionsUsed", []))
    doc["extensionsUsed"] = sorted(used | {"KHR_materials_unlit", "KHR_texture_transform", "VRMC_materials_mtoon",
                                           "VRMC_vrm"})
    doc.setdefault("extensions", {})["VRMC_vrm"] = {
        "specVersion": "1.0",
        "meta": {"name": "Unity Passes avatar example", "authors": ["Unity Passes for Blender"],
                 "licenseUrl": "https://vrm.dev/licenses/1.0/"},
        "humanoid": {"humanBones": {}},
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(glb_bytes(doc, binary))
    print(f"wrote {out.relative_to(ROOT)} ({out.stat().st_size} bytes)")
    return out


if __name__ == "__main__":
    export()
    sys.exit(0)
