"""The one OFF reader: vertices and triangles, the header's counts checked, errors naming the file and line.

A plain file (no comments, counts on their own line, uniform rows) is parsed vectorised; anything else, or anything
wrong, goes line by line, which names the line of the first problem (both give the same result where both apply).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from torchmeshmetric.data.mesh_file import MeshFileError, check_text, check_vertices, not_a_mesh, text_lines

__all__ = ["parse_off"]


def parse_off(p: Path, data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of an OFF file; the header's counts must match what the file holds."""
    check_text(p, data)
    fast = _parse_off_fast(data.removeprefix(b"\xef\xbb\xbf"))
    if fast is not None:
        return fast
    return _parse_off_slow(p, data)


def _parse_off_fast(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """Vectorised parse of a plain OFF (no comments, counts on their own line, uniform rows), else ``None``."""
    if b"#" in data or b"\r" in data or not data.startswith(b"OFF\n"):
        return None
    head = data.split(b"\n", 2)
    if len(head) < 3:
        return None
    try:
        counts = [int(t) for t in head[1].split()]
    except ValueError:
        return None
    if len(counts) not in (2, 3) or counts[0] < 0 or counts[1] < 0:
        return None
    nv, nf = counts[0], counts[1]
    body = head[2] if head[2].endswith(b"\n") else head[2] + b"\n"
    nl = np.flatnonzero(np.frombuffer(body, dtype=np.uint8) == 10)
    if nl.size != nv + nf or body.startswith(b"\n") or (np.diff(nl) == 1).any():
        return None  # truncated, more than declared or blank lines: the slow pass says which
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
        nv, nf = int(rest[0]), int(rest[1])
    except (ValueError, IndexError):
        raise MeshFileError(
            f"path: '{p}' line {count_line}: expected the counts 'vertices faces edges', found "
            f"{b' '.join(rest).decode('latin-1')!r}"
        ) from None
    if nv < 0 or nf < 0:
        raise MeshFileError(f"path: '{p}' line {count_line}: negative counts {nv} vertices, {nf} faces")
    if len(body) < nv + nf:
        held_v, held_f = min(len(body), nv), max(0, len(body) - nv)
        raise MeshFileError(
            f"path: '{p}' is truncated: its header (line {count_line}) declares {nv} vertices and {nf} faces, "
            f"the file holds {held_v} vertices and {held_f} faces"
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
            verts[i] = [float(x) for x in t[:3]]
        except ValueError:
            raise MeshFileError(f"path: '{p}' line {n}: vertex {i} coordinates are not numbers") from None
    check_vertices(p, verts, "vertex", np.array([n for n, _ in body[:nv]]))
    faces = np.empty((nf, 3), dtype=np.int64)
    for j, (n, t) in enumerate(body[nv:]):
        try:
            corners = int(t[0])
            idx = [int(x) for x in t[1 : 1 + corners]]
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
