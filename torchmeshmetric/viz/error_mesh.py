"""An error-coloured mesh: a mesh with one error colour per vertex, what the HTML page and the training logs show.

One builder (:func:`error_mesh`) for every place that shows a mesh coloured by its error (the ``--html`` viewer,
TensorBoard's ``add_mesh``, a W&B GLB, a PLY/GLB artifact), and one encoding per file format (:func:`glb_bytes`,
:func:`ply_bytes`). The colours are :func:`~torchmeshmetric.viz.colors.error_colors`' (those of
:func:`~torchmeshmetric.viz.colors.write_error_ply`).
"""

from __future__ import annotations

import io
from typing import Any, NamedTuple

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._checks import check_int
from torchmeshmetric.structures import MeshLike
from torchmeshmetric.viz.colors import check_distances, check_vmax, default_vmax, error_colors, per_vertex_errors

__all__ = ["DISPLAY_FACES", "ErrorMesh", "error_mesh", "glb_bytes", "ply_bytes"]

#: Faces above which a mesh is decimated for display (the built-in demo's ~40k-face frames are shown whole).
DISPLAY_FACES = 60_000


class ErrorMesh(NamedTuple):
    """A mesh coloured by one error per vertex (a layer of the HTML viewer, a logged mesh).

    Attributes:
        name: its label (the viewer's toggle, a log's caption) (e.g. ``"Reg QEM: simplified frame 3"``).
        verts: ``(V, 3)`` float32 positions.
        faces: ``(F, 3)`` int64 vertex indices.
        colors: ``(V, 3)`` uint8 RGB colours (:func:`~torchmeshmetric.viz.colors.error_colors` of the errors).
        what: what the colour measures (e.g. ``"surface distance to registered k-1"``).
        vmax: the distance of the brightest colour (larger ones are clamped).
        unit: the unit of the distances (e.g. ``"mesh units"``).
        decimated_from: the face count before decimation for display, or ``None`` when shown whole.

    Example:
        >>> import torch, trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=1)
        >>> layer = error_mesh("sphere", sphere, torch.linspace(0, 1, 42), what="test", vmax=1.0)
        >>> layer.name, tuple(layer.verts.shape), str(layer.colors.dtype), layer.vmax, layer.decimated_from
        ('sphere', (42, 3), 'uint8', 1.0, None)
    """

    name: str
    verts: np.ndarray
    faces: np.ndarray
    colors: np.ndarray
    what: str
    vmax: float
    unit: str = "mesh units"
    decimated_from: int | None = None


