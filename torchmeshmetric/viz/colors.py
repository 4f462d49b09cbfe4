"""Per-vertex error as colours, written to a coloured PLY (the idea of the paper's Fig. 6)."""

from __future__ import annotations

import io
import math
import numbers
import os
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._atomic import atomic_write
from torchmeshmetric._checks import NonFiniteError, ShapeError, check_finite, check_flag
from torchmeshmetric.kernels.sampling import vertex_set_mask
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

__all__ = [
    "ERROR_COLOR_ANCHORS",
    "check_distances",
    "check_vmax",
    "default_vmax",
    "error_colors",
    "per_vertex_errors",
    "write_error_ply",
]

#: Viridis-like anchors (dark blue = no error → yellow = vmax), linear in between (RGB, 0..255).
ERROR_COLOR_ANCHORS = np.array(
    [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]],
    dtype=np.float64,
)


def check_vmax(vmax: object, name: str = "vmax") -> float | None:
    """``None``, or ``vmax`` as a float: the distance of the brightest colour must be finite and positive.

    Every place that colours or logs errors checks its ``vmax`` here: a NaN, infinite, zero or negative one made every
    vertex the colour of "no error", without a word.

    Raises:
        TypeError: ``vmax`` is not a real number (nor a one-element tensor).
        NonFiniteError: ``vmax`` is NaN or infinite.
        ValueError: ``vmax`` is zero or negative.

    Example:
        >>> check_vmax(0.5), check_vmax(None)
        (0.5, None)
    """
    if vmax is None:
        return None
    one = isinstance(vmax, Tensor) and vmax.numel() == 1 and not vmax.dtype.is_complex and vmax.dtype != torch.bool
    if not (one or (isinstance(vmax, numbers.Real) and not isinstance(vmax, bool))):  # numpy's numbers are Real
        raise TypeError(f"{name}: expected None or a positive number, found {type(vmax).__name__} {vmax!r}")
    value = float(vmax)  # type: ignore[arg-type]
    if not math.isfinite(value):
        raise NonFiniteError(f"{name}: expected a finite distance for the brightest colour, found {value}")
    if value <= 0:
        raise ValueError(f"{name}: expected a distance > 0 for the brightest colour, found {value:g}")
    return value


def check_distances(dists: Tensor, name: str = "dists") -> None:
    """Require finite, non-negative distances (a NaN was coloured as "no error", a negative one too).

    Raises:
        NonFiniteError: a distance is NaN or infinite.
        ValueError: a distance is negative.
    """
    check_finite(dists, name)
    if dists.numel() and float(dists.min()) < 0:
        n = int((dists < 0).sum())
        raise ValueError(
            f"{name}: expected distances >= 0, found {n} negative value(s), the least {float(dists.min()):g}"
        )


def default_vmax(dists: np.ndarray) -> float:
    """The default distance of the brightest colour: the 95th percentile of ``dists``.

    When that is 0 (most vertices on the reference surface) the largest distance, so that the vertices off the
    surface still show; 1 when every distance is 0 (all of them the colour of no error) or there is none.

    Example:
        >>> import numpy as np
        >>> default_vmax(np.arange(101.0)), default_vmax(np.r_[np.zeros(99), 0.5]), default_vmax(np.zeros(3))
        (95.0, 0.5, 1.0)
    """
    if not dists.size:
        return 1.0
    return float(np.quantile(dists, 0.95)) or float(np.max(dists)) or 1.0


def error_colors(dists: Tensor, vmax: float | None = None) -> Tensor:
    """Map distances to RGBA colours (``uint8``) on a viridis-like scale from 0 to ``vmax``.

    Args:
        dists: ``(N,)`` finite non-negative distances.
        vmax: distance mapped to the brightest colour, finite and positive (default: :func:`default_vmax`, the 95th
            percentile of ``dists``, so a few outliers do not wash out the map); larger values are clamped.

    Returns:
        ``(N, 4)`` ``uint8`` RGBA colours.

    Raises:
        ShapeError: ``dists`` is not one-dimensional.
        NonFiniteError: a distance, or ``vmax``, is NaN or infinite.
        ValueError: a distance is negative, or ``vmax`` is not positive.
        TypeError: ``vmax`` is not a number.

    Example:
        >>> import torch
        >>> error_colors(torch.tensor([0.0, 1.0]), vmax=1.0).tolist()
        [[68, 1, 84, 255], [253, 231, 37, 255]]
    """
    if dists.ndim != 1:
        raise ShapeError(f"dists: expected shape (N,), found {tuple(dists.shape)}")
    check_distances(dists)
    d = dists.detach().double().cpu().numpy()
    scale = check_vmax(vmax)
    t = np.clip(d / (default_vmax(d) if scale is None else scale), 0.0, 1.0)
    pos = t * (len(ERROR_COLOR_ANCHORS) - 1)
    lo = np.minimum(np.floor(pos).astype(np.int64), len(ERROR_COLOR_ANCHORS) - 2)
    frac = (pos - lo)[:, None]
    rgb = ERROR_COLOR_ANCHORS[lo] * (1 - frac) + ERROR_COLOR_ANCHORS[lo + 1] * frac
    rgba = np.concatenate([np.rint(rgb), np.full((d.size, 1), 255.0)], axis=1).astype(np.uint8)
    return torch.from_numpy(rgba)


