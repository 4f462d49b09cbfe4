"""One dispatch for the selection kernels: a small contract and one plain table (no registration by import).

Every distance call splits its work in two: a **selection** without gradient (closest face, or nearest reference
point, per query) and a differentiable recomputation on the selected primitive. Only the selection differs between
backends. A backend is a :class:`~torchmeshmetric.kernels.contract.SelectionBackend` (a leaf module, so the
backends need not import this one): six functions that build, refit and query a structure over
*centred, packed, detached* primitives (:class:`FaceSet` / :class:`PointSet`), taken from one module of
``kernels/accel/`` (``bruteforce``, ``pruned``, ``bvh``, ``triton_backend``) that names them as the contract does.
A structure is whatever the backend keeps (``None`` for the scanning backends: they read the set at each query); a
:class:`Selector` builds it on the first query, keeps it and refits it, so a :class:`~torchmeshmetric.MeshIndex`
builds once and queries many times. A new backend is a module with the six functions and one line in the table.

Contract of every backend (the brute force is the reference in tests):

- ``query_faces`` returns, per query, the face (row of ``FaceSet.faces``) of least computed squared distance
  (the expression of :func:`~torchmeshmetric.kernels.triangle.region_candidates`), the lowest index among equal squares;
- ``query_points`` returns the reference row of least ``(dx*dx + dy*dy) + dz*dz``, the lowest index among ties;
- ``refit_*`` accepts moved coordinates of the same primitives (same faces, same counts) and returns a structure
  whose queries are exact for them;
- queries only see items of their own batch index; memory is ``O(points + primitives)`` except for the brute force,
  whose intermediates are bounded by ``max_memory`` (the only backends that use it: ``"bruteforce"``, ``"pruned"``).

:func:`resolve_backend` turns a ``backend=`` name into a table entry (``"auto"``: the rule of
``docs/acceleration.md``); :func:`check_backend` is the one check of a ``backend=`` name.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

import torch
from torch import Tensor

from torchmeshmetric import native
from torchmeshmetric.kernels.accel import bruteforce, bvh, pruned, triton_backend
from torchmeshmetric.kernels.contract import FaceSet, PointSet, SelectionBackend

__all__ = [
    "BACKENDS",
    "MIN_PAIRS",
    "REBUILD_AREA_GROWTH",
    "REBUILD_EVERY",
    "Selector",
    "auto_backend_name",
    "check_backend",
    "resolve_backend",
]

MIN_PAIRS = 1 << 20
"""Below this many point-primitive pairs ``backend="auto"`` keeps the brute force off the CPU (and on a CPU where
the C++ extension cannot be built); above, an accelerated backend (see docs/acceleration.md)."""

REBUILD_AREA_GROWTH = 1.2
"""A refitted structure whose area (the backend's ``faces_area`` / ``points_area``: the summed surface areas of its
node boxes over its roots') has grown by this factor since it was built is rebuilt instead. A refit keeps the tree of
the build: after large deformations its boxes overlap and every query visits more of them (the 20k-face demo mesh
twisted by 360 degrees: a query 11.1 ms of CPU refitted only, 8.7 ms on a new tree;
``tests/benchmarks/index_rebuild.py``). Answers are the same bits either way: every backend is exact, whatever its
tree."""

REBUILD_EVERY = 256
"""A refitted structure whose backend measures its area is also rebuilt after this many refits: training can move a
mesh away from the pose it was built on without growing that area (from a noisy start, the area of the refitted tree
stays that of its build while a new tree's drops by a sixth: queries 19.4 ms against 17.0). A rebuild costs about
one query (an SAH tree of 20k faces: 13 ms), under 0.5 % of the steps it serves."""


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
        getattr(module, "query_faces_closest", None),
        getattr(module, "faces_area", None),
        getattr(module, "points_area", None),
    )


BRUTEFORCE = _scanning("bruteforce", bruteforce)
PRUNED = _scanning("pruned", pruned)
BVH = _kept("bvh", bvh)
TRITON = _kept("triton", triton_backend)

BACKENDS: dict[str, SelectionBackend] = {b.name: b for b in (BRUTEFORCE, PRUNED, BVH, TRITON)}
"""Every selection backend by its ``backend=`` name."""


def auto_backend_name(device: torch.device, dtype: torch.dtype, num_pairs: int) -> str:
    """The backend ``"auto"`` picks for ``num_pairs`` query-primitive pairs on ``device`` (docs/acceleration.md).

    CPU: ``"bvh"`` (faster than the brute force at every size; the C++ extension is built first, once per machine,
    with a progress line); where it cannot be built, as on other devices. Other devices: brute force below
    :data:`MIN_PAIRS`; above, ``"triton"`` on CUDA when Triton imports (float32/float64), else ``"pruned"``. The
    choice never depends on whether a build happened to exist: it is fixed for the process.
    """
    if device.type == "cpu" and native.try_load("bvh") is not None:
        return "bvh"
    if num_pairs < MIN_PAIRS:
        return "bruteforce"
    if device.type == "cuda" and dtype in (torch.float32, torch.float64) and triton_backend.triton_available():
        return "triton"
    return "pruned"


def check_backend(name: str) -> str:
    """Return ``name`` if it is ``"auto"`` or a name of :data:`BACKENDS`; else raise ``TypeError`` / ``ValueError``.

    The metrics and losses call it at construction: a misspelt backend of a validation metric failed at the first
    validation step, after a training epoch (found by review).
    """
    if not isinstance(name, str):
        raise TypeError(f"backend: expected one of {['auto', *BACKENDS]}, found {type(name).__name__} {name!r}")
    if name != "auto" and name not in BACKENDS:
        raise ValueError(f"backend: expected one of {['auto', *BACKENDS]}, found {name!r}")
    return name


def resolve_backend(name: str, device: torch.device, dtype: torch.dtype, num_pairs: int) -> SelectionBackend:
    """The table entry for ``backend=name`` (``"auto"`` decided by :func:`auto_backend_name`).

    ``"bvh"`` off the CPU, or when the extension cannot be compiled (one ``RuntimeWarning``), is ``"pruned"``.

    Raises:
        ValueError: for an unknown name.
    """
    check_backend(name)
    if name == "auto":
        name = auto_backend_name(device, dtype, num_pairs)
    if name == "bvh" and (device.type != "cpu" or native.try_load("bvh") is None):
        return PRUNED
    return BACKENDS[name]


class Selector:
    """A primitive set (faces or reference points) with its backend's structure, built on the first query and kept.

    The one place where a structure is built, queried and refitted: :class:`~torchmeshmetric.MeshIndex` keeps one
    for its faces and one for its vertex set.

    Args:
        backend: a ``backend=`` name (``"auto"`` resolved on the first query, for its device, dtype and size).
        prims: the centred, packed, detached primitives.
        max_memory: bound in bytes of one intermediate (``"bruteforce"`` and ``"pruned"`` only).
        tree: the face hierarchy of ``"bvh"`` (``"sah"`` or ``"morton"``); unused for points.
    """

    def __init__(self, backend: str, prims: FaceSet | PointSet, max_memory: int, tree: str = "morton") -> None:
        self.backend_name, self.prims, self.max_memory, self.tree = backend, prims, max_memory, tree
        self.backend: SelectionBackend | None = None
        self.structure: Any = None
        self._built_area = 0.0  # the area of the structure when it was built (the backend's faces_/points_area)
        self._refits = 0  # refits since then

    def _backend(self, points: Tensor) -> SelectionBackend:
        """The resolved backend, its structure built on the first query."""
        if self.backend is None:
            prims = self.prims
            num_prims = prims.faces.shape[0] if isinstance(prims, FaceSet) else prims.points.shape[0]
            self.backend = resolve_backend(self.backend_name, points.device, points.dtype, points.shape[0] * num_prims)
            self._build(self.backend)
        return self.backend

    def _build(self, backend: SelectionBackend) -> None:
        """A new structure over the current primitives, and its area (where the backend measures one)."""
        prims = self.prims
        if isinstance(prims, FaceSet):
            self.structure = backend.build_faces(prims, self.tree)
        else:
            self.structure = backend.build_points(prims)
        area = self._area(backend)
        self._built_area, self._refits = (0.0 if area is None else area), 0

    def _area(self, backend: SelectionBackend) -> float | None:
        area = backend.faces_area if isinstance(self.prims, FaceSet) else backend.points_area
        return None if area is None else area(self.structure)

    def select(self, points: Tensor, point_batch: Tensor) -> Tensor:
        """``(P,)`` int64 row of the selected primitive of each centred point's item (the contract's choice)."""
        backend, prims = self._backend(points), self.prims
        with torch.no_grad():
            if isinstance(prims, FaceSet):
                return backend.query_faces(self.structure, prims, points.detach(), point_batch, self.max_memory)
            return backend.query_points(self.structure, prims, points.detach(), point_batch, self.max_memory)

    def select_closest(self, points: Tensor, point_batch: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor] | None:
        """Faces only: ``(face_idx, sq_dists, bary, closest)`` on the centred faces in one pass, without autograd.

        ``None`` when the backend has no fused query (the caller selects, then computes on the selected faces).
        """
        backend, prims = self._backend(points), self.prims
        if backend.query_faces_closest is None or not isinstance(prims, FaceSet):
            return None
        with torch.no_grad():
            return backend.query_faces_closest(self.structure, prims, points.detach(), point_batch)

    def refit(self, prims: FaceSet | PointSet) -> None:
        """Moved coordinates of the same primitives: the kept structure is refitted (exact for them).

        Where the backend measures its structures' area, a refitted structure that has worn (area grown by
        :data:`REBUILD_AREA_GROWTH` since its build, or :data:`REBUILD_EVERY` refits) is rebuilt: the queries regain
        a new tree's speed and answer the same bits (every backend is exact, whatever its tree).
        """
        self.prims = prims
        backend = self.backend
        if backend is None:
            return
        if isinstance(prims, FaceSet):
            self.structure = backend.refit_faces(self.structure, prims)
        else:
            self.structure = backend.refit_points(self.structure, prims)
        self._refits += 1
        area = self._area(backend)  # host work on a host structure: no device read
        if area is not None and (area > REBUILD_AREA_GROWTH * self._built_area or self._refits >= REBUILD_EVERY):
            self._build(backend)
