"""The evaluation system of the paper (Fig. 2): registration, the four distance sets, their statistics.

For the simplified mesh of frame ``k``: register original frame ``k-1`` onto original frame ``k`` (rigid, then
non-rigid: :func:`torchmeshmetric.registration.register_nonrigid`), then measure from the simplified vertices
the mesh surface distance (Eq. 4, exact closest point on the surface) and the nearest vertex distance (Eq. 5) to
both references, and summarise each set with :func:`torchmeshmetric.stats.distance_statistics`. Given the
simplified frame ``k-1`` too (always in :func:`evaluate_sequence`), the ``flicker`` set compares it, moved onto
frame ``k`` by the registration's deformation, with the simplified frame ``k``
(:mod:`torchmeshmetric.evaluation.flicker`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import torch
from torch import Tensor

from torchmeshmetric._checks import ShapeError
from torchmeshmetric.evaluation.cache import CachedRegistration, RegistrationCache
from torchmeshmetric.evaluation.flicker import FLICKER, flicker_distances
from torchmeshmetric.evaluation.results import SET_NAMES, PairEvaluation, SequenceEvaluation
from torchmeshmetric.kernels import IndexCache, MeshIndex, point_mesh_distance
from torchmeshmetric.registration.warp import RegistrationWarp, SurfaceWarp, Warp
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh

__all__ = ["RegisterFn", "default_register", "evaluate_pair", "evaluate_sequence", "registration_settings"]

#: A registration function ``register(source_k_minus_1, target_k)`` returning the registered frame ``k-1``: a
#: :class:`CachedRegistration`, a result object with ``verts`` (and optionally ``residual``, ``converged``), or a
#: mesh-like with the vertices of the source.
RegisterFn = Callable[[Mesh, Mesh], Any]


def default_register(
    source: Mesh, target: Mesh, *, device: torch.device | str | None = None, **options: Any
) -> CachedRegistration:
    """Register ``source`` (frame ``k-1``) onto ``target`` (frame ``k``) with the library's non-rigid registration.

    Calls :func:`torchmeshmetric.registration.register_nonrigid` (rigid initialisation, then the deformation
    graph) and keeps its registered vertices, residual, convergence flag and deformation
    (:class:`~torchmeshmetric.registration.RegistrationWarp`, which moves any point: the ``flicker`` set needs it).
    """
    from torchmeshmetric.registration import register_nonrigid

    start = time.perf_counter()
    result = register_nonrigid(source, target, device=device, **options)
    seconds = time.perf_counter() - start
    warp = RegistrationWarp.from_registration(result, target)
    return CachedRegistration(result.verts.detach(), result.residual.detach(), bool(result.converged), seconds, warp)


def registration_settings(register: RegisterFn | None, options: Mapping[str, Any] | None) -> dict[str, Any]:
    """The settings that identify a registration in the cache: the function's qualified name and its options."""
    fn: Any = default_register if register is None else register
    name = f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', type(fn).__name__)}"
    return {"register": name, "options": dict(options or {})}


def _registration_from(registration: Any, original_k_minus_1: Mesh, original_k: Mesh) -> CachedRegistration:
    """Normalise a caller-given registration (mesh-like or result object with ``verts``) to a CachedRegistration."""
    if isinstance(registration, CachedRegistration):
        reg = registration
    else:
        verts = getattr(registration, "verts", None)
        if verts is None:
            verts = as_mesh(registration).verts
        verts = torch.as_tensor(verts)
        residual = getattr(registration, "residual", None)
        if residual is None:
            with torch.no_grad():
                residual = point_mesh_distance(verts.to(original_k.verts), original_k).dists
        warp = getattr(registration, "warp", None)
        if warp is None and getattr(registration, "graph", None) is not None and hasattr(registration, "rigid"):
            warp = RegistrationWarp.from_registration(registration, original_k)  # a NonRigidRegistration
        converged = bool(getattr(registration, "converged", True))
        reg = CachedRegistration(verts, torch.as_tensor(residual), converged, 0.0, warp)
    if tuple(reg.verts.shape) != tuple(original_k_minus_1.verts.shape):
        raise ShapeError(
            f"registration: expected registered vertices of shape {tuple(original_k_minus_1.verts.shape)} "
            f"(the vertices of original_k_minus_1), found {tuple(reg.verts.shape)}"
        )
    return reg


