"""Plain PLY: a ``vertex`` then a triangle ``face`` element, binary or ASCII, read with numpy; written by ply_bytes.

Polygons, extra ASCII lines and ASCII values that are no numbers are refused here, naming the face or line. Anything
else (other elements, truncation, trailing binary bytes) is left to
:func:`~torchmeshmetric.data.trimesh_formats.read_with_trimesh`, which names the problem.
"""

from __future__ import annotations

import functools
import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

from torchmeshmetric._float32_text import float32_of_texts
from torchmeshmetric.data.mesh_file import MeshFileError, values_per_line, without_bom

__all__ = [
    "PlyArrays",
    "declared_counts",
    "header_end",
    "ply_bytes",
    "polygon_error",
    "read_plain_ply",
    "read_ply_file",
    "read_ply_point_arrays",
    "read_ply_points",
]


_PLY_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}


_END_HEADER = re.compile(rb"^end_header[ \t\r]*$", re.MULTILINE)


def read_ply_file(p: Path) -> bytes:
    """A PLY file's bytes without a UTF-8 byte-order mark, which trimesh reads past and OBJ and OFF accept too.

    Every PLY reader starts here: with the mark, the file was refused as "not a PLY" (found by review).
    """
    return without_bom(p.read_bytes())


def polygon_error(p: Path, face: int, corners: int, line: int | None = None) -> MeshFileError:
    """The error for a PLY face that is not a triangle (its line in ASCII), in the words of the OBJ and OFF readers.

    Polygons are refused, never triangulated: a count check alone (triangles against declared faces) was fooled by
    a quad beside a 2-corner face (found by review).
    """
    where = f"line {line} has a face with" if line is not None else f"face {face} has"
    return MeshFileError(f"path: '{p}' {where} {corners} corners; expected triangles")


def header_end(data: bytes) -> int:
    """Where a PLY's ``end_header`` line starts, or -1: that line itself, never the words in a comment."""
    m = _END_HEADER.search(data)
    return -1 if m is None else m.start()


class PlyArrays(NamedTuple):
    """What :func:`read_plain_ply` reads: the mesh and its per-vertex attributes (``None`` where the file has none).

    Attributes:
        verts: ``(V, 3)`` float64 positions.
        faces: ``(F, 3)`` int64 triangles.
        colors: ``(V, 3)`` float64 colours in ``[0, 255]`` from ``uchar`` ``red green blue``.
        normals: ``(V, 3)`` float64 ``nx ny nz`` (as their declared type holds them).
        uvs: ``(V, 2)`` float64 ``texture_u texture_v`` (mmetric's names for per-vertex texture coordinates).
    """

    verts: np.ndarray
    faces: np.ndarray
    colors: np.ndarray | None
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None


def read_plain_ply(p: Path) -> PlyArrays | None:
    """A plain PLY (a ``vertex`` then a triangle ``face`` element, nothing else) read with numpy, else ``None``.

    Binary (either byte order) or ASCII; vertex properties are scalars; the face element has one list property
    ``vertex_indices`` (or ``vertex_index``), every face a triangle. Other elements, truncation and trailing binary
    bytes return ``None`` and go through trimesh, which then names the problem.
    Returns :class:`PlyArrays`: colours from ``uchar`` ``red green blue`` properties, normals from ``nx ny nz``,
    texture coordinates from ``texture_u texture_v`` (the properties mmetric reads).

    Raises:
        MeshFileError: a face that is not a triangle, an ASCII line beyond the declared elements, an ASCII value that
            is no number or that its type cannot hold (naming the file and the face or line).
    """
    data = read_ply_file(p)
    declared_counts(p, data)
    header = _plain_header(data)
    if header is None:
        return None
    table = _read_ascii(p, header) if header.fmt == "ascii" else _read_binary(p, header)
    if table is None:
        return None
    cols, faces = table
    names = [pr[1] for pr in header.vprops]
    if "xyz" in cols:
        verts = cols["xyz"].astype(np.float64)
    else:
        verts = np.stack([cols["x"], cols["y"], cols["z"]], axis=1).astype(np.float64)
    colors = None
    if {"red", "green", "blue"} <= set(names):
        if not all(_PLY_TYPES[pr[0]] == "u1" for pr in header.vprops if pr[1] in ("red", "green", "blue")):
            return None  # float colours: trimesh's conversion decides
        colors = np.stack([cols["red"], cols["green"], cols["blue"]], axis=1).astype(np.float64)
    normals = _columns(cols, ("nx", "ny", "nz"))
    uvs = _columns(cols, ("texture_u", "texture_v"))
    return PlyArrays(verts, faces, colors, normals, uvs)


