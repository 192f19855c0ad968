"""The frame debugger (docs/framedebugger.md): draw-call statistics, pixel history, and stepping through draws.

Everything here watches an ordinary render through :class:`blendlib.core.records.FrameObserver`:

- :func:`draw_list`: every draw call with its triangles, fragments rasterised and fragments
  written (what an occlusion query counts), from one render.
- :func:`pixel_history`: every fragment rasterised at one pixel, in the order the pipeline
  applies it (draw order, then primitive order), with the pixel's colour, depth and stencil
  before and after it and the test that discarded it. The render records only the fragments
  of the pixel; before/after come from replaying those fragments, one by one, through the
  output merger on a one-pixel buffer (exactly the merger the frame uses, so the last
  ``after`` is the frame's pixel).
- :class:`FrameCapture`: one render that keeps the draw statistics, the frame and buffer
  snapshots every few draws within a memory bound; :meth:`FrameCapture.frame_after` shows
  the frame after any draw by replaying from the nearest snapshot (never from scratch).

Coordinates are those of :class:`Frame`: X the column from the left, Y the row from the top.
Triangles are named by ``Mesh.loop_triangles`` (their index in the evaluated Blender mesh)
and faces by ``Mesh.polygons``; a synthetic mesh without them reports the triangle's index in
the renderer's mesh and ``polygon`` None.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace

import numpy as np

from ..core import merger, msaa, shade
from ..core.drawlist import DrawCall, draw_calls
from ..core.merger import FrameBuffers, Outcome
from ..core.pipeline import render_scene
from ..core.records import Frame, FrameObserver, ShadedFragments
from ..core.scene import DrawScene, SceneError
from ..core.vertex import DEPTH_MAX
from ..core.vocabulary import pass_state_text
from .snapshots import RowSnapshots

#: ``result`` of a fragment in the pixel history, by :class:`Outcome` (``alpha_to_mask``: MSAA only).
RESULT_NAMES = {Outcome.WRITTEN: "written", Outcome.ALPHA_TEST: "alpha_test", Outcome.STENCIL: "stencil",
                Outcome.DEPTH: "depth", Outcome.ALPHA_TO_MASK: "alpha_to_mask"}

#: Default memory bound of a capture's snapshots (bytes). A whole snapshot costs 9 bytes per
#: pixel in LDR (colour 4, depth 4, stencil 1) and 21 in HDR: 19 MB / 44 MB at 1920x1080, so the
#: default keeps at least 28 (LDR) or 12 (HDR) snapshots of a 1080p frame.
SNAPSHOT_MEMORY = 512 * 1024 * 1024


def float32_json(value: float) -> float:
    """The float whose shortest repr is the shortest text that reads back to the same float32
    (docs/json.md: JSON floats at full float32 precision)."""
    v = np.float32(value)
    if not np.isfinite(v):
        return float(v)
    return float(str(v))


def _rgba_json(values) -> list[float]:
    return [float32_json(v) for v in values]


def _call_json(call: DrawCall) -> dict:
    r = call.renderer
    return {"index": call.index, "object": r.name, "slot": r.slot, "material": r.material.name,
            "pass": call.pass_index, "pass_name": call.state.name, "light": _light_name(call), "queue": call.queue,
            "distance": float(call.distance), "state": pass_state_text(call.state)}


def _light_name(call: DrawCall) -> str | None:
    """The name of the light a ForwardAdd draw is for (one draw per per-pixel light), else None."""
    return None if call.light is None else call.light.name


# ------------------------------------------------------------------ draw list


@dataclass(frozen=True)
class DrawStats:
    """One draw call and what it did: ``triangles`` drawn (neither culled, nor degenerate, nor
    entirely outside the view), ``fragments`` rasterised (before any test), ``written`` (passed
    alpha test, stencil and depth: what an occlusion query counts).

    With MSAA a fragment is a pixel fragment (one per pixel with a covered sample, shaded once):
    ``written`` counts those with at least one sample written, ``samples_written`` the samples
    written (what an occlusion query counts then); None without MSAA."""

    call: DrawCall
    triangles: int
    fragments: int
    written: int
    samples_written: int | None = None

    def __repr__(self) -> str:  # the call's renderer holds the whole mesh: name it instead
        c = self.call
        return (f"DrawStats(call={c.index}, object={c.renderer.name!r}, slot={c.renderer.slot}, pass={c.pass_index}, "
                f"queue={c.queue}, triangles={self.triangles}, fragments={self.fragments}, written={self.written})")

    def to_json(self) -> dict:
        """The ``drawlist --json`` item (docs/json.md)."""
        out = _call_json(self.call)
        out.update(triangles=self.triangles, fragments=self.fragments, written=self.written)
        if self.samples_written is not None:
            out["samples_written"] = self.samples_written
        return out


class _StatsObserver(FrameObserver):
    """Counts fragments and writes per draw call (with MSAA, written samples too); optionally keeps
    snapshots and a pixel mask."""

    per_sample = True

    #: Counting and snapshots need no exact draw boundaries: snapshots are taken band by band
    #: (:meth:`snapshot_rows`) while calls are drawn in batches.
    exact_boundaries = False

    def __init__(self, snapshot_every: int = 0, last: int = 0, mark_draw: int | None = None, samples: int = 1,
                 size: tuple[int, int] = (0, 0)):
        self.lock = threading.Lock()
        self.samples = samples
        self.rasterised: dict[int, int] = {}
        self.passed: dict[int, int] = {}
        self.samples_passed: dict[int, int] = {}
        self.triangles: dict[int, int] = {}
        # After every snapshot_every-th call before the last, in the buffers' (width, height) ``size``.
        marks = list(range(snapshot_every, last, snapshot_every) if snapshot_every else ())
        self.snapshot_after = frozenset(marks)
        self._previous = dict(zip(marks, [None, *marks[:-1]], strict=False))
        self.width = int(size[0])
        self.snapshots = RowSnapshots(int(size[1]))
        self.mark_draw = mark_draw
        self.mask: np.ndarray | None = None

    def colors_read(self, call) -> bool:
        return False  # counts, pixels and outcomes only

    def draw_begin(self, call, buffers):
        if call.index == self.mark_draw:
            self.mask = np.zeros(buffers.width * buffers.height, dtype=bool)

    def fragments(self, call, frags: ShadedFragments, outcome: np.ndarray) -> None:
        hits = outcome == Outcome.WRITTEN
        samples = 0
        if hits.ndim == 2:  # MSAA: an outcome per sample
            samples = int(np.count_nonzero(hits))
            hits = hits.any(axis=1)
        written = int(np.count_nonzero(hits))
        with self.lock:
            self.rasterised[call.index] = self.rasterised.get(call.index, 0) + frags.count
            self.passed[call.index] = self.passed.get(call.index, 0) + written
            self.samples_passed[call.index] = self.samples_passed.get(call.index, 0) + samples
            if call.index == self.mark_draw:
                self.mask[frags.pix] = True
        if self.snapshot_after:
            self.snapshots.touched(frags.pix, self.width)

    def draw_end(self, call, buffers, triangles):
        self.triangles[call.index] = triangles

    def snapshot_rows(self, index, buffers, y0, y1):
        self.snapshots.take(index, self._previous[index], buffers, y0, y1)

    def stats(self, calls: list[DrawCall]) -> list[DrawStats]:
        return [DrawStats(c, self.triangles.get(c.index, 0), self.rasterised.get(c.index, 0),
                          self.passed.get(c.index, 0),
                          None if self.samples == 1 else self.samples_passed.get(c.index, 0)) for c in calls]


def draw_list(scene: DrawScene, *, progress: Callable[[float], None] | None = None,
              should_cancel: Callable[[], bool] | None = None, workers: int | None = None) -> list[DrawStats]:
    """Every draw call of ``scene`` in order with its statistics: one render of the scene that
    keeps no colour (:func:`colourless_calls`), since no statistic depends on one."""
    calls = draw_calls(scene)
    observer = _StatsObserver(samples=int(scene.msaa))
    render_scene(scene, progress=progress, should_cancel=should_cancel, workers=workers, observer=observer,
                 calls=colourless_calls(calls), output=False)
    return observer.stats(calls)


def colourless_calls(calls: list[DrawCall]) -> list[DrawCall]:
    """``calls`` with every pass drawn as ``ColorMask 0``: the same fragments and outcomes, no colour.

    A fragment's outcome (written, or failed by the depth, stencil or alpha test) and what it
    does to the depth and stencil buffers never read the colour buffer, nor the fragment's
    colour: only its alpha, where the alpha test or AlphaToMask reads it, which a pass with an
    alpha test or AlphaToMask still shades (:func:`.prepare.chunk_shading`). So a render of these
    calls gives an observer that reads no colour the fragments, outcomes and triangles of the
    real calls (same indices), without lighting or blending; its colour buffer stays clear."""
    return [replace(c, state=replace(c.state, color_mask=frozenset())) for c in calls]


# ------------------------------------------------------------------ pixel history


@dataclass(frozen=True)
class SampleResult:
    """One covered sample of an MSAA fragment in a pixel history (docs/json.md): the sample's
    index in the pattern, its depth code, its stored colour before and after the fragment (in
    ``frame.color`` units), its depth and stencil before and after, and ``result``."""

    sample: int
    depth_code: int
    before: tuple[float, float, float, float]
    after: tuple[float, float, float, float]
    depth_before: float
    depth_after: float
    stencil_before: int
    stencil_after: int
    result: str

    @property
    def depth(self) -> float:
        return float(np.float32(self.depth_code / float(DEPTH_MAX)))

    def to_json(self) -> dict:
        return {"sample": self.sample, "depth": float32_json(self.depth), "before": _rgba_json(self.before),
                "after": _rgba_json(self.after), "depth_before": float32_json(self.depth_before),
                "depth_after": float32_json(self.depth_after), "stencil_before": self.stencil_before,
                "stencil_after": self.stencil_after, "result": self.result}


@dataclass(frozen=True)
class PixelFragment:
    """One fragment of a pixel history (docs/json.md).

    ``source`` (4,) float64: the shader's RGBA in shading space before the LDR clamp.
    ``before``/``after`` (4,): the stored pixel in ``frame.color`` units (float32 values);
    ``depth*`` window depth code / (2**24 - 1) as float32; ``depth_code`` the 24-bit code.
    ``triangle``: index in the evaluated mesh's loop triangles (or the renderer's mesh);
    ``polygon``: the face index, None for a synthetic mesh. ``result``: ``written``,
    ``alpha_test``, ``stencil`` or ``depth``.

    With MSAA: ``coverage`` the samples the rasteriser found covered (bit s = sample s) and
    ``samples`` one :class:`SampleResult` per covered sample; ``before``/``after`` are then the
    resolved pixel, ``depth_before``/``depth_after``/``stencil_*`` those of sample 0 (what
    ``frame.depth``/``frame.stencil`` show), ``depth_code`` the depth at the lowest covered
    sample and ``result`` ``written`` when a sample was written, else the lowest covered
    sample's (``alpha_to_mask`` among them). None without MSAA.
    """

    call: DrawCall
    triangle: int
    polygon: int | None
    depth_code: int
    source: tuple[float, float, float, float]
    before: tuple[float, float, float, float]
    after: tuple[float, float, float, float]
    depth_before: float
    depth_after: float
    stencil_before: int
    stencil_after: int
    result: str
    coverage: int | None = None
    samples: tuple[SampleResult, ...] | None = None

    @property
    def depth(self) -> float:
        return float(np.float32(self.depth_code / float(DEPTH_MAX)))

    def to_json(self) -> dict:
        out = self._json()
        if self.samples is not None:
            out["coverage"] = self.coverage
            out["samples"] = [sample.to_json() for sample in self.samples]
        return out

    def _json(self) -> dict:
        call = self.call
        return {
            "draw": call.index, "object": call.renderer.name, "slot": call.renderer.slot,
            "material": call.renderer.material.name, "pass": call.pass_index, "pass_name": call.state.name,
            "light": _light_name(call), "triangle": self.triangle, "polygon": self.polygon,
            "depth": float32_json(self.depth),
            "source": _rgba_json(self.source), "before": _rgba_json(self.before), "after": _rgba_json(self.after),
            "depth_before": float32_json(self.depth_before), "depth_after": float32_json(self.depth_after),
            "stencil_before": self.stencil_before, "stencil_after": self.stencil_after, "result": self.result,
        }


@dataclass
class PixelHistory:
    """The history of pixel (``x``, ``y``): ``clear`` and ``final`` (4,) stored RGBA (``final`` is
    ``frame.color[y, x]``) and every fragment rasterised there, in application order; ``msaa``
    the samples per pixel."""

    x: int
    y: int
    clear: tuple[float, float, float, float]
    final: tuple[float, float, float, float]
    fragments: list[PixelFragment] = field(default_factory=list)
    msaa: int = 1

    def to_json(self) -> dict:
        """The ``pixel --json`` object (docs/json.md)."""
        out = {"x": self.x, "y": self.y, "clear": _rgba_json(self.clear), "final": _rgba_json(self.final),
               "fragments": [f.to_json() for f in self.fragments]}
        if self.msaa > 1:
            out["msaa"] = self.msaa
        return out


class _PixelObserver(FrameObserver):
    """Keeps the fragments that land on the target window pixels, in application order.

    A pixel belongs to one band, so its fragments arrive from one thread at a time, in
    primitive order, and draw calls follow each other: appending keeps each pixel's order.
    """

    exact_boundaries = False  # only fragments are read
    per_sample = True

    def __init__(self, targets: np.ndarray, width: int, height: int):
        self.lock = threading.Lock()
        self.single = int(targets[0]) if targets.size == 1 else None
        self.wanted = np.zeros(width * height, dtype=bool)
        self.wanted[targets] = True
        self.watched_rows = np.zeros(height, dtype=bool)  # chunks elsewhere are not reported
        self.watched_rows[targets // width] = True
        self.records: list[tuple] = []

    def colors_read(self, call) -> np.ndarray:
        return self.wanted  # the target pixels' colours only

    def fragments(self, call, frags: ShadedFragments, outcome: np.ndarray) -> None:
        hit = np.flatnonzero(frags.pix == self.single if self.single is not None else self.wanted[frags.pix])
        if hit.size == 0:
            return
        hits = frags.select(hit)  # deferred depths and triangles are computed for these only
        record = (call, hits.pix, hits.triangle, hits.depth, np.array(hits.colors(), dtype=np.float64),
                  outcome[hit].copy())
        with self.lock:
            self.records.append(record)


def _stored(buf: FrameBuffers) -> tuple[tuple, float, int]:
    color, depth, stencil = buf.output()
    return tuple(float(v) for v in color[0, 0]), float(depth[0, 0]), int(stencil[0, 0])


def _clear_buffers(scene: DrawScene, width: int = 1, height: int = 1) -> FrameBuffers:
    cs = scene.color_space
    clear = shade.gamma_color_to_shading(scene.clear_color[:3], cs) + (float(scene.clear_color[3]),)
    return FrameBuffers(width, height, scene.hdr, cs, clear, samples=int(scene.msaa))


def _stored_samples(buf: FrameBuffers) -> list[tuple[tuple, float, int]]:
    """Each sample of the 1x1 ``buf``: (colour in frame units, depth, stencil)."""
    codes = buf.sample_colors(np.zeros(1, dtype=np.int64))[0]
    colors = codes if buf.hdr else np.divide(codes, np.float32(255.0), dtype=np.float32)
    depths = np.divide(buf.depth, np.float32(DEPTH_MAX), dtype=np.float32)
    return [(tuple(float(v) for v in colors[s]), float(depths[s]), int(buf.stencil[s])) for s in range(buf.samples)]


def _replay(scene: DrawScene, records: list[tuple]) -> list[PixelFragment]:
    """Before/after of each fragment of ONE pixel: its fragments through the merger on a 1x1 buffer."""
    if int(scene.msaa) > 1:
        return _replay_samples(scene, records)
    buf = _clear_buffers(scene)
    zero = np.zeros(1, dtype=np.int64)
    out = []
    color, depth, stencil = _stored(buf)
    for call, triangle, code, rgba, outcome in records:
        mesh = call.renderer.mesh
        tri = int(triangle) if mesh.loop_triangles is None else int(mesh.loop_triangles[triangle])
        polygon = None if mesh.polygons is None else int(mesh.polygons[triangle])
        result = Outcome(int(outcome))
        if result is not Outcome.ALPHA_TEST:
            replayed = np.empty(1, dtype=np.int8)
            merger.merge(buf, call.state, zero, np.array([code], dtype=np.int64), rgba[None, :].copy(),
                         outcome=replayed)
            if Outcome(int(replayed[0])) is not result:  # the replay is the frame's own arithmetic
                raise RuntimeError(f"pixel replay disagrees with the render at draw {call.index}")
        after, depth_after, stencil_after = _stored(buf)
        out.append(PixelFragment(call, tri, polygon, int(code), tuple(float(v) for v in rgba), color, after,
                                 depth, depth_after, stencil, stencil_after, RESULT_NAMES[result]))
        color, depth, stencil = after, depth_after, stencil_after
    return out


def _replay_samples(scene: DrawScene, records: list[tuple]) -> list[PixelFragment]:
    """:func:`_replay` with MSAA: each fragment's covered samples through the same per-sample
    merger (:func:`blendlib.core.msaa.merge_samples`) on a 1x1 buffer of N samples."""
    buf = _clear_buffers(scene)
    n = buf.samples
    zero = np.zeros(1, dtype=np.int64)
    out = []
    color, depth, stencil = _stored(buf)
    samples = _stored_samples(buf)
    for call, triangle, codes, rgba, outcome in records:
        mesh = call.renderer.mesh
        tri = int(triangle) if mesh.loop_triangles is None else int(mesh.loop_triangles[triangle])
        polygon = None if mesh.polygons is None else int(mesh.polygons[triangle])
        covered = outcome != Outcome.NOT_COVERED
        coverage = int(sum(1 << s for s in range(n) if covered[s]))
        if not (outcome[covered] == Outcome.ALPHA_TEST).all():
            frags = ShadedFragments(zero, np.asarray(codes, dtype=np.int64)[None, :], rgba[None, :].copy(), None, None,
                                    None, None, True, coverage=np.array([coverage], dtype=np.uint8))
            replayed = np.empty((1, n), dtype=np.int8)
            msaa.merge_samples(buf, call.state, frags, outcome=replayed)
            if not np.array_equal(replayed[0], outcome):  # the replay is the frame's own arithmetic
                raise RuntimeError(f"pixel replay disagrees with the render at draw {call.index}")
        after, depth_after, stencil_after = _stored(buf)
        samples_after = _stored_samples(buf)
        results = [RESULT_NAMES[Outcome(int(outcome[s]))] for s in range(n) if covered[s]]
        per_sample = tuple(SampleResult(s, int(codes[s]), samples[s][0], samples_after[s][0], samples[s][1],
                                        samples_after[s][1], samples[s][2], samples_after[s][2],
                                        RESULT_NAMES[Outcome(int(outcome[s]))])
                           for s in range(n) if covered[s])
        lowest = per_sample[0]
        result = "written" if "written" in results else lowest.result
        out.append(PixelFragment(call, tri, polygon, lowest.depth_code, tuple(float(v) for v in rgba), color, after,
                                 depth, depth_after, stencil, stencil_after, result, coverage, per_sample))
        color, depth, stencil, samples = after, depth_after, stencil_after, samples_after
    return out


def _check_pixel(scene: DrawScene, x, y) -> tuple[int, int]:
    w, h = int(scene.camera.width), int(scene.camera.height)
    if isinstance(x, bool) or isinstance(y, bool) or not (isinstance(x, (int, np.integer))
                                                          and isinstance(y, (int, np.integer))):
        raise SceneError(f"pixel ({x!r}, {y!r}): X and Y must be integers")
    if not (0 <= x < w and 0 <= y < h):
        raise SceneError(f"pixel ({x}, {y}) is outside the {w}x{h} image (X 0..{w - 1} from the left, "
                         f"Y 0..{h - 1} from the top)")
    return int(x), int(y)


def pixel_histories(scene: DrawScene, pixels: Iterable[tuple[int, int]], *,
                    progress: Callable[[float], None] | None = None,
                    should_cancel: Callable[[], bool] | None = None,
                    workers: int | None = None) -> tuple[list[PixelHistory], Frame]:
    """The histories of several pixels (X from the left, Y from the top) from one render, and
    the frame. Costs one render plus a replay of each pixel's fragments."""
    pixels = [_check_pixel(scene, x, y) for x, y in pixels]
    return _histories(scene, pixels, None, progress, should_cancel, workers)


