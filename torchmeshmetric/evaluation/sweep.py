"""Registered QEM's trade-off: a sweep over the weight of the registered previous frame, beside plain QEM.

Registered QEM (the paper's dynamic simplification) adds ``weight`` times the registered frame ``k-1``'s plane
quadrics to frame ``k``'s. A larger weight should bring the simplified frame ``k`` closer to the registered frame
``k-1`` (the paper's ``k-1`` sets) and to the previous simplified frame (``flicker``), at the cost of frame ``k``'s
own error. :func:`registered_qem_sweep` measures both for a list of weights on one sequence (the registrations are
shared), so the trade-off can be plotted as a Pareto curve (:func:`~torchmeshmetric.viz.plot_weight_sweep`) and a
weight chosen from data.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping, Sequence
from typing import Any, NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import check_flag
from torchmeshmetric.evaluation.pipeline import evaluate_sequence
from torchmeshmetric.evaluation.reports import COLUMN_FORMATS, statistic_cell
from torchmeshmetric.evaluation.results import SequenceEvaluation
from torchmeshmetric.simplification import simplify_sequence
from torchmeshmetric.structures import MeshLike, as_mesh

__all__ = ["DEFAULT_SWEEP_WEIGHTS", "SWEEP_DIGITS_NOTE", "WeightSweep", "pareto_front", "registered_qem_sweep"]

#: Weights swept by default (0 is the Registered QEM code without the previous frame).
DEFAULT_SWEEP_WEIGHTS: tuple[float, ...] = (0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0)

_SWEEP_SETS = ("surface_k", "surface_k_minus_1", "flicker")

#: Printed under the sweep's table: why weights can read alike.
SWEEP_DIGITS_NOTE = (
    "Digits as in the report's tables: only those the input determines (docs/statistics.md). Frame k: weights that "
    "read alike differ by less than rounding the frames to float32 moves the figure (up to 5e-3 relative at ~20k "
    "vertices); the registered k-1 and flicker columns too (the registration draws independently of how the original "
    "frames are stored). The sweep's JSON (weight_sweep.json) keeps every digit."
)


class WeightSweep(NamedTuple):
    """Result of :func:`registered_qem_sweep`.

    Attributes:
        weights: the swept weights, in the order given.
        results: one :class:`SequenceEvaluation` per weight.
        baseline: plain QEM (fast-simplification) on the same frames, or ``None``.

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.evaluation import evaluate_sequence
        >>> frames = [trimesh.creation.icosphere(1)] * 3
        >>> moved = [f.copy().apply_translation([0.01, 0, 0]) for f in frames]  # every vertex 0.01 away
        >>> seq = evaluate_sequence(frames, moved, registration_fn=lambda s, t: s)
        >>> sweep = WeightSweep(weights=[0.5], results=[seq], baseline=None)  # as registered_qem_sweep returns it
        >>> row = next(iter(sweep.rows("ave")))
        >>> row["weight"], round(row["surface_k"], 6) == round(seq.aggregate().get("surface_k").get("ave"), 6)
        (0.5, True)
    """

    weights: list[float]
    results: list[SequenceEvaluation]
    baseline: SequenceEvaluation | None

    def rows(self, statistic: str = "ave") -> list[dict[str, Any]]:
        """One row per weight (then the baseline, ``weight`` ``None``): ``statistic`` of each set, mean over pairs.

        Keys: ``weight``, ``surface_k``, ``surface_k_minus_1``, ``flicker``.
        """
        runs: list[tuple[float | None, SequenceEvaluation]] = list(zip(self.weights, self.results, strict=True))
        if self.baseline is not None:
            runs.append((None, self.baseline))
        out = []
        for weight, seq in runs:
            agg = seq.aggregate()
            out.append({"weight": weight, **{s: agg[s][statistic] for s in _SWEEP_SETS}})
        return out

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: ``{"weights", "ave": rows, "rmse": rows, "registration": residual/error means}``."""
        first = self.results[0] if self.results else self.baseline
        assert first is not None
        return {
            "weights": list(self.weights),
            "ave": self.rows("ave"),
            "rmse": self.rows("rmse"),
            "registration": first.aggregate_registration(),
        }

    def markdown(self, statistic: str = "ave") -> str:
        """The sweep as a Markdown table (the baseline row is ``QEM``), with the report tables' digits.

        Each cell prints only the digits the input determines, as the paper's tables do
        (:func:`~torchmeshmetric.evaluation.reports.statistic_cell`: 2 significant digits for the averages, in every
        column: the registered k-1 and flicker columns are as determined as frame k's), so weights whose figures
        differ below the input's rounding read alike; :meth:`as_dict` keeps every digit.

        Args:
            statistic: one of the printed statistics (``"ave"``, ``"var"``, ``"std"``, ``"mse"``, ``"rmse"``,
                ``"max"``, ``"p95"``, ``"psnr"``).

        Raises:
            ValueError: another ``statistic`` (``"min"``, ``"median"``: no table prints them).
        """
        if statistic not in COLUMN_FORMATS:
            raise ValueError(
                f"statistic: expected one of {', '.join(map(repr, COLUMN_FORMATS))} (the tables' statistics), "
                f"found {statistic!r}"
            )
        lines = [
            f"| method | weight | frame k ({statistic}) | registered k-1 ({statistic}) | flicker ({statistic}) |",
            "|---|---|---|---|---|",
        ]
        for row in self.rows(statistic):
            name = "QEM (fast-simplification)" if row["weight"] is None else "Registered QEM"
            weight = "" if row["weight"] is None else f"{row['weight']:g}"
            cells = " | ".join(statistic_cell(row[s], statistic) for s in _SWEEP_SETS)
            lines.append(f"| {name} | {weight} | {cells} |")
        lines += ["", SWEEP_DIGITS_NOTE]
        return "\n".join(lines) + "\n"


