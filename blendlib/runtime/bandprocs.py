"""Frames split across processes: two horizontal bands drawn at the same time (docs/pipeline.md §8).

Threads of one process share one interpreter lock, and on a viewport-sized frame numpy's array
calls are short enough that two rendering threads spend much of their time waiting for it (a
profile of a two-thread frame shows the lock held most of the wall time, so a second thread
gains little there). A band drawn by another process has a lock of its own.

:class:`BandRenderer` keeps one helper process, started once and reused for every frame: the
viewport's scheduler has one, and final renders (F12, ``blendlib.render``, the CLI) share
:func:`final_renderer`'s. Per
frame the helper draws the top band and this process the bottom one, both through
:func:`~blendlib.core.pipeline.render_scene`'s ``band`` (each does the whole vertex setup and
draws only its rows). Pixels never depend on one another, so the joined frame equals
``render_scene``'s bit for bit. The cut between the bands follows the measured times of the
previous frame, so both halves end together. :meth:`BandRenderer.begin` starts the helper's band
of a frame early (during the viewport's reduced frame); the helper keeps the last scene, so a
view change sends only the camera, and the parts of it a changed scene shares
(:func:`~blendlib.core.scene.reuse_unchanged`) are sent by number, not again (:class:`_PartsWriter`).

Requests and replies are pickled messages over a :mod:`multiprocessing.connection` pair
(``send_bytes`` / ``recv_bytes`` frame them; ``wait`` polls while ``should_cancel`` is
checked). The helper's rows come back through an anonymous shared file (``memfd_create``):
nothing named is left behind if either process dies. Its first byte is the stop flag, which
the helper reads between chunks. A large request (a scene's meshes, :data:`SHARED_REQUEST_BYTES`)
travels the other way through the same file, where the band's rows will go: the connection
carries only its length, and the helper copies it out before it draws.

Frames below :data:`MIN_PIXELS`, scenes over a renderer's triangle limit (final renders:
:data:`FINAL_MAX_TRIANGLES`), renders with other options, and machines where the helper cannot
run (one core, Windows, a helper that failed) go to ``render_scene`` unchanged.

One concern in one module, over 700 lines: both ends of one wire protocol — the parent's
requests (:class:`BandRenderer`, :class:`_PartsWriter`) and the helper's loop that answers them
(:func:`serve`, :class:`_PartsReader`) — kept side by side, because a message changed on one end
must change on the other in the same edit.
"""

from __future__ import annotations

import dataclasses
import io
import mmap
import os
import pickle
import signal
import subprocess
import sys
import tempfile
import threading
import time
import weakref
from collections.abc import Callable
from multiprocessing import Pipe
from multiprocessing.connection import Connection, wait

import numpy as np

from ..core import merger, pipeline
from ..core.records import Frame, RenderCancelled
from ..core.scene import DrawScene, SceneError, SceneMemo, scene_parts
from . import allocator

#: Frames of fewer pixels render in one process: the hand-over (pickling the scene, copying the
#: helper's rows back) outweighs the half frame it saves (docs/benchmark.md, "Why the constants
#: are what they are").
MIN_PIXELS = 200_000

#: Fragments per chunk in a viewport band render. Smaller than ``render_scene``'s default: with
#: no other thread contending for the interpreter lock, arrays that stay in the core's own 1 MB
#: L2 cache pay on viewport-sized frames (docs/benchmark.md, "Why the constants are what they
#: are"); final renders keep the default (:func:`final_renderer`).
BAND_CHUNK_CANDIDATES = 1 << 15

#: Bytes before the pixel data in the shared file; byte 0 is the stop flag the helper polls
#: (the shared memory, not a message: the helper reads it between chunks without waiting).
_HEAD = 64
#: How often a waiting render polls ``should_cancel`` (seconds).
_POLL_S = 0.01
#: Requests of this many bytes or more (a scene's meshes) go through the shared file: written
#: there in one copy, and the connection carries :data:`_SHARED_REQUEST` and their length. Sent
#: through the connection, the sender waits until the helper has read every socket buffer-full:
#: S1's 11.6 MB scene held up this process's band 5–80 ms a frame (docs/benchmark.md, round twelve).
SHARED_REQUEST_BYTES = 1 << 20
#: The first bytes of a message that says "the request is in the shared file" (a pickle starts
#: with its protocol byte, 0x80, so no request message starts so); the length follows, 8 bytes.
_SHARED_REQUEST = b"shared:"
#: A helper that dropped its scene (after a final frame) gives the heap it freed back to the
#: system once it has waited this long for the next request: frames that follow one another (an
#: animation, repeated F12, the benchmark) reuse its pages instead of faulting fresh zeroed ones
#: in, and an idle helper still holds little (docs/benchmark.md, "Why the constants are what
#: they are").
IDLE_TRIM_S = 2.0


