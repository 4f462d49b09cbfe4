"""Evaluation across the ranks of a ``torch.distributed`` process group: shard by index, gather, one result.

The work of an evaluation is a list of independent tasks: first the registrations of the original frame pairs
(done while evaluating the first method on each pair), then every other method x frame pair (distance sets only,
the registration comes from the shared cache). Task ``i`` runs on rank ``i % world_size``; each task's result is
whatever the pipeline returns for one frame pair (a :class:`PairEvaluation` today), moved to the CPU and gathered with
``torch.distributed``'s object collectives, so new distance sets or columns need no change here.

Results equal a single-process run's exactly: every pair is computed by the same call with the same inputs and
the same cache semantics (the first method's pairs compute or load the registration, later methods hit the cache);
registration results depend on the torch thread count, so compare runs with the same threads per process.

Failures: a task that raises stops its rank's share; all ranks then learn of it in the next collective and raise
:class:`RankFailedError` naming the rank and the task. A rank that dies (killed, crashed) is detected by the collective
(the transport reports the lost peer) and named from the status every rank posts in the process group's store.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable, Mapping, Sequence
from typing import Any, NamedTuple, TypeVar

import torch
import torch.distributed as dist

from torchmeshmetric._deprecation import renamed_keywords
from torchmeshmetric.evaluation.cache import CachedRegistration, RegistrationCache
from torchmeshmetric.evaluation.pipeline import _check_sequence, check_methods, evaluate_sequence
from torchmeshmetric.evaluation.results import SequenceEvaluation
from torchmeshmetric.structures import MeshLike

__all__ = [
    "RankFailedError",
    "SequenceWork",
    "evaluate_sequences",
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
    """``True`` inside an initialised process group of more than one rank."""
    return dist.is_available() and dist.is_initialized() and dist.get_world_size() > 1


def rank_and_world_size() -> tuple[int, int]:
    """``(rank, world_size)`` of the default process group; ``(0, 1)`` outside one."""
    if dist.is_available() and dist.is_initialized():
        return dist.get_rank(), dist.get_world_size()
    return 0, 1


def shard(num_tasks: int, rank: int, world_size: int) -> range:
    """Indices of the tasks of ``rank``: ``rank, rank + world_size, ...`` (round robin, so ranks stay balanced).

    Example:
        >>> list(shard(5, 0, 2)), list(shard(5, 1, 2))
        ([0, 2, 4], [1, 3])
    """
    return range(rank, num_tasks, world_size)


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


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text.splitlines()[0]}" if text else type(exc).__name__


class _Board:
    """Status and progress of one :func:`run_tasks` call in the process group's key-value store."""

    def __init__(self, rank: int, world_size: int) -> None:
        self.rank, self.world_size = rank, world_size
        self.store: Any = None
        if world_size > 1:
            try:  # the default group's store (c10d keeps it private; progress and fault names degrade without it)
                base = dist.distributed_c10d._get_default_store()
                self.store = dist.PrefixStore(f"torchmeshmetric/tasks/{next(_call_counter)}/", base)
            except Exception:
                self.store = None

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
                mine.append((i, fn(tasks[i])))
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


class SequenceWork(NamedTuple):
    """One original sequence and the simplified sequences of the methods evaluated on it.

    Attributes:
        name: the sequence's name in messages (``""`` for an unnamed sequence).
        original: the ``N`` original frames.
        methods: method name -> its ``N`` simplified frames.
    """

    name: str
    original: Sequence[MeshLike]
    methods: Mapping[str, Sequence[MeshLike]]


def _at_frame(pair: Any, k: int) -> Any:
    """The pair evaluated on the two-frame slice ``(k-1, k)`` carries frame 1; give it its index in the sequence."""
    return pair._replace(frame=k)


def _describe(work: Sequence[SequenceWork], w: int, method: str, k: int) -> str:
    seq = f"sequence {work[w].name!r} " if work[w].name else ""
    named = f"method {method!r} " if method else ""
    return f"{seq}{named}frame pair {k - 1} -> {k}"


