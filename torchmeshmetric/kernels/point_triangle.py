"""Exact point-to-triangle-mesh distance: the closest face selected, the closest point on it recomputed.

The per-triangle primitive (Ericson's seven Voronoi regions, exact for degenerate triangles) is
:mod:`torchmeshmetric.kernels.triangle`; :class:`~torchmeshmetric.MeshIndex` implements the mesh query, which this
function builds for one call.
"""

from __future__ import annotations

from collections.abc import Sequence

from torch import Tensor

from torchmeshmetric._checks import check_same_device, common_dtype
from torchmeshmetric.kernels._common import DEFAULT_MAX_MEMORY
from torchmeshmetric.kernels.mesh_index import PointMeshResult, measure_once, pack_mesh_args
from torchmeshmetric.structures import MeshLike, pack_points

__all__ = ["point_mesh_distance"]

Backend = str
"""``"auto"`` or a name of ``kernels.select.BACKENDS``: ``"bruteforce"``, ``"bvh"``, ``"pruned"``, ``"triton"``."""


def point_mesh_distance(
    points: Tensor | Sequence[Tensor],
    verts: Tensor | MeshLike | Sequence[MeshLike],
    faces: Tensor | None = None,
    *,
    points_lengths: Tensor | None = None,
    verts_lengths: Tensor | None = None,
    faces_lengths: Tensor | None = None,
    max_memory: int = DEFAULT_MAX_MEMORY,
    backend: Backend = "auto",
) -> PointMeshResult:
    """Exact Euclidean distance from every point to the surface of a triangle mesh (paper Eq. 4, exact).

    The closest face is selected without gradient (chunked; no intermediate exceeds ``max_memory``), then the
    closest point on that face is recomputed with autograd, so the result is differentiable w.r.t. ``points``
    and ``verts``. Gradients are finite at zero distance and for zero-area faces.

    Args:
        points: ``(P, 3)`` query points, a packed ``(sum P_b, 3)`` tensor with ``points_lengths``, or a list of
            ``(P_b, 3)`` tensors (one per mesh).
        verts: ``(V, 3)`` vertices (with ``faces``), packed vertices (with ``verts_lengths``/``faces_lengths``),
            or, with ``faces=None``, a mesh-like (:class:`~torchmeshmetric.Mesh`, ``(verts, faces)`` tuple,
            ``trimesh.Trimesh``) or a list of them.
        faces: ``(F, 3)`` integer faces; in a packed batch, indices are local to each item's vertices.
        points_lengths: ``(B,)`` points per item of a packed batch.
        verts_lengths: ``(B,)`` vertices per item of a packed batch.
        faces_lengths: ``(B,)`` faces per item of a packed batch.
        max_memory: upper bound in bytes of one intermediate of the selection pass (default 256 MiB).
        backend: ``"auto"`` (the fastest exact path for the device and size), ``"bvh"``, ``"triton"``, ``"pruned"`` or
            ``"bruteforce"``. To query the same mesh many times, build a :class:`~torchmeshmetric.MeshIndex` once.

    Returns:
        :class:`PointMeshResult` ``(dists, face_idx, bary, closest)``, in the promoted dtype of ``points`` and
        ``verts`` (float64 if either is; gradients come back in each input's own dtype). ``dists`` is the plain
        Euclidean distance, **not squared**. ``face_idx`` indexes the rows of the (packed) ``faces`` tensor: the face
        of least *computed* squared distance (bounding-box centred coordinates), the lowest index among equal ones;
        every backend selects the same face. Faces equidistant in exact arithmetic may compute differently in the
        last bit, and then the lower computed square wins, whatever its index.

    Raises:
        ShapeError, DTypeError, NonFiniteError, IndexRangeError, DeviceError, EmptyInputError: on bad input,
            naming the argument.

    Example:
        >>> import trimesh, torch
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> r = point_mesh_distance(torch.tensor([[0.0, 0.0, 3.0]]), sphere)
        >>> round(r.dists.item(), 6)
        2.0
    """
    packed = pack_mesh_args(verts, faces, verts_lengths, faces_lengths)
    pts = pack_points(points, points_lengths)
    check_same_device({"points": pts.points, "verts": packed.verts})
    dtype = common_dtype(pts.points.dtype, packed.verts.dtype)  # the dtype rule (docs/concepts.md, Precision)
    # measure_once scales extreme coordinates exactly (the mesh's, and far points' in a frame of their own) and
    # raises when distances overflow the dtype.
    points = pts.points.to(dtype)
    return measure_once(packed._replace(verts=packed.verts.to(dtype)), points, pts.lengths, backend, max_memory)
