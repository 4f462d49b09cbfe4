"""Exact accelerated selection backends for the distance kernels (registered on import).

- ``"bvh"``: C++ bounding volume hierarchy, compiled just in time and cached (CPU);
- ``"pruned"``: certified cluster pruning in plain torch ops (any device; CUDA, and the CPU without a compiler);
- ``"triton"``: implicit BVH built with torch ops, traversed by a Triton kernel (CUDA; on the CPU only in Triton's
  interpreter, ``TRITON_INTERPRET=1``). Triton is optional: it is imported on the first call of this backend.

``backend="auto"`` (see :func:`auto_face_backend` / :func:`auto_nearest_backend`) picks ``"bvh"`` for CPU tensors of
any size once the C++ extension is compiled (it is faster than the brute force from ten points on); until then, and
on other devices, it keeps the brute force for problems below :data:`MIN_PAIRS` point-primitive pairs (they never
pay the compilation) and above picks ``"bvh"`` on the CPU, ``"triton"`` on CUDA when Triton imports (float32 /
float64), ``"pruned"`` otherwise. The choice is documented in ``docs/acceleration.md``.
"""

from __future__ import annotations

import importlib
from functools import cache
from types import ModuleType

import torch
from torch import Tensor

from torchmeshmetric.kernels.accel._extension import bvh_ready
from torchmeshmetric.kernels.accel.bvh import bvh_closest_points, bvh_faces, bvh_nearest, bvh_nearest_single
from torchmeshmetric.kernels.accel.pruned import pruned_faces, pruned_nearest
from torchmeshmetric.kernels.nearest import register_nearest_backend
from torchmeshmetric.kernels.point_triangle import register_face_backend, register_nograd_closest

__all__ = [
    "MIN_PAIRS",
    "auto_face_backend",
    "auto_nearest_backend",
    "bvh_closest_points",
    "bvh_faces",
    "bvh_nearest",
    "bvh_nearest_single",
    "pruned_faces",
    "pruned_nearest",
    "triton_available",
    "triton_faces",
    "triton_nearest",
]

MIN_PAIRS = 1 << 20
"""Below this many point-primitive pairs ``backend="auto"`` keeps the brute force: tiny problems never pay the
one-time compilation of the C++ extension (see docs/acceleration.md)."""


@cache
def triton_available() -> bool:
    """Whether the optional ``triton`` package imports (checked once)."""
    try:
        importlib.import_module("triton")
    except Exception:  # ImportError, or a broken install failing at import time
        return False
    return True


def _triton_module() -> ModuleType:
    if not triton_available():
        raise ImportError(
            "backend='triton' needs the optional triton package (pip install triton; CUDA builds of torch ship it)"
        )
    return importlib.import_module("torchmeshmetric.kernels.accel.triton_traversal")


def triton_faces(
    points: Tensor,
    point_batch: Tensor,
    verts: Tensor,
    faces: Tensor,
    face_batch: Tensor,
    face_offsets: Tensor,
    max_memory: int,
) -> Tensor:
    """Closest face per point by the Triton BVH traversal (face-selector contract), exact, lowest index on ties.

    Raises:
        ImportError: when triton is not installed.
        DeviceError: on non-CUDA tensors unless ``TRITON_INTERPRET=1`` (Triton's interpreter, for tests).
        DTypeError: for dtypes other than float32 / float64.
    """
    module = _triton_module()
    return module.triton_faces(points, point_batch, verts, faces, face_batch, face_offsets, max_memory)


def triton_nearest(
    points: Tensor, point_batch: Tensor, ref: Tensor, ref_batch: Tensor, ref_offsets: Tensor, max_memory: int
) -> Tensor:
    """Nearest reference point per point by the Triton BVH traversal (nearest-selector contract), exact.

    Raises:
        ImportError: when triton is not installed.
        DeviceError: on non-CUDA tensors unless ``TRITON_INTERPRET=1`` (Triton's interpreter, for tests).
        DTypeError: for dtypes other than float32 / float64.
    """
    module = _triton_module()
    return module.triton_nearest(points, point_batch, ref, ref_batch, ref_offsets, max_memory)


def _auto(points: Tensor, num_prims: int, dtype: torch.dtype) -> str | None:
    if points.device.type == "cpu" and bvh_ready():
        return "bvh"  # compiled already: faster than the brute force at every size (docs/acceleration.md)
    if points.shape[0] * num_prims < MIN_PAIRS:
        return None
    if points.device.type == "cpu":
        return "bvh"
    if points.device.type == "cuda" and dtype in (torch.float32, torch.float64) and triton_available():
        return "triton"
    return "pruned"


def auto_face_backend(points: Tensor, verts: Tensor, faces: Tensor) -> str | None:
    """``backend="auto"`` rule for :func:`~torchmeshmetric.point_mesh_distance`: a backend name or ``None``."""
    return _auto(points, faces.shape[0], torch.promote_types(points.dtype, verts.dtype))


def auto_nearest_backend(points: Tensor, ref: Tensor) -> str | None:
    """``backend="auto"`` rule for :func:`~torchmeshmetric.nearest_vertex_distance`: a backend name or ``None``."""
    return _auto(points, ref.shape[0], torch.promote_types(points.dtype, ref.dtype))


register_face_backend("bvh", bvh_faces, auto=auto_face_backend)
register_nograd_closest(bvh_closest_points)
register_face_backend("pruned", pruned_faces)
register_nearest_backend("bvh", bvh_nearest, auto=auto_nearest_backend, single=bvh_nearest_single)
register_nearest_backend("pruned", pruned_nearest)
register_face_backend("triton", triton_faces)
register_nearest_backend("triton", triton_nearest)
