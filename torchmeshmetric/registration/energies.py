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
from typing import Any, NamedTuple

import torch
from torch import Tensor

from torchmeshmetric.kernels.accel._extension import bvh_ready, load_bvh
from torchmeshmetric.kernels.mesh_index import MeshIndex
from torchmeshmetric.kernels.point_triangle import closest_point_on_triangle, point_mesh_distance
from torchmeshmetric.registration.deformation_graph import DeformationGraph
from torchmeshmetric.structures import Mesh

__all__ = [
    "Correspondences",
    "EnergyTerms",
    "deformed_vertices",
    "embedded_deformation_regularizer",
    "find_correspondences",
    "FusedStep",
    "fused_energy",
    "geman_mcclure",
    "registration_ops",
    "reject_correspondences",
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
    index: MeshIndex | None = None,
    face_normals: Tensor | None = None,
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
        index: a :class:`~torchmeshmetric.MeshIndex` of ``(verts, faces)`` of the points' dtype, to query instead of
            building a structure for this call (the registration loop keeps one per mesh).
        face_normals: ``(F, 3)`` :meth:`~torchmeshmetric.Mesh.face_normals` of the mesh, when already known.

    Returns:
        :class:`Correspondences`.
    """
    with torch.no_grad():
        p = points.detach()
        v = verts.detach()
        if index is None:
            res = point_mesh_distance(p, v, faces)
        else:
            res = index._point_mesh_distance(p, torch.tensor([p.shape[0]], device=p.device))
        fn = None
        if point_normals is not None:
            fn = (Mesh(v, faces, validate=False).face_normals() if face_normals is None else face_normals)[res.face_idx]
        return reject_correspondences(res.face_idx, res.dists, point_normals, fn, max_distance, max_normal_angle)


def reject_correspondences(
    face_idx: Tensor,
    dists: Tensor,
    point_normals: Tensor | None,
    matched_normals: Tensor | None,
    max_distance: float,
    max_normal_angle: float,
) -> Correspondences:
    """:func:`find_correspondences`' rejection of assignments, given the unit normals of the matched faces."""
    ok = dists <= max_distance
    if point_normals is not None and matched_normals is not None:
        fn = matched_normals
        cos = (fn * point_normals.detach()).sum(-1)
        has = ((fn * fn).sum(-1) > 0) & ((point_normals * point_normals).sum(-1) > 0)
        ok &= ~has | (cos >= math.cos(math.radians(max_normal_angle)))
    return Correspondences(face_idx, ok.to(dists.dtype), dists)


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


class EnergyTerms(NamedTuple):
    """The correspondences of one refresh, laid out for :func:`fused_energy` (indices local to ``need``).

    Attributes:
        rest: ``(I, 3)`` rest positions of the source vertices the energies touch (data vertices and corners of
            matched faces), ``graph.verts[need]``.
        vert_nodes: ``(I, K)`` their skinning nodes, ``graph.vert_nodes[need]``.
        vert_weights: ``(I, K)`` their skinning weights, ``graph.vert_weights[need]``.
        data_idx: ``(S,)`` int64 row of ``need`` of each data vertex.
        data_tri: ``(S, 3, 3)`` its assigned target triangle ``(a, b, c)``.
        data_normals: ``(S, 3)`` unit normal of that triangle (zero for a zero-area face).
        data_weights: ``(S,)`` acceptance weights.
        samples: ``(Q, 3)`` target samples of the reverse term.
        rev_faces: ``(Q, 3)`` int64 rows of ``need`` of the corners of each sample's assigned source face.
        rev_weights: ``(Q,)`` acceptance weights.
    """

    rest: Tensor
    vert_nodes: Tensor
    vert_weights: Tensor
    data_idx: Tensor
    data_tri: Tensor
    data_normals: Tensor
    data_weights: Tensor
    samples: Tensor
    rev_faces: Tensor
    rev_weights: Tensor


def registration_ops() -> Any | None:
    """The C++ registration operators (``torch.ops.torchmeshmetric_registration``), or ``None`` without the extension.

    Only where the extension is ready (built, or cached), as ``backend="auto"``: never compiles on first use.
    """
    if not bvh_ready() or load_bvh() is None:
        return None
    return torch.ops.torchmeshmetric_registration


class FusedStep:
    """:func:`fused_energy` for one refresh's terms, laid out once and evaluated at every Adam step (CPU, C++).

    The layout (:func:`energy_layout` in ``deformation_energy.cpp``) lists, per touched vertex and per node, its
    gradient contributions in a fixed order, so one evaluation's sums do not depend on the thread count.

    Args:
        graph: the deformation graph (its buffers are read once; its parameters at every call).
        terms: the correspondences of one refresh.
        ops: :func:`registration_ops`.
        layout: the layout of ``terms``, when already built (``energy_terms`` returns it).
    """

    def __init__(
        self, graph: DeformationGraph, terms: EnergyTerms, ops: Any, layout: list[Tensor] | None = None
    ) -> None:
        self._ops = ops
        self._buffers = [t.contiguous() for t in (graph.nodes, *terms, graph.edges)]
        nodes, _, vidx, _, data_idx, _, _, data_w, _, rev_faces, rev_w, edges = self._buffers
        if layout is None:
            layout = ops.energy_layout(data_idx, data_w, rev_faces, rev_w, vidx, nodes, edges)
        self._layout = layout

    def __call__(self, rotations: Tensor, translations: Tensor, scalars: list[float]) -> list[Tensor]:
        """``[loss, dL/drotations (N, 3), dL/dtranslations (N, 3), max |gradient| (float64)]`` at these parameters.

        ``scalars``: ``[sigma, plane_weight, point_weight, reverse_weight, data_scale, regularization]``.
        """
        out: list[Tensor] = self._ops.energy_step(
            rotations.detach(), translations.detach(), *self._buffers, self._layout, scalars
        )
        return out


class _FusedEnergy(torch.autograd.Function):
    """Energy and its gradient to the axis-angle rotations and translations from one C++ pass (:class:`FusedStep`).

    The rotation matrices are kornia's exponential map (the same operations in C++, bit for bit); the pass
    back-propagates through it with Gallego & Yezzi's closed form. Backward scales the stored gradients.
    """

    @staticmethod
    def forward(ctx: Any, rotations: Tensor, translations: Tensor, step: FusedStep, scalars: list[float]) -> Tensor:
        loss, g_rot, g_tr, _ = step(rotations, translations, scalars)
        ctx.save_for_backward(g_rot, g_tr)
        return loss

    @staticmethod
    def backward(ctx: Any, grad: Tensor) -> tuple[Tensor | None, ...]:
        g_rot, g_tr = ctx.saved_tensors
        return grad * g_rot, grad * g_tr, None, None


def fused_energy(
    graph: DeformationGraph,
    terms: EnergyTerms,
    *,
    sigma: float,
    plane_weight: float,
    point_weight: float,
    reverse_weight: float,
    data_scale: float,
    regularization: float,
) -> Tensor | None:
    """The registration loop's energy in one C++ pass, or ``None`` where the C++ extension cannot serve (not CPU).

    ``data_scale * (surface_term(data) + reverse_weight * surface_term(reverse)) + regularization * E_reg`` with
    the data vertices deformed by ``graph`` (the loop's energy, :func:`surface_term` and
    :func:`embedded_deformation_regularizer`), differentiable w.r.t. the graph's rotations and translations. The
    gradient to the deformed points is ``2 (p - q)`` through the Geman-McClure weights (the closest point ``q``
    moves along the surface, orthogonally to ``p - q``), so it is the torch formulation's within rounding
    (tested); forward and backward cost one pass over the terms instead of ~100 small torch ops. Threaded over
    torch's intra-op threads, with the same result for any thread count.
    """
    ops = registration_ops() if graph.nodes.device.type == "cpu" else None
    if ops is None:
        return None
    scalars = [sigma, plane_weight, point_weight, reverse_weight, data_scale, regularization]
    out: Tensor = _FusedEnergy.apply(graph.rotations, graph.translations, FusedStep(graph, terms, ops), scalars)
    return out


def deformed_vertices(graph: DeformationGraph) -> Tensor:
    """``graph()`` without gradient: every vertex deformed, in one C++ pass on the CPU (torch ops elsewhere)."""
    with torch.no_grad():
        if graph.nodes.device.type != "cpu" or not bvh_ready():
            return graph()
        ext = load_bvh()
        assert ext is not None
        rot = graph.rotation_matrices().contiguous()
        return ext.deform_vertices(
            rot, graph.translations.detach().contiguous(), graph.nodes.contiguous(), graph.verts.contiguous(),
            graph.vert_nodes.contiguous(), graph.vert_weights.contiguous(),
        )  # fmt: skip