def _band_bytes(rows: int, width: int) -> int:
    """Shared bytes for a band: colour (rows, W, 4) float32, depth (rows, W) float32, stencil uint8."""
    return _HEAD + rows * width * (16 + 4 + 1)


def _band_views(buffer: mmap.mmap, rows: int, width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The (colour, depth, stencil) arrays of a band laid out in ``buffer`` (:func:`_band_bytes`)."""
    n = rows * width
    color = np.frombuffer(buffer, dtype=np.float32, count=n * 4, offset=_HEAD).reshape(rows, width, 4)
    depth = np.frombuffer(buffer, dtype=np.float32, count=n, offset=_HEAD + 16 * n).reshape(rows, width)
    stencil = np.frombuffer(buffer, dtype=np.uint8, count=n, offset=_HEAD + 20 * n).reshape(rows, width)
    return color, depth, stencil


def _send(conn: Connection, message) -> None:
    """Send one pickled message (a request's scene parts go through :class:`_PartsWriter`)."""
    conn.send_bytes(pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL))


def _receive(conn: Connection):
    """The next message; raises EOFError when the other process closed its end (or died)."""
    return pickle.loads(conn.recv_bytes())


class _PartsWriter:
    """Pickles requests for the helper so that each scene part (texture, material, mesh,
    renderer: :func:`~blendlib.core.scene.scene_parts`) travels once: a part the helper holds
    from an earlier request is sent as its number.

    After :func:`~blendlib.core.scene.reuse_unchanged` a changed scene shares most parts with
    the last one: such a request carries the changed parts only (pickling a template's meshes
    again was a noticeable share of the viewport's reduced frame), and the helper's memo keeps what it
    derived from the rest. A message is: the numbers the helper may forget and a count, then each
    new part as (number, part) with the parts it holds as numbers, then the request. A request that
    sends none of the parts the helper holds has the count -1 and one plain pickle (first number,
    new parts, request). The numbers kept are those of the parts of the last scene sent, on both
    sides.
    """

    def __init__(self) -> None:
        self._numbers: dict[int, tuple[object, int]] = {}  # id(part) -> (part, number)
        self._next = 0

    def dumps(self, request, scene: DrawScene | None) -> bytes:
        """The message for ``request``; ``scene``: the scene it sends (None: a request without one)."""
        out = io.BytesIO()
        numbers = self._numbers

        class Pickler(pickle.Pickler):
            def persistent_id(self, obj):
                hit = numbers.get(id(obj))
                return hit[1] if hit is not None and hit[0] is obj else None

        parts = scene_parts(scene) if scene is not None else []
        alive = {id(p) for p in parts}
        forget = [] if scene is None else [n for key, (_, n) in numbers.items() if key not in alive]
        new = [p for p in parts if id(p) not in numbers]
        if len(new) == len(parts):
            # Nothing the helper holds is sent (a final frame's new scene, a view): one plain
            # pickle, without a persistent_id call per object pickled (most of a small scene's
            # pickling time); the new parts' numbers travel with them.
            first = self._next
            for part in new:
                numbers[id(part)] = (part, self._next)
                self._next += 1
            pickle.Pickler(out, protocol=pickle.HIGHEST_PROTOCOL).dump((forget, -1))
            pickle.Pickler(out, protocol=pickle.HIGHEST_PROTOCOL).dump((first, new, request))
        else:
            pickle.Pickler(out, protocol=pickle.HIGHEST_PROTOCOL).dump((forget, len(new)))
            for part in new:
                Pickler(out, protocol=pickle.HIGHEST_PROTOCOL).dump((self._next, part))
                numbers[id(part)] = (part, self._next)
                self._next += 1
            Pickler(out, protocol=pickle.HIGHEST_PROTOCOL).dump(request)
        if scene is not None:
            self._numbers = {key: hit for key, hit in numbers.items() if key in alive}
        return out.getvalue()

    def restarted(self) -> _PartsWriter:
        """A writer that counts no part as held, numbering on from this one's: for a message that
        was made and never sent (the helper may lack parts this writer counts as held, so the next
        request must send its scene whole; parts the helper does hold linger there until it drops
        its scene)."""
        fresh = _PartsWriter()
        fresh._next = self._next
        return fresh


class _PartsReader:
    """The helper's side of :class:`_PartsWriter`: the parts it holds, by number."""

    def __init__(self) -> None:
        self.parts: dict[int, object] = {}

    def loads(self, data: bytes):
        stream = io.BytesIO(data)
        parts = self.parts

        class Unpickler(pickle.Unpickler):
            def persistent_load(self, number):
                try:
                    return parts[number]
                except KeyError:
                    raise pickle.UnpicklingError(f"scene part {number} was never sent") from None

        forget, count = pickle.Unpickler(stream).load()
        for number in forget:
            parts.pop(number, None)
        if count < 0:  # one plain pickle: the new parts (numbered from ``first``) and the request
            first, new, request = pickle.Unpickler(stream).load()
            parts.update(enumerate(new, start=first))
            return request
        for _ in range(count):
            number, part = Unpickler(stream).load()
            parts[number] = part
        return Unpickler(stream).load()


def _same_but_camera(scene: DrawScene, other: DrawScene | None) -> bool:
    """Whether ``scene`` differs from ``other`` at most in its camera, every other field being
    the very same object (the viewport's frames are ``dataclasses.replace(template, camera=…)``)."""
    return other is not None and all(getattr(scene, f.name) is getattr(other, f.name)
                                     for f in dataclasses.fields(DrawScene) if f.name != "camera")


def _anonymous_file() -> int:
    """A file descriptor of a file with no name, the band's shared memory.

    ``memfd_create`` (Linux), else an unlinked temporary file: nothing has a name, so nothing
    is left behind when either process dies, however it dies (a named segment of
    ``multiprocessing.shared_memory`` outlives a crash, and its resource tracker is another
    process to run).
    """
    if hasattr(os, "memfd_create"):
        return os.memfd_create("unity-passes-bands")
    handle = tempfile.TemporaryFile()
    fd = os.dup(handle.fileno())
    handle.close()
    return fd


class _Helper:
    """One helper process (``python -m blendlib.runtime.bandprocs CONN FD``), the connection
    to it (a :func:`multiprocessing.Pipe`: length-framed messages over a socket pair whose
    other end the helper inherits as descriptor CONN) and the file FD it shares."""

    def __init__(self) -> None:
        self.fd = _anonymous_file()
        self.size = 0
        self.buffer: mmap.mmap | None = None
        env = dict(os.environ)
        # The helper imports blendlib and numpy from wherever this process found them (a venv,
        # Blender's bundled Python plus the extension's wheels).
        env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p and os.path.isdir(p))
        self.conn, theirs = Pipe()
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "blendlib.runtime.bandprocs", str(theirs.fileno()), str(self.fd)],
                stdin=subprocess.DEVNULL, pass_fds=(theirs.fileno(), self.fd), env=env,
                # Its own session: a terminal's Ctrl+C goes to the parent's process group only
                # (the parent stops the helper's band itself), even while the helper starts.
                start_new_session=True,
            )
        except OSError:
            self.conn.close()
            os.close(self.fd)
            raise
        finally:
            theirs.close()  # the helper's copy stays open: its end closes when it exits
        self.ready = False
        self.closed = False
        #: The last scene sent: the helper keeps it, so a frame that differs only in its camera
        #: sends just the camera (pickling a whole scene is a noticeable part of a frame).
        self.scene: DrawScene | None = None
        #: The scene parts the helper holds (a changed scene sends only its new parts).
        self.parts = _PartsWriter()
        #: Whether the helper may hold a scene (a request was sent since the last "drop").
        self.holding = False
        #: Whether a request was sent whose answer has not been read: nothing else may be sent
        #: or read until it is (:meth:`BandRenderer._abandon`).
        self.in_flight = False

    def poll_ready(self, timeout: float = 0.0) -> bool:
        """Whether the helper has started (read its hello if it has arrived)."""
        if not self.ready and self.proc.poll() is None and self.conn.poll(timeout):
            try:
                self.ready = _receive(self.conn) == ("ready",)
            except (OSError, EOFError, pickle.UnpicklingError):
                self.ready = False
        return self.ready and self.proc.poll() is None

    def read_reply(self):
        """The answer to the request in flight (EOFError when the helper died, its end closed).
        After an error answer the helper holds no scene: the next frame sends it whole."""
        reply = _receive(self.conn)
        self.in_flight = False
        if reply[0] == "error":
            self.scene = None
        return reply

    def reserve(self, size: int) -> mmap.mmap:
        """The shared file grown to at least ``size`` bytes, mapped here."""
        if self.buffer is None or size > self.size:
            if self.buffer is not None:
                self.buffer.close()
            os.ftruncate(self.fd, size)
            self.size = size
            self.buffer = mmap.mmap(self.fd, size)
        return self.buffer

    def close(self) -> None:
        """End the process (it exits when its end of the connection sees ours close) and release
        the file, once (the descriptor's number may be reused after)."""
        if self.closed:
            return
        self.closed = True
        try:
            self.conn.close()
            self.proc.wait(timeout=2.0)
        except (OSError, subprocess.TimeoutExpired):
            self.proc.kill()
            self.proc.wait()
        finally:
            try:
                os.close(self.fd)
            except OSError:
                pass
        if self.buffer is not None:
            try:
                self.buffer.close()
            except BufferError:  # a view of the last frame is still referenced: freed with it
                pass