def pixel_history(scene: DrawScene, x: int, y: int, *, progress: Callable[[float], None] | None = None,
                  should_cancel: Callable[[], bool] | None = None, workers: int | None = None) -> PixelHistory:
    """The history of pixel (``x`` from the left, ``y`` from the top). An untouched pixel has an
    empty history (a valid answer). Raises :class:`SceneError` for a pixel outside the image.

    Only the pixel's row is rendered (a band render, whose every pixel equals the whole frame's:
    pixels never depend on one another, a mipmap's LOD included): the vertex setup of every
    renderer and that row's fragments, a fraction of a render on large frames."""
    x, y = _check_pixel(scene, x, y)
    row = int(scene.camera.height) - 1 - y  # buffer rows count from the bottom
    return _histories(scene, [(x, y)], (row, row + 1), progress, should_cancel, workers)[0][0]


def _histories(scene: DrawScene, pixels: list[tuple[int, int]], band: tuple[int, int] | None, progress,
               should_cancel, workers) -> tuple[list[PixelHistory], Frame]:
    """:func:`pixel_histories` of checked ``pixels``, rendering buffer rows ``band`` (y0, y1)
    only when given (every pixel must lie there; the Frame is then those rows, top row first)."""
    w, h = int(scene.camera.width), int(scene.camera.height)
    window = np.array([(h - 1 - y) * w + x for x, y in pixels], dtype=np.int64)
    observer = _PixelObserver(window, w, h)
    frame = render_scene(scene, progress=progress, should_cancel=should_cancel, workers=workers,
                         observer=observer, band=band)
    top = 0 if band is None else h - band[1]  # the image row of the Frame's first row
    per_pixel: dict[int, list[tuple]] = {int(p): [] for p in window}
    for call, pix, tri, depth, colors, outcome in observer.records:
        for k in range(pix.size):  # only fragments on the asked pixels
            per_pixel[int(pix[k])].append((call, tri[k], depth[k], colors[k], outcome[k]))
    clear, _, _ = _stored(_clear_buffers(scene))
    out = []
    for (x, y), p in zip(pixels, window, strict=True):
        final = tuple(float(v) for v in frame.color[y - top, x])
        out.append(PixelHistory(x, y, clear, final, _replay(scene, per_pixel[int(p)]), int(scene.msaa)))
    return out, frame


