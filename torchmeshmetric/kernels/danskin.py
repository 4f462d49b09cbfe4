r"""Point-to-surface distances differentiated by Danskin's theorem: the backward pass of every surface loss.

``d(p, V) = min_{b in simplex} |p - sum_j b_j v_j|``: where the minimiser ``b*`` (the closest point) is unique, the
gradient of the minimum is the gradient at the fixed minimiser (Danskin 1967): ``dd/dp = (p - c) / d`` and ``dd/dv_j =
-b*_j (p - c) / d`` for the corners of the closest face. On the surface (``d`` at or below :data:`GRADIENT_ULPS` ulps of
the largest centred |coordinate| of the point and of its closest face's corners: the rounding of the computed ``p - c``)
the gradient is the subgradient 0, as autograd through :func:`~torchmeshmetric.point_mesh_distance` gives at ``d = 0``
(``(p - c) / d`` would be a unit vector in a direction set by rounding, e.g. along the face). The floor is the point's
own, not the mesh's: a float32 point 3e-6 above a unit triangle keeps its gradient, as does one 2e-4 above a 0.01
triangle beside a 100-unit plane (found by review: a floor of 64 ulps of the whole mesh's largest coordinate zeroed
both). ``p - c`` and ``d`` are taken in the centred, scaled frame the kernels computed them in, so that float32
gradients keep their accuracy far from the origin. Elsewhere these are the values of autograd through the closest-point
formulas (float64: 1e-10 apart), without their graph: the forward pass is the index's fused no-autograd query, the
backward pass a few ``(P, 3)`` operations and one ``index_add_`` (about 5x faster than autograd through the seven-region
formulas).

First order only: the backward pass is not itself differentiable (the closest face and its barycentric coordinates are
held fixed), so a double backward (``create_graph=True``) is refused with :class:`DoubleBackwardError` rather than
returning a wrong Hessian-vector product.
"""

from __future__ import annotations

import itertools
from typing import Any

import torch
from torch import Tensor

from torchmeshmetric._checks import DoubleBackwardError
from torchmeshmetric.kernels.mesh_index import MeshIndex
from torchmeshmetric.structures import Mesh

__all__ = ["GRADIENT_ULPS", "mesh_surface_distances", "surface_distances"]

GRADIENT_ULPS = 8.0
"""Distances at or below this many ulps of the largest centred |coordinate| of the point and its closest face's
corners are on the surface: the computed ``p - c`` (rounded to about one ulp of those coordinates per component) has
no direction there. Points built on the surface by rounding (face centroids, edge midpoints) measure up to ~2 ulps."""


class _DanskinDistance(torch.autograd.Function):
    """Distances from packed points to the packed surface an index holds, with Danskin's gradient."""

    @staticmethod
    def forward(
        ctx: Any, points: Tensor, verts: Tensor, faces: Tensor, index: MeshIndex, lengths: Tensor, owner: str
    ) -> Tensor:
        with torch.no_grad():
            centred = index.point_mesh_distance_centred(points.detach(), lengths)
            hit = index.to_world(centred)
            # The direction p - c in the frame the distance was computed in (centred and scaled: a difference of
            # world coordinates far from the origin has lost the digits of a short distance); only its ratio to
            # that frame's distance is used, which the scale leaves unchanged.
            diff = centred.points_c - centred.result.closest
            dists_c = centred.result.dists
            # At or below the rounding of p - c (ulps of the point's and its face's own coordinates, not the whole
            # mesh's) the point is on the surface: its direction is rounding noise.
            corners = faces[hit.face_idx]  # (P, 3): the selected faces' vertex rows
            corners_c = index.centred_verts()[corners]  # (P, 3, 3)
            magnitude = torch.maximum(centred.points_c.abs().amax(-1), corners_c.abs().amax((-2, -1)))
            on_surface = dists_c <= GRADIENT_ULPS * torch.finfo(dists_c.dtype).eps * magnitude
        ctx.save_for_backward(diff, dists_c, on_surface, hit.bary, corners)
        ctx.num_verts = int(verts.shape[0])
        ctx.owner = owner
        return hit.dists

    @staticmethod
    def backward(ctx: Any, grad: Tensor) -> tuple[Tensor | None, Tensor | None, None, None, None, None]:
        if torch.is_grad_enabled():  # create_graph=True: the caller wants to differentiate this gradient
            raise DoubleBackwardError(
                f"{ctx.owner}: first-order only: its gradient holds the closest points fixed (Danskin's theorem), "
                "so a double backward (create_graph=True, Hessian-vector products) would be wrong; differentiate "
                "once"
            )
        diff, dists, on_surface, bary, corners = ctx.saved_tensors
        off = ~on_surface
        scale = torch.where(off, grad / torch.where(off, dists, torch.ones_like(dists)), 0.0)
        unit = scale[:, None] * diff  # dL/dp
        grad_verts = None
        if ctx.needs_input_grad[1]:
            grad_verts = unit.new_zeros(ctx.num_verts, 3).index_add_(
                0, corners.reshape(-1), (-bary[:, :, None] * unit[:, None, :]).reshape(-1, 3)
            )
        return (unit if ctx.needs_input_grad[0] else None), grad_verts, None, None, None, None


