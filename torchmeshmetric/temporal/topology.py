"""The edges of a triangle mesh and STED's neighbourhoods: which edges lie in the closed 1-ring of each vertex.

STED (Váša & Skala 2011) measures, around every vertex ``v``, the edges of its neighbourhood of topological width
1: the edges whose two ends both lie in ``{v} + ring(v)`` (the spokes of ``v`` and the edges between its
neighbours, the rim). An edge ``(a, b)`` lies in the neighbourhood of ``a``, of ``b`` and of every common neighbour
of ``a`` and ``b`` (on a manifold, the apexes of the edge's two triangles; more where the mesh is not one).
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import check_faces, check_int
from torchmeshmetric.structures import vertex_set_mask

__all__ = ["Neighbourhoods", "mesh_edges", "neighbourhoods"]


def referenced_vertices(faces: Tensor, num_verts: int) -> tuple[Tensor, Tensor]:
    """The vertices some face references and ``faces`` renumbered onto them: ``(V,)`` bool and ``(T, 3)`` int64.

    A vertex no face uses is not part of the surface: the temporal figures, exact and registered, leave it out (the
    registered form's tracked frame 0 and the exact forms' sequences alike; docs/temporal.md).

    Example:
        >>> used, faces = referenced_vertices(torch.tensor([[0, 2, 3]]), 4)
        >>> used.tolist(), faces.tolist()
        ([True, False, True, True], [[0, 1, 2]])
    """
    used = vertex_set_mask(faces, num_verts)
    return used, (torch.cumsum(used.long(), 0) - 1)[faces.long()]


def mesh_edges(faces: Tensor, num_verts: int) -> Tensor:
    """The ``(E, 2)`` undirected edges of ``faces`` (each once, ``a < b``, sorted), int64.

    Args:
        faces: ``(T, 3)`` integer faces, indices in ``[0, num_verts)``.
        num_verts: the vertex count ``V``.

    Returns:
        ``(E, 2)`` int64 edges; a degenerate face's repeated corner gives no edge.

    Raises:
        IndexRangeError: a face index outside ``[0, num_verts)``.

    Example:
        >>> mesh_edges(torch.tensor([[0, 1, 2], [0, 2, 3]]), 4).tolist()
        [[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]
    """
    check_faces(faces, check_int(num_verts, "num_verts", 0))  # an index >= num_verts gave edges of other vertices
    f = faces.long()
    pairs = torch.cat([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]  # a degenerate face's repeated corner is no edge
    lo, hi = pairs.min(dim=1).values, pairs.max(dim=1).values
    keys = torch.unique(lo * num_verts + hi)
    return torch.stack([keys // num_verts, keys % num_verts], dim=1)


class Neighbourhoods(NamedTuple):
    """Which edges lie in which vertex's neighbourhood: the pairs ``(vertex[i], edge[i])``.

    Attributes:
        edges: ``(E, 2)`` the mesh's edges (:func:`mesh_edges`).
        vertex: ``(P,)`` int64 the vertex of each pair.
        edge: ``(P,)`` int64 the edge (a row of ``edges``) of each pair.
        num_verts: the mesh's vertex count.

    Example:
        >>> import torch
        >>> n = neighbourhoods(torch.tensor([[0, 1, 2], [0, 2, 3]]), 4)  # two triangles sharing edge (0, 2)
        >>> n.edges.tolist(), n.num_verts, sorted(n.edge[n.vertex == 3].tolist())  # vertex 3 sees 0, 2, 3
        ([[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]], 4, [1, 2, 4])
    """

    edges: Tensor
    vertex: Tensor
    edge: Tensor
    num_verts: int


def neighbourhoods(faces: Tensor, num_verts: int) -> Neighbourhoods:
    """The edges of every vertex's neighbourhood of width 1 (see the module docstring).

    Args:
        faces: ``(T, 3)`` int faces.
        num_verts: the vertex count ``V``.

    Returns:
        :class:`Neighbourhoods` (on ``faces``' device).

    Example:
        >>> n = neighbourhoods(torch.tensor([[0, 1, 2], [0, 2, 3]]), 4)  # two triangles sharing edge (0, 2)
        >>> sorted(n.edge[n.vertex == 1].tolist())  # vertex 1's neighbourhood {0, 1, 2}: edges (0,1), (0,2), (1,2)
        [0, 1, 3]
        >>> sorted(n.edge[n.vertex == 0].tolist())  # vertex 0 sees every vertex: all five edges
        [0, 1, 2, 3, 4]
    """
    edges = mesh_edges(faces, num_verts)
    device = edges.device
    num_edges = edges.shape[0]
    # Directed adjacency, sorted by (source, target): the CSR rows give each vertex's neighbours, and the sorted keys
    # answer "is (u, w) an edge?" by binary search.
    directed = torch.cat([edges, edges.flip(1)])
    keys, order = torch.sort(directed[:, 0] * num_verts + directed[:, 1])
    targets = directed[order, 1]
    degree = torch.bincount(directed[:, 0], minlength=num_verts)
    start = torch.cumsum(degree, 0) - degree
    # For each edge (a, b), each neighbour w of a: w is a common neighbour when (w, b) is an edge too.
    a, b = edges[:, 0], edges[:, 1]
    counts = degree[a]
    edge_of = torch.repeat_interleave(torch.arange(num_edges, device=device), counts)
    within = torch.arange(int(counts.sum()), device=device) - torch.repeat_interleave(
        torch.cumsum(counts, 0) - counts, counts
    )
    w = targets[start[a][edge_of] + within]
    query = w * num_verts + b[edge_of]
    pos = torch.searchsorted(keys, query).clamp_max(keys.numel() - 1)
    common = (keys[pos] == query) & (w != b[edge_of])
    ids = torch.arange(num_edges, device=device)
    vertex = torch.cat([a, b, w[common]])
    edge = torch.cat([ids, ids, edge_of[common]])
    return Neighbourhoods(edges, vertex, edge, num_verts)
