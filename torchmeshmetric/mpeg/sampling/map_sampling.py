"""mmetric's texture-map sampling (``mm sample --mode map``): one point per texel whose centre lies in a face's UVs.

For each face of area at least ``DBL_EPSILON``, the texels ``(i, j)`` of the integer box
``int((W - 1) * uv_min) .. int((W - 1) * uv_max)`` (and the same with ``H``) are visited; a texel centre
``((i + 0.5) / W, (j + 0.5) / H)`` inside the face's UV triangle (mmetric's barycentric test, float32) gives the
point at the same barycentric coordinates on the face, with the face normal and the texel's colour (nearest).
Points equal in position, UV, colour and normal are kept once; the order is mmetric's. A face whose UV box starts
below 0 gives no point (mmetric's unsigned loop counter wraps and the loop does not run).
"""

from __future__ import annotations

import numpy as np
import torch

from torchmeshmetric._checks import EmptyInputError
from torchmeshmetric.mpeg.core import _float32 as f32
from torchmeshmetric.mpeg.core.point_cloud import PointCloud
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh, as_textured_mesh
from torchmeshmetric.mpeg.sampling.grid_sampling import mesh_arrays, unique_vertex_rows
from torchmeshmetric.mpeg.sampling.texture import sample_texture
from torchmeshmetric.mpeg.sampling.vertex_sampling import zero_area_message
from torchmeshmetric.structures import MeshLike

__all__ = ["map_sample"]

_DBL_EPSILON = 2.220446049250313e-16


def _texel_boxes(uv: np.ndarray, w: int, h: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per face the first texel and the texel counts along u and v (0 where mmetric's loop does not run)."""
    size = np.array([w - 1, h - 1], np.float32)
    lo = (size * uv.min(axis=1)).astype(np.int64)  # float -> int32 truncates toward zero, as glm's conversion
    hi = (size * uv.max(axis=1)).astype(np.int64)
    count = np.where(lo >= 0, np.maximum(hi - lo + 1, 0), 0)
    return lo[:, 0], lo[:, 1], count[:, 0], count[:, 1]


#: Candidate texels per run of faces (:func:`map_sample`): ~400 MB of arrays at a time.
_CHUNK = 1 << 22


def _runs(count: np.ndarray, budget: int) -> list[tuple[int, int]]:
    """Consecutive face ranges ``[a, b)`` of at most ``budget`` candidates each (a face above it: alone)."""
    ends = np.cumsum(count)
    out, a = [], 0
    while a < count.size:
        before = ends[a - 1] if a else 0
        b = max(int(np.searchsorted(ends, before + budget, side="right")), a + 1)
        out.append((a, b))
        a = b
    return out


def _face_texels(
    p: np.ndarray, uv: np.ndarray, normal: np.ndarray, boxes: list[np.ndarray], w: int, h: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The points, normals and texel centres (UVs) of faces ``p`` whose texel centres lie in their UV triangles."""
    i0, j0, ni, nj = boxes
    count = ni * nj
    face = np.repeat(np.arange(p.shape[0]), count)
    local = np.arange(face.size) - np.repeat(np.cumsum(count) - count, count)
    i = i0[face] + local // nj[face]  # i outer, j inner, as mmetric loops
    j = j0[face] + local % nj[face]
    t = np.stack(
        [
            (np.float32(0.5) + i.astype(np.float32)) / np.float32(w),
            (np.float32(0.5) + j.astype(np.float32)) / np.float32(h),
        ],
        axis=1,
    )
    a, b, c = uv[face, 0], uv[face, 1], uv[face, 2]
    v0, v1, v2 = b - a, c - a, t - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
        v = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    one = np.float32(1.0)
    inside = (u >= 0) & (u <= 1) & (v >= 0) & (v <= 1) & (u + v <= 1)
    face, t, u, v = face[inside], t[inside], u[inside, None], v[inside, None]
    pf = p[face]
    return (pf[:, 0] * ((one - u) - v) + pf[:, 1] * u) + pf[:, 2] * v, normal[face], t


def map_sample(mesh: TexturedMesh | MeshLike, *, name: str = "mesh") -> PointCloud:
    """Sample a textured mesh as ``mm sample --mode map`` does.

    Args:
        mesh: a mesh with UVs and a texture (e.g. from :func:`load_textured_mesh`); vertices are float32.
        name: the mesh's name in error messages.

    Returns:
        :class:`PointCloud` with face normals, texel colours and the texel centres as UVs (the `vt` rows of mmetric's
            OBJ), mmetric's points in its order.

    Raises:
        ValueError: the mesh has no UVs or no texture.
        EmptyInputError: every face has zero area.

    Example:
        >>> import numpy as np, torch
        >>> from torchmeshmetric.structures import Mesh
        >>> tri = Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> uvs = torch.tensor([[[0.0, 0], [1, 0], [0, 1]]])
        >>> map_sample(TexturedMesh(tri, uvs, np.zeros((4, 4, 3), np.uint8))).num_points  # 4 + 3 + 2 + 1 texels
        10
    """
    mesh = as_textured_mesh(mesh, name)  # a Mesh, (V, F) or trimesh too: no colour
    if mesh.uvs is None or mesh.texture is None:
        raise ValueError(
            f"{name}: map sampling needs UVs and a texture; found {'no UVs' if mesh.uvs is None else 'no texture'}"
        )
    verts, faces = mesh_arrays(mesh.mesh)
    p, uv = verts[faces], mesh.uvs.numpy().astype(np.float32)
    keep = f32.area(p[:, 0], p[:, 1], p[:, 2]) >= _DBL_EPSILON
    if not keep.any():
        raise EmptyInputError(zero_area_message(name, faces.shape[0]))
    p, uv = p[keep], uv[keep]
    normal = f32.normalize(f32.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    h, w = mesh.texture.shape[:2]
    boxes = _texel_boxes(uv, w, h)
    # The candidate texels (each face's UV box) in runs of faces of at most _CHUNK candidates: the arrays of one run
    # take ~100 bytes a candidate, so UV boxes of hundreds of millions of texels (UVs not in [0, 1]) stay within
    # memory; the runs are in face order, so the points are mmetric's, in its order.
    runs = [
        _face_texels(p[a:b], uv[a:b], normal[a:b], [x[a:b] for x in boxes], w, h)
        for a, b in _runs(boxes[2] * boxes[3], _CHUNK)
    ]
    points, normals, t = (np.concatenate([r[k] for r in runs]) for k in range(3))
    del runs  # the runs' arrays, copied above: not held through the deduplication
    colours = sample_texture(mesh.texture, t, bilinear=False)
    kept = unique_vertex_rows(points, normals, np.concatenate([t, colours], axis=1))
    return PointCloud(
        torch.from_numpy(np.ascontiguousarray(points[kept])),
        torch.from_numpy(np.ascontiguousarray(normals[kept])),
        torch.from_numpy(np.ascontiguousarray(colours[kept])),
        torch.from_numpy(np.ascontiguousarray(t[kept], dtype=np.float32)),  # mmetric keeps the texel UVs (OBJ vt)
    )
