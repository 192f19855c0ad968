"""The viewport's rendering off the main thread: a reduced frame first, then the full one (bpy-free).

:class:`ViewportScheduler` renders the newest submitted :class:`~blendlib.core.scene.DrawScene`
on one worker thread and drops stale work as soon as a newer request comes. It works on
bpy-free values because bpy is not thread-safe: the add-on extracts the scene on the main
thread (:func:`blendlib.blender.viewport.extract_template`, :func:`~blendlib.blender.viewport.region_view`)
and hands the result over. Large frames go through a :class:`~.bandprocs.BandRenderer`
(two screen bands, one drawn by a helper process).
"""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Callable, Hashable

from ..core.records import Frame, RenderCancelled
from ..core.scene import Camera, DrawScene, SceneError
from . import bandprocs

#: The reduced frame is 1/REDUCED_FACTOR of the full one per side (1/16 of the pixels).
REDUCED_FACTOR = 4
#: Frames of at most this many pixels are rendered at full size at once (no reduced frame first).
REDUCED_MIN_PIXELS = 128 * 128
#: The helper process begins a full frame during the reduced one when the previous split frame
#: took at least this many seconds of work in both processes together (a full frame of half
#: that). Both cores then work from the start, which brings heavy full frames sooner, but the
#: reduced frame shares the machine and takes longer: scenes whose full frames are well within
#: the viewport's budget keep their reduced frames quick (docs/benchmark.md, "Why the constants
#: are what they are").
BEGIN_AFTER_WORK_S = 0.100


def begins_early(bands: bandprocs.BandRenderer | None, begin_after_work_s: float = BEGIN_AFTER_WORK_S) -> bool:
    """Whether the helper of ``bands`` should begin the next full frame while the reduced one
    renders: after a split frame of ``begin_after_work_s`` or more of work in both processes
    together (never before the first split frame, nor without a helper)."""
    work = None if bands is None else bands.last_work_s
    return work is not None and work >= begin_after_work_s


def reduced_size(width: int, height: int, factor: int = REDUCED_FACTOR,
                 min_pixels: int = REDUCED_MIN_PIXELS) -> tuple[int, int] | None:
    """The size of the quick first frame (each side divided by ``factor``, rounded up), or None
    when the full frame is small enough to come first."""
    if factor <= 1 or width * height <= min_pixels:
        return None
    return -(-width // factor), -(-height // factor)


@dataclasses.dataclass(frozen=True, eq=False)
class ViewFrame:
    """A finished viewport frame: the Frame, the request key it answers, and whether it is full size."""

    frame: Frame
    key: Hashable
    full: bool


class ViewportScheduler:
    """Renders the newest submitted DrawScene on one worker thread: reduced frame, then full.

    ``submit`` cancels whatever is running or waiting (the render's ``should_cancel`` turns True,
    so it stops between chunks) and queues the new scene. Each finished frame becomes
    :meth:`latest` and ``on_ready()`` is called (from the worker thread; the add-on tags a
    redraw). ``render`` is :func:`blendlib.core.pipeline.render_scene` or a stand-in with its
    signature; by default a :class:`~.bandprocs.BandRenderer` of the scheduler's own
    (large frames drawn in two bands by this process and a helper process, ended by :meth:`close`;
    the helper starts with the first large frame, which renders here meanwhile; from then on it
    begins each full frame's band while the reduced frame renders here when the previous split
    frame took ``begin_after_work_s`` or more, both processes' times together). ``error``
    holds the last render's one-line error, cleared by the next success.
    """

    def __init__(self, on_ready: Callable[[], None] = lambda: None,
                 render: Callable[..., Frame] | None = None,
                 factor: int = REDUCED_FACTOR, min_pixels: int = REDUCED_MIN_PIXELS,
                 begin_after_work_s: float = BEGIN_AFTER_WORK_S):
        self._on_ready = on_ready
        self.bands = bandprocs.BandRenderer(start=False) if render is None else None
        self._render = self.bands if render is None else render
        self._factor = factor
        self._min_pixels = min_pixels
        self._begin_after_work_s = begin_after_work_s
        self._cond = threading.Condition()
        self._generation = 0
        self._pending: tuple[int, DrawScene, Hashable] | None = None
        self._running = False
        self._latest: ViewFrame | None = None
        self._closed = False
        self._thread: threading.Thread | None = None
        self.error: str | None = None

    # -- main thread ---------------------------------------------------------------------------
    def submit(self, draw: DrawScene, key: Hashable) -> None:
        """Render ``draw`` (its camera is the view) for request ``key``; stale work is dropped."""
        with self._cond:
            if self._closed:
                raise RuntimeError("viewport scheduler is closed")
            self._generation += 1
            self._pending = (self._generation, draw, key)
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="unity-passes-viewport", daemon=True)
                self._thread.start()
            self._cond.notify_all()

    def latest(self) -> ViewFrame | None:
        """The newest finished frame (possibly of an older request), or None."""
        with self._cond:
            return self._latest

    @property
    def busy(self) -> bool:
        with self._cond:
            return self._pending is not None or self._running

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until nothing is queued or running; False on timeout (tests, scripts)."""
        with self._cond:
            return self._cond.wait_for(lambda: self._pending is None and not self._running, timeout)

    def close(self, timeout: float | None = 5.0) -> None:
        """Cancel all work and stop the worker thread (idempotent)."""
        with self._cond:
            self._closed = True
            self._generation += 1
            self._pending = None
            self._cond.notify_all()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
        if self.bands is not None:
            self.bands.close()

    # -- worker thread -------------------------------------------------------------------------
    def _stages(self, camera: Camera) -> list[tuple[Camera, bool]]:
        small = reduced_size(camera.width, camera.height, self._factor, self._min_pixels)
        stages = [] if small is None else [(dataclasses.replace(camera, width=small[0], height=small[1]), False)]
        return stages + [(camera, True)]

    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._pending is not None or self._closed)
                if self._closed:
                    self._running = False
                    self._cond.notify_all()
                    return
                generation, draw, key = self._pending
                self._pending = None
                self._running = True

            def stale(generation=generation) -> bool:
                return self._generation != generation

            stages = [(dataclasses.replace(draw, camera=camera), full) for camera, full in self._stages(draw.camera)]
            if len(stages) > 1 and begins_early(self.bands, self._begin_after_work_s) and not stale():
                # The helper process starts on the full frame's top band while this thread
                # renders the reduced frame (both cores busy from the start).
                self.bands.begin(stages[-1][0])
            for scene, full in stages:
                if stale():
                    break
                try:
                    frame = self._render(scene, should_cancel=stale)
                except RenderCancelled:
                    break
                except (SceneError, MemoryError) as exc:
                    self.error = str(exc) or type(exc).__name__
                    break
                except Exception as exc:  # noqa: BLE001 - shown in the viewport, the worker lives on
                    self.error = f"internal error: {type(exc).__name__}: {exc}"
                    break
                with self._cond:
                    if stale():
                        break
                    self._latest = ViewFrame(frame, key, full)
                    self.error = None
                self._on_ready()
            with self._cond:
                self._running = False
                self._cond.notify_all()
