"""CPU selection structures backed by the C++ BVH extension (``bvh.cpp``): build once, refit, query.

A structure is the list of tensors the extension returns (nodes, roots, slot order, slot data, pruning slack); see
:mod:`torchmeshmetric.kernels.select` for the contract. Callers resolve ``"bvh"`` to ``"pruned"`` when the extension
cannot be compiled, so these functions assume it loads.
"""

from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING

import torch
from torch import Tensor

from torchmeshmetric import native

if TYPE_CHECKING:
    from torchmeshmetric.kernels.contract import FaceSet, PointSet

__all__ = [
    "build_faces",
    "build_points",
    "faces_area",
    "points_area",
    "bvh_closest_points",
    "bvh_nearest_single",
    "query_faces",
    "query_faces_closest",
    "query_points",
    "refit_faces",
    "refit_points",
]


def _ext() -> ModuleType:
    ext = native.try_load("bvh")
    if ext is None:  # resolve_backend never hands out "bvh" then
        raise RuntimeError("bvh: the C++ extension is not available")
    return ext


def build_faces(faces: FaceSet, tree: str) -> list[Tensor]:
    """Face hierarchy (one per item) over centred faces: ``tree="sah"`` binned SAH, ``"morton"`` Morton splits.

    The SAH tree answers queries ~25 % faster and costs ~10x the Morton build (docs/acceleration.md).
    """
    return _ext().face_bvh_build(
        faces.verts.contiguous(), faces.faces.contiguous(), faces.offsets.contiguous(), tree == "sah"
    )


def refit_faces(structure: list[Tensor], faces: FaceSet) -> list[Tensor]:
    """Bounds, face records and slack of ``structure`` rewritten in place for moved vertices (same tree)."""
    _ext().face_bvh_refit(structure, faces.verts.contiguous(), faces.faces.contiguous(), faces.offsets.contiguous())
    return structure


def faces_area(structure: list[Tensor]) -> float:
    """Summed half surface areas of the node boxes over the roots' (the SAH cost of the tree; a few microseconds)."""
    return float(_ext().face_bvh_area(structure))


def query_faces(
    structure: list[Tensor], faces: FaceSet, points: Tensor, point_batch: Tensor, _max_memory: int = 0
) -> Tensor:
    """Closest face per centred point, exact, lowest index among equal squared distances."""
    # max_memory is unused: a tree query has no pairwise intermediate.
    points, point_batch, offsets = points.contiguous(), point_batch.contiguous(), faces.offsets.contiguous()
    return _ext().face_bvh_query(structure, points, point_batch, offsets, False)[0]


def query_faces_closest(
    structure: list[Tensor], faces: FaceSet, points: Tensor, point_batch: Tensor
) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """:func:`query_faces` and the closest points on the selected faces in one pass: ``(face_idx, sq, bary, closest)``.

    Bit-identical to :func:`query_faces` followed by :func:`bvh_closest_points` (the closest point is computed from
    the vertices in the face block the traversal has just read: no second pass over the faces).
    """
    points, point_batch, offsets = points.contiguous(), point_batch.contiguous(), faces.offsets.contiguous()
    face_idx, sq, bary, closest = _ext().face_bvh_query(structure, points, point_batch, offsets, True)
    return face_idx, sq, bary, closest


def build_points(ref: PointSet) -> list[Tensor]:
    """Point hierarchy (one per item) over centred reference points."""
    return _ext().point_bvh_build(ref.points.contiguous(), ref.offsets.contiguous())


def refit_points(structure: list[Tensor], ref: PointSet) -> list[Tensor]:
    """Bounds, sorted points and slack of ``structure`` rewritten in place for moved points (same tree)."""
    _ext().point_bvh_refit(structure, ref.points.contiguous(), ref.offsets.contiguous())
    return structure


def points_area(structure: list[Tensor]) -> float:
    """Summed half surface areas of the node boxes over the roots' (as :func:`faces_area`)."""
    return float(_ext().point_bvh_area(structure))