def _columns(cols: dict[str, np.ndarray], names: tuple[str, ...]) -> np.ndarray | None:
    """The vertex properties ``names`` side by side as float64, or ``None`` unless the file has all of them."""
    if not set(names) <= set(cols):
        return None
    return np.stack([cols[n] for n in names], axis=1).astype(np.float64)


class _Header(NamedTuple):
    fmt: str
    nv: int
    nf: int
    vprops: list[tuple[str, ...]]  # (type, name) of each vertex property
    count_t: str  # the face list's count type
    index_t: str  # the face list's index type
    body: bytes  # what follows the header
    first_line: int  # the file's line number of the body's first line


def _plain_header(data: bytes, *, points: bool = False) -> _Header | None:
    """The header of a plain PLY (see :func:`read_plain_ply`; ``points``: a lone ``vertex`` element, or with 0 faces).

    Returns ``None`` for any other header.
    """
    end = header_end(data)
    if not data.startswith(b"ply") or end < 0:
        return None
    stop = data.find(b"\n", end)
    if stop < 0:
        return None
    fmt = None
    elements: list[tuple[str, int, list[tuple[str, ...]]]] = []
    for line in data[:end].decode("latin-1").split("\n")[1:]:
        t = line.split()
        if not t or t[0] in ("comment", "obj_info"):
            continue
        if t[0] == "format" and len(t) >= 2:
            fmt = t[1]
        elif t[0] == "element" and len(t) == 3 and t[2].isascii() and t[2].isdigit():
            elements.append((t[1], int(t[2]), []))
        elif t[0] == "property" and elements:
            elements[-1][2].append(tuple(t[1:]))
        else:
            return None
    if points and [e[:2] for e in elements][1:] == [("face", 0)]:
        elements = elements[:1]  # a cloud that declares no face, as some writers do: its faces need no reading
    kinds = [e[0] for e in elements]
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian") or kinds not in (
        [["vertex"]] if points else [["vertex", "face"]]
    ):
        return None
    fprops: list[tuple[str, ...]]
    if points:
        (_, nv, vprops), nf, fprops = elements[0], 0, [("list", "uchar", "int", "vertex_indices")]
    else:
        (_, nv, vprops), (_, nf, fprops) = elements
    if any(len(pr) != 2 or pr[0] not in _PLY_TYPES for pr in vprops):
        return None
    names = [pr[1] for pr in vprops]
    if names[:3] != ["x", "y", "z"] and not {"x", "y", "z"} <= set(names):
        return None
    lists = [pr for pr in fprops if pr[0] == "list"]
    one_list = len(fprops) == 1 and len(lists) == 1 and len(lists[0]) == 4
    if not one_list or lists[0][3] not in ("vertex_indices", "vertex_index"):
        return None
    count_t, index_t = lists[0][1], lists[0][2]
    if count_t not in _PLY_TYPES or index_t not in _PLY_TYPES or _PLY_TYPES[index_t][0] == "f":
        return None
    first_line = data.count(b"\n", 0, stop + 1) + 1
    return _Header(fmt, nv, nf, vprops, count_t, index_t, data[stop + 1 :], first_line)


class _Body(NamedTuple):
    """The non-blank lines of an ASCII PLY body: how many values each holds, where it is, its line in the file."""

    counts: np.ndarray
    starts: np.ndarray  # first byte of each line in the body
    ends: np.ndarray  # its newline
    lines: np.ndarray


def _ascii_body(h: _Header) -> _Body:
    """Count the values of every line of an ASCII body, vectorised (a few passes over its bytes)."""
    body = h.body if h.body.endswith(b"\n") else h.body + b"\n"
    buf = np.frombuffer(body, dtype=np.uint8)
    nl = np.flatnonzero(buf == 10)
    starts = np.concatenate(([0], nl[:-1] + 1))
    counts = values_per_line(buf, starts)  # a control byte, which no number holds, counts as a space
    keep = np.flatnonzero(counts)
    return _Body(counts[keep], starts[keep], nl[keep], keep + h.first_line)


