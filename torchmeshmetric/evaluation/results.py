"""Result objects of the evaluation system: one frame pair, a whole sequence, and their aggregates.

Vocabulary (paper, Section II.C): for the simplified mesh of frame ``k`` the evaluation builds four distance sets,
each measured from the simplified vertices (Eq. 3):

* ``surface_k`` — mesh surface distance to the original mesh of frame ``k`` (Eq. 4, :math:`D^{(k)}_{surf(k)}`);
* ``surface_k_minus_1`` — mesh surface distance to the original frame ``k-1`` registered onto frame ``k``
  (:math:`D^{(k)}_{surf(k-1)}`);
* ``vertex_k`` — nearest vertex distance to the vertices of frame ``k`` (Eq. 5, :math:`D^{(k)}_{vertex(k)}`);
* ``vertex_k_minus_1`` — nearest vertex distance to the vertices of the registered frame ``k-1``.

Beyond the paper, the ``flicker`` set (:mod:`torchmeshmetric.evaluation.flicker`) measures from the simplified
vertices of frame ``k`` to the simplified frame ``k-1`` moved onto frame ``k`` by the registration: consecutive
simplified frames against each other, which the paper's ``k-1`` sets (against the *original* frame ``k-1``) cannot
see. It is present when the simplified frame ``k-1`` was given (always in a sequence evaluation).

Beyond the paper, the *reverse* sets measure the same four distances from the reference (the vertices of frame
``k`` or of the registered frame ``k-1``) to the simplified mesh, so a simplification that drops part of the
surface cannot score well (the paper's one-sided sets are blind to missing parts).
"""

from __future__ import annotations

from typing import NamedTuple

from torch import Tensor

from torchmeshmetric.evaluation.flicker import FLICKER
from torchmeshmetric.stats import DistanceStatistics
from torchmeshmetric.stats.statistics import mean_psnr

__all__ = [
    "BEST_PAIR_RULE",
    "FLOOR_SET_NAMES",
    "SET_NAMES",
    "PairEvaluation",
    "SequenceEvaluation",
    "flatten_statistics",
    "mean_statistics",
]

#: The four distance sets of the paper, in the order of its Section II.C.
SET_NAMES: tuple[str, str, str, str] = ("surface_k_minus_1", "surface_k", "vertex_k_minus_1", "vertex_k")

#: Sets measured against the registered frame ``k-1``: their differences between methods are only meaningful above
#: the registration's error (its noise floor, see :func:`~torchmeshmetric.evaluation.compare_methods`).
FLOOR_SET_NAMES: tuple[str, ...] = ("surface_k_minus_1", "vertex_k_minus_1", FLICKER)

#: How :meth:`SequenceEvaluation.best_pair_index` picks the paper's "best" (representative) frame pair.
BEST_PAIR_RULE = (
    "the frame pair whose original frames move the least: smallest mean displacement of the registered "
    "frame k-1 vertices from their original positions, relative to the bounding-box diagonal of frame k "
    "(independent of the simplification method, so every method is judged on the same pair; ties: lowest k)"
)


