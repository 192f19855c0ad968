"""The renderer core: pure stage functions over numpy arrays. Imports nothing outside ``core/``.

Stages in pipeline order, one module each: :mod:`.vertex` (transform, clip, snap, cull) →
:mod:`.raster` (coverage, fragments, depth and weights) → :mod:`.shade` (the book's
ForwardBase program) → :mod:`.merger` (stencil, depth, blend, colour mask in exact primitive
order). :mod:`.pipeline` chains them per draw call of :mod:`.drawlist`. The data:
:mod:`.vocabulary` (ShaderLab enums and frozen dataclasses), :mod:`.scene` (draw scene),
:mod:`.colorspace` (exact sRGB).
"""
