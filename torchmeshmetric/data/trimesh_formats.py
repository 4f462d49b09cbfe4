"""PLY, STL and GLB/GLTF through trimesh (``process=False``, order kept), with the declared element counts checked.

trimesh is imported on use only (~0.3 s): ``import torchmeshmetric`` never loads it.
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from torchmeshmetric.data.mesh_file import MeshFileError, not_a_mesh, text_lines
from torchmeshmetric.data.ply import declared_counts, header_end, polygon_error, read_ply_file

__all__ = ["read_with_trimesh"]


def _utf8(data: bytes) -> bytes:
    """``data`` as UTF-8: unchanged when it is, else read as Latin-1 (trimesh then never guesses an encoding)."""
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1").encode("utf-8")
    return data


def read_with_trimesh(p: Path, suffix: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """PLY, STL and GLB/GLTF through trimesh, with the declared element counts checked; ``(verts, faces, colors)``.

    ``colors`` are ``(V, 3)`` per-vertex colours in ``[0, 255]`` when the file has some, else ``None``.
    """
    import trimesh  # ~0.3 s to import: on use only, `import torchmeshmetric` never loads it

    declared: dict[str, int] = {}
    source: Any = os.fspath(p)
    if suffix == ".ply":
        data = read_ply_file(p)
        declared = declared_counts(p, data)  # the header checked line by line, as for every PLY
        end = header_end(data)
        # without its comments: trimesh takes the first "end_header" in the file, a comment's too, for the end
        head = b"".join(ln for ln in data[:end].splitlines(keepends=True) if ln.split()[:1] != [b"comment"])
        source = io.BytesIO(_utf8(head) + data[end:])
    elif suffix == ".stl":
        data = p.read_bytes()
        n = int.from_bytes(data[80:84], "little") if len(data) >= 84 else -1
        if len(data) != 84 + 50 * n:  # not binary STL: must be text
            if not data.lstrip().startswith(b"solid"):
                raise MeshFileError(
                    f"path: '{p}' is not a mesh file, or is truncated: a text STL starts with 'solid', and a binary "
                    f"STL whose header declares {max(n, 0)} triangles holds 84 + 50 * {max(n, 0)} bytes, this file "
                    f"{len(data)} bytes"
                )
            text_lines(p, data)
            data = _utf8(data)
        else:
            declared = {"face": n}
        source = io.BytesIO(data)
    elif suffix == ".glb" and p.read_bytes()[:4] != b"glTF":
        raise not_a_mesh(p, "a GLB file starts with 'glTF'")
    elif suffix == ".gltf" and p.read_bytes()[:4] != b"glTF":  # binary glTF named .gltf: trimesh decides, as before
        # trimesh falls back on a text that is not JSON and names a file the user never gave: "model.gltf" (found
        # by review)
        try:
            json.loads(p.read_bytes())
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            where = f"line {err.lineno} column {err.colno}: {err.msg}" if isinstance(err, json.JSONDecodeError) else err
            raise not_a_mesh(p, f"a .gltf file is JSON; {where}") from err
    try:
        loaded = trimesh.load(source, file_type=suffix[1:], process=False, maintain_order=True)
    except Exception as err:  # trimesh raises many exception types on malformed input
        hint = ""
        if declared:
            counts = ", ".join(f"{n} {element}" for element, n in declared.items())
            hint = f"; its header declares {counts} elements: truncated or malformed?"
        raise MeshFileError(f"path: could not read mesh file '{p}' ({type(err).__name__}: {err}){hint}") from err
    if isinstance(loaded, trimesh.Scene):
        geoms = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)] if loaded.geometry else []
        if not geoms:
            raise MeshFileError(f"path: mesh file '{p}' holds no triangle geometry")
        loaded = trimesh.util.concatenate(geoms) if len(geoms) > 1 else geoms[0]
    if not isinstance(loaded, trimesh.Trimesh):
        raise MeshFileError(f"path: '{p}' holds a {type(loaded).__name__}, not a triangle mesh")
    if suffix == ".ply":
        _refuse_polygons(p, loaded)
    verts = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.int64)
    for element, held in (("vertex", verts.shape[0]), ("face", faces.shape[0])):
        if element in declared and declared[element] != held:
            what = "triangles" if element == "face" else "vertices"
            hint = " (truncated, or faces that are not triangles)" if element == "face" else " (truncated)"
            raise MeshFileError(
                f"path: '{p}' declares {declared[element]} {element} elements but holds {held} {what}{hint}"
            )
    visual = getattr(loaded, "visual", None)
    vc = getattr(visual, "vertex_colors", None)
    colors = None
    if vc is not None and getattr(visual, "kind", None) == "vertex":
        colors = np.asarray(vc, dtype=np.float64)[:, :3]
    return verts, faces, colors


def _refuse_polygons(p: Path, loaded: Any) -> None:
    """Refuse a PLY whose face lists, as trimesh read them, are not all triangles (trimesh fans polygons).

    The count check (triangles against declared faces) alone was fooled by a quad beside a 2-corner face, which
    trimesh drops (found by review). trimesh keeps the lists it read in ``metadata["_ply_raw"]``: an ``(F, n)`` array
    or an object array of lists (ASCII), or ``(count, indices)`` records (binary, every list read at the first one's
    length, so the first count that is not 3 is where the faces stop being triangles). A short last list is left to
    the count check, which calls the file truncated. Without that metadata (another trimesh), the count check remains.
    """
    raw = getattr(loaded, "metadata", {}).get("_ply_raw")
    data = raw.get("face", {}).get("data") if isinstance(raw, dict) and isinstance(raw.get("face"), dict) else None
    names = data.keys() if isinstance(data, dict) else getattr(getattr(data, "dtype", None), "names", None) or ()
    name = next((n for n in ("vertex_indices", "vertex_index") if n in names), None)
    if name is None:
        return
    lists = np.asarray(data[name])  # type: ignore[index]
    if lists.dtype.names:
        corners = lists[lists.dtype.names[0]].astype(np.int64).reshape(-1)
    elif lists.dtype == object:
        corners = np.fromiter((len(f) for f in lists), dtype=np.int64, count=lists.shape[0])
    else:
        corners = np.full(lists.shape[0], lists.shape[1] if lists.ndim == 2 else 1, dtype=np.int64)
    bad = np.flatnonzero(corners != 3)
    if bad.size and bad[0] == corners.shape[0] - 1 and corners[bad[0]] < 3:
        return  # a short last list: a file cut there, which the count check names as truncated
    if bad.size:
        raise polygon_error(p, int(bad[0]), int(corners[bad[0]]))