def error_mesh(
    name: str,
    mesh: MeshLike,
    dists: Tensor | None,
    *,
    what: str,
    vmax: float | None = None,
    unit: str = "mesh units",
    max_faces: int = DISPLAY_FACES,
) -> ErrorMesh:
    """A mesh with its per-vertex errors, ready to be shown or logged (decimated above ``max_faces`` faces).

    Args:
        name: the layer's label.
        mesh: the mesh.
        dists: ``(V,)`` one distance per vertex, or one per referenced vertex (the paper's vertex set); ``None``
            for a reference shown without error (all vertices at distance 0).
        what: what the distances measure (shown beside the colour scale).
        vmax: the distance of the brightest colour, finite and positive (default: the 95th percentile,
            :func:`~torchmeshmetric.viz.colors.default_vmax`); give the same value to layers compared side by side.
        unit: the unit of the distances.
        max_faces: above this face count the mesh is decimated for display, each kept vertex coloured by the
            error of its nearest original vertex.

    Returns:
        The :class:`ErrorMesh`.

    Raises:
        ShapeError: ``dists`` has neither one value per vertex nor one per referenced vertex.
        NonFiniteError: a distance, or ``vmax``, is NaN or infinite.
        ValueError: a distance is negative, or ``vmax`` is not positive.
        TypeError: ``vmax`` is not a number.

    Example:
        >>> import trimesh, torch
        >>> sphere = trimesh.creation.icosphere(subdivisions=1)
        >>> layer = error_mesh("s", sphere, torch.linspace(0, 1, 42), what="test", vmax=1.0)
        >>> layer.colors.shape, layer.colors[-1].tolist()
        ((42, 3), [253, 231, 37])
    """
    from torchmeshmetric.structures import as_mesh

    max_faces = check_int(max_faces, "max_faces", low=1)
    m = as_mesh(mesh)
    d = torch.zeros(m.num_verts, dtype=torch.float64) if dists is None else dists
    m, d = per_vertex_errors(m, d.detach().cpu())
    check_distances(d)  # before the scale is taken from them: a NaN made every vertex the colour of no error
    scale = check_vmax(vmax)
    vmax = default_vmax(d.double().numpy()) if scale is None else scale
    decimated_from = None
    if m.num_faces > max_faces:
        from torchmeshmetric.kernels.nearest import nearest_vertex_distance
        from torchmeshmetric.simplification.qem import simplify_qem

        decimated_from = m.num_faces
        small = simplify_qem(m.to(dtype=torch.float64), max_faces)
        nearest = nearest_vertex_distance(small.verts, m.verts.to(small.verts)).idx
        m, d = small, d[nearest.cpu()]
    colors = error_colors(d, vmax).numpy()[:, :3] if dists is not None else np.full((m.num_verts, 3), 190, np.uint8)
    # (a reference without error is grey; its layer's `what` is empty unless the caller gives the colours' meaning)
    return ErrorMesh(
        name,
        m.verts.detach().cpu().numpy().astype(np.float32),
        m.faces.cpu().numpy().astype(np.int64),
        np.ascontiguousarray(colors, dtype=np.uint8),
        what,
        float(vmax),
        unit,
        decimated_from,
    )


def _trimesh(mesh: ErrorMesh) -> Any:
    if not isinstance(mesh, ErrorMesh):  # None failed on its missing .colors (found by review)
        raise TypeError(f"mesh: expected an ErrorMesh (from error_mesh), found {type(mesh).__name__}")
    import trimesh  # ~0.3 s to import: on use only

    rgba = np.concatenate([mesh.colors, np.full((len(mesh.colors), 1), 255, np.uint8)], axis=1)
    return trimesh.Trimesh(mesh.verts, mesh.faces, vertex_colors=rgba, process=False)


def glb_bytes(mesh: ErrorMesh) -> bytes:
    """The mesh as binary glTF (GLB) with per-vertex colours: what ``wandb.Object3D`` and 3D viewers take.

    Args:
        mesh: an :class:`ErrorMesh` (from :func:`error_mesh`).

    Returns:
        The GLB file's bytes.

    Raises:
        TypeError: ``mesh`` is not an :class:`ErrorMesh`.

    Example:
        >>> import io, torch, trimesh
        >>> m = error_mesh("s", trimesh.creation.icosphere(subdivisions=1), torch.linspace(0, 1, 42), what="", vmax=1)
        >>> back = trimesh.load(io.BytesIO(glb_bytes(m)), file_type="glb", force="mesh", process=False)
        >>> back.vertices.shape, back.visual.vertex_colors[-1].tolist()
        ((42, 3), [253, 231, 37, 255])
    """
    return bytes(_trimesh(mesh).export(file_type="glb"))


def ply_bytes(mesh: ErrorMesh) -> bytes:
    """The mesh as binary PLY with per-vertex colours (the format of :func:`~torchmeshmetric.viz.write_error_ply`).

    Args:
        mesh: an :class:`ErrorMesh` (from :func:`error_mesh`).

    Returns:
        The PLY file's bytes.

    Raises:
        TypeError: ``mesh`` is not an :class:`ErrorMesh`.

    Example:
        >>> import torch, trimesh
        >>> m = error_mesh("s", trimesh.creation.icosphere(subdivisions=1), torch.linspace(0, 1, 42), what="", vmax=1)
        >>> ply_bytes(m)[:3]
        b'ply'
    """
    buf = io.BytesIO()
    _trimesh(mesh).export(buf, file_type="ply")
    return buf.getvalue()
