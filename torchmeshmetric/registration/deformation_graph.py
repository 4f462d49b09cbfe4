r"""Embedded deformation graph (Sumner, Schmid & Pauly 2007, *Embedded Deformation for Shape Manipulation*).

Nodes ``g_j`` are sampled on the source surface; node ``j`` carries a rotation ``R_j`` and a translation ``t_j``.
A vertex ``v_i`` skinned to its ``K`` nearest nodes with weights ``w_ij`` moves to

.. math::

    \\tilde v_i = \\sum_j w_{ij} \\left[ R_j (v_i - g_j) + g_j + t_j \\right].

Rotations are axis-angle vectors mapped onto SO(3) by kornia's exponential map
(:func:`kornia.geometry.conversions.axis_angle_to_rotation_matrix`, Rodrigues with a Taylor branch near 0), so every
``R_j`` is a rotation by construction: Sumner's orthogonality term ``E_rot`` is not needed, and gradients are
finite at the identity (where every parameter starts).

**Skinning is Euclidean**, not geodesic. Captured frames are triangle soups in practice — duplicate vertices,
zero-length edges, holes, several connected components, non-manifold edges — on which mesh-graph geodesics are
wrong or infinite, while Euclidean distances only need positions. The known drawback is that parts close in space
but far along the surface (a hand resting on a hip) share nodes; keep ``node_spacing`` below the smallest gap
between such parts (the default, 3 % of the bounding-box diagonal, is ~5 cm on a 1.8 m performer).
"""

from __future__ import annotations

import math

import numpy as np
import torch
from kornia.geometry.conversions import axis_angle_to_rotation_matrix
from torch import Tensor, nn

from torchmeshmetric import native
from torchmeshmetric._checks import EmptyInputError, check_finite, check_flag, check_float, check_int, check_shape
from torchmeshmetric.structures import Mesh

__all__ = [
    "DeformationGraph",
    "canonical_farthest_points",
    "embedded_deformation",
    "farthest_point_nodes",
    "skinning_weights",
]


def _coordinate_order(points: Tensor) -> Tensor:
    """``(P,)`` int64 permutation sorting ``points`` lexicographically by ``(x, y, z)``.

    The same order whatever order the points are stored in (equal points keep their stored order, and are the same
    point).
    """
    p = points.detach().cpu().numpy()
    return torch.from_numpy(np.lexsort((p[:, 2], p[:, 1], p[:, 0])).astype(np.int64)).to(points.device)


def _exact_mean(points: Tensor) -> Tensor:
    """The mean of ``points`` as an exactly rounded sum per coordinate: the same for any order and thread count."""
    p = points.detach().double().cpu()
    n = p.shape[0]
    return torch.tensor([math.fsum(p[:, j].tolist()) / n for j in range(3)], dtype=points.dtype, device=points.device)


def _canonical_start(points: Tensor) -> tuple[Tensor, Tensor, int]:
    """``(order, sorted, start)``: the points in coordinate order and the row nearest their exactly rounded mean.

    Farthest-point sampling over ``sorted`` from ``start`` breaks every tie (of the start and of each farthest point)
    by coordinates, never by the stored index: the first of ties in coordinate order wins.
    """
    order = _coordinate_order(points)
    q = points[order].contiguous()
    return order, q, int(((q - _exact_mean(q)) ** 2).sum(-1).argmin())


