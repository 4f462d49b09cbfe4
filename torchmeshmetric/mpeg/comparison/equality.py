"""mmetric's equality comparison of two meshes (``compare --mode equ``), with every line it prints.

mmetric v1.1.7's ``Compare::equ`` prints, in order:

1. A line per pair of texture maps (the models' map sets, one map per material of their MTL files, or the map given
   with ``--inputMap``): ``texture maps are equal``, ``... not equal: mapA is null`` / ``mapB is null`` / ``dimensions
   are not equal`` / ``<n>pixel differences`` (RGB compared texel by texel), nothing for a pair where neither model
   has a map; ``... not of equal: size of set A is diffrent from size of set B`` when the sets differ in size.
2. The verdict. It walks the triangles of A in order and, for each, takes the first not yet matched triangle of B
   with the same three corners (position, and UV / colour / normal when both models have them, compared as float32
   values) in the same cyclic order -- or in either order with ``--unoriented``. Because "same corners up to a
   rotation (or a reflection)" is an equivalence, that greedy walk leaves exactly the triangles of A beyond the count
   B has of their class unmatched: the k-th triangle of A in a class is unmatched when B has fewer than k of that
   class. This module counts that way (a sort, not mmetric's quadratic search), so the verdict, the count of
   different triangles and the first unmatched triangle of A are mmetric's.
3. When the meshes differ and every triangle was searched: the position, UV, colour and normal lists compared index
   by index, plus the difference of their lengths (``Position differences: N`` ... ``Normals differences: N``).

Models without triangles (point clouds: an OBJ without faces, a PLY such as ``mm sample`` writes) take mmetric's
point-cloud branch instead of 2. and 3., when neither model has a triangle (one model with triangles and one without
is the "number of triangles are different" line): both position lists sorted lexicographically (x, then y, then z,
as float32), then, with ``epsilon`` 0, compared as whole lists (``model vertices are equals`` / ``... not equals``;
different counts are not equal), or, with ``epsilon`` > 0, point by point in sorted order, a point differing when
its float32 distance ``length(A - B) >= epsilon`` (``model vertices are not equals, found N differences``; different
counts: ``... not equals``). UVs, colours and normals take no part; ``--unoriented`` and ``--earlyReturn`` change
nothing there. ``epsilon`` is ignored for meshes, as mmetric ignores it.

The lists are the models' as mmetric's readers fill them, which :func:`load_equality_model` reproduces through the
library's one reader per format: OBJ ``vt`` lines (indexed per corner), ``v x y z r g b`` colours of the vertices
that have one (scaled as mmetric does, ``roundf(value * 255)``), ``vn`` lines unless a face corner names a normal
(mmetric then drops them); PLY ``texture_u texture_v`` (per vertex), ``red green blue`` and ``nx ny nz``. Colours and
normals take part in the triangle comparison when both models have one per position; UVs when both have them per
corner, or one per position.

``compare --mode eqTFAN`` reads the same lists and maps and prints the same texture lines and list differences
(:mod:`~torchmeshmetric.mpeg.comparison.tfan_comparison` uses this module's model, loader and lines).

Where a file is read otherwise than by mmetric: a NaN or infinite coordinate is refused (mmetric sorts it with an
ordering NaN breaks, and its distance test never counts a NaN); a face line naming fewer than three vertices is
refused (mmetric skips it, so a file of such lines is a point cloud for it); a greyscale texture is refused (mmetric
reads three bytes per texel of a one-channel image); a ``map_Kd`` is found beside its MTL (mmetric looks beside the
OBJ); an OBJ vertex of four numbers is ``x y z w`` (mmetric takes the fourth for a red channel); PLY colours other
than ``uchar red green blue`` and per-corner ``texcoord`` lists go through trimesh, without normals or UVs; OFF, which
mmetric does not read, gives positions and triangles; negative (relative) OBJ face indices are resolved as the OBJ
format defines them, where mmetric v1.1.7 does not resolve them (its equ compared garbage triangles and its eqTFAN
crashed on such a file, review P): re-export the file with
positive indices to compare it with mm; PLY ``x y z`` declared in another order (``z y x``) are read by their names,
where mmetric (tinyply) takes them in their declared order as x, y, z (measured, review S; docs/mpeg.md).
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypedDict

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._checks import DTypeError, IndexRangeError, NonFiniteError, ShapeError, check_flag, check_real
from torchmeshmetric.data.ply import PlyArrays
from torchmeshmetric.mpeg.comparison.point_order import lexicographic_order
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh, _obj_colors, as_textured_mesh, read_texture
from torchmeshmetric.structures import MeshLike

__all__ = ["EqualityModel", "MeshEquality", "load_equality_model", "mesh_equality", "point_cloud_verdict"]


def _empty(cols: int, dtype: type = np.float32) -> np.ndarray:
    return np.zeros((0, cols), dtype=dtype)


def _table(
    name: str,
    value: object,
    cols: int,
    *,
    integer: bool,
    indexes: tuple[str, int] | None = None,
) -> np.ndarray:
    """One table of an :class:`EqualityModel` as ``(N, cols)``: indices inside ``indexes``, or finite float32."""
    where = f"EqualityModel.{name}"
    arr = np.asarray(value.detach().cpu().numpy() if isinstance(value, Tensor) else value)
    if arr.size == 0 and arr.ndim < 2:
        arr = arr.reshape(0, cols)
    if arr.ndim != 2 or arr.shape[1] != cols:
        raise ShapeError(f"{where}: expected shape (N, {cols}), found {tuple(arr.shape)}")
    if integer:
        if arr.size and (arr.dtype == np.bool_ or arr.dtype.kind not in "iu"):
            raise DTypeError(f"{where}: expected integer indices, found dtype {arr.dtype}")
        arr = arr.astype(np.int64, copy=False)
        assert indexes is not None
        of, n = indexes
        if arr.size and (int(arr.min()) < 0 or int(arr.max()) >= n):
            raise IndexRangeError(
                f"{where}: expected indices of {of} in [0, {n - 1}], found values in [{int(arr.min())}, "
                f"{int(arr.max())}]"
            )
        return arr
    if arr.size and (arr.dtype == np.bool_ or arr.dtype.kind not in "iuf"):
        raise DTypeError(f"{where}: expected numbers, found dtype {arr.dtype}")
    wide = arr.astype(np.float64, copy=False)
    if arr.size and np.isfinite(wide).all() and (np.abs(wide) > float(np.finfo(np.float32).max)).any():
        # finite values that float32 cannot hold were called "NaN/Inf" after the cast (review P)
        big = float(wide.flat[int(np.argmax(np.abs(wide)))])
        raise NonFiniteError(
            f"{where}: expected values that fit float32 (mmetric reads them as float), found {big!r}, beyond +/-3.4e38"
        )
    with np.errstate(over="ignore"):
        arr = arr.astype(np.float32, copy=False)
    if arr.size and not np.isfinite(arr).all():
        raise NonFiniteError(
            f"{where}: expected finite values, found {int((~np.isfinite(arr)).sum())} NaN/Inf value(s)"
        )
    return arr


class _ListDifferences(TypedDict):
    """The four lists' differences, as keyword arguments of :class:`MeshEquality` and ``TfanEquality``."""

    position_differences: int
    uv_differences: int
    color_differences: int
    normal_differences: int