def evaluate_pair(
    simplified_k: MeshLike,
    original_k: MeshLike,
    original_k_minus_1: MeshLike,
    *,
    registration: Any = None,
    two_sided: bool = True,
    device: torch.device | str | None = None,
    register: RegisterFn | None = None,
    register_options: Mapping[str, Any] | None = None,
    cache: RegistrationCache | None = None,
    frame: int = 1,
    backend: str = "auto",
    indexes: IndexCache | None = None,
    simplified_k_minus_1: MeshLike | None = None,
    true_registration: Tensor | None = None,
) -> PairEvaluation:
    """Evaluate the simplified mesh of frame ``k`` against original frames ``k`` and ``k-1`` (paper Fig. 2).

    Args:
        simplified_k: the simplified mesh of frame ``k`` (any mesh-like).
        original_k: the original mesh of frame ``k``.
        original_k_minus_1: the original mesh of frame ``k-1``.
        registration: frame ``k-1`` already registered onto frame ``k``: a mesh-like with the vertices (and
            topology) of ``original_k_minus_1``, a :class:`~torchmeshmetric.registration.NonRigidRegistration`,
            or a :class:`CachedRegistration`. ``None`` (default) registers with ``register``.
        two_sided: also compute the reverse (reference → simplified) sets (default ``True``).
        device: where distances are computed (default: the device of ``simplified_k``).
        register: registration function ``(source, target) -> registered source`` (see :data:`RegisterFn`); default
            :func:`default_register` (with ``register_options`` and ``device``).
        register_options: keyword options of the default registration (part of the cache key).
        cache: a :class:`RegistrationCache`; reused registrations cost nothing.
        frame: the index ``k`` recorded in the result.
        backend: kernel backend of the distances and of the default registration (``"auto"``, ``"bvh"``, ...).
        indexes: an :class:`~torchmeshmetric.IndexCache` shared across calls: the original frames' indexes are
            built once for every method and both frame pairs that use them.
        simplified_k_minus_1: the simplified frame ``k-1``; when given, the ``flicker`` set is measured: the
            simplified frame ``k`` against it, moved onto frame ``k`` by the registration's deformation (its
            ``warp`` when it has one, e.g. the default registration or a ``NonRigidRegistration``; otherwise the
            piecewise-linear map of the registered vertices, :class:`~torchmeshmetric.registration.SurfaceWarp`).
        true_registration: ``(V_{k-1}, 3)`` true positions in frame ``k`` of the vertices of ``original_k_minus_1``
            (known motion, e.g. :meth:`~torchmeshmetric.data.DemoSequence.transfer`): the registration's error is
            then reported beside its residual.

    Returns:
        :class:`PairEvaluation` with the four distance sets (keys ``surface_k``, ``surface_k_minus_1``,
        ``vertex_k``, ``vertex_k_minus_1``; and ``flicker`` when ``simplified_k_minus_1`` is given), their statistics
        (PSNR peak: bounding-box diagonal of ``original_k``), the reverse sets, the registration residual and timings.

    Raises:
        ShapeError: when ``registration`` does not have the vertices of ``original_k_minus_1``.

    Example:
        >>> import trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> coarse = trimesh.creation.icosphere(subdivisions=1)
        >>> r = evaluate_pair(coarse, sphere, sphere, registration=sphere)
        >>> float(r.statistics["vertex_k"].max) < 1e-12, float(r.statistics["surface_k"].max) < 1e-12
        (True, True)
        >>> round(float(r.reverse_statistics["surface_k"].max), 3)  # fine vertices off the coarse surface
        0.049
    """
    from torchmeshmetric.stats import distance_statistics

    simp = as_mesh(simplified_k)
    dev = torch.device(device) if device is not None else simp.device
    simp = simp.to(dev)
    orig_k = as_mesh(original_k).to(dev, simp.dtype)
    orig_km1 = as_mesh(original_k_minus_1).to(dev, simp.dtype)
    timings = {"registration": 0.0}

    if registration is not None:
        reg, cached = _registration_from(registration, orig_km1, orig_k), True
    else:
        options = dict(register_options or {})

        def compute() -> CachedRegistration:
            if register is None:
                return default_register(orig_km1, orig_k, device=dev, **{"backend": backend, **options})
            t0 = time.perf_counter()
            given = _registration_from(register(orig_km1, orig_k), orig_km1, orig_k)
            return given._replace(seconds=given.seconds or time.perf_counter() - t0)

        start = time.perf_counter()
        if cache is None:
            reg, cached = compute(), False
        else:
            reg, cached = cache.get_or_compute(orig_km1, orig_k, registration_settings(register, options), compute)
        reg = _registration_from(reg, orig_km1, orig_k)
        timings["registration"] = 0.0 if cached else time.perf_counter() - start
    registered = Mesh(reg.verts.to(dev, simp.dtype), orig_km1.faces, validate=False)

    start = time.perf_counter()
    with torch.no_grad():
        # One index per mesh: the references' (shared across methods through `indexes`) and the simplified frame's
        # (queried by both references' vertex sets).
        shared = indexes if indexes is not None else IndexCache()
        # A reference is queried a few times per sequence: the cheap Morton build pays more than a SAH tree.
        simp_index = MeshIndex(simp.verts, simp.faces, backend=backend, tree="morton")
        points = simp_index.ref_points.points
        refs = {
            name: shared.get(m, backend=backend, tree="morton")
            for name, m in (("k", orig_k), ("k_minus_1", registered))
        }
        distances: dict[str, Tensor] = {}
        reverse: dict[str, Tensor] = {}
        for name, index in refs.items():
            distances[f"surface_{name}"] = index.point_mesh_distance(points).dists
            distances[f"vertex_{name}"] = index.nearest_vertex_distance(points).dists
            if two_sided:
                ref_points = index.ref_points.points
                reverse[f"surface_{name}"] = simp_index.point_mesh_distance(ref_points).dists
                reverse[f"vertex_{name}"] = simp_index.nearest_vertex_distance(ref_points).dists
        motion = float((registered.verts - orig_km1.verts).norm(dim=-1).mean() / orig_k.bbox_diagonal())
        flicker = None
        if simplified_k_minus_1 is not None:
            warp: Warp = reg.warp if reg.warp is not None else SurfaceWarp(orig_km1, registered.verts)
            flicker = flicker_distances(simp, simplified_k_minus_1, warp, two_sided=two_sided)
    timings["distances"] = time.perf_counter() - start

    start = time.perf_counter()
    peak = float(orig_k.bbox_diagonal())
    distances = {name: distances[name] for name in SET_NAMES}
    reverse = {name: reverse[name] for name in SET_NAMES if name in reverse}
    if flicker is not None:
        distances[FLICKER] = flicker.dists
        if flicker.reverse is not None:
            reverse[FLICKER] = flicker.reverse
    statistics = {name: distance_statistics(d, peak=peak) for name, d in distances.items()}
    reverse_statistics = {name: distance_statistics(d, peak=peak) for name, d in reverse.items()}
    residual = reg.residual.to(dev)
    registration_statistics = distance_statistics(residual, peak=peak)
    error = error_statistics = None
    if true_registration is not None:
        truth = torch.as_tensor(true_registration).to(dev, registered.verts.dtype)
        if tuple(truth.shape) != tuple(registered.verts.shape):
            raise ShapeError(
                f"true_registration: expected the shape of the vertices of original_k_minus_1 "
                f"{tuple(registered.verts.shape)}, found {tuple(truth.shape)}"
            )
        error = (registered.verts - truth).norm(dim=-1)
        error_statistics = distance_statistics(error, peak=peak)
    timings["statistics"] = time.perf_counter() - start
    return PairEvaluation(
        frame=frame,
        distances=distances,
        statistics=statistics,
        reverse_distances=reverse,
        reverse_statistics=reverse_statistics,
        registration_residual=residual,
        registration_statistics=registration_statistics,
        registration_converged=reg.converged,
        motion=motion,
        peak=peak,
        timings=timings,
        registration_cached=cached,
        registration_error=error,
        registration_error_statistics=error_statistics,
    )


