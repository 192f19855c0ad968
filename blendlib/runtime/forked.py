"""Independent pieces of work shared with a forked copy of this process (Linux; bpy-free).

The advice's candidate measurements (:mod:`blendlib.explain.advice`) are renders of the same
scene with one change each, and each needs the analysis's buffers (megabytes). Threads of one
process share one interpreter lock, and these renders are mostly short array calls, so a
second thread gains little on them (docs/benchmark.md, round fourteen). A process of its own
does gain, but sending it the scene and the buffers would cost about what a measurement costs.
A forked child starts with all of it already in memory (copy-on-write): forking a 300 MB
process with ``bpy`` loaded takes about 3 ms here.

The copy is not free either: a page either process writes while both live is copied first
(a fault of about 4 µs here), 20–35 ms for each process's first measurement of a 720p frame.
So :class:`ForkedMap` runs the first item here, timed, and shares the others with a forked
child only when they would take long enough one after the other (:data:`FORK_MIN_WORK_S`).
Before it forks, the freed memory this process keeps for reuse
(:func:`.allocator.keep_freed_memory`) is given back: shared, each of those pages would be
copied when either process reused it; given back, a page allocated anew is only zeroed (96 MB
written while a child lives: 82 ms on reused pages, 18 ms on pages given back first).
The items' numbers wait in a pipe that both processes read (a read of 4 bytes from a pipe is
atomic), so whichever is free takes the next one; the child sends back its results (pickled)
when the pipe is empty and leaves through ``os._exit``, never running the parent's exit
handlers or touching its files. The parent polls ``should_cancel`` while it waits; on
cancel, an error or a child that dies, the child is killed and reaped, and items the child took
but did not answer are computed here — the results are the same either way, only slower.

A caller that knows its items are long (the advice's measurements of a frame of millions of
fragments) asks for them shared ``at_once``: the child is forked before the first item, and
each process takes items from the start, the first included. Run here alone, the first would
draw with two threads, which gain about a third of its time over one, while every other item
waits; shared at once, two items run side by side from the start.

Where forking is not safe or not possible (not Linux: macOS's system frameworks are not
fork-safe, Windows has no fork; one core), with fewer than three items (two ``at_once``), or
where the items after the first would be quick, ``fn`` runs over the items here, in order.
"""

from __future__ import annotations

import os
import pickle
import select
import signal
import struct
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

from .allocator import give_back_freed_memory

#: How often the parent polls ``should_cancel`` while it waits for the child (seconds).
_POLL_S = 0.01
_INDEX = struct.Struct("<I")
_LENGTH = struct.Struct("<Q")


def fork_available() -> bool:
    """Whether :class:`ForkedMap` forks here: Linux with ``os.fork`` and two cores or more."""
    return sys.platform.startswith("linux") and hasattr(os, "fork") and (os.cpu_count() or 1) >= 2


#: A forked child pays for its memory: every page either process writes after the fork is
#: copied first (about 4 µs a page here, 20–35 ms for the first measurement of a 720p frame in
#: each process). So the items are shared only when the ones left after the first would take at
#: least this long one after the other (docs/benchmark.md, "Why the constants are what they are").
FORK_MIN_WORK_S = 0.08


