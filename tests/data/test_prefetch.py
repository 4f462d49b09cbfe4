"""The background reader: frames in order, errors at the right frame, nothing left running on an early exit."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric.data.mesh_file import MeshFileError
from torchmeshmetric.data.sequence import Prefetcher, iter_sequence, load_sequence, prefetch_frames


def _frames(folder: Path, n: int) -> list[Path]:
    out = []
    for k in range(n):
        p = folder / f"frame{k}.obj"
        p.write_text(f"v 0 0 {k}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        out.append(p)
    return out


def _threads() -> int:
    return sum(t.name == "torchmeshmetric-prefetch" and t.is_alive() for t in threading.enumerate())


@settings(max_examples=20, deadline=None)
@given(n=st.integers(1, 12), ahead=st.integers(1, 5), bad=st.one_of(st.none(), st.integers(0, 11)))
def test_items_in_order_and_the_error_at_its_item(n: int, ahead: int, bad: int | None) -> None:
    seen: list[int] = []

    def load(k: int) -> int:
        if k == bad:
            raise KeyError(f"item {k}")
        return k * k

    got = []
    with Prefetcher(range(n), load=load, ahead=ahead) as items:
        if bad is not None and bad < n:
            with pytest.raises(KeyError, match=f"item {bad}"):
                for x in items:
                    got.append(x)
            assert got == [k * k for k in range(bad)]  # every item before the bad one, in order
        else:
            got = list(items)
            assert got == [k * k for k in range(n)]
    del seen
    assert _threads() == 0


def test_loads_ahead_and_no_further(tmp_path: Path) -> None:
    started: list[int] = []

    def load(k: int) -> int:
        started.append(k)
        return k

    items = Prefetcher(range(100), load=load, ahead=3)
    assert next(items) == 0
    time.sleep(0.3)
    assert len(started) <= 1 + 3 + 1  # the one consumed, `ahead` queued, one waiting to be queued
    items.close()
    assert _threads() == 0
    with pytest.raises(StopIteration):
        next(items)


def test_early_break_and_keyboard_interrupt_stop_the_thread(tmp_path: Path) -> None:
    paths = _frames(tmp_path, 8)
    with prefetch_frames(paths, ahead=2) as frames:
        first = next(iter(frames))
    assert _threads() == 0 and first.num_faces == 1
    with pytest.raises(KeyboardInterrupt), prefetch_frames(paths) as frames:
        for _ in frames:
            raise KeyboardInterrupt
    assert _threads() == 0


def test_waits_for_a_slow_item() -> None:
    gate = threading.Event()

    def load(k: int) -> int:
        gate.wait(5)
        return k

    items = Prefetcher(range(3), load=load)
    timer = threading.Timer(0.2, gate.set)
    timer.start()
    assert list(items) == [0, 1, 2]
    timer.join()
    assert _threads() == 0


def test_sequence_readers_agree_and_name_the_bad_file(tmp_path: Path) -> None:
    paths = _frames(tmp_path, 5)
    with iter_sequence(tmp_path) as frames:
        lazy = [float(m.verts[0, 2]) for m in frames]
    assert lazy == [float(m.verts[0, 2]) for m in load_sequence(tmp_path)] == [0.0, 1.0, 2.0, 3.0, 4.0]
    paths[3].write_text("v 0 0 0\nf 1 2 3\n")
    got = []
    message = r"frame3\.obj' line 2: face 0: vertex index 2 is out of range"
    with pytest.raises(MeshFileError, match=message), iter_sequence(tmp_path) as frames:
        for m in frames:
            got.append(m)
    assert len(got) == 3
    with pytest.raises(MeshFileError, match=r"frame3\.obj"):
        load_sequence(tmp_path)
    assert _threads() == 0


@pytest.mark.parametrize(
    ("ahead", "error", "message"),
    [
        (0, ValueError, "ahead: expected an int >= 1"),
        (-1, ValueError, "ahead: expected an int >= 1"),
        (1.5, TypeError, "ahead: expected an int, found float"),
        (True, TypeError, "ahead: expected an int, found bool"),
    ],
)
def test_bad_ahead_is_refused(ahead: object, error: type[Exception], message: str) -> None:
    with pytest.raises(error, match=message):
        Prefetcher([1], load=str, ahead=ahead)  # type: ignore[arg-type]