def _list_differences(a: EqualityModel, b: EqualityModel) -> _ListDifferences:
    """The position, UV, colour and normal lists compared index by index (mmetric's "... differences" lines)."""
    return _ListDifferences(
        position_differences=_differences(a.positions, b.positions),
        uv_differences=_differences(a.uvs, b.uvs),
        color_differences=_differences(a.colors, b.colors),
        normal_differences=_differences(a.normals, b.normals),
    )


def _differences(a: np.ndarray, b: np.ndarray) -> int:
    """The "... differences" mmetric prints: the count difference plus the rows that differ index by index."""
    n = min(len(a), len(b))
    return abs(len(a) - len(b)) + int(np.any(a[:n] != b[:n], axis=1).sum()) if n else abs(len(a) - len(b))


@dataclass(frozen=True, eq=False)
class EqualityModel:
    """A mesh as ``mm compare --mode equ`` (and ``eqTFAN``) holds it: its lists as read from the file, its maps.

    Build it with :func:`load_equality_model` (a file, as mmetric reads it); :func:`mesh_equality` also takes a
    :class:`~torchmeshmetric.mpeg.TexturedMesh` or any mesh form, whose UVs are then its per-corner list.

    Args:
        positions: ``(V, 3)`` float32 positions.
        triangles: ``(F, 3)`` 0-based position indices.
        uvs: ``(T, 2)`` float32 texture coordinates, as listed in the file.
        triangles_uv: ``(F, 3)`` 0-based indices into ``uvs`` per corner, or ``(0, 3)``: then ``uvs`` are per
            position (used when ``T = V``).
        colors: ``(C, 3)`` float32 colours, as listed (per position when ``C = V``).
        normals: ``(N, 3)`` float32 normals, as listed (per position when ``N = V``).
        textures: the texture maps, one per material (``(H, W, 3)`` uint8, or ``None`` for a material without a
            map); ``(None,)`` (the default) for a model without a map, as mmetric counts it.

    Raises:
        ShapeError, DTypeError, IndexRangeError, NonFiniteError: a table of the wrong shape or type, an index
            outside its list, a non-finite value (naming the field).

    Example:
        >>> import numpy as np
        >>> m = EqualityModel(np.eye(3, dtype=np.float32), np.array([[0, 1, 2]]))
        >>> m.uvs.shape, m.textures
        ((0, 2), (None,))
    """

    positions: np.ndarray
    triangles: np.ndarray
    uvs: np.ndarray = field(default_factory=lambda: _empty(2))
    triangles_uv: np.ndarray = field(default_factory=lambda: _empty(3, np.int64))
    colors: np.ndarray = field(default_factory=lambda: _empty(3))
    normals: np.ndarray = field(default_factory=lambda: _empty(3))
    textures: tuple[np.ndarray | None, ...] = (None,)

    def __post_init__(self) -> None:
        """Check every table when built (shapes, dtypes, finite values, indices inside their lists)."""
        own = "EqualityModel"
        pos = _table("positions", self.positions, 3, integer=False)
        tri = _table("triangles", self.triangles, 3, integer=True, indexes=("positions", pos.shape[0]))
        uvs = _table("uvs", self.uvs, 2, integer=False)
        tuv = _table("triangles_uv", self.triangles_uv, 3, integer=True, indexes=("uvs", uvs.shape[0]))
        if tuv.shape[0] not in (0, tri.shape[0]):
            raise ShapeError(
                f"{own}.triangles_uv: expected 0 or {tri.shape[0]} rows (one per triangle), found {tuv.shape[0]}"
            )
        col = _table("colors", self.colors, 3, integer=False)
        nrm = _table("normals", self.normals, 3, integer=False)
        if not isinstance(self.textures, tuple):
            raise TypeError(f"{own}.textures: expected a tuple of images or None, found {type(self.textures).__name__}")
        for k, t in enumerate(self.textures):
            if t is None:
                continue
            if not isinstance(t, np.ndarray) or t.dtype != np.uint8:
                found = t.dtype if hasattr(t, "dtype") else type(t).__name__
                raise DTypeError(f"{own}.textures[{k}]: expected an (H, W, 3) uint8 numpy image, found {found}")
            if t.ndim != 3 or t.shape[2] != 3 or 0 in t.shape:
                raise ShapeError(f"{own}.textures[{k}]: expected shape (H, W, 3) with H, W >= 1, found {t.shape}")
        for name, value in (("positions", pos), ("triangles", tri), ("uvs", uvs), ("triangles_uv", tuv),
                            ("colors", col), ("normals", nrm)):  # fmt: skip
            object.__setattr__(self, name, value)

    @property
    def has_uvs(self) -> bool:
        """Whether mmetric compares its UVs (``hasUvCoords``): UVs per corner (an index table), or one per position."""
        return len(self.uvs) > 0 and (len(self.triangles_uv) > 0 or len(self.uvs) == len(self.positions))

    @property
    def has_colors(self) -> bool:
        """Whether mmetric compares its colours (``hasColors``): one colour per position."""
        return len(self.positions) > 0 and len(self.colors) == len(self.positions)

    @property
    def has_normals(self) -> bool:
        """Whether mmetric compares its normals (``hasNormals``): one normal per position."""
        return len(self.positions) > 0 and len(self.normals) == len(self.positions)

    def corner_uvs(self) -> np.ndarray:
        """``(F, 3, 2)`` the UV of every corner (mmetric's ``fetchTriangleUVs``); only meaningful with ``has_uvs``."""
        return self.uvs[self.triangles_uv if len(self.triangles_uv) else self.triangles]