class ForkedMap:
    """``map(fn, items)`` shared between this process and a forked child (module doc).

    ``processes``: at most how many processes share the items (1 or 2; default 2 where
    :func:`fork_available`). ``min_work_s``: the first item runs here alone, timed; the others
    are shared only if they would take at least this long one after the other
    (:data:`FORK_MIN_WORK_S`)."""

    def __init__(self, processes: int | None = None, min_work_s: float = FORK_MIN_WORK_S) -> None:
        self.processes = (2 if fork_available() else 1) if processes is None else max(1, min(2, processes))
        self.min_work_s = float(min_work_s)

    def __call__(self, fn: Callable[[Any, int], Any], items: Sequence[Any],
                 should_cancel: Callable[[], bool] | None = None,
                 on_done: Callable[[int], None] | None = None, at_once: bool = False) -> list:
        """``[fn(item, processes) for item in items]``, ``processes`` being how many processes
        share the machine while that item runs (1 or 2: an item may size its own threads by
        it). Raises what ``fn`` raises here (an error in the child's items is raised again by
        computing them here). ``on_done(n)``: called in this process only, with how many items
        are done, as they get done here or come back. ``at_once``: the caller knows the items
        are long; two or more are shared from the first, none run here alone first (module
        doc). Items are taken in their order: the longest first shares them best."""
        items = list(items)
        done: dict[int, Any] = {}
        parent = os.getpid()

        def run(index: int, processes: int = 1) -> None:
            done[index] = fn(items[index], processes)
            if on_done is not None and os.getpid() == parent:  # never from the child
                on_done(len(done))

        if not items:
            return []
        if at_once and self.processes >= 2 and len(items) >= 2:
            self._shared(run, done, items, should_cancel, on_done, first=0)
        else:
            start = time.perf_counter()
            run(0)
            rest = len(items) - 1
            if self.processes >= 2 and rest >= 2 and (time.perf_counter() - start) * rest >= self.min_work_s:
                self._shared(run, done, items, should_cancel, on_done)
        for index in range(len(items)):  # here: all of them, or the child's it did not answer
            if index not in done:
                run(index)
        return [done[index] for index in range(len(items))]

    @staticmethod
    def _shared(run: Callable[[int, int], None], done: dict[int, Any], items: list,
                should_cancel: Callable[[], bool] | None, on_done: Callable[[int], None] | None,
                first: int = 1) -> None:
        """Items ``first`` on, shared with a forked child; ``done`` gets what both computed (the
        child's missing where it died or failed)."""
        queue_read, queue_write = os.pipe()
        os.write(queue_write, b"".join(_INDEX.pack(i) for i in range(first, len(items))))  # far below 64 KB
        os.close(queue_write)  # an empty queue reads as end of file
        result_read, result_write = os.pipe()
        # Freed memory this process keeps (allocator.keep_freed_memory) would be shared with the
        # child: each page either process then reuses is copied first. Given back now, a page
        # allocated anew is only zeroed, about four times cheaper (module doc).
        give_back_freed_memory()
        try:
            pid = os.fork()
        except OSError:
            for fd in (queue_read, result_read, result_write):
                os.close(fd)
            return
        if pid == 0:  # the child: never returns
            _serve_child(run, done, queue_read, result_write)
        os.close(result_write)
        try:
            while (index := _take(queue_read)) is not None:
                run(index, 2)
            done.update(_child_results(result_read, should_cancel))
            if on_done is not None:
                on_done(len(done))
        finally:
            os.close(queue_read)
            os.close(result_read)
            _reap(pid)


def _take(queue: int) -> int | None:
    """The next item's number from the queue pipe, or None when it is empty."""
    data = os.read(queue, _INDEX.size)
    return _INDEX.unpack(data)[0] if len(data) == _INDEX.size else None


def _serve_child(run: Callable[[int, int], None], done: dict[int, Any], queue: int, out: int) -> None:
    """The child's whole life: take items until the queue is empty, send ``{index: result}`` of
    its own (pickled, after its length), leave. The parent handles interrupts and kills it on
    cancel; an item that raises ends the child, and the parent computes it again."""
    status = 1
    try:
        try:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        except ValueError:  # not the interpreter's main thread after all: Ctrl+C's default then
            pass
        taken = []
        while (index := _take(queue)) is not None:
            run(index, 2)
            taken.append(index)
        data = pickle.dumps({k: done[k] for k in taken}, protocol=pickle.HIGHEST_PROTOCOL)
        view = memoryview(_LENGTH.pack(len(data)) + data)
        while view:
            view = view[os.write(out, view):]
        status = 0
    except BaseException:  # noqa: BLE001 - the parent computes what the child did not answer
        pass
    finally:
        os._exit(status)


def _child_results(pipe: int, should_cancel: Callable[[], bool] | None) -> dict[int, Any]:
    """The child's ``{index: result}``, or {} if it ended without answering or ``should_cancel``
    said so while waiting (the caller then computes the missing items with its ``fn``, which
    raises on cancel)."""
    chunks = []
    while True:
        if should_cancel is not None and should_cancel():
            return {}
        ready, _, _ = select.select([pipe], [], [], _POLL_S)
        if not ready:
            continue
        chunk = os.read(pipe, 1 << 20)
        if not chunk:
            break
        chunks.append(chunk)
    data = b"".join(chunks)
    if len(data) < _LENGTH.size or len(data) != _LENGTH.size + _LENGTH.unpack_from(data)[0]:
        return {}
    return pickle.loads(data[_LENGTH.size:])


def _reap(pid: int) -> None:
    """Kill the child if it still runs and wait for it (no zombie left)."""
    try:
        finished, _ = os.waitpid(pid, os.WNOHANG)
        if finished == 0:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
    except ChildProcessError:
        pass