def surface_distances(
    points: Tensor, verts: Tensor, faces: Tensor, index: MeshIndex, lengths: Tensor, *, owner: str = "loss"
) -> Tensor:
    """Exact distances from packed points to the packed meshes ``index`` holds; differentiable by Danskin's theorem.

    Args:
        points: ``(sum P_b, 3)`` query points, packed, in the index's dtype and on its device (trusted: the callers'
            validated vertex or point sets).
        verts: ``(sum V_b, 3)`` the vertices the gradient reaches: the packed vertices of the meshes the index was
            built from (equal values; the index itself may hold detached copies).
        faces: ``(sum F_b, 3)`` their faces, packed, indices into ``verts``.
        index: the :class:`~torchmeshmetric.MeshIndex` of those meshes (queried without autograd).
        lengths: ``(B,)`` points per item; item ``b``'s points are measured to mesh ``b``.
        owner: the loss's name in the error of a double backward.

    Returns:
        ``(sum P_b,)`` distances (those of ``index.point_mesh_distance``, bit for bit), differentiable w.r.t.
        ``points`` and ``verts``; the gradient is 0 where a distance is at or below the rounding floor (a point on
        the surface).

    Raises:
        DoubleBackwardError: at a backward pass with ``create_graph=True``.

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric import MeshIndex
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> index = MeshIndex(sphere)
        >>> v, f = index.verts.clone().requires_grad_(), index.faces
        >>> p = torch.tensor([[0.0, 0.0, 3.0]], dtype=torch.float64, requires_grad=True)
        >>> d = surface_distances(p, v, f, index, torch.tensor([1]))
        >>> d.sum().backward()
        >>> round(d.item(), 4), [round(g, 4) for g in p.grad[0].tolist()], round(float(v.grad.sum(0)[2]), 4)
        (2.0, [0.0, 0.0, 1.0], -1.0)
    """
    out: Tensor = _DanskinDistance.apply(points, verts, faces, index, lengths, owner)
    return out


def mesh_surface_distances(
    points: Tensor, lengths: Tensor, meshes: list[Mesh], index: MeshIndex, *, owner: str = "loss"
) -> Tensor:
    """:func:`surface_distances` to a batch of meshes: their vertices and faces packed as the index packs them.

    Args:
        points: ``(sum P_b, 3)`` packed query points in the index's dtype, on its device.
        lengths: ``(B,)`` points per item.
        meshes: the ``B`` meshes the index was built from (equal values); the gradient reaches their vertices
            unless they are detached.
        index: their :class:`~torchmeshmetric.MeshIndex`.
        owner: the loss's name in the error of a double backward.

    Returns:
        ``(sum P_b,)`` distances, differentiable w.r.t. ``points`` and the meshes' vertices (first order). Without
        anything to differentiate (no gradient required, or grad mode off) the index's query alone, bit for bit.

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric import MeshIndex, as_mesh
        >>> sphere = as_mesh(trimesh.creation.icosphere(subdivisions=2))
        >>> p = torch.tensor([[0.0, 0.0, 3.0]], dtype=torch.float64)
        >>> round(float(mesh_surface_distances(p, torch.tensor([1]), [sphere], MeshIndex(sphere))), 4)
        2.0
    """
    if not (torch.is_grad_enabled() and (points.requires_grad or any(m.verts.requires_grad for m in meshes))):
        return index.point_mesh_distance_unchecked(points, lengths).dists  # a metric: nothing to differentiate
    if len(meshes) == 1:
        verts, faces = meshes[0].verts, meshes[0].faces
    else:
        offsets = itertools.accumulate([m.num_verts for m in meshes[:-1]], initial=0)  # ints: no device read
        verts = torch.cat([m.verts for m in meshes])
        faces = torch.cat([m.faces + o for m, o in zip(meshes, offsets, strict=True)])
    return surface_distances(points, verts.to(index.dtype), faces, index, lengths, owner=owner)
