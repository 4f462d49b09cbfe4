"""mmetric's ``reindex --sort oriented`` (also IBSM's and ``compare --mode pcc``'s reorder of a mesh's faces).

The float32 arithmetic of the grid sampling and of the rasterizer starts from a face's first corner, so the figures
depend on this order: corners merged on equal (position, UV or colour) and sorted, each face rotated to start at
its smallest corner, duplicate faces dropped, faces sorted.
"""

from __future__ import annotations

import numpy as np
import torch

from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.structures import Mesh

__all__ = ["oriented_faces", "oriented_reindex"]


def _lex_groups(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Dense lexicographic rank of every row of ``keys`` and the first (smallest) row index of every rank.

    The same as ``np.unique(keys, axis=0, return_index=True, return_inverse=True)`` (numeric order column by column,
    ``-0.0 == 0.0``), through one stable ``lexsort`` instead of a sort of row records.
    """
    order = np.lexsort(keys.T[::-1])
    ks = keys[order]
    new = np.ones(order.size, dtype=bool)
    new[1:] = np.any(ks[1:] != ks[:-1], axis=1)
    rank = np.empty(order.size, dtype=np.int64)
    rank[order] = np.cumsum(new) - 1
    return rank, order[new]


def oriented_faces(corner_keys: np.ndarray) -> np.ndarray:
    """The faces of mmetric's ``reorder(..., "oriented")`` over corners ``(3k, 3k+1, 3k+2)`` of face ``k``.

    Equal corner keys are one corner; the corners are sorted, each face rotated to start at its smallest corner
    (orientation kept), duplicate faces dropped and the faces sorted.

    Args:
        corner_keys: ``(3F, C)`` each face corner's key (position, then UV or colour).

    Returns:
        ``(F', 3)`` rows into ``corner_keys`` (the first corner of each equal key).

    Example:
        >>> keys = np.array([[2.0], [0], [1], [0], [1], [2]])
        >>> oriented_faces(keys).tolist()
        [[1, 2, 0]]
    """
    rank, first = _lex_groups(corner_keys)
    tri = rank.reshape(-1, 3)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    rot1 = (b < a) & (b <= c)
    rot2 = ~rot1 & (c <= a) & (c < b)
    out = tri.copy()
    out[rot1] = np.stack([b, c, a], axis=1)[rot1]
    out[rot2] = np.stack([c, a, b], axis=1)[rot2]
    _, kept = _lex_groups(out)  # sorted faces, each once
    return first[out[kept]]


def oriented_reindex(mesh: TexturedMesh) -> TexturedMesh:
    """The ``reindex --sort oriented`` of mmetric: equal corners merged and sorted, faces rotated and sorted.

    Corners are equal when position and UV (or vertex colour) are equal. Each face is rotated to start at its
    smallest corner (orientation kept), duplicate faces are dropped and the faces sorted; the vertices are the
    distinct corners in sorted order (mmetric's numbering, which its ``--outputModel`` files show). Positions are
    unchanged; only the order of corners within faces and of faces moves, which moves the float32 arithmetic of the
    grid sampling (mmetric's ray-triangle test starts from a face's first corner).

    Example:
        >>> m = TexturedMesh(Mesh(torch.eye(3), torch.tensor([[2, 0, 1], [0, 1, 2]])))
        >>> oriented_reindex(m).mesh.faces.shape[0]
        1
    """
    verts = mesh.mesh.verts.detach().cpu().numpy().astype(np.float32)
    faces = mesh.mesh.faces.detach().cpu().numpy()
    pos = verts[faces].reshape(-1, 3)
    keys = [pos]
    uv = col = None
    # mmetric's key: position, then UV and colour whenever the model has them (with or without a texture)
    if mesh.uvs is not None:
        uv = mesh.uvs.detach().cpu().numpy().astype(np.float32).reshape(-1, 2)
        keys.append(uv)
    if mesh.colors is not None:
        col = mesh.colors.detach().cpu().numpy().astype(np.float32)[faces].reshape(-1, 3)
        keys.append(col)
    corner_keys = np.concatenate(keys, axis=1)
    tri = oriented_faces(corner_keys)
    used = np.unique(tri)
    used = used[np.lexsort(corner_keys[used].T[::-1])]  # the corners in sorted order, as mmetric numbers them
    renumber = np.empty(corner_keys.shape[0], dtype=np.int64)
    renumber[used] = np.arange(used.size)
    new_faces = torch.from_numpy(renumber[tri])
    new_mesh = Mesh(torch.from_numpy(np.ascontiguousarray(pos[used])), new_faces)
    return TexturedMesh(
        new_mesh,
        None if uv is None else torch.from_numpy(np.ascontiguousarray(uv[tri])),
        mesh.texture,
        None if col is None else torch.from_numpy(np.ascontiguousarray(col[used])),
    )
