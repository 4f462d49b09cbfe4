"""mmetric's "pseudo-random" sampling (``mm sample --mode prnd``): a fixed low-discrepancy sequence per face.

Not random at all: mmetric takes, for every face of area at least ``DBL_EPSILON``, its three corners and then
``ceil(N * area / total area) - 1`` points ``o + x d0 + y d1`` of the R2 sequence (``x, y`` the fractional parts of
``i g`` and ``i g^2``, ``g = 1 / 1.32471795572`` the plastic number's inverse, folded into the triangle when
``x + y > 1``), with ``o`` the corner opposite the longest edge. The total area is summed in double in face order
(degenerate faces included), everything else in float32 as glm computes it, so the points are mmetric's bit for bit
and in its order. mmetric gives the inner points no per-vertex colour (they are black); with a texture they take
the texel at their UV. Points equal in position, UV, colour and normal are kept once.
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

__all__ = ["prnd_sample"]

# The working set per point, temporaries included (tracemalloc peak over the points kept, prnd sampling of
# review X's sphere.obj, untextured: 2.0 M points, 177 bytes), so check_allocation refuses what would exhaust the
# memory available (24 bytes, the points' own float32 position and normal, let several times that through).
_BYTES_PER_POINT = 176

_DBL_EPSILON = 2.220446049250313e-16
_G = np.float32(np.float32(1.0) / np.float32(1.32471795572))
_G2 = np.float32(_G * _G)


def _origin_and_edges(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per face, mmetric's (origin corner, first, second) corner indices: the origin faces the longest edge."""
    d = p[:, [1, 2, 0]] - p[:, [0, 1, 2]]  # v2 - v1, v3 - v2, v1 - v3
    d12, d23, d31 = np.sqrt(f32.dot(d, d)).T
    first = (d12 >= d23) & (d12 >= d31)
    second = ~first & (d31 >= d23)
    origin = np.where(first, 2, np.where(second, 1, 0))
    a = np.where(first | second, 0, 1)
    b = np.where(first, 1, 2)
    return origin, a, b


def prnd_sample(
    mesh: TexturedMesh | MeshLike, *, num_samples: int = 2000000, bilinear: bool = False, name: str = "mesh"
) -> PointCloud:
    """Sample a mesh as ``mm sample --mode prnd --nbSamples N [--bilinear]`` does.

    Args:
        mesh: the mesh with its colour (e.g. from :func:`load_textured_mesh`); vertices are float32.
        num_samples: mmetric's ``--nbSamples``, the target count (corners and duplicates make the result differ).
        bilinear: bilinear texture filtering (mmetric ``--bilinear``), nearest otherwise.
        name: the mesh's name in error messages.

    Returns:
        :class:`PointCloud` with face normals (and colours), mmetric's points in its order.

    Raises:
        ValueError: ``num_samples`` below 1.
        EmptyInputError: every face has zero area.

    Example:
        >>> import torch
        >>> from torchmeshmetric.structures import Mesh
        >>> tri = Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> prnd_sample(TexturedMesh(tri), num_samples=10).num_points  # 3 corners + 9 inner points
        12
    """
    bilinear = check_flag(bilinear, "bilinear")
    mesh = as_textured_mesh(mesh, name)  # a Mesh, (V, F) or trimesh too: no colour
    if isinstance(num_samples, bool) or not isinstance(num_samples, (int, np.integer)) or num_samples < 1:
        raise ValueError(f"num_samples: expected an integer >= 1, found {num_samples!r}")
    num_samples = int(num_samples)  # a numpy integer too
    # before any int64 count can wrap
    check_allocation(num_samples, _BYTES_PER_POINT, "num_samples", num_samples, "points")
    verts, faces = mesh_arrays(mesh.mesh)
    attr = corner_attributes(mesh, faces)
    p = verts[faces]
    area = f32.area(p[:, 0], p[:, 1], p[:, 2])
    total = np.cumsum(area)[-1] if area.size else 0.0  # mmetric's running double sum, in face order
    keep = area >= _DBL_EPSILON
    if not keep.any():
        raise EmptyInputError(zero_area_message(name, faces.shape[0]))
    p, attr, area = p[keep], attr[keep], area[keep]
    nf = p.shape[0]
    normal = f32.normalize(f32.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    inner = np.maximum(np.ceil(float(num_samples) * area / total).astype(np.int64) - 1, 0)
    face = np.repeat(np.arange(nf), inner)
    i = (np.arange(face.size) - np.repeat(np.cumsum(inner) - inner, inner) + 1).astype(np.float32)
    r1, r2 = i * _G, i * _G2
    x, y = r1 - np.floor(r1), r2 - np.floor(r2)
    fold = (x + y) > np.float32(1.0)
    x, y = np.where(fold, np.float32(1.0) - x, x), np.where(fold, np.float32(1.0) - y, y)
    o, a, b = (k[face] for k in _origin_and_edges(p))
    pf, af = p[face], attr[face]
    rows = np.arange(face.size)
    po, ao = pf[rows, o], af[rows, o]
    pos = (po + x[:, None] * (pf[rows, a] - po)) + y[:, None] * (pf[rows, b] - po)
    att = (ao + x[:, None] * (af[rows, a] - ao)) + y[:, None] * (af[rows, b] - ao)
    # mmetric interpolates the inner points' UVs but leaves their vertex colour at zero (with or without UVs)
    att[:, 0 if mesh.uvs is None else 2 :] = 0
    # mmetric's order: per face its three corners, then its inner points
    order = np.argsort(np.concatenate([np.repeat(np.arange(nf), 3), face]), kind="stable")
    points = np.concatenate([p.reshape(-1, 3), pos])[order]
    normals = np.concatenate([np.repeat(normal, 3, axis=0), normal[face]])[order]
    atts = np.concatenate([attr.reshape(3 * nf, attr.shape[2]), att])[order]
    return builder_cloud(mesh, points, normals, atts, bilinear)
