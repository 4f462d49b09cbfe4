"""Energies of non-rigid registration: robust data terms, correspondence rejection, the embedded-deformation prior.

Correspondences are *face* assignments found with the exact closest-point kernel
(:func:`~torchmeshmetric.point_mesh_distance`, accelerated exact backends) and refreshed every few
optimiser steps; between refreshes each energy recomputes the exact closest point on the assigned face
(Ericson 2004, :func:`~torchmeshmetric.closest_point_on_triangle`), so the residual stays exact and differentiable
while the expensive search is amortised. All distances are in the units of the points given; the registration loop
normalises meshes to a unit bounding-box diagonal, so its thresholds are fractions of the diagonal.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric.kernels.point_triangle import closest_point_on_triangle, point_mesh_distance
from torchmeshmetric.registration._common import face_unit_normals
from torchmeshmetric.registration.deformation_graph import DeformationGraph

__all__ = [
    "Correspondences",
    "embedded_deformation_regularizer",
    "find_correspondences",
    "geman_mcclure",
    "surface_term",
]


class Correspondences(NamedTuple):
    """Face assignments of query points on a mesh, with rejection.

    Attributes:
        face_idx: ``(P,)`` int64 closest face of each point.
        weights: ``(P,)`` 1 for accepted matches, 0 for rejected ones (too far, or normals too different).
        dists: ``(P,)`` distance at assignment time (no gradient).
    """

    face_idx: Tensor
    weights: Tensor
    dists: Tensor


def geman_mcclure(sq: Tensor, sigma: float) -> Tensor:
    """Geman-McClure robust kernel on squared residuals: ``sigma^2 r^2 / (sigma^2 + r^2)`` (``~ r^2`` for small r).

    Example:
        >>> import torch
        >>> geman_mcclure(torch.tensor([0.0, 1.0, 1e6]), 1.0).tolist()
        [0.0, 0.5, 0.9999989867210388]
    """
    s2 = sigma * sigma
    return s2 * sq / (s2 + sq)


def find_correspondences(
    points: Tensor,
    point_normals: Tensor | None,
    verts: Tensor,
    faces: Tensor,
    *,
    max_distance: float,
    max_normal_angle: float,
) -> Correspondences:
    """Assign each point its exactly closest face and reject implausible matches (no gradient).

    A match is rejected when it is farther than ``max_distance`` or when the point's normal and the face's
    normal differ by more than ``max_normal_angle`` degrees. Points or faces without a normal (zero vectors, e.g.
    zero-area faces) skip the angle test.

    Args:
        points: ``(P, 3)`` query points.
        point_normals: ``(P, 3)`` unit normals of the points, or ``None`` to skip the angle test.
        verts: ``(V, 3)`` mesh vertices.
        faces: ``(F, 3)`` mesh faces.
        max_distance: rejection distance (same units as the points).
        max_normal_angle: rejection angle in degrees.

    Returns:
        :class:`Correspondences`.
    """
    with torch.no_grad():
        p = points.detach()
        v = verts.detach()
        res = point_mesh_distance(p, v, faces)
        face_idx, d = res.face_idx, res.dists
        ok = d <= max_distance
        if point_normals is not None:
            fn = face_unit_normals(v, faces)[face_idx]
            cos = (fn * point_normals.detach()).sum(-1)
            has = ((fn * fn).sum(-1) > 0) & ((point_normals * point_normals).sum(-1) > 0)
            ok &= ~has | (cos >= math.cos(math.radians(max_normal_angle)))
        return Correspondences(face_idx, ok.to(p.dtype), d)


def surface_term(
    points: Tensor,
    verts: Tensor,
    faces: Tensor,
    corr: Correspondences,
    *,
    sigma: float,
    plane_weight: float = 1.0,
    point_weight: float = 1.0,
) -> Tensor:
    """Robust point-to-point + point-to-plane energy of ``points`` to their assigned faces (weighted mean).

    ``E = sum_i c_i [a rho(|p_i - q_i|^2) + b rho(((p_i - x_i) . n_i)^2)] / sum_i c_i`` with ``q_i`` the exact
    closest point on the assigned face, ``n_i`` its unit normal (zero for zero-area faces, which therefore drop
    out of the point-to-plane part), ``rho`` the Geman-McClure kernel and ``c_i`` the acceptance weights.
    Differentiable w.r.t. ``points`` and ``verts``.

    Args:
        points: ``(P, 3)`` points.
        verts: ``(V, 3)`` mesh vertices.
        faces: ``(F, 3)`` mesh faces.
        corr: assignments from :func:`find_correspondences`.
        sigma: Geman-McClure scale.
        plane_weight: ``b``, weight of point-to-plane.
        point_weight: ``a``, weight of point-to-point.

    Returns:
        0-dim energy (0 when every match is rejected).
    """
    tri = verts[faces[corr.face_idx]]
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    sq = closest_point_on_triangle(points, a, b, c).sq_dists
    e = point_weight * geman_mcclure(sq, sigma)
    if plane_weight:
        n = torch.linalg.cross(b - a, c - a, dim=-1)
        nn_ = (n * n).sum(-1)
        ok = nn_ > 0
        n = n / torch.where(ok, nn_, torch.ones_like(nn_)).sqrt()[:, None]
        plane_sq = torch.where(ok, ((points - a) * n).sum(-1) ** 2, torch.zeros_like(nn_))
        e = e + plane_weight * geman_mcclure(plane_sq, sigma)
    w = corr.weights
    return (w * e).sum() / w.sum().clamp_min(1.0)


def embedded_deformation_regularizer(graph: DeformationGraph) -> Tensor:
    """Sumner's ``E_reg``: each node's affine map should predict its neighbours' deformed positions.

    ``E_reg = mean_{(j,k)} || R_j (g_k - g_j) + g_j + t_j - (g_k + t_k) ||^2 / mean ||g_k - g_j||^2`` (normalised by
    the squared edge length, so its weight does not depend on the node spacing). With rotations from the SO(3)
    exponential map this is an as-rigid-as-possible prior; no orthogonality term is needed.

    Args:
        graph: the deformation graph.

    Returns:
        0-dim energy (0 for a graph with a single node).
    """
    e = graph.edges
    if e.shape[0] == 0:
        return graph.translations.sum() * 0.0
    g, t = graph.nodes, graph.translations
    R = graph.rotation_matrices()
    j, k = e[:, 0], e[:, 1]
    dg = g[k] - g[j]
    pred = torch.einsum("eab,eb->ea", R[j], dg) + g[j] + t[j]
    r = pred - (g[k] + t[k])
    return (r * r).sum(-1).mean() / (dg * dg).sum(-1).mean().clamp_min(torch.finfo(g.dtype).tiny)