def _obj_maps(p: Path, mtllibs: list[tuple[str, int]]) -> tuple[np.ndarray | None, ...]:
    """The map set mmetric reads for an OBJ: every material of every ``mtllib``, in order, its map or ``None``."""
    from torchmeshmetric.data.obj import parse_mtl

    maps: list[np.ndarray | None] = []
    for name, line in mtllibs:
        mtl = p.parent / name
        if not mtl.is_file():
            warnings.warn(
                f"{p}:{line}: 'mtllib {name}' names a material file that does not exist ({mtl}); as mmetric, the "
                "comparison goes on without its materials",
                stacklevel=3,
            )
            continue
        for m in parse_mtl(mtl):
            image = None
            if m.map_kd is not None:
                f = mtl.parent / m.map_kd
                if f.is_file():
                    image = read_texture(f, f"{p} (map_Kd at {mtl}:{m.map_line})")
                else:
                    warnings.warn(
                        f"{mtl}:{m.map_line}: the texture '{f}' of material '{m.name}' does not exist; as mmetric, it "
                        "is compared as a null map",
                        stacklevel=3,
                    )
            maps.append(image)
    return tuple(maps) or (None,)  # no material: mmetric compares one null map


def load_equality_model(path: str | os.PathLike, texture: str | os.PathLike | None = None) -> EqualityModel:
    r"""Read a mesh file as ``mm compare --mode equ`` / ``eqTFAN`` read it, through the one reader per format.

    OBJ: ``v`` positions; ``vt`` lines as listed, indexed per corner (a corner without one takes the first, as
    mmetric's reader does); the ``v x y z r g b`` colours of the vertices that have one, as mmetric scales them
    (``roundf(value * 255)``); ``vn`` lines as listed, unless a face corner names a normal (``v/vt/vn``, ``v//vn``):
    mmetric then drops them all. The texture maps are every material of every ``mtllib``, in order (a material
    without ``map_Kd`` has none), read as mmetric reads them (:func:`~torchmeshmetric.mpeg.read_texture`); a missing
    MTL or texture file is warned about and, as mmetric does, compared as no map. PLY: ``x y z``, ``red green blue``,
    ``nx ny nz`` and ``texture_u texture_v`` (per vertex) of a plain PLY; other PLYs, OFF and the other formats give
    positions and triangles (and colours where trimesh finds them). The positions and triangles are checked as
    :func:`~torchmeshmetric.data.load_mesh` checks them. A file without faces (an OBJ of ``v`` lines, a PLY point
    cloud such as ``mm sample`` writes, binary or ASCII, with its ``red green blue`` / ``nx ny nz`` /
    ``texture_u texture_v``) is a model without triangles, which :func:`mesh_equality` compares as mmetric compares
    point clouds; it needs at least one vertex, all finite (mmetric refuses a model without vertices too).

    Args:
        path: OBJ, PLY or OFF file.
        texture: a texture image replacing the file's maps (mmetric's ``--inputMap``).

    Returns:
        :class:`EqualityModel`.

    Raises:
        MeshFileError: unreadable or malformed file (naming the file and line), a greyscale texture, a file without
            faces or vertices, a NaN or infinite coordinate.

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (d / "t.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\nf 1 2 3\n")
        >>> load_equality_model(d / "t.obj").normals.shape
        (3, 3)
    """
    from torchmeshmetric.data.io import read_mesh_arrays
    from torchmeshmetric.data.mesh_file import MeshFileError, check_dtype_range, check_mesh, existing_mesh_file
    from torchmeshmetric.data.obj import parse_obj
    from torchmeshmetric.data.ply import read_plain_ply, read_ply_point_arrays

    p = existing_mesh_file(path)
    f32 = torch.float32
    given = (read_texture(Path(texture), "texture"),) if texture is not None else None
    points = read_ply_point_arrays(p) if p.suffix.lower() == ".ply" else None
    if points is not None:  # a PLY without faces: mmetric's point-cloud branch compares its positions
        return _ply_model(p, points, given)
    if p.suffix.lower() == ".obj":
        data = p.read_bytes()
        try:
            d = parse_obj(p, data, uvs=True, normals=True)
        except MeshFileError:
            # mmetric drops the normals when a face corner names one (below), unread: a malformed or NaN 'vn' line
            # there is no error (review P: such files compared before the normals were read). Read again without
            # them only then, so a file without a fault is parsed once.
            d = parse_obj(p, data, uvs=True, normals=False)
            if not d.normal_indexed:
                raise
        faces, face_uvs = d.triangles()
        if len(faces):
            check_mesh(p, d.verts, faces, d.vert_lines)
        else:  # no face: a point cloud for mmetric, whose positions must be there and finite all the same
            _check_points(p, d.verts, d.vert_lines)
        check_dtype_range(p, d.verts, f32, d.vert_lines, "mmetric reads coordinates as float32")
        what = ("texture coordinate", "values", "'vt' lines")
        check_dtype_range(p, d.uvs, f32, d.uv_lines, "mmetric reads texture coordinates as float32", what=what)
        what = ("normal", "values", "'vn' lines")
        if not d.normal_indexed:
            check_dtype_range(p, d.normals, f32, d.normal_lines, "mmetric reads normals as float32", what=what)
        indexed = face_uvs >= 0
        return EqualityModel(
            positions=d.verts.astype(np.float32),
            triangles=faces,
            uvs=d.uvs.astype(np.float32),
            # mmetric keeps the UV index table when any corner has an index; the others index the first UV
            triangles_uv=np.where(indexed, face_uvs, 0) if indexed.any() else _empty(3, np.int64),
            colors=_obj_colors(d.color_rows),
            # "normals with separate index table are not yet supported. Skipping normals." (mmetric's reader)
            normals=_empty(3) if d.normal_indexed else d.normals.astype(np.float32),
            textures=given or _obj_maps(p, d.mtllibs),
        )
    plain = read_plain_ply(p) if p.suffix.lower() == ".ply" else None
    if plain is not None:
        check_mesh(p, plain.verts, plain.faces, None)
        return _ply_model(p, plain, given)
    verts, faces, colors = read_mesh_arrays(p)
    return _ply_model(p, PlyArrays(verts, faces, colors), given)


