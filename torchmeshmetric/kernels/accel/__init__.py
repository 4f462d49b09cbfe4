"""Exact accelerated selection backends for the distance kernels (dispatched by :mod:`torchmeshmetric.kernels.select`).

- ``"bvh"``: C++ bounding volume hierarchy, compiled just in time and cached (CPU);
- ``"pruned"``: certified cluster pruning in plain torch ops (any device; CUDA, and the CPU without a compiler);
- ``"triton"``: implicit BVH built with torch ops, traversed by a Triton kernel (CUDA; on the CPU only in Triton's
  interpreter, ``TRITON_INTERPRET=1``). Triton is optional: it is imported on the first call of this backend.

Importing this package registers nothing: the one table of backends is ``select.BACKENDS``.
"""

from torchmeshmetric._lazy import attach

# Every name loads on first use: __init__.pyi lists them (for this loader, mypy and IDEs) and their modules.
__getattr__, __dir__, __all__ = attach(__name__, __file__)