@dataclasses.dataclass(eq=False)
class _HelperBand:
    """The helper's band of a frame, requested and not yet collected."""

    scene: DrawScene
    cut: int  # rows [0, cut) are drawn here, [cut, height) by the helper
    buffer: mmap.mmap
    sent_at: float  # perf_counter when the request was written: the helper starts then
    begun: bool  # requested by :meth:`BandRenderer.begin` (ahead of the call that collects it)


class BandRenderer:
    """:func:`~blendlib.core.pipeline.render_scene` for viewport and final frames, large ones split
    in two bands drawn at once by this process and a helper process (see the module docstring).

    Call it as ``render_scene`` (``should_cancel`` and ``progress`` are honoured; any other
    option renders in this process). ``start=False`` defers starting the helper to the first
    large frame. While the helper is starting, or after it failed (:attr:`failure` says why),
    frames render in this process. One frame at a time; :meth:`close` ends the helper.

    :meth:`begin` starts the helper on a frame's band ahead of the call for that frame, so it
    works while this process does something else (the viewport's reduced frame).

    A frame whose scene differs from the previous one only in its camera (every other field the
    very same object, as in the viewport's frames of one template) sends the helper just the
    camera: change a scene by building a new one, never by writing into its arrays.
    """

    def __init__(self, min_pixels: int = MIN_PIXELS, start: bool = True, max_triangles: int | None = None,
                 keep_scene: bool = True, chunk_candidates: int = BAND_CHUNK_CANDIDATES):
        self.min_pixels = int(min_pixels)
        #: Fragments per chunk in both bands.
        self.chunk_candidates = int(chunk_candidates)
        #: Scenes of more triangles render in this process (None: no limit): each band does the
        #: whole vertex setup, and the scene is pickled for the helper.
        self.max_triangles = max_triangles
        #: Whether the helper (and this renderer's memo) keep the last scene after a frame: the
        #: viewport's next frame is mostly the same scene; final renders build a new scene each
        #: time, so :func:`final_renderer` frees it (an idle helper holds nothing of it).
        self.keep_scene = keep_scene
        #: The next request asks the helper to forget its blend tables kept from earlier frames
        #: (:meth:`forget_tables`).
        self._forget_tables = False
        #: Share of the rows drawn here (the bottom band), tuned frame by frame; frames started
        #: by :meth:`begin` keep a share of their own (the helper has a head start there).
        self.fraction = 0.5
        self.begun_fraction = 0.5
        #: Why the helper is not used (None while it is usable or not yet needed).
        self.failure: str | None = None
        #: Frames drawn split in two, and how many of them :meth:`begin` started (tests, benchmark).
        self.split_frames = 0
        self.begun_frames = 0
        #: Seconds of work of the last split frame, both bands' times together (None before one).
        self.last_work_s: float | None = None
        self._helper: _Helper | None = None
        self._pending: _HelperBand | None = None
        # Checked renderers and converted textures of the current template (SceneMemo).
        self._memo: SceneMemo | None = None
        self._memo_scene: DrawScene | None = None
        self._lock = threading.Lock()
        self._closed = False
        if os.name == "nt" or (os.cpu_count() or 1) < 2:
            self.failure = "needs two cores and a POSIX system"
        elif not sys.executable or "blender" in os.path.basename(sys.executable).lower():
            # Blender sets sys.executable to its bundled Python (since 2.91); never start Blender itself.
            self.failure = f"no Python executable to start the helper with ({sys.executable!r})"
        elif start:
            self._start()

    def _start(self) -> None:
        try:
            self._helper = _Helper()
        except OSError as exc:
            self.failure = f"helper process did not start: {exc}"
            return
        weakref.finalize(self, _Helper.close, self._helper)

    def _usable(self, pixels: int, wait: float) -> _Helper | None:
        if self._closed or self.failure is not None or pixels < self.min_pixels:
            return None
        if self._helper is None:
            self._start()
        helper = self._helper
        if helper is None:
            return None
        if helper.poll_ready(wait):
            return helper
        if helper.proc.poll() is not None:
            self._fail(f"helper process exited with code {helper.proc.returncode}")
        return None

    def _fail(self, reason: str) -> None:
        self.failure = reason
        self._pending = None
        if self._helper is not None:
            self._helper.close()
            self._helper = None

    @property
    def helper_pid(self) -> int | None:
        """The helper's process id while it runs (the benchmark adds its CPU time), else None."""
        helper = self._helper
        return helper.proc.pid if helper is not None and helper.proc.poll() is None else None

    def forget_tables(self) -> None:
        """Clear this process's kept blend tables (:data:`~blendlib.core.merger.RECENT_TABLES`) and
        have the helper clear its own before the next frame: that frame is drawn from scratch, as
        the first of a session is (the benchmark)."""
        merger.RECENT_TABLES.clear()
        self._forget_tables = True

    def wait_ready(self, timeout: float = 30.0) -> bool:
        """Block until the helper has started (tests, the benchmark); False if it cannot run."""
        if self._helper is None and self.failure is None and not self._closed:
            self._start()
        return self._usable(self.min_pixels, timeout) is not None

    def close(self, timeout: float = 5.0) -> None:
        """End the helper process (idempotent); later frames render in this process. Waits up
        to ``timeout`` seconds for a frame in progress on another thread; if it is still going
        then, the helper's band of it is stopped (the frame fails as cancelled) and that thread
        ends the helper when it is done with it."""
        self._closed = True
        if not self._lock.acquire(timeout=timeout):
            helper = self._helper
            if helper is not None and helper.buffer is not None and not helper.closed:
                helper.buffer[0] = 1
            return
        try:
            self._close_helper()
        finally:
            self._lock.release()

    def _close_helper(self) -> None:
        """End the helper (the lock held): a band nobody will collect is stopped first."""
        if self._pending is not None:
            self._pending.buffer[0] = 1
            self._pending = None
        if self._helper is not None:
            self._helper.close()
            self._helper = None

    def begin(self, scene: DrawScene) -> bool:
        """Start the helper on its band of ``scene`` now; the call ``self(scene)`` with this very
        scene object draws this process's band and joins them. Meanwhile other calls may render
        smaller frames here (the viewport's reduced frame); a large frame of another scene, a
        later :meth:`begin` or :meth:`close` drops the band. False when the frame will not be
        split (too small, no helper, another thread rendering)."""
        width, height = int(scene.camera.width), int(scene.camera.height)
        if height < 2 or not self._lock.acquire(blocking=False):
            return False
        try:
            helper = self._usable(width * height, 0.0)
            if helper is None:
                return False
            self._drop_pending(helper)
            self._pending = self._request(helper, scene, self.begun_fraction, begun=True)
            return self._pending is not None
        finally:
            try:
                if self._closed:  # close() came from another thread meanwhile
                    self._close_helper()
            finally:
                self._lock.release()

    def __call__(self, scene: DrawScene, *, should_cancel: Callable[[], bool] | None = None,
                 progress: Callable[[float], None] | None = None, **options) -> Frame:
        width, height = int(scene.camera.width), int(scene.camera.height)
        if options or height < 2 or self._too_many_triangles(scene) or not self._lock.acquire(blocking=False):
            return pipeline.render_scene(scene, should_cancel=should_cancel, progress=progress, **options)
        try:
            memo = self._memo_for(scene)
            helper = self._usable(width * height, 0.0)
            if helper is not None:
                band = self._pending if self._pending is not None and self._pending.scene is scene else None
                if band is None:
                    self._drop_pending(helper)
                    band = self._request(helper, scene, self.fraction, begun=False)
                self._pending = None
                if band is not None:
                    frame = self._join(helper, band, should_cancel, progress, memo)
                    if frame is not None:
                        return frame
            # A small frame, no helper, or it stopped during this frame: the frame in this process.
            return pipeline.render_scene(scene, should_cancel=should_cancel, progress=progress, memo=memo)
        finally:
            try:
                self._settle()
            finally:
                self._lock.release()

    def _settle(self) -> None:
        """After a frame, whatever ended it (the lock held): collect a band sent and not collected
        (an interrupt between sending it and joining it), drop the scene when it is not kept, end
        the helper when :meth:`close` came from another thread meanwhile."""
        helper = self._helper
        if helper is not None and helper.in_flight and self._pending is None:
            self._abandon(helper)
        if not self.keep_scene:
            self._release_scene()
        if self._closed:
            self._close_helper()

    def _too_many_triangles(self, scene: DrawScene) -> bool:
        return (self.max_triangles is not None
                and sum(r.mesh.triangle_count for r in scene.renderers) > self.max_triangles)

    def _release_scene(self) -> None:
        """Free the last scene here and in the helper (``keep_scene`` False): the memo goes, and
        the helper is told to drop its scene, memo and parts (it answers nothing; the next
        request sends a scene whole)."""
        self._memo = None
        self._memo_scene = None
        helper = self._helper
        if helper is None or not helper.holding or helper.in_flight or self._pending is not None:
            return
        if not self._write(helper, helper.parts.dumps(("drop",), None)):
            return
        helper.scene = None
        helper.parts = _PartsWriter()
        helper.holding = False

    def _memo_for(self, scene: DrawScene) -> SceneMemo:
        """The memo of renders of ``scene``'s template: whole while frames differ in their camera
        only, else keeping the entries of the parts ``scene`` shares with the last one."""
        if self._memo is None:
            self._memo = SceneMemo()
        elif not _same_but_camera(scene, self._memo_scene):
            self._memo.retain(scene)
        self._memo_scene = scene
        return self._memo

    def _request(self, helper: _Helper, scene: DrawScene, fraction: float, begun: bool) -> _HelperBand | None:
        """Ask the helper for the top band of ``scene`` (the cut at ``fraction`` of the rows);
        None when the helper stopped (it is not used again)."""
        if helper.closed or helper is not self._helper:  # it stopped (collecting an earlier band)
            return None
        width, height = int(scene.camera.width), int(scene.camera.height)
        cut = min(max(int(round(fraction * height)), 1), height - 1)
        forget, self._forget_tables = self._forget_tables, False
        if _same_but_camera(scene, helper.scene):
            request = ("view", scene.camera, cut, height, self.chunk_candidates, forget)
        else:
            request = ("scene", scene, cut, height, self.chunk_candidates, forget)
        message = helper.parts.dumps(request, scene if request[0] == "scene" else None)
        try:
            shared = len(message) >= SHARED_REQUEST_BYTES
            # A large request waits in the band's own bytes: the helper copies it out before it draws.
            buffer = helper.reserve(max(_band_bytes(height - cut, width), _HEAD + len(message) if shared else 0))
            buffer[0] = 0  # the stop flag
            if shared:
                buffer[_HEAD:_HEAD + len(message)] = message
                message = _SHARED_REQUEST + len(message).to_bytes(8, "little")
        except BaseException:  # nothing sent (the shared file could not grow, an interrupt)
            helper.parts = helper.parts.restarted()
            helper.scene = None
            self._forget_tables = self._forget_tables or forget
            raise
        helper.in_flight = True
        if not self._write(helper, message):
            return None
        helper.scene = scene
        helper.holding = True
        return _HelperBand(scene, cut, buffer, time.perf_counter(), begun)

    def _write(self, helper: _Helper, message: bytes) -> bool:
        """Send ``message`` to the helper; False when it stopped (it is not used again). An
        interrupt in the middle of the message leaves the stream out of step: the helper is
        ended, and the interrupt goes on."""
        try:
            helper.conn.send_bytes(message)
            return True
        except (OSError, ValueError) as exc:
            self._fail(f"helper process stopped: {exc}")
            return False
        except BaseException:
            self._fail("interrupted while writing to the helper process")
            raise

    def _drop_pending(self, helper: _Helper) -> None:
        """Stop and collect a band requested by :meth:`begin` that no call came for."""
        band, self._pending = self._pending, None
        if band is not None:
            band.buffer[0] = 1
            self._reply(helper, None)

    def _join(self, helper: _Helper, band: _HelperBand, should_cancel: Callable[[], bool] | None,
              progress: Callable[[float], None] | None, memo: SceneMemo) -> Frame | None:
        """This process's band of ``band.scene``, then the helper's: the whole frame, or None
        when the helper stopped (it is not used again)."""
        scene, cut, buffer = band.scene, band.cut, band.buffer
        width, height = int(scene.camera.width), int(scene.camera.height)
        top = height - cut
        started = time.perf_counter()
        # This process's band goes straight into its rows of the frame (row 0 is the top of the image).
        color = np.empty((height, width, 4), dtype=np.float32)
        depth = np.empty((height, width), dtype=np.float32)
        stencil = np.empty((height, width), dtype=np.uint8)
        try:
            own = pipeline.render_scene(scene, band=(0, cut), workers=1, chunk_candidates=self.chunk_candidates,
                                        should_cancel=should_cancel, out=(color[top:], depth[top:], stencil[top:]),
                                        progress=None if progress is None else lambda f: progress(0.5 * f),
                                        memo=memo)
        except BaseException:
            buffer[0] = 1
            self._reply(helper, None)  # let the helper finish (it stops at its next check)
            helper.scene = None  # it may have refused the scene too: send it whole next time
            raise
        own_s = time.perf_counter() - started
        reply = self._reply(helper, should_cancel, buffer)
        if reply is None:  # the helper died
            return None
        if reply[0] == "cancelled":
            raise RenderCancelled("render cancelled")
        if reply[0] == "error":
            raise SceneError(reply[1])
        if reply[0] != "ok":
            self._fail(f"helper process failed: {reply[1]}")
            return None
        views = _band_views(buffer, top, width)
        for whole, theirs in zip((color, depth, stencil), views, strict=True):
            whole[:top] = theirs
        del views
        self.split_frames += 1
        self.last_work_s = own_s + float(reply[1])
        fraction = balanced_fraction(self.begun_fraction if band.begun else self.fraction, cut, height,
                                     own_s, float(reply[1]), lead_s=started - band.sent_at)
        if band.begun:
            self.begun_frames += 1
            self.begun_fraction = fraction
        else:
            self.fraction = fraction
        if progress is not None:
            progress(1.0)
        return Frame(color=color, depth=depth, stencil=stencil, warnings=own.warnings, encoded=own.encoded)

    def _reply(self, helper: _Helper, should_cancel: Callable[[], bool] | None, buffer: mmap.mmap | None = None):
        """The helper's answer, polling ``should_cancel`` meanwhile (True sets the stop flag);
        None if the helper died (then it is not used again)."""
        try:
            while not wait([helper.conn], _POLL_S):
                if helper.proc.poll() is not None:
                    raise EOFError
                if buffer is not None and should_cancel is not None and buffer[0] == 0 and should_cancel():
                    buffer[0] = 1
            return helper.read_reply()
        except (OSError, ValueError, EOFError, pickle.UnpicklingError):
            self._fail(f"helper process exited with code {helper.proc.poll()}")
            return None
        except BaseException:
            # Interrupted while the helper draws (KeyboardInterrupt, an error in should_cancel):
            # its answer must not be taken for the next frame's. Stop it and collect the answer.
            self._abandon(helper)
            raise

    def _abandon(self, helper: _Helper, timeout: float = 2.0) -> None:
        """Stop the helper's band and read its answer (a helper that does not answer within
        ``timeout`` seconds is ended, and not used again)."""
        try:
            if helper.buffer is not None:
                helper.buffer[0] = 1
            if helper.conn.poll(timeout):
                helper.read_reply()
                return
        except (OSError, ValueError, EOFError, pickle.UnpicklingError):
            pass
        except BaseException:  # interrupted again: its answer is still unread, so it goes
            self._fail("helper process ended after an interrupted frame")
            raise
        self._fail("helper process did not answer after an interrupted frame")