def _check_points(p: Path, verts: np.ndarray, lines: np.ndarray | None) -> None:
    """A model without faces, as mmetric takes it: at least one position (mm: "has no vertices"), all finite."""
    from torchmeshmetric.data.mesh_file import MeshFileError, check_vertices

    if verts.shape[0] == 0:
        raise MeshFileError(f"path: mesh file '{p}' has no vertices and no faces (mmetric refuses it too)")
    check_vertices(p, verts, "vertex", lines)


def _ply_model(p: Path, arrays: PlyArrays, given: tuple[np.ndarray | None, ...] | None) -> EqualityModel:
    """The model of a mesh read by a PLY (or other non-OBJ) reader, or of a PLY point cloud (no faces)."""
    from torchmeshmetric.data.mesh_file import check_dtype_range

    f32 = torch.float32
    if len(arrays.faces) == 0:
        _check_points(p, arrays.verts, None)
    check_dtype_range(p, arrays.verts, f32, None, "mmetric reads coordinates as float32")
    extra = {}
    for name, values in (("normals", arrays.normals), ("uvs", arrays.uvs)):
        if values is not None:
            what = (name[:-1], "values", name)
            check_dtype_range(p, values, f32, None, f"mmetric reads {name} as float32", what=what)
            extra[name] = values.astype(np.float32)
    return EqualityModel(
        positions=arrays.verts.astype(np.float32),
        triangles=arrays.faces,
        colors=_empty(3) if arrays.colors is None else arrays.colors.astype(np.float32),
        textures=given or (None,),
        **extra,
    )


