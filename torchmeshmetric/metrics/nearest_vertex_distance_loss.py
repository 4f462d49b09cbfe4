"""Nearest vertex distance (paper Eq. 5) as a differentiable loss: function and ``nn.Module``."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from torch import Tensor

from torchmeshmetric.kernels.index_cache import IndexCache
from torchmeshmetric.metrics._loss import DistanceLossModule, check_loss_args, check_options, reduce_directed
from torchmeshmetric.metrics.vertex_distance_sets import NearestVertexOptions, nearest_vertex_distance_sets

if TYPE_CHECKING:  # typing.Unpack needs Python 3.11; annotations are not evaluated at run time
    from typing_extensions import Unpack

__all__ = ["NearestVertexDistanceLoss", "nearest_vertex_distance_loss"]


def nearest_vertex_distance_loss(
    simplified: Any,
    reference: Any,
    *,
    power: float = 1.0,
    reduction: str = "mean",
    **options: Unpack[NearestVertexOptions],
) -> Tensor:
    """Loss on the nearest vertex distances ``d`` of :func:`~torchmeshmetric.metrics.nearest_vertex_distance_sets`.

    ``mean``: pooled mean of ``d ** power`` over all simplified points (plus, two-sided, the pooled mean over all
    reference points: the Chamfer distance for ``power=2``); ``sum``; ``none``: packed per-point terms, forward then
    reverse. Differentiable w.r.t. the simplified points (and the reference when ``detach_reference=False``).

    Args:
        simplified: mesh-like, ``(P, 3)`` points, or a list (ragged batch).
        reference: mesh-like (its vertex set) or ``(R, 3)`` points, or a list.
        power: exponent applied to each distance (> 0).
        reduction: ``"mean"``, ``"sum"`` or ``"none"``.
        options: the options of :func:`nearest_vertex_distance_sets` (:class:`NearestVertexOptions`):
            ``two_sided`` (add the reverse direction, reference points → nearest simplified point),
            ``detach_reference`` (cut the gradient to the reference points, default ``True``), ``backend``.

    Returns:
        A 0-dim loss, or the per-point terms for ``reduction="none"``, in the promoted dtype of the inputs (float64
        if either is; each input's gradient in its own dtype: ``docs/concepts.md``, *Precision*).

    Raises:
        EmptyInputError: ``reduction="mean"`` on a batch without any point (``"sum"`` gives 0, ``"none"`` an
            empty tensor).
        TypeError: an option that :func:`nearest_vertex_distance_sets` does not take.

    Example:
        >>> import torch
        >>> x = torch.tensor([[0.0, 0, 0]], requires_grad=True)
        >>> loss = nearest_vertex_distance_loss(x, torch.tensor([[3.0, 4, 0]]))
        >>> loss.backward()
        >>> loss.item(), x.grad[0].tolist()
        (5.0, [-0.6000000238418579, -0.800000011920929, 0.0])
    """
    power = check_loss_args(reduction, power)
    check_options(options, NearestVertexOptions, "nearest_vertex_distance_loss")
    return reduce_directed(nearest_vertex_distance_sets(simplified, reference, **options), power, reduction)


class NearestVertexDistanceLoss(DistanceLossModule):
    """``nn.Module`` form of :func:`nearest_vertex_distance_loss` (same arguments, checked at construction).

    Keeps an :class:`~torchmeshmetric.IndexCache` of the reference meshes (unless ``indexes`` is given): training or
    validating every epoch on the same reference meshes builds each one's nearest-vertex index once (found again by
    content, any tensor object). References given as point sets are searched afresh at each call.

    Example:
        >>> import torch
        >>> NearestVertexDistanceLoss(power=2)(torch.tensor([[0.0, 0, 0]]), torch.tensor([[3.0, 4, 0]])).item()
        25.0
    """

    def __init__(self, *, power: float = 1.0, reduction: str = "mean", **options: Unpack[NearestVertexOptions]) -> None:
        check_options(options, NearestVertexOptions, type(self).__name__)
        super().__init__(nearest_vertex_distance_loss, power, reduction, {"indexes": IndexCache(), **options})
