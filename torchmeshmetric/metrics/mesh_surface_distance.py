"""Mesh surface distance (paper Eq. 4, cloud-to-mesh) as a function and a ``torchmetrics.Metric``."""

from __future__ import annotations

from typing import Any, TypedDict

import torch
from torch import Tensor

from torchmeshmetric._deprecation import deprecated_names
from torchmeshmetric.kernels.index_cache import IndexCache
from torchmeshmetric.kernels.nearest import nearest_vertex_distance
from torchmeshmetric.kernels.point_triangle import point_mesh_distance
from torchmeshmetric.kernels.sampling import sample_surface, vertex_set
from torchmeshmetric.metrics._inputs import (
    as_point_sources,
    as_reference_meshes,
    check_surface_samples,
    require_meshes,
)
from torchmeshmetric.metrics.directed_distances import DirectedDistances, lengths_of
from torchmeshmetric.metrics.distance_states import DistanceStates
from torchmeshmetric.metrics.distance_statistics_metric import MeasuredDistanceBase
from torchmeshmetric.structures import Mesh

__all__ = ["MeshSurfaceDistance", "SurfaceDistanceOptions", "mesh_surface_distance_sets"]


class SurfaceDistanceOptions(TypedDict, total=False):
    """The keyword options of :func:`mesh_surface_distance_sets`, which its loss function and module take too.

    The defaults and meanings are those of :func:`mesh_surface_distance_sets`.
    """

    two_sided: bool
    surface_samples: int | None
    seed: int
    detach_reference: bool
    backend: str
    indexes: IndexCache | None


def _to_surface(
    points: list[Tensor],
    meshes: list[Mesh],
    surface_samples: int | None,
    seed: int,
    backend: str,
    indexes: IndexCache | None = None,
) -> Tensor:
    """Packed distances from each item's points to its mesh surface (exact, or to N area-sampled points)."""
    if sum(p.shape[0] for p in points) == 0:  # an empty update: nothing to measure
        return torch.cat(points).new_zeros(0)
    p = torch.cat(points)  # torch.cat promotes mixed float dtypes
    if surface_samples is None and indexes is not None:
        dtype = p.dtype
        for m in meshes:
            dtype = torch.promote_types(dtype, m.dtype)
        index = indexes.get([m.to(dtype=dtype) for m in meshes], backend=backend)
        return index.point_mesh_distance(p.to(dtype), points_lengths=lengths_of(points)).dists
    if surface_samples is None:
        return point_mesh_distance(p, meshes, points_lengths=lengths_of(points), backend=backend).dists
    gen = torch.Generator(device=meshes[0].device).manual_seed(seed)
    s = sample_surface(meshes, n=surface_samples, generator=gen)
    dtype = torch.promote_types(p.dtype, s.points.dtype)
    return nearest_vertex_distance(
        p.to(dtype), s.points.to(dtype), points_lengths=lengths_of(points), ref_lengths=s.lengths, backend=backend
    ).dists


def mesh_surface_distance_sets(
    simplified: Any,
    reference: Any,
    *,
    two_sided: bool = False,
    surface_samples: int | None = None,
    seed: int = 0,
    detach_reference: bool = True,
    backend: str = "auto",
    indexes: IndexCache | None = None,
) -> DirectedDistances:
    """The mesh surface distance sets (forward, and reverse when two-sided) of a simplified mesh to a reference mesh.

    Works on one item or a ragged batch; the per-point distances come back packed, one set per direction.

    Forward (paper Eq. 4): from every vertex of the simplified mesh (the vertices referenced by a face, paper
    Eq. 3) or every given point, the distance to the reference surface, exact by default. With
    ``surface_samples=N`` the reference surface is replaced, as in the paper, by ``N`` area-uniform samples
    (seeded by ``seed``, identical on every call), and the distance is to the nearest sample (an over-estimate of
    the exact distance). Reverse (``two_sided=True``, catches holes and dropped parts): from every vertex of the
    reference to the simplified surface (or its ``N`` samples); needs the simplified item to be a mesh.

    Args:
        simplified: a mesh-like (``Mesh``, ``(verts, faces)``, ``trimesh.Trimesh``), a ``(P, 3)`` point set, or a
            list of them (ragged batch).
        reference: a mesh-like or a list of them, one per simplified item.
        two_sided: also measure reference → simplified.
        surface_samples: ``None`` (exact surface) or the number of surface samples per mesh.
        seed: seed of the surface sampling.
        detach_reference: cut the gradient to the reference vertices (default); ``False`` lets it flow.
        backend: kernel backend (``"auto"``, ``"bruteforce"``, ...).
        indexes: an :class:`~torchmeshmetric.IndexCache`: the references' indexes are found again by content
            (a validation or training loop over the same references builds each once).

    Returns:
        :class:`~torchmeshmetric.metrics.DirectedDistances`; ``forward`` is differentiable w.r.t. the simplified
        vertices (and the reference when not detached).

    Example:
        >>> import torch, trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> r = mesh_surface_distance_sets(torch.tensor([[0.0, 0.0, 2.0], [0.0, 3.0, 0.0]]), sphere)
        >>> [round(x, 5) for x in r.forward.tolist()]
        [1.0, 2.0]
    """
    check_surface_samples(surface_samples)
    sources = as_point_sources(simplified, "simplified")
    refs = as_reference_meshes(reference, len(sources), "reference")
    if detach_reference:
        refs = [m.detach() for m in refs]
    points = [s.points for s in sources]
    forward = _to_surface(points, refs, surface_samples, seed, backend, indexes)
    reverse = reverse_lengths = None
    if two_sided:
        simp_meshes = require_meshes(sources, "simplified", "two_sided=True measures reference → simplified surface")
        ref_points = [vertex_set(m) for m in refs]
        reverse = _to_surface(ref_points, simp_meshes, surface_samples, seed, backend)
        reverse_lengths = lengths_of(ref_points)
    peak = torch.stack([m.bbox_diagonal().detach().to(torch.float64) for m in refs])
    return DirectedDistances(forward, lengths_of(points), reverse, reverse_lengths, peak)


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
        seed: seed of the surface sampling.
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
        self.seed = int(seed)
        self.backend = backend
        self._options = {"surface_samples": surface_samples, "seed": self.seed, "backend": backend}


__getattr__ = deprecated_names(
    __name__,
    {"mesh_surface_distances": ("torchmeshmetric.metrics.mesh_surface_distance_sets", mesh_surface_distance_sets)},
)
