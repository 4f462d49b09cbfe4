"""Tasks shared by the ranks of a ``torch.distributed`` process group: shard by index, run, gather in order.

The package's ground floor for parallel work (it imports torch only): evaluation maps its frame pairs through
:func:`run_tasks`, the ``ctc`` command its frames, and :mod:`torchmeshmetric.launch` names the ranks that failed
from what :func:`run_tasks` posts. Task ``i`` runs on rank ``i % world_size``; each result is moved to the CPU and
gathered with ``torch.distributed``'s object collectives, so results equal a single process's exactly when each task
is computed by the same call with the same inputs.

Failures: a task that raises stops its rank's share; all ranks then learn of it in the next collective and raise
:class:`RankFailedError` naming the rank and the task. A rank that dies (killed, crashed) is detected by the collective
(the transport reports the lost peer) and named from the status every rank posts in the process group's store.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import torch
import torch.distributed as dist

from torchmeshmetric._checks import check_int

__all__ = [
    "RankFailedError",
    "default_store",
    "exchange",
    "in_flight",
    "is_distributed",
    "rank_and_world_size",
    "run_tasks",
    "shard",
]

T = TypeVar("T")
R = TypeVar("R")

_IDLE = "idle"
_call_counter = itertools.count()
_current: _Board | None = None


class RankFailedError(RuntimeError):
    """A rank raised or died while working on a task; raised on every surviving rank.

    Attributes:
        rank: the failing rank (``-1`` when it could not be identified).
        task: what that rank was doing (e.g. ``"sequence 'a' method 'QEM' frame pair 1 -> 2"``).
        reason: the error message (or ``"died"`` for a rank that stopped without a message).
    """

    def __init__(self, rank: int, task: str, reason: str) -> None:
        self.rank, self.task, self.reason = rank, task, reason
        who = f"rank {rank}" if rank >= 0 else "a rank"
        super().__init__(f"{who} failed on {task}: {reason}")


def is_distributed() -> bool:
    """``True`` inside an initialised process group of more than one rank.

    Returns:
        Whether tasks are shared between ranks.

    Example:
        >>> is_distributed()  # a plain process
        False
    """
    return dist.is_available() and dist.is_initialized() and dist.get_world_size() > 1


def rank_and_world_size() -> tuple[int, int]:
    """``(rank, world_size)`` of the default process group; ``(0, 1)`` outside one.

    Returns:
        This process's rank and the number of ranks.

    Example:
        >>> rank_and_world_size()  # a plain process
        (0, 1)
    """
    if dist.is_available() and dist.is_initialized():
        return dist.get_rank(), dist.get_world_size()
    return 0, 1


def shard(num_tasks: int, rank: int, world_size: int) -> range:
    """Indices of the tasks of ``rank``: ``rank, rank + world_size, ...`` (round robin, so ranks stay balanced).

    Args:
        num_tasks: the number of tasks, ``>= 0``.
        rank: this process's rank, in ``[0, world_size)``.
        world_size: the number of processes, ``>= 1``.

    Returns:
        The task indices of ``rank``.

    Raises:
        TypeError: an argument is not an int.
        ValueError: an argument is out of its range (``world_size=0`` raised ``range()``'s error; a rank outside
            the world was given no task, or another rank's, in silence).

    Example:
        >>> list(shard(5, 0, 2)), list(shard(5, 1, 2))
        ([0, 2, 4], [1, 3])
    """
    num_tasks = check_int(num_tasks, "num_tasks", 0)
    world_size = check_int(world_size, "world_size", 1)
    rank = check_int(rank, "rank", 0)
    if rank >= world_size:
        raise ValueError(f"rank: expected a rank in [0, {world_size - 1}] (world_size {world_size}), found {rank}")
    return range(rank, num_tasks, world_size)


def default_store() -> Any:
    """The default process group's key-value store; ``None`` outside a group or where it is not reachable.

    c10d keeps the accessor private, so this is the one place that reaches for it (the task board and the command
    line's error lines both post there).
    """
    try:
        return dist.distributed_c10d._get_default_store()
    except Exception:
        return None


def exchange(obj: Any, *, what: str) -> list[Any]:
    """Every rank's ``obj``, in rank order (a collective); ``[obj]`` outside a process group.

    Args:
        obj: this rank's picklable object.
        what: the exchange's name in the error when a rank is lost (e.g. ``"the exchange of registrations"``).

    Raises:
        RankFailedError: a rank died before the exchange.

    Example:
        >>> exchange({"a": 1}, what="the example")
        [{'a': 1}]
    """
    if not is_distributed():
        return [obj]
    gathered: list[Any] = [None] * dist.get_world_size()
    try:
        dist.all_gather_object(gathered, obj)
    except Exception as exc:  # a rank died since the last collective
        raise RankFailedError(-1, what, f"lost contact ({_one_line(exc)})") from exc
    return gathered


def _to_cpu(obj: Any) -> Any:
    """Tensors moved to the CPU inside NamedTuples, dicts, lists and tuples.

    A CUDA tensor pickled on rank 1 would otherwise be unpickled onto rank 0's ``cuda:1``.
    """
    if isinstance(obj, torch.Tensor):
        return obj.detach().cpu()
    if isinstance(obj, tuple) and hasattr(obj, "_fields"):
        return type(obj)(*(_to_cpu(v) for v in obj))
    if isinstance(obj, (list, tuple)):
        return type(obj)(_to_cpu(v) for v in obj)
    if isinstance(obj, dict):
        return {k: _to_cpu(v) for k, v in obj.items()}
    return obj


def name_task(exc: BaseException, task: str) -> None:
    """Add ``while running <task>`` to an exception's notes (``add_note``), keeping its type; once per task.

    Example:
        >>> err = ValueError("bad frame")
        >>> name_task(err, "frame pair 1 -> 2")
        >>> err.__notes__
        ['while running frame pair 1 -> 2']
    """
    note = f"while running {task}"
    notes = list(getattr(exc, "__notes__", []))
    if note in notes:
        return
    if hasattr(exc, "add_note"):
        exc.add_note(note)
    else:  # pragma: no cover (Python 3.10: no add_note, the same attribute)
        exc.__notes__ = [*notes, note]


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text.splitlines()[0]}" if text else type(exc).__name__


class _Board:
    """Status and progress of one :func:`run_tasks` call in the process group's key-value store."""

    def __init__(self, rank: int, world_size: int) -> None:
        self.rank, self.world_size = rank, world_size
        self.store: Any = None
        if world_size > 1:
            base = default_store()  # progress and fault names degrade without it
            if base is not None:
                self.store = dist.PrefixStore(f"torchmeshmetric/tasks/{next(_call_counter)}/", base)

    def post(self, status: str) -> None:
        if self.store is not None:
            self.store.set(f"status/{self.rank}", status)

    def count_done(self) -> None:
        if self.store is not None:
            self.store.add("done", 1)

    def done(self) -> int:
        return int(self.store.add("done", 0)) if self.store is not None else 0

    def status(self, rank: int) -> str | None:
        if self.store is None:
            return None
        try:
            if not self.store.check([f"status/{rank}"]):
                return "its first task (it never started)"
            return bytes(self.store.get(f"status/{rank}")).decode()
        except Exception:
            return None

    def lost_rank(self, exc: BaseException) -> RankFailedError:
        """The failure to report when a collective broke because a peer is gone."""
        for rank in range(self.world_size):
            status = self.status(rank) if rank != self.rank else _IDLE
            if status is not None and status != _IDLE:
                return RankFailedError(rank, status, "the process died (killed or crashed) or lost contact")
        return RankFailedError(-1, "a collective", f"lost contact with another rank ({_one_line(exc)})")


class _Progress:
    """Rank 0 reports the tasks done by all ranks, read from the store by a helper thread."""

    def __init__(self, board: _Board, total: int, progress: Callable[[int, int], None] | None) -> None:
        self.board, self.total, self.progress = board, total, progress
        self.shown = 0
        self.stop = threading.Event()
        self.thread: threading.Thread | None = None
        if progress is not None and board.rank == 0 and board.store is not None:
            self.thread = threading.Thread(target=self._poll, name="torchmeshmetric-progress", daemon=True)
            self.thread.start()

    def _show(self, done: int) -> None:
        if self.progress is not None and done > self.shown:
            self.shown = done
            self.progress(done, self.total)

    def _poll(self) -> None:
        while not self.stop.wait(0.5):
            try:
                self._show(self.board.done())
            except Exception:  # the store went away with a lost rank: the collective reports it
                return

    def local(self, done: int) -> None:
        """After a task of this process: a single process reports itself."""
        if self.board.world_size == 1:
            self._show(done)

    def finish(self, ok: bool) -> None:
        self.stop.set()
        if self.thread is not None:
            self.thread.join()
        if ok and self.board.rank == 0:
            self._show(self.total)


def run_tasks(
    fn: Callable[[T], R],
    tasks: Sequence[T],
    *,
    describe: Callable[[T], str],
    to: int | None = 0,
    progress: Callable[[int, int], None] | None = None,
) -> list[R] | None:
    """Run ``fn`` on this rank's share of ``tasks`` and gather the results in task order.

    Outside a process group (or with one rank) every task runs here. Every rank must call this with the same
    tasks (a collective).

    Args:
        fn: computes one task's result (any picklable object; tensors are moved to the CPU before gathering).
        tasks: the work items, identical on every rank.
        describe: a task's name in messages (e.g. ``"frame pair 1 -> 2"``).
        to: the rank that receives the results (others get ``None``); ``None``: every rank receives them.
        progress: called on rank 0 as ``progress(done, len(tasks))`` as tasks finish on any rank.

    Returns:
        ``[fn(task) for task in tasks]`` on the receiving rank(s), ``None`` on the others.

    Raises:
        RankFailedError: on every rank, when a task raised on some rank or a rank died.
        Exception: with one rank (or none), a task's own exception, its task added to its notes
            (:func:`name_task`; the command line's error line shows them).

    Example:
        >>> run_tasks(lambda x: x * x, [1, 2, 3], describe=str)
        [1, 4, 9]
    """
    global _current
    rank, world_size = rank_and_world_size()
    board = _current = _Board(rank, world_size)
    display = _Progress(board, len(tasks), progress)
    mine: list[tuple[int, Any]] = []
    failure: tuple[int, str, str] | None = None
    ok = False
    try:
        for n, i in enumerate(shard(len(tasks), rank, world_size), start=1):
            board.post(describe(tasks[i]))
            if world_size == 1:
                try:
                    mine.append((i, fn(tasks[i])))
                except Exception as exc:  # its own type, the task named as two ranks name it
                    name_task(exc, describe(tasks[i]))
                    raise
            else:
                try:
                    mine.append((i, _to_cpu(fn(tasks[i]))))
                except Exception as exc:  # reported by every rank after the next collective
                    failure = (rank, describe(tasks[i]), _one_line(exc))
                    break
            board.count_done()
            display.local(n)
        board.post(_IDLE)
        if world_size == 1:
            ok = True
            return [result for _, result in mine]
        try:
            failures: list[Any] = [None] * world_size
            dist.all_gather_object(failures, failure)
            reported = next((f for f in failures if f is not None), None)
            if reported is not None:
                raise RankFailedError(*reported)
            gathered: list[Any] = [None] * world_size
            if to is None:
                dist.all_gather_object(gathered, mine)
            else:
                dist.gather_object(mine, gathered if rank == to else None, dst=to)
        except RankFailedError:
            raise
        except Exception as exc:  # the transport lost a peer
            raise board.lost_rank(exc) from exc
        ok = True
        if to is not None and rank != to:
            return None
        ordered = sorted(itertools.chain.from_iterable(gathered), key=lambda item: item[0])
        return [result for _, result in ordered]
    finally:
        display.finish(ok)
        if ok:  # after a failure the board stays readable for in_flight()
            _current = None


def in_flight() -> list[tuple[int, str]]:
    """``(rank, task)`` of the other ranks that were busy when this one was stopped (the suspects of a failure).

    Read from the process group's store while :func:`run_tasks` runs; empty outside it or without a store.
    """
    board = _current
    if board is None:
        return []
    busy = []
    for rank in range(board.world_size):
        status = board.status(rank) if rank != board.rank else None
        if status is not None and status != _IDLE:
            busy.append((rank, status))
    return busy