class PairEvaluation(NamedTuple):
    """Evaluation of the simplified mesh of one frame ``k`` against original frames ``k`` and ``k-1``.

    Attributes:
        frame: index ``k`` of the simplified frame in its sequence (``k >= 1``).
        distances: the four distance sets (keys :data:`SET_NAMES`), each ``(V_s,)`` with one value per vertex of
            the simplified mesh (referenced vertices only), not squared, on the evaluation device; plus
            ``"flicker"`` when the simplified frame ``k-1`` was given (see :attr:`set_names`).
        statistics: :class:`~torchmeshmetric.stats.DistanceStatistics` of each set.
        reverse_distances: reference → simplified sets under the same keys (``surface_*``: reference vertices to
            the simplified surface; ``vertex_*``: reference vertices to the nearest simplified vertex); ``(V_ref,)``
            each. Empty dict when evaluated one-sided.
        reverse_statistics: statistics of the reverse sets (empty dict when one-sided).
        registration_residual: ``(V_{k-1},)`` distance of every registered frame ``k-1`` vertex to the surface of
            original frame ``k``: the registration's own quality (0 for a perfect registration).
        registration_converged: the registration's own convergence flag (``True`` for a given registration).
        motion: mean displacement of the registered ``k-1`` vertices from their original positions divided by the
            bounding-box diagonal of frame ``k`` (used to pick the best pair, see :data:`BEST_PAIR_RULE`).
        peak: the PSNR peak used for every set of this pair (bounding-box diagonal of original frame ``k``).
        timings: seconds spent in ``"registration"`` (0 on a cache hit), ``"distances"`` and ``"statistics"``.
        registration_cached: ``True`` when the registration came from a cache or was given by the caller.
        registration_error: ``(V_{k-1},)`` distance of every registered vertex to its true position in frame ``k``
            when the true motion was given (e.g. the built-in sequence), else ``None``.
        registration_error_statistics: statistics of :attr:`registration_error`, or ``None``.

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.evaluation import evaluate_sequence
        >>> frames = [trimesh.creation.icosphere(1)] * 3
        >>> moved = [f.copy().apply_translation([0.01, 0, 0]) for f in frames]  # every vertex 0.01 away
        >>> seq = evaluate_sequence(frames, moved, registration_fn=lambda s, t: s)
        >>> pair = seq.pairs[0]
        >>> pair.frame, pair.set_names, tuple(pair.distances["vertex_k"].shape)
        (1, ('surface_k_minus_1', 'surface_k', 'vertex_k_minus_1', 'vertex_k', 'flicker'), (42,))
        >>> round(pair.statistics["vertex_k"].max.item(), 12), pair.registration_converged, round(pair.peak, 6)
        (0.01, True, 3.464102)
    """

    frame: int
    distances: dict[str, Tensor]
    statistics: dict[str, DistanceStatistics]
    reverse_distances: dict[str, Tensor]
    reverse_statistics: dict[str, DistanceStatistics]
    registration_residual: Tensor
    registration_statistics: DistanceStatistics
    registration_converged: bool
    motion: float
    peak: float
    timings: dict[str, float]
    registration_cached: bool
    registration_error: Tensor | None = None
    registration_error_statistics: DistanceStatistics | None = None

    @property
    def set_names(self) -> tuple[str, ...]:
        """The sets this pair holds: :data:`SET_NAMES`, then ``"flicker"`` when it was measured."""
        return SET_NAMES + ((FLICKER,) if FLICKER in self.statistics else ())

    def as_dict(self) -> dict[str, object]:
        """JSON-ready summary (statistics only, no per-vertex values).

        Returns:
            ``{"frame", "surface_k", "surface_k_minus_1", "vertex_k", "vertex_k_minus_1", ["flicker",] "reverse",
            "registration", "timings"}``; each set maps statistic names (``ave``, ``var``, ``std``, ``mse``,
            ``rmse``, ``max``, ``min``, ``median``, ``p95``, ``p99``, ``count``, ``psnr``) to floats.
        """
        out: dict[str, object] = {"frame": self.frame}
        out.update({name: self.statistics[name].as_dict() for name in self.set_names})
        out["reverse"] = {name: s.as_dict() for name, s in self.reverse_statistics.items()}
        out["registration"] = {
            "residual": self.registration_statistics.as_dict(),
            "converged": self.registration_converged,
            "motion": self.motion,
            "cached": self.registration_cached,
        }
        if self.registration_error_statistics is not None:
            out["registration"]["error"] = self.registration_error_statistics.as_dict()  # type: ignore[index]
        out["peak"] = self.peak
        out["timings"] = dict(self.timings)
        return out


def mean_statistics(stats: list[DistanceStatistics]) -> dict[str, float]:
    """Mean of per-pair statistics, field by field: the paper's "average performance" (Tables III/IV).

    Every field is the arithmetic mean over pairs of that field (so the aggregate ``std`` is the mean of the
    per-pair standard deviations, not the standard deviation of the pooled distances; ``count`` is the mean
    number of values per pair). This is what the paper reports as "the average result in all five mesh pairs".
    The ``psnr`` follows the library's rule for an infinite PSNR (:func:`~torchmeshmetric.stats.statistics.mean_psnr`):
    a pair measured without error (``psnr = inf``) is left out of the mean PSNR, which is ``inf`` only when every pair
    is (before, one lossless pair made a method's mean PSNR ``inf`` whatever its other pairs lost).

    Args:
        stats: one :class:`~torchmeshmetric.stats.DistanceStatistics` per pair (non-empty).

    Returns:
        Statistic name → mean value. A field that is ``None`` in every pair (``psnr`` of statistics computed
        without a peak) has no mean and no key (it raised ``TypeError: float() ... NoneType``).

    Raises:
        ValueError: ``stats`` is empty, or a field is ``None`` in some pairs only.

    Example:
        >>> from collections import namedtuple
        >>> S = namedtuple("S", "ave rmse")
        >>> mean_statistics([S(1.0, 2.0), S(3.0, 4.0)])
        {'ave': 2.0, 'rmse': 3.0}
    """
    if not stats:
        raise ValueError("stats: expected at least one pair, found none")
    fields = stats[0]._fields
    out: dict[str, float] = {}
    for f in fields:
        values = [getattr(s, f) for s in stats]
        missing = [i for i, v in enumerate(values) if v is None]
        if len(missing) == len(values):  # statistics without a peak have psnr=None: there is no mean PSNR
            continue
        if missing:  # the mean of some pairs only would pass for the mean of all
            raise ValueError(
                f"stats: {f} is None in pair {missing[0]} (computed without a peak?) but a number in pair "
                f"{values.index(next(v for v in values if v is not None))}; give every pair the same peak"
            )
        if f == "psnr":
            out[f] = mean_psnr([float(v) for v in values], "stats: the pairs' psnr")[0]
        else:
            out[f] = sum(float(v) for v in values) / len(values)
    return out


