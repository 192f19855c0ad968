"""glTF and VRM files: each material as UniVRM and UniGLTF set it for Unity's built-in pipeline (SPEC §11.6).

Bpy-free: reads the JSON of a ``.vrm`` / ``.glb`` / ``.gltf`` file and maps its materials to the typed
:class:`~blendlib.core.vocabulary.Material` (queue, passes with their state and LightMode, colour,
``_MainTex`` settings). The geometry is Blender's glTF importer's (:mod:`blendlib.blender.gltf_import`).

One module per step, each importing only those above it:

* :mod:`.container` — the file: glb chunks, strict JSON, the checks that stop an import
  (:class:`GltfError`: one line naming the file);
* :mod:`.textures` — a texture's sampler and ``KHR_texture_transform`` as UniGLTF loads them;
* :mod:`.mtoon` — MToon's four passes (0.x and 1.0) for given property values;
* :mod:`.records` — :class:`ImportedMaterial`, :class:`GltfImport` (their JSON: the ShaderLab
  package's material record per material);
* :mod:`.unigltf` — plain glTF: UniUnlit and Standard;
* :mod:`.vrm0` — VRM 0.x ``materialProperties`` (UniVRM's legacy loader: values as stored);
* :mod:`.vrm1` — VRM 1.0 ``VRMC_materials_mtoon`` through MToon's validator;
* :mod:`.importer` — which importer takes which material; :func:`import_file`;
* :mod:`.vrm_addon` — the VRM Add-on for Blender's MToon settings as the JSON its exporters write;
* :mod:`.vrm_advice` — sort advice in those settings' terms (queue within MToon's clamps, render modes).
"""

from .container import GltfDocument, GltfError, document_from_json, read_document
from .importer import import_file, import_material, import_materials, vrm_version
from .mtoon import BLEND_CLIP_MTOON0, BLEND_CLIP_MTOON1
from .records import SHADING_APPROXIMATION, GltfImport, ImportedMaterial

__all__ = [
    "BLEND_CLIP_MTOON0",
    "BLEND_CLIP_MTOON1",
    "SHADING_APPROXIMATION",
    "GltfDocument",
    "GltfError",
    "GltfImport",
    "ImportedMaterial",
    "document_from_json",
    "import_file",
    "import_material",
    "import_materials",
    "read_document",
    "vrm_version",
]
