"""Sequences loaded in a background thread, frames ahead of their use (I/O overlaps work), in natural order."""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, TypeVar, cast, overload

import torch

from torchmeshmetric._checks import check_float_dtype, check_int
from torchmeshmetric.data.frames import PathsLike, list_frames
from torchmeshmetric.data.io import load_mesh
from torchmeshmetric.structures import Mesh

__all__ = ["Prefetcher", "iter_sequence", "load_sequence", "prefetch_frames"]


def load_sequence(paths: PathsLike, *, dtype: torch.dtype = torch.float32) -> list[Mesh]:
    r"""Load the frames of a sequence in natural order (see :func:`list_frames`).

    Frames are read ahead by a background thread (:func:`iter_sequence`), so reading a file overlaps parsing the
    previous one.

    Args:
        paths: a directory, a glob pattern, a single file or a list of files.
        dtype: vertex dtype of the frames.

    Returns:
        One :class:`~torchmeshmetric.Mesh` per frame, in the order of :func:`list_frames`.

    Raises:
        MeshFileError: no frame found, or a frame cannot be read (the message names the file).
        DTypeError: ``dtype`` is neither torch.float32 nor torch.float64.

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> for n in (3, 1):
        ...     _ = (d / f"f{n}.obj").write_text(f"v 0 0 {n}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        >>> tuple(float(m.verts[0, 2]) for m in load_sequence(d))
        (1.0, 3.0)
    """
    with iter_sequence(paths, dtype=dtype) as frames:
        return list(frames)


def iter_sequence(paths: PathsLike, *, dtype: torch.dtype = torch.float32, ahead: int = 2) -> Prefetcher[Mesh]:
    r"""The frames of a sequence, in natural order, loaded ``ahead`` frames in advance by a background thread.

    Use it where frames are processed one at a time: frame ``k + 1`` is read and parsed while frame ``k`` is
    being used, and at most ``ahead + 1`` frames are in memory. Same files, order and errors as
    :func:`load_sequence`.

    Args:
        paths: a directory, a glob pattern, a single file or a list of files.
        dtype: vertex dtype of the frames.
        ahead: frames loaded in advance (>= 1).

    Returns:
        A :class:`Prefetcher` (an iterator and a context manager).

    Raises:
        MeshFileError: no frame found (at once), or a frame cannot be read (when that frame is reached).
        DTypeError: ``dtype`` is neither torch.float32 nor torch.float64 (at once).

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> for n in (2, 1):
        ...     _ = (d / f"f{n}.obj").write_text(f"v 0 0 {n}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        >>> with iter_sequence(d) as frames:
        ...     tuple(m.num_verts for m in frames)
        (3, 3)
    """
    check_float_dtype(dtype)  # at once, not when the first frame is reached
    return prefetch_frames(list_frames(paths), load=lambda p: load_mesh(p, dtype=dtype), ahead=ahead)


T = TypeVar("T")


class Prefetcher(Iterator[T]):
    """Items ``load(path)`` produced by a background thread, ``ahead`` items in advance, yielded in order.

    An exception raised by ``load`` is re-raised by :meth:`__next__` at the item that failed (the items before it
    are yielded first), and nothing after it is loaded. :meth:`close` (also on leaving a ``with`` block, on
    garbage collection, and after the last item) stops the thread, which finishes at most the item it is loading;
    an early ``break`` or a ``KeyboardInterrupt`` in the consumer therefore never leaves work running.

    Args:
        paths: the items' paths, in order.
        load: called on each path in the background thread.
        ahead: items loaded in advance (>= 1).

    Example:
        >>> with Prefetcher(["a", "b", "c"], load=str.upper, ahead=2) as items:
        ...     list(items)
        ['A', 'B', 'C']
    """

    def __init__(self, paths: Iterable[Any], load: Callable[[Any], T], ahead: int = 2) -> None:
        ahead = check_int(ahead, "ahead", 1)
        if not callable(load):
            raise TypeError(f"load: expected a callable, found {type(load).__name__}")
        self._paths = list(paths)
        self._load = load
        self._queue: queue.Queue[tuple[bool, Any]] = queue.Queue(maxsize=ahead)
        self._stop = threading.Event()
        self._done = False
        self._thread = threading.Thread(target=self._work, name="torchmeshmetric-prefetch", daemon=True)
        self._thread.start()

    def _put(self, item: tuple[bool, Any]) -> bool:
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def _work(self) -> None:
        for path in self._paths:
            if self._stop.is_set():
                return
            try:
                item = (True, self._load(path))
            except BaseException as exc:  # handed to the consumer, raised there at this item
                self._put((False, exc))
                return
            if not self._put(item):
                return
        self._put((True, _END))

    def __iter__(self) -> Prefetcher[T]:
        return self

    def __next__(self) -> T:
        if self._done:
            raise StopIteration
        try:
            while True:
                try:
                    ok, value = self._queue.get(timeout=0.1)
                    break
                except queue.Empty:
                    if not self._thread.is_alive() and self._queue.empty():
                        raise RuntimeError("prefetch: the loading thread ended without a result") from None
        except BaseException:
            self.close()
            raise
        if not ok:
            self.close()
            raise value
        if value is _END:
            self.close()
            raise StopIteration
        return cast(T, value)

    def close(self) -> None:
        """Stop the background thread and drop what it loaded ahead (idempotent)."""
        self._done = True
        self._stop.set()
        while True:
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join()

    def __enter__(self) -> Prefetcher[T]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        if getattr(self, "_thread", None) is not None:
            self._stop.set()


_END = object()


@overload
def prefetch_frames(paths: PathsLike, *, load: None = None, ahead: int = 2) -> Prefetcher[Mesh]: ...


@overload
def prefetch_frames(paths: PathsLike, *, load: Callable[[Path], T], ahead: int = 2) -> Prefetcher[T]: ...


def prefetch_frames(paths: PathsLike, *, load: Callable[[Path], Any] | None = None, ahead: int = 2) -> Prefetcher[Any]:
    r"""Load frames in a background thread, ``ahead`` in advance, and yield them in order (I/O overlaps work).

    Args:
        paths: a directory, a glob pattern, a single file or a list of files (see :func:`list_frames`).
        load: what to call on each path (default :func:`load_mesh`), e.g.
            :func:`~torchmeshmetric.mpeg.load_textured_mesh`.
        ahead: frames loaded in advance (>= 1); at most ``ahead + 1`` frames are in memory.

    Returns:
        A :class:`Prefetcher`: iterate it, preferably in a ``with`` block (it is closed on leaving it, on an early
        ``break`` once collected, and after the last frame). An error loading frame ``k`` is raised when frame
        ``k`` is reached.

    Raises:
        MeshFileError: no frame found (at once).
        ValueError: ``ahead < 1``.
        TypeError: ``ahead`` is not an int.

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> for n in (10, 2):
        ...     _ = (d / f"f{n}.obj").write_text(f"v 0 0 {n}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        >>> with prefetch_frames(d, ahead=1) as frames:
        ...     tuple(float(m.verts[0, 2]) for m in frames)
        (2.0, 10.0)
    """
    files = list_frames(paths)
    return Prefetcher(files, load if load is not None else load_mesh, ahead)
