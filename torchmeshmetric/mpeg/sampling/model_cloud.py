"""The point set ``mm compare`` measures for a model file: a mesh's samples, or a point cloud's own points."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import torch

from torchmeshmetric._checks import EmptyInputError
from torchmeshmetric.data.mesh_file import check_dtype_range, existing_mesh_file
from torchmeshmetric.data.ply import read_ply_point_arrays
from torchmeshmetric.mpeg.core.point_cloud import PointCloud
from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh
from torchmeshmetric.mpeg.sampling.vertex_sampling import vertex_sample

__all__ = ["load_model_cloud"]


def load_model_cloud(
    path: str | os.PathLike, texture: str | os.PathLike | None = None, name: str = "model"
) -> PointCloud:
    r"""The point set mmetric compares for a model, as its ``sampleIfNeeded`` makes it.

    A mesh (faces present) is reordered and sampled at its vertices and subdivided faces, in mmetric's order
    (:func:`~torchmeshmetric.mpeg.vertex_sample`), with the colours of its texture or vertices; a file
    without faces (``mm sample``'s PLY output) passes through with its normals (``nx ny nz``, which mmetric's D2
    uses), vertex colours and UVs (``texture_u texture_v``, which only an OBJ of the cloud shows).

    Args:
        path: OBJ, PLY or OFF file.
        texture: texture image overriding the OBJ's MTL (mmetric's ``--inputMap``).
        name: how error messages name the model.

    Returns:
        :class:`PointCloud` (normals and colours when the model has any).

    Raises:
        MeshFileError: an unreadable file (a point-cloud PLY through the one PLY reader: header, count and
            coordinates checked, the message naming the file and line or vertex).
        EmptyInputError: a model without points.

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (d / "t.obj").write_text("v 0 0 0\nv 4 0 0\nv 0 4 0\nf 1 2 3\n")
        >>> load_model_cloud(d / "t.obj").num_points  # area 8 >= 2: corners and two levels of midpoints
        15
    """
    p = Path(path)
    points = read_ply_point_arrays(existing_mesh_file(p)) if p.suffix.lower() == ".ply" else None
    if points is not None:  # a point cloud: checked by the one PLY reader, used as it is
        check_dtype_range(p, points.verts, torch.float32, None, "mmetric reads coordinates as float32")
        rgb = None if points.colors is None else torch.from_numpy(points.colors.astype(np.float32))
        normals = None if points.normals is None else torch.from_numpy(points.normals.astype(np.float32))
        uvs = None if points.uvs is None else torch.from_numpy(points.uvs.astype(np.float32))
        cloud = PointCloud(torch.from_numpy(points.verts.astype(np.float32)), normals=normals, colors=rgb, uvs=uvs)
    else:
        model = load_textured_mesh(p, texture)
        if model.mesh.faces.shape[0] > 0:
            t = model
            return vertex_sample(t.mesh, texture=t.texture, uvs=t.uvs, colors=t.colors, name=name)
        cloud = PointCloud(model.mesh.verts.to(torch.float32), colors=model.colors)
    if cloud.num_points == 0:
        raise EmptyInputError(f"{name}: expected points, found none in '{p}'")
    return cloud
