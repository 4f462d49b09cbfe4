"""Nearest vertex distance (paper Eq. 5, cloud-to-cloud) as a ``torchmetrics.Metric``.

The function it accumulates, :func:`nearest_vertex_distance_sets`, lives in ``vertex_distance_sets.py``.
"""

from __future__ import annotations

from typing import Any

from torchmeshmetric.kernels.select import check_backend
from torchmeshmetric.metrics.distance_states import DistanceStates
from torchmeshmetric.metrics.distance_statistics_metric import MeasuredDistanceBase

# The function and its options live in vertex_distance_sets.py, which imports no torchmetrics (so that a loss or
# the evaluation system does not load it); re-exported here, where they were first defined.
from torchmeshmetric.metrics.vertex_distance_sets import NearestVertexOptions, nearest_vertex_distance_sets

__all__ = ["NearestVertexDistance", "NearestVertexOptions", "nearest_vertex_distance_sets"]


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
        self.backend = check_backend(backend)  # at construction, not at the first validation step
        self._options = {"backend": backend}
