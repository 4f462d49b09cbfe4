"""The point cloud ``mm compare --mode pcc`` makes of a mesh: oriented reordering, then face subdivision."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError
from torchmeshmetric.mpeg.core import _float32 as f32
from torchmeshmetric.mpeg.core.point_cloud import PointCloud
from torchmeshmetric.mpeg.core.reindex import oriented_faces
from torchmeshmetric.mpeg.sampling.grid_sampling import mesh_arrays, unique_vertex_rows
from torchmeshmetric.mpeg.sampling.subdivision_rows import subdivision_rows
from torchmeshmetric.mpeg.sampling.texture import sample_texture
from torchmeshmetric.structures import MeshLike

__all__ = ["vertex_sample"]

_DBL_EPSILON = 2.220446049250313e-16


def zero_area_message(name: str, num_faces: int) -> str:
    """Why a mesh gave no point: all its faces are degenerate (mmetric skips faces of area below ``DBL_EPSILON``)."""
    return (
        f"{name}: no point was sampled: all {num_faces} face(s) have zero area (below DBL_EPSILON once the vertices "
        "are rounded to float32; MPEG sampling skips such faces), so the mesh has no surface to sample"
    )


def vertex_sample(
    mesh: MeshLike,
    *,
    texture: Any = None,
    uvs: Tensor | np.ndarray | None = None,
    colors: Tensor | np.ndarray | None = None,
    max_depth: int = 3,
    area_threshold: float = 2.0,
    name: str = "mesh",
) -> PointCloud:
    """Turn a mesh into the point cloud mmetric's ``compare --mode pcc`` measures (its ``sampleIfNeeded``).

    The mesh is reordered (equal corners merged, faces rotated to start at their smallest corner, duplicate faces
    dropped), degenerate faces (area below ``DBL_EPSILON``) skipped, and every face gives its three corners with the
    face normal; faces whose area is at least ``area_threshold`` (an *absolute* area in model units: a unit-scale mesh
    yields its vertices, an integer-scale one is subdivided) are split at their edge midpoints, recursively, at
    most ``max_depth - 1`` times, each new point with the normal of the face it splits. Colour comes from the texture
    (bilinear, at the point's UV) or from per-vertex colours; without a texture the points keep their UVs too (and
    the colours beside them). Points equal in position, normal, UV and colour are kept once; :func:`mpeg_compare`
    then merges equal positions.

    Args:
        mesh: the mesh (vertices rounded to float32 as mmetric reads them).
        texture: ``(H, W, 3)`` uint8 texture; needs ``uvs``.
        uvs: ``(F, 3, 2)`` texture coordinates per face corner.
        colors: ``(V, 3)`` per-vertex colours in ``[0, 255]``.
        max_depth: mmetric's maximum recursion depth (3).
        area_threshold: mmetric's subdivision area threshold (2.0).
        name: the mesh's name in error messages (``"ref"``, ``"dis"``, a file).

    Returns:
        :class:`PointCloud` with normals (and colours; UVs where there are UVs and no texture).

    Raises:
        EmptyInputError: the mesh has no face, or every face has zero area (nothing to sample).
        NonFiniteError: NaN or Inf vertices.

    Example:
        >>> import torch
        >>> tri = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> vertex_sample(tri).num_points
        3
        >>> vertex_sample((tri[0] * 4, tri[1])).num_points  # area 8 >= 2: split twice
        15
    """
    verts, faces = mesh_arrays(mesh)
    nf = faces.shape[0]
    pos = verts[faces].reshape(-1, 3)
    attrs = []  # corner attributes, UVs first: mmetric's reorder and ModelBuilder key on position, UV and colour
    if uvs is not None:  # with or without a texture
        attrs.append(np.asarray(uvs.detach().cpu().numpy() if isinstance(uvs, Tensor) else uvs, np.float32))
        attrs[0] = attrs[0].reshape(-1, 2)
    if colors is not None and (uvs is None or texture is None):  # a texture's colours replace the vertex colours
        c = np.asarray(colors.detach().cpu().numpy() if isinstance(colors, Tensor) else colors, np.float32)
        attrs.append(c[faces].reshape(-1, 3))
    attr = np.concatenate(attrs, axis=1) if attrs else None
    tri = oriented_faces(pos if attr is None else np.concatenate([pos, attr], axis=1))
    p1, p2, p3 = pos[tri[:, 0]], pos[tri[:, 1]], pos[tri[:, 2]]
    keep = f32.area(p1, p2, p3) >= _DBL_EPSILON
    if not keep.any():
        raise EmptyInputError(zero_area_message(name, nf))
    tri, p1, p2, p3 = tri[keep], p1[keep], p2[keep], p3[keep]
    corners = np.stack([p1, p2, p3], axis=1)
    width = 0 if attr is None else attr.shape[1]
    att3 = np.zeros((tri.shape[0], 3, 0), np.float32) if attr is None else attr[tri]
    points, normals, att = subdivision_rows(corners, att3.reshape(tri.shape[0], 3, width), max_depth, area_threshold)
    colours = point_uvs = None
    if uvs is not None and texture is not None:
        colours = sample_texture(texture, att, bilinear=True)
    elif uvs is not None:  # no map: the points keep their UVs, and their vertex colours (mmetric's pushVertex)
        point_uvs = att[:, :2]
        colours = att[:, 2:] if colors is not None else None
    elif colors is not None:
        colours = att
    key = colours if uvs is not None and texture is not None else att if width else None
    kept = unique_vertex_rows(points, normals, key)
    return PointCloud(
        torch.from_numpy(np.ascontiguousarray(points[kept])),
        torch.from_numpy(np.ascontiguousarray(normals[kept])),
        None if colours is None else torch.from_numpy(np.ascontiguousarray(colours[kept], dtype=np.float32)),
        None if point_uvs is None else torch.from_numpy(np.ascontiguousarray(point_uvs[kept], dtype=np.float32)),
    )
