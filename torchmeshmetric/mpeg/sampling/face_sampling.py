"""mmetric's face sampling (``mm sample --mode face``): points stepped along two edges of every face.

Each face ``(v1, v2, v3)`` (area at least ``DBL_EPSILON``) gives the points ``v1 + s * e12 + t * e23`` where
``e12``, ``e23`` are the unit edge directions, ``s`` runs over ``0, step, 2 step, ... <= |v2 - v1|`` and ``t`` over
``0, step, ... <= s / |v2 - v1| * |v3 - v2|``, with ``step`` = the largest side of the vertices' bounding box divided
by ``resolution``. mmetric advances ``s`` and ``t`` by repeated float32 additions; those sums are the same for every
face, so they are computed once and each face takes a prefix of them -- every coordinate is then mmetric's, bit for
bit (float32 operations in glm's order, no fused multiply-add). With ``thickness > 0`` the points are also stepped
along the face normal. Colour comes from the texture (nearest, or bilinear) at the interpolated UV, or from
interpolated per-vertex colours. Points equal in position, normal and colour are kept once, as mmetric's
``ModelBuilder`` keeps them.
"""

from __future__ import annotations

import numpy as np
import torch

from torchmeshmetric._checks import EmptyInputError, check_allocation, check_flag
from torchmeshmetric.mpeg.core import _float32 as f32
from torchmeshmetric.mpeg.core.point_cloud import PointCloud
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh, as_textured_mesh
from torchmeshmetric.mpeg.sampling.grid_sampling import mesh_arrays, unique_vertex_rows
from torchmeshmetric.mpeg.sampling.texture import sample_texture
from torchmeshmetric.mpeg.sampling.vertex_sampling import zero_area_message
from torchmeshmetric.structures import MeshLike

__all__ = ["face_sample"]

# The working set per point, temporaries included (tracemalloc peak over the points kept, face sampling of
# review X's sphere.obj, untextured: 8.9 M points, 101 bytes), so check_allocation refuses what would exhaust the
# memory available (24 bytes, the points' own float32 position and normal, let several times that through).
_BYTES_PER_POINT = 96

_DBL_EPSILON = 2.220446049250313e-16


def _float32_steps(step: np.float32, limit: float) -> np.ndarray:
    """``0, step, step + step, ...`` summed in float32 one addition at a time, while ``<= limit``."""
    out = []
    s = np.float32(0.0)
    while s <= limit:
        out.append(s)
        s = np.float32(s + step)
    return np.array(out, dtype=np.float32)


def _normal_offsets(step: np.float32, thickness: float) -> np.ndarray:
    """The offsets along the normal: ``-b, -b + step, ... <= b`` with ``b`` its float32 border distance."""
    border = np.float32(0.0)
    while border <= thickness:
        border = np.float32(border + step)
    border = np.float32(border - step)
    out = []
    s = np.float32(-border)
    while s <= border:
        out.append(s)
        s = np.float32(s + step)
    return np.array(out, dtype=np.float32)


def _normal_offsets_count(step: np.float32, thickness: float) -> float:
    """About how many offsets :func:`_normal_offsets` makes (``2 * thickness / step + 1``), without making them."""
    return 2.0 * float(thickness) / float(step) + 1.0


def _check(resolution: int, thickness: float) -> None:
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or resolution < 1:
        raise ValueError(f"resolution: expected an integer >= 1, found {resolution!r}")
    if not np.isfinite(thickness) or thickness < 0:
        raise ValueError(f"thickness: expected a finite value >= 0, found {thickness!r}")


