"""The index a distance set is measured on: one given by the caller, found in an ``IndexCache``, or none."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor

from torchmeshmetric._checks import DeviceError, ShapeError, check_index_dtype
from torchmeshmetric.kernels.index_cache import IndexCache
from torchmeshmetric.kernels.kept_index import KeptIndex
from torchmeshmetric.kernels.mesh_index import MeshIndex
from torchmeshmetric.structures import Mesh

__all__ = ["bound_to", "check_index", "check_index_cache", "index_of", "query_points"]


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


def check_index_cache(indexes: object, name: str = "indexes") -> None:
    """Refuse an ``indexes`` that is not an :class:`~torchmeshmetric.IndexCache` (or ``None``).

    A dict there failed at the first lookup with ``TypeError: dict.get() takes no keyword arguments`` (found by
    review); ``reference_index`` had its check (:func:`check_index`), ``indexes`` had none.

    Raises:
        TypeError: naming ``name`` and the type found.
    """
    if indexes is not None and not isinstance(indexes, IndexCache):
        raise TypeError(f"{name}: expected an IndexCache or None, found {type(indexes).__name__}")


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
    return index.with_verts_unchecked(verts.to(index.dtype))


def index_of(
    meshes: list[Mesh],
    given: MeshIndex | None,
    indexes: IndexCache | None,
    dtype: torch.dtype,
    backend: str,
    name: str,
    build: bool = False,
    kept: KeptIndex | None = None,
) -> MeshIndex | None:
    """The index of ``meshes`` for queries computed in ``dtype`` (:func:`~torchmeshmetric._checks.common_dtype`).

    ``given`` (a prebuilt index: refused when narrower than ``dtype``, used as it is otherwise), else the entry
    ``indexes`` holds for the meshes in ``dtype``, else, with ``build``, the index of the meshes (detached) in
    ``dtype`` that ``kept`` holds (refitted when only their vertices moved since its last call: the answers of a
    new index, bit for bit) or, without ``kept``, a one-off index, else ``None``. Every index a set is measured on
    is chosen here, so the dtype rule holds in both directions and for every source of index.

    Raises:
        DTypeError: ``given`` is narrower than ``dtype`` (see :func:`~torchmeshmetric._checks.check_index_dtype`).
    """
    if given is not None:
        check_index_dtype(given.dtype, dtype, name)
        return given
    if indexes is not None:
        return indexes.get([m.to(dtype=dtype) for m in meshes], backend=backend)
    if build and kept is not None:
        return kept.get([m.to(dtype=dtype) for m in meshes], backend)
    if build:
        detached = [m.detach().to(dtype=dtype) for m in meshes]
        return MeshIndex(detached if len(detached) > 1 else detached[0], backend=backend)
    return None


def query_points(index: MeshIndex, points: Tensor, name: str) -> Tensor:
    """``points`` ready for the index's trusted queries: on its device, in its dtype (never narrower than theirs).

    The index's dtype was chosen by :func:`index_of`. The points themselves are the callers' validated vertex sets
    or point sets: they are not checked again.
    """
    if points.device != index.device:
        raise DeviceError(f"{name}: expected an index on the points' device {points.device}, found {index.device}")
    return points.to(index.dtype)
