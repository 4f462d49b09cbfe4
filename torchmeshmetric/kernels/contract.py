"""The selection backends' contract: what a backend receives and returns (a leaf module of ``kernels``).

The backends (``kernels/accel/``) and the dispatch (``kernels/select.py``) both import these types from here, so
neither imports the other's module for them. The contract itself is written in ``kernels/select.py``'s docstring.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

from torch import Tensor

__all__ = ["FaceSet", "PointSet", "SelectionBackend"]


class FaceSet(NamedTuple):
    """Faces a backend selects from: centred, packed, detached.

    Attributes:
        verts: ``(V, 3)`` vertices, each item centred on the bounding box of the vertices its faces reference (rows no
            face references are never read, and may be far away or, after range scaling, not finite).
        faces: ``(F, 3)`` int64 rows of ``verts`` (global indices).
        batch: ``(F,)`` int64 item of each face.
        offsets: ``(B + 1,)`` int64 first face of each item.
    """

    verts: Tensor
    faces: Tensor
    batch: Tensor
    offsets: Tensor


class PointSet(NamedTuple):
    """Reference points a backend selects from: centred, packed, detached.

    Attributes:
        points: ``(R, 3)`` reference points, each item centred on its bounding box.
        batch: ``(R,)`` int64 item of each point.
        offsets: ``(B + 1,)`` int64 first point of each item.
    """

    points: Tensor
    batch: Tensor
    offsets: Tensor


class SelectionBackend(NamedTuple):
    """What a selection backend receives and returns (see the module docstring for the contract).

    Attributes:
        name: the ``backend=`` value.
        build_faces: ``(faces, tree) -> structure``; ``tree``: ``"sah"`` (spend more on the build for faster
            queries) or ``"morton"`` (cheapest build); a backend may have one kind only.
        refit_faces: ``(structure, moved faces) -> structure``.
        query_faces: ``(structure, faces, points, point_batch, max_memory) -> (P,) int64 face rows``.
        build_points: ``(ref) -> structure``.
        refit_points: ``(structure, moved ref) -> structure``.
        query_points: ``(structure, ref, points, point_batch, max_memory) -> (P,) int64 reference rows``.
        query_faces_closest: optional, ``(structure, faces, points, point_batch) -> (face_idx, sq_dists, bary,
            closest)``: the selection and the closest point on the selected face in one pass, bit-identical to
            ``query_faces`` followed by :func:`~torchmeshmetric.closest_point_on_triangle` without autograd.
        faces_area: optional, ``(structure) -> float``: the quality of a face structure, read on the host without
            waiting for a device (the summed surface areas of its node boxes over its roots', the surface-area
            heuristic's cost); :class:`~torchmeshmetric.kernels.select.Selector` rebuilds a refitted structure whose
            area has grown (a refit keeps the topology of its build: after large deformations its queries slow down).
        points_area: optional, ``(structure) -> float``: the same for a point structure.
    """

    name: str
    build_faces: Callable[[FaceSet, str], Any]
    refit_faces: Callable[[Any, FaceSet], Any]
    query_faces: Callable[[Any, FaceSet, Tensor, Tensor, int], Tensor]
    build_points: Callable[[PointSet], Any]
    refit_points: Callable[[Any, PointSet], Any]
    query_points: Callable[[Any, PointSet, Tensor, Tensor, int], Tensor]
    query_faces_closest: Callable[[Any, FaceSet, Tensor, Tensor], tuple[Tensor, Tensor, Tensor, Tensor]] | None = None
    faces_area: Callable[[Any], float] | None = None
    points_area: Callable[[Any], float] | None = None