# ------------------------------------------------------------------ stepping


def snapshot_bytes(width: int, height: int, hdr: bool, samples: int = 1) -> int:
    """Memory of one whole buffer snapshot (:mod:`.snapshots`): colour (4 or 16 bytes), depth (4:
    24-bit codes) and stencil (1) per pixel; with MSAA per sample, plus a uniform flag (1) per
    pixel. A snapshot that shares rows with the one before it holds less."""
    if samples == 1:
        return int(width) * int(height) * ((16 if hdr else 4) + 4 + 1)
    return int(width) * int(height) * (samples * ((16 if hdr else 4) + 4 + 1) + 1)


@dataclass(eq=False)
class FrameCapture:
    """One captured frame: draw statistics, the final frame and snapshots for stepping.

    Snapshots are taken after every ``interval``-th draw call, at most ``memory`` bytes in all
    (``interval = ceil(draws / (memory // snapshot_bytes))``), so :meth:`frame_after` replays
    at most ``interval`` draw calls from the nearest snapshot.
    """

    scene: DrawScene
    stats: list[DrawStats]
    frame: Frame
    snapshots: RowSnapshots
    interval: int

    @property
    def calls(self) -> list[DrawCall]:
        return [s.call for s in self.stats]

    @property
    def snapshot_memory(self) -> int:
        """Bytes held by the snapshots."""
        return self.snapshots.nbytes

    @classmethod
    def capture(cls, scene: DrawScene, *, memory: int = SNAPSHOT_MEMORY,
                progress: Callable[[float], None] | None = None, should_cancel: Callable[[], bool] | None = None,
                workers: int | None = None) -> FrameCapture:
        """Render ``scene`` once, keeping statistics and snapshots within ``memory`` bytes (0: none)."""
        calls = draw_calls(scene)
        cam = scene.camera
        per = snapshot_bytes(cam.width, cam.height, scene.hdr, int(scene.msaa))
        most = int(memory) // per if per else 0
        interval = 0 if most <= 0 or not calls else max(1, math.ceil(len(calls) / most))
        observer = _StatsObserver(snapshot_every=interval, last=len(calls), samples=int(scene.msaa),
                                  size=(cam.width, cam.height))
        frame = render_scene(scene, progress=progress, should_cancel=should_cancel, workers=workers,
                             observer=observer, calls=calls)
        return cls(scene, observer.stats(calls), frame, observer.snapshots, interval)

    def frame_after(self, k: int, *, highlight: bool = False,
                    workers: int | None = None) -> tuple[Frame, np.ndarray | None]:
        """The frame after draw ``k`` (0 = cleared; ≥ the draw count = the whole frame), replayed
        from the nearest snapshot before it, and with ``highlight`` the (H, W) bool mask (row 0 =
        top) of the pixels draw ``k`` rasterised (None without)."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 0:
            raise SceneError(f"draw {k!r}: must be an integer 0 or more")
        n = len(self.stats)
        k = min(int(k), n)
        if k == n and not highlight:
            return self.frame, None
        base = max((s for s in self.snapshots if s < k), default=0)
        resume = (self.snapshots[base], base) if base else None
        observer = _StatsObserver(mark_draw=k if highlight and k > 0 else None)
        frame = render_scene(self.scene, until_draw=k, resume=resume, workers=workers,
                             observer=observer if highlight else None, calls=self.calls)
        if not highlight:
            return frame, None
        cam = self.scene.camera
        mask = observer.mask
        if mask is None:
            return frame, np.zeros((cam.height, cam.width), dtype=bool)
        return frame, mask.reshape(cam.height, cam.width)[::-1].copy()


def draw_list_json(stats: list[DrawStats]) -> list[dict]:
    return [s.to_json() for s in stats]


__all__ = ["DrawStats", "FrameCapture", "PixelFragment", "PixelHistory", "RESULT_NAMES", "SNAPSHOT_MEMORY",
           "SampleResult", "colourless_calls", "draw_list", "draw_list_json", "float32_json", "pixel_histories",
           "pixel_history", "snapshot_bytes"]
