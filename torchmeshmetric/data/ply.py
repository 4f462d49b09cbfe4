"""The plain-PLY reader: a ``vertex`` then a triangle ``face`` element, binary or ASCII, read with numpy.

Anything else (other elements, polygons, truncation, trailing bytes) is left to
:func:`~torchmeshmetric.data.trimesh_formats.read_with_trimesh`, which names the problem.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

__all__ = ["read_plain_ply", "read_ply_points"]


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


def read_plain_ply(p: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
    """A plain PLY (a ``vertex`` then a triangle ``face`` element, nothing else) read with numpy, else ``None``.

    Binary (either byte order) or ASCII; vertex properties are scalars; the face element has one list property
    ``vertex_indices`` (or ``vertex_index``), every face a triangle. Anything else (other elements, polygons,
    truncation, trailing bytes) returns ``None`` and goes through trimesh, which then names the problem.
    Returns ``(verts, faces, colors)``, colours from ``uchar`` ``red green blue`` properties.
    """
    data = p.read_bytes()
    header = _plain_header(data)
    if header is None:
        return None
    read = _read_ascii if header.fmt == "ascii" else _read_binary
    table = read(header)
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
    return verts, faces, colors


class _Header(NamedTuple):
    fmt: str
    nv: int
    nf: int
    vprops: list[tuple[str, ...]]  # (type, name) of each vertex property
    count_t: str  # the face list's count type
    index_t: str  # the face list's index type
    body: bytes  # what follows the header


def _plain_header(data: bytes, *, points: bool = False) -> _Header | None:
    """The header of a plain PLY (see :func:`read_plain_ply`; ``points``: a lone ``vertex`` element), else ``None``."""
    end = data.find(b"end_header")
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
        elif t[0] == "element" and len(t) == 3 and t[2].isdigit():
            elements.append((t[1], int(t[2]), []))
        elif t[0] == "property" and elements:
            elements[-1][2].append(tuple(t[1:]))
        else:
            return None
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
    return _Header(fmt, nv, nf, vprops, count_t, index_t, data[stop + 1 :])


def _read_ascii(h: _Header) -> tuple[dict[str, np.ndarray], np.ndarray] | None:
    """``(vertex property columns, faces)`` of an ASCII body, else ``None``."""
    try:
        flat = np.fromstring(h.body, dtype=np.float64, sep=" ")
    except ValueError:
        return None
    k = len(h.vprops)
    if flat.size != h.nv * k + h.nf * 4:
        return None
    table = flat[: h.nv * k].reshape(h.nv, k)
    # each value as its declared type holds it (a "float" property is float32, as trimesh and mmetric read it)
    cols = {pr[1]: table[:, i].astype(_PLY_TYPES[pr[0]]) for i, pr in enumerate(h.vprops)}
    fl = flat[h.nv * k :].reshape(h.nf, 4)
    if (fl[:, 0] != 3).any() or (fl[:, 1:] != np.round(fl[:, 1:])).any():
        return None
    return cols, fl[:, 1:].astype(np.int64)


def _read_binary(h: _Header) -> tuple[dict[str, np.ndarray], np.ndarray] | None:
    """``(vertex property columns, faces)`` of a binary body (either byte order), else ``None``."""
    order = "<" if h.fmt == "binary_little_endian" else ">"
    vdt = np.dtype([(n, order + _PLY_TYPES[t]) for t, n in h.vprops])
    idx_t = order + _PLY_TYPES[h.index_t]
    fdt = np.dtype([("n", order + _PLY_TYPES[h.count_t]), ("i0", idx_t), ("i1", idx_t), ("i2", idx_t)])
    body, nv, nf = h.body, h.nv, h.nf
    if len(body) != nv * vdt.itemsize + nf * fdt.itemsize:
        return None  # polygons, truncation or trailing bytes: trimesh names which
    vtab = np.frombuffer(body, dtype=vdt, count=nv)
    ftab = np.frombuffer(body, dtype=fdt, count=nf, offset=nv * vdt.itemsize)
    if (ftab["n"] != 3).any():
        return None
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


def _declared(p: Path, data: bytes) -> dict[str, int]:
    """The element counts of a PLY header, checked line by line (``path: 'f.ply' line 4: ...``)."""
    from torchmeshmetric.data.mesh_file import MeshFileError, not_a_mesh, text_lines

    if not data.startswith(b"ply"):
        raise not_a_mesh(p, "a PLY file starts with 'ply'")
    end = data.find(b"end_header")
    if end < 0:
        raise MeshFileError(f"path: '{p}' has a PLY header without 'end_header'")
    declared: dict[str, int] = {}
    for i, raw in enumerate(text_lines(p, data[:end]), start=1):
        t = raw.decode("latin-1").split()
        if t[:1] == ["element"] and (len(t) != 3 or not t[2].isdigit()):
            raise MeshFileError(f"path: '{p}' line {i}: {' '.join(t)!r} is not 'element NAME COUNT'")
        if t[:1] == ["element"]:
            declared[t[1]] = int(t[2])
    return declared


def read_ply_points(p: Path) -> tuple[np.ndarray, np.ndarray | None] | None:
    r"""A PLY point cloud (no faces, ``mm sample``'s output) as ``(verts, colors)``, every value checked; else ``None``.

    The header is checked line by line and the body against its declared vertex count (a truncated file is refused,
    never read in part); coordinates must be finite (the message names the vertex and, in ASCII, its line).
    ``colors`` are ``(V, 3)`` in ``[0, 255]`` from ``uchar red green blue``, else ``None``. A point cloud with
    other elements or property types goes through trimesh, with the same count check.

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
    from torchmeshmetric.data.mesh_file import MeshFileError, check_vertices, existing_mesh_file

    p = existing_mesh_file(p)
    data = p.read_bytes()
    declared = _declared(p, data)
    if declared.get("face", 0) > 0:
        return None
    nv = declared.get("vertex", 0)
    h = _plain_header(data, points=True)
    if h is None:
        return _trimesh_points(p, nv)
    k = len(h.vprops)
    lines = None
    if h.fmt == "ascii":
        flat = np.array(h.body.split(), dtype=object)
        try:
            values = flat.astype(np.float64)
        except ValueError:
            raise MeshFileError(f"path: '{p}' holds a value that is not a number after its header") from None
        if values.size != nv * k:
            raise MeshFileError(
                f"path: '{p}' declares {nv} vertex elements of {k} values but holds {values.size} values "
                f"({values.size / k:g} vertices): truncated or malformed"
            )
        first = data[: data.find(b"end_header")].count(b"\n") + 2  # the line of the first vertex
        lines = np.arange(nv) + first
        table = values.reshape(nv, k)
        cols = {pr[1]: table[:, i].astype(_PLY_TYPES[pr[0]]) for i, pr in enumerate(h.vprops)}
    else:
        read = _read_binary(h)
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
    return verts, colors


def _trimesh_points(p: Path, nv: int) -> tuple[np.ndarray, np.ndarray | None]:
    """A point-cloud PLY outside the plain form, through trimesh, its vertex count and coordinates checked."""
    import trimesh

    from torchmeshmetric.data.mesh_file import MeshFileError, check_vertices

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
    return verts, rgb
