"""The one Wavefront OBJ (and MTL) reader: positions, UVs, faces, materials, with file:line errors.

Every OBJ the library reads goes through :func:`parse_obj` — :func:`~torchmeshmetric.data.load_mesh`,
:func:`~torchmeshmetric.data.load_sequence` and :func:`~torchmeshmetric.mpeg.load_textured_mesh` — so a file is one
geometry everywhere and a bad file gives the same message on every path (see the docs' *Bad input* page).

Two passes share one set of rules. The fast pass classifies lines by their first bytes and parses every number of a
kind in one call (numpy's C parser, correctly rounded like Python's ``float``); whenever anything is unusual (line
continuations, a comment after a statement, mixed corner forms) or wrong, the slow pass parses the file statement by
statement and raises the error naming the file and line. The two give identical results on every file the fast pass
accepts (tested against each other).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from torchmeshmetric._checks import check_flag
from torchmeshmetric.data.mesh_file import (
    MeshFileError,
    check_text,
    not_a_mesh,
    plain_float,
    plain_int,
    text_lines,
    without_bom,
)

if TYPE_CHECKING:
    from torchmeshmetric.structures import Mesh

__all__ = ["MtlMaterial", "ObjData", "obj_bytes", "obj_mtllibs", "parse_mtl", "parse_obj", "read_obj_triangles"]


@dataclass(frozen=True, eq=False)
class ObjData:
    """What an OBJ file holds, in file order, with the line of every element (for messages).

    Attributes:
        verts: ``(V, 3)`` float64 positions.
        vert_lines: ``(V,)`` 1-based line of each ``v``.
        vert_colors: ``(V, 3)`` float64 ``v x y z r g b`` colours, or ``None`` unless every vertex has one.
        uvs: ``(T, 2)`` float64 texture coordinates (``vt u v``; a third ``w`` is dropped).
        uv_lines: ``(T,)`` 1-based line of each ``vt``.
        corners: ``(C,)`` 0-based vertex index of every face corner (negative indices resolved).
        corner_uvs: ``(C,)`` 0-based ``vt`` index of every corner, ``-1`` where the corner has none.
        face_sizes: ``(F,)`` corners per face (3 for a triangle).
        face_lines: ``(F,)`` 1-based line of each ``f``.
        face_materials: ``(F,)`` index into ``materials`` of the ``usemtl`` in force, ``-1`` before any.
        materials: names given to ``usemtl``, in order of first use.
        material_lines: 1-based line of the first ``usemtl`` of each name.
        mtllibs: ``(name, line)`` of every ``mtllib`` statement (the name is the rest of the line).
        normals: ``(N, 3)`` float64 normals (``vn x y z``), read with ``parse_obj(..., normals=True)``, else empty.
        normal_lines: ``(N,)`` 1-based line of each ``vn``.
        normal_indexed: whether any face corner names a normal (``v/vt/vn`` or ``v//vn``).
        color_rows: ``(K, 3)`` float64 colours of the ``v`` lines that have one, in file order (``vert_colors``
            when every vertex has one; mmetric's colour list holds these rows whether or not all have one).
    """

    verts: np.ndarray
    vert_lines: np.ndarray
    vert_colors: np.ndarray | None
    uvs: np.ndarray
    uv_lines: np.ndarray
    corners: np.ndarray
    corner_uvs: np.ndarray
    face_sizes: np.ndarray
    face_lines: np.ndarray
    face_materials: np.ndarray
    materials: list[str] = field(default_factory=list)
    material_lines: list[int] = field(default_factory=list)
    mtllibs: list[tuple[str, int]] = field(default_factory=list)
    normals: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    normal_lines: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    normal_indexed: bool = False
    color_rows: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """``(F', 3)`` vertex and ``vt`` indices, polygons fanned from their first corner (as mmetric does).

        Returns:
            ``(faces, face_uvs)``, both ``(F', 3)`` int64; ``face_uvs`` is ``-1`` where a corner has no ``vt``.
        """
        sizes = self.face_sizes
        if sizes.size and int(sizes.min()) == int(sizes.max()) == 3:
            return self.corners.reshape(-1, 3), self.corner_uvs.reshape(-1, 3)
        first = np.cumsum(sizes) - sizes
        fan = sizes - 2
        base = np.repeat(first, fan)
        k = np.arange(int(fan.sum())) - np.repeat(np.cumsum(fan) - fan, fan) + 1
        idx = np.stack([base, base + k, base + k + 1], axis=1)
        return self.corners[idx], self.corner_uvs[idx]

    def triangle_lines(self) -> np.ndarray:
        """``(F',)`` the line of each triangle of :meth:`triangles`."""
        return np.repeat(self.face_lines, self.face_sizes - 2)


_KEYWORDS = frozenset(
    b"v vt vn vp f l p o g s mg mtllib usemtl cstype deg bmat step curv curv2 surf parm trim hole scrv sp end con "
    b"bevel c_interp d_interp lod shadow_obj trace_obj ctech stech call csh maplib usemap".split()
)


def _rest(line: bytes, key: bytes) -> str:
    """The rest of a statement line after its keyword, as text (names may hold spaces)."""
    body = line.split(b"#", 1)[0].strip()
    return body[len(key) :].strip().decode("utf-8", errors="replace")


def parse_obj(p: Path, data: bytes, *, uvs: bool = True, normals: bool = False) -> ObjData:
    r"""Parse an OBJ file's bytes (every check of the docs' *Bad input* page; errors name ``p`` and the line).

    OBJ indices are 1-based; a negative index ``-k`` is the ``k``-th element counted back from the last one defined
    before its line (so ``f -3 -2 -1`` is the last three vertices), for vertices and ``vt`` alike. Corners may be
    ``v``, ``v/vt``, ``v/vt/vn`` or ``v//vn``. Polygons are kept as such (:meth:`ObjData.triangles` fans them).

    Args:
        p: the file (for messages).
        data: its bytes.
        uvs: read and check the texture coordinates (``vt`` lines and the corners' ``vt`` indices). Without,
            they are skipped unread, as a reader of geometry only needs (``uvs`` then is empty, ``corner_uvs``
            ``-1``).
        normals: read and check the ``vn`` lines (three finite values each); without, they are skipped unread
            (``normals`` then is empty). Whether a corner names a normal is found either way.

    Returns:
        :class:`ObjData`.

    Raises:
        MeshFileError: binary data, a line that is no OBJ statement, a vertex with a wrong number of coordinates
            or non-numbers, NaN/Inf coordinates, colours, UVs or normals, a face with fewer than 3 corners, an index
            0, a negative index counting back past the first element, an index past the last element.

    Example:
        >>> d = parse_obj(Path("t.obj"), b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 -1/1\n")
        >>> d.corners.tolist(), d.corner_uvs.tolist()
        ([0, 1, 2], [0, 0, 0])
    """
    uvs = check_flag(uvs, "uvs")
    normals = check_flag(normals, "normals")
    check_text(p, data)
    data = without_bom(data)
    fast = _parse_fast(data, uvs, normals)
    if fast is None or not _valid(fast):
        fast = _parse_slow(p, data, uvs, normals)
    _check_finite(p, fast)
    return fast


def _valid(d: ObjData) -> bool:
    """Whether the fast pass's result passes every check (else the slow pass names the problem)."""
    nv, nt = d.verts.shape[0], d.uvs.shape[0]
    if d.corners.size and (int(d.corners.min()) < 0 or int(d.corners.max()) >= nv):
        return False
    return not (d.corner_uvs.size and int(d.corner_uvs.max()) >= nt)


def _check_finite(p: Path, d: ObjData) -> None:
    """Refuse the first row of vertices, colours, ``vt`` or ``vn`` values that is not finite, naming its line."""
    tables = [(d.verts, d.vert_lines, "vertex {i} (line {line}) has non-finite coordinates {row} ({n} such vertices)")]
    if d.vert_colors is not None:
        tables.append(
            (d.vert_colors, d.vert_lines, "vertex {i} (line {line}) has a non-finite colour {row} ({n} such vertices)")
        )
    uv_message = "texture coordinate {i} (line {line}) is not finite: {row} ({n} such 'vt' lines)"
    tables.append((d.uvs, d.uv_lines, uv_message))
    tables.append((d.normals, d.normal_lines, "normal {i} (line {line}) is not finite: {row} ({n} such 'vn' lines)"))
    for values, lines, message in tables:
        bad = ~np.isfinite(values).all(axis=1)
        if bad.any():
            i = int(np.nonzero(bad)[0][0])
            what = message.format(i=i, line=int(lines[i]), row=values[i].tolist(), n=int(bad.sum()))
            raise MeshFileError(f"path: mesh file '{p}' {what}")


# ----------------------------------------------------------------------------------------------- the fast pass
_SPACE = np.zeros(256, dtype=bool)
_SPACE[[9, 11, 12, 13, 32]] = True  # not the newline: a keyword must be followed by something on its line
_V, _VT, _F, _SKIP, _OTHER, _VN = 1, 2, 3, 4, 5, 6


class _Lines(NamedTuple):
    """A file's bytes cut into lines for the fast pass: each line's start, end and kind."""

    data: bytes
    buf: np.ndarray  # the bytes as uint8 (two more bytes to look past the last line start); keywords get blanked
    starts: np.ndarray
    ends: np.ndarray
    kind: np.ndarray  # _SKIP, _V, _VT, _VN, _F or _OTHER per line


def _classify(data: bytes, read_uvs: bool, read_normals: bool) -> _Lines | None:
    """Every line's kind from its first bytes, or ``None`` for what the fast pass does not take."""
    if not data or b"\\" in data:
        return None  # line continuations: statement by statement
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n")
        if b"\r" in data:
            return None
    if not data.endswith(b"\n"):
        data += b"\n"
    buf = np.frombuffer(data + b"\0\0", dtype=np.uint8).copy()  # two bytes to look past the last line start
    nl = np.flatnonzero(buf == 10)
    starts = np.concatenate(([0], nl[:-1] + 1))
    ends = nl
    c0, c1, c2 = buf[starts], buf[starts + 1], buf[starts + 2]
    sp1, sp2 = _SPACE[c1], _SPACE[c2]
    kind = np.full(len(starts), _OTHER, dtype=np.uint8)
    kind[starts == ends] = _SKIP
    kind[c0 == ord("#")] = _SKIP
    kind[(c0 == ord("v")) & sp1] = _V
    kind[(c0 == ord("v")) & (c1 == ord("t")) & sp2] = _VT if read_uvs else _SKIP
    kind[(c0 == ord("v")) & (c1 == ord("n")) & sp2] = _VN if read_normals else _SKIP
    kind[(c0 == ord("f")) & sp1] = _F
    hashes = np.flatnonzero(buf == ord("#"))
    if hashes.size:
        hash_line = np.searchsorted(starts, hashes, side="right") - 1
        k = kind[hash_line]
        if ((k == _V) | (k == _VT) | (k == _VN) | (k == _F)).any():
            return None  # a comment after a statement
    return _Lines(data, buf, starts, ends, kind)


class _Materials(NamedTuple):
    names: list[str]
    lines: list[int]
    mtllibs: list[tuple[str, int]]
    use_at: list[tuple[int, int]]  # (line index, material index)


def _other_statements(lines: _Lines) -> _Materials | None:
    """The ``mtllib`` and ``usemtl`` statements; ``None`` for anything the fast pass leaves to the slow one."""
    found = _Materials([], [], [], [])
    for i in np.flatnonzero(lines.kind == _OTHER).tolist():
        line = lines.data[lines.starts[i] : lines.ends[i]]
        tokens = line.split(b"#", 1)[0].split()
        if not tokens:
            continue
        key = tokens[0]
        if key not in _KEYWORDS or key in (b"v", b"vt", b"vn", b"f") or not line[:1].strip():
            return None  # not OBJ, or an indented statement: the slow pass
        if key == b"mtllib":
            found.mtllibs.append((_rest(line, key), i + 1))
        elif key == b"usemtl":
            name = _rest(line, key)
            if name not in found.names:
                found.names.append(name)
                found.lines.append(i + 1)
            found.use_at.append((i, found.names.index(name)))
    return found


def _corner_form(slash: np.ndarray, n_corner: int) -> tuple[int, int] | None:
    """``(numbers per corner, column of the UV index or -1)`` of ``v``, ``v/t``, ``v/t/n`` or ``v//n`` corners."""
    n_slash = int(np.count_nonzero(slash))
    double = int(np.count_nonzero(slash[:-1] & slash[1:])) if n_slash else 0
    if n_slash == 0:
        return 1, -1
    if double == 0 and n_slash == n_corner:
        return 2, 1
    if double == 0 and n_slash == 2 * n_corner:
        return 3, 1
    if double == n_corner and n_slash == 2 * n_corner:
        return 2, -1
    return None


def _resolve(index: np.ndarray, defined_before: np.ndarray) -> np.ndarray | None:
    """OBJ's 1-based (or negative, counting back) indices as 0-based ones; ``None`` for 0 or before the first."""
    if (index == 0).any():
        return None
    resolved = np.where(index < 0, defined_before + index, index - 1)
    if (index < 0).any() and (resolved[index < 0] < 0).any():
        return None
    return resolved


def _face_corners(
    lines: _Lines, regions: _Regions, f_lines: np.ndarray, sizes: np.ndarray, read_uvs: bool
) -> tuple[np.ndarray, np.ndarray, bool] | None:
    """``(vertex index, UV index or -1, any corner names a normal)`` of every face corner, 0-based, or ``None``.

    ``None`` for mixed or bad corners (the slow pass then decides).
    """
    fbytes = regions.of(_F, f_lines)
    slash = fbytes == ord("/")
    n_corner = int(sizes.sum())
    form = _corner_form(slash, n_corner)
    if form is None:
        return None
    per, uv_col = form
    normal_indexed = per == 3 or (per == 2 and uv_col < 0)  # v/vt/vn or v//vn
    if slash.any():
        per_corner = 2 if uv_col < 0 else per - 1  # slashes in each corner of the form found
        per_line = np.add.reduceat(lines.buf == ord("/"), lines.starts, dtype=np.int32)[f_lines]
        if not np.array_equal(per_line, sizes * per_corner):
            return None  # corners of mixed forms
        fbytes = np.where(slash, np.uint8(32), fbytes)
    try:
        ints = np.fromstring(fbytes.tobytes(), dtype=np.int64, sep=" ")
    except ValueError:
        return None
    if ints.size != n_corner * per:
        return None
    ints = ints.reshape(-1, per)
    corner_line = np.repeat(f_lines, sizes)
    corners = _resolve(ints[:, 0], np.cumsum(lines.kind == _V)[corner_line])  # vertices defined up to each face
    if corners is None:
        return None
    if uv_col < 0 or not read_uvs:
        return corners, np.full(n_corner, -1, dtype=np.int64), normal_indexed
    corner_uvs = _resolve(ints[:, uv_col], np.cumsum(lines.kind == _VT)[corner_line])
    return None if corner_uvs is None else (corners, corner_uvs, normal_indexed)


def _parse_fast(data: bytes, read_uvs: bool, read_normals: bool = False) -> ObjData | None:
    """Vectorised parse, or ``None`` whenever the file is unusual (the slow pass then decides)."""
    lines = _classify(data, read_uvs, read_normals)
    if lines is None:
        return None
    materials = _other_statements(lines)
    if materials is None:
        return None
    buf, starts, kind = lines.buf, lines.starts, lines.kind
    if not ((kind == _V).any() or (kind == _F).any() or (kind == _VT).any() or materials.mtllibs):
        return None  # no statement at all (or only odd ones): the slow pass names it
    v_lines = np.flatnonzero(kind == _V)
    vt_lines = np.flatnonzero(kind == _VT)
    vn_lines = np.flatnonzero(kind == _VN)
    f_lines = np.flatnonzero(kind == _F)
    buf[starts[v_lines]] = 32  # blank the keywords
    buf[starts[vt_lines]] = 32
    buf[starts[vt_lines] + 1] = 32
    buf[starts[vn_lines]] = 32
    buf[starts[vn_lines] + 1] = 32
    buf[starts[f_lines]] = 32
    # Tokens per line: space-to-text transitions, counted by a running sum read at the line ends. Control bytes
    # other than whitespace were refused, so "<= 32" is whitespace.
    space = buf <= 32
    rise = np.empty(buf.shape[0], dtype=bool)
    rise[0] = not space[0]
    np.greater(space[:-1], space[1:], out=rise[1:])  # space, then text
    # each line's segment ends with its newline (a space), so an empty line sums to 0
    counts = np.add.reduceat(rise, starts, dtype=np.int32)
    regions = _Regions(buf, kind, starts, lines.ends)

    verts, colors = _numbers(regions.of(_V, v_lines), counts[v_lines], (3, 4, 6, 7))
    if verts is None:
        return None
    uvs, _ = _numbers(regions.of(_VT, vt_lines), counts[vt_lines], (2, 3))
    if uvs is None:
        return None
    normals, _ = _numbers(regions.of(_VN, vn_lines), counts[vn_lines], (3,))
    if normals is None:
        return None
    color_rows = np.zeros((0, 3)) if colors is None else colors
    if colors is not None and (counts[v_lines] < 6).any():
        color_rows = colors[counts[v_lines] >= 6]
        colors = None
    sizes = counts[f_lines]
    if sizes.size and int(sizes.min()) < 3:
        return None
    corners = _face_corners(lines, regions, f_lines, sizes, read_uvs)
    if corners is None:
        return None
    face_materials = np.full(len(f_lines), -1, dtype=np.int64)
    if materials.use_at:
        at = np.searchsorted(np.array([a for a, _ in materials.use_at]), f_lines) - 1  # the last usemtl before
        face_materials = np.where(at >= 0, np.array([m for _, m in materials.use_at])[at], -1)
    return ObjData(
        verts=verts[:, :3],
        vert_lines=v_lines + 1,
        vert_colors=colors,
        uvs=uvs[:, :2],
        uv_lines=vt_lines + 1,
        corners=corners[0].astype(np.int64),
        corner_uvs=corners[1].astype(np.int64),
        face_sizes=sizes.astype(np.int64),
        face_lines=f_lines + 1,
        face_materials=face_materials,
        materials=materials.names,
        material_lines=materials.lines,
        mtllibs=materials.mtllibs,
        normals=normals,
        normal_lines=vn_lines + 1,
        normal_indexed=corners[2],
        color_rows=color_rows,
    )


_INTEGER_TEXT = b"0123456789-+ \t\n\r\v\f"


def _floats(text: bytes) -> np.ndarray:
    """Whitespace-separated numbers as float64, each the correctly rounded value Python's ``float`` gives.

    Integer coordinates (quantised meshes) are parsed as integers, about ten times faster, when every token is
    one and every value is below ``1e15`` (exact in float64, and no token can have been clamped by the parser), and
    no token is a negative zero.
    """
    if not text.translate(None, _INTEGER_TEXT) and b"-0" not in text:  # "-0" is the float -0.0
        ints = np.fromstring(text, dtype=np.int64, sep=" ")
        if ints.size == 0 or int(np.abs(ints).max()) < 10**15:
            return ints.astype(np.float64)
    return np.fromstring(text, dtype=np.float64, sep=" ")


class _Regions:
    """The bytes of the lines of one kind: a slice when they are consecutive (the usual layout), else a mask."""

    def __init__(self, buf: np.ndarray, kind: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> None:
        self.buf, self.kind, self.starts, self.ends = buf, kind, starts, ends
        self._line_of_byte: np.ndarray | None = None

    def of(self, k: int, lines: np.ndarray) -> np.ndarray:
        if lines.size == 0:
            return self.buf[:0]
        first, last = int(lines[0]), int(lines[-1])
        if last - first + 1 == lines.size:
            return self.buf[self.starts[first] : self.ends[last] + 1]
        if self._line_of_byte is None:
            self._line_of_byte = np.repeat(self.kind, self.ends - self.starts + 1)
        return self.buf[: self._line_of_byte.shape[0]][self._line_of_byte == k]


def _numbers(
    text: np.ndarray, counts: np.ndarray, allowed: tuple[int, ...]
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The numbers of every line of one kind: ``(rows, colours)`` (``rows`` ``(N, min(allowed))``), or ``None``."""
    width = allowed[0]
    if counts.size == 0:
        return np.zeros((0, width)), None
    if not np.isin(counts, allowed).all():
        return None, None
    try:
        flat = _floats(text.tobytes())
    except ValueError:
        return None, None
    if flat.size != int(counts.sum()):
        return None, None
    lo, hi = int(counts.min()), int(counts.max())
    if lo == hi:
        rows = flat.reshape(-1, lo)
        return rows[:, :width], (rows[:, 3:6] if lo >= 6 else None)
    offset = np.cumsum(counts) - counts
    rows = flat[offset[:, None] + np.arange(width)]
    colors = None
    if lo >= 6:
        colors = flat[offset[:, None] + np.arange(3, 6)]
    elif hi >= 6:
        has = counts >= 6  # some vertices lack a colour: the caller keeps the others' as mmetric's list
        colors = np.zeros((counts.size, 3))
        colors[has] = flat[offset[has][:, None] + np.arange(3, 6)]
    return rows, colors


# ----------------------------------------------------------------------------------------------- the slow pass
@dataclass
class _Statements:
    """What the slow pass has read so far, statement by statement (``p``: the file, in messages)."""

    p: Path
    read_uvs: bool
    verts: list[list[float]] = field(default_factory=list)
    vert_lines: list[int] = field(default_factory=list)
    colors: list[list[float] | None] = field(default_factory=list)
    uvs: list[list[float]] = field(default_factory=list)
    uv_lines: list[int] = field(default_factory=list)
    corners: list[int] = field(default_factory=list)
    corner_uvs: list[int] = field(default_factory=list)
    sizes: list[int] = field(default_factory=list)
    face_lines: list[int] = field(default_factory=list)
    face_materials: list[int] = field(default_factory=list)
    materials: list[str] = field(default_factory=list)
    material_lines: list[int] = field(default_factory=list)
    mtllibs: list[tuple[str, int]] = field(default_factory=list)
    material: int = -1
    normals: list[list[float]] = field(default_factory=list)
    normal_lines: list[int] = field(default_factory=list)
    normal_indexed: bool = False

    def vertex(self, at: int, tokens: list[bytes]) -> None:
        n = len(tokens) - 1
        if n not in (3, 4, 6, 7):
            raise MeshFileError(
                f"path: '{self.p}' line {at}: vertex {len(self.verts)} has {n} coordinate(s); expected 'v x y z' "
                "(optionally w, or r g b [a])"
            )
        self.verts.append(self.line_floats(at, tokens, 1, 4, "vertex coordinates"))
        self.colors.append(self.line_floats(at, tokens, 4, 7, "vertex coordinates") if n >= 6 else None)
        self.vert_lines.append(at)

    def uv(self, at: int, tokens: list[bytes]) -> None:
        n = len(tokens) - 1
        if n not in (2, 3):
            raise MeshFileError(
                f"path: '{self.p}' line {at}: texture coordinate {len(self.uvs)} has {n} value(s); expected "
                "'vt u v' (optionally w)"
            )
        self.uvs.append(self.line_floats(at, tokens, 1, 3, "texture coordinates"))
        self.uv_lines.append(at)

    def normal(self, at: int, tokens: list[bytes]) -> None:
        n = len(tokens) - 1
        if n != 3:
            raise MeshFileError(
                f"path: '{self.p}' line {at}: normal {len(self.normals)} has {n} value(s); expected 'vn x y z'"
            )
        self.normals.append(self.line_floats(at, tokens, 1, 4, "normal coordinates"))
        self.normal_lines.append(at)

    def line_floats(self, at: int, tokens: list[bytes], start: int, stop: int, what: str) -> list[float]:
        """``tokens[start:stop]`` as floats; an error quotes the line's values (``what``: whose)."""
        try:
            return [plain_float(t) for t in tokens[start:stop]]  # "1_0" is no number, as for the fast pass
        except ValueError:
            raise MeshFileError(
                f"path: '{self.p}' line {at}: {what} {b' '.join(tokens[1:]).decode('latin-1')!r} are not numbers"
            ) from None

    def face(self, at: int, tokens: list[bytes]) -> None:
        n = len(tokens) - 1
        if n < 3:
            raise MeshFileError(f"path: '{self.p}' line {at} has a face with {n} corners; expected triangles")
        for t in tokens[1:]:
            parts = t.split(b"/")
            self.corners.append(_index(self.p, at, parts[0], len(self.verts), "vertex", t))
            has_uv = self.read_uvs and len(parts) > 1 and parts[1] != b""
            self.corner_uvs.append(_index(self.p, at, parts[1], len(self.uvs), "texture", t) if has_uv else -1)
            self.normal_indexed = self.normal_indexed or (len(parts) > 2 and parts[2] != b"")
        self.sizes.append(n)
        self.face_lines.append(at)
        self.face_materials.append(self.material)

    def use_material(self, at: int, name: str) -> None:
        if name not in self.materials:
            self.materials.append(name)
            self.material_lines.append(at)
        self.material = self.materials.index(name)

    def check_indices(self) -> None:
        """Corners that name a vertex or UV defined after their face (or never): the first one's line."""
        corner_lines = np.repeat(self.face_lines, self.sizes).tolist()
        nv = len(self.verts)
        for c, line_no in zip(self.corners, corner_lines, strict=True):
            if c >= nv:
                face = self.face_lines.index(line_no)
                raise MeshFileError(
                    f"path: '{self.p}' line {line_no}: face {face}: vertex index {c + 1} is out of range (the file "
                    f"has {nv} vertices)"
                )
        for c, line_no in zip(self.corner_uvs, corner_lines, strict=True):
            if c >= len(self.uvs):
                raise MeshFileError(
                    f"path: '{self.p}' line {line_no}: texture index {c + 1} is out of range (the file has "
                    f"{len(self.uvs)} 'vt' lines)"
                )

    def result(self) -> ObjData:
        has_color = bool(self.colors) and all(c is not None for c in self.colors)
        return ObjData(
            verts=np.array(self.verts, dtype=np.float64).reshape(-1, 3),
            vert_lines=np.array(self.vert_lines, dtype=np.int64),
            vert_colors=np.array(self.colors, dtype=np.float64).reshape(-1, 3) if has_color else None,
            uvs=np.array(self.uvs, dtype=np.float64).reshape(-1, 2),
            uv_lines=np.array(self.uv_lines, dtype=np.int64),
            corners=np.array(self.corners, dtype=np.int64),
            corner_uvs=np.array(self.corner_uvs, dtype=np.int64),
            face_sizes=np.array(self.sizes, dtype=np.int64),
            face_lines=np.array(self.face_lines, dtype=np.int64),
            face_materials=np.array(self.face_materials, dtype=np.int64),
            materials=self.materials,
            material_lines=self.material_lines,
            mtllibs=self.mtllibs,
            normals=np.array(self.normals, dtype=np.float64).reshape(-1, 3),
            normal_lines=np.array(self.normal_lines, dtype=np.int64),
            normal_indexed=self.normal_indexed,
            color_rows=np.array([c for c in self.colors if c is not None], dtype=np.float64).reshape(-1, 3),
        )


def _statements(numbered: Iterable[tuple[int, bytes]]) -> Iterator[tuple[int, bytes, list[bytes]]]:
    """``(line, text, tokens)`` of every statement of numbered lines: continuations joined, comments and blanks out."""
    pending = b""
    start = 0
    for lineno, raw in numbered:
        line = pending + raw
        if line.rstrip().endswith(b"\\"):  # line continuation
            pending = line.rstrip()[:-1] + b" "
            start = start or lineno
            continue
        at, pending, start = start or lineno, b"", 0
        tokens = line.split(b"#", 1)[0].split()
        if tokens:
            yield at, line, tokens


_MTLLIB_LINE = re.compile(rb"[^\r\n]*mtllib[^\r\n]*")  # the lines of bytes.splitlines() that hold the word


def obj_mtllibs(data: bytes) -> list[str]:
    r"""The names of an OBJ file's ``mtllib`` statements, as :func:`parse_obj` reads them, without its geometry.

    The same statements and the same rule as the reader's ``mtllibs`` (the rest of the line, its comment and
    surrounding whitespace removed; line continuations joined; a byte-order mark skipped), for what must agree with
    the reader without parsing the whole file: the CTC campaign's cache key holds the MTL and texture the reader
    uses (a key reading ``mtllib x.mtl # note`` as the file ``x.mtl # note`` left them out, review R #1).

    Example:
        >>> obj_mtllibs(b"mtllib frame.mtl # by the encoder\nv 0 0 0\n")
        ['frame.mtl']
    """
    data = without_bom(data)
    if b"mtllib" not in data:  # a statement naming mtllib holds the word: continuations join with a space
        return []
    if b"\\" in data:
        numbered: Iterable[tuple[int, bytes]] = enumerate(data.splitlines(), 1)
    else:  # no continuation: each statement is one line, and only the lines holding the word can be one
        numbered = ((0, m.group()) for m in _MTLLIB_LINE.finditer(data))
    return [_rest(line, b"mtllib") for _, line, tokens in _statements(numbered) if tokens[0] == b"mtllib"]


def _parse_slow(p: Path, data: bytes, read_uvs: bool, read_normals: bool = False) -> ObjData:
    """One statement at a time, naming the line of the first problem."""
    read = _Statements(p, read_uvs)
    statements = 0
    for at, line, tokens in _statements(enumerate(data.splitlines(), 1)):
        key = tokens[0]
        if key not in _KEYWORDS:
            raise not_a_mesh(p, f"line {at} starts with {key.decode('latin-1')!r}, not an OBJ statement")
        statements += 1
        if key == b"v":
            read.vertex(at, tokens)
        elif key == b"vt" and read_uvs:
            read.uv(at, tokens)
        elif key == b"vn" and read_normals:
            read.normal(at, tokens)
        elif key == b"f":
            read.face(at, tokens)
        elif key == b"mtllib":
            read.mtllibs.append((_rest(line, key), at))
        elif key == b"usemtl":
            read.use_material(at, _rest(line, key))
    if statements == 0:
        raise not_a_mesh(p, "no OBJ statement (v, f, ...) found")
    read.check_indices()
    return read.result()


def _index(p: Path, at: int, text: bytes, defined: int, what: str, corner: bytes) -> int:
    """A 0-based index from an OBJ corner field (1-based, or negative counting back from the last defined)."""
    things = "vertex" if what == "vertex" else "'vt'"
    try:
        idx = plain_int(text)
    except ValueError:
        raise MeshFileError(
            f"path: '{p}' line {at}: face corner {corner.decode('latin-1')!r} is not a {what} index"
        ) from None
    if idx == 0:
        raise MeshFileError(
            f"path: '{p}' line {at}: face {what} index 0 is invalid (OBJ indices start at 1; negative ones "
            f"count back from the last {things} defined)"
            if what != "vertex"
            else f"path: '{p}' line {at}: face index 0 is invalid (OBJ indices start at 1; negative ones "
            "count back from the last vertex)"
        )
    if idx < 0:
        if -idx > defined:
            lead = "face index" if what == "vertex" else "face texture index"
            first = "the first vertex" if what == "vertex" else "the first 'vt'"
            plural = "vertices" if what == "vertex" else "'vt' lines"
            raise MeshFileError(
                f"path: '{p}' line {at}: {lead} {idx} counts back past {first} ({defined} {plural} defined "
                "before this line)"
            )
        return defined + idx
    return idx - 1


# ----------------------------------------------------------------------------------------------- MTL
@dataclass(frozen=True)
class MtlMaterial:
    """One ``newmtl`` of an MTL file.

    Attributes:
        name: the material's name (the rest of the ``newmtl`` line).
        line: its ``newmtl`` line.
        map_kd: the ``map_Kd`` texture file, relative to the MTL's folder, or ``None``.
        map_line: the ``map_Kd`` line (0 when there is none).
    """

    name: str
    line: int
    map_kd: str | None = None
    map_line: int = 0


# map_Kd options and how many arguments each takes (-o, -s, -t take 1 to 3 numbers).
_MAP_OPTIONS = {
    "-blendu": 1,
    "-blendv": 1,
    "-bm": 1,
    "-boost": 1,
    "-cc": 1,
    "-clamp": 1,
    "-imfchan": 1,
    "-mm": 2,
    "-texres": 1,
    "-type": 1,
    "-o": 3,
    "-s": 3,
    "-t": 3,
}


def _map_name(rest: str) -> str:
    """The file name of a ``map_Kd`` statement: what follows the keyword and its options (it may hold spaces)."""
    text = rest.strip()
    while text.startswith("-"):
        parts = text.split(None, 1)
        option = parts[0]
        if option not in _MAP_OPTIONS:
            break
        text = parts[1] if len(parts) > 1 else ""
        for k in range(_MAP_OPTIONS[option]):
            arg = text.split(None, 1)
            if not arg:
                break
            if k > 0 or option in ("-o", "-s", "-t"):
                try:
                    float(arg[0])
                except ValueError:
                    break  # -o/-s/-t take 1 to 3 numbers
            text = arg[1] if len(arg) > 1 else ""
    return text.strip()


def parse_mtl(path: Path) -> list[MtlMaterial]:
    r"""The materials of an MTL file and their ``map_Kd`` textures (names may hold spaces; options are skipped).

    Args:
        path: the MTL file (it must exist).

    Returns:
        The materials in file order.

    Raises:
        MeshFileError: binary data in the file, or a ``map_Kd`` without a file name (naming the line).

    Example:
        >>> import tempfile
        >>> p = Path(tempfile.mkdtemp()) / "m.mtl"
        >>> _ = p.write_text("newmtl skin\nmap_Kd -s 1 1 1 my texture.png\n")
        >>> parse_mtl(p)[0].map_kd
        'my texture.png'
    """
    out: list[MtlMaterial] = []
    for lineno, raw in enumerate(text_lines(path, path.read_bytes()), 1):
        line = raw.split(b"#", 1)[0].strip()
        tokens = line.split()
        if not tokens:
            continue
        key = tokens[0]
        if key == b"newmtl":
            out.append(MtlMaterial(_rest(line, key), lineno))
        elif key == b"map_Kd":
            name = _map_name(_rest(line, key))
            if not name:
                raise MeshFileError(f"path: '{path}' line {lineno}: 'map_Kd' names no texture file")
            if not out:
                raise MeshFileError(f"path: '{path}' line {lineno}: 'map_Kd' before any 'newmtl'")
            last = out[-1]
            out[-1] = MtlMaterial(last.name, last.line, name, lineno)
    return out


def read_obj_triangles(p: Path, data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices, triangles and vertex lines of a Wavefront OBJ file (polygons refused, naming their line)."""
    d = parse_obj(p, data, uvs=False)
    sizes = d.face_sizes
    if sizes.size and (int(sizes.min()) != 3 or int(sizes.max()) != 3):
        j = int(np.nonzero(sizes != 3)[0][0])
        raise MeshFileError(
            f"path: '{p}' line {int(d.face_lines[j])} has a face with {int(sizes[j])} corners; expected triangles"
        )
    return d.verts, d.corners.reshape(-1, 3), d.vert_lines


def obj_bytes(mesh: Mesh) -> bytes:
    """Minimal OBJ writer (vertices at full float64 precision via ``repr``-exact ``%.17g``, 1-based faces)."""
    v = mesh.verts.detach().cpu().double().numpy()
    f = mesh.faces.cpu().numpy() + 1
    lines = ["v " + " ".join(f"{x:.17g}" for x in row) for row in v]
    lines += [f"f {a} {b} {c}" for a, b, c in f]
    return ("\n".join(lines) + "\n").encode()
