"""Loss reductions shared by the distance losses."""

from __future__ import annotations

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError
from torchmeshmetric.metrics.directed_distances import DirectedDistances

REDUCTIONS = ("mean", "sum", "none")


def check_loss_args(reduction: str, power: float) -> None:
    """Validate ``reduction`` and ``power`` (constructor and functional arguments)."""
    if reduction not in REDUCTIONS:
        raise ValueError(f"reduction: expected one of {REDUCTIONS}, found {reduction!r}")
    if not isinstance(power, (int, float)) or not power > 0:
        raise ValueError(f"power: expected a positive number (1: distance, 2: squared distance), found {power!r}")


def reduce_directed(r: DirectedDistances, power: float, reduction: str) -> Tensor:
    """``d ** power`` reduced over all points of the batch; two-sided: the two directions' reductions added.

    ``"none"`` returns the per-point terms, packed: forward points first, then (two-sided) reverse points, so that
    ``none.sum() == sum``. On an empty point set ``"sum"`` is 0 and ``"none"`` empty; ``"mean"`` raises, as the
    metrics do: the mean of no distance is undefined, and a NaN loss would poison the training silently.

    Raises:
        EmptyInputError: ``reduction="mean"`` and a direction has no point in the whole batch.
    """
    if reduction == "mean":
        for direction, t in (("simplified", r.forward), ("reference", r.reverse)):
            if t is not None and t.numel() == 0:
                raise EmptyInputError(
                    f"{direction}: the batch holds no point, and the mean of no distance is undefined "
                    "(reduction='sum' gives 0 for an empty batch)"
                )
    terms = [r.forward] if r.reverse is None else [r.forward, r.reverse]
    powered = [t if power == 1 else t**power for t in terms]
    if reduction == "none":
        return torch.cat(powered)
    if reduction == "sum":
        return sum((t.sum() for t in powered), start=powered[0].new_zeros(()))
    return sum((t.mean() for t in powered), start=powered[0].new_zeros(()))
