"""Nearest vertex distance sets (paper Eq. 5, cloud-to-cloud) as a function; the ``torchmetrics.Metric`` is beside.

:class:`~torchmeshmetric.metrics.NearestVertexDistance` (``nearest_vertex_distance.py``) accumulates their
statistics; this module imports no torchmetrics, so losses and the evaluation system load without it.
"""

from __future__ import annotations

from typing import Any, TypedDict

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, check_flag, common_dtype
from torchmeshmetric.kernels.index_cache import IndexCache
from torchmeshmetric.kernels.mesh_index import MeshIndex
from torchmeshmetric.kernels.nearest import nearest_vertex_distance
from torchmeshmetric.metrics._inputs import PointSource, as_point_sources, cast_sources
from torchmeshmetric.metrics._prebuilt_index import bound_to, check_index, check_index_cache, index_of, query_points
from torchmeshmetric.metrics.directed_distances import DirectedDistances, lengths_of, packed
from torchmeshmetric.structures import Mesh, bbox_diagonal

__all__ = ["NearestVertexOptions", "measure_vertex_distance_sets", "nearest_vertex_distance_sets"]


class NearestVertexOptions(TypedDict, total=False):
    """The keyword options of :func:`nearest_vertex_distance_sets`, which its loss function and module take too.

    The defaults and meanings are those of :func:`nearest_vertex_distance_sets`.

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric import nearest_vertex_distance_loss
        >>> options: NearestVertexOptions = {"two_sided": True, "backend": "bruteforce"}
        >>> loss = nearest_vertex_distance_loss(torch.zeros(1, 3), trimesh.creation.icosphere(), **options)
        >>> round(loss.item(), 4)  # the centre to the unit sphere's vertices: 1 forward, plus 1 reverse
        2.0
    """

    two_sided: bool
    backend: str
    detach_reference: bool
    indexes: IndexCache | None
    reference_index: MeshIndex | None
    simplified_index: MeshIndex | None


def _cloud_to_cloud(
    points: list[Tensor],
    refs: list[Tensor],
    backend: str,
    index: MeshIndex | None = None,
    indexes: IndexCache | None = None,
    ref_meshes: list[Mesh] | None = None,
    index_name: str = "reference_index",
) -> Tensor:
    """Packed distances from each item's points to its nearest reference point.

    Queried on ``index`` (the index of the meshes whose vertex sets ``refs`` are) when given, else on the index
    ``indexes`` holds for ``ref_meshes`` (when the references are meshes), else computed by
    :func:`~torchmeshmetric.nearest_vertex_distance`.
    """
    p = packed(points)
    dtype = common_dtype(p.dtype, *(q.dtype for q in refs))  # the dtype rule: both directions, every index
    if p.shape[0] == 0:  # an empty update: nothing to measure
        return p.new_zeros(0, dtype=dtype)
    index = index_of(ref_meshes or [], index, indexes if ref_meshes is not None else None, dtype, backend, index_name)
    if index is not None:
        return index.nearest_vertex_distance_unchecked(query_points(index, p, index_name), lengths_of(points)).dists
    r = packed(refs)
    return nearest_vertex_distance(
        p.to(dtype), r.to(dtype), points_lengths=lengths_of(points), ref_lengths=lengths_of(refs), backend=backend
    ).dists


def _check_measurable(sources: list[PointSource], ref_sources: list[PointSource], two_sided: bool) -> None:
    """Refuse an empty set that points are measured to, named as the caller gave it.

    The kernel's own words named its argument (``ref_points: reference set 1 is empty but has 162 query points``)
    where the caller's ``simplified[1]`` was empty and ``two_sided=True`` measured the reference to it (found by
    review).
    """
    directions = [("reference", ref_sources, "simplified", sources, "")]
    if two_sided:
        why = "two_sided=True measures reference → simplified: "
        directions.append(("simplified", sources, "reference", ref_sources, why))
    for to_name, to_items, from_name, from_items, reason in directions:
        for i, (to, frm) in enumerate(zip(to_items, from_items, strict=True)):
            if to.points.shape[0] == 0 and frm.points.shape[0] > 0:
                item = "" if len(to_items) == 1 else f"[{i}]"
                raise EmptyInputError(
                    f"{to_name}{item}: expected at least one point ({reason}the {frm.points.shape[0]} points of "
                    f"{from_name}{item} have nothing to measure to), found none"
                )


def _bbox_diagonal(p: Tensor) -> Tensor:
    return bbox_diagonal(p.detach().to(torch.float64))


def measure_vertex_distance_sets(
    points: list[Tensor],
    refs: list[Tensor],
    two_sided: bool,
    reference_index: MeshIndex | None,
    simplified_index: MeshIndex | None,
    backend: str,
    ref_meshes: list[Mesh] | None = None,
    indexes: IndexCache | None = None,
) -> tuple[Tensor, Tensor | None]:
    """The packed ``(forward, reverse)`` sets of :func:`nearest_vertex_distance_sets` (trusted: nothing re-checked).

    ``points`` and ``refs``: each item's simplified and reference point sets; the indexes (``None``: none at
    hand), if given, are those of the meshes of ``refs`` and ``points``; ``ref_meshes``: the references' meshes
    (``None`` when some reference is a point set), looked up in ``indexes`` when ``reference_index`` is ``None``.
    """
    two_sided = check_flag(two_sided, "two_sided")
    forward = _cloud_to_cloud(points, refs, backend, reference_index, indexes, ref_meshes)
    if not two_sided:
        return forward, None
    # The simplified meshes are not looked up in `indexes`: they change from call to call in the loops the cache
    # serves, and would push the references out of it.
    return forward, _cloud_to_cloud(refs, points, backend, simplified_index, index_name="simplified_index")


