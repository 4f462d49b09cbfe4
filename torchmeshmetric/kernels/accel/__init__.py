"""Exact accelerated selection backends for the distance kernels (registered on import).

- ``"bvh"``: C++ bounding volume hierarchy, compiled just in time and cached (CPU);
- ``"pruned"``: certified cluster pruning in plain torch ops (any device; CUDA, and the CPU without a compiler).

``backend="auto"`` (see :func:`auto_face_backend` / :func:`auto_nearest_backend`) keeps the brute force for small
problems, where it is fast and needs no compilation, and picks ``"bvh"`` on the CPU and ``"pruned"`` elsewhere
above :data:`MIN_PAIRS` point-primitive pairs. The choice is documented in ``docs/acceleration.md``.
"""

from __future__ import annotations

from torch import Tensor

from torchmeshmetric.kernels.accel.bvh import bvh_faces, bvh_nearest, bvh_nearest_single
from torchmeshmetric.kernels.accel.pruned import pruned_faces, pruned_nearest
from torchmeshmetric.kernels.nearest import register_nearest_backend
from torchmeshmetric.kernels.point_triangle import register_face_backend

__all__ = [
    "MIN_PAIRS",
    "auto_face_backend",
    "auto_nearest_backend",
    "bvh_faces",
    "bvh_nearest",
    "bvh_nearest_single",
    "pruned_faces",
    "pruned_nearest",
]

MIN_PAIRS = 1 << 20
"""Below this many point-primitive pairs ``backend="auto"`` keeps the brute force: tiny problems never pay the
one-time compilation of the C++ extension (see docs/acceleration.md)."""


def _auto(points: Tensor, num_prims: int) -> str | None:
    if points.shape[0] * num_prims < MIN_PAIRS:
        return None
    return "bvh" if points.device.type == "cpu" else "pruned"


def auto_face_backend(points: Tensor, verts: Tensor, faces: Tensor) -> str | None:
    """``backend="auto"`` rule for :func:`~torchmeshmetric.point_mesh_distance`: a backend name or ``None``."""
    return _auto(points, faces.shape[0])


def auto_nearest_backend(points: Tensor, ref: Tensor) -> str | None:
    """``backend="auto"`` rule for :func:`~torchmeshmetric.nearest_vertex_distance`: a backend name or ``None``."""
    return _auto(points, ref.shape[0])


register_face_backend("bvh", bvh_faces, auto=auto_face_backend)
register_face_backend("pruned", pruned_faces)
register_nearest_backend("bvh", bvh_nearest, auto=auto_nearest_backend, single=bvh_nearest_single)
register_nearest_backend("pruned", pruned_nearest)
