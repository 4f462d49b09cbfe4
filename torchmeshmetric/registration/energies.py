"""Energies of non-rigid registration: robust data terms, soft correspondence weights, the embedded-deformation prior.

Correspondences are found with the exact closest-point kernel (:func:`~torchmeshmetric.point_mesh_distance`,
accelerated exact backends) and refreshed every few optimiser steps. Between refreshes they are held as *points*,
not faces: a data point is pulled to its fixed closest target point ``q`` and the plane through ``q`` with the
target's interpolated (Phong) vertex normal there; a target sample to the fixed barycentric point of its closest
deformed source face. Both are continuous functions of the meshes: a point whose closest point lies on an edge or a
vertex ties between faces, and which tied face the search returns changes with the last bit of the input, but the
closest point, its barycentric combination of the shared corners and the interpolated normal do not. The acceptance
weights fall smoothly to zero at the rejection thresholds (:func:`acceptance_weights`) instead of jumping, for the
same reason: a registration built on them is a continuous function of its input (docs/registration.md,
"Stability"). All distances are in the units of the points given; the registration loop normalises meshes to a unit
bounding-box diagonal, so its thresholds are fractions of the diagonal.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import torch
from torch import Tensor

from torchmeshmetric import native
from torchmeshmetric.kernels.mesh_index import MeshIndex
from torchmeshmetric.kernels.point_triangle import point_mesh_distance
from torchmeshmetric.registration.deformation_graph import DeformationGraph
from torchmeshmetric.structures import Mesh

__all__ = [
    "Correspondences",
    "acceptance_weights",
    "data_term",
    "interpolated_normals",
    "reverse_term",
    "EnergyTerms",
    "deformed_vertices",
    "embedded_deformation_regularizer",
    "find_correspondences",
    "FusedStep",
    "fused_energy",
    "geman_mcclure",
    "registration_ops",
]


class Correspondences(NamedTuple):
    """Closest points of query points on a mesh, with soft acceptance weights (no gradient).

    Attributes:
        face_idx: ``(P,)`` int64 closest face of each point (among tied faces, the one the search returned).
        weights: ``(P,)`` acceptance weights in ``[0, 1]`` (:func:`acceptance_weights`).
        dists: ``(P,)`` distance at assignment time.
        closest: ``(P, 3)`` the closest point on the mesh.
        bary: ``(P, 3)`` its barycentric coordinates on ``face_idx``.
        normals: ``(P, 3)`` the mesh's unit normal at the closest point (:func:`interpolated_normals`).

    Example:
        >>> import torch
        >>> verts, faces = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]])
        >>> corr = find_correspondences(torch.tensor([[0.25, 0.25, 0.5]]), None, verts, faces, max_distance=1.0,
        ...                             max_normal_angle=60.0)
        >>> corr.face_idx.tolist(), corr.bary.tolist(), corr.normals.tolist(), corr.weights.tolist()
        ([0], [[0.5, 0.25, 0.25]], [[0.0, 0.0, 1.0]], [1.0])
    """

    face_idx: Tensor
    weights: Tensor
    dists: Tensor
    closest: Tensor
    bary: Tensor
    normals: Tensor


def _smoothstep(e0: float, e1: float, x: Tensor) -> Tensor:
    """0 below ``e0``, 1 above ``e1``, the C1 cubic in between; a step at ``e1`` where the dtype cannot tell them apart.

    Edges closer than the dtype resolves (the cosines of a ``max_normal_angle`` of 1e-300 degrees are both 1.0)
    divided 0 by 0: a NaN weight, and a NaN loss at the first step.
    """
    width = e1 - e0
    if not float(torch.tensor(width, dtype=x.dtype)) > 0:  # the width as the division below rounds it
        return (x >= e1).to(x.dtype)
    t = ((x - e0) / width).clamp(0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def acceptance_weights(
    dists: Tensor,
    point_normals: Tensor | None,
    matched_normals: Tensor | None,
    max_distance: float,
    max_normal_angle: float,
) -> Tensor:
    """Soft acceptance of matches: 1 when clearly plausible, falling smoothly (C1) to 0 at the rejection thresholds.

    ``w = (1 - S(d; D/2, D)) * S(cos a; cos A, cos(A/2))`` with ``S`` the smoothstep, ``D = max_distance`` and
    ``A = max_normal_angle``: a match at most half the distance away and within half the angle counts fully, one beyond
    either threshold not at all. A hard cut-off would make the energy, and so the registration, jump when a distance
    crosses the threshold by one ulp. Points or matches without a normal (zero vectors) skip the angle factor.

    Args:
        dists: ``(P,)`` distances of the matches.
        point_normals: ``(P, 3)`` unit normals of the points, or ``None``.
        matched_normals: ``(P, 3)`` unit normals of the mesh at the matches, or ``None``.
        max_distance: distance beyond which the weight is 0 (> 0).
        max_normal_angle: angle between the normals, in degrees, beyond which the weight is 0 (``(0, 180]``).

    Returns:
        ``(P,)`` weights in ``[0, 1]``.

    Example:
        >>> import torch
        >>> acceptance_weights(torch.tensor([0.0, 0.5, 0.75, 1.0]), None, None, 1.0, 90.0).tolist()
        [1.0, 1.0, 0.5, 0.0]
    """
    w = 1.0 - _smoothstep(0.5 * max_distance, max_distance, dists)
    if point_normals is not None and matched_normals is not None:
        cos = (matched_normals * point_normals).sum(-1)
        has = ((matched_normals * matched_normals).sum(-1) > 0) & ((point_normals * point_normals).sum(-1) > 0)
        full, zero = math.cos(math.radians(0.5 * max_normal_angle)), math.cos(math.radians(max_normal_angle))
        w = torch.where(has, w * _smoothstep(zero, full, cos), w)
    return w


def interpolated_normals(vertex_normals: Tensor, faces: Tensor, face_idx: Tensor, bary: Tensor) -> Tensor:
    """Unit normals at surface points from the vertex normals of their faces (Phong), ``(P, 3)``.

    Continuous over the surface: on an edge or at a vertex every face sharing it gives the same normal (its
    barycentric coordinates weight the shared corners alike), unlike the face normals, which jump there. Zero where
    the interpolated vector vanishes (no normal).

    Args:
        vertex_normals: ``(V, 3)`` unit vertex normals (:meth:`~torchmeshmetric.Mesh.vertex_normals`).
        faces: ``(F, 3)`` faces.
        face_idx: ``(P,)`` face of each point.
        bary: ``(P, 3)`` barycentric coordinates of each point on its face.

    Returns:
        ``(P, 3)`` unit normals in ``vertex_normals``' dtype (rows of zeros where no normal exists).

    Example:
        >>> import torch
        >>> vn = torch.tensor([[0.0, 0, 1], [0, 1, 0], [0, 0, 1]])
        >>> interpolated_normals(vn, torch.tensor([[0, 1, 2]]), torch.tensor([0]), torch.tensor([[0.5, 0.5, 0]]))
        tensor([[0.0000, 0.7071, 0.7071]])
    """
    corners = vertex_normals[faces[face_idx]]  # (P, 3, 3)
    n = (bary[:, :, None] * corners).sum(1)
    norm = n.norm(dim=-1, keepdim=True)
    return torch.where(norm > 0, n / torch.where(norm > 0, norm, torch.ones_like(norm)), torch.zeros_like(n))


def geman_mcclure(sq: Tensor, sigma: float) -> Tensor:
    """Geman-McClure robust kernel on squared residuals: ``sigma^2 r^2 / (sigma^2 + r^2)`` (``~ r^2`` for small r).

    Bounded by ``sigma^2``: a residual much larger than ``sigma`` (an outlier) costs about ``sigma^2`` and has
    almost no gradient (Geman and McClure 1987; the robust scale of the registration's stages).

    Args:
        sq: squared residuals ``r^2``, any shape, non-negative.
        sigma: the robust scale (a length, in the units of the residuals).

    Returns:
        The kernel's values, same shape and dtype as ``sq``.

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
    vertex_normals: Tensor | None = None,
) -> Correspondences:
    """Find each point's exactly closest point on the mesh and weigh how plausible the match is (no gradient).

    The weight (:func:`acceptance_weights`) falls to 0 for a match farther than ``max_distance`` or whose normals
    (the point's, and the mesh's interpolated normal at the match) differ by more than ``max_normal_angle`` degrees.
    Points or matches without a normal (zero vectors, e.g. zero-area faces) skip the angle factor.

    Args:
        points: ``(P, 3)`` query points.
        point_normals: ``(P, 3)`` unit normals of the points, or ``None`` to skip the angle test.
        verts: ``(V, 3)`` mesh vertices.
        faces: ``(F, 3)`` mesh faces.
        max_distance: rejection distance (same units as the points).
        max_normal_angle: rejection angle in degrees.
        index: a :class:`~torchmeshmetric.MeshIndex` of ``(verts, faces)`` of the points' dtype, to query instead of
            building a structure for this call (the registration loop keeps one per mesh).
        vertex_normals: ``(V, 3)`` :meth:`~torchmeshmetric.Mesh.vertex_normals` of the mesh, when already known.

    Returns:
        :class:`Correspondences`.

    Example:
        >>> import torch
        >>> verts, faces = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]])
        >>> points = torch.tensor([[0.25, 0.25, 0.5], [0.25, 0.25, -3.0]])
        >>> corr = find_correspondences(points, None, verts, faces, max_distance=1.0, max_normal_angle=60.0)
        >>> corr.closest.tolist(), corr.dists.tolist(), corr.weights.tolist()
        ([[0.25, 0.25, 0.0], [0.25, 0.25, 0.0]], [0.5, 3.0], [1.0, 0.0])
    """
    with torch.no_grad():
        p = points.detach()
        v = verts.detach()
        if index is None:
            res = point_mesh_distance(p, v, faces)
        else:
            res = index.point_mesh_distance_unchecked(p, torch.tensor([p.shape[0]], device=p.device))
        vn = Mesh(v, faces, validate=False).vertex_normals() if vertex_normals is None else vertex_normals
        normals = interpolated_normals(vn, faces, res.face_idx, res.bary)
        pn = None if point_normals is None else point_normals.detach()
        weights = acceptance_weights(res.dists, pn, normals, max_distance, max_normal_angle)
        return Correspondences(res.face_idx, weights, res.dists, res.closest, res.bary, normals)


