"""Exact accelerated selection backends for the distance kernels (dispatched by :mod:`torchmeshmetric.kernels.select`).

- ``"bvh"``: C++ bounding volume hierarchy, compiled just in time and cached (CPU);
- ``"pruned"``: certified cluster pruning in plain torch ops (any device; CUDA, and the CPU without a compiler);
- ``"triton"``: implicit BVH built with torch ops, traversed by a Triton kernel (CUDA; on the CPU only in Triton's
  interpreter, ``TRITON_INTERPRET=1``). Triton is optional: it is imported on the first call of this backend.

Importing this package registers nothing: the one table of backends is ``select.BACKENDS``.
"""

from __future__ import annotations

from torchmeshmetric.kernels.accel.bvh import bvh_closest_points, bvh_nearest_single
from torchmeshmetric.kernels.accel.pruned import pruned_faces, pruned_nearest
from torchmeshmetric.kernels.accel.triton_backend import triton_available

__all__ = ["bvh_closest_points", "bvh_nearest_single", "pruned_faces", "pruned_nearest", "triton_available"]