def _token(h: _Header, b: _Body, row: int, col: int) -> str:
    """The text of value ``col`` of non-blank body line ``row`` (for messages)."""
    return h.body[int(b.starts[row]) : int(b.ends[row])].split()[col].decode("latin-1")


def _vertex_token(h: _Header, b: _Body, col: int, row: int) -> str:
    """The text of vertex ``row``'s value ``col`` (vertices come first in the body)."""
    return _token(h, b, row, col)


def _check_vertex_lines(p: Path, h: _Header, b: _Body) -> None:
    """Every vertex line holds one value per vertex property (a total alone lets a long line make up for a short)."""
    k = len(h.vprops)
    bad = np.flatnonzero(b.counts[: h.nv] != k)
    if bad.size:
        i = int(bad[0])
        names = " ".join(pr[1] for pr in h.vprops)
        raise MeshFileError(
            f"path: '{p}' line {int(b.lines[i])}: vertex {i} has {int(b.counts[i])} value(s); its header declares "
            f"{k} ({names})"
        )


def _unfit(values: np.ndarray, code: str) -> np.ndarray:
    """Which ``values`` a PLY type cannot hold: out of its range, or (an integer type) not an integer."""
    if code[0] == "f":
        with np.errstate(over="ignore"):
            return np.isinf(values.astype(code)) & np.isfinite(values)
    info = np.iinfo(code)
    return ~((values == np.floor(values)) & (values >= info.min) & (values <= info.max))  # NaN: unfit


def _check_type(
    p: Path,
    h: _Header,
    b: _Body,
    values: np.ndarray,
    ply_type: str,
    what: tuple[str, str],
    first: int,
    col0: int,
    unfit: np.ndarray | None = None,
) -> None:
    """Refuse the first of ``values`` that its declared type cannot hold (a uchar 300 or -1, an int 0.7).

    Casting would wrap or truncate it silently (300 as uchar is 44; found by review). ``values`` is
    ``(rows, columns)``, row ``r`` on non-blank body line ``first + r``, column ``c`` its line's value ``col0 + c``;
    the message names ``what[0] r what[1]`` (``("vertex", " property 'red'")``) and quotes the value as written.
    ``unfit``: which values do not fit, where the caller knows better than ``values`` (float32 from the text).
    """
    code = _PLY_TYPES[ply_type]
    if code == "f8" or values.size == 0:
        return
    with np.errstate(invalid="ignore"):  # NaN: the mask below decides
        if code == "f4":
            fits = float(np.abs(values).max()) <= float(np.finfo(code).max)
        else:  # reductions first: no temporary array for a file that is right
            lo, hi = np.iinfo(code).min, np.iinfo(code).max
            fits = lo <= float(values.min()) and float(values.max()) <= hi and bool((np.floor(values) == values).all())
    if fits:  # correct rounding cannot overflow either
        return
    bad = _unfit(values, code) if unfit is None else unfit
    if not bad.any():
        return
    row, col = (int(x) for x in np.argwhere(bad)[0])
    text = _token(h, b, row + first, col0 + col)
    if code[0] == "f":
        why = f"beyond the range of {ply_type} (max {float(np.finfo(code).max):.3g})"
    elif values[row, col] != np.floor(values[row, col]):
        why = "not an integer"
    else:
        why = f"outside [{np.iinfo(code).min}, {np.iinfo(code).max}]"
    raise MeshFileError(
        f"path: '{p}' line {int(b.lines[row + first])}: {what[0]} {row}{what[1]} is {text}, which its declared type "
        f"{ply_type} cannot hold ({why})"
    )


def _vertex_columns(p: Path, h: _Header, b: _Body, table: np.ndarray) -> dict[str, np.ndarray]:
    """Each vertex property's column as its declared type holds it, every value checked to fit that type.

    A ``float`` property is float32, as mmetric reads it: each value the float32 nearest its decimal text, as
    ``strtof`` rounds it. ``table`` is numpy's float64 parse; rounding that to float32 rounds twice, which errs for a
    decimal just past a float32 midpoint (``mpeg --mode equ`` then disagreed with mm; review S), so those few values
    are rounded again from their text (:func:`~torchmeshmetric._float32_text.float32_of_texts`).
    """
    cols = {}
    for i, (ply_type, name) in enumerate(h.vprops):
        column = table[:, i : i + 1]
        code = _PLY_TYPES[ply_type]
        if code == "f4":
            col32 = float32_of_texts(column[:, 0], functools.partial(_vertex_token, h, b, i))
            # beyond FLT_MAX by correct rounding (a float64 on the overflow midpoint may be below it in the text)
            unfit = (np.isinf(col32) & np.isfinite(column[:, 0]))[:, None]
            _check_type(p, h, b, column, ply_type, ("vertex", f" property '{name}'"), 0, i, unfit)
            cols[name] = col32
            continue
        _check_type(p, h, b, column, ply_type, ("vertex", f" property '{name}'"), 0, i)
        cols[name] = column[:, 0].astype(code)
    return cols