@dataclass(frozen=True)
class MeshEquality:
    """The outcome of :func:`mesh_equality`.

    Attributes:
        equal: every triangle of A has its own equal triangle in B (and the counts agree); for point clouds
            (``points``), the sorted positions agree (within ``epsilon``).
        triangles_a: triangle count of A.
        triangles_b: triangle count of B.
        different_triangles: triangles of A without an equal triangle in B (``None`` when the counts differ:
            mmetric stops there).
        first_unmatched: index of the first triangle of A without an equal triangle in B, the one mmetric names
            with its default early return (``None`` when there is none or the counts differ).
        position_differences: positions that differ index by index, plus the difference of the position counts
            (mmetric's "Position differences", printed when the meshes differ).
        textures: the texture comparison, one entry per pair of maps where either model has one: ``"equal"``,
            ``"mapA is null"``, ``"mapB is null"``, ``"dimensions"`` or ``"<n> pixel differences"``; or the single
            entry ``"set sizes"`` (the models have different numbers of maps) or ``"skipped"`` (neither has a map
            set at all); empty when neither model has a map.
        uv_differences: the same for the UV lists ("UV coords differences").
        color_differences: the same for the colour lists ("Colors differences").
        normal_differences: the same for the normal lists ("Normals differences").
        points: neither model has a triangle: their sorted positions were compared (mmetric's point-cloud branch,
            ``model vertices are equals``); ``different_triangles`` and ``first_unmatched`` are then ``None``.
        point_differences: point clouds compared with ``epsilon`` > 0 and as many points on both sides: the sorted
            points at distance ``>= epsilon`` ("found N differences"); ``None`` otherwise.

    Example:
        >>> import torch
        >>> from torchmeshmetric.structures import Mesh
        >>> v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
        >>> a = TexturedMesh(Mesh(v, torch.tensor([[0, 1, 2], [1, 3, 2]])))
        >>> b = TexturedMesh(Mesh(v, torch.tensor([[3, 2, 1], [2, 0, 1]])))  # the same triangles, other order
        >>> e = mesh_equality(a, b)
        >>> e.equal, e.triangles_a, e.different_triangles, e.first_unmatched
        (True, 2, 0, None)
    """

    equal: bool
    triangles_a: int
    triangles_b: int
    different_triangles: int | None
    first_unmatched: int | None
    position_differences: int
    textures: tuple[str, ...]
    uv_differences: int = 0
    color_differences: int = 0
    normal_differences: int = 0
    points: bool = False
    point_differences: int | None = None

    def report(self, early_return: bool = True) -> str:
        """Every line mmetric's ``compare --mode equ`` prints between ``Epsilon = ...`` and its timing.

        Args:
            early_return: as mmetric's ``--earlyReturn`` (default true): name the first unmatched triangle
                instead of counting them all (and the lists' differences).

        Returns:
            One or more lines, without a trailing newline.

        Example:
            >>> print(MeshEquality(False, 4, 4, 1, 2, 0, ("7 pixel differences",), 0, 0, 3).report(False))
            texture maps are not equal: 7pixel differences
            meshes are not equal, 1 different triangles
            Position differences: 0
            UV coords differences: 0
            Colors differences: 0
            Normals differences: 3
        """
        lines = [_texture_line(t) for t in self.textures]
        if self.points:
            lines.append(_points_line(self.equal, self.point_differences))
        elif self.different_triangles is None:
            lines.append(
                f"meshes are not equal, number of triangles are different {self.triangles_a} vs {self.triangles_b}"
            )
        elif self.equal:
            lines.append("meshes are equal")
        elif early_return:
            lines += [
                "meshes are not equal, early return.",
                f"triangle number {self.first_unmatched} from A has no equivalent in B",
            ]
        else:
            lines += [
                f"meshes are not equal, {self.different_triangles} different triangles",
                f"Position differences: {self.position_differences}",
                f"UV coords differences: {self.uv_differences}",
                f"Colors differences: {self.color_differences}",
                f"Normals differences: {self.normal_differences}",
            ]
        return "\n".join(lines)