def _fps(p: Tensor, start: int, spacing: float) -> Tensor:
    """``(N,)`` int64 farthest-point choices among ``p`` from ``start`` until every point is within ``spacing``."""
    if p.device.type == "cpu" and p.dtype in (torch.float32, torch.float64):
        # The same choices in C++, bit for bit (tests/registration/test_farthest_point_sampling.py): a k-d tree
        # whose nodes a new centre cannot reach are skipped, instead of ~4 torch ops over every point per choice,
        # each a parallel region on large inputs (seconds on a loaded machine).
        ext = native.try_load("bvh")
        if ext is not None:
            return ext.farthest_point_sampling(p.contiguous(), start, spacing * spacing).to(p.device)
    chosen = [start]
    dmin = ((p - p[start]) ** 2).sum(-1)
    s2 = spacing * spacing
    while True:
        far = int(dmin.argmax())
        if float(dmin[far]) <= s2:
            break
        chosen.append(far)
        dmin = torch.minimum(dmin, ((p - p[far]) ** 2).sum(-1))
    return torch.tensor(chosen, dtype=torch.long, device=p.device)


def canonical_farthest_points(points: Tensor, count: int, area: float) -> Tensor:
    """Indices of ``count`` points of ``points`` chosen by farthest-point sampling, whatever order they are stored in.

    The first ``count`` choices of farthest-point sampling started at the point nearest to the points' mean (an exactly
    rounded sum), ties (of the start and of each farthest point) broken by the coordinates (lexicographic ``(x, y,
    z)``), never by index: the same *points* for any storage order. A continuous function of the coordinates except
    where two candidates tie, the discontinuity class of the graph's nodes (:func:`farthest_point_nodes`).

    ``area`` (the surface's area the points cover, in the points' units squared) only sets the covering radius of a
    first pass that overshoots ``count``; the farthest-point order does not depend on where it stops, so the result
    does not depend on ``area`` (only the cost does).

    Returns:
        ``(min(count, P),)`` int64 indices into ``points``, in the farthest-point order (the canonical order of the
        points when ``count >= P``; each distinct point once when there are no more distinct points than ``count``).

    Raises:
        NonFiniteError: a NaN or Inf coordinate (the sampling would never stop).
        TypeError: a ``count`` that is not an int.
        ValueError: a ``count`` below 0, an ``area`` that is negative or not finite.
    """
    # A NaN or Inf coordinate never lets farthest-point sampling stop (its distances never fall within the radius):
    # the loop ran forever, its list of choices growing (found 2026-12-07).
    check_finite(points, "points")
    # a NaN or infinite area made the radius NaN or infinite: the passes below never stopped either (review P)
    count = check_int(count, "count", 0)
    if not math.isfinite(area) or area < 0:
        raise ValueError(f"area: expected a finite area >= 0, found {area!r}")
    p = points.detach()
    n = p.shape[0]
    if count >= n:
        return _coordinate_order(p)
    order, q, start = _canonical_start(p)
    # Equal points are never chosen twice (their distance is 0): with no more distinct points than `count`, one pass
    # at radius 0 takes them all. The shrinking radius below would otherwise never reach `count` and run ~4000
    # passes to 1e-300 (a triangle soup of 642 distinct in 3840 stored vertices: 20.8 s per registration, review N).
    distinct = 1 + int((q[1:] != q[:-1]).any(dim=1).sum()) if n > 1 else n
    if distinct <= count:
        return order[_fps(q, start, 0.0)]
    # Farthest-point sampling to a covering radius r leaves ~0.59 A / r^2 points on a surface of area A (measured on
    # the demo at resolution 160): 0.7 sqrt(A / count) overshoots by ~20 %, and a shortfall retries finer.
    radius = 0.7 * math.sqrt(max(area, 0.0) / max(count, 1))
    while True:
        chosen = _fps(q, start, radius)
        if chosen.numel() >= count or radius == 0.0:
            break
        radius = 0.0 if radius < 1e-300 else radius * 0.85
    return order[chosen[:count]]


