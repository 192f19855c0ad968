"""ShaderLab import and export: ``.shader`` text <-> Unity material settings.

Import (:func:`parse_shaderlab`, :func:`parse_shaderlab_file`) reads the ShaderLab subset that
decides render state and returns a :class:`ShaderLabResult`: the typed
:class:`blendlib.core.vocabulary.Material` (one :class:`~blendlib.core.vocabulary.Pass` per
``Pass { }`` of the first SubShader, no texture image), a list of warnings and what else the file
says (``extra``: tags, LightModes, UsePass, Fallback, properties). Errors raise
:class:`ShaderLabError` (one line: ``FILE:LINE:COL: message``) and nothing is returned.
Export (:func:`export_shaderlab`) writes a complete shader whose import gives the same settings
back (:func:`canonical_pass`). No module here uses bpy; ``python -m blendlib shaderlab --export``
reads the material through :mod:`blendlib.blender` (``blendlib/cli/shaderlab.py``).

One module per step, each importing only those above it in this list:

* :mod:`.diagnostics` — :class:`ShaderLabError`, positioned warnings, the cap on repeated ones;
* :mod:`.lexer` — tokens on demand and the raw text the parser skips or keeps (programs, attributes);
* :mod:`.tree` — the syntax tree: Shader → Properties / Category / SubShader / Pass blocks, their
  commands with the arguments as written, and the program texts;
* :mod:`.parser` — the grammar: text → tree (which block holds which command, each command's
  arguments), with warnings for what it skips;
* :mod:`.state` — what the commands mean: Unity's enum tables and numbering, ``[_Prop]`` values,
  Category → SubShader → Pass inheritance, the Queue tag, state → Pass fields;
* :mod:`.programs` — what the CG/HLSL text says (``clip(``, ``_LightColor0``, constant colours);
* :mod:`.importer` — the steps in order → :class:`ShaderLabResult`;
* :mod:`.exporter` — Material → shader text.

Where coming features belong (SPEC §11.1–11.5): commands Unity accepts and this renderer
ignores, fixed-function commands (``Lighting``, ``Material { }``, ``SetTexture``, ``AlphaTest``)
and GrabPass in the grammar of :mod:`.parser` and as nodes of :mod:`.tree`; what they set,
globals such as ``[unity_GUIZTestMode]``, AlphaToMask values, per-render-target Blend/ColorMask
and the advanced BlendOps in :mod:`.state` (a reference's value is read in one place,
``_Values.raw``, where a ``.mat`` file's values will take precedence over the defaults);
``#pragma surface`` and its options read in :mod:`.programs`; the passes a surface shader
generates, UsePass through a search path and the LightMode rules of which passes draw, and
``.mat`` files (Unity YAML), in modules of their own beside :mod:`.importer`.
"""

from .diagnostics import MAX_REPEATED_WARNINGS, ShaderLabError
from .exporter import canonical_pass, export_shaderlab
from .importer import ShaderLabResult, parse_shaderlab, parse_shaderlab_file
from .parser import MAX_NESTING
from .state import parse_queue

__all__ = [
    "MAX_NESTING",
    "MAX_REPEATED_WARNINGS",
    "ShaderLabError",
    "ShaderLabResult",
    "canonical_pass",
    "export_shaderlab",
    "parse_queue",
    "parse_shaderlab",
    "parse_shaderlab_file",
]