def per_vertex_errors(mesh: MeshLike, dists: Tensor) -> tuple[Mesh, Tensor]:
    """``mesh`` and ``dists`` with one distance per vertex, in order.

    Args:
        mesh: the mesh whose vertices carry the errors.
        dists: ``(V,)`` one distance per vertex of ``mesh``, or one per *referenced* vertex (the paper's vertex set,
            as in :class:`~torchmeshmetric.evaluation.PairEvaluation`): the unreferenced vertices are then dropped
            from the returned mesh.

    Returns:
        ``(mesh, dists)`` with ``dists`` of shape ``(V',)``, ``V'`` the returned mesh's vertex count.

    Raises:
        ShapeError: when ``dists`` has neither one value per vertex nor one per referenced vertex.

    Example:
        >>> import torch
        >>> m = Mesh(torch.eye(4, 3, dtype=torch.float64), torch.tensor([[0, 1, 2]]))  # vertex 3 unreferenced
        >>> kept, d = per_vertex_errors(m, torch.tensor([0.1, 0.2, 0.3], dtype=torch.float64))
        >>> kept.num_verts, d.tolist()
        (3, [0.1, 0.2, 0.3])
    """
    m = as_mesh(mesh)
    used = vertex_set_mask(m.faces, m.num_verts)
    if dists.ndim == 1 and dists.shape[0] == int(used.sum()) != m.num_verts:
        # distances of the vertex set (referenced vertices only, paper Eq. 3): drop the unreferenced vertices
        remap = torch.cumsum(used.long(), 0) - 1
        m = Mesh(m.verts[used], remap[m.faces], validate=False)
    if tuple(dists.shape) != (m.num_verts,):
        raise ShapeError(f"dists: expected shape ({m.num_verts},) (one per vertex of mesh), found {tuple(dists.shape)}")
    return m, dists


def write_error_ply(
    path: str | os.PathLike[str],
    mesh: MeshLike,
    dists: Tensor,
    *,
    vmax: float | None = None,
    overwrite: bool = False,
) -> Path:
    """Write ``mesh`` as a binary PLY with one colour per vertex showing its error, atomically.

    Args:
        path: destination ``.ply`` file.
        mesh: the mesh whose vertices carry the errors (e.g. the simplified frame ``k``).
        dists: ``(V,)`` one distance per vertex of ``mesh`` in order, or one per *referenced* vertex (the paper's
            vertex set, as in :class:`~torchmeshmetric.evaluation.PairEvaluation`): unreferenced vertices are then
            left out of the file.
        vmax: distance of the brightest colour (see :func:`error_colors`); use the same value for meshes that
            are compared side by side.
        overwrite: replace an existing file.

    Returns:
        The path written: a binary PLY with the vertices (float64), the faces and one RGBA colour per vertex.

    Raises:
        ShapeError: when ``dists`` does not have one value per vertex.
        NonFiniteError, ValueError, TypeError: a distance is NaN, infinite or negative, or ``vmax`` is not a finite
            positive number (:func:`error_colors`).
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.

    Example:
        >>> import os, tempfile, torch, trimesh
        >>> box = trimesh.creation.box()  # 8 vertices
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     path = write_error_ply(os.path.join(folder, "error.ply"), box, torch.linspace(0, 1, 8), vmax=1.0)
        ...     back = trimesh.load(path, process=False)
        >>> back.vertices.shape, back.visual.vertex_colors[[0, -1]].tolist()  # viridis: 0 dark, vmax bright
        ((8, 3), [[68, 1, 84, 255], [253, 231, 37, 255]])
    """
    overwrite = check_flag(overwrite, "overwrite")
    import trimesh  # ~0.3 s to import: on use only, `import torchmeshmetric` never loads it

    m, dists = per_vertex_errors(mesh, dists)
    tm = trimesh.Trimesh(
        m.verts.detach().cpu().double().numpy(),
        m.faces.cpu().numpy(),
        vertex_colors=error_colors(dists, vmax).numpy(),
        process=False,
    )
    buf = io.BytesIO()
    tm.export(buf, file_type="ply")
    return atomic_write(path, buf.getvalue(), overwrite=overwrite)