def farthest_point_nodes(points: Tensor, spacing: float, *, canonical: bool = False) -> Tensor:
    """Indices of nodes chosen among ``points`` by farthest-point sampling until every point is within ``spacing``.

    Duplicate points are never chosen twice (their distance to the chosen one is 0).

    Args:
        points: ``(P, 3)`` candidate positions (e.g. the source's referenced vertices).
        spacing: covering radius (absolute units).
        canonical: start at the point nearest to the exactly rounded mean and break ties by coordinates, not by
            index, so that the nodes do not depend on the order the points are stored in
            (``NonRigidOptions.sampling="canonical"``).

    Returns:
        ``(N,)`` int64 indices into ``points``, ``N >= 1``.

    Raises:
        EmptyInputError: no point.
        NonFiniteError: a NaN or Inf coordinate (the sampling would never stop).
        ValueError: a ``spacing`` that is negative or not finite.

    Example:
        >>> points = torch.tensor([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]])
        >>> farthest_point_nodes(points, 1.0).tolist(), farthest_point_nodes(points, 5.0).tolist()
        ([1, 3], [1])
    """
    canonical = check_flag(canonical, "canonical")
    if points.shape[0] == 0:
        raise EmptyInputError("points: expected at least one candidate node position, found none")
    check_finite(points, "points")  # a NaN or Inf never lets the sampling stop (canonical_farthest_points)
    if not math.isfinite(spacing) or spacing < 0:
        raise ValueError(f"spacing: expected a finite covering radius >= 0, found {spacing!r}")
    p = points.detach()
    if canonical:
        order, q, start = _canonical_start(p)
        return order[_fps(q, start, spacing)]
    start = int(((p - p.mean(0)) ** 2).sum(-1).argmin())
    return _fps(p, start, spacing)


def skinning_weights(points: Tensor, nodes: Tensor, num_neighbors: int) -> tuple[Tensor, Tensor]:
    """Sumner's skinning: each point to its ``K`` nearest nodes, ``w_j = (1 - d_j / d_{K+1})^2`` normalised.

    Args:
        points: ``(P, 3)`` points to skin.
        nodes: ``(N, 3)`` node positions.
        num_neighbors: ``K`` (clipped to the number of nodes).

    Returns:
        ``(idx (P, K) int64, weights (P, K))`` with rows summing to 1.

    Example:
        >>> nodes = torch.tensor([[0.0, 0, 0], [2, 0, 0], [4, 0, 0]])
        >>> idx, weights = skinning_weights(torch.tensor([[1.0, 0, 0]]), nodes, 2)  # halfway between two nodes
        >>> idx.tolist(), weights.tolist()
        ([[0, 1]], [[0.5, 0.5]])
    """
    n = nodes.shape[0]
    k = min(num_neighbors, n)
    d = torch.cdist(points, nodes, compute_mode="donot_use_mm_for_euclid_dist")
    dk, idx = d.topk(min(k + 1, n), dim=1, largest=False)
    # With no (K+1)-th node, 1.5x the farthest: it keeps a weight. No absolute term: a 1e-12 added here made the
    # weights of a graph of <= K nodes depend on the units (at 1e-12 units it dominated); a point on every node
    # (dmax 0) gets equal weights through the clamp below.
    dmax = dk[:, -1:] if n > k else dk[:, -1:] * 1.5
    w = (1 - dk[:, :k] / dmax.clamp_min(torch.finfo(d.dtype).tiny)).clamp_min(0) ** 2
    wsum = w.sum(1, keepdim=True)
    # All K nodes at the same distance as the (K+1)-th: fall back to equal weights.
    w = torch.where(wsum > 0, w / wsum.clamp_min(torch.finfo(d.dtype).tiny), torch.full_like(w, 1.0 / k))
    return idx[:, :k], w


