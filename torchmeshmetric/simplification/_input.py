"""The simplifiers' one input step: float64 vertices and int64 faces, coincident vertices welded."""

from __future__ import annotations

import numpy as np

from torchmeshmetric.registration._common import welded_faces
from torchmeshmetric.structures import Mesh

__all__ = ["mesh_arrays"]


def mesh_arrays(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """float64 ``(V, 3)`` vertices (a copy) and int64 ``(F, 3)`` faces, coincident vertices welded.

    Every corner is re-pointed to the first vertex at exactly the same position (the registration's
    :func:`~torchmeshmetric.registration._common.welded_faces`), then the faces that repeat a vertex are dropped.
    Captured frames store seams as duplicate vertices (:func:`~torchmeshmetric.data.add_capture_defects` models
    them): unwelded, a seam is two open borders, whose vertices the collapse keeps fixed, and with 2 % of the vertices
    duplicated Registered and Anchored QEM stopped at 1002 and 990 faces of a 636-face target (found by review).
    Welded, the seam is interior surface again; a mesh without coincident vertices keeps its faces. Every simplifier
    (QEM too) starts here, so that methods compared at one face count simplified the same surface (trimesh's loader
    welds by default as well, so a user who feeds fast-simplification a loaded mesh gets a welded one).
    """
    verts = mesh.verts.detach().cpu().double()
    faces = welded_faces(verts, mesh.faces.cpu()).numpy().astype(np.int64)
    return verts.numpy().copy(), faces[
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
    ]
