"""Nearest vertex distance (paper Eq. 5, cloud-to-cloud) as a function and a ``torchmetrics.Metric``."""

from __future__ import annotations

from typing import Any, TypedDict

import torch
from torch import Tensor

from torchmeshmetric._deprecation import deprecated_names
from torchmeshmetric.kernels.nearest import nearest_vertex_distance
from torchmeshmetric.metrics._inputs import as_point_sources
from torchmeshmetric.metrics.directed_distances import DirectedDistances, lengths_of
from torchmeshmetric.metrics.distance_states import DistanceStates
from torchmeshmetric.metrics.distance_statistics_metric import MeasuredDistanceBase

__all__ = ["NearestVertexDistance", "NearestVertexOptions", "nearest_vertex_distance_sets"]


class NearestVertexOptions(TypedDict, total=False):
    """The keyword options of :func:`nearest_vertex_distance_sets`, which its loss function and module take too.

    The defaults and meanings are those of :func:`nearest_vertex_distance_sets`.
    """

    two_sided: bool
    detach_reference: bool
    backend: str


def _cloud_to_cloud(points: list[Tensor], refs: list[Tensor], backend: str) -> Tensor:
    p, r = torch.cat(points), torch.cat(refs)
    if p.shape[0] == 0:  # an empty update: nothing to measure
        return p.new_zeros(0)
    dtype = torch.promote_types(p.dtype, r.dtype)
    return nearest_vertex_distance(
        p.to(dtype), r.to(dtype), points_lengths=lengths_of(points), ref_lengths=lengths_of(refs), backend=backend
    ).dists


def _bbox_diagonal(p: Tensor) -> Tensor:
    q = p.detach().to(torch.float64)
    return (q.amax(0) - q.amin(0)).to(torch.float64).norm().to(q.dtype) if q.shape[0] else q.new_zeros(())


def nearest_vertex_distance_sets(
    simplified: Any,
    reference: Any,
    *,
    two_sided: bool = False,
    detach_reference: bool = True,
    backend: str = "auto",
) -> DirectedDistances:
    """The nearest vertex distance sets (forward, and reverse when two-sided) of a simplified mesh to a reference.

    Works on one item or a ragged batch; the per-point distances come back packed, one set per direction.

    Forward (paper Eq. 5): from every simplified vertex (those referenced by a face, paper Eq. 3) or given point,
    the distance to the nearest reference vertex. Reverse (``two_sided=True``): from every reference vertex to
    the nearest simplified vertex.

    Args:
        simplified: a mesh-like, a ``(P, 3)`` point set, or a list of them (ragged batch).
        reference: a mesh-like (its vertex set is used) or a ``(R, 3)`` point set, or a list, one per item.
        two_sided: also measure reference → simplified.
        detach_reference: cut the gradient to the reference points (default).
        backend: kernel backend.

    Returns:
        :class:`~torchmeshmetric.metrics.DirectedDistances` (``peak``: bounding-box diagonal of each reference
        vertex set).

    Example:
        >>> import torch
        >>> r = nearest_vertex_distance_sets(torch.tensor([[0.0, 0, 0]]), torch.tensor([[3.0, 4, 0], [0, 0, 6]]))
        >>> r.forward.tolist()
        [5.0]
    """
    sources = as_point_sources(simplified, "simplified")
    ref_sources = as_point_sources(reference, "reference")
    if len(ref_sources) != len(sources):
        raise ValueError(
            f"reference: expected {len(sources)} reference(s), one per simplified item, found {len(ref_sources)}"
        )
    points = [s.points for s in sources]
    refs = [s.points.detach() if detach_reference else s.points for s in ref_sources]
    forward = _cloud_to_cloud(points, refs, backend)
    reverse = reverse_lengths = None
    if two_sided:
        reverse = _cloud_to_cloud(refs, points, backend)
        reverse_lengths = lengths_of(refs)
    peak = torch.stack([_bbox_diagonal(r) for r in refs])
    return DirectedDistances(forward, lengths_of(points), reverse, reverse_lengths, peak)


class NearestVertexDistance(MeasuredDistanceBase):
    """Statistics of the nearest vertex distance (paper Eq. 5), accumulated over batches and processes.

    ``update(simplified, reference)`` measures every simplified vertex against the nearest reference vertex (see
    :func:`nearest_vertex_distance_sets`); ``compute()`` returns the same dict of 0-dim float64 tensors as
    :class:`~torchmeshmetric.metrics.MeshSurfaceDistance` (``reverse_*`` and ``symmetric_*``/``hausdorff`` with
    ``two_sided=True``). The default PSNR peak is the largest reference bounding-box diagonal seen.

    Args:
        two_sided: also measure reference → simplified.
        backend: kernel backend.
        peak, ddof, exact_quantiles, relative_accuracy, kwargs: see
            :class:`~torchmeshmetric.metrics.distance_statistics_metric.DistanceStatisticsBase`.

    Example:
        >>> import torch
        >>> metric = NearestVertexDistance(two_sided=True)
        >>> metric.update(torch.tensor([[0.0, 0, 0]]), torch.tensor([[3.0, 4, 0], [0, 0, 6]]))
        >>> out = metric.compute()
        >>> out["ave"].item(), out["reverse_ave"].item(), out["hausdorff"].item()
        (5.0, 5.5, 6.0)
    """

    _forward_states = DistanceStates("vertex_moments", "vertex_values", "vertex_sketch")
    _reverse_states = DistanceStates("reverse_vertex_moments", "reverse_vertex_values", "reverse_vertex_sketch")

    _distance_sets = staticmethod(nearest_vertex_distance_sets)

    def __init__(self, *, backend: str = "auto", **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.backend = backend
        self._options = {"backend": backend}


__getattr__ = deprecated_names(
    __name__,
    {
        "nearest_vertex_distances": (
            "torchmeshmetric.metrics.nearest_vertex_distance_sets",
            nearest_vertex_distance_sets,
        )
    },
)
