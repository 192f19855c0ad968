"""The renderer core: pure stage functions over numpy arrays. Imports nothing outside ``core/``.

Stages in pipeline order, one module each: :mod:`.vertex` (transform, clip, snap, cull) →
:mod:`.raster` (coverage, fragments, depth and weights) → :mod:`.shade` (the book's
ForwardBase program; :mod:`.fragment` shades a chunk of a draw call's rows by the cheapest
exact path) → :mod:`.merger` (stencil, depth, blend, colour mask in exact primitive order: a
package of buffers, blending and ordering). :mod:`.pipeline` chains them in one loop over the
draw calls of :mod:`.drawlist`, each prepared once (:mod:`.prepare`: derived state, the setup
memo) and small ones fused (:mod:`.fuse`); :mod:`.records` holds what passes between the
stages and to observers. The data: :mod:`.vocabulary` (ShaderLab enums and frozen
dataclasses), :mod:`.scene` (draw scene), :mod:`.colorspace` (exact sRGB). :mod:`.parts`
splits per-element work over an executor it is given; threads and processes are made
elsewhere (:func:`.pipeline.render_scene`'s pool, :mod:`blendlib.runtime`).
"""
