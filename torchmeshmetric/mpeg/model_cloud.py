"""The point set ``mm compare`` measures for a model file: a mesh's samples, or a point cloud's own points."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import torch

from torchmeshmetric._checks import EmptyInputError
from torchmeshmetric.mpeg.point_cloud import PointCloud
from torchmeshmetric.mpeg.textured_mesh import load_textured_mesh
from torchmeshmetric.mpeg.vertex_sampling import vertex_sample

__all__ = ["load_model_cloud"]


def _ply_faces(path: Path) -> int:
    """The face count a PLY header declares (0 without a face element)."""
    with open(path, "rb") as fh:
        for raw in fh:
            line = raw.decode("ascii", "replace").split()
            if line[:2] == ["element", "face"] and len(line) > 2:
                return int(line[2])
            if line[:1] == ["end_header"]:
                break
    return 0


def _ply_points(path: Path) -> PointCloud:
    """A PLY point cloud (``mm sample``'s output): float32 positions and 8-bit colours when present."""
    import trimesh

    cloud = trimesh.load(path, process=False)
    pts = np.asarray(getattr(cloud, "vertices", np.zeros((0, 3))), dtype=np.float32).reshape(-1, 3)
    colors = getattr(cloud, "colors", None)
    rgb = None
    if colors is not None and len(colors) == pts.shape[0] and pts.shape[0] > 0:
        rgb = torch.from_numpy(np.asarray(colors)[:, :3].astype(np.float32))
    return PointCloud(torch.from_numpy(pts), colors=rgb)


def load_model_cloud(
    path: str | os.PathLike, texture: str | os.PathLike | None = None, name: str = "model"
) -> PointCloud:
    r"""The point set mmetric compares for a model, as its ``sampleIfNeeded`` makes it.

    A mesh (faces present) is reordered and sampled at its vertices and subdivided faces, in mmetric's order
    (:func:`~torchmeshmetric.mpeg.vertex_sample`), with the colours of its texture or vertices; a file
    without faces (``mm sample``'s PLY output) passes through with its vertex colours.

    Args:
        path: OBJ, PLY or OFF file.
        texture: texture image overriding the OBJ's MTL (mmetric's ``--inputMap``).
        name: how error messages name the model.

    Returns:
        :class:`PointCloud` (colours when the model has any).

    Raises:
        MeshFileError: an unreadable file.
        EmptyInputError: a model without points.

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (d / "t.obj").write_text("v 0 0 0\nv 4 0 0\nv 0 4 0\nf 1 2 3\n")
        >>> load_model_cloud(d / "t.obj").num_points  # area 8 >= 2: corners and two levels of midpoints
        15
    """
    p = Path(path)
    if p.suffix.lower() == ".ply" and _ply_faces(p) == 0:
        cloud = _ply_points(p)
    else:
        model = load_textured_mesh(p, texture)
        if model.mesh.faces.shape[0] > 0:
            t = model
            return vertex_sample(t.mesh, texture=t.texture, uvs=t.uvs, colors=t.colors, name=name)
        cloud = PointCloud(model.mesh.verts.to(torch.float32), colors=model.colors)
    if cloud.num_points == 0:
        raise EmptyInputError(f"{name}: expected points, found none in '{p}'")
    return cloud
