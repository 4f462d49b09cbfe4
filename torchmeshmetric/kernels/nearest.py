"""Exact nearest-vertex (cloud-to-cloud) distance, paper Eq. (5)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, check_finite, check_float, check_same_device, check_shape
from torchmeshmetric.kernels._common import (
    DEFAULT_MAX_MEMORY,
    check_representable,
    dot,
    item_centers,
    pair_chunks,
    range_scale,
    safe_sqrt,
)
from torchmeshmetric.structures import batch_index, lengths_to_offsets, pack_points

__all__ = ["NearestVertexResult", "nearest_vertex_distance", "register_nearest_backend"]


class NearestVertexResult(NamedTuple):
    """Result of :func:`nearest_vertex_distance`.

    Attributes:
        dists: ``(P,)`` Euclidean distance (**not squared**) to the nearest reference point.
        idx: ``(P,)`` int64 row of that point in the (packed) ``ref_points``.
    """

    dists: Tensor
    idx: Tensor


# (points, point_batch, ref, ref_batch, ref_offsets, max_memory) -> idx (P,); inputs centred, packed, detached.
NearestSelector = Callable[[Tensor, Tensor, Tensor, Tensor, Tensor, int], Tensor]
# Fused batch-of-one path: (points (P, 3), ref (R, 3)), raw (not centred), same dtype, both non-empty, no autograd
# -> (dists, idx, center) computed exactly as the general path would, or None when it cannot serve the call
# (other device, non-finite values, no compiled extension): the general path then runs (and raises).
NearestSingle = Callable[[Tensor, Tensor], "tuple[Tensor, Tensor, Tensor] | None"]
_NEAREST_BACKENDS: dict[str, NearestSelector] = {}
_NEAREST_SINGLE: dict[str, NearestSingle] = {}
_NEAREST_AUTO: list[Callable[[Tensor, Tensor], str | None]] = []


def register_nearest_backend(
    name: str,
    selector: NearestSelector,
    auto: Callable[[Tensor, Tensor], str | None] | None = None,
    single: NearestSingle | None = None,
) -> None:
    """Register a nearest-neighbour selection backend (used by accelerated kernels).

    Args:
        name: the name accepted by ``backend=``.
        selector: index of the nearest reference point per query (centred, packed, detached inputs).
        auto: a ``backend="auto"`` rule returning a backend name or ``None``.
        single: optional fused batch-of-one path returning ``(dists, idx, center)`` or ``None``.
    """
    _NEAREST_BACKENDS[name] = selector
    if single is not None:
        _NEAREST_SINGLE[name] = single
    if auto is not None:
        _NEAREST_AUTO.append(auto)


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


register_nearest_backend("bruteforce", _bruteforce_nearest)


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
        backend: ``"auto"`` or ``"bruteforce"`` (or a registered accelerated backend).

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
    if pts.points.shape[0] == 0:
        raise EmptyInputError("points: expected at least one point, found an empty point set")
    lacking = (pts.lengths > 0) & (ref.lengths == 0)
    if bool(lacking.any()):
        b = int(lacking.nonzero()[0, 0])
        raise EmptyInputError(f"ref_points: reference set {b} is empty but has {int(pts.lengths[b])} query points")
    select = _resolve_backend(backend, pts.points, ref.points)
    dtype = torch.promote_types(pts.points.dtype, ref.points.dtype)
    p, r = pts.points.to(dtype), ref.points.to(dtype)
    pb, rb = batch_index(pts.lengths), batch_index(ref.lengths)
    centers = item_centers(r, rb, int(ref.lengths.numel()))
    p_c, r_c = p - centers[pb], r - centers[rb]
    scale = range_scale(float(torch.cat([p_c.detach(), r_c.detach()]).abs().amax()), dtype, 2)
    if scale is not None:
        p_c, r_c = p_c * scale, r_c * scale
    with torch.no_grad():
        idx = select(p_c.detach(), pb, r_c.detach(), rb, lengths_to_offsets(ref.lengths), max_memory)
    diff = p_c - r_c[idx]
    dists = safe_sqrt(dot(diff, diff))
    return NearestVertexResult(dists if scale is None else dists / scale, idx)


def _resolve_name(backend: str, points: Tensor, ref: Tensor) -> str:
    if backend == "auto":
        return next((n for rule in _NEAREST_AUTO if (n := rule(points, ref)) is not None), "bruteforce")
    if backend in _NEAREST_BACKENDS:
        return backend
    raise ValueError(f"backend: expected one of {['auto', *_NEAREST_BACKENDS]}, found {backend!r}")


def _resolve_backend(backend: str, points: Tensor, ref: Tensor) -> NearestSelector:
    return _NEAREST_BACKENDS[_resolve_name(backend, points, ref)]


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
    num_p, num_r = points.shape[0], ref_points.shape[0]
    name = _resolve_name(backend, points, ref_points)
    dtype = torch.promote_types(points.dtype, ref_points.dtype)
    p, r = points.to(dtype), ref_points.to(dtype)
    fused = _NEAREST_SINGLE.get(name)
    if fused is not None and num_p and num_r and not (p.requires_grad or r.requires_grad):
        out = fused(p.detach(), r.detach())
        # Distances all below 2**-60 or beyond float range: the fused path's magnitudes are extreme, the general
        # path below scales them (one reduction of the result decides; the fused path itself stays unscaled).
        if out is not None and _in_range(out[0]):
            return NearestVertexResult(out[0], out[1])
    p_bounds = _finite_bounds(points, "points") if num_p else None
    bounds = _finite_bounds(ref_points, "ref_points") if num_r else None
    if num_p == 0:
        raise EmptyInputError("points: expected at least one point, found an empty point set")
    if bounds is None:
        raise EmptyInputError(f"ref_points: reference set 0 is empty but has {num_p} query points")
    select = _NEAREST_BACKENDS[name]
    lo, hi = bounds[0].to(dtype), bounds[1].to(dtype)
    center = 0.5 * (lo + hi)
    p_c, r_c = p - center, r - center
    assert p_bounds is not None
    extent = torch.stack([hi - center, p_bounds[1].to(dtype) - center, center - p_bounds[0].to(dtype)]).abs().amax()
    scale = range_scale(float(extent), dtype, 2)
    if scale is not None:
        p_c, r_c = p_c * scale, r_c * scale
    device = points.device
    with torch.no_grad():
        pb = torch.zeros(num_p, dtype=torch.long, device=device)
        rb = torch.zeros(num_r, dtype=torch.long, device=device)
        offsets = torch.tensor([0, num_r], dtype=torch.long, device=device)
        idx = select(p_c.detach(), pb, r_c.detach(), rb, offsets, max_memory)
    if p_c.requires_grad or r_c.requires_grad:
        diff = p_c - r_c[idx]
        dists = safe_sqrt(dot(diff, diff))
    else:
        # Without autograd, safe_sqrt(sq) is sqrt(sq) bit for bit (sq >= 0, sqrt(0) = 0).
        diff = p_c - r_c.index_select(0, idx)
        dists = torch.sqrt(dot(diff, diff))
    if scale is not None:
        dists = dists / scale
    check_representable(dists, "points")
    return NearestVertexResult(dists, idx)


def _in_range(dists: Tensor) -> bool:
    """Whether unscaled distances are trustworthy: finite, and not all below ``2**-60``.

    Squares near underflow (all zero included: tiny coordinates can underflow to exactly 0) are not.
    """
    hi = float(dists.amax())
    return math.isfinite(hi) and hi > 2.0**-60
