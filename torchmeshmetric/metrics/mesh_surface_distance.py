"""Mesh surface distance (paper Eq. 4, cloud-to-mesh) as a ``torchmetrics.Metric``.

The function it accumulates, :func:`mesh_surface_distance_sets`, lives in ``surface_distance_sets.py``.
"""

from __future__ import annotations

from typing import Any

from torchmeshmetric._checks import check_seed
from torchmeshmetric.kernels.select import check_backend
from torchmeshmetric.metrics._inputs import check_surface_samples
from torchmeshmetric.metrics.distance_states import DistanceStates
from torchmeshmetric.metrics.distance_statistics_metric import MeasuredDistanceBase

# The function and its options live in surface_distance_sets.py, which imports no torchmetrics (so that a loss or
# the evaluation system does not load it); re-exported here, where they were first defined.
from torchmeshmetric.metrics.surface_distance_sets import SurfaceDistanceOptions, mesh_surface_distance_sets

__all__ = ["MeshSurfaceDistance", "SurfaceDistanceOptions", "mesh_surface_distance_sets"]


class MeshSurfaceDistance(MeasuredDistanceBase):
    """Statistics of the mesh surface distance (paper Eq. 4), accumulated over batches and processes.

    ``update(simplified, reference)`` measures every simplified vertex against the reference surface (see
    :func:`mesh_surface_distance_sets`) and accumulates the distances of all items of all batches into one pool;
    ``compute()`` returns a dict of 0-dim float64 tensors: ``ave, var, std, mse, rmse, max, min, median, p95, p99,
    count, psnr`` for the forward (paper) direction; with ``two_sided=True`` also ``reverse_*`` for reference →
    simplified, and the symmetric combinations ``symmetric_ave`` (mean of both directions' ``ave``, the
    Chamfer distance), ``hausdorff`` (max of both ``max``), ``symmetric_mse`` (max of both ``mse``, the MPEG
    convention), ``symmetric_rmse`` and ``symmetric_psnr``. The PSNR peak is ``peak`` if given, else the largest
    reference bounding-box diagonal seen. See :class:`~torchmeshmetric.metrics.DistanceStatisticsBase` for states and
    DDP exactness.

    Args:
        two_sided: also measure reference → simplified (needs simplified meshes, not bare points).
        surface_samples: ``None`` (exact, default) or the paper's sampled-surface mode with ``N`` samples.
        seed: seed of the surface sampling: each mesh is sampled by its own generator seeded with it, so a pair's
            samples do not depend on its batch, its position in it or the DDP split.
        backend: kernel backend.
        peak, ddof, exact_quantiles, relative_accuracy, kwargs: see
            :class:`~torchmeshmetric.metrics.DistanceStatisticsBase`.

    Example:
        >>> import torch, trimesh
        >>> metric = MeshSurfaceDistance()
        >>> metric.update(torch.tensor([[0.0, 0.0, 2.0], [0.0, 3.0, 0.0]]), trimesh.creation.icosphere(subdivisions=2))
        >>> out = metric.compute()
        >>> round(out["ave"].item(), 4), round(out["mse"].item(), 4)
        (1.5, 2.5)
    """

    _forward_states = DistanceStates("surface_moments", "surface_values", "surface_sketch")
    _reverse_states = DistanceStates("reverse_surface_moments", "reverse_surface_values", "reverse_surface_sketch")

    _distance_sets = staticmethod(mesh_surface_distance_sets)

    def __init__(
        self, *, surface_samples: int | None = None, seed: int = 0, backend: str = "auto", **kwargs: Any
    ) -> None:
        check_surface_samples(surface_samples)
        super().__init__(**kwargs)
        self.surface_samples = surface_samples
        self.seed = check_seed(seed)
        self.backend = check_backend(backend)  # at construction, not at the first validation step
        self._options = {"surface_samples": surface_samples, "seed": self.seed, "backend": backend}

    def _setting_items(self) -> dict[str, object]:
        """The base's, and the sampling: exact distances, or ``surface_samples`` samples drawn with ``seed``."""
        sampling: dict[str, object] = {"surface_samples": self.surface_samples}
        if self.surface_samples is not None:  # the exact distances read no seed
            sampling["seed"] = self.seed
        return {**super()._setting_items(), **sampling}