def registered_qem_sweep(
    frames: Sequence[MeshLike],
    registrations: Sequence[Any],
    target: int | float,
    weights: Sequence[float] = DEFAULT_SWEEP_WEIGHTS,
    *,
    baseline: bool = True,
    device: torch.device | str | None = None,
    ground_truth: Callable[[Tensor, int, int], Tensor] | None = None,
    progress: Callable[[float], None] | None = None,
) -> WeightSweep:
    """Simplify the sequence with Registered QEM at every weight (and plain QEM) and evaluate each one-sided.

    Args:
        frames: the original frames.
        registrations: one registration of original frame ``k-1`` onto frame ``k`` per pair (with ``verts``, e.g.
            :class:`~torchmeshmetric.registration.CachedRegistration`): used by the simplifier and the evaluation.
        target: faces to keep per frame.
        weights: weights (>= 0) of the registered previous frame.
        baseline: also evaluate plain QEM (fast-simplification).
        device: where distances are computed.
        ground_truth: the true motion (reported as the registration's error).
        progress: called with each weight when it is done.

    Returns:
        :class:`WeightSweep`.

    Example:
        >>> import trimesh
        >>> frames = [trimesh.creation.icosphere(subdivisions=2)] * 3
        >>> sweep = registered_qem_sweep(frames, [frames[0]] * 2, 0.5, [0.0, 1.0], baseline=False)
        >>> tuple(row["weight"] for row in sweep.rows())
        (0.0, 1.0)
    """
    baseline = check_flag(baseline, "baseline")
    if isinstance(weights, (str, bytes)) or not isinstance(weights, Sequence):  # "1" ran over its characters
        raise TypeError(f"weights: expected a sequence of numbers, found {type(weights).__name__} {weights!r}")
    if not weights:
        raise ValueError("weights: expected at least one weight, found none")
    for i, w in enumerate(weights):  # all checked before the first weight's simplification, named as this argument
        if isinstance(w, bool) or not isinstance(w, numbers.Real) or not (0 <= w < math.inf):
            raise ValueError(f"weights[{i}]: expected a finite number >= 0, found {w!r}")
    regs = [r if hasattr(r, "verts") else as_mesh(r) for r in registrations]
    results = []

    def evaluate(simplified: list[Any]) -> SequenceEvaluation:
        return evaluate_sequence(
            frames,
            simplified,
            precomputed_registrations=regs,
            two_sided=False,
            device=device,
            ground_truth=ground_truth,
        )

    for weight in weights:
        results.append(evaluate(simplify_sequence(frames, target, registrations=regs, weight=float(weight))))
        if progress is not None:
            progress(float(weight))
    base = evaluate(simplify_sequence(frames, target)) if baseline else None
    return WeightSweep([float(w) for w in weights], results, base)


def pareto_front(points: Mapping[float, tuple[float, float]]) -> list[float]:
    """Keys of the points not dominated in both coordinates (lower is better), sorted by the first coordinate."""
    keys = sorted(points, key=lambda w: points[w])
    front, best = [], float("inf")
    for w in keys:
        if points[w][1] < best:
            front.append(w)
            best = points[w][1]
    return front
