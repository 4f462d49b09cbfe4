"""Meshes with colour: textured OBJ (+ MTL + PNG/JPG, UVs per face corner) and per-vertex colours."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._checks import DTypeError, ShapeError, check_finite, check_float, check_shape
from torchmeshmetric.data.io import read_mesh_arrays
from torchmeshmetric.data.mesh_file import MeshFileError, check_dtype_range, check_mesh, existing_mesh_file, to_tensor
from torchmeshmetric.data.obj import MtlMaterial, ObjData, parse_mtl, parse_obj
from torchmeshmetric.mpeg.core._float32 import roundf
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

__all__ = ["TexturedMesh", "as_textured_mesh", "load_textured_mesh", "read_texture"]


@dataclass(frozen=True, eq=False)
class TexturedMesh:
    """A mesh with optional colour, as V-DMC frames carry it.

    Args:
        mesh: the geometry.
        uvs: ``(F, 3, 2)`` float32 texture coordinates per face corner (seams keep their duplicated positions).
        texture: ``(H, W, 3)`` uint8 texture image (row 0 at the top, as stored in the file).
        colors: ``(V, 3)`` float32 per-vertex colours in ``[0, 255]`` (used when there is no texture).

    Example:
        >>> import torch
        >>> m = Mesh(torch.eye(3), torch.tensor([[0, 1, 2]]))
        >>> TexturedMesh(m).has_color
        False
    """

    mesh: Mesh
    uvs: Tensor | None = None
    texture: np.ndarray | None = None
    colors: Tensor | None = None

    def __post_init__(self) -> None:
        """Check the colour against the mesh when built (shapes, dtypes, finite values), naming the field."""
        if not isinstance(self.mesh, Mesh):
            raise TypeError(
                f"mesh: expected a Mesh, found {type(self.mesh).__name__} (as_textured_mesh takes (V, F) and trimesh)"
            )
        nv, nf = int(self.mesh.verts.shape[0]), int(self.mesh.faces.shape[0])
        if self.uvs is not None:
            check_shape(self.uvs, (nf, 3, 2), "uvs")
            check_float(self.uvs, "uvs")
            check_finite(self.uvs, "uvs")
        if self.colors is not None:
            check_shape(self.colors, (nv, 3), "colors")
            check_float(self.colors, "colors")
            check_finite(self.colors, "colors")
        if self.texture is not None:
            if not isinstance(self.texture, np.ndarray) or self.texture.dtype != np.uint8:
                found = self.texture.dtype if hasattr(self.texture, "dtype") else type(self.texture).__name__
                raise DTypeError(
                    f"texture: expected an (H, W, 3) uint8 numpy image (as read_texture gives), found {found}"
                )
            if self.texture.ndim != 3 or self.texture.shape[2] != 3 or 0 in self.texture.shape:
                raise ShapeError(f"texture: expected shape (H, W, 3) with H, W >= 1, found {self.texture.shape}")

    @property
    def has_color(self) -> bool:
        """Whether samples of this mesh carry a colour (a texture with UVs, or per-vertex colours)."""
        return (self.texture is not None and self.uvs is not None) or self.colors is not None


def as_textured_mesh(mesh: TexturedMesh | MeshLike, name: str = "mesh") -> TexturedMesh:
    """A :class:`TexturedMesh` as it is; any other mesh form (a :class:`Mesh`, ``(V, F)``, trimesh) without colour.

    Args:
        mesh: the mesh.
        name: its name in error messages.

    Returns:
        :class:`TexturedMesh`.

    Raises:
        TypeError, ShapeError, DTypeError, IndexRangeError, NonFiniteError: as :func:`~torchmeshmetric.as_mesh`.

    Example:
        >>> import torch
        >>> as_textured_mesh((torch.eye(3), torch.tensor([[0, 1, 2]]))).has_color
        False
    """
    if isinstance(mesh, TexturedMesh):
        return mesh
    return TexturedMesh(as_mesh(mesh, name=name))


def read_texture(path: str | os.PathLike, where: str = "texture") -> np.ndarray:
    """A texture image as mmetric reads it (stb_image): ``(H, W, 3)`` uint8, row 0 at the top.

    8-bit RGB and RGBA images are taken as stored (alpha dropped: mmetric reads the first three channels);
    16-bit ones are reduced to their high byte (``value >> 8``, stb_image's ``stbi__convert_16_to_8``); paletted
    images are expanded through their palette. Greyscale images (1 or 2 channels, any depth) are refused: mmetric
    keeps their channel count and reads three consecutive bytes per texel, so its colours would be meaningless.

    Args:
        path: PNG, JPEG (or another format Pillow reads) file.
        where: who asked for it, for messages (the OBJ and MTL line).

    Returns:
        ``(H, W, 3)`` uint8 array.

    Raises:
        MeshFileError: missing or unreadable file, a greyscale or otherwise unsupported image mode.

    Example:
        >>> import tempfile, pathlib
        >>> from PIL import Image
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "t.png"
        >>> Image.new("P", (2, 1), 0).save(p)  # a paletted image
        >>> read_texture(p).shape
        (1, 2, 3)
    """
    from PIL import Image

    path = Path(path)
    if not path.is_file():
        raise MeshFileError(f"{where}: texture file '{path}' not found")
    with open(path, "rb") as fh:
        head = fh.read(26)
    # Pillow widens a 16-bit grey+alpha PNG to RGBA: read the PNG's own colour type (0 grey, 4 grey + alpha)
    png_grey = head[:8] == b"\x89PNG\r\n\x1a\n" and len(head) == 26 and head[25] in (0, 4)
    try:
        with Image.open(path) as im:
            im.load()
            mode = "LA" if png_grey and im.mode not in ("L", "LA", "1", "I", "I;16", "I;16B") else im.mode
            if mode in ("RGB", "RGBA", "RGBX", "RGBa"):
                # Pillow already reduces 16-bit RGB(A) PNGs to their high byte, as stb_image does.
                arr = np.asarray(im)[..., :3]
            elif mode in ("P", "PA"):
                arr = np.asarray(im.convert("RGBA" if mode == "PA" else "RGB"))[..., :3]
            elif mode in ("CMYK", "YCbCr", "LAB", "HSV"):
                arr = np.asarray(im.convert("RGB"))
            elif mode in ("1", "L", "LA", "La", "I", "I;16", "I;16B", "I;16L", "I;16N", "F"):
                raise MeshFileError(
                    f"{where}: texture '{path}' is a greyscale image (mode {mode}); mmetric v1.1.7 reads a "
                    "greyscale map as if it had three channels per texel, so its colour figures would be "
                    "meaningless: save the texture as RGB"
                )
            else:
                raise MeshFileError(f"{where}: texture '{path}' has the unsupported image mode {mode}")
    except OSError as exc:
        raise MeshFileError(f"{where}: cannot read texture '{path}': {exc}") from exc
    return np.ascontiguousarray(arr, dtype=np.uint8)


def _obj_colors(colors: np.ndarray) -> np.ndarray:
    """``v x y z r g b`` colours as mmetric stores them: ``roundf((float)value * 255)`` (halves away from 0)."""
    return roundf(colors.astype(np.float32) * np.float32(255.0)).astype(np.float32)


def _obj_texture(p: Path, d: ObjData, corner_uv: np.ndarray | None) -> tuple[Path, str] | None:
    """The texture file the faces' material names (through ``mtllib`` / ``usemtl`` / ``map_Kd``), with its source.

    Returns ``None`` when the faces use no textured material. Materials are numbered as mmetric numbers them (every
    ``mtllib``'s ``newmtl`` in order; faces before any ``usemtl``, or after one naming an unknown material, keep
    the material in force, the first by default).
    """
    if corner_uv is None:
        return None  # no UVs: no texture is looked up (nor its MTL)
    materials: list[MtlMaterial] = []
    mtl_of: list[Path] = []
    for name, line in d.mtllibs:
        mtl = p.parent / name
        if not mtl.is_file():
            raise MeshFileError(
                f"{p}:{line}: 'mtllib {name}' names a material file that does not exist ({mtl}); the texture it "
                "names is needed for the colour figures: restore it, pass the texture explicitly (texture=..., "
                "--ref-texture/--dis-texture), or remove the mtllib line for geometry-only figures"
            )
        found = parse_mtl(mtl)
        materials += found
        mtl_of += [mtl] * len(found)
    if not materials:
        return None
    index = {m.name: i for i, m in reversed(list(enumerate(materials)))}  # the first of equal names, as mmetric
    # usemtl k -> material index; the last entry (-1 in face_materials: before any usemtl) is the first material
    known = np.array([index.get(name, -1) for name in d.materials] + [0], dtype=np.int64)
    per_face = known[d.face_materials]
    if (per_face < 0).any():
        per_face = per_face.copy()
        last = 0
        for j in range(per_face.shape[0]):  # rare: an unknown usemtl name keeps the previous material
            if per_face[j] < 0:
                per_face[j] = last
            last = per_face[j]
    used = sorted(set(per_face.tolist()))
    maps = {i: (mtl_of[i].parent / materials[i].map_kd if materials[i].map_kd else None) for i in used}
    textured = {i: m for i, m in maps.items() if m is not None}
    if not textured:
        return None
    if len(set(textured.values())) > 1 or len(textured) != len(maps):
        lines = ", ".join(
            f"'{materials[i].name}' ({m.name if (m := maps[i]) is not None else 'no map_Kd'})" for i in used
        )
        raise MeshFileError(
            f"{p}: its faces use materials with different textures ({lines}); one texture per mesh is supported: "
            "merge the textures into one atlas, or pass one texture explicitly"
        )
    i = used[0] if used[0] in textured else next(iter(textured))
    return textured[i], f"{mtl_of[i]}:{materials[i].map_line}"


def load_textured_mesh(path: str | os.PathLike, texture: str | os.PathLike | None = None) -> TexturedMesh:
    r"""Load a mesh with its colour (texture and UVs, or per-vertex colours), through the library's one reader.

    An OBJ with UVs and a texture (from its MTL ``map_Kd`` or ``texture``), an OBJ with per-vertex colours
    (``v x y z r g b``, values in ``[0, 1]`` scaled to 8 bits as mmetric does: ``roundf(value * 255)``), or a PLY
    with vertex colours. The OBJ is read by the same parser as :func:`~torchmeshmetric.data.load_mesh` (the same
    geometry, checks and file:line messages; negative indices count back from the last element defined before
    their line), polygons are fanned from their first corner as mmetric does, and ``vt`` lines and indices are
    checked too (finite, in range, every face with one when any has one). Textures are read as mmetric reads them
    (:func:`read_texture`). Coordinates must fit float32 (mmetric reads them as float).

    Args:
        path: OBJ, PLY or OFF file.
        texture: texture image overriding the MTL's (mmetric's ``--inputMap``).

    Returns:
        :class:`TexturedMesh` (no colour when the file has none).

    Raises:
        MeshFileError: unreadable or malformed file (naming the file and line), an ``mtllib`` naming a missing
            MTL file, a missing or greyscale texture, faces using several textures.

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (d / "t.obj").write_text("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n")
        >>> load_textured_mesh(d / "t.obj").colors[0].tolist()
        [255.0, 0.0, 0.0]
    """
    p = existing_mesh_file(path)
    suffix = p.suffix.lower()
    hint = "mmetric reads coordinates as float32"
    if suffix != ".obj":
        verts, faces, colors = read_mesh_arrays(p)
        check_dtype_range(p, verts, torch.float32, None, hint)
        tex = read_texture(Path(texture), "texture") if texture is not None else None
        col = torch.from_numpy(colors.astype(np.float32)) if colors is not None else None
        return TexturedMesh(Mesh(to_tensor(verts, torch.float32), torch.from_numpy(faces)), None, tex, col)
    d = parse_obj(p, p.read_bytes(), uvs=True)
    faces, face_uvs = d.triangles()
    check_mesh(p, d.verts, faces, d.vert_lines)
    check_dtype_range(p, d.verts, torch.float32, d.vert_lines, hint)
    # found by review: "vt 1e300 0" became Inf in float32, refused as "uvs: expected finite values" (no file, no line)
    uv_hint = "mmetric reads texture coordinates as float32"
    check_dtype_range(p, d.uvs, torch.float32, d.uv_lines, uv_hint, what=("texture coordinate", "values", "'vt' lines"))
    corner_uv = None
    has_uv = face_uvs >= 0
    if d.uvs.shape[0] and has_uv.any():
        if not has_uv.all():
            j = int(np.nonzero(~has_uv.all(axis=1))[0][0])
            line = int(d.triangle_lines()[j])
            raise MeshFileError(
                f"{p}:{line}: this face has no texture index ('vt') while other faces have one; every face of a "
                "textured mesh needs its UVs"
            )
        corner_uv = d.uvs[face_uvs]
    mesh = Mesh(to_tensor(d.verts, torch.float32), torch.from_numpy(faces), validate=False)
    tex = None
    if texture is not None:
        tex = read_texture(Path(texture), "texture")
    else:
        found = _obj_texture(p, d, corner_uv)
        if found is not None:
            tex = read_texture(found[0], f"{p} (map_Kd at {found[1]})")
    uvs = torch.from_numpy(corner_uv.astype(np.float32)) if corner_uv is not None else None
    col = torch.from_numpy(_obj_colors(d.vert_colors)) if d.vert_colors is not None else None
    return TexturedMesh(mesh, uvs, tex, col)
