"""Log an error-coloured mesh from a training run: TensorBoard ``add_mesh``, W&B GLB, or a PLY/GLB artifact.

:func:`log_error_mesh` takes a mesh and its per-vertex errors (or a simplified mesh and its reference, whose
surface distances it measures) and logs it to whatever it is given:

* a TensorBoard ``SummaryWriter`` (``torch.utils.tensorboard``), or a logger whose ``experiment`` is one (Lightning's
  ``TensorBoardLogger``): ``add_mesh`` with ``vertices`` float32, ``colors`` uint8 and ``faces``; the colour scale
  (``vmax``, unit, what the error is) goes into ``config_dict["torchmeshmetric"]`` and the tag is kept as given, so
  the steps of one tag stay one series;
* a Weights & Biases run, or Lightning's ``WandbLogger``: ``wandb.Object3D`` of the mesh as GLB (W&B takes meshes
  as glTF), the scale in the caption;
* any other logger (Lightning's ``CSVLogger``, ``MLFlowLogger``, ...) or a folder: a ``.glb`` (or ``.ply``) file in
  its ``log_dir`` (``meshes/<tag>_step<step>.glb``, the tag as a portable file name, :func:`mesh_file_name`:
  ``val/mesh`` as ``val_mesh-3b93a422``, so that distinct tags never share a file), handed to the logger's
  ``experiment.log_artifact`` when it has one (MLflow).

Nothing is imported until it is used: tensorboard and wandb are never imported unless such a logger is given.
:class:`~torchmeshmetric.viz.error_mesh_callback.ErrorMeshCallback` does it at the end of every validation epoch.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._atomic import atomic_write
from torchmeshmetric._checks import check_int, common_dtype
from torchmeshmetric._format import json_safe
from torchmeshmetric.structures import MeshLike, as_mesh
from torchmeshmetric.viz.colors import check_vmax
from torchmeshmetric.viz.error_mesh import DISPLAY_FACES, ErrorMesh, error_mesh, glb_bytes, ply_bytes

__all__ = ["check_tag", "log_error_mesh", "mesh_file_name", "surface_errors"]


def surface_errors(simplified: MeshLike, reference: MeshLike, *, backend: str = "auto") -> Tensor:
    """``(V,)`` distance of every vertex of ``simplified`` to the surface of ``reference`` (paper Eq. 4, exact).

    In the promoted dtype of the two meshes (docs/concepts.md, the dtype rule): a float64 simplified mesh against a
    float32 reference was rounded to float32 first, so 1.000000001 was coloured as 1.0 (found by review).

    Args:
        simplified: the mesh whose vertices are coloured (any mesh-like).
        reference: the mesh measured to (any mesh-like).
        backend: kernel backend (``"auto"``, ``"bvh"``, ...).

    Returns:
        ``(V,)`` distances of ``simplified``'s vertices, in the promoted dtype, on ``reference``'s device.

    Example:
        >>> import torch, trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> far = (torch.tensor(sphere.vertices) * 2, torch.tensor(sphere.faces))
        >>> surface_errors(far, sphere).min().item() > 0.99
        True
    """
    from torchmeshmetric.kernels.point_triangle import point_mesh_distance

    s, r = as_mesh(simplified, name="simplified"), as_mesh(reference, name="reference")
    dtype = common_dtype(s.dtype, r.dtype)
    with torch.no_grad():
        return point_mesh_distance(s.verts.to(r.device, dtype), r.to(dtype=dtype), backend=backend).dists


def check_tag(tag: object) -> str:
    """A log's name: a non-empty string (``None`` or ``""`` gave a crash, or a file named ``_step000003.glb``).

    Example:
        >>> check_tag("val/error_mesh")
        'val/error_mesh'
    """
    if not isinstance(tag, str):
        raise TypeError(f"tag: expected a string (the log's name, e.g. 'val/error_mesh'), found {type(tag).__name__}")
    if not tag.strip():
        raise ValueError(f"tag: expected a non-blank name (e.g. 'val/error_mesh'), found {tag!r}")
    return tag


def mesh_file_name(tag: str, step: int, file_format: str) -> str:
    """The file of a tag's mesh at a step: ``<name>_step<step>.<format>``, ``name`` the tag as a portable file name.

    A tag of lower-case letters, digits and ``_.-`` (not starting with ``.``) is its own name. Any other tag is
    written with each run of other characters as ``_`` (at most 80 characters kept), followed by ``-`` and the first
    8 hex digits of the tag's SHA-256, so distinct tags never write one file: ``val/mesh`` and ``val_mesh`` both
    became ``val_mesh`` (the second overwriting the first), and percent-encoding, the first remedy, made names past
    the 255-byte limit of a 32-character CJK tag, unreadable names, and on case-insensitive file systems (macOS,
    Windows) one file for ``Val/Mesh`` and ``val/mesh`` (found by review, 2026-12-07).

    Example:
        >>> mesh_file_name("val/mesh", 3, "glb"), mesh_file_name("val_mesh", 3, "glb")
        ('val_mesh-3b93a422_step000003.glb', 'val_mesh_step000003.glb')
    """
    import hashlib
    import re

    slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", tag).lstrip(".")[:80] or "_"
    if slug != tag or tag != tag.lower():
        slug = f"{slug}-{hashlib.sha256(tag.encode()).hexdigest()[:8]}"
    return f"{slug}_step{step:06d}.{file_format}"


def _is_tensorboard(x: Any) -> bool:
    return callable(getattr(x, "add_mesh", None))


def _is_wandb(x: Any) -> bool:
    """A wandb run or a logger wrapping one, known by its type's name and module (wandb itself not imported)."""
    kind = type(x)
    return kind.__module__.split(".")[0] == "wandb" or kind.__name__ == "WandbLogger"


