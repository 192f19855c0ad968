"""The records of a render: what its stages hand each other and what its observers receive.

- :class:`Frame`: the rendered frame (the result of :func:`.pipeline.render_scene`).
- :class:`DrawState`: what one draw call needs beyond its triangles, decided once per call.
- :class:`ShadedFragments`: a chunk of one draw call's fragments after shading (the output of
  :mod:`.fragment`, the input of :mod:`.merger`).
- :class:`FrameObserver`: the hooks through which the tools that explain a frame
  (``blendlib.explain``) receive every draw call and fragment, rather than forking the pipeline.
- :class:`RenderCancelled`: raised when a render's ``should_cancel()`` answered True.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .drawlist import DrawCall
from .merger import FrameBuffers
from .shade import Lights, OutlineColor, Texels, outline_color
from .vocabulary import ColorSpace, CompareFunction, Material, Pass


class RenderCancelled(Exception):
    """Raised when ``should_cancel()`` returned True; no buffers are returned."""


@dataclass(eq=False)
class Frame:
    """A rendered frame. Row 0 is the top of the image.

    - ``color`` (H, W, 4) float32: the stored frame values (sRGB-encoded in Gamma
      mode and in Linear LDR; linear in Linear HDR).
    - ``depth`` (H, W) float32: window depth ``d / (2**24 - 1)``.
    - ``stencil`` (H, W) uint8.
    - ``warnings``: one line each (skipped triangles, empty meshes, missing images).
    - ``encoded``: whether ``color``'s rgb is sRGB-encoded (Gamma mode, and Linear LDR);
      False only for Linear HDR, whose buffer holds linear values.

    ``color``, ``depth`` and ``stencil`` are None from a render asked for no output
    (:func:`.pipeline.render_scene`'s ``output=False``).
    """

    color: np.ndarray
    depth: np.ndarray
    stencil: np.ndarray
    warnings: list[str] = field(default_factory=list)
    encoded: bool = True


@dataclass(frozen=True, eq=False)
class DrawState:
    """What one draw call needs beyond its triangles, decided once per draw call (the
    "derived state" of the call): the draw call, its material and pass, the texture's
    texels in shading space, the frame's lights, colour space, buffer kind and width."""

    call: DrawCall
    material: Material
    texels: Texels | None
    lights: Lights
    color_space: ColorSpace
    hdr: bool
    width: int
    #: An observer receives every fragment: source triangles are computed, and depth codes the
    #: merge does not need are computed when the observer reads them.
    observed: bool = False
    #: ``zbound`` (T,) int64 per setup triangle (:func:`.raster.depth_upper_codes`) and ``zfloor``
    #: (H,) int64 the smallest depth code stored in each buffer row (current in the rows of the
    #: screen band being drawn: :class:`.pipeline.RowFloors`): rows whose bound is at or below
    #: (``Less``: below) the floor pass the depth test, so a pass without ZWrite needs no
    #: per-fragment depth there (a hierarchical-Z test per row, exact). None: not applicable.
    zbound: np.ndarray | None = None
    zfloor: np.ndarray | None = None
    #: The texture's mip chain (:class:`.mips.MipChain`) when the material samples through one.
    mips: object | None = None
    #: MSAA samples per pixel (``DrawScene.msaa``): fragments carry coverage masks and a depth
    #: code per sample (docs/pipeline.md §10).
    samples: int = 1
    #: A ForwardAdd draw whose fragments out of its light's reach (attenuation exactly 0) change
    #: nothing, so they are dropped unshaded (:func:`.lights.dark_skip_applies`): everywhere when
    #: ``dark_alpha`` is None, else where it — the colour buffer's (H*W,) uint8 alpha codes, read
    #: as each chunk is shaded — holds 255 (its pass adds to a saturated alpha). Observed, the
    #: fragments are told of, and those at pixels whose colours the observer does not read
    #: (``colors_read``) are not lit: their rgb is 0 (their alpha computed as always). Where they
    #: change nothing (``dark_alpha`` None, or 255 there) they are marked inert
    #: (:attr:`ShadedFragments.inert`: not merged, their outcome the depth test's); elsewhere
    #: they are merged with rgb 0, which stores the same values as the exact colour (±0).
    dark_skip: bool = False
    dark_alpha: np.ndarray | None = None
    #: Observed: where the observer reads the rgb of the call's fragments
    #: (:meth:`.FrameObserver.colors_read`: True everywhere, False nowhere, or an (H*W,) bool mask).
    colors_read: np.ndarray | bool = True
    #: The depth buffer ((H*W,) int64, read as each chunk is shaded) when fragments that fail the
    #: pass's depth test against it are dropped before they are shaded (an early depth test, as
    #: GPUs run one: :func:`.fragment.early_depth_applies`, docs/pipeline.md §8); None: not applicable.
    early_depth: np.ndarray | None = None
    #: Observed: the same call's state as a render without an observer draws it (its shortcuts:
    #: early depth test, alpha first, unlit fragments dropped), for chunks the observer is not
    #: told of (:attr:`.FrameObserver.watched_rows`); None unobserved.
    unobserved: DrawState | None = None

    @property
    def pass_state(self) -> Pass:
        return self.call.state

    @property
    def outline(self) -> OutlineColor | None:
        """The pass's outline colour in shading space (None: the material's lit colour)."""
        return outline_color(self.call.state, self.color_space)

    def depth_needed(self, rows, start: int, stop: int) -> bool:
        """Whether the fragments of rows ``[start, stop)`` need their depth codes at the pixel
        centre (never with MSAA, whose depth is per sample: :meth:`sample_depth_needed`)."""
        return self.samples == 1 and self.sample_depth_needed(rows, start, stop)

    def sample_depth_needed(self, rows, start: int, stop: int) -> bool:
        """Whether the fragments of rows ``[start, stop)`` need their depth codes (the depth test
        reads them or the pass writes them), wherever they are computed."""
        p = self.pass_state
        if p.zwrite:
            return True
        if p.ztest is CompareFunction.Always:
            return False
        if self.zbound is None or self.zfloor is None:
            return True
        bound = self.zbound[rows.tri[start:stop]]
        floor = self.zfloor[rows.y[start:stop]]
        trivial = bound < floor if p.ztest is CompareFunction.Less else bound <= floor
        return not bool(trivial.all())


@dataclass(eq=False)
class ShadedFragments:
    """A chunk of one draw call's fragments after shading, in primitive order.

    - ``pix`` (N,) int64: window pixel index ``y * W + x`` with y up (row 0 = bottom).
    - ``depth`` (N,) int64: 24-bit depth code after Offset. When the chunk provably passes the
      depth test of a pass without ZWrite (:meth:`DrawState.depth_needed`), the codes are only
      computed when an observer reads ``depth`` (``stored_depth`` None, ``depth_fn`` set), or
      never (no observer: ``depth`` None).
    - ``rgba`` (N, 4) float64: shader output in shading space (rows with ``ids >= 0`` unset),
      or None when every fragment has an id.
    - ``ids`` (N,) int32 or None, ``palette`` (K, 4) float64 or None: fragments with
      ``ids >= 0`` have the colour ``palette[ids]`` (shaded once per triangle).
    - ``triangle`` (N,) int64: the source mesh triangle (index in the renderer's mesh), computed
      when an observer reads it (``stored_triangle`` / ``triangle_fn``); None when not observed.
    - ``alive`` (N,) bool or None: passed the alpha test (None: the pass has no alpha test).
    - ``disjoint``: the fragments hit pairwise distinct pixels (one merge layer).
    - ``coverage`` (N,) uint8 or None: with MSAA, the samples each fragment covers (bit s =
      sample s; the rasteriser's coverage, before AlphaToMask); ``depth`` is then (N, samples)
      int64, each sample's code (those of samples not covered are meaningless). None without.
    """

    pix: np.ndarray
    stored_depth: np.ndarray | None
    rgba: np.ndarray
    ids: np.ndarray | None
    palette: np.ndarray | None
    stored_triangle: np.ndarray | None
    alive: np.ndarray | None
    disjoint: bool = False
    #: ``depth_fn(index)``: the deferred depth codes of fragments ``index`` (None: all).
    depth_fn: Callable[[np.ndarray | None], np.ndarray] | None = None
    #: ``triangle_fn(index)``: the source triangles of fragments ``index`` (None: all), deferred.
    triangle_fn: Callable[[np.ndarray | None], np.ndarray] | None = None
    #: ``colors_fn(index)``: the shader colours (M, 4) of fragments ``index`` (None: all), deferred
    #: (a pass that writes no colour, observed: colours only for the fragments an observer reads).
    colors_fn: Callable[[np.ndarray | None], np.ndarray] | None = None
    coverage: np.ndarray | None = None
    #: (R,) int64 fragments left in each of the chunk's rows when an early depth test dropped some
    #: (:attr:`DrawState.early_depth`); None: each row holds all its covered pixels.
    row_counts: np.ndarray | None = None
    #: (N,) bool or None: fragments whose merge would change no stored value (an observed
    #: ForwardAdd draw's fragments out of its light's reach: :attr:`DrawState.dark_skip`). They
    #: are told of with the outcome of the depth test alone (their pass has no stencil and writes
    #: no depth, so the stored depth is the same before and after the others) and not merged.
    inert: np.ndarray | None = None

    @property
    def triangle(self) -> np.ndarray | None:
        """(N,) int64 source mesh triangles, computed on first use when deferred (observed renders)."""
        if self.stored_triangle is None and self.triangle_fn is not None:
            self.stored_triangle, self.triangle_fn = self.triangle_fn(None), None
        return self.stored_triangle

    @property
    def count(self) -> int:
        return int(self.pix.shape[0])

    @property
    def depth(self) -> np.ndarray | None:
        """(N,) int64 depth codes, computed on first use when deferred (see the class doc)."""
        if self.stored_depth is None and self.depth_fn is not None:
            self.stored_depth, self.depth_fn = self.depth_fn(None), None
        return self.stored_depth

    def colors(self) -> np.ndarray:
        """(N, 4) float64 shader colours, table entries filled in."""
        if self.ids is None and self.rgba is None and self.colors_fn is not None:
            return self.colors_fn(None)
        if self.ids is None:
            return self.rgba
        if self.rgba is None:
            return self.palette.take(self.ids, axis=0)
        out = self.rgba.copy()
        tabled = self.ids >= 0
        out[tabled] = self.palette.take(self.ids[tabled], axis=0)
        return out

    def span(self, lo: int, hi: int) -> ShadedFragments:
        """Fragments ``[lo, hi)`` as views, palette kept (a chunk without deferred values)."""
        def cut(a):
            return None if a is None else a[lo:hi]

        return ShadedFragments(cut(self.pix), cut(self.stored_depth), cut(self.rgba), cut(self.ids), self.palette,
                               cut(self.stored_triangle), cut(self.alive), self.disjoint,
                               coverage=cut(self.coverage), inert=cut(self.inert))

    def select(self, keep: np.ndarray) -> ShadedFragments:
        """The fragments where ``keep`` (bool (N,) or indices) holds."""
        index = np.flatnonzero(keep) if keep.dtype == bool else keep

        def take(a):
            return None if a is None else a.take(index, axis=0)

        def deferred(stored, fn):
            # A deferred value of the selection asks for the selected fragments only (a pixel
            # history reads a handful of each chunk).
            if stored is not None or fn is None:
                return None
            return lambda sub: fn(index if sub is None else index.take(sub))

        depth_fn = deferred(self.stored_depth, self.depth_fn)
        triangle_fn = deferred(self.stored_triangle, self.triangle_fn)
        colors_fn = deferred(self.rgba if self.ids is None else self.ids, self.colors_fn)
        return ShadedFragments(take(self.pix), take(self.stored_depth), take(self.rgba), take(self.ids),
                               self.palette, take(self.stored_triangle), take(self.alive), self.disjoint, depth_fn,
                               triangle_fn, colors_fn, take(self.coverage), inert=take(self.inert))


class FrameObserver:
    """Receives the records of a render as it happens (frame debugger, sorted reference, overdraw).

    :meth:`fragments` is called from band worker threads (each band owns distinct pixels;
    within a band, chunks come in primitive order): implementations must be thread-safe.
    The base class ignores everything.
    """

    #: Whether :meth:`draw_begin` / :meth:`draw_end` must see the buffers exactly as they are
    #: between two draw calls (timing each call; snapshots need not: :attr:`snapshot_after`).
    #: False lets the renderer draw calls in batches, as
    #: without an observer: ``draw_begin`` of a batch's calls comes before it is drawn and
    #: ``draw_end`` after (with the buffers after the whole batch); fragments keep their order.
    exact_boundaries = True
    #: Draw calls (indices) whose :meth:`draw_begin` must see the buffers exactly as the calls
    #: before them left them even without :attr:`exact_boundaries`: a batch starts there.
    exact_before: frozenset[int] = frozenset()

    def reads_depth(self, call: DrawCall) -> bool:
        """Whether :meth:`fragments` reads the depth codes of every fragment of ``call``: then
        they are computed as the fragments are rasterised, not afterwards (the hierarchical-Z
        shortcut of :meth:`DrawState.depth_needed` would only defer them)."""
        return False

    #: Whether this observer reads MSAA fragments (:attr:`ShadedFragments.coverage`, per-sample
    #: depth and outcomes, :meth:`fragments`); a render with ``msaa`` > 1 refuses one that does not.
    per_sample = False

    def draw_begin(self, call: DrawCall, buffers: FrameBuffers) -> None:
        """Before draw call ``call`` (``buffers`` as left by the draw calls before it when
        :attr:`exact_boundaries`; else as left by the batch before it)."""

    def fragments(self, call: DrawCall, frags: ShadedFragments, outcome: np.ndarray) -> None:
        """Every fragment rasterised in a chunk, with its :class:`.merger.Outcome` (N,) int8.

        With MSAA (:attr:`per_sample` observers only), ``outcome`` is (N, samples) int8: each
        sample's outcome, ``Outcome.ALPHA_TO_MASK`` where AlphaToMask removed a covered sample,
        and ``Outcome.NOT_COVERED`` (-1) where the fragment does not cover the sample."""

    def draw_end(self, call: DrawCall, buffers: FrameBuffers, triangles: int) -> None:
        """After draw call ``call``; ``triangles``: the call's source triangles that reach the
        rasteriser (neither culled nor degenerate nor entirely clipped away)."""

    #: Whether :meth:`fragments` is called at all. An observer of draw boundaries only (a clock)
    #: says False: each call is then drawn as an unobserved render draws it, fragments unreported.
    reads_fragments = True

    def reads_call(self, call: DrawCall) -> bool:
        """Whether :meth:`fragments` reads the fragments of ``call`` (with :attr:`reads_fragments`):
        a call it does not read is drawn as an unobserved render draws it (its shortcuts: early
        depth test, alpha first, dropped unlit fragments), its fragments unreported."""
        return True

    def reads_hidden(self, call: DrawCall) -> bool:
        """Whether :meth:`fragments` must be told of the fragments of ``call`` that fail the depth
        test. An observer that reads written fragments only says False: such a call may drop
        them before shading, unreported, as an unobserved render does (the early depth test)."""
        return True

    #: (H,) bool, the buffer rows (from the bottom) whose fragments :meth:`fragments` reads, or None
    #: for all: chunks of fragments in no such row are drawn as if nothing observed them, unreported.
    watched_rows: np.ndarray | None = None

    def colors_read(self, call: DrawCall) -> np.ndarray | bool:
        """Where :meth:`fragments` reads the rgb of ``call``'s fragments (``ShadedFragments.colors``):
        True at every pixel, False nowhere (it reads counts, pixels, depths, outcomes, alpha), or an
        (H*W,) bool mask of window pixels (y from the bottom). Elsewhere a fragment whose exact
        colour provably merges as another does (out of a ForwardAdd light's reach: rgb 0) may
        carry that other rgb, its lighting not computed; alpha, outcomes and buffers stay exact."""
        return True

    #: Draw calls (indices) after which :meth:`snapshot_rows` is called: snapshots taken band by
    #: band as the calls are drawn, without :attr:`exact_boundaries` (so in batches).
    snapshot_after: frozenset[int] = frozenset()

    def snapshot_rows(self, index: int, buffers: FrameBuffers, y0: int, y1: int) -> None:
        """Rows ``[y0, y1)`` of ``buffers`` exactly as the draw calls up to ``index`` (one of
        :attr:`snapshot_after`) left them, before any later call touched them. Called from the
        worker that draws those rows (other workers are drawing other rows meanwhile: read only
        these), once per screen band; the bands of one ``index`` cover every row drawn."""
