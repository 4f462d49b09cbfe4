"""Nearest vertex distance (paper Eq. 5) as a differentiable loss: function and ``nn.Module``."""

from __future__ import annotations

from typing import Any

from torch import Tensor, nn

from torchmeshmetric.metrics._reduction import check_loss_args, reduce_directed
from torchmeshmetric.metrics.nearest_vertex_distance import nearest_vertex_distances

__all__ = ["NearestVertexDistanceLoss", "nearest_vertex_distance_loss"]


def nearest_vertex_distance_loss(
    simplified: Any,
    reference: Any,
    *,
    power: float = 1.0,
    reduction: str = "mean",
    two_sided: bool = False,
    detach_reference: bool = True,
    backend: str = "auto",
) -> Tensor:
    """Loss on the nearest vertex distances ``d`` of :func:`~torchmeshmetric.metrics.nearest_vertex_distances`.

    ``mean``: pooled mean of ``d ** power`` over all simplified points (plus, two-sided, the pooled mean over all
    reference points: the Chamfer distance for ``power=2``); ``sum``; ``none``: packed per-point terms, forward then
    reverse. Differentiable w.r.t. the simplified points (and the reference when ``detach_reference=False``).

    Args:
        simplified: mesh-like, ``(P, 3)`` points, or a list (ragged batch).
        reference: mesh-like (its vertex set) or ``(R, 3)`` points, or a list.
        power: exponent applied to each distance (> 0).
        reduction: ``"mean"``, ``"sum"`` or ``"none"``.
        two_sided: add the reverse direction (reference points → nearest simplified point).
        detach_reference: cut the gradient to the reference points (default ``True``).
        backend: kernel backend (``"auto"``, ``"bruteforce"``, ...).

    Returns:
        A 0-dim loss, or the per-point terms for ``reduction="none"``.

    Raises:
        EmptyInputError: ``reduction="mean"`` on a batch without any point (``"sum"`` gives 0, ``"none"`` an
            empty tensor).

    Example:
        >>> import torch
        >>> x = torch.tensor([[0.0, 0, 0]], requires_grad=True)
        >>> loss = nearest_vertex_distance_loss(x, torch.tensor([[3.0, 4, 0]]))
        >>> loss.backward()
        >>> loss.item(), x.grad[0].tolist()
        (5.0, [-0.6000000238418579, -0.800000011920929, 0.0])
    """
    check_loss_args(reduction, power)
    r = nearest_vertex_distances(
        simplified, reference, two_sided=two_sided, detach_reference=detach_reference, backend=backend
    )
    return reduce_directed(r, power, reduction)


class NearestVertexDistanceLoss(nn.Module):
    """``nn.Module`` form of :func:`nearest_vertex_distance_loss`.

    Example:
        >>> import torch
        >>> NearestVertexDistanceLoss(power=2)(torch.tensor([[0.0, 0, 0]]), torch.tensor([[3.0, 4, 0]])).item()
        25.0
    """

    def __init__(
        self,
        *,
        power: float = 1.0,
        reduction: str = "mean",
        two_sided: bool = False,
        detach_reference: bool = True,
        backend: str = "auto",
    ) -> None:
        super().__init__()
        check_loss_args(reduction, power)
        self.power = power
        self.reduction = reduction
        self.two_sided = two_sided
        self.detach_reference = detach_reference
        self.backend = backend

    def forward(self, simplified: Any, reference: Any) -> Tensor:
        """Loss of ``simplified`` against ``reference`` (see :func:`nearest_vertex_distance_loss`)."""
        return nearest_vertex_distance_loss(
            simplified,
            reference,
            power=self.power,
            reduction=self.reduction,
            two_sided=self.two_sided,
            detach_reference=self.detach_reference,
            backend=self.backend,
        )
