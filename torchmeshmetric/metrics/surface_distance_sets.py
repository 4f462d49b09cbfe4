"""Mesh surface distance sets (paper Eq. 4, cloud-to-mesh) as a function; the ``torchmetrics.Metric`` is beside.

:class:`~torchmeshmetric.metrics.MeshSurfaceDistance` (``mesh_surface_distance.py``) accumulates their statistics;
this module imports no torchmetrics, so losses and the evaluation system load without it.
"""

from __future__ import annotations

from typing import Any, TypedDict

import torch
from torch import Tensor

from torchmeshmetric._checks import check_flag, check_seed, common_dtype
from torchmeshmetric.kernels.danskin import mesh_surface_distances
from torchmeshmetric.kernels.index_cache import IndexCache
from torchmeshmetric.kernels.kept_index import KeptIndex
from torchmeshmetric.kernels.mesh_index import MeshIndex
from torchmeshmetric.kernels.nearest import nearest_vertex_distance
from torchmeshmetric.kernels.point_triangle import point_mesh_distance
from torchmeshmetric.kernels.sampling import sample_surface, vertex_set
from torchmeshmetric.metrics._inputs import (
    as_point_sources,
    as_reference_meshes,
    cast_sources,
    check_surface_samples,
    require_meshes,
)
from torchmeshmetric.metrics._prebuilt_index import bound_to, check_index, check_index_cache, index_of, query_points
from torchmeshmetric.metrics.directed_distances import DirectedDistances, lengths_of, packed
from torchmeshmetric.structures import Mesh

__all__ = ["SurfaceDistanceOptions", "measure_surface_distance_sets", "mesh_surface_distance_sets"]


class SurfaceDistanceOptions(TypedDict, total=False):
    """The keyword options of :func:`mesh_surface_distance_sets`, which its loss function and module take too.

    The defaults and meanings are those of :func:`mesh_surface_distance_sets`.

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric import mesh_surface_distance_loss
        >>> options: SurfaceDistanceOptions = {"surface_samples": 1000, "seed": 0}
        >>> loss = mesh_surface_distance_loss(torch.tensor([[0.0, 0.0, 3.0]]), trimesh.creation.icosphere(), **options)
        >>> 1.9 < loss.item() < 2.1  # about 2 (the sampled surface stands for the sphere of radius 1)
        True
    """

    two_sided: bool
    surface_samples: int | None
    seed: int
    detach_reference: bool
    backend: str
    indexes: IndexCache | None
    reference_index: MeshIndex | None
    simplified_index: MeshIndex | None


def _to_surface(
    points: list[Tensor],
    meshes: list[Mesh],
    surface_samples: int | None,
    seed: int,
    backend: str,
    index: MeshIndex | None = None,
    indexes: IndexCache | None = None,
    index_name: str = "reference_index",
    kept: KeptIndex | None = None,
) -> Tensor:
    """Packed distances from each item's points to its mesh surface (exact, or to N area-sampled points).

    The exact distances are queried on ``index`` (the index of ``meshes``) when given, else on the index
    ``indexes`` holds for ``meshes``, else (differentiable) on the index ``kept`` holds or a one-off one, else
    computed by :func:`~torchmeshmetric.point_mesh_distance`.
    """
    p = packed(points)
    dtype = common_dtype(p.dtype, *(m.dtype for m in meshes))  # the dtype rule: both directions, every index
    if p.shape[0] == 0:  # an empty update: nothing to measure
        return p.new_zeros(0, dtype=dtype)
    if surface_samples is None:
        # A loss differentiates every surface distance by Danskin's theorem, on an index (one built for this call
        # when none is given or cached).
        differentiable = torch.is_grad_enabled() and (p.requires_grad or any(m.verts.requires_grad for m in meshes))
        index = index_of(meshes, index, indexes, dtype, backend, index_name, build=differentiable, kept=kept)
        if index is None:
            return point_mesh_distance(p, meshes, points_lengths=lengths_of(points), backend=backend).dists
        q = query_points(index, p, index_name)
        return mesh_surface_distances(q, lengths_of(points), meshes, index, owner="mesh_surface_distance_loss")
    # Each mesh's samples from its own generator seeded by `seed`: one stream for the whole batch gave a mesh other
    # samples (its distances up to 0.19 apart) by the items before it, so the figures depended on the batch size,
    # the shuffling and DDP's split (found by review). A mesh alone is sampled as before (a batch's first item was).
    samples = [
        sample_surface(m, n=surface_samples, generator=torch.Generator(device=m.device).manual_seed(seed)).points
        for m in meshes
    ]
    return nearest_vertex_distance(
        p.to(dtype),
        packed(samples).to(dtype),
        points_lengths=lengths_of(points),
        ref_lengths=lengths_of(samples),
        backend=backend,
    ).dists