def _read_ascii(p: Path, h: _Header) -> tuple[dict[str, np.ndarray], np.ndarray] | None:
    """``(vertex property columns, faces)`` of an ASCII body, else ``None``.

    ``None`` for fewer lines than the header declares (truncation): trimesh then names it with the declared counts.
    Each line's values are counted (a total alone let a long line make up for a short one).

    Raises:
        MeshFileError: a line without the values its element declares, a value that is no number or that its type
            cannot hold, a face that is not a triangle, or a line beyond the declared elements (naming the file,
            line and value).
    """
    b = _ascii_body(h)
    nv, nf, k = h.nv, h.nf, len(h.vprops)
    if b.counts.size < nv + nf:
        return None
    _check_vertex_lines(p, h, b)
    try:
        flat = np.fromstring(h.body, dtype=np.float64, sep=" ")
    except ValueError:
        flat = np.zeros(0)
    if flat.size != int(b.counts.sum()):  # older numpy stopped there with a warning, no error
        raise _not_a_number(p, h, b)
    cols = _vertex_columns(p, h, b, flat[: nv * k].reshape(nv, k))
    fcounts = b.counts[nv : nv + nf]
    fvalues = flat[nv * k : nv * k + int(fcounts.sum())]
    # triangles, as usual: no offsets to sum
    corners = fvalues[::4] if (fcounts == 4).all() else fvalues[np.cumsum(fcounts) - fcounts]
    _check_type(p, h, b, corners[:, None], h.count_t, ("face", " corner count"), nv, 0)
    listed = fcounts - 1
    bad = np.flatnonzero(listed != corners)
    if bad.size:
        j = int(bad[0])
        raise MeshFileError(
            f"path: '{p}' line {int(b.lines[nv + j])}: face {j} declares {int(corners[j])} corners but lists "
            f"{int(listed[j])}"
        )
    if (corners != 3).any():
        j = int(np.flatnonzero(corners != 3)[0])
        raise polygon_error(p, j, int(corners[j]), int(b.lines[nv + j]))
    if b.counts.size > nv + nf:
        # trimesh read the declared elements and dropped the rest: a writer whose face count was wrong lost faces in
        # silence (found by review); binary PLY and OFF refuse the same
        raise MeshFileError(
            f"path: '{p}' line {int(b.lines[nv + nf])}: more lines than the header declares ({nv} vertex, {nf} face "
            "elements)"
        )
    fl = fvalues.reshape(nf, 4)[:, 1:]
    _check_type(p, h, b, fl, h.index_t, ("face", " vertex index"), nv, 1)
    return cols, fl.astype(np.int64)


def _not_a_number(p: Path, h: _Header, b: _Body) -> MeshFileError:
    """The error for an ASCII body value that is no number, naming its line; numpy's parser says only that one is.

    Read value by value with the parser of the OBJ and OFF readers (:func:`~torchmeshmetric.data.mesh_file.
    plain_float`), on this error's path only.
    """
    from torchmeshmetric.data.mesh_file import plain_float

    for row in range(b.counts.size):
        for token in h.body[int(b.starts[row]) : int(b.ends[row])].split():
            try:
                plain_float(token)
            except ValueError:
                what = f"vertex {row}" if row < h.nv else f"face {row - h.nv}" if row < h.nv + h.nf else "a value"
                return MeshFileError(
                    f"path: '{p}' line {int(b.lines[row])}: {what} holds {token.decode('latin-1')!r}, which is not a "
                    "number"
                )
    return MeshFileError(f"path: '{p}' holds a value that is not a number after its header")


