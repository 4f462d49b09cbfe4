"""The ``"bruteforce"`` selection backend: every (point, primitive) pair of an item, in chunks (the tests' reference).

No structure is kept (each query scans the set); intermediates stay under ``max_memory``. Selection follows the
contract of :mod:`torchmeshmetric.kernels.select`: the least computed squared distance, the lowest index among
equal ones.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import torch
from torch import Tensor

from torchmeshmetric.kernels._common import pair_chunks
from torchmeshmetric.kernels.triangle import region_candidates

if TYPE_CHECKING:
    from torchmeshmetric.kernels.contract import FaceSet, PointSet

__all__ = ["query_faces", "query_points"]

# (first query row, last query row, first primitive, last primitive) -> (rows, cols) squared distances.
ChunkSqDist = Callable[[int, int, int, int], Tensor]


def _chunked_argmin(
    point_batch: Tensor, prim_batch: Tensor, prim_offsets: Tensor, rows: int, cols: int, chunk_sq: ChunkSqDist
) -> Tensor:
    """Per query, the primitive of its own item with the least ``chunk_sq``, the lowest index among equal values.

    Query rows are taken ``rows`` at a time against the primitives of their items, ``cols`` at a time; a chunk's
    minimum replaces the running one only when strictly smaller, so the first (lowest) index wins ties.
    """
    num_p, num_prims = point_batch.shape[0], prim_batch.shape[0]
    best = torch.zeros(num_p, dtype=torch.long, device=point_batch.device)
    single = prim_offsets.numel() == 2
    for p0 in range(0, num_p, rows):
        p1 = min(num_p, p0 + rows)
        pb = point_batch[p0:p1]
        lo, hi = (0, num_prims) if single else (int(prim_offsets[pb[0]]), int(prim_offsets[pb[-1] + 1]))
        best_sq: Tensor | None = None
        for c0 in range(lo, hi, cols):
            c1 = min(hi, c0 + cols)
            sq = chunk_sq(p0, p1, c0, c1)
            if not single:
                sq = sq.masked_fill_(pb[:, None] != prim_batch[None, c0:c1], float("inf"))
            chunk_sq_min, chunk_idx = sq.min(-1)
            if best_sq is None:
                best_sq = torch.full_like(chunk_sq_min, float("inf"))
            better = chunk_sq_min < best_sq
            best_sq = torch.where(better, chunk_sq_min, best_sq)
            best[p0:p1] = torch.where(better, chunk_idx + c0, best[p0:p1])
    return best


def query_faces(_structure: None, faces: FaceSet, points: Tensor, point_batch: Tensor, max_memory: int) -> Tensor:
    """Closest face per centred point over all faces of its item (``max_memory`` bounds one intermediate)."""
    tri = faces.verts[faces.faces]
    a, b = tri[:, 0], tri[:, 1]
    ab, ac, bc = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], tri[:, 2] - tri[:, 1]

    def chunk_sq(p0: int, p1: int, f0: int, f1: int) -> Tensor:
        p = points[p0:p1, None]
        return region_candidates(p - a[f0:f1], p - b[f0:f1], ab[f0:f1], ac[f0:f1], bc[f0:f1])[-1].amin(-1)

    # ~40 live scalars per pair (three (..,3) edge differences, cross products, candidates).
    rows, cols = pair_chunks(points.shape[0], tri.shape[0], 40 * points.element_size(), max_memory)
    return _chunked_argmin(point_batch, faces.batch, faces.offsets, rows, cols, chunk_sq)


def query_points(_structure: None, ref: PointSet, points: Tensor, point_batch: Tensor, max_memory: int) -> Tensor:
    """Nearest reference row per centred point, by ``(dx*dx + dy*dy) + dz*dz`` on explicit differences.

    That is the order of ``dot(d, d)`` (``kernels._common.dot``, explicit adds, not a reduction whose order the
    device picks) used for the returned distances, and no ``|p|^2 - 2 p.q + |q|^2`` cancellation; every backend
    selects by this same computed value.
    """
    r_all = ref.points

    def chunk_sq(p0: int, p1: int, r0: int, r1: int) -> Tensor:
        p, r = points[p0:p1], r_all[r0:r1]
        sq = p[:, 0, None] - r[None, :, 0]
        sq.mul_(sq)
        d = p[:, 1, None] - r[None, :, 1]
        sq.add_(d.mul_(d))
        d = torch.sub(p[:, 2, None], r[None, :, 2], out=d)
        return sq.add_(d.mul_(d))

    # Three live (rows, cols) temporaries of the dtype plus the mask.
    rows, cols = pair_chunks(points.shape[0], r_all.shape[0], 4 * points.element_size(), max_memory)
    return _chunked_argmin(point_batch, ref.batch, ref.offsets, rows, cols, chunk_sq)
