"""CPU selectors backed by the C++ BVH extension (``bvh.cpp``), with the pure-torch pruned path as fallback."""

from __future__ import annotations

import torch
from torch import Tensor

from torchmeshmetric.kernels.accel._extension import bvh_ready, load_bvh
from torchmeshmetric.kernels.accel.pruned import pruned_faces, pruned_nearest

__all__ = ["bvh_closest_points", "bvh_faces", "bvh_nearest", "bvh_nearest_single"]


def bvh_faces(
    points: Tensor,
    point_batch: Tensor,
    verts: Tensor,
    faces: Tensor,
    face_batch: Tensor,
    face_offsets: Tensor,
    max_memory: int,
) -> Tensor:
    """Closest face per point through one BVH per item (face-selector contract), exact, lowest index on ties.

    Runs on CPU tensors; other devices, or a missing compiler, use :func:`pruned_faces`.
    """
    ext = load_bvh() if points.device.type == "cpu" else None
    if ext is None:
        return pruned_faces(points, point_batch, verts, faces, face_batch, face_offsets, max_memory)
    return ext.closest_faces(
        points.contiguous(),
        point_batch.contiguous(),
        verts.contiguous(),
        faces.long().contiguous(),
        face_offsets.long().contiguous(),
    )


def bvh_nearest(
    points: Tensor, point_batch: Tensor, ref: Tensor, ref_batch: Tensor, ref_offsets: Tensor, max_memory: int
) -> Tensor:
    """Nearest reference point per point through one BVH per item (nearest-selector contract), exact.

    Runs on CPU tensors; other devices, or a missing compiler, use :func:`pruned_nearest`.
    """
    ext = load_bvh() if points.device.type == "cpu" else None
    if ext is None:
        return pruned_nearest(points, point_batch, ref, ref_batch, ref_offsets, max_memory)
    return ext.nearest_points(
        points.contiguous(), point_batch.contiguous(), ref.contiguous(), ref_offsets.long().contiguous()
    )


def bvh_nearest_single(points: Tensor, ref: Tensor) -> tuple[Tensor, Tensor, Tensor] | None:
    """Fused batch-of-one nearest reference point (nearest-single contract): ``(dists, idx, center)`` or ``None``.

    Finiteness check, centring, build, query and squared distances in one C++ call; the square root is torch's,
    so the result is bit-identical to the general path.
    ``None`` (the general path runs, and raises if a value is not finite) for non-CPU tensors, a missing compiler
    or non-finite values.
    """
    if points.device.type != "cpu" or points.dtype not in (torch.float32, torch.float64):
        return None
    ext = load_bvh()
    if ext is None:
        return None
    out = ext.nearest_single(points.contiguous(), ref.contiguous())
    if not out:
        return None
    return torch.sqrt(out[0]), out[1], out[2]


def bvh_closest_points(
    points: Tensor, verts: Tensor, faces: Tensor, face_idx: Tensor
) -> tuple[Tensor, Tensor, Tensor] | None:
    """Closest point on the selected faces without autograd, in C++: ``(sq_dists, bary, closest)`` or ``None``.

    Bit-identical to :func:`~torchmeshmetric.closest_point_on_triangle` on the selected faces (same operations,
    order and dtype; tested). ``None`` (the torch recomputation runs) off the CPU, for other dtypes, or while the
    extension is not compiled yet (a small call never triggers the compilation).
    """
    if points.device.type != "cpu" or points.dtype not in (torch.float32, torch.float64) or not bvh_ready():
        return None
    ext = load_bvh()
    if ext is None:
        return None
    out = ext.closest_points(points.contiguous(), verts.contiguous(), faces.long().contiguous(), face_idx.contiguous())
    return out[0], out[1], out[2]