def log_error_mesh(
    logger: Any,
    tag: str,
    mesh: MeshLike | ErrorMesh,
    dists: Tensor | None = None,
    *,
    reference: MeshLike | None = None,
    step: int = 0,
    vmax: float | None = None,
    what: str = "surface distance to the reference",
    unit: str = "mesh units",
    file_format: Literal["glb", "ply"] = "glb",
    max_faces: int = DISPLAY_FACES,
) -> ErrorMesh:
    """Log ``mesh`` coloured by its per-vertex error to TensorBoard, W&B, or as a file (see the module docstring).

    Args:
        logger: a ``SummaryWriter``, a W&B run, a Lightning logger, or a folder (``str``/``PathLike``) for files.
        tag: the log's name (e.g. ``"val/error_mesh"``); its steps are one series (a file logger writes one file a
            step, :func:`mesh_file_name`), so give each series its own tag.
        mesh: the mesh (e.g. a model's simplified frame), or an :class:`ErrorMesh` already coloured.
        dists: ``(V,)`` one error per vertex (or per referenced vertex); with ``reference`` instead, the surface
            distance of every vertex to ``reference`` (:func:`surface_errors`).
        reference: the reference mesh whose surface distances colour ``mesh`` (when ``dists`` is not given).
        step: the training step (``global_step``), an int >= 0.
        vmax: the error of the brightest colour, finite and positive; fix it (e.g. the error of a first model) so
            that colours of successive steps compare (default: the 95th percentile of each mesh's errors).
        what: what the error measures (logged with the scale).
        unit: the unit of the errors.
        file_format: the file of a file/artifact logger and of W&B's object (W&B takes ``"glb"`` only).
        max_faces: larger meshes are decimated for the log (each kept vertex keeps its nearest vertex's error), >= 1.

    Returns:
        The :class:`ErrorMesh` logged.

    Raises:
        TypeError: neither ``dists`` nor ``reference`` (nor an ``ErrorMesh``) was given, or both were; ``tag`` is not
            a string, ``step`` or ``max_faces`` not an int, ``vmax`` not a number.
        ValueError: ``file_format`` is not ``"glb"`` or ``"ply"``; ``tag`` is blank; ``step`` is negative,
            ``max_faces`` below 1, ``vmax`` not positive or a distance negative.
        NonFiniteError: ``vmax`` or a distance is NaN or infinite.

    Example:
        >>> import tempfile, pathlib, trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> folder = tempfile.mkdtemp()
        >>> logged = log_error_mesh(folder, "val/mesh", sphere.copy().apply_scale(1.01), reference=sphere, step=3)
        >>> sorted(p.name for p in (pathlib.Path(folder) / "meshes").iterdir())
        ['val_mesh-3b93a422_step000003.glb']
    """
    if file_format not in ("glb", "ply"):
        raise ValueError(f"file_format: expected 'glb' or 'ply', found {file_format!r}")
    check_tag(tag)
    step = check_int(step, "step", low=0)
    check_vmax(vmax)  # before the distances are measured
    if isinstance(mesh, ErrorMesh):
        if dists is not None or reference is not None:
            raise TypeError("dists, reference: an ErrorMesh is already coloured; give neither")
        coloured = mesh
    else:
        if (dists is None) == (reference is None):
            raise TypeError("dists, reference: expected exactly one of them (the errors, or the mesh measuring them)")
        errors = surface_errors(mesh, reference) if reference is not None else dists
        coloured = error_mesh(tag, mesh, errors, what=what, vmax=vmax, unit=unit, max_faces=max_faces)
    # strict JSON (a file layer's unknown scale, vmax NaN, is written "nan" as the reports write it)
    scale = json_safe({"vmax": coloured.vmax, "unit": coloured.unit, "what": coloured.what, "colormap": "viridis-like"})
    writer = logger if _is_tensorboard(logger) else getattr(logger, "experiment", None)
    if not isinstance(logger, str | os.PathLike) and _is_tensorboard(writer):
        writer.add_mesh(  # type: ignore[union-attr]
            tag,
            vertices=torch.from_numpy(coloured.verts)[None],
            colors=torch.from_numpy(coloured.colors)[None],
            faces=torch.from_numpy(coloured.faces.astype(np.int32))[None],
            config_dict={"torchmeshmetric": scale},
            global_step=step,
        )
    elif _is_wandb(logger):
        import io

        import wandb  # on use only: a W&B logger was given

        run = getattr(logger, "experiment", logger)
        obj = wandb.Object3D(io.BytesIO(glb_bytes(coloured)), file_type="glb", caption=_caption(scale))
        run.log({tag: obj}, step=step)
    else:
        _log_file(logger, tag, coloured, step, file_format)
    return coloured


