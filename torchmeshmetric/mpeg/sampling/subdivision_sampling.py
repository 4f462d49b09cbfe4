"""mmetric's subdivision sampling (``mm sample --mode sdiv``): face corners, then edge midpoints, recursively.

Every face of area at least ``DBL_EPSILON`` gives its three corners with the face normal; a face whose area is at
least ``area_threshold`` gives its three edge midpoints (``a * 0.5 + b * 0.5`` in float32, for positions, UVs and
colours) with its own normal and is split into four, down to ``max_depth - 1`` levels. mmetric recurses depth
first; the faces of one level are processed here together and the rows then put in mmetric's depth-first order
(:func:`~torchmeshmetric.mpeg.sampling.subdivision_rows.subdivision_rows`), so the points kept (the first of the
rows equal in position, UV, colour and normal) are mmetric's, in its order.
"""

from __future__ import annotations

import numpy as np
import torch

from torchmeshmetric._checks import EmptyInputError, check_allocation, check_flag
from torchmeshmetric.mpeg.core import _float32 as f32
from torchmeshmetric.mpeg.core.point_cloud import PointCloud
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh, as_textured_mesh
from torchmeshmetric.mpeg.sampling.grid_sampling import mesh_arrays, unique_vertex_rows
from torchmeshmetric.mpeg.sampling.subdivision_rows import subdivision_rows
from torchmeshmetric.mpeg.sampling.texture import sample_texture
from torchmeshmetric.mpeg.sampling.vertex_sampling import zero_area_message
from torchmeshmetric.structures import MeshLike

__all__ = ["builder_cloud", "corner_attributes", "subdivision_sample"]

# The working set per point, temporaries included (tracemalloc peak over the points kept, sdiv sampling of
# review X's sphere.obj, untextured: 27.9 M points, 128 bytes), so check_allocation refuses what would exhaust the
# memory available (24 bytes, the points' own float32 position and normal, let several times that through).
_BYTES_PER_POINT = 120

_DBL_EPSILON = 2.220446049250313e-16


def corner_attributes(mesh: TexturedMesh, faces: np.ndarray) -> np.ndarray:
    """``(F, 3, C)`` float32 corner UVs (``C = 2``), then per-vertex colours (``C = 3`` more); ``C = 0`` without either.

    The colours are left out under a texture (its colours replace them); UVs without a texture keep them, as
    mmetric's sampler interpolates both and its ``ModelBuilder`` keeps both.
    """
    attrs = [np.zeros((faces.shape[0], 3, 0), np.float32)]
    if mesh.uvs is not None:
        attrs.append(mesh.uvs.numpy().astype(np.float32))
    if mesh.colors is not None and (mesh.uvs is None or mesh.texture is None):
        attrs.append(mesh.colors.numpy().astype(np.float32)[faces])
    return np.concatenate(attrs, axis=2)


