"""blendlib.runtime.forked: items shared with a forked child give the results computed here, in
order; progress comes from this process alone; a child that fails, dies or is cancelled leaves
no process behind and its items are computed here."""

from __future__ import annotations

import os
import threading
import time

import pytest

from blendlib.runtime.forked import ForkedMap

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="fork: POSIX only")


def _no_children() -> bool:
    try:
        os.waitpid(-1, os.WNOHANG)
    except ChildProcessError:
        return True
    return False


def _slow_square(item: int, processes: int) -> tuple[int, int, int]:
    time.sleep(0.02)
    return item * item, os.getpid(), processes


def test_items_are_shared_with_a_child_and_come_back_in_order():
    results = ForkedMap(2, min_work_s=0.0)(_slow_square, list(range(12)))
    assert [r[0] for r in results] == [k * k for k in range(12)]
    pids = {r[1] for r in results}
    assert os.getpid() in pids and len(pids) == 2  # the child took some
    assert results[0][1:] == (os.getpid(), 1)  # the first runs here alone, timed
    assert all(p == 2 for _, _, p in results[1:])  # the others shared the machine
    assert _no_children()


def test_quick_items_stay_here():
    results = ForkedMap(2, min_work_s=10.0)(_slow_square, list(range(6)))
    assert [r[0] for r in results] == [k * k for k in range(6)]
    assert {r[1:] for r in results} == {(os.getpid(), 1)}


@pytest.mark.parametrize("processes", [1, 2])
def test_fewer_than_three_items_or_one_process_stay_here(processes):
    count = 2 if processes == 2 else 5
    results = ForkedMap(processes, min_work_s=0.0)(_slow_square, list(range(count)))
    assert {r[1:] for r in results} == {(os.getpid(), 1)}


@pytest.mark.parametrize("count", [2, 5])
def test_items_at_once_are_shared_from_the_first(count):
    """Long items (``at_once``): none runs here alone first; two items are shared too."""
    def slower_square(item: int, processes: int) -> tuple[int, int, int]:
        time.sleep(0.15)  # the child has time to take the second item before this one is done
        return _slow_square(item, processes)

    results = ForkedMap(2, min_work_s=10.0)(slower_square, list(range(count)), at_once=True)
    assert [r[0] for r in results] == [k * k for k in range(count)]
    assert all(p == 2 for _, _, p in results)  # every item shared the machine, the first included
    assert len({r[1] for r in results}) == 2
    assert _no_children()


def test_items_at_once_stay_here_with_one_process_or_one_item():
    assert [r[1:] for r in ForkedMap(1)(_slow_square, list(range(3)), at_once=True)] == [(os.getpid(), 1)] * 3
    assert [r[1:] for r in ForkedMap(2)(_slow_square, [7], at_once=True)] == [(os.getpid(), 1)]


def test_progress_comes_from_this_process_alone(tmp_path):
    log = tmp_path / "progress.txt"

    def on_done(n: int) -> None:
        with open(log, "a", encoding="utf-8") as f:  # a file: the child's calls would show here too
            f.write(f"{os.getpid()} {n}\n")

    ForkedMap(2, min_work_s=0.0)(_slow_square, list(range(10)), on_done=on_done)
    lines = [tuple(map(int, line.split())) for line in log.read_text(encoding="utf-8").splitlines()]
    assert {pid for pid, _ in lines} == {os.getpid()}
    counts = [n for _, n in lines]
    assert counts == sorted(counts) and counts[0] == 1 and counts[-1] == 10


@pytest.mark.parametrize("how", ["raises", "dies"])
def test_the_childs_items_are_computed_here_when_it_fails(how):
    parent = os.getpid()

    def fn(item: int, processes: int) -> tuple[int, int]:
        time.sleep(0.02)
        if os.getpid() != parent:
            if how == "raises":
                raise ValueError("in the child")
            os._exit(3)
        return item + 100, os.getpid()

    results = ForkedMap(2, min_work_s=0.0)(fn, list(range(8)))
    assert results == [(k + 100, parent) for k in range(8)]
    assert _no_children()


def test_a_cancel_stops_waiting_for_the_child_and_kills_it():
    parent = os.getpid()
    cancelled = []

    class Cancelled(Exception):
        pass

    def fn(item: int, processes: int) -> int:
        if cancelled:
            raise Cancelled
        if os.getpid() != parent:
            time.sleep(30)  # far longer than the test: only a kill ends it in time
        else:
            time.sleep(0.05)
        return item

    def should_cancel() -> bool:
        cancelled.append(True)
        return True

    start = time.perf_counter()
    with pytest.raises(Cancelled):
        ForkedMap(2, min_work_s=0.0)(fn, list(range(6)), should_cancel)
    assert time.perf_counter() - start < 5.0
    assert _no_children()


def test_a_map_called_from_another_thread_shares_too():
    """The add-on runs analyses on a job thread of Blender's: the child forked from it works."""
    out = {}
    worker = threading.Thread(target=lambda: out.update(r=ForkedMap(2, min_work_s=0.0)(_slow_square, list(range(10)))))
    worker.start()
    worker.join(30)
    assert [r[0] for r in out["r"]] == [k * k for k in range(10)]
    assert len({r[1] for r in out["r"]}) == 2
    assert _no_children()


def test_freed_memory_is_given_back_before_the_child_is_forked(monkeypatch):
    """Pages this process keeps freed would be shared with the child and copied on each reuse:
    they are given back once, here, before the fork (and not by the child)."""
    from blendlib.runtime import forked

    calls = []
    monkeypatch.setattr(forked, "give_back_freed_memory",
                        lambda: calls.append((os.getpid(), _no_children())) or True)
    results = ForkedMap(2, min_work_s=0.0)(_slow_square, list(range(8)))
    assert [r[0] for r in results] == [k * k for k in range(8)]
    assert len({r[1] for r in results}) == 2  # a child did share the items
    assert calls == [(os.getpid(), True)]  # once, in this process, while no child lived yet


def test_no_memory_is_given_back_when_nothing_is_forked(monkeypatch):
    from blendlib.runtime import forked

    calls = []
    monkeypatch.setattr(forked, "give_back_freed_memory", lambda: calls.append(1) or True)
    assert [r[0] for r in ForkedMap(1)(_slow_square, list(range(4)))] == [0, 1, 4, 9]
    assert calls == []
