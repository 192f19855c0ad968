"""ShaderLab import and export: Unity ``.shader`` and ``.mat`` files <-> Unity material settings.

Import (:func:`parse_shaderlab`, :func:`parse_shaderlab_file`, :func:`import_material_file`) reads
what decides what Unity's built-in pipeline draws (SPEC §11.1–11.5) and returns a
:class:`ShaderLabResult`: the typed :class:`blendlib.core.vocabulary.Material` (the passes of the
first SubShader as Unity compiles them — Category/SubShader/Pass state, the passes a surface shader
generates, fixed-function passes, UsePass — each with its LightMode; no texture image), the
warnings (what is not imported or approximated, one line each) and what else the files say
(``extra``). ``ShaderLabResult.to_dict()`` is THE material record (:func:`material_record`), the
JSON of ``python -m blendlib shaderlab``. Errors raise :class:`ShaderLabError` (one line:
``FILE:LINE:COL: message``; a ``.mat``'s :class:`UnityFileError` ``FILE: message``) and nothing is
returned. Export (:func:`export_shaderlab`) writes a complete shader whose import gives the same
settings back (:func:`canonical_pass`). No module here uses bpy.

One module per step, each importing only those above it in this list:

* :mod:`.diagnostics` — :class:`ShaderLabError`, positioned warnings, the cap on repeated ones;
* :mod:`.lexer` — tokens on demand and the raw text the parser skips or keeps (programs, blocks);
* :mod:`.tree` — the syntax tree: Shader → Properties / Category / SubShader / Pass blocks, their
  commands with the arguments as written, programs, texture stages, GrabPass;
* :mod:`.parser` — the grammar: text → tree, every command consumed exactly;
* :mod:`.state` — what the commands mean: Unity's enum tables, ``[_Prop]`` values (a ``.mat``'s,
  the defaults, globals), Category → SubShader → Pass inheritance, the Queue tag;
* :mod:`.programs` — what the CG/HLSL says (keywords and ``#if`` branches, the alpha test and its
  comparison, vertex colours, premultiplication, Unity's own include files);
* :mod:`.surface` — ``#pragma surface`` → the passes Unity generates, per option;
* :mod:`.fixed_function` — legacy passes: ``Lighting``, ``Material { }``, ``SetTexture … combine``,
  ``AlphaTest``;
* :mod:`.assets` — shaders by name and assets by guid on a search path, the built-in fileIDs;
* :mod:`.unity_yaml` — Unity's YAML, read exactly (ruamel.yaml's composer);
* :mod:`.material_file` — ``.mat`` files (three layouts) and textures' importer settings;
* :mod:`.record` — the material record (JSON) other importers print too;
* :mod:`.importer` — the steps in order → :class:`ShaderLabResult`;
* :mod:`.project` — a ``.mat`` with its shader and texture; a project's ``.mat`` files by name;
* :mod:`.exporter` — Material → shader text.
"""

from .assets import BUILTIN_SHADERS, AssetSearch
from .diagnostics import MAX_REPEATED_WARNINGS, ShaderLabError
from .exporter import canonical_pass, export_shaderlab
from .importer import ShaderLabResult, parse_shaderlab, parse_shaderlab_file
from .material_file import TextureSettings, UnityMaterialFile, read_material_file, read_texture_settings
from .parser import MAX_NESTING
from .project import import_material_file, project_folder, project_materials
from .record import material_record
from .state import MaterialValues, parse_queue
from .unity_yaml import UnityFileError

__all__ = [
    "BUILTIN_SHADERS",
    "MAX_NESTING",
    "MAX_REPEATED_WARNINGS",
    "AssetSearch",
    "MaterialValues",
    "ShaderLabError",
    "ShaderLabResult",
    "TextureSettings",
    "UnityFileError",
    "UnityMaterialFile",
    "canonical_pass",
    "export_shaderlab",
    "import_material_file",
    "material_record",
    "parse_queue",
    "parse_shaderlab",
    "parse_shaderlab_file",
    "project_folder",
    "project_materials",
    "read_material_file",
    "read_texture_settings",
]