def subdivision_sample(
    mesh: TexturedMesh | MeshLike,
    *,
    max_depth: int = 100,
    area_threshold: float = 1.0,
    bilinear: bool = False,
    map_threshold: bool = False,
    name: str = "mesh",
) -> PointCloud:
    """Sample a mesh as ``mm sample --mode sdiv --maxDepth D --areaThreshold A [--bilinear] [--mapThreshold]`` does.

    Args:
        mesh: the mesh with its colour (e.g. from :func:`load_textured_mesh`); vertices are float32.
        max_depth: mmetric's ``--maxDepth`` (1 keeps only the corners).
        area_threshold: mmetric's ``--areaThreshold``, an absolute area in model units: faces at least this large
            are split.
        bilinear: bilinear texture filtering (mmetric ``--bilinear``), nearest otherwise.
        map_threshold: mmetric's ``--mapThreshold``: with a texture, a face is also split while its corners' texels
            (``int(u * W)``, ``int(v * H)``, clamped) are more than one texel apart in x or y.
        name: the mesh's name in error messages.

    Returns:
        :class:`PointCloud` with face normals (and colours): mmetric's points, in its order.

    Raises:
        ValueError: ``max_depth`` below 1 or ``area_threshold`` not positive and finite.
        EmptyInputError: every face has zero area.

    Example:
        >>> import torch
        >>> from torchmeshmetric.structures import Mesh
        >>> tri = Mesh(torch.tensor([[0.0, 0, 0], [4, 0, 0], [0, 4, 0]]), torch.tensor([[0, 1, 2]]))
        >>> subdivision_sample(TexturedMesh(tri), max_depth=3, area_threshold=2.0).num_points  # area 8, then 2
        15
    """
    bilinear = check_flag(bilinear, "bilinear")
    map_threshold = check_flag(map_threshold, "map_threshold")
    mesh = as_textured_mesh(mesh, name)  # a Mesh, (V, F) or trimesh too: no colour
    if isinstance(max_depth, bool) or not isinstance(max_depth, (int, np.integer)) or max_depth < 1:
        raise ValueError(f"max_depth: expected an integer >= 1, found {max_depth!r}")
    if not (np.isfinite(area_threshold) and area_threshold > 0):
        raise ValueError(f"area_threshold: expected a finite value > 0, found {area_threshold!r}")
    verts, faces = mesh_arrays(mesh.mesh)
    attr = corner_attributes(mesh, faces)
    p = verts[faces]
    keep = f32.area(p[:, 0], p[:, 1], p[:, 2]) >= _DBL_EPSILON
    if not keep.any():
        raise EmptyInputError(zero_area_message(name, faces.shape[0]))
    p, attr = p[keep], attr[keep]
    # each face is split until its parts are below area_threshold (or max_depth levels of 4): refused before the
    # split when that many points (a float32 position and normal each) cannot fit
    area = f32.area(p[:, 0], p[:, 1], p[:, 2]).astype(np.float64)
    count = min(float(area.sum()) / float(area_threshold), p.shape[0] * 4.0 ** min(int(max_depth), 500))
    check_allocation(count, _BYTES_PER_POINT, "area_threshold", area_threshold, f"points of {name}")
    texels = None
    if map_threshold and mesh.texture is not None and mesh.uvs is not None:
        texels = (int(mesh.texture.shape[1]), int(mesh.texture.shape[0]))
    points, normals, att = subdivision_rows(p, attr, max_depth, area_threshold, texels)
    return builder_cloud(mesh, points, normals, att, bilinear)


def builder_cloud(
    mesh: TexturedMesh, points: np.ndarray, normals: np.ndarray, att: np.ndarray, bilinear: bool
) -> PointCloud:
    """The rows mmetric's ``ModelBuilder`` keeps of pushed points with corner attributes ``att`` (UVs, colours).

    ``att`` is laid out as :func:`corner_attributes` gives it. The key is position, UV, colour and normal; UVs
    become texture colours (nearest or bilinear) when a texture is there, and are kept as the cloud's UVs otherwise
    (mmetric's ``pushVertex`` without a valid map), with the vertex colours where the mesh has them.
    """
    bilinear = check_flag(bilinear, "bilinear")
    colours = uvs = None
    key = att if att.shape[1] else None
    if mesh.uvs is not None and mesh.texture is not None:
        colours = sample_texture(mesh.texture, att, bilinear=bilinear)
        key = np.concatenate([att, colours], axis=1)
    elif mesh.uvs is not None:
        uvs = att[:, :2]
        colours = att[:, 2:] if mesh.colors is not None else None
    elif mesh.colors is not None:
        colours = att
    kept = unique_vertex_rows(points, normals, key)
    return PointCloud(
        torch.from_numpy(np.ascontiguousarray(points[kept])),
        torch.from_numpy(np.ascontiguousarray(normals[kept])),
        None if colours is None else torch.from_numpy(np.ascontiguousarray(colours[kept], dtype=np.float32)),
        None if uvs is None else torch.from_numpy(np.ascontiguousarray(uvs[kept], dtype=np.float32)),
    )