def nearest_vertex_distance_sets(
    simplified: Any,
    reference: Any,
    *,
    two_sided: bool = False,
    backend: str = "auto",
    detach_reference: bool = True,
    indexes: IndexCache | None = None,
    reference_index: MeshIndex | None = None,
    simplified_index: MeshIndex | None = None,
) -> DirectedDistances:
    """The nearest vertex distance sets (forward, and reverse when two-sided) of a simplified mesh to a reference.

    Works on one item or a ragged batch; the per-point distances come back packed, one set per direction.

    Forward (paper Eq. 5): from every simplified vertex (those referenced by a face, paper Eq. 3) or given point,
    the distance to the nearest reference vertex. Reverse (``two_sided=True``): from every reference vertex to
    the nearest simplified vertex.

    The distances are queried on a :class:`~torchmeshmetric.MeshIndex` of the measured-to mesh when one is at
    hand: ``reference_index`` (forward; else the one ``indexes`` holds for the references, when they are meshes)
    and ``simplified_index`` (reverse). Build each once to measure a mesh many times, or to share it with
    :func:`~torchmeshmetric.metrics.mesh_surface_distance_sets`; the distances are those computed without an
    index, bit for bit.

    Args:
        simplified: a mesh-like, a ``(P, 3)`` point set, or a list of them (ragged batch).
        reference: a mesh-like (its vertex set is used) or a ``(R, 3)`` point set, or a list, one per item.
        two_sided: also measure reference → simplified.
        backend: kernel backend of the distances computed without an index.
        detach_reference: cut the gradient to the reference points (default); ``False`` lets it flow.
        indexes: an :class:`~torchmeshmetric.IndexCache`: the reference meshes' indexes are found again by content
            (the same entries as :func:`~torchmeshmetric.metrics.mesh_surface_distance_sets`').
        reference_index: the :class:`~torchmeshmetric.MeshIndex` of the reference meshes (the ``B`` items in order,
            their ``(V_b, 3)`` vertices packed), used instead of ``indexes``. Its content is not compared with
            ``reference``: it must be built from the same meshes (or equal vertices and faces). Gradients
            flow as without an index: to the vertices of ``reference`` and ``simplified``, not to the tensors an
            index was built from.
        simplified_index: the :class:`~torchmeshmetric.MeshIndex` of the simplified meshes, for the reverse set.

    Returns:
        :class:`~torchmeshmetric.metrics.DirectedDistances` in the promoted dtype of the inputs and of any index
        given (``docs/concepts.md``, *Precision*; ``peak``: bounding-box diagonal of each reference
        vertex set).

    Raises:
        TypeError: an index given with point-set items.
        ShapeError, DeviceError: an index whose vertex counts or device do not fit its meshes.
        DTypeError: an index narrower than the promoted dtype of the inputs (it would round them).

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric import MeshIndex
        >>> r = nearest_vertex_distance_sets(torch.tensor([[0.0, 0, 0]]), torch.tensor([[3.0, 4, 0], [0, 0, 6]]))
        >>> r.forward.tolist()
        [5.0]
        >>> fine, coarse = trimesh.creation.icosphere(subdivisions=2), trimesh.creation.icosphere(subdivisions=1)
        >>> r = nearest_vertex_distance_sets(
        ...     coarse, fine, two_sided=True, reference_index=MeshIndex(fine), simplified_index=MeshIndex(coarse)
        ... )
        >>> r.forward.shape, float(r.forward.max()) < 1e-12, r.reverse.shape, round(float(r.reverse.max()), 3)
        (torch.Size([42]), True, torch.Size([162]), 0.313)
    """
    check_flag(two_sided, "two_sided")
    check_flag(detach_reference, "detach_reference")
    check_index_cache(indexes)
    sources = as_point_sources(simplified, "simplified")
    ref_sources = as_point_sources(reference, "reference")
    if len(ref_sources) != len(sources):
        raise ValueError(
            f"reference: expected {len(sources)} reference(s), one per simplified item, found {len(ref_sources)}"
        )
    _check_measurable(sources, ref_sources, two_sided)
    check_index(reference_index, [s.mesh for s in ref_sources], "reference_index")
    check_index(simplified_index, [s.mesh for s in sources], "simplified_index")
    # The dtype rule, at the door: everything in the promoted dtype of the inputs (a given index stands for its
    # mesh); a prebuilt index narrower than that is refused where it is used (index_of).
    given = [i.dtype for i in (reference_index, simplified_index) if i is not None]
    dtype = common_dtype(*(s.points.dtype for s in (*sources, *ref_sources)), *given)
    sources, ref_sources = cast_sources(sources, dtype), cast_sources(ref_sources, dtype)
    ref_meshes = [s.mesh for s in ref_sources if s.mesh is not None]
    if detach_reference:
        ref_meshes = [m.detach() for m in ref_meshes]
    reference_index = bound_to(reference_index, ref_meshes)
    simplified_index = bound_to(simplified_index, [s.mesh for s in sources if s.mesh is not None])
    points = [s.points for s in sources]
    refs = [s.points.detach() if detach_reference else s.points for s in ref_sources]
    all_meshes = len(ref_meshes) == len(ref_sources)
    forward, reverse = measure_vertex_distance_sets(
        points, refs, two_sided, reference_index, simplified_index, backend, ref_meshes if all_meshes else None, indexes
    )
    peak = torch.stack([_bbox_diagonal(r) for r in refs])
    reverse_lengths = lengths_of(refs) if two_sided else None
    return DirectedDistances(forward, lengths_of(points), reverse, reverse_lengths, peak)
