"""Exact selection by certified cluster pruning, in plain torch ops (any device; the CUDA and no-compiler path).

Primitives (faces or reference points) of each item are sorted along a Morton curve of their box centres and
grouped into clusters of ``CLUSTER`` consecutive primitives with a bounding box. For a chunk of query points:

1. lower bound ``lb[p, c]``: squared distance from ``p`` to the box of cluster ``c`` (same item only);
2. upper bound ``ub[p]``: exact distance to every primitive of the cluster with the smallest ``lb``;
3. candidate clusters: ``lb <= bound(ub)``, where ``bound`` adds a certified slack for rounding (64 ulps of the
   distance and of the item's coordinate scale, the same rule as the C++ BVH); every other cluster provably holds
   no primitive whose computed distance could tie or beat ``ub``;
4. exact distances to the primitives of the candidate clusters, computed by the very same torch expression as the
   brute force, then the minimum with the lowest primitive index among ties.

Memory is ``O(points + primitives)`` per chunk bound: ``lb`` is chunked so that it stays under ``max_memory``, and
the candidate pairs are evaluated in chunks of the same budget.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import torch
from torch import Tensor

from torchmeshmetric.kernels._common import ROUNDING_ULPS, dot, rounding_slack
from torchmeshmetric.kernels.triangle import region_candidates

if TYPE_CHECKING:
    from torchmeshmetric.kernels.contract import FaceSet, PointSet

__all__ = ["pruned_faces", "pruned_nearest", "query_faces", "query_points"]

CLUSTER = 32
"""Primitives per cluster."""

# (query points (Q, 3), primitive ids (Q, K) with -1 = none) -> squared distances (Q, K), inf for -1.
PairSqDist = Callable[[Tensor, Tensor], Tensor]


def _morton(x: Tensor, lo: Tensor, hi: Tensor) -> Tensor:
    """30-bit Morton codes of ``x`` (N, 3) within per-row boxes ``lo``/``hi`` (N, 3)."""
    ext = (hi - lo).clamp_min(torch.finfo(x.dtype).tiny)
    q = ((x - lo) / ext * 1023.99).clamp(0, 1023).long()
    code = torch.zeros(x.shape[0], dtype=torch.long, device=x.device)
    for bit in range(10):
        for axis in range(3):
            code |= ((q[:, axis] >> bit) & 1) << (3 * bit + 2 - axis)
    return code


def _clusters(lo: Tensor, hi: Tensor, batch: Tensor, offsets: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
    """Sort primitives per item along a Morton curve and group them in clusters.

    Returns ``(members (C, CLUSTER) global ids or -1, box_lo (C, 3), box_hi (C, 3), cluster_batch (C,),
    cluster_offsets (B+1,))``.
    """
    n, device = lo.shape[0], lo.device
    num_items = offsets.numel() - 1
    cen = 0.5 * (lo + hi)
    big = torch.full((num_items, 3), float("inf"), dtype=lo.dtype, device=device)
    c_lo = big.scatter_reduce(0, batch[:, None].expand(-1, 3), cen, "amin")
    c_hi = (-big).scatter_reduce(0, batch[:, None].expand(-1, 3), cen, "amax")
    code = _morton(cen, c_lo[batch], c_hi[batch])
    order = torch.sort(batch * (1 << 30) + code, stable=True).indices
    lengths = offsets[1:] - offsets[:-1]
    per_item = (lengths + CLUSTER - 1) // CLUSTER
    c_off = torch.cat([per_item.new_zeros(1), per_item.cumsum(0)])
    rank = torch.arange(n, device=device) - offsets[batch[order]]
    slot = (c_off[batch[order]] + rank // CLUSTER) * CLUSTER + rank % CLUSTER
    num_c = int(c_off[-1])
    members = torch.full((num_c * CLUSTER,), -1, dtype=torch.long, device=device)
    members[slot] = order
    members = members.view(num_c, CLUSTER)
    cl = torch.arange(num_c, device=device).repeat_interleave(CLUSTER)
    ok = members.view(-1) >= 0
    cid, mid = cl[ok], members.view(-1)[ok]
    inf = torch.full((num_c, 3), float("inf"), dtype=lo.dtype, device=device)
    b_lo = inf.scatter_reduce(0, cid[:, None].expand(-1, 3), lo[mid], "amin")
    b_hi = (-inf).scatter_reduce(0, cid[:, None].expand(-1, 3), hi[mid], "amax")
    c_batch = torch.arange(num_items, device=device).repeat_interleave(per_item)
    return members, b_lo, b_hi, c_batch, c_off


def _box_sq(p: Tensor, lo: Tensor, hi: Tensor) -> Tensor:
    """(Q, C) squared distance from points (Q, 3) to boxes (C, 3)."""
    d = torch.maximum((lo[None] - p[:, None]).clamp_min(0), (p[:, None] - hi[None]).clamp_min(0))
    return dot(d, d)  # the fixed order of the point distances below, not a reduction's (device-dependent) one


def _select(
    points: Tensor,
    point_batch: Tensor,
    lo: Tensor,
    hi: Tensor,
    prim_batch: Tensor,
    offsets: Tensor,
    pair_sq: PairSqDist,
    max_memory: int,
) -> Tensor:
    device, dtype = points.device, points.dtype
    num_items = offsets.numel() - 1
    members, b_lo, b_hi, c_batch, c_off = _clusters(lo, hi, prim_batch, offsets)
    eps = torch.finfo(dtype).eps
    scale = torch.zeros(num_items, dtype=dtype, device=device)
    scale = scale.scatter_reduce(0, prim_batch, torch.maximum(lo.abs(), hi.abs()).amax(-1), "amax")
    slack = rounding_slack(scale)
    num_p, num_c = points.shape[0], members.shape[0]
    out = torch.empty(num_p, dtype=torch.long, device=device)
    # One (chunk, C) lower-bound matrix of ~6 live values per entry, or pairs x CLUSTER x ~40 values.
    rows = max(1, min(num_p, max_memory // max(1, 6 * num_c * points.element_size())))
    pair_rows = max(1, max_memory // (40 * CLUSTER * points.element_size()))
    big = torch.iinfo(torch.long).max
    for p0 in range(0, num_p, rows):
        p1 = min(num_p, p0 + rows)
        p, pb = points[p0:p1], point_batch[p0:p1]
        c_lo_i, c_hi_i = int(c_off[pb.min()]), int(c_off[pb.max() + 1])
        lb = _box_sq(p, b_lo[c_lo_i:c_hi_i], b_hi[c_lo_i:c_hi_i])
        lb = lb.masked_fill(pb[:, None] != c_batch[None, c_lo_i:c_hi_i], float("inf"))
        first = lb.argmin(-1) + c_lo_i
        ub = pair_sq(p, members[first]).amin(-1)
        bound = (ub.sqrt() * (1 + ROUNDING_ULPS * eps) + slack[pb]) ** 2
        # Same item only: where squares overflow, ub and the other items' masked bounds are both inf.
        same = pb[:, None] == c_batch[None, c_lo_i:c_hi_i]
        q_idx, c_idx = ((lb <= bound[:, None]) & same).nonzero(as_tuple=True)
        c_idx = c_idx + c_lo_i
        key = torch.full((p1 - p0,), float("inf"), dtype=dtype, device=device)
        keys, ids = [], []
        for s0 in range(0, q_idx.numel(), pair_rows):
            q, c = q_idx[s0 : s0 + pair_rows], c_idx[s0 : s0 + pair_rows]
            mem = members[c]
            sq = pair_sq(p[q], mem)
            kmin = sq.amin(-1)
            # Padding (-1, squared distance inf) never wins: it would tie with squares that overflowed to inf.
            kid = torch.where((sq == kmin[:, None]) & (mem >= 0), mem, torch.full_like(mem, big)).amin(-1)
            key = key.scatter_reduce(0, q, kmin, "amin")
            keys.append(kmin)
            ids.append(kid)
        kmin, kid = torch.cat(keys), torch.cat(ids)
        best = torch.full((p1 - p0,), big, dtype=torch.long, device=device)
        best = best.scatter_reduce(0, q_idx, torch.where(kmin == key[q_idx], kid, torch.full_like(kid, big)), "amin")
        # A point without a candidate (only where its squares overflow: every lower bound inf) takes its item's
        # first primitive; its distance is then inf too, and the caller raises NonFiniteError as for any backend.
        out[p0:p1] = torch.where(best == big, offsets[pb], best)
    return out


def pruned_faces(
    points: Tensor,
    point_batch: Tensor,
    verts: Tensor,
    faces: Tensor,
    face_batch: Tensor,
    face_offsets: Tensor,
    max_memory: int,
) -> Tensor:
    """Closest face per point (brute-force face-selector contract, see ``kernels.select``), exact, any device.

    Faces are grouped in clusters whose bounding boxes bound each point's distance from below; only clusters whose
    bound can beat the best face found so far (with the rounding slack of the coordinates' scale) are searched.

    Args:
        points: ``(P, 3)`` query points, centred as their item's faces (:class:`~torchmeshmetric.kernels.contract.
            FaceSet`).
        point_batch: ``(P,)`` int64 item of each point.
        verts: ``(V, 3)`` vertices.
        faces: ``(F, 3)`` int64 faces (global rows of ``verts``), grouped by item.
        face_batch: ``(F,)`` int64 item of each face.
        face_offsets: ``(B + 1,)`` int64 first face of each item.
        max_memory: bytes the temporary candidate matrices may take (the points are processed in chunks).

    Returns:
        ``(P,)`` int64 row of ``faces`` of each point's closest face in its item (lowest row among equal squared
        distances).

    Example:
        >>> import torch
        >>> verts = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 5], [1, 0, 5], [0, 1, 5]])
        >>> faces = torch.tensor([[0, 1, 2], [3, 4, 5]])
        >>> points = torch.tensor([[0.25, 0.25, 1.0], [0.2, 0.2, 4.0]])
        >>> one_item = torch.zeros(2, dtype=torch.long)
        >>> pruned_faces(points, one_item, verts, faces, one_item, torch.tensor([0, 2]), 2**20).tolist()
        [0, 1]
    """
    tri = verts[faces]
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac, bc = b - a, c - a, c - b

    def pair_sq(p: Tensor, mem: Tensor) -> Tensor:
        f = mem.clamp_min(0)
        q = p[:, None]
        sq = region_candidates(q - a[f], q - b[f], ab[f], ac[f], bc[f])[-1].amin(-1)
        return sq.masked_fill(mem < 0, float("inf"))

    return _select(points, point_batch, tri.amin(1), tri.amax(1), face_batch, face_offsets, pair_sq, max_memory)


def pruned_nearest(
    points: Tensor, point_batch: Tensor, ref: Tensor, ref_batch: Tensor, ref_offsets: Tensor, max_memory: int
) -> Tensor:
    """Nearest reference point per point (nearest-selector contract, see ``kernels.select``), exact, any device.

    Selects by the computed squared distance, lowest index among equal ones, like the brute force.

    Args:
        points: ``(P, 3)`` query points, centred as their item's reference points.
        point_batch: ``(P,)`` int64 item of each point.
        ref: ``(R, 3)`` reference points, grouped by item.
        ref_batch: ``(R,)`` int64 item of each reference point.
        ref_offsets: ``(B + 1,)`` int64 first reference point of each item.
        max_memory: bytes the temporary candidate matrices may take.

    Returns:
        ``(P,)`` int64 row of ``ref`` nearest to each point in its item.

    Example:
        >>> import torch
        >>> ref = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 0, 5]])
        >>> points = torch.tensor([[0.0, 0, 1], [0.1, 0, 4], [0.9, 0, 0]])
        >>> batch = torch.zeros(3, dtype=torch.long)
        >>> pruned_nearest(points, batch, ref, batch, torch.tensor([0, 3]), 2**20).tolist()
        [0, 2, 1]
    """

    def pair_sq(p: Tensor, mem: Tensor) -> Tensor:
        d = p[:, None] - ref[mem.clamp_min(0)]
        # (dx*dx + dy*dy) + dz*dz on every device, the brute force's selection key (not a reduction, see dot).
        return dot(d, d).masked_fill(mem < 0, float("inf"))

    return _select(points, point_batch, ref, ref, ref_batch, ref_offsets, pair_sq, max_memory)


def query_faces(_structure: None, faces: FaceSet, points: Tensor, point_batch: Tensor, max_memory: int) -> Tensor:
    """:func:`pruned_faces` in the backend contract (no structure is kept: clusters are rebuilt per query)."""
    return pruned_faces(points, point_batch, faces.verts, faces.faces, faces.batch, faces.offsets, max_memory)


def query_points(_structure: None, ref: PointSet, points: Tensor, point_batch: Tensor, max_memory: int) -> Tensor:
    """:func:`pruned_nearest` in the backend contract (no structure is kept)."""
    return pruned_nearest(points, point_batch, ref.points, ref.batch, ref.offsets, max_memory)
