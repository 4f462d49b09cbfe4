"""Loss reductions shared by the distance losses."""

from __future__ import annotations

import torch
from torch import Tensor

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
    ``none.sum() == sum``.
    """
    terms = [r.forward] if r.reverse is None else [r.forward, r.reverse]
    powered = [t if power == 1 else t**power for t in terms]
    if reduction == "none":
        return torch.cat(powered)
    if reduction == "sum":
        return sum((t.sum() for t in powered), start=powered[0].new_zeros(()))
    return sum((t.mean() for t in powered), start=powered[0].new_zeros(()))
