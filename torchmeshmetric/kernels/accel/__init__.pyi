"""The names of ``torchmeshmetric.kernels.accel``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import bruteforce as bruteforce
from . import bvh as bvh
from . import lbvh as lbvh
from . import pruned as pruned
from . import triton_backend as triton_backend
from . import triton_traversal as triton_traversal
from .bvh import bvh_closest_points, bvh_nearest_single
from .pruned import pruned_faces, pruned_nearest
from .triton_backend import triton_available

__all__ = [
    "bvh_closest_points",
    "bvh_nearest_single",
    "pruned_faces",
    "pruned_nearest",
    "triton_available",
]
