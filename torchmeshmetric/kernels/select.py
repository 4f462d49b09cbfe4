"""One dispatch for the selection kernels: a small contract and one plain table (no registration by import).

Every distance call splits its work in two: a **selection** without gradient (closest face, or nearest reference
point, per query) and a differentiable recomputation on the selected primitive. Only the selection differs between
backends. A backend is a :class:`SelectionBackend`: six functions that build, refit and query a structure over
*centred, packed, detached* primitives (:class:`FaceSet` / :class:`PointSet`). A structure is whatever the backend
keeps (``None`` for the brute force: it scans the set each time), so a :class:`~torchmeshmetric.MeshIndex` builds it
once and queries it many times.

Contract of every backend (the brute force is the reference in tests):

- ``query_faces`` returns, per query, the face (row of ``FaceSet.faces``) of least computed squared distance
  (the expression of ``point_triangle._region_candidates``), the lowest index among equal squares;
- ``query_points`` returns the reference row of least ``(dx*dx + dy*dy) + dz*dz``, the lowest index among ties;
- ``refit_*`` accepts moved coordinates of the same primitives (same faces, same counts) and returns a structure
  whose queries are exact for them;
- queries only see items of their own batch index; memory is ``O(points + primitives)`` except for the brute force,
  whose intermediates are bounded by ``max_memory`` (the only backends that use it: ``"bruteforce"``, ``"pruned"``).

:func:`resolve_backend` turns a ``backend=`` name into a table entry (``"auto"``: the rule of
``docs/acceleration.md``).
"""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType
from typing import Any, NamedTuple

import torch
from torch import Tensor

from torchmeshmetric.kernels.accel import bruteforce, bvh, pruned, triton_backend
from torchmeshmetric.kernels.accel._extension import bvh_ready, load_bvh

__all__ = [
    "BACKENDS",
    "MIN_PAIRS",
    "FaceSet",
    "PointSet",
    "SelectionBackend",
    "auto_backend_name",
    "check_backend",
    "resolve_backend",
]

MIN_PAIRS = 1 << 20
"""Below this many point-primitive pairs ``backend="auto"`` keeps the brute force until the C++ extension is
compiled: tiny problems never pay its one-time compilation (see docs/acceleration.md)."""


class FaceSet(NamedTuple):
    """Faces a backend selects from: centred, packed, detached.

    Attributes:
        verts: ``(V, 3)`` vertices, each item centred on its bounding box.
        faces: ``(F, 3)`` int64 rows of ``verts`` (global indices).
        batch: ``(F,)`` int64 item of each face.
        offsets: ``(B + 1,)`` int64 first face of each item.
    """

    verts: Tensor
    faces: Tensor
    batch: Tensor
    offsets: Tensor


class PointSet(NamedTuple):
    """Reference points a backend selects from: centred, packed, detached.

    Attributes:
        points: ``(R, 3)`` reference points, each item centred on its bounding box.
        batch: ``(R,)`` int64 item of each point.
        offsets: ``(B + 1,)`` int64 first point of each item.
    """

    points: Tensor
    batch: Tensor
    offsets: Tensor


class SelectionBackend(NamedTuple):
    """What a selection backend receives and returns (see the module docstring for the contract).

    Attributes:
        name: the ``backend=`` value.
        build_faces: ``(faces, tree) -> structure``; ``tree``: ``"sah"`` (spend more on the build for faster
            queries) or ``"morton"`` (cheapest build); a backend may have one kind only.
        refit_faces: ``(structure, moved faces) -> structure``.
        query_faces: ``(structure, faces, points, point_batch, max_memory) -> (P,) int64 face rows``.
        build_points: ``(ref) -> structure``.
        refit_points: ``(structure, moved ref) -> structure``.
        query_points: ``(structure, ref, points, point_batch, max_memory) -> (P,) int64 reference rows``.
    """

    name: str
    build_faces: Callable[[FaceSet, str], Any]
    refit_faces: Callable[[Any, FaceSet], Any]
    query_faces: Callable[[Any, FaceSet, Tensor, Tensor, int], Tensor]
    build_points: Callable[[PointSet], Any]
    refit_points: Callable[[Any, PointSet], Any]
    query_points: Callable[[Any, PointSet, Tensor, Tensor, int], Tensor]


def _none(*_: Any) -> None:
    return None


def _scanning(name: str, module: ModuleType) -> SelectionBackend:
    """A backend that keeps no structure: every query scans the primitives (its ``query_*`` receive ``None``)."""
    return SelectionBackend(name, _none, _none, module.query_faces, _none, _none, module.query_points)


def _kept(name: str, module: ModuleType) -> SelectionBackend:
    """A backend whose module builds, refits and queries a kept structure."""
    return SelectionBackend(
        name,
        module.build_faces,
        module.refit_faces,
        module.query_faces,
        module.build_points,
        module.refit_points,
        module.query_points,
    )


BRUTEFORCE = _scanning("bruteforce", bruteforce)
PRUNED = _scanning("pruned", pruned)
BVH = _kept("bvh", bvh)
TRITON = _kept("triton", triton_backend)

BACKENDS: dict[str, SelectionBackend] = {b.name: b for b in (BRUTEFORCE, PRUNED, BVH, TRITON)}
"""Every selection backend by its ``backend=`` name."""


def auto_backend_name(device: torch.device, dtype: torch.dtype, num_pairs: int) -> str:
    """The backend ``"auto"`` picks for ``num_pairs`` query-primitive pairs on ``device`` (docs/acceleration.md).

    CPU: ``"bvh"`` once the C++ extension is compiled (faster than the brute force at every size), before that the
    brute force below :data:`MIN_PAIRS` and ``"bvh"`` above. Other devices: brute force below :data:`MIN_PAIRS`;
    above, ``"triton"`` on CUDA when Triton imports (float32/float64), else ``"pruned"``.
    """
    if device.type == "cpu" and bvh_ready():
        return "bvh"
    if num_pairs < MIN_PAIRS:
        return "bruteforce"
    if device.type == "cpu":
        return "bvh"
    if device.type == "cuda" and dtype in (torch.float32, torch.float64) and triton_backend.triton_available():
        return "triton"
    return "pruned"


def check_backend(name: str) -> None:
    """Raise ``ValueError`` unless ``name`` is ``"auto"`` or a name of :data:`BACKENDS`."""
    if name != "auto" and name not in BACKENDS:
        raise ValueError(f"backend: expected one of {['auto', *BACKENDS]}, found {name!r}")


def resolve_backend(name: str, device: torch.device, dtype: torch.dtype, num_pairs: int) -> SelectionBackend:
    """The table entry for ``backend=name`` (``"auto"`` decided by :func:`auto_backend_name`).

    ``"bvh"`` off the CPU, or when the extension cannot be compiled (one ``RuntimeWarning``), is ``"pruned"``.

    Raises:
        ValueError: for an unknown name.
    """
    check_backend(name)
    if name == "auto":
        name = auto_backend_name(device, dtype, num_pairs)
    if name == "bvh" and (device.type != "cpu" or load_bvh() is None):
        return PRUNED
    return BACKENDS[name]