def data_term(
    points: Tensor, corr: Correspondences, *, sigma: float, plane_weight: float = 1.0, point_weight: float = 1.0
) -> Tensor:
    """Robust point-to-point + point-to-plane energy of ``points`` to their fixed matches (weighted mean).

    ``E = sum_i c_i [a rho(|p_i - q_i|^2) + b rho(((p_i - q_i) . n_i)^2)] / max(sum_i c_i, 1)`` with ``q_i`` and
    ``n_i`` the match's closest point and interpolated normal (``corr.closest``, ``corr.normals``, held fixed between
    refreshes), ``rho`` the Geman-McClure kernel and ``c_i`` the acceptance weights. Differentiable w.r.t. ``points``.

    Args:
        points: ``(P, 3)`` points (e.g. deformed data vertices).
        corr: their :class:`Correspondences`.
        sigma: Geman-McClure scale.
        plane_weight: ``b``, weight of point-to-plane.
        point_weight: ``a``, weight of point-to-point.

    Returns:
        0-dim energy (0 when every weight is 0).

    Example:
        >>> import torch
        >>> verts, faces = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]])
        >>> points = torch.tensor([[0.25, 0.25, 0.5], [0.25, 0.25, -3.0]])  # the second too far: weight 0
        >>> corr = find_correspondences(points, None, verts, faces, max_distance=1.0, max_normal_angle=60.0)
        >>> round(data_term(points, corr, sigma=1.0).item(), 6)  # rho(0.25) = 0.25 / 1.25, twice, over weight 1
        0.4
    """
    d = points - corr.closest
    e = point_weight * geman_mcclure((d * d).sum(-1), sigma)
    if plane_weight:
        e = e + plane_weight * geman_mcclure((d * corr.normals).sum(-1) ** 2, sigma)
    w = corr.weights
    return (w * e).sum() / w.sum().clamp_min(1.0)


