"""Plain QEM simplification (the paper's "original QEM") through the fast-simplification library.

fast-simplification (MIT) wraps Sven Forstmann's Fast Quadric Mesh Simplification, an implementation of the quadric
error metric edge collapse of Garland & Heckbert, "Surface Simplification Using Quadric Error Metrics",
SIGGRAPH 1997. We keep it as the baseline rather than rewriting it.
"""

from __future__ import annotations

import math
import warnings

import fast_simplification
import numpy as np
import torch

from torchmeshmetric._checks import EmptyInputError, check_finite
from torchmeshmetric.simplification._target import resolve_target
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

__all__ = ["simplify_qem"]


def simplify_qem(mesh: MeshLike, target: int | float, *, preserve_border: bool = False, agg: float = 7.0) -> Mesh:
    """Simplify a triangle mesh with QEM edge collapse (Garland & Heckbert 1997) via fast-simplification.

    Args:
        mesh: the mesh (any form accepted by :func:`~torchmeshmetric.as_mesh`).
        target: an ``int`` face count in ``[1, F]``, or a ``float`` ratio of faces to **keep** in ``(0, 1]``.
        preserve_border: forbid collapses of edges touching an open boundary.
        agg: fast-simplification's aggressiveness (its threshold growth exponent), a finite number > 0. Below the
            default it may stop short of the target (a warning says so): on a 1548-face frame asked for 774, 2.0
            stopped at 1222.

    Returns:
        The simplified mesh (same dtype and device as the input, detached). fast-simplification reaches the count
        to within about one face (each collapse removes two faces); it may stop above it on meshes with few
        collapsible edges. A target of every face returns ``mesh`` itself (as a :class:`Mesh`), nothing collapsed.
        Faces with a repeated corner in the input (a capture defect, ``[a, a, b]``) are never collapsed and pass
        through: the output keeps them, as it keeps every other defect of the input.

    Raises:
        TypeError, ValueError: bad ``target`` or ``agg``; a triangle soup (no vertex shared by two faces, as STL
            stores meshes), whose edges all look like borders to the collapse.
        EmptyInputError: the mesh has no faces, or the simplification left none (a target of 1 face).
        NonFiniteError: a vertex is NaN or infinite (possible only in a ``Mesh`` built with ``validate=False``).

    Warns:
        UserWarning: the simplification stopped above the target (more than one face above it).

    Example:
        >>> import trimesh
        >>> sphere = as_mesh(trimesh.creation.icosphere(subdivisions=3))
        >>> simplify_qem(sphere, 0.25).num_faces
        320
    """
    m = as_mesh(mesh)
    if m.num_faces == 0:
        raise EmptyInputError("mesh: expected at least one face, found 0")
    # A Mesh built with validate=False skipped this; fast-simplification turned NaN into NaN vertices silently.
    check_finite(m.verts, "mesh.verts")
    count = resolve_target(target, m.num_faces)
    if isinstance(agg, bool) or not isinstance(agg, (int, float)) or not (0 < agg < math.inf):
        raise ValueError(f"agg: expected a finite number > 0, found {agg!r}")  # NaN or -1 missed the target silently
    if count == m.num_faces:
        return m
    if m.num_faces > 1 and int(torch.unique(m.faces).numel()) == m.faces.numel():
        # Every edge of a soup is a border: fast-simplification removed whole triangles, half the surface of a
        # sphere at 50 % (found by review: STL frames, which load as soups, came out full of holes).
        raise ValueError(
            f"mesh: a triangle soup ({m.num_faces} faces, no vertex shared by two of them, as STL stores meshes) "
            "cannot be simplified by edge collapse; weld its coincident vertices first (trimesh: merge_vertices())"
        )
    verts = m.verts.detach().cpu().double().numpy()
    faces = m.faces.cpu().numpy().astype(np.int64)
    out_v, out_f = fast_simplification.simplify(
        verts, faces, target_count=count, agg=agg, preserve_border=preserve_border
    )
    if len(out_f) == 0:  # a closed mesh asked for 1 or 2 faces collapses whole: never return an empty "simplification"
        raise EmptyInputError(
            f"target: {target!r} ({count} of {m.num_faces} faces) left no face: every face collapsed; ask for more "
            "faces"
        )
    if len(out_f) > count + 1:  # as simplify_registered_qem says it (each collapse removes two faces)
        warnings.warn(
            f"simplify_qem: stopped at {len(out_f)} faces, above the target {count} (agg={agg!r}; the default 7.0 "
            "collapses further)",
            UserWarning,
            stacklevel=2,
        )
    return Mesh(
        torch.from_numpy(np.ascontiguousarray(out_v)).to(device=m.device, dtype=m.dtype),
        torch.from_numpy(np.ascontiguousarray(out_f).astype(np.int64)).to(m.device),
        validate=False,
    )