def _read_binary(p: Path, h: _Header) -> tuple[dict[str, np.ndarray], np.ndarray] | None:
    """``(vertex property columns, faces)`` of a binary body (either byte order), else ``None``.

    Raises:
        MeshFileError: a face that is not a triangle (the first one, by its number).
    """
    order = "<" if h.fmt == "binary_little_endian" else ">"
    vdt = np.dtype([(n, order + _PLY_TYPES[t]) for t, n in h.vprops])
    idx_t = order + _PLY_TYPES[h.index_t]
    fdt = np.dtype([("n", order + _PLY_TYPES[h.count_t]), ("i0", idx_t), ("i1", idx_t), ("i2", idx_t)])
    body, nv, nf = h.body, h.nv, h.nf
    # Every face before the first non-triangle lies at a triangle's stride, so that face's count is read right
    # whatever follows it (trimesh reads every list at the first one's length).
    whole = max(0, min(nf, (len(body) - nv * vdt.itemsize) // fdt.itemsize)) if len(body) >= nv * vdt.itemsize else 0
    counts = np.frombuffer(body, dtype=fdt, count=whole, offset=nv * vdt.itemsize)["n"] if whole else np.zeros(0)
    polygons = np.flatnonzero(counts != 3)
    if polygons.size:
        raise polygon_error(p, int(polygons[0]), int(counts[polygons[0]]))
    if len(body) != nv * vdt.itemsize + nf * fdt.itemsize:
        return None  # truncation or trailing bytes: trimesh names which
    vtab = np.frombuffer(body, dtype=vdt, count=nv)
    ftab = np.frombuffer(body, dtype=fdt, count=nf, offset=nv * vdt.itemsize)
    names = [pr[1] for pr in h.vprops]
    cols = {n: vtab[n] for n in names}
    if names[:3] == ["x", "y", "z"] and len({pr[0] for pr in h.vprops[:3]}) == 1:
        # x, y, z side by side: one strided view instead of three columns
        xyz = np.ndarray((nv, 3), dtype=vdt["x"], buffer=body, offset=0, strides=(vdt.itemsize, vdt["x"].itemsize))
        cols = {**cols, "xyz": xyz}
    faces = np.empty((nf, 3), dtype=np.int64)
    for k in range(3):  # one column at a time: three times faster than a (3,) subarray field
        faces[:, k] = ftab[f"i{k}"]
    return cols, faces


def declared_counts(p: Path, data: bytes) -> dict[str, int]:
    """The element counts of a PLY header, checked line by line (``path: 'f.ply' line 4: ...``).

    Every PLY the library reads passes this check: a ``format`` line of PLY 1.0 (the only version there is; trimesh
    read ``format ascii 2.0`` without a word), element counts of ASCII digits, no element named twice (the second
    count replaced the first, and the message blamed the faces), no property named twice in one element (binary numpy
    said ``field 'x' occurs more than once``, ASCII used the last column; all found by review).

    Raises:
        MeshFileError: not a PLY, no ``end_header`` line, binary data in the header, a missing or bad ``format``
            line, a bad ``element`` line, or an element or a property declared twice (naming the file and line).
    """
    from torchmeshmetric.data.mesh_file import not_a_mesh, plain_float, text_lines

    if not data.startswith(b"ply"):
        raise not_a_mesh(p, "a PLY file starts with 'ply'")
    end = header_end(data)
    if end < 0:
        raise MeshFileError(f"path: '{p}' has a PLY header without 'end_header'")
    declared: dict[str, int] = {}
    element_lines: dict[str, int] = {}
    properties: dict[str, int] = {}  # the current element's property names and their lines
    has_format = False
    for i, raw in enumerate(text_lines(p, data[:end]), start=1):
        t = raw.decode("latin-1").split()
        if t[:1] == ["format"]:
            try:
                version = plain_float(t[2].encode()) if len(t) == 3 else None
            except ValueError:
                version = None
            if t[1:2] not in (["ascii"], ["binary_little_endian"], ["binary_big_endian"]) or version != 1.0:
                raise MeshFileError(
                    f"path: '{p}' line {i}: {' '.join(t)!r} is not 'format ascii 1.0', 'format binary_little_endian "
                    "1.0' or 'format binary_big_endian 1.0' (PLY 1.0 is the only version)"
                )
            has_format = True
        # ASCII digits only: str.isdigit() takes "²", which int() refuses
        if t[:1] == ["element"] and (len(t) != 3 or not (t[2].isascii() and t[2].isdigit())):
            raise MeshFileError(f"path: '{p}' line {i}: {' '.join(t)!r} is not 'element NAME COUNT'")
        if t[:1] == ["element"]:
            if t[1] in element_lines:
                raise MeshFileError(
                    f"path: '{p}' line {i}: element '{t[1]}' is declared twice (first at line {element_lines[t[1]]}); "
                    "which of the two is meant cannot be told"
                )
            declared[t[1]] = int(t[2])
            element_lines[t[1]] = i
            properties = {}
        elif t[:1] == ["property"] and len(t) >= 3:
            name = t[-1]  # the name ends the line, after the type (or "list COUNT_TYPE INDEX_TYPE")
            if name in properties:
                raise MeshFileError(
                    f"path: '{p}' line {i}: property '{name}' is declared twice in its element (first at line "
                    f"{properties[name]}); which of the two is meant cannot be told"
                )
            properties[name] = i
    if not has_format:
        raise MeshFileError(f"path: '{p}' has a PLY header without a 'format' line (such as 'format ascii 1.0')")
    return declared


def read_ply_points(p: Path) -> tuple[np.ndarray, np.ndarray | None] | None:
    r"""A PLY point cloud (no faces, ``mm sample``'s output) as ``(verts, colors)``, every value checked; else ``None``.

    :func:`read_ply_point_arrays`'s positions and colours (see there).

    Raises:
        MeshFileError: naming the file (and line or vertex).

    Example:
        >>> import tempfile, pathlib
        >>> f = pathlib.Path(tempfile.mkdtemp()) / "c.ply"
        >>> head = "ply\nformat ascii 1.0\nelement vertex 2\n" + "".join(f"property float {c}\n" for c in "xyz")
        >>> _ = f.write_text(head + "end_header\n0 0 0\n1 2 3\n")
        >>> read_ply_points(f)[0].tolist()
        [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]]
    """
    arrays = read_ply_point_arrays(p)
    return None if arrays is None else (arrays.verts, arrays.colors)


def read_ply_point_arrays(p: Path) -> PlyArrays | None:
    r"""A PLY point cloud (no faces, ``mm sample``'s output) as :class:`PlyArrays`, every value checked; else ``None``.

    ``None`` when the header declares faces. The header is checked line by line and the body against its declared
    vertex count (a truncated file is refused, never read in part); coordinates must be finite (the message names
    the vertex and, in ASCII, its line). ``faces`` is ``(0, 3)``; ``colors`` are ``(V, 3)`` in ``[0, 255]`` from
    ``uchar red green blue``, ``normals`` from ``nx ny nz`` and ``uvs`` from ``texture_u texture_v``, each ``None``
    where the file has none. A point cloud with other elements or property types goes through trimesh, with the same
    count check (positions and colours only).

    Raises:
        MeshFileError: naming the file (and line or vertex).

    Example:
        >>> import tempfile, pathlib
        >>> f = pathlib.Path(tempfile.mkdtemp()) / "c.ply"
        >>> props = "".join(f"property float {c}\n" for c in ("x", "y", "z", "nx", "ny", "nz"))
        >>> _ = f.write_text("ply\nformat ascii 1.0\nelement vertex 1\n" + props + "end_header\n1 2 3 0 0 1\n")
        >>> a = read_ply_point_arrays(f)
        >>> a.faces.shape, a.normals.tolist(), a.colors
        ((0, 3), [[0.0, 0.0, 1.0]], None)
    """
    from torchmeshmetric.data.mesh_file import check_vertices, existing_mesh_file

    p = existing_mesh_file(p)
    data = read_ply_file(p)
    declared = declared_counts(p, data)
    if declared.get("face", 0) > 0:
        return None
    nv = declared.get("vertex", 0)
    h = _plain_header(data, points=True)
    if h is None:
        return _trimesh_points(p, nv)
    k = len(h.vprops)
    lines = None
    if h.fmt == "ascii":
        b = _ascii_body(h)
        total = int(b.counts.sum())
        if b.counts.size != nv and total != nv * k:
            raise MeshFileError(
                f"path: '{p}' declares {nv} vertex elements of {k} values but holds {total} values "
                f"({total / k:g} vertices): truncated or malformed"
            )
        # the values of its vertices on other lines than theirs: the first line that is wrong is among the first nv
        _check_vertex_lines(p, h, b)
        try:  # numpy's parser, not Python's float: "1_0" is no number
            values = np.fromstring(h.body, dtype=np.float64, sep=" ")
        except ValueError:
            values = np.zeros(0)
        if values.size != total:  # older numpy stopped there with a warning, no error
            raise _not_a_number(p, h, b)
        lines = b.lines
        cols = _vertex_columns(p, h, b, values.reshape(nv, k))
    else:
        read = _read_binary(p, h)
        if read is None:
            size = np.dtype([(n, _PLY_TYPES[t]) for t, n in h.vprops]).itemsize
            raise MeshFileError(
                f"path: '{p}' declares {nv} vertex elements of {size} bytes ({nv * size} bytes) but holds "
                f"{len(h.body)} bytes after its header: truncated or malformed"
            )
        cols = read[0]
    verts = np.stack([cols["x"], cols["y"], cols["z"]], axis=1).astype(np.float64)
    check_vertices(p, verts, "vertex", lines)
    names = [pr[1] for pr in h.vprops]
    colors = None
    if {"red", "green", "blue"} <= set(names):
        if not all(_PLY_TYPES[pr[0]] == "u1" for pr in h.vprops if pr[1] in ("red", "green", "blue")):
            return _trimesh_points(p, nv)  # float colours: trimesh's conversion decides, as for meshes
        colors = np.stack([cols["red"], cols["green"], cols["blue"]], axis=1).astype(np.float64)
    faces = np.zeros((0, 3), dtype=np.int64)
    return PlyArrays(
        verts, faces, colors, _columns(cols, ("nx", "ny", "nz")), _columns(cols, ("texture_u", "texture_v"))
    )


def _trimesh_points(p: Path, nv: int) -> PlyArrays:
    """A point-cloud PLY outside the plain form, through trimesh, its vertex count and coordinates checked."""
    import trimesh

    from torchmeshmetric.data.mesh_file import check_vertices

    try:
        cloud = trimesh.load(p, file_type="ply", process=False)
    except Exception as err:  # trimesh raises many exception types on malformed input
        raise MeshFileError(
            f"path: could not read point cloud '{p}' ({type(err).__name__}: {err}); its header declares {nv} "
            "vertex elements: truncated or malformed?"
        ) from err
    verts = np.asarray(getattr(cloud, "vertices", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
    if verts.shape[0] != nv:
        raise MeshFileError(f"path: '{p}' declares {nv} vertex elements but holds {verts.shape[0]} (truncated)")
    check_vertices(p, verts, "vertex")
    colors = getattr(cloud, "colors", None)
    rgb = None
    if colors is not None and len(colors) == nv and nv > 0:
        rgb = np.asarray(colors)[:, :3].astype(np.float64)
    return PlyArrays(verts, np.zeros((0, 3), dtype=np.int64), rgb)


def ply_bytes(verts: np.ndarray, faces: np.ndarray) -> bytes:
    """A binary little-endian PLY of a triangle mesh whose coordinates read back bit for bit.

    ``float`` properties for float32 (or narrower) vertices, ``double`` for float64: trimesh's writer stored float32
    whatever the mesh, so a float64 mesh lost its low bits (errors up to 2.6e-8 on a unit sphere).

    Args:
        verts: ``(V, 3)`` vertex positions (a floating numpy array).
        faces: ``(F, 3)`` vertex indices.

    Example:
        >>> v = np.array([[0.1, 0, 0], [1, 0, 0], [0, 1, 0]])
        >>> data = ply_bytes(v, np.array([[0, 1, 2]]))
        >>> data[: data.index(b"end_header")].decode().splitlines()[3]
        'property double x'
    """
    kind, code = ("double", "<f8") if verts.dtype == np.float64 else ("float", "<f4")
    if int(faces.max(initial=0)) > np.iinfo(np.int32).max:
        raise ValueError(f"faces: vertex index {int(faces.max())} beyond a PLY int")
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {verts.shape[0]}\n"
        + "".join(f"property {kind} {axis}\n" for axis in "xyz")
        + f"element face {faces.shape[0]}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rows = np.empty(faces.shape[0], dtype=[("n", "u1"), ("v", "<i4", (3,))])
    rows["n"], rows["v"] = 3, faces
    return header.encode("ascii") + np.ascontiguousarray(verts, dtype=code).tobytes() + rows.tobytes()