def embedded_deformation(
    points: Tensor, nodes: Tensor, rotations: Tensor, translations: Tensor, idx: Tensor, weights: Tensor
) -> Tensor:
    """Apply an embedded deformation to skinned points (Sumner et al. 2007, Eq. 1 blended over nodes).

    Args:
        points: ``(P, 3)`` rest positions.
        nodes: ``(N, 3)`` node positions ``g_j``.
        rotations: ``(N, 3, 3)`` node rotations ``R_j``.
        translations: ``(N, 3)`` node translations ``t_j``.
        idx: ``(P, K)`` skinning node indices.
        weights: ``(P, K)`` skinning weights.

    Returns:
        ``(P, 3)`` deformed positions.

    Example:
        >>> nodes = torch.tensor([[0.0, 0, 0], [2, 0, 0], [4, 0, 0]])
        >>> points = torch.tensor([[1.0, 0, 0]])
        >>> idx, weights = skinning_weights(points, nodes, 2)
        >>> rotations, lift = torch.eye(3).expand(3, 3, 3), torch.tensor([[0.0, 0, 1]] * 3)  # every node moves up 1
        >>> embedded_deformation(points, nodes, rotations, lift, idx, weights).tolist()
        [[1.0, 0.0, 1.0]]
    """
    # Each node's map is affine, x -> R_j x + (g_j + t_j - R_j g_j): blend the K affine maps (one (P, K, 12)
    # gather), then apply the blended map once. Same value as blending the K moved positions.
    offset = nodes + translations - torch.einsum("nab,nb->na", rotations, nodes)
    affine = torch.cat([rotations.reshape(-1, 9), offset], dim=1)  # (N, 12)
    blended = (weights[..., None] * affine[idx]).sum(1)  # (P, 12)
    return torch.einsum("pab,pb->pa", blended[:, :9].reshape(-1, 3, 3), points) + blended[:, 9:]


class DeformationGraph(nn.Module):
    """Embedded deformation graph over a source mesh (Sumner et al. 2007), parameters at the identity.

    Nodes are chosen by farthest-point sampling among the referenced vertices (the vertices of any face, zero-area
    ones included) so that every one of them is within ``node_spacing * diagonal`` of a node. All vertices,
    unreferenced ones included, are skinned to their ``num_neighbors`` nearest nodes (Euclidean; see the module
    docstring).
    Two nodes are graph neighbours when they influence a common vertex (Sumner's rule).

    Args:
        verts: ``(V, 3)`` source vertices (rest pose).
        faces: ``(F, 3)`` source faces (used to find the referenced vertices; at least one of positive area).
        node_spacing: node covering radius relative to the bounding-box diagonal of the referenced vertices.
        num_neighbors: nodes per vertex ``K``.
        canonical: choose the nodes whatever order the vertices are stored in (see :func:`farthest_point_nodes`).

    Attributes:
        rotations: ``(N, 3)`` axis-angle parameters (radians), zeros = identity.
        translations: ``(N, 3)`` translation parameters.
        nodes: ``(N, 3)`` buffer of node positions; ``edges`` ``(E, 2)`` buffer of directed node pairs.

    Example:
        >>> import torch, trimesh
        >>> m = trimesh.creation.icosphere(subdivisions=2)
        >>> g = DeformationGraph(torch.tensor(m.vertices, dtype=torch.float32), torch.tensor(m.faces))
        >>> bool(torch.allclose(g(), g.verts))
        True
    """

    verts: Tensor
    nodes: Tensor
    vert_nodes: Tensor
    vert_weights: Tensor
    edges: Tensor

    def __init__(
        self,
        verts: Tensor,
        faces: Tensor,
        *,
        node_spacing: float = 0.03,
        num_neighbors: int = 4,
        canonical: bool = False,
    ) -> None:
        canonical = check_flag(canonical, "canonical")
        super().__init__()
        check_shape(verts, ("V", 3), "verts")
        check_float(verts, "verts")
        check_finite(verts, "verts")
        check_shape(faces, ("F", 3), "faces")
        if not node_spacing > 0:
            raise ValueError(f"node_spacing: expected a positive fraction of the diagonal, found {node_spacing}")
        if num_neighbors < 1:
            raise ValueError(f"num_neighbors: expected at least 1, found {num_neighbors}")
        verts = verts.detach()
        mesh = Mesh(verts, faces, validate=False)
        if not bool(mesh.surface_face_mask().any()):
            raise EmptyInputError("faces: expected at least one face of positive area, found none")
        # The candidates are the vertices of every face, zero-area ones included (they lie on the surface too): whether
        # a collinear face has a normal depends on the input's rounding (float32 rounding gives it one), and its
        # midpoint vertex would otherwise join or leave the candidates, and could become a node (docs/statistics.md).
        cand = verts[mesh.referenced_vertex_mask()]
        diag = float((cand.amax(0) - cand.amin(0)).norm())
        nodes = cand[farthest_point_nodes(cand, node_spacing * diag, canonical=canonical)]
        idx, w = skinning_weights(verts, nodes, num_neighbors)
        self.register_buffer("verts", verts)
        self.register_buffer("nodes", nodes)
        self.register_buffer("vert_nodes", idx)
        self.register_buffer("vert_weights", w)
        self.register_buffer("edges", _node_edges(idx, w, nodes))
        self.node_spacing = node_spacing
        self.rotations = nn.Parameter(torch.zeros_like(nodes))
        self.translations = nn.Parameter(torch.zeros_like(nodes))

    def rotation_matrices(self) -> Tensor:
        """``(N, 3, 3)`` node rotations from the axis-angle parameters (kornia's SO(3) exponential map)."""
        return axis_angle_to_rotation_matrix(self.rotations)

    def forward(self) -> Tensor:
        """``(V, 3)`` deformed vertices (all of them, unreferenced ones included)."""
        return embedded_deformation(
            self.verts, self.nodes, self.rotation_matrices(), self.translations, self.vert_nodes, self.vert_weights
        )

    def deform_vertices(self, index: Tensor) -> Tensor:
        """``(I, 3)`` deformed positions of the vertices ``index`` (``(I,)`` int64) only: ``forward()[index]``.

        Cheaper than :meth:`forward` when an energy needs a subset of the vertices (forward and backward scale with
        ``I``, not ``V``).
        """
        return embedded_deformation(
            self.verts[index], self.nodes, self.rotation_matrices(), self.translations, self.vert_nodes[index],
            self.vert_weights[index],
        )  # fmt: skip


