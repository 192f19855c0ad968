"""Fusing consecutive draw calls of a batch (docs/pipeline.md §8, "Fused constant-colour draw calls"
and "Draw calls with shared shading"): several small calls drawn as one, bit for bit as one
after another.

Each small draw call costs a fixed amount of array-call overhead in every stage, whatever
its size. When nothing observes the render (an observer is told of each call's own
fragments), :func:`fuse_constant_calls` draws consecutive calls of one pass state whose
fragments each take their call's constant colour as one call, and :func:`fuse_shared_shading`
rasterises, interpolates and shades consecutive calls of one shading as one, then merges each
call's fragments with its own pass. Both return :class:`~.prepare.PreparedCall` s the driver
draws like any other.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from . import fragment, raster, shade, vertex
from .outline import outline_key
from .prepare import Member, PreparedCall
from .records import DrawState, ShadedFragments
from .scene import SceneMemo
from .vocabulary import CompareFunction, Lighting

#: Consecutive draw calls of one constant colour each are fused (drawn as one) in groups of at
#: most this many triangles: a call of a few hundred triangles costs mostly fixed array-call
#: overhead; big meshes gain nothing and would be copied (docs/benchmark.md, "Why the
#: constants are what they are").
FUSE_TRIANGLES = 1 << 15
#: Draw calls with shared shading are fused in groups of at most this many fragments (about a
#: chunk): beyond that the fixed cost saved is small beside the work, and a chunk holding rows of
#: several large calls loses their proof of distinct pixels (large planes ran much slower fused).
FUSE_FRAGMENTS = 1 << 17


def _constant_color(prepared: PreparedCall, memo: SceneMemo | None = None) -> np.ndarray | None:
    """(4,) float64: the colour the shader gives every fragment of the call, when that does not
    depend on the fragment (Unlit, no texture, no alpha test); else None. Kept in ``memo`` per
    material and colour space (Unlit reads no light)."""
    state = prepared.state
    material = state.material
    if prepared.shade is not fragment.shade_chunk:  # already specialised (a colourless pass)
        return None
    if (material.lighting is not Lighting.Unlit or state.texels is not None or state.pass_state.alpha_test
            or prepared.setup.object_colors is not None):
        return None

    outline = state.outline

    def compute() -> np.ndarray:  # what shade_chunk's flat path computes for each of the call's triangles
        return shade.shade(material, None, state.lights, state.color_space, np.zeros((1, 2), dtype=np.float64),
                           np.zeros((1, 3), dtype=np.float64), outline=outline)[0]

    return compute() if memo is None else memo.lookup(("constant colour", state.color_space, outline), material,
                                                      compute)


def fuse_constant_calls(prepared: list[PreparedCall], memo: SceneMemo | None = None) -> list[PreparedCall]:
    """Consecutive draw calls with one pass state whose fragments each take their call's
    constant colour (:func:`_constant_color`: text labels, unlit props) drawn as one call.

    Their setups and rows are concatenated in draw order and each fragment gets its call's
    colour from a palette, so the merger applies exactly the fragments the calls would apply
    one after another, in the same order (a pixel's fragments of several calls are layers of
    one chunk, as overlapping triangles of one call are). Saves the per-call fixed cost.
    ``memo``: where the calls' colours are kept across renders.
    """
    out: list[PreparedCall] = []
    group: list[tuple[PreparedCall, np.ndarray]] = []
    triangles = 0

    def flush() -> None:
        if len(group) > 1:
            out.append(_fused(group))
        else:
            out.extend(pr for pr, _ in group)
        group.clear()

    for pr in prepared:
        color = _constant_color(pr, memo) if pr.setup.count <= FUSE_TRIANGLES else None
        if color is None:
            flush()
            out.append(pr)
            triangles = 0
            continue
        if group and (pr.state.pass_state != group[0][0].state.pass_state
                      or triangles + pr.setup.count > FUSE_TRIANGLES):
            flush()
            triangles = 0
        group.append((pr, color))
        triangles += pr.setup.count
    flush()
    return out


def _concatenated(group: list[PreparedCall]) -> tuple[object, raster.Rows, np.ndarray, np.ndarray]:
    """The setups, rows and Cull-kept triangles of ``group``'s calls in order, as one call's:
    (setup, rows, selected, each call's first triangle (G,) int64 in the setup). World positions
    come along when shading reads them (Lambert under a point or spot light)."""
    first = group[0]
    positions = first.state.lights.positional and first.setup.object_normals is not None
    setup = vertex.concatenate_setups([pr.setup for pr in group], positions=positions)
    counts = np.array([pr.setup.count for pr in group], dtype=np.int64)
    offsets = counts.cumsum() - counts
    rows = raster.join_rows([pr.rows for pr in group], offsets)
    selected = np.concatenate([pr.selected + o for pr, o in zip(group, offsets, strict=True)])
    return setup, rows, selected, offsets


def _fused(group: list[tuple[PreparedCall, np.ndarray]]) -> PreparedCall:
    """One :class:`PreparedCall` drawing ``group``'s calls (prepared call, its colour) in order."""
    setup, rows, selected, _ = _concatenated([pr for pr, _ in group])
    counts = np.array([pr.setup.count for pr, _ in group], dtype=np.int64)
    # Palette entries by bytes (as shade_chunk's flat path keeps -0.0 and NaN colours apart).
    entries: dict[bytes, int] = {}
    for _, color in group:
        entries.setdefault(color.tobytes(), len(entries))
    palette = np.array([np.frombuffer(b, dtype=np.float64) for b in entries], dtype=np.float64)
    color_id = np.array([entries[c.tobytes()] for _, c in group], dtype=np.int32).repeat(counts)
    first = group[0][0]
    zbounds = [pr.state.zbound for pr, _ in group]
    zbound = None if any(z is None for z in zbounds) else np.concatenate(zbounds)
    state = replace(first.state, zbound=zbound)

    def shade_fused(setup, rows, start: int, stop: int, state: DrawState) -> ShadedFragments | None:
        return fragment.shade_constant_chunk(setup, rows, start, stop, state, color_id, palette)

    return PreparedCall(first.call, setup, selected, rows, state, shade_fused)


def _shading_key(prepared: PreparedCall, memo: SceneMemo | None = None) -> tuple | None:
    """Calls with equal keys shade every fragment alike and interpolate depth alike: the same
    texels, mip chain, lights (a ForwardAdd draw's own light) and :func:`shade.shading_key`, the
    same Offset and vertex program, setups with the same corner arrays.
    None: the call is not fused (specialised shading, or a big mesh that would be copied).
    ``memo``: where materials' keys are kept across renders."""
    if prepared.shade is not fragment.shade_chunk or prepared.setup.count > FUSE_TRIANGLES:
        return None
    state, setup = prepared.state, prepared.setup
    p = state.pass_state
    material = state.material
    key = shade.shading_key(material) if memo is None else memo.lookup("shading key", material,
                                                                         lambda: shade.shading_key(material))
    return (id(state.texels), id(state.mips), id(state.lights), key, float(p.offset_factor), float(p.offset_units),
            outline_key(p), state.outline, setup.object_normals is None, setup.object_uvs is None,
            setup.object_colors is None)


def fuse_shared_shading(prepared: list[PreparedCall], memo: SceneMemo | None = None) -> list[PreparedCall]:
    """Consecutive draw calls with one :func:`_shading_key` (the same material but for its
    pass and cutoff: blend-mode swatches, alpha-test cutoffs, a small mesh's passes) drawn
    as one: raster, interpolation and shading of their concatenated triangles once per chunk,
    then each call's fragments (a contiguous run of the chunk; calls in draw order) pass its
    own alpha test and merge with its own pass (:func:`.pipeline._draw_members`). Saves the
    per-call fixed cost of those stages. ``memo``: as :func:`_shading_key`'s."""
    out: list[PreparedCall] = []
    group: list[PreparedCall] = []
    key = None
    triangles = fragments = 0

    def flush() -> None:
        out.append(_shared(group) if len(group) > 1 else group[0])
        group.clear()

    for pr in prepared:
        count = int(pr.rows.length.sum())
        k = _shading_key(pr, memo) if count <= FUSE_FRAGMENTS else None
        if group and (k is None or k != key or triangles + pr.setup.count > FUSE_TRIANGLES
                      or fragments + count > FUSE_FRAGMENTS):
            flush()
        if k is None:
            out.append(pr)
            continue
        if not group:
            key, triangles, fragments = k, 0, 0
        group.append(pr)
        triangles += pr.setup.count
        fragments += count
    if group:
        flush()
    return out


def _shared(group: list[PreparedCall]) -> PreparedCall:
    """One :class:`PreparedCall` shading ``group``'s calls together; ``members`` draws each."""
    setup, rows, selected, firsts = _concatenated(group)
    passes = [pr.state.pass_state for pr in group]
    depth = any(p.zwrite or p.ztest is not CompareFunction.Always for p in passes)
    # The pass shade_chunk sees: depth when any call reads or writes it, no alpha test (each
    # call tests its own cutoff), the first call's blend state for the palette decision (calls
    # whose pass cannot use tables resolve it). When every call has a depth bound (no ZWrite,
    # ZTest Less or LEqual), rows proven to pass under the stricter of their tests need none.
    zbound, ztest = None, CompareFunction.LEqual if depth else CompareFunction.Always
    if all(pr.state.zbound is not None for pr in group):
        zbound = np.concatenate([pr.state.zbound for pr in group])
        ztest = CompareFunction.Less if any(p.ztest is CompareFunction.Less for p in passes) else ztest
    shading_pass = replace(passes[0], alpha_test=False, zwrite=any(p.zwrite for p in passes), ztest=ztest)
    first = group[0]
    # Fragments a ForwardAdd light does not reach are dropped only when they change nothing for
    # every call (all may drop them; the stored alpha checked when any needs it).
    dark_skip = all(pr.state.dark_skip for pr in group)
    dark_alpha = next((pr.state.dark_alpha for pr in group if pr.state.dark_alpha is not None), None)
    # An early depth test holds for the group when every call may take one with the same test,
    # Less or LEqual (the shading pass's): each call's merge then only lowers the stored depth.
    early = (all(pr.state.early_depth is not None for pr in group) and ztest in (CompareFunction.Less,
             CompareFunction.LEqual) and all(p.ztest is ztest for p in passes))
    state = replace(first.state, call=replace(first.call, state=shading_pass), zbound=zbound,
                    dark_skip=dark_skip, dark_alpha=dark_alpha if dark_skip else None,
                    early_depth=first.state.early_depth if early else None)
    members = [Member(pr.state, pr.tables, int(f)) for pr, f in zip(group, firsts, strict=True)]
    return PreparedCall(first.call, setup, selected, rows, state, fragment.shade_chunk, members=members)