def _caption(scale: dict[str, Any]) -> str:
    vmax = scale["vmax"] if isinstance(scale["vmax"], str) else f"{scale['vmax']:.4g}"
    return f"{scale['what']}: colours 0 .. {vmax} {scale['unit']} ({scale['colormap']})"


def _log_file(logger: Any, tag: str, coloured: ErrorMesh, step: int, file_format: str) -> Path:
    """The mesh as ``<log_dir>/meshes/<tag>_step<step>.<format>``, handed to ``experiment.log_artifact`` if any."""
    if isinstance(logger, str | os.PathLike):
        folder = Path(logger)
    else:
        where = getattr(logger, "log_dir", None) or getattr(logger, "save_dir", None)
        if where is None:
            raise TypeError(
                f"logger: a {type(logger).__name__} is neither TensorBoard, W&B, nor has a log_dir/save_dir to "
                "write the mesh file in"
            )
        folder = Path(where)
    path = folder / "meshes" / mesh_file_name(tag, step, file_format)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = glb_bytes(coloured) if file_format == "glb" else ply_bytes(coloured)
    atomic_write(path, data, overwrite=True)
    experiment: Any = getattr(logger, "experiment", None)
    if callable(getattr(experiment, "log_artifact", None)) and getattr(logger, "run_id", None) is not None:
        experiment.log_artifact(logger.run_id, str(path), artifact_path="meshes")  # MLflow's client
    return path