def measure_surface_distance_sets(
    points: list[Tensor],
    references: list[Mesh],
    reference_points: list[Tensor] | None,
    simplified_meshes: list[Mesh] | None,
    reference_index: MeshIndex | None,
    simplified_index: MeshIndex | None,
    backend: str,
    surface_samples: int | None = None,
    seed: int = 0,
    indexes: IndexCache | None = None,
) -> tuple[Tensor, Tensor | None]:
    """The packed ``(forward, reverse)`` sets of :func:`mesh_surface_distance_sets` (trusted: nothing re-checked).

    ``points``: each item's query points (its vertex set); ``reference_points``: each reference's vertex set, and
    ``simplified_meshes``: the items' meshes, both ``None`` for one-sided sets; the indexes (``None``: none at
    hand), if given, are those of ``references`` and ``simplified_meshes``.
    """
    forward = _to_surface(points, references, surface_samples, seed, backend, reference_index, indexes)
    if reference_points is None or simplified_meshes is None:
        return forward, None
    # The simplified meshes are not looked up in `indexes`: they change from call to call in the loops the cache
    # serves, and would push the references out of it. A loss (differentiable) measures them on the index the cache
    # keeps apart for them, refitted while their faces stay the same (a rebuild was ~45 % of a training step).
    reverse = _to_surface(
        reference_points,
        simplified_meshes,
        surface_samples,
        seed,
        backend,
        simplified_index,
        None,
        "simplified_index",
        indexes.moving if indexes is not None else None,
    )
    return forward, reverse


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
    reference_index: MeshIndex | None = None,
    simplified_index: MeshIndex | None = None,
) -> DirectedDistances:
    """The mesh surface distance sets (forward, and reverse when two-sided) of a simplified mesh to a reference mesh.

    Works on one item or a ragged batch; the per-point distances come back packed, one set per direction.

    Forward (paper Eq. 4): from every vertex of the simplified mesh (the vertices referenced by a face, paper
    Eq. 3) or every given point, the distance to the reference surface, exact by default. With
    ``surface_samples=N`` the reference surface is replaced, as in the paper, by ``N`` area-uniform samples
    (seeded by ``seed``, identical on every call), and the distance is to the nearest sample (an over-estimate of
    the exact distance). Reverse (``two_sided=True``, catches holes and dropped parts): from every vertex of the
    reference to the simplified surface (or its ``N`` samples); needs the simplified item to be a mesh.

    The exact distances are queried on a :class:`~torchmeshmetric.MeshIndex` of the measured-to mesh when one is
    at hand: ``reference_index`` (forward; else the one ``indexes`` holds for the references) and
    ``simplified_index`` (reverse). Build each once to measure a mesh many times, or to share it with
    :func:`~torchmeshmetric.metrics.nearest_vertex_distance_sets`; the distances are those computed without an
    index, bit for bit, whatever its ``tree``.

    Args:
        simplified: a mesh-like (``Mesh``, ``(verts, faces)``, ``trimesh.Trimesh``), a ``(P, 3)`` point set, or a
            list of them (ragged batch).
        reference: a mesh-like or a list of them, one per simplified item.
        two_sided: also measure reference → simplified.
        surface_samples: ``None`` (exact surface) or the number of surface samples per mesh.
        seed: seed of the surface sampling (each mesh by its own generator seeded with it: its samples do not
            depend on the batch).
        detach_reference: cut the gradient to the reference vertices (default); ``False`` lets it flow.
        backend: kernel backend (``"auto"``, ``"bruteforce"``, ...) of the distances computed without an index.
        indexes: an :class:`~torchmeshmetric.IndexCache`: the references' indexes are found again by content
            (a validation or training loop over the same references builds each once); a differentiable two-sided
            call also measures the reverse set on the simplified meshes' index the cache keeps (``moving``),
            refitted while their faces stay the same.
        reference_index: the :class:`~torchmeshmetric.MeshIndex` of ``reference`` (the ``B`` items in order, their
            ``(V_b, 3)`` vertices packed), used instead of ``indexes``. Its content is not compared with
            ``reference``: it must be built from the same meshes (or equal vertices and faces). Gradients
            flow as without an index: to the vertices of ``reference`` and ``simplified``, not to the tensors an
            index was built from.
        simplified_index: the :class:`~torchmeshmetric.MeshIndex` of the simplified meshes, for the reverse set.

    Returns:
        :class:`~torchmeshmetric.metrics.DirectedDistances` in the promoted dtype of the inputs and of any index
        given (``docs/concepts.md``, *Precision*); ``forward`` is differentiable w.r.t. the simplified
        vertices (and the reference when not detached).

    Raises:
        ShapeError, DeviceError: an index whose vertex counts or device do not fit its meshes.
        DTypeError: an index narrower than the promoted dtype of the inputs (it would round them).
        ValueError: an index with ``surface_samples`` (the sampled mode measures to samples, not to a surface).

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric import MeshIndex
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> r = mesh_surface_distance_sets(torch.tensor([[0.0, 0.0, 2.0], [0.0, 3.0, 0.0]]), sphere)
        >>> [round(x, 5) for x in r.forward.tolist()]
        [1.0, 2.0]
        >>> coarse = trimesh.creation.icosphere(subdivisions=1)
        >>> fine_index, coarse_index = MeshIndex(sphere), MeshIndex(coarse)  # float64, like the trimeshes
        >>> r = mesh_surface_distance_sets(
        ...     coarse, sphere, two_sided=True, reference_index=fine_index, simplified_index=coarse_index
        ... )
        >>> r.forward.shape, r.reverse.shape, round(float(r.reverse.max()), 3)
        (torch.Size([42]), torch.Size([162]), 0.049)
    """
    check_surface_samples(surface_samples)
    check_flag(two_sided, "two_sided")
    check_flag(detach_reference, "detach_reference")
    check_seed(seed)
    check_index_cache(indexes)
    if surface_samples is not None and (reference_index is not None or simplified_index is not None):
        raise ValueError("reference_index, simplified_index: only with surface_samples=None (the exact surface)")
    sources = as_point_sources(simplified, "simplified")
    refs = as_reference_meshes(reference, len(sources), "reference")
    check_index(reference_index, refs, "reference_index")
    check_index(simplified_index, [s.mesh for s in sources], "simplified_index")
    # The dtype rule, at the door: everything in the promoted dtype of the inputs (a given index stands for its
    # mesh); a prebuilt index narrower than that is refused where it is used (index_of).
    given = [i.dtype for i in (reference_index, simplified_index) if i is not None]
    dtype = common_dtype(*(s.points.dtype for s in sources), *(m.dtype for m in refs), *given)
    sources, refs = cast_sources(sources, dtype), [m.to(dtype=dtype) for m in refs]
    simp_meshes = None
    if two_sided:
        simp_meshes = require_meshes(sources, "simplified", "two_sided=True measures reference → simplified surface")
    if detach_reference:
        refs = [m.detach() for m in refs]
    reference_index = bound_to(reference_index, refs)
    simplified_index = bound_to(simplified_index, [s.mesh for s in sources if s.mesh is not None])
    points = [s.points for s in sources]
    ref_points = [vertex_set(m) for m in refs] if two_sided else None
    forward, reverse = measure_surface_distance_sets(
        points,
        refs,
        ref_points,
        simp_meshes,
        reference_index,
        simplified_index,
        backend,
        surface_samples,
        seed,
        indexes,
    )
    peak = torch.stack([m.bbox_diagonal().detach().to(torch.float64) for m in refs])
    reverse_lengths = None if ref_points is None else lengths_of(ref_points)
    return DirectedDistances(forward, lengths_of(points), reverse, reverse_lengths, peak)
