"""The ``"triton"`` selection backend's entry points: Triton is imported on first use (it is optional).

See :mod:`torchmeshmetric.kernels.accel.triton_traversal` for the tree and the kernels, and
:mod:`torchmeshmetric.kernels.select` for the contract.
"""

from __future__ import annotations

import importlib
from functools import cache
from types import ModuleType
from typing import TYPE_CHECKING, Any

from torch import Tensor

if TYPE_CHECKING:
    from torchmeshmetric.kernels.contract import FaceSet, PointSet

__all__ = [
    "build_faces",
    "build_points",
    "query_faces",
    "query_points",
    "refit_faces",
    "refit_points",
    "triton_available",
]


@cache
def triton_available() -> bool:
    """Whether the optional ``triton`` package imports (checked once)."""
    try:
        importlib.import_module("triton")
    except Exception:  # ImportError, or a broken install failing at import time
        return False
    return True


def _module() -> ModuleType:
    if not triton_available():
        raise ImportError(
            "backend='triton' needs the optional triton package (pip install triton; CUDA builds of torch ship it)"
        )
    return importlib.import_module("torchmeshmetric.kernels.accel.triton_traversal")


def build_faces(faces: FaceSet, tree: str = "morton") -> Any:
    """Kept implicit BVH over centred faces (Morton order whatever ``tree``).

    Raises:
        ImportError: when triton is not installed.
        DeviceError: on non-CUDA tensors unless ``TRITON_INTERPRET=1`` (Triton's interpreter, for tests).
        DTypeError: for dtypes other than float32 / float64.
    """
    return _module().build_faces(faces.verts, faces.faces, faces.batch, faces.offsets)


def refit_faces(structure: Any, faces: FaceSet) -> Any:
    """Same tree, refitted to moved vertices."""
    return _module().refit_faces(structure, faces.verts, faces.faces, faces.batch, faces.offsets)


def query_faces(structure: Any, faces: FaceSet, points: Tensor, point_batch: Tensor, _max_memory: int = 0) -> Tensor:
    """Closest face per centred point (Triton traversal), exact, lowest index on ties."""
    # max_memory is unused: a tree query has no pairwise intermediate.
    return _module().query_faces(structure, points, point_batch, faces.offsets)


def build_points(ref: PointSet) -> Any:
    """Kept implicit BVH over centred reference points (raises as :func:`build_faces`)."""
    return _module().build_points(ref.points, ref.batch, ref.offsets)


def refit_points(structure: Any, ref: PointSet) -> Any:
    """Same tree, refitted to moved reference points."""
    return _module().refit_points(structure, ref.points, ref.batch, ref.offsets)


def query_points(structure: Any, ref: PointSet, points: Tensor, point_batch: Tensor, _max_memory: int = 0) -> Tensor:
    """Nearest reference row per centred point (Triton traversal), exact, lowest index on ties."""
    # max_memory is unused: a tree query has no pairwise intermediate.
    return _module().query_points(structure, points, point_batch, ref.offsets)
