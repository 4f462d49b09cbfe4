"""Exact nearest-vertex (cloud-to-cloud) distance, paper Eq. (5)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import (
    EmptyInputError,
    check_finite,
    check_float,
    check_same_device,
    check_shape,
    common_dtype,
)
from torchmeshmetric.kernels._common import (
    DEFAULT_MAX_MEMORY,
    centred,
    check_max_memory,
    check_queries,
    check_representable,
    dot,
    in_own_frame,
    item_rows,
    merge_rows,
    range_scale,
    rows_of,
    safe_sqrt,
)
from torchmeshmetric.kernels.accel import bvh
from torchmeshmetric.kernels.contract import PointSet
from torchmeshmetric.kernels.select import Selector, check_backend, resolve_backend
from torchmeshmetric.structures import PackedPoints, lengths_to_offsets, pack_points

__all__ = ["NearestVertexResult", "nearest_vertex_distance"]


class NearestVertexResult(NamedTuple):
    """Result of :func:`nearest_vertex_distance`.

    Attributes:
        dists: ``(P,)`` Euclidean distance (**not squared**) to the nearest reference point.
        idx: ``(P,)`` int64 row of that point in the (packed) ``ref_points``.

    Example:
        >>> import torch
        >>> ref = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
        >>> r = nearest_vertex_distance(torch.tensor([[0.0, 0, 2], [1.5, 0, 0]]), ref)
        >>> r.dists.tolist(), r.idx.tolist()
        ([2.0, 0.5], [0, 1])
    """

    dists: Tensor
    idx: Tensor


class _NearestIndex:
    """Reference point sets prepared for nearest-point queries (centred once, structure kept). Trusted input.

    Coordinates whose squares would overflow or underflow the dtype are scaled by an exact power of two
    (:func:`~torchmeshmetric.kernels._common.range_scale`) before selection, and distances divided back. The scale
    covers the reference sets; a one-off index also passes its one query (``queries``) so that the scale covers
    points far from a small reference set too (their distances are representable, their squares may not be).
    """

    def __init__(
        self, ref: Tensor, lengths: Tensor, backend: str, max_memory: int, *, queries: PackedPoints | None = None
    ) -> None:
        self.lengths = lengths
        self.selector = Selector(backend, self._set(ref, queries), check_max_memory(max_memory))

    def _set(self, ref: Tensor, queries: PackedPoints | None = None) -> PointSet:
        """Centre and scale ``ref`` (and keep it for the differentiable distances): the set the backend selects from."""
        self.ref = ref
        self.centers, self._row_center, batch = centred(ref, self.lengths)
        ref_c = (ref - self._row_center).detach()
        extent = float(ref_c.abs().amax()) if ref_c.numel() else 0.0
        self._extent = extent  # the reference's own, before any query's (_query_once compares the two frames)
        if queries is not None and queries.points.numel():
            extent = max(extent, float(self._centred_queries(*queries)[1].detach().abs().amax()))
        self._scale = range_scale(extent, ref.dtype, 2)
        if self._scale is not None:
            ref_c = ref_c * self._scale
        self._ref_c = ref_c
        return PointSet(ref_c, batch, lengths_to_offsets(self.lengths))

    def _centred_queries(self, points: Tensor, points_lengths: Tensor) -> tuple[Tensor, Tensor]:
        """``(batch, points - centre of their item)``, unscaled."""
        batch, center = item_rows(points_lengths, points.shape[0], self.centers)
        return batch, points - center

    def refit(self, ref: Tensor) -> None:
        self.selector.refit(self._set(ref))

    def query(self, points: Tensor, points_lengths: Tensor) -> NearestVertexResult:
        check_queries(
            points,
            points_lengths,
            self.lengths,
            count_error="ref_points: expected {sets} reference sets (one per point set), found {items}",
            lacking_error="ref_points: reference set {item} is empty but has {points} query points",
        )
        pb, p_c = self._centred_queries(points, points_lengths)
        scale = self._scale
        if scale is not None:
            p_c = p_c * scale
        idx = self.selector.select(p_c, pb)
        if p_c.requires_grad or self.ref.requires_grad:
            r_c = self.ref - self._row_center
            diff = p_c - (r_c if scale is None else r_c * scale)[idx]
            dists = safe_sqrt(dot(diff, diff))
        else:
            # Without autograd, safe_sqrt(sq) is sqrt(sq) bit for bit (sq >= 0, sqrt(0) = 0).
            diff = p_c - self._ref_c.index_select(0, idx)
            dists = torch.sqrt(dot(diff, diff))
        if scale is not None:
            dists = dists / scale
        check_representable(dists, "points")
        return NearestVertexResult(dists, idx)


def nearest_vertex_distance(
    points: Tensor | Sequence[Tensor],
    ref_points: Tensor | Sequence[Tensor],
    *,
    points_lengths: Tensor | None = None,
    ref_lengths: Tensor | None = None,
    max_memory: int = DEFAULT_MAX_MEMORY,
    backend: str = "auto",
) -> NearestVertexResult:
    """Exact distance from every point to its nearest reference point (paper Eq. 5, cloud-to-cloud).

    Args:
        points: ``(P, 3)`` query points, packed ``(sum P_b, 3)`` with ``points_lengths``, or a list.
        ref_points: ``(R, 3)`` reference points (e.g. a mesh's vertex set), packed with ``ref_lengths``, or a list.
        points_lengths: ``(B,)`` points per item of a packed batch.
        ref_lengths: ``(B,)`` reference points per item of a packed batch.
        max_memory: upper bound in bytes of one intermediate (default 256 MiB).
        backend: ``"auto"``, ``"bvh"``, ``"triton"``, ``"pruned"`` or ``"bruteforce"``.

    Returns:
        :class:`NearestVertexResult` ``(dists, idx)``; ``dists``, in the promoted dtype of the two point sets
        (float64 if either is), is **not squared** and differentiable w.r.t. both point sets (gradient 0 at zero
        distance). The nearest point is the one with the smallest computed squared distance (bounding-box centred
        coordinates), the lowest index among equal ones; every backend returns the same index.

    Example:
        >>> import torch
        >>> r = nearest_vertex_distance(torch.tensor([[0.0, 0, 0]]), torch.tensor([[3.0, 4, 0], [0, 0, 6]]))
        >>> r.dists.item(), r.idx.item()
        (5.0, 0)
    """
    if points_lengths is None and ref_lengths is None and isinstance(points, Tensor) and isinstance(ref_points, Tensor):
        return _nearest_single(points, ref_points, max_memory, backend)

    pts = pack_points(points, points_lengths, "points")
    ref = pack_points(ref_points, ref_lengths, "ref_points")
    check_same_device({"points": pts.points, "ref_points": ref.points})
    if pts.lengths.numel() != ref.lengths.numel():
        raise ValueError(
            f"ref_points: expected {pts.lengths.numel()} reference sets (one per point set), "
            f"found {ref.lengths.numel()}"
        )
    check_backend(backend)
    dtype = common_dtype(pts.points.dtype, ref.points.dtype)  # the dtype rule (docs/concepts.md, Precision)
    return _query_once(pts.points.to(dtype), pts.lengths, ref.points.to(dtype), ref.lengths, backend, max_memory)


def _query_once(
    points: Tensor, points_lengths: Tensor, ref: Tensor, ref_lengths: Tensor, backend: str, max_memory: int
) -> NearestVertexResult:
    """A one-off index over ``ref`` queried once: in the reference's own frame, and far points in one scaled for them.

    As :func:`~torchmeshmetric.kernels.mesh_index.measure_once`: the points the reference's range scale covers are
    measured in its frame; the others, if any, in a frame scaled for them as well (one frame for all let a float32
    point at 1e30 make every other distance to a unit set 0).
    """
    index = _NearestIndex(ref, ref_lengths, backend, max_memory)
    num_items, num_points = int(ref_lengths.numel()), int(points.shape[0])
    if not (num_points and int(points_lengths.numel()) == num_items):
        return index.query(points, points_lengths)  # raises, naming the fault
    batch, points_c = index._centred_queries(points, points_lengths)
    own = in_own_frame(points_c.detach().abs().amax(-1), index._extent, 2)
    if own is None:
        return index.query(points, points_lengths)
    if not bool(own.any()):  # every point needs the wider frame: one index scaled for them all
        queries = PackedPoints(points, points_lengths)
        return _NearestIndex(ref, ref_lengths, backend, max_memory, queries=queries).query(points, points_lengths)
    near, near_lengths = rows_of(own, batch, num_items)
    far, far_lengths = rows_of(~own, batch, num_items)
    far_points = points.index_select(0, far)
    wide = _NearestIndex(ref, ref_lengths, backend, max_memory, queries=PackedPoints(far_points, far_lengths))
    parts = (
        index.query(points.index_select(0, near), near_lengths),
        wide.query(far_points, far_lengths),
    )
    return NearestVertexResult(*(merge_rows(num_points, (near, far), pair) for pair in zip(*parts, strict=True)))


def _finite_bounds(x: Tensor, name: str) -> tuple[Tensor, Tensor]:
    """Per-column ``(lo, hi)`` of a non-empty ``(N, 3)`` tensor in one pass, raising as ``check_finite`` would.

    ``aminmax`` propagates NaN and keeps +-Inf, so finite bounds mean finite values.
    """
    lo, hi = torch.aminmax(x.detach(), dim=0)
    if not bool(torch.isfinite(torch.cat([lo, hi])).all()):
        check_finite(x, name)
    return lo, hi


def _nearest_single(points: Tensor, ref_points: Tensor, max_memory: int, backend: str) -> NearestVertexResult:
    """Batch-of-one path of :func:`nearest_vertex_distance`: same checks, errors and results, less overhead.

    Without autograd a backend's fused path (finiteness, centring, selection and distances in one call) serves
    the call when it can. Otherwise the bounding-box pass of the reference set doubles as its finiteness check and
    gives the centre directly (no scatter, no batch index, no gathers of per-item centres).
    """
    check_shape(points, ("P", 3), "points")
    check_float(points, "points")
    check_shape(ref_points, ("P", 3), "ref_points")
    check_float(ref_points, "ref_points")
    check_same_device({"points": points, "ref_points": ref_points})
    check_backend(backend)
    check_max_memory(max_memory)
    num_p, num_r = points.shape[0], ref_points.shape[0]
    dtype = common_dtype(points.dtype, ref_points.dtype)
    p, r = points.to(dtype), ref_points.to(dtype)
    fused = bool(num_p and num_r) and not (p.requires_grad or r.requires_grad)
    if fused and resolve_backend(backend, points.device, dtype, num_p * num_r).name == "bvh":
        out = bvh.bvh_nearest_single(p.detach(), r.detach())
        # The fused path is unscaled: distances that overflowed or all lie below 2**-60 go to the scaled path.
        if out is not None and _in_range(out[0]):
            return NearestVertexResult(out[0], out[1])
    if num_p:
        _finite_bounds(points, "points")
    if num_r:
        _finite_bounds(ref_points, "ref_points")
    if num_p == 0:
        raise EmptyInputError("points: expected at least one point, found an empty point set")
    if num_r == 0:
        raise EmptyInputError(f"ref_points: reference set 0 is empty but has {num_p} query points")
    lengths = torch.tensor([num_r], device=points.device)
    return _query_once(p, torch.tensor([num_p], device=points.device), r, lengths, backend, max_memory)


def _in_range(dists: Tensor) -> bool:
    """Whether unscaled distances are trustworthy: finite, and not all below ``2**-60`` (squares near underflow)."""
    hi = float(dists.amax())
    return math.isfinite(hi) and hi > 2.0**-60
