"""mmetric's equality comparison of two meshes (``compare --mode equ``): the same triangles, in any order.

mmetric v1.1.7 walks the triangles of A in order and, for each, takes the first not yet matched triangle of B with
the same three corners (position, and UV / colour when both meshes have them, compared as float32 values) in the
same cyclic order -- or in either order with ``--unoriented``. Because "same corners up to a rotation (or a
reflection)" is an equivalence, that greedy walk leaves exactly the triangles of A beyond the count B has of their
class unmatched: the k-th triangle of A in a class is unmatched when B has fewer than k of that class. This module
counts that way (a sort, not mmetric's quadratic search), so the verdict, the count of different triangles and the
first unmatched triangle of A are mmetric's.

Not compared: per-vertex normals (the library's reader does not keep them; mmetric compares them when both files
carry them), and point clouds (mmetric's sorted-vertex comparison of meshes without faces).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from torchmeshmetric._checks import EmptyInputError
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh, as_textured_mesh
from torchmeshmetric.structures import MeshLike

__all__ = ["MeshEquality", "mesh_equality"]


@dataclass(frozen=True)
class MeshEquality:
    """The outcome of :func:`mesh_equality`.

    Attributes:
        equal: every triangle of A has its own equal triangle in B (and the counts agree).
        triangles_a: triangle count of A.
        triangles_b: triangle count of B.
        different_triangles: triangles of A without an equal triangle in B (``None`` when the counts differ:
            mmetric stops there).
        first_unmatched: index of the first triangle of A without an equal triangle in B, the one mmetric names
            with its default early return (``None`` when there is none or the counts differ).
        position_differences: positions that differ index by index, plus the difference of the position counts
            (mmetric's "Position differences", printed when the meshes differ).
        textures: ``"equal"``, ``"skipped"`` (neither mesh has a texture), ``"one missing"``, ``"dimensions"``
            or ``"<n> pixel differences"``.
    """

    equal: bool
    triangles_a: int
    triangles_b: int
    different_triangles: int | None
    first_unmatched: int | None
    position_differences: int
    textures: str

    def report(self, early_return: bool = True) -> str:
        """The verdict in mmetric's words (the lines its regression scripts look for).

        Args:
            early_return: as mmetric's ``--earlyReturn`` (default true): name the first unmatched triangle
                instead of counting them all.

        Returns:
            One or more lines, without a trailing newline.

        Example:
            >>> MeshEquality(True, 4, 4, 0, None, 0, "skipped").report()
            'meshes are equal'
        """
        if self.different_triangles is None:
            return f"meshes are not equal, number of triangles are different {self.triangles_a} vs {self.triangles_b}"
        if self.equal:
            return "meshes are equal"
        if early_return:
            return (
                "meshes are not equal, early return.\n"
                f"triangle number {self.first_unmatched} from A has no equivalent in B"
            )
        return (
            f"meshes are not equal, {self.different_triangles} different triangles\n"
            f"Position differences: {self.position_differences}"
        )


def _corner_rows(m: TexturedMesh, with_uv: bool, with_colour: bool) -> np.ndarray:
    """``(F, 3, D)`` float32 corner attributes: position, then UV and colour when compared."""
    faces = m.mesh.faces.numpy()
    parts = [m.mesh.verts.numpy().astype(np.float32)[faces]]
    if with_uv and m.uvs is not None:
        parts.append(m.uvs.numpy().astype(np.float32))
    if with_colour and m.colors is not None:
        parts.append(m.colors.numpy().astype(np.float32)[faces])
    # + 0.0 turns -0.0 into 0.0: C++ float == holds between them, and np.unique must see one value
    return np.concatenate(parts, axis=2) + np.float32(0.0)


def _lexicographic_min(candidates: np.ndarray) -> np.ndarray:
    """The lexicographically smallest of ``(F, K, 3)`` integer triples along K: a canonical triangle."""
    best = candidates[:, 0]
    for k in range(1, candidates.shape[1]):
        c = candidates[:, k]
        smaller = (c[:, 0] < best[:, 0]) | (
            (c[:, 0] == best[:, 0]) & ((c[:, 1] < best[:, 1]) | ((c[:, 1] == best[:, 1]) & (c[:, 2] < best[:, 2])))
        )
        best = np.where(smaller[:, None], c, best)
    return best


def _canonical(ids: np.ndarray, unoriented: bool) -> np.ndarray:
    """Each triangle of corner ids as the smallest of its rotations (and reflections when unoriented)."""
    a, b, c = ids[:, 0], ids[:, 1], ids[:, 2]
    orders = [(a, b, c), (b, c, a), (c, a, b)]
    if unoriented:
        orders += [(a, c, b), (c, b, a), (b, a, c)]
    return _lexicographic_min(np.stack([np.stack(o, axis=1) for o in orders], axis=1))


def _texture_status(a: TexturedMesh, b: TexturedMesh) -> str:
    if a.texture is None and b.texture is None:
        return "skipped"
    if a.texture is None or b.texture is None:
        return "one missing"
    if a.texture.shape != b.texture.shape:
        return "dimensions"
    diffs = int(np.any(a.texture != b.texture, axis=2).sum())
    return "equal" if diffs == 0 else f"{diffs} pixel differences"


def _position_differences(a: TexturedMesh, b: TexturedMesh) -> int:
    pa, pb = a.mesh.verts.numpy().astype(np.float32), b.mesh.verts.numpy().astype(np.float32)
    n = min(len(pa), len(pb))
    return abs(len(pa) - len(pb)) + int(np.any(pa[:n] != pb[:n], axis=1).sum())


def mesh_equality(a: TexturedMesh | MeshLike, b: TexturedMesh | MeshLike, unoriented: bool = False) -> MeshEquality:
    """Whether two meshes have the same triangles in any order, as mmetric's ``compare --mode equ`` decides.

    Corners are compared by position, and by UV (resp. colour) when both meshes have UVs (resp. per-vertex
    colours), all as float32 values; a triangle equals another when its corners are a rotation of the other's (or
    also a reflection with ``unoriented``). Each triangle of B matches at most one triangle of A.

    Args:
        a: reference mesh (mmetric's ``--inputModelA``), e.g. from :func:`load_textured_mesh`.
        b: distorted mesh (``--inputModelB``).
        unoriented: mmetric's ``--unoriented``: a triangle also equals its reversed copy.

    Raises:
        EmptyInputError: a mesh without triangles.

    Returns:
        :class:`MeshEquality` (the verdict, counts and mmetric's message through ``report()``).

    Example:
        >>> import torch
        >>> from torchmeshmetric.structures import Mesh
        >>> v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
        >>> a = TexturedMesh(Mesh(v, torch.tensor([[0, 1, 2], [1, 3, 2]])))
        >>> b = TexturedMesh(Mesh(v, torch.tensor([[3, 2, 1], [2, 0, 1]])))
        >>> mesh_equality(a, b).equal
        True
        >>> print(mesh_equality(a, TexturedMesh(Mesh(v, torch.tensor([[0, 2, 1], [1, 3, 2]])))).report())
        meshes are not equal, early return.
        triangle number 0 from A has no equivalent in B
    """
    a, b = as_textured_mesh(a, "a"), as_textured_mesh(b, "b")
    for name, m in (("a", a), ("b", b)):
        if m.mesh.faces.shape[0] == 0:  # no triangle to compare: "equal" would say nothing about the vertices
            raise EmptyInputError(
                f"{name}: expected a mesh with triangles, found {m.mesh.verts.shape[0]} vertices and no face (mm "
                "compares vertex-only models by their vertex lists instead: compare a.mesh.verts and b.mesh.verts)"
            )
    fa, fb = int(a.mesh.faces.shape[0]), int(b.mesh.faces.shape[0])
    textures = _texture_status(a, b)
    positions = _position_differences(a, b)
    if fa != fb:
        return MeshEquality(False, fa, fb, None, None, positions, textures)
    with_uv = a.uvs is not None and b.uvs is not None
    with_colour = a.colors is not None and b.colors is not None
    rows = np.concatenate([_corner_rows(a, with_uv, with_colour), _corner_rows(b, with_uv, with_colour)])
    _, corner_ids = np.unique(rows.reshape(-1, rows.shape[2]), axis=0, return_inverse=True)
    canonical = _canonical(corner_ids.reshape(-1, 3), unoriented)
    _, cls = np.unique(canonical, axis=0, return_inverse=True)
    cls = cls.reshape(-1)
    cls_a, cls_b = cls[:fa], cls[fa:]
    in_b = np.bincount(cls_b, minlength=int(cls.max()) + 1 if cls.size else 0)
    # rank of each triangle of A among the earlier triangles of A of its class (mmetric's greedy walk order)
    order = np.argsort(cls_a, kind="stable")
    sorted_cls = cls_a[order]
    starts = np.searchsorted(sorted_cls, sorted_cls, side="left")
    rank = np.empty(fa, dtype=np.int64)
    rank[order] = np.arange(fa) - starts
    unmatched = np.nonzero(rank >= in_b[cls_a])[0]
    first = int(unmatched[0]) if unmatched.size else None
    return MeshEquality(unmatched.size == 0, fa, fb, int(unmatched.size), first, positions, textures)
