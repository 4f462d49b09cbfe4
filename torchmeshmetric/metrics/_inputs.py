"""Normalise the ``(simplified, reference)`` arguments of the metrics and losses into per-item lists."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, check_int
from torchmeshmetric.kernels.sampling import vertex_set
from torchmeshmetric.structures import Mesh, as_mesh, as_points, is_mesh_like

__all__ = ["PointSource", "as_point_sources", "as_reference_meshes", "cast_sources", "check_surface_samples"]


class PointSource(NamedTuple):
    """One item: the query points and, when the item was given as a mesh, that mesh."""

    points: Tensor
    mesh: Mesh | None


def _as_items(x: Any) -> list[Any]:
    """A single item (tensor, array, mesh-like) becomes a batch of one; a list/tuple of items stays a batch."""
    if isinstance(x, (Tensor, np.ndarray)):
        if x.ndim == 3:
            return list(x)
        return [x]
    if is_mesh_like(x):
        return [x]
    if isinstance(x, (list, tuple)):
        return list(x)
    return [x]


def as_point_sources(x: Any, name: str = "simplified") -> list[PointSource]:
    """Items of ``x``: a ``(P, 3)`` point set, a mesh-like (its vertex set, paper Eq. 3), ``(B, P, 3)``, or a list.

    Mesh items contribute the vertices referenced by at least one face (:func:`~torchmeshmetric.vertex_set`).
    """
    items = _as_items(x)
    if not items:
        raise ValueError(f"{name}: expected at least one point set or mesh, found an empty list")
    out = []
    for i, it in enumerate(items):
        nm = name if len(items) == 1 else f"{name}[{i}]"
        if is_mesh_like(it):
            m = as_mesh(it, name=nm)
            out.append(PointSource(vertex_set(m, name=nm), m))
        else:
            out.append(PointSource(as_points(it, nm), None))
    return out


def cast_sources(sources: Sequence[PointSource], dtype: torch.dtype) -> list[PointSource]:
    """The items in ``dtype`` (the set's :func:`~torchmeshmetric._checks.common_dtype`), cast once at the door.

    A mesh item is cast as a whole and its points taken again from the cast mesh, so that its vertices reach the
    computation through one cast: autograd sums their gradient from every use (query points, measured-to surface)
    in ``dtype`` and rounds it once to the vertices' own dtype. Items already in ``dtype`` are returned as they are.
    """
    out = []
    for s in sources:
        if s.points.dtype == dtype:
            out.append(s)
        elif s.mesh is None:
            out.append(PointSource(s.points.to(dtype), None))
        else:
            mesh = s.mesh.to(dtype=dtype)
            out.append(PointSource(vertex_set(mesh), mesh))
    return out


def as_reference_meshes(x: Any, num_items: int, name: str = "reference") -> list[Mesh]:
    """Reference meshes, one per item (a single mesh-like is used for a batch of one only)."""
    items = [x] if is_mesh_like(x) else list(x) if isinstance(x, (list, tuple)) else [x]
    names = [name if len(items) == 1 else f"{name}[{i}]" for i in range(len(items))]
    meshes = [as_mesh(m, name=nm) for m, nm in zip(items, names, strict=True)]
    _check_count(len(meshes), num_items, name)
    for m, nm in zip(meshes, names, strict=True):
        if m.faces.shape[0] == 0:  # the kernel's message named "faces: mesh 0", neither the argument nor the item
            raise EmptyInputError(f"{nm}: expected a surface to measure to, found {m.num_verts} vertices and no face")
    return meshes


def _check_count(found: int, expected: int, name: str) -> None:
    if found != expected:
        raise ValueError(f"{name}: expected {expected} reference(s), one per simplified item, found {found}")


def require_meshes(sources: Sequence[PointSource], name: str, why: str) -> list[Mesh]:
    """The meshes of every item, or a ``TypeError`` explaining why a mesh is needed."""
    meshes = []
    for i, s in enumerate(sources):
        if s.mesh is None:
            raise TypeError(f"{name}[{i}]: expected a mesh ({why}), found a point set")
        meshes.append(s.mesh)
    return meshes


def check_surface_samples(surface_samples: object) -> None:
    """Validate the ``surface_samples`` argument: ``None`` (exact surface) or a positive int."""
    if surface_samples is not None:
        check_int(surface_samples, "surface_samples", 1)  # True was 1 sample; np.int64(100) was refused
