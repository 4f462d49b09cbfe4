"""Exact nearest-vertex (cloud-to-cloud) distance, paper Eq. (5)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, check_finite, check_float, check_same_device, check_shape
from torchmeshmetric.kernels._common import DEFAULT_MAX_MEMORY, check_representable, extreme_range, pair_chunks
from torchmeshmetric.structures import pack_points

__all__ = ["NearestVertexResult", "nearest_vertex_distance"]


class NearestVertexResult(NamedTuple):
    """Result of :func:`nearest_vertex_distance`.

    Attributes:
        dists: ``(P,)`` Euclidean distance (**not squared**) to the nearest reference point.
        idx: ``(P,)`` int64 row of that point in the (packed) ``ref_points``.
    """

    dists: Tensor
    idx: Tensor


def _bruteforce_nearest(
    points: Tensor, point_batch: Tensor, ref: Tensor, ref_batch: Tensor, ref_offsets: Tensor, max_memory: int
) -> Tensor:
    """Chunked brute force on explicit differences (no ``|p|^2 - 2 p.q + |q|^2`` cancellation).

    Selects by the squared distance ``(dx*dx + dy*dy) + dz*dz`` (the order of ``(d * d).sum(-1)`` used for the
    returned distances), lowest index among equal squares: every backend selects by this same computed value.
    """
    num_p, num_r = points.shape[0], ref.shape[0]
    # Three live (rows, cols) temporaries of the dtype plus the mask.
    rows, cols = pair_chunks(num_p, num_r, 4 * points.element_size(), max_memory)
    best = torch.zeros(num_p, dtype=torch.long, device=points.device)
    single = ref_offsets.numel() == 2
    for p0 in range(0, num_p, rows):
        p1 = min(num_p, p0 + rows)
        pb = point_batch[p0:p1]
        p = points[p0:p1]
        r_lo, r_hi = (0, num_r) if single else (int(ref_offsets[pb[0]]), int(ref_offsets[pb[-1] + 1]))
        best_d = torch.full((p1 - p0,), float("inf"), dtype=points.dtype, device=points.device)
        for r0 in range(r_lo, r_hi, cols):
            r1 = min(r_hi, r0 + cols)
            r = ref[r0:r1]
            sq = p[:, 0, None] - r[None, :, 0]
            sq.mul_(sq)
            d = p[:, 1, None] - r[None, :, 1]
            sq.add_(d.mul_(d))
            d = torch.sub(p[:, 2, None], r[None, :, 2], out=d)
            sq.add_(d.mul_(d))
            if not single:
                sq = sq.masked_fill_(pb[:, None] != ref_batch[None, r0:r1], float("inf"))
            chunk_d, chunk_i = sq.min(-1)
            better = chunk_d < best_d
            best_d = torch.where(better, chunk_d, best_d)
            best[p0:p1] = torch.where(better, chunk_i + r0, best[p0:p1])
    return best


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
        :class:`NearestVertexResult` ``(dists, idx)``; ``dists`` is **not squared** and differentiable
        w.r.t. both point sets (gradient 0 at zero distance). The nearest point is the one with the smallest
        computed squared distance (bounding-box centred coordinates), the lowest index among equal ones; every
        backend returns the same index.

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
    _check_backend(backend)
    dtype = torch.promote_types(pts.points.dtype, ref.points.dtype)
    return _scaled_query(pts.points.to(dtype), pts.lengths, ref.points.to(dtype), ref.lengths, backend, max_memory)


def _scaled_query(
    points: Tensor, points_lengths: Tensor, ref: Tensor, ref_lengths: Tensor, backend: str, max_memory: int
) -> NearestVertexResult:
    """Query a one-off index, scaling coordinates of extreme magnitude exactly (powers of two) when needed."""
    from torchmeshmetric.kernels.mesh_index import _NearestIndex  # builds on this module

    extreme = extreme_range(points, ref, 2)
    if extreme is not None:
        centre, scale = extreme
        points, ref = (points - centre) * scale, (ref - centre) * scale
    # Already scaled for the points too: the index must not rescale by the reference set's extent alone.
    res = _NearestIndex(ref, ref_lengths, backend, max_memory, rescale=extreme is None).query(points, points_lengths)
    if extreme is not None:
        res = res._replace(dists=res.dists / scale)
    check_representable(res.dists, "points")
    return res


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
    from torchmeshmetric.kernels.accel.bvh import bvh_nearest_single
    from torchmeshmetric.kernels.select import resolve_backend

    _check_backend(backend)
    num_p, num_r = points.shape[0], ref_points.shape[0]
    dtype = torch.promote_types(points.dtype, ref_points.dtype)
    p, r = points.to(dtype), ref_points.to(dtype)
    fused = bool(num_p and num_r) and not (p.requires_grad or r.requires_grad)
    if fused and resolve_backend(backend, points.device, dtype, num_p * num_r).name == "bvh":
        out = bvh_nearest_single(p.detach(), r.detach())
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
    return _scaled_query(p, torch.tensor([num_p], device=points.device), r, lengths, backend, max_memory)


def _check_backend(backend: str) -> None:
    from torchmeshmetric.kernels.select import BACKENDS

    if backend != "auto" and backend not in BACKENDS:
        raise ValueError(f"backend: expected one of {['auto', *BACKENDS]}, found {backend!r}")


def _in_range(dists: Tensor) -> bool:
    """Whether unscaled distances are trustworthy: finite, and not all below ``2**-60`` (squares near underflow)."""
    hi = float(dists.amax())
    return math.isfinite(hi) and hi > 2.0**-60
