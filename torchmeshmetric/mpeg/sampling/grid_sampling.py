"""mmetric's ``sample --mode grid``: the points where axis-aligned rays on a regular grid cross the surface."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric import native
from torchmeshmetric._checks import EmptyInputError, NonFiniteError, available_memory, check_flag, check_int
from torchmeshmetric.mpeg.core import _float32 as f32
from torchmeshmetric.mpeg.core.fixed_point import fixed_point_box, fixed_point_ceil
from torchmeshmetric.mpeg.core.point_cloud import PointCloud
from torchmeshmetric.structures import MeshLike, as_mesh

__all__ = [
    "BoxError",
    "GridHits",
    "GridSamples",
    "GridTooLargeError",
    "check_box",
    "fixed_point_box",
    "fixed_point_ceil",
    "grid_hits",
    "grid_sample",
    "grid_sample_faces",
    "mesh_arrays",
    "mesh_box",
    "unique_vertex_rows",
]

_DBL_EPSILON = 2.220446049250313e-16
_FP16 = np.float32(1 << 16)
_ZERO_TOLERANCE = np.float32(1e-6)
_CHUNK = 1 << 21  # ray-triangle pairs per vectorised step (a few tens of MB of float32 temporaries)


class BoxError(ValueError):
    """A sampling box that is malformed or does not contain the mesh.

    Example:
        >>> import torch
        >>> tri = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> from torchmeshmetric.mpeg import mpeg_metrics
        >>> try:
        ...     mpeg_metrics(tri, tri, box=([0.5, 0, 0], [1, 1, 1]), grid_size=8)
        ... except BoxError as error:  # a ValueError too
        ...     print(str(error).split(" (")[0])
        box: [[0.5, 0.0, 0.0], [1.0, 1.0, 1.0]] does not contain the reference mesh
    """


def mesh_box(verts: np.ndarray | Tensor) -> tuple[np.ndarray, np.ndarray]:
    """The float32 bounding box of a mesh's vertices (mmetric's ``computeBBox``).

    Args:
        verts: ``(V, 3)`` vertices (numpy or a tensor; rounded to float32 as mmetric reads them), ``V >= 1``.

    Returns:
        ``(min, max)``, two ``(3,)`` float32 arrays.

    Example:
        >>> lo, hi = mesh_box(np.array([[0, 1, 2], [3, -1, 5]], np.float32))
        >>> lo.tolist(), hi.tolist()
        ([0.0, -1.0, 2.0], [3.0, 1.0, 5.0])
    """
    v = verts.detach().cpu().numpy() if isinstance(verts, Tensor) else np.asarray(verts)
    v = v.astype(np.float32)
    return v.min(axis=0), v.max(axis=0)


def mesh_arrays(mesh: MeshLike) -> tuple[np.ndarray, np.ndarray]:
    """A mesh as mmetric reads it: float32 vertices ``(V, 3)`` and int64 faces ``(F, 3)`` (numpy, CPU).

    Raises:
        EmptyInputError: the mesh has no face.
        NonFiniteError: NaN or Inf vertices.

    Example:
        >>> import torch
        >>> v, f = mesh_arrays((torch.eye(3, dtype=torch.float64), torch.tensor([[0, 1, 2]])))
        >>> v.dtype, f.shape
        (dtype('float32'), (1, 3))
    """
    m = as_mesh(mesh)
    if m.faces.shape[0] == 0:
        raise EmptyInputError("mesh: expected at least one face, found none")
    verts = m.verts.detach().cpu().numpy().astype(np.float32)
    if not np.isfinite(verts).all():
        raise NonFiniteError("mesh: vertex positions hold NaN or Inf")
    return verts, m.faces.detach().cpu().numpy()


def _main_axes(normal: np.ndarray) -> np.ndarray:
    """The ``useNormal`` axis of mmetric: the largest ``|n|`` component, with its tie rules (x before y before z)."""
    a = np.abs(normal)
    x_main = (a[:, 0] >= a[:, 1]) & (a[:, 0] >= a[:, 2])
    y_main = (a[:, 1] >= a[:, 0]) & (a[:, 1] >= a[:, 2])
    return np.where(x_main, 0, np.where(y_main, 1, 2))


def check_box(box: tuple[Any, Any], verts: np.ndarray | Tensor, name: str = "box") -> tuple[np.ndarray, np.ndarray]:
    """Validate a sampling box ``(min, max)`` and require that it contains ``verts``.

    Raises:
        BoxError: wrong shape, non-finite corners, ``max < min``, or vertices outside the box.

    Example:
        >>> lo, hi = check_box(([0, 0, 0], [1, 1, 1]), np.zeros((1, 3), np.float32))
        >>> hi.tolist()
        [1.0, 1.0, 1.0]
    """
    lo, hi = _parse_box(box, name)
    vlo, vhi = mesh_box(verts)
    if (vlo < lo).any() or (vhi > hi).any():
        raise BoxError(
            f"{name}: [{lo.tolist()}, {hi.tolist()}] does not contain the reference mesh (its box is "
            f"[{vlo.tolist()}, {vhi.tolist()}])"
        )
    return lo, hi


def _parse_box(box: tuple[Any, Any], name: str = "box") -> tuple[np.ndarray, np.ndarray]:
    lo = np.asarray(box[0], dtype=np.float32).reshape(-1)
    hi = np.asarray(box[1], dtype=np.float32).reshape(-1)
    if lo.shape != (3,) or hi.shape != (3,):
        raise BoxError(f"{name}: expected two corners of 3 coordinates, found shapes {lo.shape} and {hi.shape}")
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        raise BoxError(f"{name}: corners must be finite, found {lo.tolist()} and {hi.tolist()}")
    if (hi < lo).any():
        raise BoxError(f"{name}: max corner {hi.tolist()} is below min corner {lo.tolist()}")
    if not (hi > lo).any():
        raise BoxError(f"{name}: the box is a single point {lo.tolist()}")
    return lo, hi


def grid_sample(
    mesh: MeshLike,
    grid_size: int = 1024,
    *,
    use_normal: bool = True,
    box: tuple[Sequence[float] | np.ndarray | Tensor, Sequence[float] | np.ndarray | Tensor] | None = None,
    texture: Any = None,
    uvs: Tensor | np.ndarray | None = None,
    colors: Tensor | np.ndarray | None = None,
    bilinear: bool = True,
    use_fixed_point: bool = False,
) -> PointCloud:
    """Sample a mesh on a grid exactly as ``mm sample --mode grid`` does (the V-DMC common test conditions).

    Rays parallel to the axes are cast from a regular grid of ``grid_size`` steps over the longest side of ``box``
    (step ``range / (grid_size - 1)``); each ray that crosses a triangle (Moller-Trumbore, mmetric's float32
    arithmetic) gives a point with the triangle's normal. With ``use_normal`` only rays along the axis closest to
    the triangle's normal are cast (the CTC setting). Degenerate triangles (area below ``DBL_EPSILON``) are skipped,
    points equal in position, normal and colour are kept once. The result is what mmetric writes, before the
    comparison merges points with equal positions (:func:`merge_duplicate_points`).

    Args:
        mesh: the mesh (float vertices are rounded to float32 as mmetric reads them).
        grid_size: grid steps over the box's longest side (``>= 2``).
        use_normal: cast only along the axis closest to each triangle's normal (mmetric ``--useNormal``).
        box: ``(min, max)`` corners of the sampling box (the grid's origin and extent); default the mesh's bounding
            box. The CTC passes the reference's box for both meshes; a distorted mesh may reach outside it (its
            points there are still sampled, as mmetric does). :func:`check_box` checks a box against a reference.
        texture: an ``(H, W, 3)`` uint8 texture image; needs ``uvs``.
        uvs: ``(F, 3, 2)`` texture coordinates per face corner.
        colors: ``(V, 3)`` per-vertex colours in ``[0, 255]`` (used without a texture).
        bilinear: bilinear texture filtering (mmetric ``--bilinear``), nearest otherwise.
        use_fixed_point: mmetric ``--useFixedPoint`` (the CTC setting; needs ``box``): the box's min corner is
            rounded down and its max corner up to a multiple of 1/65536, and so is the grid step (up).

    Returns:
        :class:`PointCloud` with normals (and colours when the mesh has some).

    Raises:
        ValueError: ``grid_size < 2``.
        TypeError: ``grid_size`` is not an int (numpy's and one-element integer tensors are), or a flag not a bool.
        EmptyInputError: the mesh has no face.
        BoxError: a malformed box (wrong shape, non-finite, max below min, a single point).
        GridTooLargeError: the expected number of samples (the triangles' projected areas over the squared step)
            cannot fit in the memory available; raised before any ray is cast. Rays are cast in chunks of a few
            million, so the memory used is the samples' plus a bounded working set.

    Example:
        >>> import torch
        >>> tri = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> grid_sample(tri, 3, box=([0, 0, 0], [1, 1, 1])).num_points
        6
    """
    use_normal = check_flag(use_normal, "use_normal")
    bilinear = check_flag(bilinear, "bilinear")
    use_fixed_point = check_flag(use_fixed_point, "use_fixed_point")
    return _grid_samples(mesh, grid_size, use_normal, box, texture, uvs, colors, bilinear, use_fixed_point).cloud


class GridSamples(NamedTuple):
    """A grid sampling's cloud and the face each of its points lies on (:func:`grid_sample_faces`).

    Attributes:
        cloud: what :func:`grid_sample` returns.
        face_idx: ``(N,)`` the face of every point of ``cloud`` (index into the mesh's faces; a point that several
            faces produced keeps the first, in mmetric's push order).

    Example:
        >>> import torch
        >>> tri = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> g = grid_sample_faces(tri, 3, box=([0, 0, 0], [1, 1, 1]))
        >>> g.cloud.num_points, g.face_idx.tolist()
        (6, [0, 0, 0, 0, 0, 0])
    """

    cloud: PointCloud
    face_idx: np.ndarray


def grid_sample_faces(
    mesh: MeshLike,
    grid_size: int = 1024,
    *,
    use_normal: bool = True,
    box: tuple[Sequence[float] | np.ndarray | Tensor, Sequence[float] | np.ndarray | Tensor] | None = None,
    texture: Any = None,
    uvs: Tensor | np.ndarray | None = None,
    colors: Tensor | np.ndarray | None = None,
    bilinear: bool = True,
    use_fixed_point: bool = False,
) -> GridSamples:
    """:func:`grid_sample` (the same arguments and cloud) with the face of every point, for per-face maps.

    Args:
        mesh: the mesh, as for :func:`grid_sample`.
        grid_size: grid steps over the box's longest side (``>= 2``).
        use_normal: cast only along the axis closest to each triangle's normal.
        box: ``(min, max)`` corners of the sampling box; default the mesh's bounding box.
        texture: an ``(H, W, 3)`` uint8 texture image; needs ``uvs``.
        uvs: ``(F, 3, 2)`` texture coordinates per face corner.
        colors: ``(V, 3)`` per-vertex colours in ``[0, 255]``.
        bilinear: bilinear texture filtering, nearest otherwise.
        use_fixed_point: mmetric ``--useFixedPoint`` (needs ``box``).

    Returns:
        :class:`GridSamples`: :func:`grid_sample`'s cloud and the face of each of its points.

    Raises:
        The errors of :func:`grid_sample`.

    Example:
        >>> import torch
        >>> tri = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> grid_sample_faces(tri, 3, box=([0, 0, 0], [1, 1, 1])).face_idx.tolist()
        [0, 0, 0, 0, 0, 0]
    """
    use_normal = check_flag(use_normal, "use_normal")
    bilinear = check_flag(bilinear, "bilinear")
    use_fixed_point = check_flag(use_fixed_point, "use_fixed_point")
    return _grid_samples(mesh, grid_size, use_normal, box, texture, uvs, colors, bilinear, use_fixed_point)


def _grid_samples(
    mesh: MeshLike,
    grid_size: int,
    use_normal: bool,
    box: Any,
    texture: Any,
    uvs: Any,
    colors: Any,
    bilinear: bool,
    use_fixed_point: bool,
) -> GridSamples:
    from torchmeshmetric.mpeg.sampling.texture import sample_texture

    hits = grid_hits(mesh, grid_size, use_normal=use_normal, box=box, use_fixed_point=use_fixed_point)
    pos, nrm, face, bary = hits.points, hits.normals, hits.face_idx, hits.bary
    faces = hits.faces
    col = None
    if texture is not None and uvs is not None:
        fuv = np.asarray(uvs.detach().cpu().numpy() if isinstance(uvs, Tensor) else uvs, dtype=np.float32)[face]
        u, v = bary[:, 0], bary[:, 1]
        w = (np.float32(1.0) - u) - v
        uv = (fuv[:, 0] * w[:, None] + fuv[:, 1] * u[:, None]) + fuv[:, 2] * v[:, None]
        col = sample_texture(texture, uv, bilinear=bilinear)
    elif colors is not None:
        c = np.asarray(colors.detach().cpu().numpy() if isinstance(colors, Tensor) else colors, dtype=np.float32)
        fc = c[faces[face]]
        u, v = bary[:, 0], bary[:, 1]
        w = (np.float32(1.0) - u) - v
        col = (fc[:, 0] * w[:, None] + fc[:, 1] * u[:, None]) + fc[:, 2] * v[:, None]
    kept = unique_vertex_rows(pos, nrm, col)
    cloud = PointCloud(
        torch.from_numpy(np.ascontiguousarray(pos[kept])),
        torch.from_numpy(np.ascontiguousarray(nrm[kept])),
        None if col is None else torch.from_numpy(np.ascontiguousarray(col[kept], dtype=np.float32)),
    )
    return GridSamples(cloud, face[kept])


class GridHits(NamedTuple):
    """Every ray-triangle hit of a grid sampling, in mmetric's push order (before removing repeated points).

    Attributes:
        points: ``(H, 3)`` float32 hit points.
        normals: ``(H, 3)`` float32 normals of the hit faces.
        face_idx: ``(H,)`` hit face (index into the mesh's faces).
        axis: ``(H,)`` ray axis (0, 1, 2).
        origin: ``(H, 3)`` float32 ray origins.
        bary: ``(H, 2)`` float32 barycentric ``(u, v)`` of the hit on its face (weights of corners 1 and 2).
        faces: ``(F, 3)`` the mesh's faces (numpy).

    Example:
        >>> import torch
        >>> tri = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> h = grid_hits(tri, 3, box=([0, 0, 0], [1, 1, 1]))  # a flat triangle: only the z rays hit it
        >>> h.points.shape, h.axis.tolist(), h.face_idx.tolist(), bool((h.points[:, 2] == 0).all())
        ((6, 3), [2, 2, 2, 2, 2, 2], [0, 0, 0, 0, 0, 0], True)
    """

    points: np.ndarray
    normals: np.ndarray
    face_idx: np.ndarray
    axis: np.ndarray
    origin: np.ndarray
    bary: np.ndarray
    faces: np.ndarray


class _Entries(NamedTuple):
    """Per (face, axis) entry of the grid: the face, its rays and the ray-independent part of Moller-Trumbore."""

    fid: np.ndarray  # (F',) original index of every kept (non-degenerate) face
    v1: np.ndarray  # (F', 3) first vertex of every kept face
    normal: np.ndarray  # (F', 3) unit normals (float32, mmetric's arithmetic)
    face: np.ndarray  # (E,) kept face of every entry
    axis: np.ndarray  # (E,) ray axis of every entry
    n3: np.ndarray  # (E,) rays along the third axis
    rays: np.ndarray  # (E,) rays of the entry
    starts: np.ndarray  # (E + 1,) first ray of every entry in mmetric's push order
    e1: np.ndarray  # (E, 3) edges v2 - v1 and v3 - v1
    e2: np.ndarray
    e2b: np.ndarray  # (E,) the two components of e2 across the ray axis
    e2c: np.ndarray
    inv_det: np.ndarray  # (E,) 1 / determinant
    live: np.ndarray  # (E,) determinant outside mmetric's zero tolerance
    lmin: np.ndarray  # (E, 3) first grid line of the face's box
    main_origin: np.ndarray  # (E,) origin of the entry's rays along their axis


def _entries(verts: np.ndarray, faces: np.ndarray, min_box: np.ndarray, max_box: np.ndarray, step: np.ndarray,
             use_normal: bool) -> _Entries:  # fmt: skip
    v1, v2, v3 = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    keep = f32.area(v1, v2, v3) >= _DBL_EPSILON
    fid = np.flatnonzero(keep)
    v1, v2, v3 = v1[keep], v2[keep], v3[keep]
    normal = f32.normalize(f32.cross(v2 - v1, v3 - v1))
    tmin = np.minimum(np.minimum(v1, v2), v3)
    tmax = np.maximum(np.maximum(v1, v2), v3)
    with np.errstate(divide="ignore", invalid="ignore"):
        lmin = np.floor((tmin - min_box) / step)
        lmax = np.ceil((tmax - min_box) / step)
    lcnt = lmax - lmin

    if use_normal:
        face_ax = [(np.arange(fid.size), _main_axes(normal))]
    else:
        face_ax = [(np.arange(fid.size), np.full(fid.size, a)) for a in range(3)]
    # Interleave the axes per face (mmetric loops axes inside its face loop), so first occurrences keep its order.
    f_list = np.concatenate([fa[0] for fa in face_ax])
    a_list = np.concatenate([fa[1] for fa in face_ax])
    order = np.argsort(f_list, kind="stable")
    f_list, a_list = f_list[order], a_list[order]
    second = np.where(a_list == 0, 1, 0)
    third = np.where(a_list == 2, 1, 2)
    flat_box = min_box == max_box
    ok = ~(flat_box[second] | flat_box[third])
    f_list, a_list, second, third = f_list[ok], a_list[ok], second[ok], third[ok]
    n2 = lcnt[f_list, second].astype(np.int64) + 1
    n3 = lcnt[f_list, third].astype(np.int64) + 1
    rays = n2 * n3

    # For a ray along axis a, pvec = e_a x edge2 has a zero a-component, so glm's dot products reduce exactly to the
    # two remaining float32 terms.
    e1 = (v2 - v1)[f_list]
    e2 = (v3 - v1)[f_list]
    b_ax, c_ax = (a_list + 1) % 3, (a_list + 2) % 3
    rows_e = np.arange(f_list.size)
    e1b, e1c = e1[rows_e, b_ax], e1[rows_e, c_ax]
    e2b, e2c = e2[rows_e, b_ax], e2[rows_e, c_ax]
    det = e1c * e2b - e1b * e2c
    live = ~((det > -_ZERO_TOLERANCE) & (det < _ZERO_TOLERANCE))
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_det = np.float32(1.0) / det
    lm_e = lmin[f_list]
    main_origin = min_box[a_list] + lm_e[rows_e, a_list] * step[a_list]
    main_origin = np.where(step[a_list] == 0, min_box[a_list] - np.float32(0.5), main_origin)
    starts = np.concatenate([[0], np.cumsum(rays)])
    return _Entries(fid, v1, normal, f_list, a_list, n3, rays, starts, e1, e2, e2b, e2c, inv_det, live, lm_e,
                    main_origin)  # fmt: skip


def _cast_rays(en: _Entries, ent: np.ndarray, first: np.ndarray, cnt: np.ndarray, a: int, min_box: np.ndarray,
               step: np.ndarray) -> tuple[np.ndarray, ...]:  # fmt: skip
    """The hits of rays ``first[k] .. first[k] + cnt[k] - 1`` of every entry ``ent[k]`` (all along axis ``a``).

    Returns (push-order key, position, origin, entry, u, v) of each hit.
    """
    b, c = (a + 1) % 3, (a + 2) % 3
    s2, s3 = (1, 2) if a == 0 else ((0, 2) if a == 1 else (0, 1))
    e = np.repeat(ent, cnt)
    starts = np.concatenate([[0], np.cumsum(cnt)[:-1]])
    local = np.arange(e.size) - np.repeat(starts - first, cnt)
    n3e = en.n3[e]
    i = (local // n3e).astype(np.float32)
    j = (local % n3e).astype(np.float32)
    p0 = en.v1[en.face[e]]
    tv = np.empty((e.size, 3), dtype=np.float32)
    tv[:, a] = en.main_origin[e] - p0[:, a]
    o2 = min_box[s2] + (en.lmin[e, s2] + i) * step[s2]
    o3 = min_box[s3] + (en.lmin[e, s3] + j) * step[s3]
    tv[:, s2] = o2 - p0[:, s2]
    tv[:, s3] = o3 - p0[:, s3]
    idet = en.inv_det[e]
    u = (tv[:, c] * en.e2b[e] - tv[:, b] * en.e2c[e]) * idet
    ok = ~((u < 0) | (u > 1))
    q = f32.cross(tv, en.e1[e])
    v = q[:, a] * idet
    ok &= ~((v < 0) | (u + v > 1))
    hit = np.flatnonzero(ok)
    eh = e[hit]
    t = f32.dot(en.e2[eh], q[hit]) * idet[hit]
    origin = np.empty((hit.size, 3), dtype=np.float32)
    origin[:, a] = en.main_origin[eh]
    origin[:, s2] = o2[hit]
    origin[:, s3] = o3[hit]
    pos = origin.copy()
    pos[:, a] = origin[:, a] + t
    return en.starts[eh] + local[hit], pos, origin, eh, u[hit], v[hit]


class GridTooLargeError(ValueError):
    """A grid so fine that its samples cannot fit in memory (refused before any ray is cast).

    Example:
        >>> import torch
        >>> tri = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> try:
        ...     grid_sample(tri, 1 << 20)  # about 5e11 points: refused before any ray is cast
        ... except GridTooLargeError as error:  # a ValueError too
        ...     print(str(error).split(":")[0])
        grid_size (--grid-size) 1048576
    """


# Peak bytes per sample of grid_sample (tracemalloc, torus of tests/mpeg: 157 at grid 1024 = 1.7 M points, 128 at
# 2048 = 6.8 M): ray temporaries, hit lists, their sort, normals, colours, the kept cloud.
_BYTES_PER_HIT = 160


def _available_memory() -> int:
    return available_memory()  # one implementation (_checks); a name of this module's own, which tests replace


def _estimated_hits(en: _Entries, step: np.ndarray) -> float:
    """The expected number of ray hits: every triangle's area projected across its ray axis, over the step squared.

    A triangle of projected area ``A`` on a grid of step ``s`` is crossed by about ``A / s**2`` rays (exact on
    average over grid offsets), so the sum predicts the sampling's size before a ray is cast.
    """
    live = en.live
    area = 0.5 * np.abs(en.e1[live, (en.axis[live] + 2) % 3].astype(np.float64) * en.e2b[live]
                        - en.e1[live, (en.axis[live] + 1) % 3].astype(np.float64) * en.e2c[live])  # fmt: skip
    return float(area.sum() / (float(step[0]) ** 2))


def _check_hit_budget(en: _Entries, step: np.ndarray, grid_size: int) -> None:
    hits = _estimated_hits(en, step)
    need = hits * _BYTES_PER_HIT
    avail = _available_memory()
    if need > avail:
        raise GridTooLargeError(
            f"grid_size (--grid-size) {grid_size}: the grid sampling would give about {hits:.3g} points and need "
            f"about {need / 2**30:.3g} GiB, more than the {avail / 2**30:.3g} GiB of memory available; use a "
            f"smaller grid size (about {int(grid_size * (avail / need) ** 0.5)} fits)"
        )


def grid_hits(
    mesh: MeshLike,
    grid_size: int = 1024,
    *,
    use_normal: bool = True,
    box: tuple[Sequence[float] | np.ndarray | Tensor, Sequence[float] | np.ndarray | Tensor] | None = None,
    use_fixed_point: bool = False,
) -> GridHits:
    """The rays of :func:`grid_sample` that hit the mesh, with their faces, axes and origins.

    Args:
        mesh: the mesh, as for :func:`grid_sample`.
        grid_size: grid steps over the box's longest side (``>= 2``).
        use_normal: cast only along the axis closest to each triangle's normal.
        box: ``(min, max)`` corners of the sampling box; default the mesh's bounding box.
        use_fixed_point: mmetric ``--useFixedPoint`` (needs ``box``).

    Returns:
        :class:`GridHits`: every ray-triangle hit, in mmetric's order, before repeated points are removed.

    Raises:
        The errors of :func:`grid_sample` about the mesh, the box and ``grid_size``.

    Example:
        >>> import torch
        >>> tri = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> grid_hits(tri, 3, box=([0, 0, 0], [1, 1, 1])).axis.tolist()
        [2, 2, 2, 2, 2, 2]
    """
    use_normal = check_flag(use_normal, "use_normal")
    use_fixed_point = check_flag(use_fixed_point, "use_fixed_point")
    grid_size = check_int(grid_size, "grid_size", 2)
    verts, faces = mesh_arrays(mesh)
    if use_fixed_point and box is None:
        raise ValueError("use_fixed_point: needs a box (mmetric rounds only a box given as --minPos/--maxPos)")
    min_box, max_box = mesh_box(verts) if box is None else _parse_box(box)
    if use_fixed_point:
        min_box, max_box = fixed_point_box(min_box, max_box)
    diag = max_box - min_box
    rng = max(diag[0], diag[1], diag[2])
    step = np.full(3, rng * (np.float32(1.0) / np.float32(grid_size - 1)), dtype=np.float32)
    if use_fixed_point:
        step = fixed_point_ceil(step)
    en = _entries(verts, faces, min_box, max_box, step, use_normal)

    _check_hit_budget(en, step, grid_size)
    native = _native()
    if native is not None:
        return _native_hits(native, verts, faces, en, min_box, max_box, step, use_normal)
    out: list[tuple[np.ndarray, ...]] = []
    for a in range(3):
        ents = np.flatnonzero((en.axis == a) & en.live)
        cum = np.concatenate([[0], np.cumsum(en.rays[ents])])  # first ray of every entry along this axis
        # chunks of _CHUNK consecutive rays: an entry whose rays straddle a chunk boundary is split, so one large
        # triangle on a fine grid never needs more than one chunk of temporaries
        for g0 in range(0, int(cum[-1]), _CHUNK):
            g1 = min(g0 + _CHUNK, int(cum[-1]))
            k0 = int(np.searchsorted(cum, g0, side="right")) - 1
            k1 = int(np.searchsorted(cum, g1, side="left"))
            first = np.maximum(cum[k0:k1], g0) - cum[k0:k1]
            cnt = np.minimum(cum[k0 + 1 : k1 + 1], g1) - cum[k0:k1] - first
            out.append(_cast_rays(en, ents[k0:k1], first, cnt, a, min_box, step))
    if out:
        order = np.argsort(np.concatenate([o[0] for o in out]), kind="stable")  # mmetric's push order
        pos_all = np.concatenate([o[1] for o in out])[order]
        origin_all = np.concatenate([o[2] for o in out])[order]
        ent_all = np.concatenate([o[3] for o in out])[order]
        uv_all = np.stack([np.concatenate([o[4] for o in out]), np.concatenate([o[5] for o in out])], 1)[order]
    else:
        pos_all = origin_all = np.zeros((0, 3), np.float32)
        ent_all = np.zeros(0, np.int64)
        uv_all = np.zeros((0, 2), np.float32)
    return GridHits(
        pos_all,
        en.normal[en.face[ent_all]],
        en.fid[en.face[ent_all]],
        en.axis[ent_all],
        origin_all,
        uv_all,
        faces,
    )


_USE_NATIVE = True  # the C++ caster (same float32 operations, same order); False: this module's numpy path


def _native() -> Any:
    """The compiled caster (shared with IBSM's rasterizer), or ``None`` (numpy path) where it cannot be built."""
    if not _USE_NATIVE:
        return None
    return native.try_load("ibsm")


def _native_hits(native: Any, verts: np.ndarray, faces: np.ndarray, en: _Entries, min_box: np.ndarray,
                 max_box: np.ndarray, step: np.ndarray, use_normal: bool) -> GridHits:  # fmt: skip
    pos, origin, bary, face, axis = native.grid_cast(
        torch.from_numpy(np.ascontiguousarray(verts, np.float32)),
        torch.from_numpy(np.ascontiguousarray(faces, np.int64)),
        torch.from_numpy(np.ascontiguousarray(min_box, np.float32)),
        torch.from_numpy(np.ascontiguousarray(step, np.float32)),
        torch.from_numpy(np.ascontiguousarray(min_box == max_box)),
        use_normal,
    )
    normals = np.zeros((faces.shape[0], 3), np.float32)
    normals[en.fid] = en.normal
    f = face.numpy()
    return GridHits(pos.numpy(), normals[f], f, axis.numpy(), origin.numpy(), bary.numpy(), faces)


_HASH_MIX = np.uint64(0x9E3779B97F4A7C15)


def _row_hashes(keys: list[np.ndarray]) -> np.ndarray:
    # 64-bit mix of every value's bits (-0.0 first made 0.0: equal values, equal bits)
    h = np.zeros(keys[0].shape[0], np.uint64)
    for k in keys:
        k = np.ascontiguousarray(k)
        if k.dtype.kind == "f":
            k = k + k.dtype.type(0)
        bits = k.view(np.dtype(f"u{k.dtype.itemsize}")).astype(np.uint64)
        for j in range(bits.shape[1]):
            h = (h ^ bits[:, j]) * _HASH_MIX
            h ^= h >> np.uint64(29)
    return h


def unique_vertex_rows(pos: np.ndarray, nrm: np.ndarray, col: np.ndarray | None) -> np.ndarray:
    """Rows mmetric's ``ModelBuilder`` keeps: the first of the points equal in position, normal and colour (sorted).

    Equal rows are found through a 64-bit hash of their values: in C++ for float32 keys (the rows in order through a
    hash table of the rows kept so far), otherwise in numpy (the hashes sorted: one integer sort instead of a
    lexicographic sort of six to nine keys). Rows with equal hashes are compared value by value (in numpy, a collision
    falls back to the lexicographic sort), so the result is exact either way.

    Example:
        >>> p = np.array([[0, 0, 0], [0, 0, 0], [1, 0, 0]], np.float32)
        >>> unique_vertex_rows(p, np.zeros_like(p), None).tolist()
        [0, 2]
    """
    keys = [pos, nrm] if col is None else [pos, nrm, col]
    ext = _native()
    if ext is not None and all(k.dtype == np.float32 and k.ndim == 2 for k in keys):
        # the same rows through a hash table in C++ (float32 keys: compared as the values they are)
        return ext.unique_rows([torch.from_numpy(np.ascontiguousarray(k)) for k in keys]).numpy()
    h = _row_hashes(keys)
    order = np.argsort(h, kind="stable")  # equal hashes stay in index order: the first of a run is the one kept
    i = np.flatnonzero(h[order[1:]] == h[order[:-1]])
    same = np.ones(i.size, dtype=bool)
    for k in keys:
        same &= np.all(k[order[i]] == k[order[i + 1]], axis=1)
    if not same.all():  # a hash collision between different rows
        return _unique_rows_lexsort(keys)
    later = np.zeros(pos.shape[0], dtype=bool)
    later[order[i + 1]] = True
    return np.flatnonzero(~later)


def _unique_rows_lexsort(keys: list[np.ndarray]) -> np.ndarray:
    cols = [k[:, j] for k in keys for j in range(k.shape[1])]
    order = np.lexsort([np.arange(keys[0].shape[0]), *reversed(cols)])
    stacked = np.stack([c[order] for c in cols], axis=1)
    first = np.ones(order.size, dtype=bool)
    first[1:] = np.any(stacked[1:] != stacked[:-1], axis=1)
    return np.sort(order[first])
