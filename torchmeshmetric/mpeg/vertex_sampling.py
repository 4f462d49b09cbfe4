"""The point cloud ``mm compare --mode pcc`` makes of a mesh: oriented reordering, then face subdivision."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError
from torchmeshmetric.mpeg import _float32 as f32
from torchmeshmetric.mpeg.grid_sampling import mesh_arrays, unique_vertex_rows
from torchmeshmetric.mpeg.point_cloud import PointCloud
from torchmeshmetric.mpeg.reindex import oriented_faces
from torchmeshmetric.mpeg.texture import sample_texture
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
    mm_order: bool = False,
) -> PointCloud:
    """Turn a mesh into the point cloud mmetric's ``compare --mode pcc`` measures (its ``sampleIfNeeded``).

    The mesh is reordered (equal corners merged, faces rotated to start at their smallest corner, duplicate faces
    dropped), degenerate faces (area below ``DBL_EPSILON``) skipped, and every face gives its three corners with the
    face normal; faces whose area is at least ``area_threshold`` (an *absolute* area in model units: a unit-scale mesh
    yields its vertices, an integer-scale one is subdivided) are split at their edge midpoints, recursively, at
    most ``max_depth - 1`` times, each new point with the normal of the face it splits. Colour comes from the texture
    (bilinear, at the point's UV) or from per-vertex colours. Points equal in position, normal and colour are kept
    once; :func:`mpeg_compare` then merges equal positions.

    Args:
        mesh: the mesh (vertices rounded to float32 as mmetric reads them).
        texture: ``(H, W, 3)`` uint8 texture; needs ``uvs``.
        uvs: ``(F, 3, 2)`` texture coordinates per face corner.
        colors: ``(V, 3)`` per-vertex colours in ``[0, 255]``.
        max_depth: mmetric's maximum recursion depth (3).
        area_threshold: mmetric's subdivision area threshold (2.0).
        name: the mesh's name in error messages (``"ref"``, ``"dis"``, a file).
        mm_order: return the points in mmetric's order (face after face, each face's corners then its subdivision
            points depth first) instead of level by level; the set is the same. Figures that depend on the order,
            such as PCQM's (its k-d tree keeps the first of equidistant points), need it.

    Returns:
        :class:`PointCloud` with normals (and colours).

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
    keys = [pos]
    uv = col = None
    if texture is not None and uvs is not None:
        uv = np.asarray(uvs.detach().cpu().numpy() if isinstance(uvs, Tensor) else uvs, np.float32).reshape(-1, 2)
        keys.append(uv)
    elif colors is not None:
        c = np.asarray(colors.detach().cpu().numpy() if isinstance(colors, Tensor) else colors, np.float32)
        col = c[faces].reshape(-1, 3)
        keys.append(col)
    corner_keys = np.concatenate(keys, axis=1)
    tri = oriented_faces(corner_keys)
    p1, p2, p3 = pos[tri[:, 0]], pos[tri[:, 1]], pos[tri[:, 2]]
    keep = f32.area(p1, p2, p3) >= _DBL_EPSILON
    if not keep.any():
        raise EmptyInputError(zero_area_message(name, nf))
    tri, p1, p2, p3 = tri[keep], p1[keep], p2[keep], p3[keep]
    attr = uv if uv is not None else col
    empty = np.zeros((tri.shape[0], 0), np.float32)
    a1, a2, a3 = (empty, empty, empty) if attr is None else (attr[tri[:, 0]], attr[tri[:, 1]], attr[tri[:, 2]])
    normal = f32.normalize(f32.cross(p2 - p1, p3 - p1))
    out_pos = [np.stack([p1, p2, p3], axis=1).reshape(-1, 3)]
    out_nrm = [np.repeat(normal, 3, axis=0)]
    out_att = [np.stack([a1, a2, a3], axis=1).reshape(3 * a1.shape[0], a1.shape[1])]
    half = np.float32(0.5)
    depth = max_depth - 1
    # mmetric's push order, as sort keys: (face, path of child numbers + 1 padded with 0, slot); a node's points
    # come before its children's (pre-order), corners are slots 0-2 and a node's edge midpoints slots 3-5.
    levels = max(depth, 0)
    face_id = np.arange(tri.shape[0])
    path = np.zeros((tri.shape[0], levels), np.int8)
    keys_face = [np.repeat(face_id, 3)]
    keys_path = [np.repeat(path, 3, axis=0)]
    keys_slot = [np.tile(np.arange(3), tri.shape[0])]
    while depth > 0 and p1.shape[0] > 0:
        big = f32.area(p1, p2, p3) >= area_threshold
        p1, p2, p3 = p1[big], p2[big], p3[big]
        face_id, path = face_id[big], path[big]
        keys_face.append(np.repeat(face_id, 3))
        keys_path.append(np.repeat(path, 3, axis=0))
        keys_slot.append(np.tile(np.arange(3, 6), face_id.shape[0]))
        level = levels - depth
        children = []
        for child in range(4):
            sub = path.copy()
            if level + 1 < levels:
                sub[:, level] = child + 1
            children.append(sub)
        face_id, path = np.tile(face_id, 4), np.concatenate(children)
        nrm = f32.normalize(f32.cross(p2 - p1, p3 - p1))
        e1, e2, e3 = p1 * half + p2 * half, p2 * half + p3 * half, p3 * half + p1 * half
        out_pos.append(np.stack([e1, e2, e3], axis=1).reshape(-1, 3))
        out_nrm.append(np.repeat(nrm, 3, axis=0))
        a1, a2, a3 = a1[big], a2[big], a3[big]
        b1, b2, b3 = a1 * half + a2 * half, a2 * half + a3 * half, a3 * half + a1 * half
        out_att.append(np.stack([b1, b2, b3], axis=1).reshape(3 * b1.shape[0], b1.shape[1]))
        a1, a2, a3 = (np.concatenate(x) for x in ((b1, a1, b1, b2), (b2, b1, a2, a3), (b3, b3, b2, b3)))
        p1, p2, p3 = (np.concatenate(x) for x in ((e1, p1, e1, e2), (e2, e1, p2, p3), (e3, e3, e2, e3)))
        depth -= 1
    points = np.concatenate(out_pos)
    normals = np.concatenate(out_nrm)
    colours = None
    if attr is not None:
        att = np.concatenate(out_att)
        colours = sample_texture(texture, att, bilinear=True) if uv is not None else att
    if mm_order:
        path_cols = np.concatenate(keys_path)
        cols: list[np.ndarray] = [np.concatenate(keys_slot), *(path_cols[:, j] for j in reversed(range(levels)))]
        order = np.lexsort((*cols, np.concatenate(keys_face)))
        points, normals = points[order], normals[order]
        colours = None if colours is None else colours[order]
    kept = unique_vertex_rows(points, normals, colours)
    return PointCloud(
        torch.from_numpy(np.ascontiguousarray(points[kept])),
        torch.from_numpy(np.ascontiguousarray(normals[kept])),
        None if colours is None else torch.from_numpy(np.ascontiguousarray(colours[kept], dtype=np.float32)),
    )