def _points_line(equal: bool, differences: int | None) -> str:
    """The line mmetric's point-cloud branch prints (its "equals", its count of differences with an epsilon)."""
    if equal:
        return "model vertices are equals"
    if differences is None:
        return "model vertices are not equals"
    return f"model vertices are not equals, found {differences} differences"


def _epsilon(epsilon: object) -> np.float32:
    """``epsilon`` as the float32 mmetric reads, checked: a finite distance >= 0."""
    x = check_real(epsilon, "epsilon")
    with np.errstate(over="ignore"):
        e = np.float32(x)
    if not (np.isfinite(e) and x >= 0):
        raise ValueError(f"epsilon: expected a finite float32 distance >= 0, found {x!r}")
    return e


def _sorted_points(positions: np.ndarray) -> np.ndarray:
    """The positions in mmetric's order: lexicographic on (x, y, z), as its ``CompareVertex<true, ...>`` sorts them.

    -0.0 is made 0.0: mmetric's ``<`` sees them equal, so either may come first there; the comparison below is the
    same whichever did (the files of the sorted points place them:
    :func:`~torchmeshmetric.mpeg.comparison.point_order.mmetric_point_order`).
    """
    keys, order = lexicographic_order(positions)
    return keys[order]


def point_cloud_verdict(a: np.ndarray, b: np.ndarray, epsilon: float = 0.0) -> tuple[bool, int | None]:
    """Mmetric's comparison of two models without triangles: their positions sorted, then compared.

    Args:
        a: ``(N, 3)`` positions of A (compared as float32).
        b: ``(M, 3)`` positions of B.
        epsilon: 0: the sorted lists must be equal, value for value (``-0.0 == 0.0``); > 0: lists of equal length
            are compared point by point, a point differing when ``length(A - B) >= epsilon``, computed as mmetric's
            ``glm::length`` does in float32 (``sqrt((dx*dx + dy*dy) + dz*dz)``).

    Returns:
        ``(equal, differences)``: ``differences`` is the count of differing points with ``epsilon`` > 0 and lists
        of equal length, else ``None``.

    Raises:
        ValueError: ``epsilon`` negative, NaN or beyond float32.

    Example:
        >>> a = np.array([[0, 0, 1], [0, 0, 0]], np.float32)
        >>> point_cloud_verdict(a, a[::-1]), point_cloud_verdict(a, a + [0, 0, 0.5], epsilon=0.5)
        ((True, None), (False, 2))
    """
    eps = _epsilon(epsilon)
    sa = _sorted_points(np.asarray(a, dtype=np.float32).reshape(-1, 3))
    sb = _sorted_points(np.asarray(b, dtype=np.float32).reshape(-1, 3))
    if eps == 0:
        return sa.shape == sb.shape and bool(np.array_equal(sa, sb)), None
    if sa.shape != sb.shape:
        return False, None
    with np.errstate(over="ignore", invalid="ignore"):  # an overflowing difference is an infinite distance, as in C++
        d = sa - sb
        length = np.sqrt((d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2])
    count = int((length >= eps).sum())
    return count == 0, count


