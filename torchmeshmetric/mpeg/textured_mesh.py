"""Meshes with colour: textured OBJ (+ MTL + PNG/JPG, UVs per face corner) and per-vertex colours."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric.data.io import MeshFileError, load_mesh
from torchmeshmetric.structures import Mesh

__all__ = ["TexturedMesh", "load_textured_mesh"]


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

    @property
    def has_color(self) -> bool:
        """Whether samples of this mesh carry a colour (a texture with UVs, or per-vertex colours)."""
        return (self.texture is not None and self.uvs is not None) or self.colors is not None


def _read_texture(path: Path, where: str) -> np.ndarray:
    from PIL import Image

    if not path.is_file():
        raise MeshFileError(f"{where}: texture file {path} not found")
    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"), dtype=np.uint8).copy()
    except OSError as exc:
        raise MeshFileError(f"{where}: cannot read texture {path}: {exc}") from exc


def _parse_obj(
    path: Path,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray | None, str | None]:
    verts: list[list[float]] = []
    cols: list[list[float]] = []
    uvs: list[list[float]] = []
    faces: list[list[int]] = []
    fuv: list[list[int]] = []
    mtllib = None
    with open(path, encoding="utf-8", errors="replace") as fh:
        for lineno, line in enumerate(fh, 1):
            parts = line.split()
            if not parts:
                continue
            tag = parts[0]
            try:
                if tag == "v":
                    xyz = [float(x) for x in parts[1:4]]
                    if len(xyz) != 3 or not all(np.isfinite(xyz)):
                        raise ValueError("expected 3 finite coordinates")
                    verts.append(xyz)
                    if len(parts) >= 7:
                        cols.append([float(x) for x in parts[4:7]])
                elif tag == "vt":
                    uvs.append([float(x) for x in parts[1:3]])
                elif tag == "f":
                    corners = [c.split("/") for c in parts[1:]]
                    if len(corners) < 3:
                        raise ValueError("a face needs at least 3 corners")
                    vi = [int(c[0]) for c in corners]
                    ti = [int(c[1]) if len(c) > 1 and c[1] else 0 for c in corners]
                    for k in range(1, len(vi) - 1):  # fan triangulation of polygons
                        faces.append([vi[0], vi[k], vi[k + 1]])
                        fuv.append([ti[0], ti[k], ti[k + 1]])
                elif tag == "mtllib" and mtllib is None:
                    mtllib = line.strip()[len("mtllib") :].strip()
            except (ValueError, IndexError) as exc:
                raise MeshFileError(f"{path}:{lineno}: malformed '{tag}' line: {line.strip()!r} ({exc})") from exc
    v = np.asarray(verts, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    f = np.where(f < 0, f + v.shape[0], f - 1)
    t = np.asarray(fuv, dtype=np.int64).reshape(-1, 3)
    uv_arr = np.asarray(uvs, dtype=np.float64).reshape(-1, 2)
    corner_uv = None
    if uv_arr.shape[0] and f.shape[0] and (t != 0).all():
        t = np.where(t < 0, t + uv_arr.shape[0], t - 1)
        if (t >= uv_arr.shape[0]).any() or (t < 0).any():
            raise MeshFileError(f"{path}: a face's texture index is outside the {uv_arr.shape[0]} 'vt' lines")
        corner_uv = uv_arr[t]
    if f.size and ((f < 0).any() or (f >= v.shape[0]).any()):
        raise MeshFileError(f"{path}: a face's vertex index is outside the {v.shape[0]} 'v' lines")
    colors = np.asarray(cols, dtype=np.float64) if len(cols) == v.shape[0] and cols else None
    return v, f, corner_uv, colors, uv_arr, mtllib


def _texture_from_mtl(mtl: Path) -> Path | None:
    if not mtl.is_file():
        return None
    with open(mtl, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            parts = line.strip().split(maxsplit=1)
            if len(parts) == 2 and parts[0] == "map_Kd":
                return mtl.parent / parts[1].split()[-1]
    return None


def load_textured_mesh(path: str | os.PathLike, texture: str | os.PathLike | None = None) -> TexturedMesh:
    r"""Load a mesh with its colour (texture and UVs, or per-vertex colours).

    An OBJ with UVs and a texture (from its MTL ``map_Kd`` or ``texture``), an OBJ
    with per-vertex colours (``v x y z r g b``, values in ``[0, 1]`` scaled to 8 bits), or a PLY with vertex colours.

    Args:
        path: OBJ or PLY file.
        texture: texture image overriding the MTL's (mmetric's ``--inputMap``).

    Returns:
        :class:`TexturedMesh` (no colour when the file has none).

    Raises:
        MeshFileError: unreadable or malformed file, a missing texture.

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (d / "t.obj").write_text("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n")
        >>> load_textured_mesh(d / "t.obj").colors[0].tolist()
        [255.0, 0.0, 0.0]
    """
    p = Path(path)
    if not p.is_file():
        raise MeshFileError(f"{p}: file not found")
    if p.suffix.lower() != ".obj":
        mesh = load_mesh(p)
        colors = None
        import trimesh

        loaded: Any = trimesh.load(os.fspath(p), process=False, maintain_order=True)
        visual = getattr(loaded, "visual", None)
        vc = getattr(visual, "vertex_colors", None)
        if vc is not None and getattr(visual, "kind", None) == "vertex":
            colors = torch.from_numpy(np.asarray(vc, dtype=np.float32)[:, :3].copy())
        tex = _read_texture(Path(texture), "texture") if texture is not None else None
        return TexturedMesh(mesh, None, tex, colors)
    v, f, corner_uv, vcolors, _, mtllib = _parse_obj(p)
    mesh = Mesh(torch.from_numpy(v).to(torch.float32), torch.from_numpy(f))
    tex_path = Path(texture) if texture is not None else None
    if tex_path is None and mtllib is not None and corner_uv is not None:
        tex_path = _texture_from_mtl(p.parent / mtllib)
    tex = _read_texture(tex_path, str(p)) if tex_path is not None else None
    uvs = torch.from_numpy(corner_uv.astype(np.float32)) if corner_uv is not None else None
    col = torch.from_numpy((vcolors * 255.0).astype(np.float32)) if vcolors is not None else None
    return TexturedMesh(mesh, uvs, tex, col)
