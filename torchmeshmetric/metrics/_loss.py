"""What the distance losses share: argument checks, the reduction, and the ``nn.Module`` that calls a loss."""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping
from typing import Any

import torch
from torch import Tensor, nn

from torchmeshmetric._checks import EmptyInputError, as_real, check_flag, check_int
from torchmeshmetric.kernels.select import check_backend
from torchmeshmetric.metrics.directed_distances import DirectedDistances

REDUCTIONS = ("mean", "sum", "none")


def check_loss_args(reduction: str, power: float) -> float:
    """Validate ``reduction`` and ``power`` (constructor and functional arguments); return ``power`` as a number.

    ``power`` is any number (:func:`~torchmeshmetric._checks.as_real`: numpy scalars, one-element tensors), returned
    as a Python ``int`` when it is an integer (``d ** 2`` as before) and a ``float`` otherwise.
    """
    if reduction not in REDUCTIONS:
        raise ValueError(f"reduction: expected one of {REDUCTIONS}, found {reduction!r}")
    value = as_real(power, "power")
    if value is None or not 0 < value < math.inf:
        # inf would make every distance below 1 count 0 and every other one inf; NaN fails both comparisons
        raise ValueError(
            f"power: expected a finite positive number (1: distance, 2: squared distance), found {power!r}"
        )
    return int(value) if isinstance(power, numbers.Integral) else value


def check_options(options: Mapping[str, Any], allowed: type, owner: str) -> None:
    """Refuse keyword options that are not keys of the ``TypedDict`` ``allowed`` (checked at construction)."""
    unknown = sorted(set(options) - set(allowed.__annotations__))
    if unknown:
        raise TypeError(f"{owner}: unexpected option(s) {unknown}, expected some of {sorted(allowed.__annotations__)}")
    for key, value in options.items():  # detach_reference="False" cut the gradient to the reference, in silence
        hint = allowed.__annotations__[key]  # a ForwardRef (postponed annotations), a string, or the type
        kind = getattr(hint, "__forward_arg__", getattr(hint, "__name__", hint))
        if kind == "bool":
            check_flag(value, key)
        elif kind == "int":
            check_int(value, key)
        elif key == "backend":  # checked here, not at the first step (found by review)
            check_backend(value)


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


class DistanceLossModule(nn.Module):
    """``nn.Module`` form of a distance loss function: ``forward`` calls it with the options given at construction.

    Args:
        loss: the loss function, ``loss(simplified, reference, *, power, reduction, **options)``.
        power: exponent of each distance.
        reduction: ``"mean"``, ``"sum"`` or ``"none"``.
        options: the loss function's other keyword arguments.
    """

    def __init__(self, loss: Callable[..., Tensor], power: float, reduction: str, options: Mapping[str, Any]) -> None:
        super().__init__()
        self._loss = loss
        self.power = check_loss_args(reduction, power)
        self.reduction = reduction
        self.options = dict(options)

    def forward(self, simplified: Any, reference: Any) -> Tensor:
        """The loss of ``simplified`` against ``reference`` (see the loss function)."""
        return self._loss(simplified, reference, power=self.power, reduction=self.reduction, **self.options)

    def extra_repr(self) -> str:
        """The loss's arguments (shown in ``repr``)."""
        shown = {"power": self.power, "reduction": self.reduction} | {
            k: v for k, v in self.options.items() if k != "indexes"
        }
        return ", ".join(f"{k}={v!r}" for k, v in shown.items())