def reverse_term(
    samples: Tensor,
    verts: Tensor,
    faces: Tensor,
    corr: Correspondences,
    *,
    sigma: float,
    plane_weight: float = 1.0,
    point_weight: float = 1.0,
) -> Tensor:
    """Robust energy of fixed ``samples`` to the fixed barycentric points of their (deforming) faces (weighted mean).

    ``E = sum_k r_k [a rho(|s_k - x_k|^2) + b rho(((s_k - x_k) . n_k)^2)] / max(sum_k r_k, 1)`` with
    ``x_k = sum_c b_kc v_{f_k c}``, ``(f_k, b_k)`` the face and barycentric coordinates found at the refresh
    (``corr.face_idx``, ``corr.bary``) and ``n_k`` the mesh's interpolated normal there (``corr.normals``, fixed).
    Differentiable w.r.t. ``verts``.

    Args:
        samples: ``(Q, 3)`` points (e.g. target samples).
        verts: ``(V, 3)`` vertices of the mesh they were matched to (e.g. the deformed source).
        faces: ``(F, 3)`` its faces.
        corr: the samples' :class:`Correspondences` on that mesh.
        sigma: Geman-McClure scale.
        plane_weight: ``b``, weight of point-to-plane.
        point_weight: ``a``, weight of point-to-point.

    Returns:
        0-dim energy.

    Example:
        >>> import torch
        >>> verts, faces = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]])
        >>> samples = torch.tensor([[0.25, 0.25, 0.5]])
        >>> corr = find_correspondences(samples, None, verts, faces, max_distance=1.0, max_normal_angle=60.0)
        >>> moved = verts.clone().requires_grad_()
        >>> energy = reverse_term(samples, moved, faces, corr, sigma=1.0)
        >>> round(energy.item(), 6)  # rho(0.25) = 0.25 / 1.25, point and plane
        0.4
        >>> energy.backward()
        >>> [round(g, 4) for g in moved.grad[:, 2].tolist()]  # descent lifts the face, each corner by its bary
        [-0.64, -0.32, -0.32]
    """
    x = (corr.bary[:, :, None] * verts[faces[corr.face_idx]]).sum(1)
    fixed = corr._replace(closest=samples)
    return data_term(x, fixed, sigma=sigma, plane_weight=plane_weight, point_weight=point_weight)


