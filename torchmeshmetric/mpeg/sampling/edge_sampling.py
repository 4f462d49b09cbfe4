"""mmetric's edge subdivision sampling (``mm sample --mode ediv``): split edges until they are short, no T-vertices.

Every face of area at least ``DBL_EPSILON`` gives its three corners with the face normal; then an edge is split
when half its length is at least the threshold (``length(b - a) * 0.5 >= L`` in float32), its midpoint
``(a + b) * 0.5`` pushed with the normal of the face being split, and the face replaced by the two, three or four
faces mmetric makes for that pattern of split edges, until no edge is split. The threshold is ``--lengthThreshold``
or, when that is 0, the largest side of the vertices' bounding box divided by ``--resolution``. mmetric recurses
depth first; one level of faces is processed here at a time, which yields the same set of distinct (position, UV,
colour, normal) rows but not mmetric's order.
"""

from __future__ import annotations

import numpy as np

from torchmeshmetric._checks import EmptyInputError, check_allocation, check_flag
from torchmeshmetric.mpeg.core import _float32 as f32
from torchmeshmetric.mpeg.core.point_cloud import PointCloud
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh, as_textured_mesh
from torchmeshmetric.mpeg.sampling.grid_sampling import mesh_arrays
from torchmeshmetric.mpeg.sampling.subdivision_sampling import builder_cloud, corner_attributes
from torchmeshmetric.mpeg.sampling.vertex_sampling import zero_area_message
from torchmeshmetric.structures import MeshLike

__all__ = ["edge_sample"]

# The working set per point, temporaries included (tracemalloc peak over the points kept, ediv sampling of
# review X's sphere.obj, untextured: 12.1 M points, 285 bytes), so check_allocation refuses what would exhaust the
# memory available (24 bytes, the points' own float32 position and normal, let several times that through).
_BYTES_PER_POINT = 280

_DBL_EPSILON = 2.220446049250313e-16

# The children of a face (v1 v2 v3) with midpoints (e1 e2 e3) = 3..5 per split pattern (split1 + 2 split2 + 4 split3),
# as mmetric lists them; corner indices 0..2 are v1..v3, 3..5 are e1..e3.
_CHILDREN = {
    7: [(3, 4, 5), (0, 3, 5), (3, 1, 4), (4, 2, 5)],
    6: [(0, 1, 5), (5, 1, 4), (4, 2, 5)],
    5: [(0, 3, 5), (3, 1, 5), (1, 2, 5)],
    3: [(0, 3, 2), (3, 4, 2), (3, 1, 4)],
    4: [(0, 1, 5), (1, 2, 5)],
    2: [(0, 1, 4), (0, 4, 2)],
    1: [(0, 3, 2), (3, 1, 2)],
}


def _length(mesh: TexturedMesh, verts: np.ndarray, length_threshold: float, resolution: int) -> np.float32:
    if not (np.isfinite(length_threshold) and length_threshold >= 0):
        raise ValueError(f"length_threshold: expected a finite value >= 0, found {length_threshold!r}")
    if length_threshold > 0:
        return np.float32(length_threshold)
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or resolution < 1:
        raise ValueError(f"resolution: expected an integer >= 1 (length_threshold is 0), found {resolution!r}")
    size = np.max(verts.max(axis=0) - verts.min(axis=0))
    length = np.float32(np.float32(size) / np.float32(resolution))
    if not length > 0:
        raise ValueError("the vertices' bounding box is a point; pass length_threshold > 0")
    return length


def edge_sample(
    mesh: TexturedMesh | MeshLike,
    *,
    length_threshold: float = 0.0,
    resolution: int = 1024,
    bilinear: bool = False,
    name: str = "mesh",
) -> PointCloud:
    """Sample a mesh as ``mm sample --mode ediv [--lengthThreshold L | --resolution R] [--bilinear]`` does.

    Args:
        mesh: the mesh with its colour (e.g. from :func:`load_textured_mesh`); vertices are float32.
        length_threshold: mmetric's ``--lengthThreshold`` (model units); 0 takes it from ``resolution``.
        resolution: mmetric's ``--resolution``: the threshold is the box's largest side / ``resolution``.
        bilinear: bilinear texture filtering (mmetric ``--bilinear``), nearest otherwise.
        name: the mesh's name in error messages.

    Returns:
        :class:`PointCloud` with face normals (and colours): mmetric's points, in another order.

    Raises:
        ValueError: a negative or non-finite threshold, ``resolution`` below 1 when it is used, a flat box.
        EmptyInputError: every face has zero area.

    Example:
        >>> import torch
        >>> from torchmeshmetric.structures import Mesh
        >>> tri = Mesh(torch.tensor([[0.0, 0, 0], [2, 0, 0], [0, 2, 0]]), torch.tensor([[0, 1, 2]]))
        >>> edge_sample(TexturedMesh(tri), length_threshold=1.0).num_points  # corners + 3 midpoints, then stop
        6
    """
    bilinear = check_flag(bilinear, "bilinear")
    mesh = as_textured_mesh(mesh, name)  # a Mesh, (V, F) or trimesh too: no colour
    verts, faces = mesh_arrays(mesh.mesh)
    length = _length(mesh, verts, length_threshold, resolution)
    attr = corner_attributes(mesh, faces)
    p = verts[faces]
    keep = f32.area(p[:, 0], p[:, 1], p[:, 2]) >= _DBL_EPSILON
    if not keep.any():
        raise EmptyInputError(zero_area_message(name, faces.shape[0]))
    p, attr = p[keep], attr[keep]
    # every triangle left has edges below 2 * length, so at most sqrt(3) * length^2 of area: at least a quarter of
    # the area over length^2 points (a float32 position and normal each), refused before the loop when that cannot fit
    count = float(f32.area(p[:, 0], p[:, 1], p[:, 2]).astype(np.float64).sum()) / float(length) ** 2 / 4
    option = ("length_threshold", length_threshold) if length_threshold > 0 else ("resolution", resolution)
    check_allocation(count, _BYTES_PER_POINT, option[0], option[1], f"points of {name}")
    normal = f32.normalize(f32.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    out_pos, out_att = [p.reshape(-1, 3)], [attr.reshape(3 * attr.shape[0], attr.shape[2])]
    out_nrm = [np.repeat(normal, 3, axis=0)]
    half = np.float32(0.5)
    while p.shape[0]:
        nrm = f32.normalize(f32.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
        d = p[:, [1, 1, 2]] - p[:, [0, 2, 0]]  # v2 - v1, v2 - v3, v3 - v1, as mmetric measures them
        split = np.sqrt(f32.dot(d, d)) * half >= length
        ep = (p + p[:, [1, 2, 0]]) * half
        ea = (attr + attr[:, [1, 2, 0]]) * half
        out_pos.append(ep[split])
        out_att.append(ea[split])
        out_nrm.append(np.broadcast_to(nrm[:, None], ep.shape)[split])
        pattern = split[:, 0] * 1 + split[:, 1] * 2 + split[:, 2] * 4
        corners_p, corners_a = np.concatenate([p, ep], axis=1), np.concatenate([attr, ea], axis=1)
        kids_p, kids_a = [], []
        for code, kids in _CHILDREN.items():
            sel = pattern == code
            for kid in kids:
                kids_p.append(corners_p[sel][:, list(kid)])
                kids_a.append(corners_a[sel][:, list(kid)])
        p, attr = np.concatenate(kids_p), np.concatenate(kids_a)
    return builder_cloud(mesh, np.concatenate(out_pos), np.concatenate(out_nrm), np.concatenate(out_att), bilinear)