#: Final renders of scenes with more triangles stay in one process: the vertex setup done in both
#: bands and the pickled meshes outweigh the half frame saved (docs/benchmark.md, "Why the
#: constants are what they are": 300k triangles gain, 1M lose).
FINAL_MAX_TRIANGLES = 400_000

_final: list[BandRenderer] = []
_final_lock = threading.Lock()


def final_renderer() -> BandRenderer:
    """The process's renderer of final frames (F12, ``blendlib.render``, the CLI): one
    :class:`BandRenderer`, made on first use, whose helper starts with the first frame of
    :data:`MIN_PIXELS` or more (that frame renders here while it starts) and is reused after.
    Scenes over :data:`FINAL_MAX_TRIANGLES` render in this process; the helper keeps nothing of
    a scene after its frame. :func:`close_final_renderer` ends the helper (else it ends with
    this process)."""
    with _final_lock:
        if not _final or _final[0]._closed:
            # Chunks of render_scene's default size: on final frames 32k chunks lost (S2's fifty
            # planes 465 → 745 ms, blend_modes, lights, alpha_test), where the viewport's gained.
            _final[:] = [BandRenderer(start=False, max_triangles=FINAL_MAX_TRIANGLES, keep_scene=False,
                                      chunk_candidates=pipeline.CHUNK_CANDIDATES)]
        return _final[0]


