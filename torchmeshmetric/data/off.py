"""The one OFF reader and writer: vertices and triangles, the header's counts checked, errors naming file and line.

A plain file (no comments, counts on their own line, 3 values on every vertex line and 4 on every face line) is
parsed vectorised; anything else, or anything wrong, goes line by line, which names the line of the first problem
(both give the same result where both apply). :func:`off_bytes` writes every coordinate so that it reads back
bit for bit.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch

from torchmeshmetric.data.mesh_file import (
    MeshFileError,
    check_text,
    check_vertices,
    not_a_mesh,
    plain_float,
    plain_int,
    text_lines,
    values_per_line,
    without_bom,
)

if TYPE_CHECKING:
    from torchmeshmetric.structures import Mesh

__all__ = ["off_bytes", "parse_off"]


def parse_off(p: Path, data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of an OFF file; the header's counts must match what the file holds."""
    check_text(p, data)
    fast = _parse_off_fast(without_bom(data))
    if fast is not None:
        return fast
    return _parse_off_slow(p, data)


def _parse_off_fast(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """Vectorised parse of a plain OFF (no comments, counts on their own line, uniform rows), else ``None``.

    Every vertex line must hold 3 values and every face line 4: a total count alone would let a short line and a
    long one make up for each other and load other geometry (found by review).
    """
    if b"#" in data or b"\r" in data or not data.startswith(b"OFF\n"):
        return None
    head = data.split(b"\n", 2)
    if len(head) < 3:
        return None
    try:
        counts = [plain_int(t) for t in head[1].split()]
    except ValueError:
        return None
    if len(counts) not in (2, 3) or counts[0] < 0 or counts[1] < 0:
        return None
    nv, nf = counts[0], counts[1]
    body = head[2] if head[2].endswith(b"\n") else head[2] + b"\n"
    nl = np.flatnonzero(np.frombuffer(body, dtype=np.uint8) == 10)
    if nl.size != nv + nf or body.startswith(b"\n") or (np.diff(nl) == 1).any():
        return None  # truncated, more than declared or blank lines: the slow pass says which
    per_line = values_per_line(np.frombuffer(body, dtype=np.uint8), np.concatenate(([0], nl[:-1] + 1)))
    if (per_line[:nv] != 3).any() or (per_line[nv:] != 4).any():
        return None  # colours, polygons or bad rows: the slow pass takes or names them
    v_end = int(nl[nv - 1]) + 1 if nv else 0
    v_text, f_text = body[:v_end], body[v_end:]
    try:
        verts = np.fromstring(v_text, dtype=np.float64, sep=" ")
        faces = np.fromstring(f_text, dtype=np.int64, sep=" ")
    except ValueError:
        return None
    if verts.size != 3 * nv or faces.size != 4 * nf:
        return None  # colours, polygons or bad rows: the slow pass
    verts, faces = verts.reshape(-1, 3), faces.reshape(-1, 4)
    if (faces[:, 0] != 3).any() or not np.isfinite(verts).all():
        return None
    faces = faces[:, 1:]
    if faces.size and (faces.min() < 0 or faces.max() >= nv):
        return None
    return verts, np.ascontiguousarray(faces)


def _parse_off_slow(p: Path, data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """OFF line by line, naming the line of the first problem."""
    lines = [(n, ln.split(b"#", 1)[0].split()) for n, ln in enumerate(text_lines(p, data), 1)]
    lines = [(n, t) for n, t in lines if t]
    if not lines or not re.fullmatch(rb"C?N?OFF", lines[0][1][0]):
        found = lines[0][1][0].decode("latin-1")[:20] if lines else "nothing"
        raise not_a_mesh(p, f"an OFF file starts with 'OFF', found {found!r}")
    if b"BINARY" in lines[0][1][1:]:
        raise MeshFileError(f"path: '{p}' is a binary OFF file; only text OFF is supported")
    rest = lines[0][1][1:]
    body = lines[1:]
    if not rest:
        if not body:
            raise MeshFileError(f"path: '{p}' ends after its 'OFF' line (no vertex and face counts)")
        rest, body = body[0][1], body[1:]
    count_line = lines[0][0] if lines[0][1][1:] else lines[1][0]
    try:
        nv, nf = plain_int(rest[0]), plain_int(rest[1])
    except (ValueError, IndexError):
        raise MeshFileError(
            f"path: '{p}' line {count_line}: expected the counts 'vertices faces edges', found "
            f"{b' '.join(rest).decode('latin-1')!r}"
        ) from None
    if nv < 0 or nf < 0:
        raise MeshFileError(f"path: '{p}' line {count_line}: negative counts {nv} vertices, {nf} faces")
    if len(body) < nv:  # the file ends among its vertices: which of its lines were meant as faces is unknown
        raise MeshFileError(
            f"path: '{p}' is truncated: its header (line {count_line}) declares {nv} vertices and {nf} faces, "
            f"the file holds {len(body)} lines after it, fewer than its vertices"
        )
    if len(body) < nv + nf:
        raise MeshFileError(
            f"path: '{p}' is truncated: its header (line {count_line}) declares {nv} vertices and {nf} faces, "
            f"the file holds {nv} vertices and {len(body) - nv} faces"
        )
    if len(body) > nv + nf:
        extra = body[nv + nf][0]
        raise MeshFileError(
            f"path: '{p}' line {extra}: more lines than the header (line {count_line}) declares "
            f"({nv} vertices, {nf} faces)"
        )
    verts = np.empty((nv, 3))
    for i, (n, t) in enumerate(body[:nv]):
        if len(t) < 3:
            raise MeshFileError(f"path: '{p}' line {n}: vertex {i} has {len(t)} coordinate(s); expected 3")
        try:
            verts[i] = [plain_float(x) for x in t[:3]]
        except ValueError:
            raise MeshFileError(f"path: '{p}' line {n}: vertex {i} coordinates are not numbers") from None
    check_vertices(p, verts, "vertex", np.array([n for n, _ in body[:nv]]))
    faces = np.empty((nf, 3), dtype=np.int64)
    for j, (n, t) in enumerate(body[nv:]):
        try:
            corners = plain_int(t[0])
            idx = [plain_int(x) for x in t[1 : 1 + corners]]
        except ValueError:
            raise MeshFileError(f"path: '{p}' line {n}: face {j} is not a list of vertex indices") from None
        if corners != 3:
            raise MeshFileError(f"path: '{p}' line {n} has a face with {corners} corners; expected triangles")
        if len(idx) != 3:
            raise MeshFileError(f"path: '{p}' line {n}: face {j} declares 3 corners but lists {len(idx)}")
        if min(idx) < 0 or max(idx) >= nv:
            raise MeshFileError(
                f"path: '{p}' line {n}: face {j} has vertex indices {idx} outside [0, {nv - 1}] (OFF is 0-based)"
            )
        faces[j] = idx
    return verts, faces


def off_bytes(mesh: Mesh) -> bytes:
    """An OFF file of ``mesh`` whose coordinates read back bit for bit in the mesh's dtype.

    Each coordinate is the shortest decimal that reads back as the same value of the mesh's dtype (``repr`` for
    float64, numpy's shortest float32 form for float32), as :func:`parse_off` reads it (a float64, then the dtype):
    trimesh's writer gave 10 decimals, so coordinates of ~3e-11 were saved as zeros (found by review). 0-based
    triangles follow.

    Example:
        >>> import torch
        >>> from torchmeshmetric.structures import Mesh
        >>> m = Mesh(torch.tensor([[0.1, 0, 3e-11], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> print(off_bytes(m).decode(), end="")
        OFF
        3 1 0
        0.1 0.0 3e-11
        1.0 0.0 0.0
        0.0 1.0 0.0
        3 0 1 2
    """
    v = mesh.verts.detach().cpu()
    faces = mesh.faces.cpu().numpy().tolist()
    if v.dtype == torch.float32:
        flat32 = v.numpy().ravel()
        text = [str(x) for x in flat32]  # numpy's str of a float32: the shortest that rounds back to it
        # The reader parses a float64 and rounds it to float32: check that this double rounding gives the value
        # back, and write the exact float64 of any value it would not (none was found, but no proof excludes one).
        back = np.fromstring(" ".join(text), dtype=np.float64, sep=" ").astype(np.float32)
        for i in np.flatnonzero(back.view(np.int32) != flat32.view(np.int32)).tolist():
            text[i] = repr(float(flat32[i]))
    else:
        text = [repr(x) for x in v.double().numpy().ravel().tolist()]  # repr: the shortest that reads back
    rows = [" ".join(text[i : i + 3]) for i in range(0, len(text), 3)]
    lines = ["OFF", f"{len(rows)} {len(faces)} 0", *rows, *(f"3 {a} {b} {c}" for a, b, c in faces)]
    return ("\n".join(lines) + "\n").encode()
