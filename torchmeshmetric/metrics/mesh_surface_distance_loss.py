"""Mesh surface distance (paper Eq. 4) as a differentiable loss: function and ``nn.Module``."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from torch import Tensor

from torchmeshmetric.kernels.index_cache import IndexCache
from torchmeshmetric.metrics._inputs import check_surface_samples
from torchmeshmetric.metrics._loss import DistanceLossModule, check_loss_args, check_options, reduce_directed
from torchmeshmetric.metrics.surface_distance_sets import SurfaceDistanceOptions, mesh_surface_distance_sets

if TYPE_CHECKING:  # typing.Unpack needs Python 3.11; annotations are not evaluated at run time
    from typing_extensions import Unpack

__all__ = ["MeshSurfaceDistanceLoss", "mesh_surface_distance_loss"]


def mesh_surface_distance_loss(
    simplified: Any,
    reference: Any,
    *,
    power: float = 1.0,
    reduction: str = "mean",
    **options: Unpack[SurfaceDistanceOptions],
) -> Tensor:
    r"""Loss on the mesh surface distances ``d`` of :func:`~torchmeshmetric.metrics.mesh_surface_distance_sets`.

    .. math::

        L_{\text{mean}} = \frac{1}{P} \sum_{i} d_i^{\,p} \; \Big(+ \frac{1}{R} \sum_j \tilde d_j^{\,p}
        \text{ when two-sided}\Big)

    over all ``P`` simplified points of the batch (pooled) and, two-sided, all ``R`` reference vertices to the
    simplified surface. ``power=2`` gives the MSE of the paper's statistics; ``power=1`` their Average.
    Differentiable w.r.t. the simplified vertices (and the reference's when ``detach_reference=False``); the
    gradient is finite (zero) for points lying exactly on the surface.

    Args:
        simplified: mesh-like, ``(P, 3)`` points, or a list (ragged batch); see :func:`mesh_surface_distance_sets`.
        reference: reference mesh-like or list.
        power: exponent ``p`` applied to each distance (> 0).
        reduction: ``"mean"`` (pooled mean per direction, directions added), ``"sum"`` or ``"none"`` (packed
            per-point terms, forward then reverse; ``none.sum() == sum``).
        options: the options of :func:`mesh_surface_distance_sets` (:class:`SurfaceDistanceOptions`):
            ``two_sided`` (add the reverse direction, reference vertices → simplified surface), ``detach_reference``
            (cut the gradient to the reference vertices, default ``True``), ``surface_samples`` (``None``: exact
            surface; or the paper's sampled-surface mode with ``N`` samples), ``seed``, ``backend``, ``indexes``
            (an :class:`~torchmeshmetric.IndexCache` for the references, which also keeps the simplified meshes'
            index of a two-sided loss, refitted from call to call while their faces stay the same;
            :class:`MeshSurfaceDistanceLoss` keeps one).

    Returns:
        A 0-dim loss, or ``(P [+ R],)`` per-point terms for ``reduction="none"``, in the promoted dtype of the
        inputs (float64 if either is; each input's gradient in its own dtype: ``docs/concepts.md``, *Precision*).

    Raises:
        EmptyInputError: ``reduction="mean"`` on a batch without any point (``"sum"`` gives 0, ``"none"`` an
            empty tensor).
        TypeError: an option that :func:`mesh_surface_distance_sets` does not take.

    Example:
        >>> import torch, trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> x = torch.tensor([[0.0, 0.0, 3.0]], requires_grad=True)
        >>> loss = mesh_surface_distance_loss(x, sphere, power=2)
        >>> loss.backward()
        >>> round(loss.item(), 4), [round(g, 4) for g in x.grad[0].tolist()]
        (4.0, [0.0, 0.0, 4.0])
    """
    power = check_loss_args(reduction, power)
    check_options(options, SurfaceDistanceOptions, "mesh_surface_distance_loss")
    return reduce_directed(mesh_surface_distance_sets(simplified, reference, **options), power, reduction)


class MeshSurfaceDistanceLoss(DistanceLossModule):
    """``nn.Module`` form of :func:`mesh_surface_distance_loss` (same arguments, checked at construction).

    Keeps an :class:`~torchmeshmetric.IndexCache` of the reference meshes (unless ``indexes`` is given): training or
    validating every epoch on the same references builds each reference's index once (found again by content, any
    tensor object). Two-sided, the cache also keeps the index of the simplified meshes (the reverse direction is
    measured to them): a training step moves their vertices, so it is refitted while their faces stay the same
    (compared with a copy of the last call's) and rebuilt when they change; the values and gradients are those of a
    new index, bit for bit. Nothing else is kept between steps (no graph); the module pickles as before (its caches
    empty) and has no state in ``state_dict``.

    Example:
        >>> import torch, trimesh
        >>> loss_fn = MeshSurfaceDistanceLoss(power=2)
        >>> round(loss_fn(torch.tensor([[0.0, 0.0, 3.0]]), trimesh.creation.icosphere(subdivisions=2)).item(), 4)
        4.0
    """

    def __init__(
        self, *, power: float = 1.0, reduction: str = "mean", **options: Unpack[SurfaceDistanceOptions]
    ) -> None:
        check_options(options, SurfaceDistanceOptions, type(self).__name__)
        check_surface_samples(options.get("surface_samples"))
        super().__init__(mesh_surface_distance_loss, power, reduction, {"indexes": IndexCache(), **options})
