"""Several sequences and methods evaluated together, their frame pairs shared among the ranks of a process group.

The work is a list of independent frame pairs (:class:`~torchmeshmetric.evaluation.pipeline.PairTask`): first the
pairs of each sequence's first method (they compute the registrations of the original frame pairs), then every other
method x frame pair (distance sets only, the registration comes from the shared cache). Both lists go through
:func:`~torchmeshmetric.evaluation.pipeline.evaluate_pairs`, which maps
:func:`~torchmeshmetric.evaluation.evaluate_pair` through :func:`torchmeshmetric.tasks.run_tasks` (task ``i`` on rank
``i % world_size``; failures named by rank and pair).

Results equal a single-process run's exactly: every pair is computed by the same call with the same inputs and
the same cache semantics (the first method's pairs compute or load the registration, later methods hit the cache);
registration results depend on the torch thread count, so compare runs with the same threads per process.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, NamedTuple

from torchmeshmetric.evaluation.pipeline import PairTask, check_methods, check_sequence, evaluate_pairs
from torchmeshmetric.evaluation.results import SequenceEvaluation
from torchmeshmetric.registration.cache import RegistrationCache
from torchmeshmetric.structures import MeshLike

__all__ = ["SequenceWork", "evaluate_sequences"]


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


def _describe(work: Sequence[SequenceWork], w: int, method: str, k: int) -> str:
    seq = f"sequence {work[w].name!r} " if work[w].name else ""
    named = f"method {method!r} " if method else ""
    return f"{seq}{named}frame pair {k - 1} -> {k}"


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
            check_sequence(item.original, frames, given)
    cache = registration_cache if registration_cache is not None else RegistrationCache()
    first: dict[tuple[int, str, int], PairTask] = {}
    rest: dict[tuple[int, str, int], PairTask] = {}
    for w, item in enumerate(work):
        for m, (method, frames) in enumerate(item.methods.items()):
            for k in range(1, len(item.original)):
                given = None if (known := regs[w]) is None else known[k - 1]
                task = PairTask(item.original, frames, k, given, _describe(work, w, method, k))
                (first if m == 0 and regs[w] is None else rest)[(w, method, k)] = task
    total = len(first) + len(rest)

    def counted(offset: int) -> Callable[[int, int], None] | None:
        if progress is None:
            return None
        return lambda done, _: progress(offset + done, total)

    # First the pairs that compute the registrations; the second call finds them in every rank's cache.
    run: dict[str, Any] = {"registration_cache": cache, "sharded": True, "to": to, **options}
    first_pairs = evaluate_pairs(list(first.values()), progress=counted(0), **run)
    rest_pairs = evaluate_pairs(list(rest.values()), progress=counted(len(first)), **run)
    if first_pairs is None or rest_pairs is None:
        return None
    by_task = dict(zip([*first, *rest], first_pairs + rest_pairs, strict=True))
    return [
        {
            method: SequenceEvaluation([by_task[(w, method, k)] for k in range(1, len(item.original))])
            for method in item.methods
        }
        for w, item in enumerate(work)
    ]
