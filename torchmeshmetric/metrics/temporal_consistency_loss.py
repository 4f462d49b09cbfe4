r"""The ``flicker`` set as a differentiable loss: simplified frame ``k`` against simplified frame ``k-1``, moved.

A simplifier trained on one frame at a time has no reason to give consecutive frames the same surface; the flicker
set (:mod:`torchmeshmetric.evaluation.flicker`) measures how far the simplified frame ``k`` is from the simplified
frame ``k-1`` carried onto frame ``k`` by the registration of the *original* frames. This module makes it a loss:

.. math::

    L = \underbrace{\overline{d\big(V(S_k),\, W(S_{k-1})\big)^p} + \overline{d\big(W(V(S_{k-1})),\, S_k\big)^p}}_
        {\text{flicker, two-sided}}
        \;+\; \lambda_f\, \underbrace{\Big(\overline{d\big(V(S_k),\, O_k\big)^p}
        + \overline{d\big(V(O_k),\, S_k\big)^p}\Big)}_{\text{frame } k\text{, two-sided}}

with ``W`` the registration's deformation of original frame ``k-1`` onto original frame ``k`` (a fixed map: no
gradient reaches the registration), ``d`` the exact point-to-surface distance (paper Eq. 4), the bars pooled means
over the batch (``reduction="mean"``) and ``\lambda_f`` the ``frame_weight``. The gradient reaches the vertices of
**both** simplified frames: ``S_k`` as the query points and the measured-to surface, ``S_{k-1}`` through the warp
(``W`` is differentiable in the points it moves; its parameters are constants).

The registration is the expensive part (about a second per pair) and depends only on the original frames: the loss
registers each original pair once through a :class:`TemporalLossCache`, whose
:class:`~torchmeshmetric.registration.RegistrationCache` (the evaluation's cache, under the same key: they can share
one) finds it again by content; the cache also keeps the indexes of the original frames ``k``. Within a training
loop the simplified frames keep their faces while their vertices move: the cache keeps their indexes too and refits
them (bounds only, answers exact) instead of rebuilding.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Mapping
from typing import Any

import torch
from torch import Tensor, nn

from torchmeshmetric._checks import EmptyInputError, NonFiniteError, as_real, check_flag, check_int, common_dtype
from torchmeshmetric.kernels.danskin import mesh_surface_distances
from torchmeshmetric.kernels.index_cache import IndexCache
from torchmeshmetric.kernels.kept_index import KeptIndex
from torchmeshmetric.kernels.mesh_index import MeshIndex, _version
from torchmeshmetric.kernels.select import check_backend
from torchmeshmetric.metrics._loss import check_loss_args, reduce_directed
from torchmeshmetric.metrics.directed_distances import DirectedDistances
from torchmeshmetric.registration._common import registration_dtype
from torchmeshmetric.registration.cache import (
    CachedRegistration,
    RegistrationCache,
    compute_registration,
    default_registration_settings,
    registration_key,
)
from torchmeshmetric.registration.options import NonRigidOptions
from torchmeshmetric.registration.warp import RegistrationWarp, Warp, as_warp, check_warped
from torchmeshmetric.structures import Mesh, as_mesh, is_mesh_like, require_faces, vertex_set_mask

__all__ = ["TemporalConsistencyLoss", "TemporalLossCache", "temporal_consistency_loss"]


class _VertexRows:
    """The rows of :func:`~torchmeshmetric.vertex_set` per faces tensor, kept between calls.

    A training step's meshes keep their faces, and finding their referenced vertices again would read a mask back
    from the device (two syncs a mesh on CUDA).
    """

    def __init__(self, max_entries: int) -> None:
        self.max_entries = max_entries
        self._rows: OrderedDict[int, tuple[Tensor, int, int, Tensor | None]] = OrderedDict()

    def __call__(self, mesh: Mesh) -> Tensor:
        """``vertex_set(mesh)``: the same values in the same order, differentiable w.r.t. ``mesh.verts``."""
        key, version = id(mesh.faces), _version(mesh.faces)
        found = self._rows.get(key)
        if found is not None and found[0] is mesh.faces and version >= 0 and found[1:3] == (version, mesh.num_verts):
            self._rows.move_to_end(key)
            rows = found[3]
        else:
            used = vertex_set_mask(mesh.faces, mesh.num_verts)
            if not bool(used.any()):
                raise EmptyInputError("mesh: no vertex is referenced by a face")
            rows = None if bool(used.all()) else used.nonzero().squeeze(1)
            self._rows[key] = (mesh.faces, version, mesh.num_verts, rows)
            if len(self._rows) > self.max_entries:
                self._rows.popitem(last=False)
        return mesh.verts if rows is None else mesh.verts.index_select(0, rows)


class TemporalLossCache:
    """What :func:`temporal_consistency_loss` keeps between calls: registrations, their warps, meshes' indexes.

    * the registration of every original pair the loss registers (``registration=None``), in a
      :class:`~torchmeshmetric.registration.RegistrationCache` keyed by
      :func:`~torchmeshmetric.registration.registration_key` (the content of both frames and the registration
      settings, as the evaluation keys them): give the evaluation's cache as ``registrations`` and each finds the
      other's registrations of float64 frames (the loss registers in the frames' dtype, the evaluation in float64:
      float32 frames get one entry each);
    * the warp of each of those registrations on the device and in the dtype of the loss's frames, converted once
      (least recently used dropped beyond ``max_warps``);
    * the indexes of the original frames ``k`` (an :class:`~torchmeshmetric.IndexCache`);
    * the indexes of the simplified frames ``k`` and of the moved frames ``k-1`` of the last call, refitted when the
      next call brings the same faces (a training step moves vertices, not faces), rebuilt otherwise.

    Args:
        max_warps: warps kept (and registrations, when the cache is the loss's own).
        max_indexes: indexes of original frames kept.
        registrations: the registration cache to use (e.g. the evaluation's, or one on disk); ``None``: a memory
            cache of its own, bounded by ``max_warps``.

    Raises:
        ValueError: ``max_warps`` or ``max_indexes`` below 1 (a non-int is a TypeError).
        TypeError: ``registrations`` not a :class:`~torchmeshmetric.registration.RegistrationCache` or ``None``.

    Example:
        >>> cache = TemporalLossCache()
        >>> cache.num_warps, cache.registrations.max_entries
        (0, 64)
    """

    def __init__(
        self, max_warps: int = 64, max_indexes: int = 64, *, registrations: RegistrationCache | None = None
    ) -> None:
        max_warps = check_int(max_warps, "max_warps", 1)
        if registrations is not None and not isinstance(registrations, RegistrationCache):
            raise TypeError(
                f"registrations: expected a RegistrationCache or None, found {type(registrations).__name__}"
            )
        self.max_warps = max_warps
        self.registrations = registrations if registrations is not None else RegistrationCache(max_entries=max_warps)
        # The warps in use, by (registration key, dtype, device): converted from the cache's CPU entry once.
        self._warps: OrderedDict[tuple[str, torch.dtype, torch.device], Warp] = OrderedDict()
        self.indexes = IndexCache(max_entries=check_int(max_indexes, "max_indexes", low=1))
        self._simplified = KeptIndex()
        self._moved = KeptIndex()
        self._vertex_rows = _VertexRows(4 * max_warps)  # simplified k, moved k-1 and original k of each pair

    @property
    def num_warps(self) -> int:
        """Warps held, converted to the loss's devices and dtypes."""
        return len(self._warps)

    def warp(self, original_k: Mesh, original_k_minus_1: Mesh, options: NonRigidOptions, backend: str) -> Warp:
        """The warp of ``original_k_minus_1`` registered onto ``original_k`` (registered on the first request)."""
        source, target = original_k_minus_1.detach(), original_k.detach()
        # In the frames' dtype: a float32 training loop registers in float32 (float64 is slow on most GPUs).
        settings = default_registration_settings(options, registration_dtype(source, target))
        key = registration_key(source, target, settings)
        converted = (key, source.dtype, source.device)
        found = self._warps.get(converted)
        if found is not None:
            self._warps.move_to_end(converted)
            return found

        def compute() -> CachedRegistration:
            with torch.no_grad():
                return compute_registration(source, target, options=options, backend=backend)

        entry, _ = self.registrations.get_or_compute(source, target, settings, compute)
        # The entry is on the CPU; the warp goes where the frames are, in the dtype a registration of them has (that
        # of frame k-1). An entry without a deformation is extended by its registered vertices' piecewise-linear map.
        if isinstance(entry.warp, RegistrationWarp):
            warp: Warp = entry.warp.to(source.device, source.dtype)
        else:
            warp = as_warp(entry, target, source, name="registration")
        self._warps[converted] = warp
        if len(self._warps) > self.max_warps:
            self._warps.popitem(last=False)
        return warp

    def __getstate__(self) -> dict[str, object]:
        # A cache: pickled empty (a module holding one is deep-copied, pickled by checkpoints); a shared registration
        # cache comes back as an empty one with the same folder and bound.
        registrations = RegistrationCache(self.registrations.directory, max_entries=self.registrations.max_entries)
        return {"max_warps": self.max_warps, "registrations": registrations, "_warps": OrderedDict(),
                "indexes": self.indexes, "_simplified": KeptIndex(), "_moved": KeptIndex(),
                "_vertex_rows": _VertexRows(4 * self.max_warps)}  # fmt: skip


def _to_surface(points: list[Tensor], meshes: list[Mesh], index: MeshIndex) -> Tensor:
    """Packed distances from each item's points to its mesh, on ``index`` (the index of ``meshes``).

    Differentiable w.r.t. the points and the meshes' vertices, first order (:mod:`torchmeshmetric.kernels.danskin`).
    """
    p = torch.cat(points) if len(points) > 1 else points[0]
    if p.shape[0] == 0:
        return p.new_zeros(0)
    lengths = _device_lengths(tuple(q.shape[0] for q in points), p.device)
    return mesh_surface_distances(p.to(index.dtype), lengths, meshes, index, owner="temporal_consistency_loss")


_LENGTHS: OrderedDict[tuple[tuple[int, ...], torch.device], Tensor] = OrderedDict()


def _device_lengths(lengths: tuple[int, ...], device: torch.device) -> Tensor:
    """``torch.tensor(lengths, device=device)``, kept for the next steps (the same sizes recur at every step).

    Copying a Python list to a CUDA device synchronises with the host (a pageable host-to-device copy); the loss made
    2-4 of them per step. The kept tensors are never written to (the kernels only read lengths).
    """
    key = (lengths, device)
    found = _LENGTHS.get(key)
    if found is None:
        found = _LENGTHS[key] = torch.tensor(lengths, dtype=torch.long, device=device)
        if len(_LENGTHS) > 64:
            _LENGTHS.popitem(last=False)
    else:
        _LENGTHS.move_to_end(key)
    return found


def _directed(
    points: list[Tensor],
    meshes: list[Mesh],
    index: MeshIndex,
    reverse: tuple[list[Tensor], list[Mesh], MeshIndex] | None,
) -> DirectedDistances:
    """Forward (``points`` → ``meshes``) and, when given, reverse distances, packed as the losses reduce them."""
    forward = _to_surface(points, meshes, index)
    rev = None if reverse is None else _to_surface(*reverse)
    no_lengths = torch.zeros(0, dtype=torch.long, device=forward.device)  # the device of the other fields
    return DirectedDistances(forward, no_lengths, rev, None, forward.new_zeros(0))


def _mesh_items(x: Any, name: str) -> list[Mesh]:
    """A mesh-like is a batch of one; a list/tuple of mesh-likes a batch. Each item must be a mesh."""
    if is_mesh_like(x):
        items = [(name, as_mesh(x, name=name))]
    elif isinstance(x, (list, tuple)):
        if not x:
            raise ValueError(f"{name}: expected a mesh or a non-empty list of meshes, found an empty list")
        items = [(f"{name}[{i}]", as_mesh(m, name=f"{name}[{i}]")) for i, m in enumerate(x)]
    else:
        raise TypeError(
            f"{name}: expected a mesh (Mesh, (verts, faces) or trimesh.Trimesh) or a list of them, found "
            f"{type(x).__name__}"
        )
    # named here: the kernels would name their own argument ("mesh")
    return [require_faces(mesh, item_name) for item_name, mesh in items]


def _registration_items(registration: Any, count: int) -> list[Any]:
    if registration is None:
        return [None] * count
    # A list, or a plain tuple, is a batch; a NamedTuple (a RegistrationWarp, a NonRigidRegistration) is one item.
    if (isinstance(registration, list) or type(registration) is tuple) and not is_mesh_like(registration):
        if len(registration) != count:
            raise ValueError(f"registration: expected {count} (one per frame pair), found {len(registration)}")
        return list(registration)
    if count != 1:
        raise ValueError(f"registration: expected a list of {count} (one per frame pair), found a single one")
    return [registration]


def _moved(warp: Warp, simplified_k_minus_1: Mesh, like: Mesh, name: str) -> Mesh:
    """``simplified_k_minus_1`` moved onto frame ``k`` by ``warp`` (differentiable in its vertices)."""
    moved = check_warped(warp(simplified_k_minus_1.verts), simplified_k_minus_1.verts, name)
    return Mesh(moved.to(like.device, like.dtype), simplified_k_minus_1.faces.to(like.device), validate=False)


def _check_moved(moved: list[Mesh], names: list[str]) -> None:
    """Require every moved vertex finite: one device read for the whole batch (a sync on CUDA), not one per pair."""
    finite = [torch.isfinite(m.verts).all() for m in moved]
    if bool(torch.stack(finite).all()):
        return
    for m, ok, name in zip(moved, finite, names, strict=True):
        if not bool(ok):
            bad = int((~torch.isfinite(m.verts)).any(dim=1).sum())
            raise NonFiniteError(
                f"{name}: the warp moved {bad} vertices of simplified_k_minus_1 to non-finite positions (NaN/Inf)"
            )


def _options(given: Mapping[str, Any] | NonRigidOptions | None) -> NonRigidOptions:
    """The default registration's options, validated (a misspelled field fails here, before any work)."""
    return given if isinstance(given, NonRigidOptions) else NonRigidOptions.from_keywords(None, **dict(given or {}))


def _check_arguments(frame_weight: float, two_sided: bool, reduction: str, power: float) -> tuple[float, float]:
    """The loss's scalar arguments (function and module alike): a bad one would give a NaN or inf loss, or 0.

    Returns ``(frame_weight, power)`` as floats (numbers as :func:`~torchmeshmetric._checks.as_real` reads them).
    """
    power = check_loss_args(reduction, power)
    weight = as_real(frame_weight, "frame_weight")
    if weight is None or not 0 <= weight < math.inf:  # NaN fails both comparisons
        raise ValueError(f"frame_weight: expected a finite number >= 0, found {frame_weight!r}")
    check_flag(two_sided, "two_sided")
    return weight, power


def temporal_consistency_loss(
    simplified_k: Any,
    simplified_k_minus_1: Any,
    original_k: Any,
    original_k_minus_1: Any,
    registration: Any = None,
    *,
    frame_weight: float = 1.0,
    two_sided: bool = True,
    power: float = 1.0,
    reduction: str = "mean",
    registration_options: Mapping[str, Any] | NonRigidOptions | None = None,
    backend: str = "auto",
    cache: TemporalLossCache | None = None,
) -> Tensor:
    r"""Flicker loss plus, weighted, the frame-``k`` surface loss, of a batch of simplified frame pairs.

    See the module docstring for the formula. Per pair: the distances from the vertex set of ``simplified_k`` to the
    surface of ``simplified_k_minus_1`` moved onto frame ``k`` by the registration ``W`` of ``original_k_minus_1``
    onto ``original_k`` (and, two-sided, from the moved vertices to ``simplified_k``); plus ``frame_weight`` times
    the distances between ``simplified_k`` and ``original_k`` (two-sided: both directions), as
    :func:`~torchmeshmetric.metrics.mesh_surface_distance_loss` measures them. Differentiable w.r.t. the vertices
    of ``simplified_k`` and ``simplified_k_minus_1`` (through ``W``, whose parameters are constants); gradients are
    finite (zero) where a distance is exactly 0. First order only (Danskin's theorem,
    :mod:`torchmeshmetric.kernels.danskin`): a double backward is refused.

    Args:
        simplified_k: the simplified frame ``k``: a mesh-like (:class:`~torchmeshmetric.Mesh`, ``(verts, faces)``,
            ``trimesh.Trimesh``) or a list of them (a batch of pairs; sizes may differ).
        simplified_k_minus_1: the simplified frame ``k-1`` (in frame ``k-1``'s space), any connectivity; or a list.
        original_k: the original frame ``k``, or a list.
        original_k_minus_1: the original frame ``k-1``, or a list.
        registration: ``None`` (register ``original_k_minus_1`` onto ``original_k`` with
            :func:`~torchmeshmetric.registration.register_nonrigid`, once per pair when ``cache`` is given), or per
            pair (a list for a batch): a warp (any callable mapping ``(P, 3)`` frame ``k-1`` points to frame ``k``,
            e.g. a :class:`~torchmeshmetric.registration.RegistrationWarp`), a
            :class:`~torchmeshmetric.registration.NonRigidRegistration`, an object with a ``warp`` (the evaluation's
            ``CachedRegistration``) or only ``verts``, or the registered mesh (frame ``k-1``'s topology); the last
            two are extended by their piecewise-linear map (:class:`~torchmeshmetric.registration.SurfaceWarp`,
            whose gradient treats each point's local displacement as constant).
        frame_weight: weight (finite, >= 0) of the frame-``k`` term; 0 leaves it out (not computed).
        two_sided: also measure the reverse directions (moved ``k-1`` → ``k``; original ``k`` → simplified ``k``).
        power: exponent ``p`` of each distance (finite, > 0; 1: the Average of the statistics, 2: their MSE).
        reduction: ``"mean"`` (pooled mean over the batch per direction and term, then added), ``"sum"`` or
            ``"none"``: the packed per-point terms, in the order flicker forward, (flicker reverse), frame forward,
            (frame reverse), the frame terms already multiplied by ``frame_weight`` (absent when it is 0), so that
            ``none.sum() == sum``.
        registration_options: options of the default registration (fields of
            :class:`~torchmeshmetric.registration.NonRigidOptions`).
        backend: kernel backend (``"auto"``, ``"bvh"``, ...).
        cache: a :class:`TemporalLossCache`: registrations, original frames' indexes and refitted simplified
            indexes kept between calls (:class:`TemporalConsistencyLoss` keeps one). Without it every call
            registers every pair again.

    Returns:
        A 0-dim loss, or the per-point terms (``reduction="none"``), in the promoted dtype of the four frames (each
        frame's gradient in its own dtype: ``docs/concepts.md``, *Precision*).

    Raises:
        TypeError: an argument that is not a mesh or list of meshes, a registration of an unknown kind.
        ValueError: batches of different lengths, a bad ``frame_weight`` (negative, NaN or infinite), ``power``
            (not a finite positive number) or ``reduction``.
        EmptyInputError: a frame without faces (named: ``simplified_k``, ``original_k[1]``, ...).
        NonFiniteError: a warp that moves vertices to NaN or infinite positions.
        DoubleBackwardError: a double backward (``create_graph=True``): the loss is differentiable once.
        ShapeError: a registration whose vertices are not those of ``original_k_minus_1``, a warp that does not map
            ``(P, 3)`` to ``(P, 3)``.
        DTypeError: a warp whose output is not float32 or float64 (integers, booleans, complex, half precision):
            refused as the evaluation refuses it, not cast.
        EmptyInputError: ``reduction="mean"`` on a batch without any point.

    Example:
        >>> import torch, trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> coarse = trimesh.creation.icosphere(subdivisions=1)
        >>> v = torch.tensor(coarse.vertices, requires_grad=True)
        >>> f = torch.tensor(coarse.faces)
        >>> identity = lambda p: p  # the frames do not move
        >>> loss = temporal_consistency_loss((v, f), (v, f), sphere, sphere, identity, frame_weight=0.0)
        >>> loss.backward()
        >>> loss.item(), float(v.grad.abs().max())  # the same simplification twice: no flicker, zero gradient
        (0.0, 0.0)
    """
    two_sided = check_flag(two_sided, "two_sided")
    frame_weight, power = _check_arguments(frame_weight, two_sided, reduction, power)
    check_backend(backend)
    if cache is not None and not isinstance(cache, TemporalLossCache):
        raise TypeError(f"cache: expected a TemporalLossCache or None, found {type(cache).__name__}")
    s_k = _mesh_items(simplified_k, "simplified_k")
    s_km1 = _mesh_items(simplified_k_minus_1, "simplified_k_minus_1")
    o_k = _mesh_items(original_k, "original_k")
    o_km1 = _mesh_items(original_k_minus_1, "original_k_minus_1")
    for name, items in (("simplified_k_minus_1", s_km1), ("original_k", o_k), ("original_k_minus_1", o_km1)):
        if len(items) != len(s_k):
            raise ValueError(f"{name}: expected {len(s_k)} frame(s), one per simplified_k, found {len(items)}")
    given = _registration_items(registration, len(s_k))
    options = _options(registration_options)
    work = cache if cache is not None else TemporalLossCache(max_warps=max(1, len(s_k)))
    # The dtype rule (docs/concepts.md, Precision): every term in the promoted dtype of all the frames; the casts
    # are differentiable, so each frame's gradient comes back in its own dtype. The registrations stay in the
    # originals' dtype (their cache keys are the evaluation's); the warps promote the points they move.
    dtype = common_dtype(*(m.dtype for m in (*s_k, *s_km1, *o_k, *o_km1)))
    s_k = [m.to(dtype=dtype) for m in s_k]
    moved, names = [], []
    for i, (g, ok, okm1, skm1, sk) in enumerate(zip(given, o_k, o_km1, s_km1, s_k, strict=True)):
        name = "registration" if len(s_k) == 1 else f"registration[{i}]"
        warp = work.warp(ok, okm1, options, backend) if g is None else as_warp(g, ok, okm1, name=name)
        item = "" if len(s_k) == 1 else f"[{i}]"
        moved.append(_moved(warp, skm1.to(dtype=dtype), sk, f"{name}(simplified_k_minus_1{item}.verts)"))
        names.append(name)
    _check_moved(moved, names)
    # One index per role for the whole batch: the moved frames k-1 (measured to) and the simplified frames k
    # (measured to by both reverse directions), refitted across calls while their faces stay the same; the
    # original frames k found again by content. Every index holds detached vertices: the gradient to the vertices
    # comes from Danskin's backward (kernels.danskin), to the meshes given here.
    k_points = [work._vertex_rows(m) for m in s_k]
    simplified_index = work._simplified.get(s_k, backend) if two_sided else None
    moved_index = work._moved.get(moved, backend)
    flicker = _directed(
        k_points,
        moved,
        moved_index,
        ([work._vertex_rows(m) for m in moved], s_k, simplified_index) if simplified_index is not None else None,
    )
    total = reduce_directed(flicker, power, reduction)
    if frame_weight == 0:
        return total
    originals = [m.detach().to(dtype=dtype) for m in o_k]
    original_index = work.indexes.get(originals if len(originals) > 1 else originals[0], backend=backend)
    reverse = None
    if simplified_index is not None:  # two-sided: the original vertices are queried on the simplified index too
        reverse = ([work._vertex_rows(m) for m in originals], s_k, simplified_index)
    frame = _directed(k_points, originals, original_index, reverse)
    frame_term = reduce_directed(frame, power, reduction)
    if reduction == "none":
        return torch.cat([total, frame_weight * frame_term])
    return total + frame_weight * frame_term


class TemporalConsistencyLoss(nn.Module):
    """``nn.Module`` form of :func:`temporal_consistency_loss` (arguments checked at construction).

    Keeps a :class:`TemporalLossCache`: each original frame pair is registered once over the whole training (found
    again by content), the original frames' indexes are built once, and the simplified frames' indexes are refitted
    from step to step while their faces stay the same.

    Args:
        frame_weight: weight (>= 0) of the frame-``k`` surface term.
        two_sided: also measure the reverse directions.
        reduction: ``"mean"``, ``"sum"`` or ``"none"``.
        power: exponent of each distance.
        registration_options: options of the default registration.
        backend: kernel backend.
        registration_cache: where the default registrations are kept (e.g. the evaluation's
            :class:`~torchmeshmetric.registration.RegistrationCache`, to share them); ``None``: a memory cache of
            the loss's own (64 registrations, least recently used dropped).

    Example:
        >>> import torch, trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> coarse = trimesh.creation.icosphere(subdivisions=1)
        >>> v = torch.tensor(coarse.vertices, requires_grad=True)
        >>> f = torch.tensor(coarse.faces)
        >>> loss_fn = TemporalConsistencyLoss()
        >>> shift = torch.tensor([0.0, 0.0, 0.1], dtype=torch.float64)
        >>> loss = loss_fn((v + shift, f), (v, f), sphere, sphere, registration=lambda p: p)  # frame k jumped
        >>> round(loss.item(), 2) > 0.1, v.grad is None
        (True, True)
    """

    def __init__(
        self,
        frame_weight: float = 1.0,
        two_sided: bool = True,
        reduction: str = "mean",
        *,
        power: float = 1.0,
        registration_options: Mapping[str, Any] | NonRigidOptions | None = None,
        backend: str = "auto",
        registration_cache: RegistrationCache | None = None,
    ) -> None:
        two_sided = check_flag(two_sided, "two_sided")
        super().__init__()
        self.frame_weight, self.power = _check_arguments(frame_weight, two_sided, reduction, power)
        self.two_sided = two_sided
        self.reduction = reduction
        # Validated once here (a misspelled option fails at construction, not at the first step).
        self.registration_options = _options(registration_options)
        self.backend = check_backend(backend)
        self.cache = TemporalLossCache(registrations=registration_cache)

    def forward(
        self,
        simplified_k: Any,
        simplified_k_minus_1: Any,
        original_k: Any,
        original_k_minus_1: Any,
        registration: Any = None,
    ) -> Tensor:
        """The loss of the pair(s) (see :func:`temporal_consistency_loss`)."""
        return temporal_consistency_loss(
            simplified_k,
            simplified_k_minus_1,
            original_k,
            original_k_minus_1,
            registration,
            frame_weight=self.frame_weight,
            two_sided=self.two_sided,
            power=self.power,
            reduction=self.reduction,
            registration_options=self.registration_options,
            backend=self.backend,
            cache=self.cache,
        )

    def extra_repr(self) -> str:
        """The loss's arguments (shown in ``repr``)."""
        return (
            f"frame_weight={self.frame_weight!r}, two_sided={self.two_sided!r}, reduction={self.reduction!r}, "
            f"power={self.power!r}"
        )