def close_final_renderer() -> None:
    """End :func:`final_renderer`'s helper, if one runs (the add-on's unregister); a later final
    render makes a new renderer."""
    with _final_lock:
        renderers, _final[:] = list(_final), []
    for renderer in renderers:
        renderer.close(timeout=0.0)  # a frame in progress ends the helper itself


def balanced_fraction(fraction: float, cut: int, height: int, own_s: float, helper_s: float,
                      lead_s: float = 0.0) -> float:
    """The share of rows to draw here next time, after a frame cut at ``cut`` of ``height`` rows
    took ``own_s`` here and ``helper_s`` in the helper, which started ``lead_s`` seconds before
    this process's band. Takes each band's time per row as even; the cut where both would end
    together is ``(r_h * height - lead) / (r_own + r_h)``. Moves half way there from
    ``fraction`` (one odd frame does not swing it), within 0.05..0.95."""
    per_row_own = own_s / max(cut, 1)
    per_row_helper = helper_s / max(height - cut, 1)
    if per_row_own + per_row_helper <= 0.0:
        return fraction
    target = (per_row_helper * height - lead_s) / (per_row_own + per_row_helper)
    return min(max(0.5 * fraction + 0.5 * target / height, 0.05), 0.95)


def _mapping(fd: int, buffer: mmap.mmap | None, size: int) -> mmap.mmap:
    """The helper's mapping of the shared file ``fd``, at least ``size`` bytes: ``buffer`` when it
    is that large, else the whole file mapped again (the parent grew it; the old mapping closes
    once nothing views it)."""
    if buffer is not None and len(buffer) >= size:
        return buffer
    return mmap.mmap(fd, os.fstat(fd).st_size)


