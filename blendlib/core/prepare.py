"""Preparing draw calls (docs/pipeline.md §1–§4): the derived state of each call, and the setup memo.

Mesa's softpipe computes what the current state implies once per state change
(``sp_state_derived.c``); here :func:`prepare_batch` does it once per draw call, before any
fragment is drawn: the renderer's vertex setup (shared by its passes, kept across the
viewport's frames in the :class:`~.scene.SceneMemo` within the budgets below), the triangles
its Cull keeps and their covered rows, its :class:`~.records.DrawState` (with the per-triangle
depth bounds of the hierarchical-Z shortcut) and how its chunks are shaded
(:func:`chunk_shading`). The result is a :class:`PreparedCall`, which the driver
(:mod:`.pipeline`) and the fusion of calls (:mod:`.fuse`) pass around whole.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np

from . import colorspace, fragment, lights, mips, msaa, raster, shade, vertex
from .drawlist import DrawCall
from .fragment import ChunkShader
from .merger import BlendTables, FrameBuffers
from .outline import outline_key, width_factors
from .records import DrawState
from .scene import Camera, SceneMemo
from .shaded_cache import ShadedCache
from .vertex import TriangleSetup
from .vocabulary import ColorSpace, CompareFunction, Lighting, Material, Pass, VertexColor


@dataclass(eq=False)
class FrameContext:
    """What the draw calls of one render share (made by :func:`.pipeline.render_scene`):
    buffers, camera, lights, the thread pool and its stop flag, caches, notes for warnings."""

    buf: FrameBuffers
    camera: Camera
    lights: shade.Lights
    color_space: ColorSpace
    hdr: bool
    chunk_candidates: int
    pool: ThreadPoolExecutor | None
    workers: int
    stop_flag: threading.Event
    observed: bool = False
    #: ``reads_depth(call)`` of the observer (:meth:`.records.FrameObserver.reads_depth`), or None.
    reads_depth: Callable[[DrawCall], bool] | None = None
    #: ``reads_call(call)`` of the observer (:meth:`.records.FrameObserver.reads_call`), or None:
    #: with ``observed``, the calls whose fragments it is told of (the others drawn as unobserved).
    reads_call: Callable[[DrawCall], bool] | None = None
    #: ``reads_hidden(call)`` of the observer (:meth:`.records.FrameObserver.reads_hidden`), or None.
    reads_hidden: Callable[[DrawCall], bool] | None = None
    #: ``colors_read(call)`` of the observer (:meth:`.records.FrameObserver.colors_read`), or None.
    colors_read: Callable[[DrawCall], np.ndarray | bool] | None = None
    #: Buffer rows ``[y0, y1)`` (y from the bottom) this render draws, or None for all
    #: (:func:`.pipeline.render_scene`'s ``band``: one process's share of a frame).
    band: tuple[int, int] | None = None
    #: Converted textures and (small renderers') setups, kept across renders when render_scene
    #: is given a memo.
    memo: SceneMemo = field(default_factory=SceneMemo)
    #: Whether setups go into the memo (it outlives this render: render_scene was given one).
    keep_setups: bool = False
    #: With ``keep_setups``: per mesh (by id) the matrices (bytes) the scene's renderers place it
    #: at; a kept setup of another placement through this camera is dropped (:func:`_setups`).
    placements: dict = field(default_factory=dict)
    #: Held while the memo's setups are looked up and stored: renderers sharing a mesh may be
    #: prepared on several threads at once (:func:`prepare_batch`).
    memo_lock: threading.Lock = field(default_factory=threading.Lock)
    warnings: list[str] = field(default_factory=list)
    degenerate: list[tuple[str, int]] = field(default_factory=list)  # (object, zero-area triangles)
    #: The shading-space lights of ForwardAdd draws, by light: id → (light, :class:`shade.Lights`).
    call_lights: dict = field(default_factory=dict)
    #: Shaded chunks kept across renders, or None; with it, each call's key prefix by call index
    #: (:func:`.shaded_cache.call_slots`; a call missing is not kept, and none without a cache).
    shaded_cache: ShadedCache | None = None
    shaded_slots: dict = field(default_factory=dict)

    @property
    def samples(self) -> int:
        """MSAA samples per pixel (the buffers')."""
        return self.buf.samples

    @functools.cached_property
    def sample_offsets(self) -> np.ndarray | None:
        """(N, 2) int64 sample positions for the coverage of MSAA rows (:func:`.msaa.sample_offsets`),
        None without MSAA (coverage at pixel centres)."""
        return None if self.samples == 1 else msaa.sample_offsets(self.samples)

    @property
    def width(self) -> int:
        return self.buf.width

    @property
    def height(self) -> int:
        return self.buf.height

    @functools.cached_property
    def camera_key(self) -> tuple:
        """What a kept vertex setup is for: the camera's matrices and size (:func:`_setups`)."""
        return _camera_key(self.camera)

    def record(self, notes: list[str], degenerate: tuple[str, int] | None) -> None:
        """What :func:`_setup` found about a renderer, for the frame's warnings (in draw order)."""
        self.warnings.extend(notes)
        if degenerate is not None:
            self.degenerate.append(degenerate)

    def texels_of(self, material: Material):
        """The material's texture in shading space, converted once per memo (main thread only)."""
        return self.texture_texels(material.main_tex)

    def texture_texels(self, texture):
        """A texture in shading space, converted once per memo (main thread only); None for None."""
        if texture is None:
            return None
        color_space = self.color_space
        return self.memo.lookup(("texels", color_space), texture, lambda: shade.texture_texels(texture, color_space))

    def inputs_of(self, call: DrawCall) -> CallInputs:
        """What shading reads of a draw call besides its triangles (main thread only): its texture's
        texels and, with ``main_tex_mipmaps``, mip chain (once per memo per texture, colour space
        and Preserve Coverage cutoff), and its lights (a ForwardAdd draw's own, once per render)."""
        material = call.renderer.material
        texels = self.texels_of(material)
        chain = None
        if texels is not None and material.main_tex_mipmaps:
            preserve = bool(material.main_tex_preserve_coverage)
            cutoff = float(material.cutoff) if preserve else None
            chain = self.memo.lookup(("mips", self.color_space, cutoff), material.main_tex,
                                     lambda: mips.build_chain(texels, preserve, cutoff or 0.0))
        light = call.light
        if light is None:
            return CallInputs(texels, chain, self.lights)
        if id(light) not in self.call_lights:
            self.call_lights[id(light)] = (light, replace(self.lights, add=lights.add_light(light, self.color_space)))
        return CallInputs(texels, chain, self.call_lights[id(light)][1])

    def vertex_colors_of(self, renderer) -> np.ndarray | None:
        """The renderer's vertex colours in shading space (T, 3, 4) float64 when its material reads
        them, converted once per memo and colour space as texels are (§7), else None."""
        mesh = renderer.mesh
        if renderer.material.vertex_color is VertexColor.Off or mesh.colors is None:
            return None
        return self.memo.lookup(("vertex colours", self.color_space), mesh,
                                lambda: vertex_colors(mesh, self.color_space))


def vertex_colors(mesh, color_space: ColorSpace) -> np.ndarray:
    """A mesh's corner colours (T, 3, 4) float64 in shading space: RGB of ``sRGB``-encoded colours
    as is in Gamma and decoded in Linear, of ``Linear`` ones encoded in Gamma and as is in Linear;
    alpha as is (docs/pipeline.md §7)."""
    values = np.asarray(mesh.colors, dtype=np.float32).astype(np.float64)
    if mesh.color_encoding == "sRGB" and color_space is ColorSpace.Linear:
        values[..., :3] = colorspace.decode_array(values[..., :3])
    elif mesh.color_encoding == "Linear" and color_space is ColorSpace.Gamma:
        values[..., :3] = colorspace.encode_array(values[..., :3])
    return values


@dataclass(frozen=True, eq=False)
class CallInputs:
    """What :meth:`FrameContext.inputs_of` finds for a draw call: texels (or None), mip chain (or
    None) and shading-space lights."""

    texels: object
    mips: object
    lights: shade.Lights


@dataclass(eq=False)
class PreparedCall:
    """A draw call ready to draw, the one record the driver and the fusion of calls pass around.

    ``setup``: its renderer's triangle setup; ``selected`` (S,) int64: the setup triangles its
    Cull keeps; ``rows``: their covered rows; ``state``: its :class:`~.records.DrawState`
    (``zfloor`` filled in by whoever draws it, per screen band); ``shade``: how a chunk of its
    rows is rasterised, interpolated and shaded (:data:`~.fragment.ChunkShader`: chosen by
    :func:`chunk_shading`, or a fused one of :mod:`.fuse`); ``tables``: the blend tables of its
    palettes, built once and shared by the bands that draw it; ``members``: the calls shaded
    together and merged one by one (:func:`.fuse.fuse_shared_shading`), each with its own pass,
    or None (``state`` is then only how the chunks are shaded).
    """

    call: DrawCall
    setup: TriangleSetup
    selected: np.ndarray
    rows: raster.Rows
    state: DrawState
    shade: ChunkShader
    tables: BlendTables = field(default_factory=BlendTables)
    members: list[Member] | None = None


@dataclass(eq=False)
class Member:
    """One draw call of a :class:`PreparedCall` with shared shading: its own state (pass,
    cutoff), blend tables, and first triangle in the shared setup."""

    state: DrawState
    tables: BlendTables
    first: int


def chunk_shading(p: Pass) -> ChunkShader:
    """How the chunks of a call with pass ``p`` are shaded: a pass that writes no colour and
    has no alpha test (a depth prepass, ``ColorMask 0``) gets fragments without colours (only
    depth and stencil reach the buffers; an observer's reads are shaded lazily), every other
    pass :func:`.fragment.shade_chunk`."""
    if not p.color_mask and not p.alpha_test:
        return fragment.shade_colourless_chunk
    return fragment.shade_chunk


def _shading_of(frame: FrameContext, p: Pass) -> ChunkShader:
    """:func:`chunk_shading`, except that under MSAA a pass with AlphaToMask is always shaded: its
    alpha decides which samples it covers, colour written or not."""
    if frame.samples > 1 and p.alpha_to_mask:
        return fragment.shade_chunk
    return chunk_shading(p)


def setup_input(renderer, colors: np.ndarray | None = None, program: Pass | None = None,
                color_space: ColorSpace = ColorSpace.Gamma, texels_of=None) -> vertex.SetupInput:
    """What the vertex setup of ``renderer`` needs: normals only for lit shading, UVs only with a
    texture, its vertex colours in shading space when shading reads them
    (:meth:`FrameContext.vertex_colors_of`), the pass whose outline program moves its
    vertices (None: none) and, with one, the material's outline-width factors in ``color_space``
    (its texels from ``texels_of(texture)``, :meth:`FrameContext.texture_texels`, when given)."""
    material = renderer.material
    factors = None
    if program is not None and material.outline_width_tex is not None:
        texels = None if texels_of is None else texels_of(material.outline_width_tex)
        factors = width_factors(renderer.mesh, material, color_space, texels)
    return vertex.SetupInput(renderer.mesh, renderer.matrix_world, need_normals=material.lighting is not Lighting.Unlit,
                             need_uvs=material.main_tex is not None, colors=colors, program=program,
                             width_factors=factors)


def _programs(run: list[DrawCall]) -> dict:
    """The vertex programs of a renderer's draw calls: :func:`.outline.outline_key` → the first
    pass with it (None: the plain vertex stage), in order. Each needs its own vertex setup."""
    programs: dict = {}
    for call in run:
        programs.setdefault(outline_key(call.state), call.state)
    return programs


def _setup_notes(renderer, setup) -> tuple[list[str], tuple[str, int] | None]:
    """What to tell the user about a renderer's setup: skipped triangles, zero-area ones."""
    notes = []
    if setup.skipped_nonfinite:
        label = f"object {renderer.name!r} slot {renderer.slot}"
        notes.append(f"{label}: skipped {setup.skipped_nonfinite} triangles with non-finite vertices")
    return notes, ((renderer.name, setup.degenerate) if setup.degenerate else None)


#: A memo keeps the vertex setup of meshes of at most this many triangles per camera (and their
#: passes' coverage rows for the last band drawn): the viewport's next frame through the same
#: view redraws the renderers a change left alone without setting them up again (a moved
#: object, an edited material). Bigger meshes are set up again: their setup is a small part of
#: their frame, and keeping it would hold 100+ bytes a triangle.
MEMO_SETUP_TRIANGLES = 1 << 17
#: Cameras per mesh whose setups a memo keeps: the viewport's reduced and full frame sizes.
MEMO_CAMERAS = 2
#: At most this many triangles' setups (over all renderers and cameras) in one memo: about
#: 120-200 bytes each, 72 more with world normals kept (:data:`.vertex.KEPT_WORLD_NORMALS`), so
#: some 300-500 MB; renderers beyond it are set up every frame.
MEMO_SETUP_BUDGET = 1 << 21


@dataclass(eq=False)
class _Geometry:
    """A mesh's triangle setup through one camera and placement (:func:`_setup_key`) and its
    passes' rows by (Cull, MSAA samples): (band or None, selected triangles, rows) of the last
    band drawn (:func:`_keep_rows`), kept in a memo (:data:`MEMO_SETUP_TRIANGLES`)."""

    setup: TriangleSetup
    rows: dict = field(default_factory=dict)


def _camera_key(camera) -> tuple:
    return (np.asarray(camera.view_matrix, dtype=np.float64).tobytes(),
            np.asarray(camera.projection, dtype=np.float64).tobytes(), int(camera.width), int(camera.height))


def _kept_geometry(frame: FrameContext, renderer) -> dict | None:
    """The memo's geometries of ``renderer``'s mesh by :func:`_setup_key`, or None when they are
    not kept (too big, or the memo is this render's own: keeping every setup to the end would
    raise its peak). Keyed by the mesh, not the renderer: a renderer that differs from a kept
    one in its material alone (a changed queue, pass or colour: the advice's fixes, an edit in
    the viewport) places the same triangles and finds their setup."""
    if not frame.keep_setups or renderer.mesh.triangle_count > MEMO_SETUP_TRIANGLES:
        return None
    return frame.memo.lookup("geometry", renderer.mesh, dict)


def _setups(frame: FrameContext, items: list[tuple], pool=None, parts: int = 1) -> list[_Geometry]:
    """The geometry through the frame's camera of each of ``items`` (renderer, its vertex colours
    or None, the pass of its vertex program or None): kept ones from the memo, the others set up
    together (:func:`vertex.setup_renderers`: each equals its own setup) and kept for the next
    frame (:func:`_setup_key`)."""
    keys = [_setup_key(frame, r, colors, program) for r, colors, program in items]
    with frame.memo_lock:
        kept = [_kept_geometry(frame, r) for r, _, _ in items]
        out = [None if k is None else k.get(key) for k, key in zip(kept, keys, strict=True)]
    todo = [i for i, g in enumerate(out) if g is None]
    if not todo:
        return out
    made = vertex.setup_renderers([setup_input(*items[i], color_space=frame.color_space,
                                               texels_of=frame.texture_texels) for i in todo],
                                  frame.camera, pool=pool, parts=parts)
    with frame.memo_lock:
        held = None  # triangles whose setups the memo holds (counted once something is to be kept)
        for i, setup in zip(todo, made, strict=True):
            out[i] = _Geometry(setup)
            if kept[i] is None:
                continue
            if held is None:
                held = sum(mesh.triangle_count * len(d) for mesh, d in frame.memo.entries("geometry"))
            mesh = items[i][0].mesh
            placed = frame.placements.get(id(mesh), ())
            cameras = list(dict.fromkeys(key[0] for key in kept[i]))
            if keys[i][0] not in cameras and len(cameras) >= MEMO_CAMERAS:  # the oldest camera's setups go
                gone = [key for key in kept[i] if key[0] == cameras[0]]
            else:  # placements through this camera that no renderer of the scene has (a moved object's old one)
                gone = [key for key in kept[i] if key[0] == keys[i][0] and key[1] not in placed]
            for key in gone:
                del kept[i][key]
                held -= mesh.triangle_count
            if held + mesh.triangle_count <= MEMO_SETUP_BUDGET:
                kept[i][keys[i]] = out[i]
                held += mesh.triangle_count
    return out


def _setup_key(frame: FrameContext, renderer, colors: np.ndarray | None, program: Pass | None) -> tuple:
    """What a kept vertex setup of a mesh (:func:`_kept_geometry`) is for: the frame's camera
    (first), the renderer's placement (its matrix's bytes), the attributes shading reads
    (:func:`setup_input`: normals, UVs, vertex colours), the colour space when the setup holds
    values converted into it (vertex colours, an outline's width factors) and the vertex
    program (:func:`.outline.outline_key`), with the material when its outline-width texture
    scales the program's corners (all else the program reads is the mesh's own)."""
    material = renderer.material
    converted = colors is not None or program is not None
    widths = material if program is not None and material.outline_width_tex is not None else None
    return (frame.camera_key, placement(renderer),
            material.lighting is not Lighting.Unlit, material.main_tex is not None, colors is not None,
            frame.color_space if converted else None, None if program is None else outline_key(program), widths)


def placement(renderer) -> bytes:
    """Where a renderer places its mesh, as a kept setup's key holds it: its matrix's bytes."""
    return np.asarray(renderer.matrix_world, dtype=np.float64).tobytes()


def placements_of(renderers) -> dict[int, set[bytes]]:
    """Per mesh (by id) the placements (:func:`placement`) of ``renderers``
    (:attr:`FrameContext.placements`)."""
    out: dict[int, set[bytes]] = {}
    for r in renderers:
        out.setdefault(id(r.mesh), set()).add(placement(r))
    return out


def _draw_state(frame: FrameContext, call: DrawCall, setup, inputs: CallInputs,
                selected: np.ndarray | None = None) -> tuple[DrawState, np.ndarray]:
    """A draw call's derived state and the triangles its Cull keeps (``selected`` when known)."""
    p = call.state
    zbound = None
    if (not p.zwrite and p.ztest in (CompareFunction.Less, CompareFunction.LEqual)
            and not (frame.reads_depth is not None and frame.reads_depth(call))):
        zbound = raster.depth_upper_codes(setup, p.offset_factor, p.offset_units)
    material = call.renderer.material
    selected = vertex.cull_select(setup, p.cull) if selected is None else selected
    peak = 0.0 if inputs.texels is None else inputs.texels.peak()
    dark_skip, saturated = lights.dark_skip_applies(p, material, inputs.lights.add, peak, frame.hdr, frame.samples,
                                                    False)
    early = fragment.early_depth_applies(p, frame.samples, False)
    plain = DrawState(call, material, inputs.texels, inputs.lights, frame.color_space, frame.hdr,
                      frame.width, zbound=zbound, mips=inputs.mips, samples=frame.samples, dark_skip=dark_skip,
                      dark_alpha=frame.buf.color[:, 3] if saturated else None,
                      early_depth=frame.buf.depth if early else None)
    if not (frame.observed and (frame.reads_call is None or frame.reads_call(call))):
        return plain, selected
    # Observed: every fragment is told of (no early depth test unless the observer reads written
    # fragments only; no alpha first); unlit ones keep rgb 0 where their colour is not read.
    hidden_unread = frame.reads_hidden is not None and not frame.reads_hidden(call)
    colors_read = True if frame.colors_read is None else frame.colors_read(call)
    if not isinstance(colors_read, np.ndarray):
        colors_read = bool(colors_read)  # True / False as such, whatever the observer returned
    observed_dark, observed_saturated = lights.dark_skip_applies(p, material, inputs.lights.add, peak, frame.hdr,
                                                                 frame.samples, colors_read is True)
    # Observed, the unreached fragments are all told of; where the stored alpha makes them change
    # nothing they are inert (DrawState.dark_skip), elsewhere merged with rgb 0.
    state = replace(plain, observed=True, unobserved=plain, colors_read=colors_read, dark_skip=observed_dark,
                    dark_alpha=frame.buf.color[:, 3] if observed_dark and observed_saturated else None,
                    early_depth=frame.buf.depth if fragment.early_depth_applies(
                        p, frame.samples, not hidden_unread) else None)
    return state, selected


def _prepare(frame: FrameContext, call: DrawCall, geometry: _Geometry, inputs: CallInputs, pool,
             parts: int) -> PreparedCall:
    """Cull, coverage and derived state of one draw call. Passes of a renderer with one Cull
    cover the same pixels: their rows are computed once (``geometry.rows``; in a memo across
    frames, those of the last band drawn: :func:`_kept_rows`)."""
    setup = geometry.setup
    known = _kept_rows(frame, geometry, call)
    state, selected = _draw_state(frame, call, setup, inputs, selected=None if known is None else known[0])
    shade = _shading_of(frame, call.state)
    if known is not None:
        return PreparedCall(call, setup, selected, raster.Rows(**vars(known[1])), state, shade)
    rows = raster.coverage_rows(setup, selected, frame.width, frame.height, pool=pool, parts=parts, band=frame.band,
                                samples=frame.sample_offsets)
    _keep_rows(frame, geometry, call, selected, rows)
    return PreparedCall(call, setup, selected, rows, state, shade)


def _kept_rows(frame: FrameContext, geometry: _Geometry, call: DrawCall) -> tuple | None:
    """(selected triangles, rows) of ``geometry`` kept for the call's Cull, the frame's MSAA
    samples and band, or None. Passes of a renderer with one Cull cover the same pixels."""
    known = geometry.rows.get((call.state.cull, frame.samples))
    return None if known is None or known[0] != frame.band else known[1:]


def _keep_rows(frame: FrameContext, geometry: _Geometry, call: DrawCall, selected, rows: raster.Rows) -> None:
    """Keep the rows of ``geometry`` for :func:`_kept_rows`, those of one band per Cull and
    sample count: a band render's replace another band's (the cut of the viewport's frames
    split between processes moves; the advice's measurements of one fix after another share
    theirs)."""
    key = (call.state.cull, frame.samples)
    known = geometry.rows.get(key)
    if known is None or known[0] != frame.band:
        geometry.rows[key] = (frame.band, selected, rows)


def _run_geometries(frame: FrameContext, runs: list[list[DrawCall]], colors: list, pool=None,
                    parts: int = 1) -> tuple[list[dict], list[tuple]]:
    """Per renderer run, its geometries by vertex program key (:func:`_programs`), set up together,
    and what to tell the user about each renderer (:func:`_setup_notes` of its plain setup, or of
    its first)."""
    programs = [_programs(run) for run in runs]
    items = [(run[0].renderer, run_colors, None if key is None else p)
             for run, run_colors, found in zip(runs, colors, programs, strict=True) for key, p in found.items()]
    made = iter(_setups(frame, items, pool, parts))
    out, notes = [], []
    for run, found in zip(runs, programs, strict=True):
        by_key = {key: next(made) for key in found}
        notes.append(_setup_notes(run[0].renderer, by_key.get(None, next(iter(by_key.values()))).setup))
        out.append(by_key)
    return out, notes


def _prepare_together(frame: FrameContext, runs: list[list[DrawCall]], inputs, colors) -> list[PreparedCall]:
    """Prepare many small renderers' draw calls with one vertex setup and one coverage pass for
    all of them (per-call array work on a few hundred triangles is mostly fixed cost)."""
    geometries, notes = _run_geometries(frame, runs, colors)
    for found in notes:
        frame.record(*found)
    items = []  # (call, geometry, state, selected, kept rows or None)
    for run, by_key, run_inputs in zip(runs, geometries, inputs, strict=True):
        for call, found in zip(run, run_inputs, strict=True):
            geometry = by_key[outline_key(call.state)]
            known = _kept_rows(frame, geometry, call)
            state, selected = _draw_state(frame, call, geometry.setup, found,
                                          selected=None if known is None else known[0])
            items.append((call, geometry, state, selected, None if known is None else known[1]))
    todo = [k for k, item in enumerate(items) if item[4] is None]
    made = raster.coverage_rows_many([(items[k][1].setup, items[k][3]) for k in todo], frame.width,
                                     frame.height, frame.band, frame.sample_offsets) if todo else []
    rows = [item[4] for item in items]
    for k, r in zip(todo, made, strict=True):
        rows[k] = r
        call, geometry, _, selected, _ = items[k]
        _keep_rows(frame, geometry, call, selected, r)
    return [PreparedCall(call, geometry.setup, selected, r if kept is None else raster.Rows(**vars(r)), state,
                         _shading_of(frame, call.state))
            for (call, geometry, state, selected, kept), r in zip(items, rows, strict=True)]


#: Below this many triangles a batch's renderers are prepared in the calling thread: their
#: many small array operations hold the GIL, so a second thread only adds contention.
PARALLEL_PREPARE_TRIANGLES = 1 << 15


def prepare_batch(frame: FrameContext, runs: list[list[DrawCall]]) -> list[PreparedCall]:
    """Prepare a batch's draw calls in draw order: renderers in parallel on the pool, or one
    renderer with its per-vertex and per-triangle work split over the pool."""
    runs = [run for run in runs if run[0].renderer.mesh.triangle_count > 0]
    inputs = [[frame.inputs_of(call) for call in run] for run in runs]
    colors = [frame.vertex_colors_of(run[0].renderer) for run in runs]

    def prepare_run(k: int, pool, parts: int):
        (by_key,), (notes,) = _run_geometries(frame, [runs[k]], [colors[k]], pool, parts)
        return notes, [_prepare(frame, call, by_key[outline_key(call.state)], found, pool, parts)
                       for call, found in zip(runs[k], inputs[k], strict=True)]

    triangles = sum(int(run[0].renderer.mesh.triangle_count) for run in runs)
    if len(runs) > 1 and triangles < PARALLEL_PREPARE_TRIANGLES:
        return _prepare_together(frame, runs, inputs, colors)
    if frame.pool is None or len(runs) <= 1:
        results = [prepare_run(k, frame.pool, frame.workers) for k in range(len(runs))]
    else:
        results = list(frame.pool.map(lambda k: prepare_run(k, None, 1), range(len(runs))))
    prepared: list[PreparedCall] = []
    for notes, items in results:
        frame.record(*notes)
        prepared.extend(items)
    return prepared