def _texture_line(status: str) -> str:
    """The line mmetric prints for one entry of :attr:`MeshEquality.textures` (its spelling, its missing space)."""
    if status == "set sizes":
        return "texture maps are not of equal: size of set A is diffrent from size of set B"
    if status == "skipped":
        return "skipping texture maps comparison"
    if status == "equal":
        return "texture maps are equal"
    if status == "dimensions":
        return "texture maps are not equal: dimensions are not equal"
    if status.endswith(" pixel differences"):
        return f"texture maps are not equal: {status.split()[0]}pixel differences"
    return f"texture maps are not equal: {status}"


def _as_model(m: EqualityModel | TexturedMesh | MeshLike, name: str) -> EqualityModel:
    """An :class:`EqualityModel` as it is; a textured (or plain) mesh with its per-corner UVs and its one map."""
    if isinstance(m, EqualityModel):
        return m
    t = as_textured_mesh(m, name)
    faces = t.mesh.faces.detach().cpu().numpy()
    uvs, tuv = _empty(2), _empty(3, np.int64)
    if t.uvs is not None:
        uvs = t.uvs.detach().cpu().numpy().reshape(-1, 2)
        tuv = np.arange(3 * faces.shape[0], dtype=np.int64).reshape(-1, 3)
    return EqualityModel(
        positions=t.mesh.verts.detach().cpu().numpy().astype(np.float32),
        triangles=faces,
        uvs=uvs,
        triangles_uv=tuv,
        colors=t.colors.detach().cpu().numpy() if t.colors is not None else _empty(3),
        textures=(t.texture,),
    )