def _await_request(conn: Connection, trim_after: float | None) -> None:
    """Wait until the next request (or the end of the connection) arrives on ``conn``. With
    ``trim_after`` (seconds), the heap this process freed goes back to the system
    (:func:`.allocator.give_back_freed_memory`) once that long passes without one."""
    if trim_after is not None and not conn.poll(trim_after):
        allocator.give_back_freed_memory()
    conn.poll(None)


def serve(conn_fd: int, fd: int) -> int:
    """The helper's loop: read ("scene", scene, y0, y1, chunk, forget) or ("view", camera, y0, y1,
    chunk, forget) requests (the latter: the last scene seen through ``camera``; ``forget``: clear
    the kept blend tables first) from the connection on descriptor ``conn_fd``, draw band
    [y0, y1) into the shared file ``fd`` (where a large request came, :data:`_SHARED_REQUEST`),
    answer ("ok", seconds since the request arrived),
    ("cancelled",), ("error", line) or ("failed", line). A ("drop",) request frees the scene,
    its memo and parts and is not answered; the heap they leave free goes back to the system
    when no request follows within :data:`IDLE_TRIM_S`. Returns 0 when the parent closes its end,
    whether it waits for a request or answers one."""
    allocator.keep_freed_memory()  # every frame allocates the same arrays again (allocator.py)
    os.dup2(2, 1)  # anything printed goes to stderr, never into the parent's own output
    # Ctrl+C in a terminal reaches the whole process group: the parent handles it and stops this
    # band through the stop flag (or closes its end, which ends this loop).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    conn = Connection(conn_fd)
    try:
        _send(conn, ("ready",))
    except OSError:  # the parent closed its end before this process started
        return 0
    buffer: mmap.mmap | None = None
    scene: DrawScene | None = None
    memo = SceneMemo()
    parts = _PartsReader()
    trim_after = None  # seconds idle after a drop before the freed heap goes back
    while True:
        try:
            _await_request(conn, trim_after)  # until the request's first bytes (or the end) arrive
            trim_after = None
            arrived = time.perf_counter()
            data = conn.recv_bytes()
        except (EOFError, OSError):  # the parent closed its end, or died (connection reset)
            return 0
        if data.startswith(_SHARED_REQUEST):  # the request waits in the shared file, after its head
            end = _HEAD + int.from_bytes(data[len(_SHARED_REQUEST):], "little")
            buffer = _mapping(fd, buffer, end)
            data = buffer[_HEAD:end]  # a copy: the band is drawn over it
        request = parts.loads(data)
        if request[0] == "drop":  # idle until the next request: hold nothing of the last scene
            scene = content = request = data = None
            memo = SceneMemo()
            parts.parts.clear()
            trim_after = IDLE_TRIM_S
            continue
        kind, content, y0, y1, chunk, forget = request
        if forget:
            merger.RECENT_TABLES.clear()
        try:
            if kind == "scene":
                scene = content
                memo.retain(scene)  # what it derived from parts the new scene shares stays
            elif scene is None:
                raise RuntimeError("a view request before any scene")
            else:
                scene = dataclasses.replace(scene, camera=content)
            width = int(scene.camera.width)
            buffer = _mapping(fd, buffer, _band_bytes(y1 - y0, width))
            pipeline.render_scene(scene, band=(y0, y1), workers=1, chunk_candidates=chunk,
                                  should_cancel=lambda stop=buffer: stop[0] != 0,
                                  out=_band_views(buffer, y1 - y0, width), memo=memo)
            reply = ("ok", time.perf_counter() - arrived)
        except RenderCancelled:
            reply = ("cancelled",)
        except SceneError as exc:
            scene = None
            reply = ("error", str(exc))
        except Exception as exc:  # noqa: BLE001 - reported to the parent, which renders alone from then on
            reply = ("failed", f"{type(exc).__name__}: {exc}")
        try:
            _send(conn, reply)
        except OSError:  # the parent closed its end meanwhile (it dropped the band and ended us)
            return 0


if __name__ == "__main__":
    sys.exit(serve(int(sys.argv[1]), int(sys.argv[2])))