def evaluate_sequence(
    original_frames: Sequence[MeshLike],
    simplified_frames: Sequence[MeshLike],
    *,
    cache_dir: str | None = None,
    cache: RegistrationCache | None = None,
    two_sided: bool = True,
    device: torch.device | str | None = None,
    register: RegisterFn | None = None,
    register_options: Mapping[str, Any] | None = None,
    registrations: Sequence[Any] | None = None,
    progress: Callable[[int, int], None] | None = None,
    backend: str = "auto",
    indexes: IndexCache | None = None,
    ground_truth: Callable[[Tensor, int, int], Tensor] | None = None,
    distributed: bool = False,
) -> SequenceEvaluation:
    """Evaluate a simplified sequence frame pair by frame pair (pairs ``(k-1, k)`` for ``k = 1 .. N-1``).

    Frame 0 has no previous frame and is not evaluated (as in the paper, whose sets need frame ``k-1``).

    Args:
        original_frames: the ``N`` original frames, in order.
        simplified_frames: the ``N`` simplified frames (frame ``k`` simplifies ``original_frames[k]``).
        cache_dir: folder of an on-disk :class:`RegistrationCache` (ignored when ``cache`` is given).
        cache: a registration cache to use (share one across methods: registrations depend only on the originals).
        two_sided: also compute the reverse sets (default ``True``).
        device: where distances (and the default registration) are computed.
        register: registration function (default :func:`default_register`).
        register_options: options of the default registration.
        registrations: optional precomputed registrations, one per pair (``registrations[k-1]`` is frame ``k-1``
            registered onto frame ``k``); bypasses ``register`` and the cache.
        progress: called as ``progress(k, N - 1)`` after frame pair ``k`` is evaluated.
        backend: kernel backend of the distances and of the default registration.
        indexes: an :class:`~torchmeshmetric.IndexCache` (share one across methods: each original frame's index is
            then built once for all of them; default: one for this sequence).
        ground_truth: the true motion, ``ground_truth(points, k - 1, k)`` → positions in frame ``k`` of points of
            frame ``k - 1`` (e.g. :meth:`~torchmeshmetric.data.DemoSequence.transfer`); when given, every pair also
            reports the registration's error to it.

        progress: called as ``progress(k, N - 1)`` after frame pair ``k`` is evaluated (distributed: on rank 0,
            from a helper thread, with the number of pairs done by all ranks).
        distributed: share the frame pairs among the ranks of the initialised ``torch.distributed`` process group
            (every rank calls with the same arguments; every rank returns the whole result, equal to one process's;
            see :mod:`torchmeshmetric.evaluation.distributed`). Explicit, not automatic: inside a DDP job each rank
            may be evaluating its own data. Without a process group the sequence is evaluated here.

    Every pair ``k`` also holds the ``flicker`` set (simplified frame ``k`` against the simplified frame ``k-1``
    moved onto frame ``k``).

    Returns:
        :class:`SequenceEvaluation` with ``N - 1`` pairs.

    Raises:
        ValueError: when the frame counts differ or fewer than two frames are given.
        RankFailedError: distributed only: a rank raised or died (names the rank and the frame pair).
    """
    if len(original_frames) != len(simplified_frames):
        raise ValueError(
            f"simplified_frames: expected as many frames as original_frames ({len(original_frames)}), "
            f"found {len(simplified_frames)}"
        )
    if len(original_frames) < 2:
        raise ValueError(f"original_frames: expected at least 2 frames, found {len(original_frames)}")
    if registrations is not None and len(registrations) != len(original_frames) - 1:
        raise ValueError(
            f"registrations: expected {len(original_frames) - 1} (one per frame pair), found {len(registrations)}"
        )
    if cache is None:
        cache = RegistrationCache(cache_dir)
    if distributed:
        from torchmeshmetric.evaluation.distributed import SequenceWork, evaluate_sequences

        if ground_truth is not None:
            raise ValueError("ground_truth: not supported with distributed=True (each rank sees frame pairs alone)")
        options = {
            "two_sided": two_sided,
            "device": device,
            "register": register,
            "register_options": register_options,
            "backend": backend,
        }
        work = [SequenceWork("", original_frames, {"": simplified_frames})]
        shared = evaluate_sequences(
            work, cache=cache, registrations=[registrations], to=None, progress=progress, **options
        )
        assert shared is not None  # every rank receives the result (to=None)
        return shared[0][""]
    if indexes is None:
        # Each original frame is a reference of two pairs (k, and k-1 registered is another mesh): keep them all.
        indexes = IndexCache(max_entries=2 * len(original_frames))
    pairs = []
    total = len(original_frames) - 1
    for k in range(1, len(original_frames)):
        truth = None
        if ground_truth is not None:
            truth = ground_truth(as_mesh(original_frames[k - 1]).verts, k - 1, k)
        pairs.append(
            evaluate_pair(
                simplified_frames[k],
                original_frames[k],
                original_frames[k - 1],
                registration=None if registrations is None else registrations[k - 1],
                two_sided=two_sided,
                device=device,
                register=register,
                register_options=register_options,
                cache=cache,
                frame=k,
                backend=backend,
                indexes=indexes,
                simplified_k_minus_1=simplified_frames[k - 1],
                true_registration=truth,
            )
        )
        if progress is not None:
            progress(k, total)
    return SequenceEvaluation(pairs)