class SequenceEvaluation(NamedTuple):
    """Evaluation of a simplified sequence: one :class:`PairEvaluation` per frame pair ``(k-1, k)``, ``k >= 1``.

    Attributes:
        pairs: per-pair evaluations, in frame order.

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.evaluation import evaluate_sequence
        >>> frames = [trimesh.creation.icosphere(1)] * 3
        >>> moved = [f.copy().apply_translation([0.01, 0, 0]) for f in frames]  # every vertex 0.01 away
        >>> seq = evaluate_sequence(frames, moved, registration_fn=lambda s, t: s)
        >>> [p.frame for p in seq.pairs], seq.best_pair_index()
        ([1, 2], 0)
        >>> round(seq.aggregate().get("vertex_k").get("ave"), 12)  # mean over the pairs
        0.01
    """

    pairs: list[PairEvaluation]

    @property
    def set_names(self) -> tuple[str, ...]:
        """The sets every pair holds: :data:`SET_NAMES`, then ``"flicker"`` when every pair has it."""
        has_flicker = bool(self.pairs) and all(FLICKER in p.statistics for p in self.pairs)
        return SET_NAMES + ((FLICKER,) if has_flicker else ())

    def aggregate(self) -> dict[str, dict[str, float]]:
        """The paper's "average performance" (Tables III/IV): per set, the mean over pairs of each statistic.

        Returns:
            ``{set_name: {statistic: mean}}`` for the four :data:`SET_NAMES` and ``"flicker"`` when measured (see
            :func:`mean_statistics`).
        """
        return {name: mean_statistics([p.statistics[name] for p in self.pairs]) for name in self.set_names}

    def aggregate_reverse(self) -> dict[str, dict[str, float]]:
        """Mean over pairs of the reverse (reference → simplified) statistics; empty when evaluated one-sided."""
        if not self.pairs or not self.pairs[0].reverse_statistics:
            return {}
        return {name: mean_statistics([p.reverse_statistics[name] for p in self.pairs]) for name in self.set_names}

    def aggregate_registration(self) -> dict[str, dict[str, float]]:
        """Mean over pairs of the registration's ``residual`` statistics, and of its ``error`` when known."""
        out = {"residual": mean_statistics([p.registration_statistics for p in self.pairs])}
        errors = [p.registration_error_statistics for p in self.pairs]
        if errors and all(e is not None for e in errors):
            out["error"] = mean_statistics(errors)  # type: ignore[arg-type]
        return out

    def best_pair_index(self) -> int:
        """Index into :attr:`pairs` of the paper's best pair (Tables I/II); see :data:`BEST_PAIR_RULE`."""
        if not self.pairs:
            raise ValueError("pairs: the sequence evaluation holds no frame pair")
        return min(range(len(self.pairs)), key=lambda i: (self.pairs[i].motion, self.pairs[i].frame))

    def as_dict(self) -> dict[str, object]:
        """JSON-ready summary: ``{"pairs": [...], "aggregate": {...}, "best_pair": {...}}``.

        ``aggregate`` holds the sets under the same keys as each pair, plus ``"reverse"`` (two-sided only)
        and ``"registration"`` (mean of the residual statistics, and of the error to the true motion when known).
        """
        best = self.best_pair_index()
        aggregate: dict[str, object] = dict(self.aggregate())
        aggregate["reverse"] = self.aggregate_reverse()
        aggregate["registration"] = self.aggregate_registration()
        return {
            "pairs": [p.as_dict() for p in self.pairs],
            "aggregate": aggregate,
            "best_pair": {"index": best, "frame": self.pairs[best].frame, "rule": BEST_PAIR_RULE},
        }


def flatten_statistics(nested: dict[str, object], sep: str = "/") -> dict[str, object]:
    """Flatten a nested statistics dict (e.g. :meth:`TemporalConsistency.compute`) for ``log_dict``.

    Args:
        nested: statistic names to values or to nested dicts of them.
        sep: the separator of the flattened keys.

    Returns:
        One entry per leaf, keyed by its path joined with ``sep``.

    Raises:
        ValueError: two leaves flatten to one key (``{"a/b": 1, "a": {"b": 2}}`` kept one of the two in silence).

    Example:
        >>> flatten_statistics({"surface_k": {"ave": 1.0}, "reverse": {"vertex_k": {"max": 2.0}}})
        {'surface_k/ave': 1.0, 'reverse/vertex_k/max': 2.0}
    """
    flat: dict[str, object] = {}

    def put(key: str, value: object) -> None:
        if key in flat:
            raise ValueError(f"nested: two statistics flatten to the key {key!r} (separator {sep!r}); rename one")
        flat[key] = value

    for key, value in nested.items():
        if isinstance(value, dict):
            for sub, v in flatten_statistics(value, sep).items():
                put(f"{key}{sep}{sub}", v)
        else:
            put(key, value)
    return flat