def face_sample(
    mesh: TexturedMesh | MeshLike,
    *,
    resolution: int = 1024,
    thickness: float = 0.0,
    bilinear: bool = False,
    name: str = "mesh",
) -> PointCloud:
    """Sample a mesh as ``mm sample --mode face --resolution R [--thickness T] [--bilinear]`` does.

    Args:
        mesh: the mesh with its colour (e.g. from :func:`load_textured_mesh`); vertices are float32 as mmetric
            reads them.
        resolution: steps along the largest side of the vertices' bounding box (mmetric ``--resolution``).
        thickness: distance to the face sampled on either side along its normal (mmetric ``--thickness``).
        bilinear: bilinear texture filtering (mmetric ``--bilinear``), nearest otherwise.
        name: the mesh's name in error messages.

    Returns:
        :class:`PointCloud` with face normals (and colours): the points mmetric writes, in its order.

    Raises:
        ValueError: ``resolution`` below 1, a negative or non-finite ``thickness``, a flat bounding box.
        EmptyInputError: every face has zero area.

    Example:
        >>> import torch
        >>> from torchmeshmetric.structures import Mesh
        >>> tri = Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [1, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> face_sample(TexturedMesh(tri), resolution=2).num_points  # s in {0, .5, 1}: 1 + 2 + 3 points
        6
    """
    bilinear = check_flag(bilinear, "bilinear")
    mesh = as_textured_mesh(mesh, name)  # a Mesh, (V, F) or trimesh too: no colour
    _check(resolution, thickness)
    resolution = int(resolution)  # a numpy integer too
    verts, faces = mesh_arrays(mesh.mesh)
    size = np.max(verts.max(axis=0) - verts.min(axis=0)) if verts.size else np.float32(0)
    step = np.float32(np.float32(size) / np.float32(resolution))
    if not step > 0:
        raise ValueError(f"{name}: the vertices' bounding box is a point; face sampling needs a step > 0")
    p1, p2, p3 = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    keep = f32.area(p1, p2, p3) >= _DBL_EPSILON
    if not keep.any():
        raise EmptyInputError(zero_area_message(name, faces.shape[0]))
    p1, p2, p3 = p1[keep], p2[keep], p3[keep]
    normal = f32.normalize(f32.cross(p2 - p1, p3 - p1))
    d12, d23 = p2 - p1, p3 - p2
    l12, l23 = np.sqrt(f32.dot(d12, d12)), np.sqrt(f32.dot(d23, d23))
    e12, e23 = d12 / l12[:, None], d23 / l23[:, None]
    # the rows below hold about (l12 / step + 1) * (l23 / step + 1) / 2 points a face, at least a float32 position and
    # normal each: refused before any allocation (or the float32 loop of steps) when that cannot fit
    per_face = (l12.astype(np.float64) / step + 1) * (l23.astype(np.float64) / step + 1) / 2
    count = float(per_face.sum()) * _normal_offsets_count(step, thickness)
    if thickness == 0:
        check_allocation(count, _BYTES_PER_POINT, "resolution", resolution, f"points of {name}")
    else:
        check_allocation(count, _BYTES_PER_POINT, "resolution, thickness", (resolution, thickness), f"points of {name}")
    steps = _float32_steps(step, float(max(l12.max(), l23.max())))
    # rows (face, i): s = steps[i] <= l12; then (face, i, j): t = steps[j] <= s / l12 * l23
    n12 = np.searchsorted(steps, l12, side="right")
    fi = np.repeat(np.arange(l12.size), n12)
    i = np.arange(fi.size) - np.repeat(np.cumsum(n12) - n12, n12)
    a = steps[i] / l12[fi]
    n23 = np.searchsorted(steps, a * l23[fi], side="right")
    f = np.repeat(fi, n23)
    a = np.repeat(a, n23)
    s = np.repeat(steps[i], n23)
    j = np.arange(f.size) - np.repeat(np.cumsum(n23) - n23, n23)
    t = steps[j]
    b = t / l23[f]
    base = (p1[f] + s[:, None] * e12[f]) + t[:, None] * e23[f]
    offsets = _normal_offsets(step, thickness)
    points = (
        np.concatenate([base + o * normal[f] for o in offsets]) if offsets.size != 1 else base + offsets[0] * normal[f]
    )
    k = offsets.size
    normals = np.tile(normal[f], (k, 1))
    colours = _colours(mesh, keep, f, a, b, bilinear)
    if colours is not None:
        colours = np.tile(colours, (k, 1))
    # mmetric's loop nests the normal offset innermost: order the rows as (face, s, t, offset)
    order = np.arange(points.shape[0]).reshape(k, -1).T.reshape(-1)
    points, normals = points[order], normals[order]
    colours = None if colours is None else colours[order]
    kept = unique_vertex_rows(points, normals, colours)
    return PointCloud(
        torch.from_numpy(np.ascontiguousarray(points[kept])),
        torch.from_numpy(np.ascontiguousarray(normals[kept])),
        None if colours is None else torch.from_numpy(np.ascontiguousarray(colours[kept])),
    )


def _colours(
    mesh: TexturedMesh, keep: np.ndarray, f: np.ndarray, a: np.ndarray, b: np.ndarray, bilinear: bool
) -> np.ndarray | None:
    """Colours at the samples: ``c1 + a * (c2 - c1) + b * (c3 - c2)`` of corner UVs (then texture) or colours."""
    if mesh.uvs is not None and mesh.texture is not None:
        corners = mesh.uvs.numpy().astype(np.float32)[keep]
    elif mesh.colors is not None:
        corners = mesh.colors.numpy().astype(np.float32)[mesh.mesh.faces.numpy()][keep]
    else:
        return None
    c1, c2, c3 = corners[f, 0], corners[f, 1], corners[f, 2]
    values = (c1 + a[:, None] * (c2 - c1)) + b[:, None] * (c3 - c2)
    if mesh.uvs is not None and mesh.texture is not None:
        return sample_texture(mesh.texture, values, bilinear=bilinear)
    return values.astype(np.float32)