def _corner_rows(m: EqualityModel, with_uv: bool, with_colour: bool, with_normal: bool) -> np.ndarray:
    """``(F, 3, D)`` float32 corner attributes: position, then UV, colour and normal when compared."""
    parts = [m.positions[m.triangles]]
    if with_uv:
        parts.append(m.corner_uvs())
    if with_colour:
        parts.append(m.colors[m.triangles])
    if with_normal:
        parts.append(m.normals[m.triangles])
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


def _texture_status(a: tuple[np.ndarray | None, ...], b: tuple[np.ndarray | None, ...]) -> tuple[str, ...]:
    """The map sets compared pair by pair, as mmetric does (RGB texel by texel, when the dimensions agree)."""
    if len(a) != len(b):
        return ("set sizes",)
    if not a:
        return ("skipped",)
    out = []
    for ma, mb in zip(a, b, strict=True):
        if ma is None and mb is None:
            continue  # mmetric prints nothing for two null maps
        if ma is None or mb is None:
            out.append("mapA is null" if ma is None else "mapB is null")
        elif ma.shape != mb.shape:
            out.append("dimensions")
        else:
            diffs = int(np.any(ma != mb, axis=2).sum())
            out.append("equal" if diffs == 0 else f"{diffs} pixel differences")
    return tuple(out)


def mesh_equality(
    a: EqualityModel | TexturedMesh | MeshLike,
    b: EqualityModel | TexturedMesh | MeshLike,
    unoriented: bool = False,
    epsilon: float = 0.0,
) -> MeshEquality:
    """Whether two meshes have the same triangles in any order, as mmetric's ``compare --mode equ`` decides.

    Corners are compared by position, and by UV (resp. colour, normal) when both meshes have UVs (resp. colours,
    normals) -- per corner or per position, see :class:`EqualityModel` --, all as float32 values; a triangle equals
    another when its corners are a rotation of the other's (or also a reflection with ``unoriented``). Each
    triangle of B matches at most one triangle of A. The texture maps are compared too (they do not change the
    verdict, as in mmetric), and the position, UV, colour and normal lists index by index. When neither model has a
    triangle (point clouds), their positions are compared as :func:`point_cloud_verdict` does (mmetric's point-cloud
    branch); one model with triangles and one without have different triangle counts.

    Args:
        a: reference mesh (mmetric's ``--inputModelA``): :func:`load_equality_model` reads a file as mmetric does;
            a :class:`~torchmeshmetric.mpeg.TexturedMesh` (or any mesh form) gives its own arrays (UVs per corner,
            its texture as its one map, no normals).
        b: distorted mesh (``--inputModelB``).
        unoriented: mmetric's ``--unoriented``: a triangle also equals its reversed copy.
        epsilon: mmetric's ``--epsilon``: the distance at which two sorted points of point clouds differ (0: they
            must be equal); ignored for meshes, as mmetric ignores it.

    Raises:
        ValueError: ``epsilon`` negative, NaN or beyond float32.

    Returns:
        :class:`MeshEquality` (the verdict, counts and mmetric's lines through ``report()``).

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
    unoriented = check_flag(unoriented, "unoriented")
    _epsilon(epsilon)  # checked for meshes too: a bad value is refused whatever the models
    a, b = _as_model(a, "a"), _as_model(b, "b")
    fa, fb = int(a.triangles.shape[0]), int(b.triangles.shape[0])
    textures = _texture_status(a.textures, b.textures)
    lists = _list_differences(a, b)
    if fa != fb:
        return MeshEquality(False, fa, fb, None, None, textures=textures, **lists)
    if fa == 0:  # neither has a triangle: mmetric compares the sorted positions
        equal, diffs = point_cloud_verdict(a.positions, b.positions, epsilon)
        return MeshEquality(equal, 0, 0, None, None, textures=textures, **lists, points=True, point_differences=diffs)
    flags = (a.has_uvs and b.has_uvs, a.has_colors and b.has_colors, a.has_normals and b.has_normals)
    rows = np.concatenate([_corner_rows(a, *flags), _corner_rows(b, *flags)])
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
    return MeshEquality(unmatched.size == 0, fa, fb, int(unmatched.size), first, textures=textures, **lists)
