"""The rows mmetric's subdivision pushes (``sdiv`` and ``compare --mode pcc``'s mesh sampling), in its order.

mmetric's ``meshToPcDiv`` walks the faces in order; each face pushes its three corners (with the face normal),
then ``subdivideTriangle`` pushes the face's three edge midpoints ``e1 = mid(v1, v2)``, ``e2 = mid(v2, v3)``,
``e3 = mid(v3, v1)`` (``a * 0.5 + b * 0.5`` in float32, for positions, UVs and colours, with the normal of the face
split) and recurses into the children ``(e1 e2 e3) (v1 e1 e3) (e1 v2 e2) (e2 v3 e3)``, depth first, while a face's
area is at least the threshold and the depth allows. Here the faces of one level are split together (numpy over all
of them); each row carries its face, its path of child numbers and its slot, and one ``lexsort`` puts the rows in
mmetric's depth-first (pre-order) push order, so the ``ModelBuilder``'s "first equal row wins" keeps mmetric's rows
in mmetric's order.
"""

from __future__ import annotations

import numpy as np

from torchmeshmetric.mpeg.core import _float32 as f32

__all__ = ["subdivision_rows"]


def subdivision_rows(
    corners: np.ndarray,
    attributes: np.ndarray,
    max_depth: int,
    area_threshold: float,
    texture_size: tuple[int, int] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points, face normals and attributes pushed by mmetric's recursive subdivision, in its push order.

    Args:
        corners: ``(F, 3, 3)`` float32 corner positions of the faces to sample (degenerate faces already left out).
        attributes: ``(F, 3, C)`` float32 corner attributes interpolated with the positions (UVs or colours;
            ``C = 0`` for none).
        max_depth: mmetric's maximum recursion depth (1: the corners only).
        area_threshold: faces with an area at least this are split (mmetric's ``areaThreshold``).
        texture_size: ``(W, H)`` of the texture for mmetric's ``mapThreshold`` (``attributes`` are then UVs): a
            face is also split while its corners' texels are more than one apart in x or y. ``None``: area only.

    Returns:
        ``(N, 3)`` points, ``(N, 3)`` normals and ``(N, C)`` attributes, in mmetric's order (duplicates included).

    Example:
        >>> tri = np.array([[[0, 0, 0], [4, 0, 0], [0, 4, 0]]], np.float32)
        >>> p, n, a = subdivision_rows(tri, np.zeros((1, 3, 0), np.float32), 2, 2.0)
        >>> p.tolist()[3:]  # the corners, then the midpoints of the split face
        [[2.0, 0.0, 0.0], [2.0, 2.0, 0.0], [0.0, 2.0, 0.0]]
    """
    p, attr = corners, attributes
    nf, c = p.shape[0], attr.shape[2]
    normal = f32.normalize(f32.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    out_pos, out_att, out_nrm = [p.reshape(-1, 3)], [attr.reshape(3 * nf, c)], [np.repeat(normal, 3, axis=0)]
    # each row's sort key: its face, the child numbers (1..4) of its node's path from the face, its slot (0..5:
    # corners then midpoints of the face; 0..2: midpoints of a deeper node)
    face = np.arange(nf)
    paths: list[np.ndarray] = []  # per level: the child number of each node at that level, for the current nodes
    out_face, out_paths, out_slot = [np.repeat(face, 3)], [np.zeros((3 * nf, 0), np.int8)], [np.tile([0, 1, 2], nf)]
    half = np.float32(0.5)
    for level in range(max_depth - 1):
        big = f32.area(p[:, 0], p[:, 1], p[:, 2]) >= area_threshold
        if texture_size is not None:
            big |= ~_texels_adjacent(attr, texture_size)
        p, attr, face = p[big], attr[big], face[big]
        paths = [d[big] for d in paths]
        n = p.shape[0]
        if n == 0:
            break
        nrm = f32.normalize(f32.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
        ep = p * half + p[:, [1, 2, 0]] * half
        ea = attr * half + attr[:, [1, 2, 0]] * half
        out_pos.append(ep.reshape(-1, 3))
        out_att.append(ea.reshape(3 * n, c))
        out_nrm.append(np.repeat(nrm, 3, axis=0))
        out_face.append(np.repeat(face, 3))
        out_paths.append(np.repeat(np.stack(paths, axis=1) if paths else np.zeros((n, 0), np.int8), 3, axis=0))
        out_slot.append(np.tile([0, 1, 2], n) + (3 if level == 0 else 0))
        p, attr = _children(p, ep), _children(attr, ea)
        face = np.tile(face, 4)
        paths = [np.tile(d, 4) for d in paths] + [np.repeat(np.arange(1, 5, dtype=np.int8), n)]
    depth = max(x.shape[1] for x in out_paths)
    digits = np.concatenate([np.pad(x, ((0, 0), (0, depth - x.shape[1]))) for x in out_paths])
    keys = [np.concatenate(out_slot), *(digits[:, k] for k in reversed(range(depth))), np.concatenate(out_face)]
    order = np.lexsort(keys)  # a path sorts before its extensions (padding 0 < child numbers 1..4): pre-order
    return np.concatenate(out_pos)[order], np.concatenate(out_nrm)[order], np.concatenate(out_att)[order]


def _texels_adjacent(uv: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Whether the three corners' texels (mmetric's ``mapCoordClamped``) are within one of each other in x and y."""
    w, h = size
    x = np.clip((uv[:, :, 0] * np.float32(w)).astype(np.int64), 0, w - 1)  # (int) truncates toward zero
    y = np.clip((uv[:, :, 1] * np.float32(h)).astype(np.int64), 0, h - 1)  # (the v flip keeps differences)
    return (np.ptp(x, axis=1) <= 1) & (np.ptp(y, axis=1) <= 1)


def _children(v: np.ndarray, e: np.ndarray) -> np.ndarray:
    """The children ``(e1 e2 e3) (v1 e1 e3) (e1 v2 e2) (e2 v3 e3)`` of ``(F, 3, C)`` corners and midpoints.

    Child ``k`` of node ``i`` is row ``k * F + i``.
    """
    v1, v2, v3 = v[:, 0], v[:, 1], v[:, 2]
    e1, e2, e3 = e[:, 0], e[:, 1], e[:, 2]
    kids = [(e1, e2, e3), (v1, e1, e3), (e1, v2, e2), (e2, v3, e3)]
    return np.concatenate([np.stack(k, axis=1) for k in kids])