def embedded_deformation_regularizer(graph: DeformationGraph) -> Tensor:
    """Sumner's ``E_reg``: each node's affine map should predict its neighbours' deformed positions.

    ``E_reg = mean_{(j,k)} || R_j (g_k - g_j) + g_j + t_j - (g_k + t_k) ||^2 / mean ||g_k - g_j||^2`` (normalised by
    the squared edge length, so its weight does not depend on the node spacing). With rotations from the SO(3)
    exponential map this is an as-rigid-as-possible prior; no orthogonality term is needed.

    Args:
        graph: the deformation graph.

    Returns:
        0-dim energy (0 for a graph with a single node).

    Example:
        >>> import torch
        >>> verts, faces = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]])
        >>> from torchmeshmetric.registration import DeformationGraph
        >>> graph = DeformationGraph(verts, faces, node_spacing=0.5, num_neighbors=2)  # a node on each vertex
        >>> embedded_deformation_regularizer(graph).item()  # the identity
        0.0
        >>> with torch.no_grad():
        ...     _ = graph.translations[0].copy_(torch.tensor([0.0, 0.0, 1.0]))  # one node lifted: not rigid
        >>> embedded_deformation_regularizer(graph).item()
        1.0
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
        data_points: ``(S, 3)`` its fixed target point (the closest point at the refresh).
        data_normals: ``(S, 3)`` the target's interpolated unit normal there (zero where there is none).
        data_weights: ``(S,)`` acceptance weights.
        samples: ``(Q, 3)`` target samples of the reverse term.
        rev_faces: ``(Q, 3)`` int64 rows of ``need`` of the corners of each sample's assigned source face.
        rev_weights: ``(Q,)`` acceptance weights, times each sample's area weight in the registration (its samples
            are drawn by face index, each weighted by its face's area).
        rev_bary: ``(Q, 3)`` the fixed barycentric coordinates of each sample's point on that face.
        rev_normals: ``(Q, 3)`` the source's interpolated unit normal there at the refresh.
    """

    rest: Tensor
    vert_nodes: Tensor
    vert_weights: Tensor
    data_idx: Tensor
    data_points: Tensor
    data_normals: Tensor
    data_weights: Tensor
    samples: Tensor
    rev_faces: Tensor
    rev_weights: Tensor
    rev_bary: Tensor
    rev_normals: Tensor


def registration_ops() -> Any | None:
    """The C++ registration operators (``torch.ops.torchmeshmetric_registration``), or ``None`` without the extension.

    The extension is built first where needed (once per machine, the caller waits); ``None`` only where it cannot
    be built here, which holds for the whole process, so a registration never mixes the two formulations.
    """
    if native.try_load("bvh") is None:
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
        nodes, _, vidx, _, data_idx, _, _, data_w, _, rev_faces, rev_w, _, _, edges = self._buffers
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

    ``data_scale * (data_term(data) + reverse_weight * reverse_term(reverse)) + regularization * E_reg`` with
    the data vertices deformed by ``graph`` (the loop's energy, :func:`data_term`, :func:`reverse_term` and
    :func:`embedded_deformation_regularizer`), differentiable w.r.t. the graph's rotations and translations: the
    torch formulation's value and gradient within rounding (tested); forward and backward cost one pass over the
    terms instead of ~100 small torch ops. Threaded over torch's intra-op threads, with the same result for any
    thread count.
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
        ext = native.try_load("bvh") if graph.nodes.device.type == "cpu" else None
        if ext is None:
            return graph()
        rot = graph.rotation_matrices().contiguous()
        return ext.deform_vertices(
            rot, graph.translations.detach().contiguous(), graph.nodes.contiguous(), graph.verts.contiguous(),
            graph.vert_nodes.contiguous(), graph.vert_weights.contiguous(),
        )  # fmt: skip