@renamed_keywords(cache="registration_cache", registrations="precomputed_registrations")
def evaluate_sequences(
    work: Sequence[SequenceWork],
    *,
    registration_cache: RegistrationCache | None = None,
    precomputed_registrations: Sequence[Sequence[Any] | None] | None = None,
    to: int | None = 0,
    progress: Callable[[int, int], None] | None = None,
    **options: Any,
) -> list[dict[str, SequenceEvaluation]] | None:
    """Evaluate every method of every sequence, sharded over the ranks (or in this process outside a group).

    Tasks: first the pairs of each sequence's first method (they compute the registrations of the original pairs),
    then, with those registrations shared by all ranks, every other method x pair. Each task is
    :func:`~torchmeshmetric.evaluation.evaluate_sequence` on the two frames ``(k-1, k)``, so every pair is exactly
    what a single-process run computes.

    Args:
        work: the sequences and their methods (identical on every rank).
        registration_cache: the registration cache (default: a new in-memory cache); a shared folder lets ranks
            and later runs reuse registrations.
        precomputed_registrations: per sequence, optional precomputed registrations (see ``evaluate_sequence``).
        to: the rank that receives the results (``None``: every rank).
        progress: called on rank 0 as ``progress(pairs_done, pairs_total)`` across all ranks.
        **options: passed to ``evaluate_sequence`` (``two_sided``, ``device``, ``registration_fn``, ...).

    The keywords ``cache`` and ``registrations`` are the deprecated names of ``registration_cache`` and
    ``precomputed_registrations``.

    Returns:
        Per sequence, method name -> :class:`SequenceEvaluation` (on the receiving rank(s)); ``None`` elsewhere.

    Raises:
        ValueError: before any work (on every rank alike): a method whose frame count differs from its sequence's,
            fewer than 2 frames, or precomputed registrations of the wrong count.
        RankFailedError: a rank raised or died; names the rank and its frame pair.
    """
    regs = list(precomputed_registrations) if precomputed_registrations is not None else [None] * len(work)
    if len(regs) != len(work):
        raise ValueError(
            f"precomputed_registrations: expected {len(work)} entries (one per sequence), found {len(regs)}"
        )
    for item, given in zip(work, regs, strict=True):  # every count checked before the first task starts
        check_methods(item.original, item.methods, sequence=item.name)
        for frames in item.methods.values():
            _check_sequence(item.original, frames, given)
    cache = registration_cache if registration_cache is not None else RegistrationCache()
    first: list[tuple[int, str, int]] = []
    rest: list[tuple[int, str, int]] = []
    for w, item in enumerate(work):
        for m, method in enumerate(item.methods):
            for k in range(1, len(item.original)):
                (first if m == 0 and regs[w] is None else rest).append((w, method, k))
    total = len(first) + len(rest)

    def one_pair(task: tuple[int, str, int]) -> Any:
        w, method, k = task
        given = regs[w]
        sub = evaluate_sequence(
            work[w].original[k - 1 : k + 1],
            work[w].methods[method][k - 1 : k + 1],
            registration_cache=cache,
            precomputed_registrations=None if given is None else given[k - 1 : k],
            **options,
        )
        return _at_frame(sub.pairs[0], k)

    def describe(task: tuple[int, str, int]) -> str:
        return _describe(work, *task)

    def counted(offset: int) -> Callable[[int, int], None] | None:
        if progress is None:
            return None
        return lambda done, _: progress(offset + done, total)

    journal: dict[str, CachedRegistration] = {}
    outer, cache.journal = cache.journal, journal  # the entries this call's first phase returns, by key
    try:
        first_pairs = run_tasks(one_pair, first, describe=describe, to=to, progress=counted(0))
    finally:
        cache.journal = outer
    if outer is not None:
        outer.update(journal)
    _share_registrations(cache, journal)
    rest_pairs = run_tasks(one_pair, rest, describe=describe, to=to, progress=counted(len(first)))
    if first_pairs is None or rest_pairs is None:
        return None
    by_task = dict(zip(first + rest, first_pairs + rest_pairs, strict=True))
    return [
        {
            method: SequenceEvaluation([by_task[(w, method, k)] for k in range(1, len(item.original))])
            for method in item.methods
        }
        for w, item in enumerate(work)
    ]


def _share_registrations(cache: RegistrationCache, journal: dict[str, CachedRegistration]) -> None:
    """Every rank receives the registrations the others computed or loaded (``journal``: this rank's; a collective)."""
    if not is_distributed():
        return
    gathered: list[Any] = [None] * dist.get_world_size()
    try:
        dist.all_gather_object(gathered, journal)
    except Exception as exc:  # a rank died between the two phases
        raise RankFailedError(-1, "the exchange of registrations", f"lost contact ({_one_line(exc)})") from exc
    for entries in gathered:
        cache.adopt(entries)
