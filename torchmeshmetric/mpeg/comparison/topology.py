r"""mmetric's topology check (``compare --mode topo``): is B the same connectivity as A, under given index maps?

A decoder that reorders faces and vertices (V-DMC's TFAN connectivity coder does) writes two text files with B's
mesh: the *face map*, one ``b a`` pair a line (face ``b`` of B is face ``a`` of A), and the *vertex map*, the same
for vertex indices. mmetric v1.1.7 then checks, in this order and stopping at the first failure:

1. A and B have the same number of triangles;
2. the face map gives every face index of B (``0 <= b < F``) exactly one face of A (``0 <= a < F``);
3. the vertex map gives every index below A's vertex count exactly one vertex of A;
4. every face of B, its corners mapped through the vertex map, is its mapped face of A up to a rotation of its
   corners (the orientation is kept: ``abc`` equals ``bca`` and ``cab``, not ``acb``).

Only the first column has to cover all indices ("bijective" in mmetric's words); two lines may name the same face
of A. Map files are read as mmetric reads them: a line is split at ``\n``, a ``\r`` is whitespace, the first two
unsigned integers of a line count and the rest of it is ignored (``1.5 2`` reads ``1`` then fails on ``.5``; a
negative value wraps to a huge index and is out of range); every line counts, so an empty line -- also one after the
last newline -- is malformed. Where mmetric prints ``Error: ...`` and carries on (a missing file, a bad line, an
index out of range, an index of B given twice) the library raises :class:`TopologyMapError` naming the file and the
line (1-based; mmetric counts lines from 0). A face of B using a vertex beyond A's vertex count, which mmetric
looks up past the end of its table, is refused the same way.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, Union

import numpy as np
from torch import Tensor

from torchmeshmetric._checks import DTypeError
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.structures import MeshLike, as_mesh

__all__ = ["TopologyComparison", "TopologyMapError", "read_topology_map", "topology_equivalence"]

MapLike = Union[str, os.PathLike, np.ndarray, Tensor]  # noqa: UP007 (a runtime alias)
Reason = Literal["matching", "triangle count", "face map", "vertex map", "orientation"]

_MAX_INDEX = 2**64 - 1  # mmetric reads indices as size_t
# std::istream >> size_t: leading whitespace (" \t\n\v\f\r"), an optional sign, decimal digits
_NUMBER = re.compile(rb"[ \t\n\v\f\r]*([+-]?)([0-9]+)")


class TopologyMapError(ValueError):
    """A topology map file is missing or malformed, or does not fit the meshes (the message names file and line).

    Example:
        >>> import os, tempfile
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     path = os.path.join(folder, "faces.txt")
        ...     with open(path, "w") as f:
        ...         _ = f.write("0 1" + chr(10) + "0 2" + chr(10))  # face 0 of B given twice
        ...     try:
        ...         read_topology_map(path, 3)
        ...     except TopologyMapError as error:  # a ValueError too
        ...         print(str(error).replace(folder, "FOLDER"))
        FOLDER/faces.txt:2: face 0 of mesh B is already mapped to face 1 of mesh A
    """


@dataclass(frozen=True)
class TopologyComparison:
    """The outcome of :func:`topology_equivalence`.

    Attributes:
        matching: B has A's connectivity under the two maps (mmetric's "Topologies are matching.").
        reason: ``"matching"``, or the first check that failed: ``"triangle count"``, ``"face map"`` / ``"vertex
            map"`` (an index of B without an entry), ``"orientation"``.
        triangles_a: triangle count of A.
        triangles_b: triangle count of B.
        first_unmapped: the first index of B the failing map leaves without an entry (``None`` otherwise).
        face_b: the first face of B that is not its mapped face of A (``"orientation"`` only).
        face_a: the face of A the face map gives it.
        corners_a: that face's vertex indices in A.
        corners_b: the corners of ``face_b`` mapped to A's vertex indices.

    Example:
        >>> import torch
        >>> v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
        >>> a = (v, torch.tensor([[0, 1, 2], [1, 3, 2]]))
        >>> b = (v, torch.tensor([[0, 2, 1], [1, 3, 2]]))  # face 0 turned over
        >>> t = topology_equivalence(a, b, torch.tensor([0, 1]), torch.tensor([0, 1, 2, 3]))
        >>> t.matching, t.reason, t.face_b, t.corners_a, t.corners_b
        (False, 'orientation', 0, (0, 1, 2), (0, 2, 1))
    """

    matching: bool
    reason: Reason
    triangles_a: int
    triangles_b: int
    first_unmapped: int | None = None
    face_b: int | None = None
    face_a: int | None = None
    corners_a: tuple[int, int, int] | None = None
    corners_b: tuple[int, int, int] | None = None

    def report(self) -> str:
        """The verdict in mmetric's words (its lines, brackets and trailing space included).

        Returns:
            One or three lines, without a trailing newline.

        Example:
            >>> TopologyComparison(False, "triangle count", 4, 960).report()
            'Topologies are different: number of triangles differs (A=4,B=960).'
        """
        if self.reason == "matching":
            return "Topologies are matching."
        if self.reason == "triangle count":
            return f"Topologies are different: number of triangles differs (A={self.triangles_a},B={self.triangles_b})."
        if self.reason in ("face map", "vertex map"):
            kind = self.reason.split()[0]
            return f"Topologies are different: topology {kind} map is not bijective."
        a, m = self.corners_a or (0, 0, 0), self.corners_b or (0, 0, 0)
        return (
            "Topologies are different: orientations are not preserved \n"
            f"modelA->Triangle[{self.face_a}] = [{a[0]},{a[1]},{a[2]})].\n"
            f"modelB(with mapped indices from modelA)->Triangle[{self.face_b}] = [{m[0]},{m[1]},{m[2]})]."
        )


def _parse_pair(line: bytes) -> tuple[list[int], int | None]:
    """The integers mmetric reads from one line (up to two, wrapped as size_t) and the index of the one it fails on."""
    values: list[int] = []
    pos = 0
    for k in range(2):
        m = _NUMBER.match(line, pos)
        if m is None:
            return values, k
        v = int(m.group(2))
        if v > _MAX_INDEX:  # strtoull overflow: the stream fails
            return values, k
        values.append((-v) % 2**64 if m.group(1) == b"-" else v)
        pos = m.end()
    return values, None


def read_topology_map(path: str | os.PathLike, count: int, kind: Literal["face", "vertex"] = "face") -> np.ndarray:
    r"""Read a topology map file (``b a`` a line: index ``b`` of B is index ``a`` of A) as mmetric reads it.

    Args:
        path: the text file (mmetric's ``--faceMapFile`` / ``--vertexMapFile``).
        count: A's triangle count (face map) or vertex count (vertex map): both columns must be below it.
        kind: ``"face"`` or ``"vertex"``, for messages.

    Returns:
        ``(count,)`` int64 array: entry ``b`` is the index of A that line ``b ...`` gives, ``-1`` where no line does.

    Raises:
        TopologyMapError: the file is missing or unreadable; a line without two unsigned integers; an index not
            below ``count``; an index of B on two lines. The message names the file and the 1-based line.

    Example:
        >>> import tempfile, pathlib
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "faces.txt"
        >>> _ = p.write_text("0 1\n1 0\n")
        >>> read_topology_map(p, 3).tolist()
        [1, 0, -1]
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise TopologyMapError(f"{kind} map file '{p}': cannot read it ({exc.strerror or exc})") from exc
    lines = data.split(b"\n")
    if lines[-1] == b"":
        lines.pop()  # the text after the last newline is a line only when not empty (std::getline)
    out = np.full(count, -1, dtype=np.int64)
    for n, line in enumerate(lines, start=1):
        values, failed = _parse_pair(line)
        where = f"{p}:{n}"
        for k, v in enumerate(values):
            if v >= count:
                col = "B" if k == 0 else "A"
                raise TopologyMapError(
                    f"{where}: {kind} index {v} (column {k + 1}, mesh {col}) out of range: mesh A has {count} "
                    f"{'vertices' if kind == 'vertex' else kind + 's'}"
                )
        if failed is not None:
            raise TopologyMapError(
                f"{where}: expected two unsigned {kind} indices 'b a' (B's index, then A's), found "
                f"{line.decode('utf-8', 'replace').strip()!r}"
            )
        b, a = values
        if out[b] >= 0:
            raise TopologyMapError(f"{where}: {kind} {b} of mesh B is already mapped to {kind} {out[b]} of mesh A")
        out[b] = a
    return out


def _map_array(m: MapLike, count: int, kind: Literal["face", "vertex"]) -> tuple[np.ndarray, str]:
    """A map from a file (read as mmetric does) or an array of A's indices (``-1`` = none); and how to name it."""
    if isinstance(m, (str, os.PathLike)):
        return read_topology_map(m, count, kind), f"{kind} map file '{m}'"
    raw = m.detach().cpu().numpy() if isinstance(m, Tensor) else np.asarray(m)
    if raw.size and (raw.dtype == np.bool_ or raw.dtype.kind not in "iu"):  # never cast: 0.4 would become face 0
        raise DTypeError(f"{kind}_map: expected an integer array of indices, found dtype {raw.dtype}")
    arr = raw.astype(np.int64, copy=False)
    if arr.shape != (count,) or (arr.size and (arr.min() < -1 or arr.max() >= count)):
        found = f"shape {tuple(arr.shape)}" if arr.shape != (count,) else f"values in [{arr.min()}, {arr.max()}]"
        raise TopologyMapError(
            f"{kind}_map: expected a ({count},) array of indices in [-1, {count - 1}], found {found}"
        )
    return arr, f"{kind}_map"


def _faces(m: MeshLike | TexturedMesh) -> tuple[np.ndarray, int]:
    mesh = m.mesh if isinstance(m, TexturedMesh) else as_mesh(m)
    return mesh.faces.detach().cpu().numpy().astype(np.int64), int(mesh.verts.shape[0])


def topology_equivalence(
    a: MeshLike | TexturedMesh, b: MeshLike | TexturedMesh, face_map: MapLike, vertex_map: MapLike
) -> TopologyComparison:
    """Whether B is A's connectivity under a face map and a vertex map, as mmetric's ``compare --mode topo``.

    Args:
        a: reference mesh (``--inputModelA``): ``(V, 3)`` vertices and ``(F, 3)`` faces, or a :class:`TexturedMesh`.
        b: the mesh to check (``--inputModelB``).
        face_map: ``--faceMapFile`` (a path), or a ``(F_A,)`` integer array: entry ``j`` = the face of A that face
            ``j`` of B is (``-1`` = none).
        vertex_map: ``--vertexMapFile``, or a ``(V_A,)`` integer array the same way for vertices.

    Returns:
        :class:`TopologyComparison` (``report()`` gives mmetric's lines). Like mmetric, a map is read only when the
        checks before it passed.

    Raises:
        TopologyMapError: a map file missing or malformed, or an array of the wrong shape or range (see
            :func:`read_topology_map`); a face of B using a vertex index beyond A's vertex count.

    Example:
        >>> import torch
        >>> v = torch.rand(4, 3)
        >>> a = (v, torch.tensor([[0, 1, 2], [0, 2, 3]]))
        >>> b = (v[[3, 2, 1, 0]], torch.tensor([[1, 0, 3], [3, 2, 1]]))  # faces swapped, vertices reversed
        >>> topology_equivalence(a, b, torch.tensor([1, 0]), torch.tensor([3, 2, 1, 0])).report()
        'Topologies are matching.'
    """
    fa, na = _faces(a)
    fb, _ = _faces(b)
    counts = (len(fa), len(fb))
    if len(fa) != len(fb):
        return TopologyComparison(False, "triangle count", *counts)
    fmap, _ = _map_array(face_map, len(fa), "face")
    if (fmap < 0).any():
        return TopologyComparison(False, "face map", *counts, first_unmapped=int(np.argmax(fmap < 0)))
    vmap, vname = _map_array(vertex_map, na, "vertex")
    if (vmap < 0).any():
        return TopologyComparison(False, "vertex map", *counts, first_unmapped=int(np.argmax(vmap < 0)))
    if fb.size and int(fb.max()) >= na:
        j = int(np.argmax((fb >= na).any(axis=1)))
        raise TopologyMapError(
            f"{vname}: face {j} of mesh B uses vertex {int(fb[j].max())}, beyond the {na} vertices of mesh A the map "
            "covers (mmetric reads past its table here)"
        )
    ta, mb = fa[fmap], vmap[fb]
    same = np.zeros(len(fb), dtype=bool)
    for r in range(3):  # A's corners equal B's mapped corners rotated by r
        same |= (ta == np.roll(mb, -r, axis=1)).all(axis=1)
    if same.all():
        return TopologyComparison(True, "matching", *counts)
    j = int(np.argmin(same))
    return TopologyComparison(
        False,
        "orientation",
        *counts,
        face_b=j,
        face_a=int(fmap[j]),
        corners_a=(int(ta[j, 0]), int(ta[j, 1]), int(ta[j, 2])),
        corners_b=(int(mb[j, 0]), int(mb[j, 1]), int(mb[j, 2])),
    )