_MARK_MAX_NODES = 4096  # n^2 booleans: 16 MB at most


def _node_edges(idx: Tensor, w: Tensor, nodes: Tensor) -> Tensor:
    """Directed node pairs ``(E, 2)`` sharing a vertex with positive weights; isolated nodes get their nearest."""
    n = nodes.shape[0]
    if n == 1:
        return torch.zeros(0, 2, dtype=torch.long, device=nodes.device)
    k = idx.shape[1]
    a = idx[:, :, None].expand(-1, k, k)
    b = idx[:, None, :].expand(-1, k, k)
    ok = (w[:, :, None] > 0) & (w[:, None, :] > 0) & (a != b)
    pairs = torch.stack([a[ok], b[ok]], 1)
    # Every node gets at least its nearest other node as a neighbour.
    d = torch.cdist(nodes, nodes)
    d.fill_diagonal_(float("inf"))
    nn_idx = d.argmin(1)
    ar = torch.arange(n, device=nodes.device)
    extra = torch.cat([torch.stack([ar, nn_idx], 1), torch.stack([nn_idx, ar], 1)])
    # Unique rows in lexicographic order through one integer key per pair (unique(dim=0) sorts rows: ~50x slower);
    # on small graphs by marking the keys among all n^2 (a tenth of the sort's time on ~200k pairs).
    keys = torch.cat([pairs, extra]) @ torch.tensor([n, 1], device=nodes.device)
    if n <= _MARK_MAX_NODES:
        seen = torch.zeros(n * n, dtype=torch.bool, device=nodes.device)
        seen[keys] = True
        key = seen.nonzero()[:, 0]
    else:
        key = torch.unique(keys)
    return torch.stack([key // n, key % n], 1)
