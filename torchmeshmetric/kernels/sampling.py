"""Point sets of a mesh: area-weighted surface samples (paper Eq. 2) and the vertex set (paper Eq. 3)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple, cast

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, check_allocation, check_flag, check_generator, check_int
from torchmeshmetric.structures import (
    MeshLike,
    as_mesh,
    batch_index,
    lengths_to_offsets,
    pack_meshes,
    power_of_two_scale_down,
    vertex_set_mask,
)

__all__ = ["SurfaceSamples", "sample_surface", "vertex_set"]


class SurfaceSamples(NamedTuple):
    """Result of :func:`sample_surface`.

    Attributes:
        points: ``(N, 3)`` (or packed ``(sum N_b, 3)``) samples, differentiable w.r.t. the vertices.
        face_idx: ``(N,)`` int64 face of each sample (row of the packed faces).
        bary: ``(N, 3)`` barycentric coordinates of each sample in its face.
        lengths: ``(B,)`` samples per mesh (``(1,)`` for a single mesh).

    Example:
        >>> import torch
        >>> verts, faces = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]])
        >>> s = sample_surface(verts, faces, 4, generator=torch.Generator().manual_seed(0))
        >>> tuple(s.points.shape), s.face_idx.tolist(), s.lengths.tolist(), bool((s.points[:, 2] == 0).all())
        ((4, 3), [0, 0, 0, 0], [4], True)
    """

    points: Tensor
    face_idx: Tensor
    bary: Tensor
    lengths: Tensor


# Least bytes each sample takes: float32 point and barycentrics (2 x 12), int64 face index and batch index (2 x 8).
_SAMPLE_BYTES = 40


def _sample_counts(n: object, num_items: int) -> list[int]:
    """``sample_surface``'s ``n`` as one count per mesh: an int for all, or a sequence of ``num_items`` ints.

    Each is :func:`~torchmeshmetric._checks.check_int`'s int (numpy's and one-element integer tensors too, not a
    bool), at least 0; their total must fit in memory. ``n=1.5``, ``np.int64(5)`` or ``True`` gave torch or Python
    errors naming no argument, or one sample (found by review).

    Raises:
        TypeError: ``n`` or one of its items is not an int.
        ValueError: a count is negative, or the sequence has another length than the batch.
        SizeLimitError: the samples cannot fit in memory.
    """
    is_one = not isinstance(n, (Sequence, Tensor)) or isinstance(n, str) or (isinstance(n, Tensor) and n.dim() == 0)
    if is_one:
        counts = [check_int(n, "n", 0)] * num_items
    else:
        counts = [check_int(c, f"n[{i}]", 0) for i, c in enumerate(cast(Sequence[object], n))]
        if len(counts) != num_items:
            raise ValueError(f"n: expected an int or {num_items} ints (one per mesh), found {len(counts)}")
    check_allocation(float(sum(counts)), _SAMPLE_BYTES, "n", n, "samples")
    return counts


def sample_surface(
    verts: Tensor | MeshLike | Sequence[MeshLike],
    faces: Tensor | None = None,
    n: int | Sequence[int] = 10_000,
    *,
    generator: torch.Generator | None = None,
) -> SurfaceSamples:
    """Sample points uniformly by area on the surface of one mesh or a batch of meshes (paper Eq. 2).

    Faces are drawn with probability proportional to their area and points placed with the square-root
    barycentric map (Osada et al. 2002), which is uniform on each triangle. Vectorised over a batch: one
    inverse-CDF search over all items, no Python loop.

    Args:
        verts: ``(V, 3)`` vertices with ``faces``; or a mesh-like / list of mesh-likes with ``faces=None``.
        faces: ``(F, 3)`` faces when ``verts`` is a tensor.
        n: samples per mesh (an int for all, or one per mesh).
        generator: optional seeded ``torch.Generator`` (on the mesh's device) for reproducible samples.

    Returns:
        :class:`SurfaceSamples` ``(points, face_idx, bary, lengths)``.

    Raises:
        EmptyInputError: a mesh with samples requested has zero total area.
        TypeError: ``n`` is not an int (or a sequence of them), or ``generator`` is not a ``torch.Generator``.
        ValueError: a count is negative, or ``n`` has another length than the batch.
        SizeLimitError: the samples cannot fit in memory.

    Example:
        >>> import torch, trimesh
        >>> g = torch.Generator().manual_seed(0)
        >>> s = sample_surface(trimesh.creation.icosphere(), n=100, generator=g)
        >>> s.points.shape
        torch.Size([100, 3])
    """
    packed = pack_meshes(verts, faces)
    num_items = int(packed.verts_lengths.numel())
    counts = torch.as_tensor(_sample_counts(n, num_items), dtype=torch.long)
    check_generator(generator)
    device = packed.verts.device
    counts = counts.to(device)
    face_batch = batch_index(packed.faces_lengths)
    v_off = lengths_to_offsets(packed.verts_lengths)
    faces_g = packed.faces + v_off[face_batch][:, None]
    tri = packed.verts[faces_g]
    with torch.no_grad():
        # Areas in each mesh's own power-of-two unit where the input dtype's |cross|**2 would overflow or underflow
        # (the distribution is per mesh, so a mesh's unit cancels; other meshes keep their bits).
        unit = area_units(tri, face_batch, num_items)
        corners = tri if unit is None else tri * unit[face_batch][:, None, None]
        edge_1, edge_2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
        area = 0.5 * torch.linalg.cross(edge_1, edge_2, dim=-1).norm(dim=-1)
        area = area.double()
        total = torch.zeros(num_items, dtype=area.dtype, device=device).index_add_(0, face_batch, area)
        bad = (counts > 0) & ~(total > 0)
        if bool(bad.any()):
            b = int(bad.nonzero()[0, 0])
            raise EmptyInputError(f"verts/faces: mesh {b} has zero surface area; cannot sample {int(counts[b])} points")
        # Per-item normalised CDF shifted by the item index: one searchsorted serves the whole batch.
        # One cumsum runs over the whole batch, so an item's CDF is a difference of running sums: each item's
        # areas are first scaled by a power of two that brings its total into [0.5, 1), else the sums of a much
        # larger earlier item swamp a later item's areas (area ratio ~1e15: every sample on one face). The
        # scaling is exact, so a single mesh and a batch's first item keep the CDF of the unscaled sums.
        f_off = lengths_to_offsets(packed.faces_lengths)
        scale = power_of_two_scale_down(total)
        total = total * scale
        csum = (area * scale[face_batch]).cumsum(0)
        start = torch.cat([csum.new_zeros(1), csum])[f_off[:-1]]
        cdf = face_batch.double() + (csum - start[face_batch]) / total.clamp_min(1e-300)[face_batch]
        sample_batch = batch_index(counts)
        u = torch.rand(sample_batch.numel(), dtype=torch.float64, device=device, generator=generator)
        key = sample_batch.double() + u.clamp(max=1.0 - 2**-53)
        face_idx = torch.searchsorted(cdf, key, right=True)
        # Guard rounding at the upper end of an item's segment.
        face_idx = torch.minimum(face_idx, f_off[1:][sample_batch] - 1)
        r = torch.rand(sample_batch.numel(), 2, dtype=packed.verts.dtype, device=device, generator=generator)
        s1 = r[:, 0].sqrt()
        bary = torch.stack([1 - s1, s1 * (1 - r[:, 1]), s1 * r[:, 1]], dim=-1)
    t = tri[face_idx]
    points = (bary[:, :, None] * t).sum(1)
    return SurfaceSamples(points, face_idx, bary, counts)


def area_units(tri: Tensor, face_batch: Tensor, num_items: int) -> Tensor | None:
    """``(B,)`` per-mesh power of two to scale corners by before their areas are taken, or ``None`` (no mesh needs one).

    A face's area is ``|ab x ac| / 2``, and the norm squares the cross product: products of four coordinates, which
    overflow float32 for edges beyond ~1e9 (``inf`` areas: at 1e20 every sample fell on the overflowing faces, 0 %
    instead of 1 % on a small face; review V) and underflow below ~1e-9 (a valid mesh at 1e-25 had "zero surface
    area"); float64 likewise beyond ~1e76 or below ~1e-77. A mesh whose largest edge component lies outside
    ``2**(+-(maxexp / 4 - 2))`` gets the power of two that brings it into ``[0.5, 1)`` (capped at
    ``2**(maxexp - 2)`` for subnormal meshes), every other mesh 1: the same bits where nothing over- or underflowed,
    since a power of two scales exactly.

    Args:
        tri: ``(F, 3, 3)`` the packed faces' corners.
        face_batch: ``(F,)`` the mesh of each face.
        num_items: number of meshes ``B``.

    Returns:
        The scales (the corners' dtype), or ``None``.

    Example:
        >>> import torch
        >>> tri = torch.tensor([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
        >>> area_units(tri, torch.zeros(1, dtype=torch.long), 1) is None
        True
        >>> area_units(tri * 1e20, torch.zeros(1, dtype=torch.long), 1).item() == 2.0**-67
        True
    """
    if tri.shape[0] == 0:
        return None
    half = tri.detach() * 0.5  # halved: differences of finite coordinates cannot overflow (only the exponent is used)
    edge = torch.maximum((half[:, 1] - half[:, 0]).abs().amax(-1), (half[:, 2] - half[:, 0]).abs().amax(-1))
    extent = edge.new_zeros(num_items).scatter_reduce(0, face_batch, edge, "amax")
    maxexp = math.frexp(torch.finfo(tri.dtype).max)[1]
    bound = maxexp // 4 - 2  # float32 30, float64 254
    exponent = torch.frexp(extent)[1] + 1  # + 1: the halving
    needs = (extent > 0) & ((exponent > bound) | (exponent < -bound))
    if not bool(needs.any()):
        return None
    exponent = torch.where(needs, (-exponent).clamp_max(maxexp - 2), torch.zeros_like(exponent))
    return torch.ldexp(torch.ones_like(extent), exponent)


def vertex_set(mesh: MeshLike, *, referenced_only: bool = True, name: str = "mesh") -> Tensor:
    """The vertex set of a mesh (paper Eq. 3), the points from which the paper measures distances.

    Args:
        mesh: any mesh-like.
        referenced_only: drop vertices that no face references (real captured frames contain some; they are
            not part of the surface). Duplicated vertices are kept: each is a vertex of the simplified mesh.
        name: the argument's name in errors.

    Returns:
        ``(V', 3)`` vertex positions, in their original order, differentiable w.r.t. ``mesh.verts``.

    Example:
        >>> import torch
        >>> v = torch.tensor([[0., 0, 0], [1, 0, 0], [0, 1, 0], [9, 9, 9]])
        >>> vertex_set((v, torch.tensor([[0, 1, 2]]))).shape
        torch.Size([3, 3])
    """
    referenced_only = check_flag(referenced_only, "referenced_only")
    m = as_mesh(mesh, name=name)
    if not referenced_only:
        return m.verts
    used = vertex_set_mask(m.faces, m.num_verts)
    if not bool(used.any()):
        raise EmptyInputError(
            f"{name}: no vertex is referenced by a face ({m.num_verts} vertices, {m.faces.shape[0]} faces); give a "
            "(P, 3) tensor to measure points without faces"
        )
    return m.verts[used]
