"""The index a distance set is measured on: one given by the caller, found in an ``IndexCache``, or none."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor

from torchmeshmetric._checks import DeviceError, DTypeError, ShapeError
from torchmeshmetric.kernels.index_cache import IndexCache
from torchmeshmetric.kernels.mesh_index import MeshIndex
from torchmeshmetric.structures import Mesh

__all__ = ["bound_to", "check_index", "index_of", "query_points"]


def check_index(index: MeshIndex | None, items: Sequence[Mesh | None], name: str) -> None:
    """Refuse an index that cannot be the index of the meshes ``items`` (``None``: a point-set item).

    Checks the item and vertex counts, the device and the vertex set; the content is not compared (that would cost
    what the index saves): the caller vouches for it.
    """
    if index is None:
        return
    if not isinstance(index, MeshIndex):
        raise TypeError(f"{name}: expected a MeshIndex or None, found {type(index).__name__}")
    meshes = [m for m in items if m is not None]
    if len(meshes) != len(items):
        raise TypeError(f"{name}: expected mesh items to go with it (an index is built from meshes), found point sets")
    found = index.verts_lengths.tolist()
    expected = [m.num_verts for m in meshes]
    if found != expected:
        raise ShapeError(f"{name}: expected the index of meshes with {expected} vertices, found one of {found}")
    if index.device != meshes[0].device:
        raise DeviceError(f"{name}: expected an index on {meshes[0].device}, found one on {index.device}")
    if not index.referenced_only:
        # Its nearest-vertex reference would hold unreferenced vertices, which the vertex set (Eq. 3) excludes.
        raise ValueError(f"{name}: expected an index built with referenced_only=True, found referenced_only=False")


def bound_to(index: MeshIndex | None, meshes: Sequence[Mesh]) -> MeshIndex | None:
    """The index measuring with the vertices of ``meshes`` (structures shared), so gradients reach those vertices.

    As without an index: the gradient flows to the vertices of the meshes given (unless they are detached), not
    to the tensors the index happened to be built from.
    """
    if index is None:
        return None
    verts = meshes[0].verts if len(meshes) == 1 else torch.cat([m.verts for m in meshes])
    if verts is index.verts or not (verts.requires_grad or index.verts.requires_grad):
        return index  # equal values and no autograd graph to connect: nothing to rebind
    return index.with_verts(verts.to(index.dtype))


def index_of(
    meshes: list[Mesh], given: MeshIndex | None, indexes: IndexCache | None, dtype: torch.dtype, backend: str
) -> MeshIndex | None:
    """``given``, else the cached index of ``meshes`` (one entry per batch; dtype: ``dtype`` promoted with theirs)."""
    if given is not None or indexes is None:
        return given
    for m in meshes:
        dtype = torch.promote_types(dtype, m.dtype)
    return indexes.get([m.to(dtype=dtype) for m in meshes], backend=backend)


def query_points(index: MeshIndex, points: Tensor, name: str) -> Tensor:
    """``points`` ready for the index's trusted queries: on its device, in its dtype (never rounded to a narrower one).

    The points themselves are the callers' validated vertex sets or point sets: they are not checked again.
    """
    if points.device != index.device:
        raise DeviceError(f"{name}: expected an index on the points' device {points.device}, found {index.device}")
    if torch.promote_types(points.dtype, index.dtype) != index.dtype:
        raise DTypeError(f"{name}: expected an index of dtype {points.dtype} (that of the points), found {index.dtype}")
    return points.to(index.dtype)