def query_points(
    structure: list[Tensor], ref: PointSet, points: Tensor, point_batch: Tensor, _max_memory: int = 0
) -> Tensor:
    """Nearest reference row per centred point, exact, lowest index among equal squared distances."""
    # max_memory is unused: a tree query has no pairwise intermediate.
    return _ext().point_bvh_query(structure, points.contiguous(), point_batch.contiguous())


def bvh_nearest_single(points: Tensor, ref: Tensor) -> tuple[Tensor, Tensor, Tensor] | None:
    """Fused batch-of-one nearest reference point (one-off calls): ``(dists, idx, center)`` or ``None``.

    Finiteness check, centring, build, query and squared distances in one C++ call; the square root is torch's,
    so the result is bit-identical to the general path.
    ``None`` (the general path runs, and raises if a value is not finite) for non-CPU tensors, a missing compiler
    or non-finite values.

    Args:
        points: ``(P, 3)`` query points, float32 or float64 (another dtype or device: ``None``).
        ref: ``(R, 3)`` reference points, same dtype.

    Returns:
        ``(dists, idx, center)``: ``(P,)`` Euclidean distance to the nearest reference point, ``(P,)`` int64 its
        row (lowest among equal distances), ``(3,)`` the centre of ``ref``'s bounding box the search ran centred
        on; or ``None`` as above.

    Example:
        >>> import torch
        >>> ref = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 0, 5]], dtype=torch.float64)
        >>> out = bvh_nearest_single(torch.tensor([[0.0, 0, 1], [0.0, 0, 3.5]], dtype=torch.float64), ref)
        >>> out is None or (out[0].tolist(), out[1].tolist(), out[2].tolist())  # None without a C++ compiler
        ([1.0, 1.5], [0, 2], [0.5, 0.0, 2.5])
    """
    if points.device.type != "cpu" or points.dtype not in (torch.float32, torch.float64):
        return None
    ext = native.try_load("bvh")
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
    order and dtype; tested). ``None`` (the torch recomputation runs) off the CPU, for other dtypes, or where the
    extension cannot be built (fixed for the process: see :mod:`torchmeshmetric.native`).

    Args:
        points: ``(P, 3)`` query points, float32 or float64.
        verts: ``(V, 3)`` vertices, same dtype.
        faces: ``(F, 3)`` faces (rows of ``verts``).
        face_idx: ``(P,)`` the face selected for each point (rows of ``faces``).

    Returns:
        ``(sq_dists, bary, closest)``: ``(P,)`` squared distance to the closest point of the selected face,
        ``(P, 3)`` its barycentric coordinates and ``(P, 3)`` the point; or ``None`` as above.

    Raises:
        RuntimeError: a ``face_idx`` outside ``[0, F)`` (a selection backend that broke its contract).

    Example:
        >>> import torch
        >>> verts = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=torch.float64)
        >>> points = torch.tensor([[0.25, 0.25, 1.0]], dtype=torch.float64)
        >>> out = bvh_closest_points(points, verts, torch.tensor([[0, 1, 2]]), torch.tensor([0]))
        >>> out is None or (out[0].tolist(), out[1].tolist(), out[2].tolist())  # None without a C++ compiler
        ([1.0], [[0.5, 0.25, 0.25]], [[0.25, 0.25, 0.0]])
    """
    if points.device.type != "cpu" or points.dtype not in (torch.float32, torch.float64):
        return None
    ext = native.try_load("bvh")
    if ext is None:
        return None
    # The C++ loop reads faces[face_idx] unchecked: a selection that broke its contract must not read out of bounds.
    if face_idx.numel():
        lo, hi = (int(v) for v in face_idx.aminmax())
        if lo < 0 or hi >= faces.shape[0]:
            raise RuntimeError(
                f"bvh_closest_points: selected face indices outside [0, {faces.shape[0]}) (min {lo}, max {hi}): "
                "a selection backend broke its contract; please report it"
            )
    out = ext.closest_points(points.contiguous(), verts.contiguous(), faces.long().contiguous(), face_idx.contiguous())
    return out[0], out[1], out[2]
