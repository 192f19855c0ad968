"""The output merger stage (docs/pipeline.md §8): stencil, depth, blending, colour mask — in exact primitive order.

One concern per module:

- :mod:`.buffers`: :class:`FrameBuffers` (colour, depth and stencil of a frame, their
  storage and conversions, per sample with MSAA and :func:`resolve_colors`), the
  depth/stencil :func:`compare` and :func:`stencil_op`, and :class:`Outcome` (the test that
  discarded a fragment);
- :mod:`.blending`: the blend equations and factors (:func:`blend`) and the blend tables of
  constant colours (:func:`blend_lut`, :class:`BlendTable`, :func:`table_pays`,
  :data:`RECENT_TABLES`, :class:`BlendTables`);
- :mod:`.ordering`: applying a chunk in primitive order (:func:`merge`: distinct pixels at once,
  else layers peeled or ranked by :func:`layers_by_rank`; :func:`apply_layer` per layer).

This package's namespace is the stage's interface: the names below, each defined once in
its module.
"""

from .blending import (
    PAIR_TABLE_FRAGMENTS,
    RECENT_TABLES,
    BlendTable,
    BlendTables,
    RecentTables,
    blend,
    blend_fragments,
    blend_lut,
    find_table,
    lut_eligible,
    table_pays,
    table_rows,
)
from .buffers import FrameBuffers, Outcome, compare, resolve_colors, resolve_planes, stencil_op
from .ordering import PEEL_LAYERS, apply_layer, layers_by_rank, merge, order_free_depth, primitive_layers

__all__ = [
    "PAIR_TABLE_FRAGMENTS", "PEEL_LAYERS", "RECENT_TABLES", "BlendTable", "BlendTables", "FrameBuffers", "Outcome",
    "RecentTables", "apply_layer", "blend", "blend_fragments", "blend_lut", "compare", "find_table",
    "layers_by_rank", "lut_eligible", "merge", "order_free_depth", "primitive_layers", "resolve_colors",
    "resolve_planes", "stencil_op", "table_pays", "table_rows",
]
