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
from typing import Any, NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import ShapeError, check_device, check_flag, common_dtype
from torchmeshmetric.evaluation.flicker import FLICKER, flicker_distances
from torchmeshmetric.evaluation.results import SET_NAMES, PairEvaluation, SequenceEvaluation
from torchmeshmetric.kernels import IndexCache, MeshIndex, point_mesh_distance
from torchmeshmetric.metrics._prebuilt_index import check_index_cache
from torchmeshmetric.metrics.surface_distance_sets import measure_surface_distance_sets
from torchmeshmetric.metrics.vertex_distance_sets import measure_vertex_distance_sets
from torchmeshmetric.registration import NonRigidOptions
from torchmeshmetric.registration.cache import (
    CachedRegistration,
    RegistrationCache,
    compute_registration,
    default_registration_settings,
    registration_fn_name,
)
from torchmeshmetric.registration.warp import as_warp, deformation_of
from torchmeshmetric.stats import DistanceStatistics, distance_statistics
from torchmeshmetric.stats.statistics import derived_peak
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh, power_of_two_scale_down, require_faces
from torchmeshmetric.tasks import exchange, run_tasks

__all__ = [
    "REGISTRATION_DTYPE",
    "REGISTRATION_SAMPLING",
    "PairTask",
    "RegisterFn",
    "RegistrationOptions",
    "check_methods",
    "check_sequence",
    "default_register",
    "evaluate_pair",
    "evaluate_pairs",
    "evaluate_sequence",
    "evaluation_keywords",
    "register_pairs",
    "registration_keywords",
    "registration_settings",
]


#: A registration function ``register(source_k_minus_1, target_k)`` returning the registered frame ``k-1``: a
#: :class:`CachedRegistration`, a result object with ``verts`` (and optionally ``residual``, ``converged``), or a
#: mesh-like with the vertices of the source. A cache (and a cache folder) keeps its registrations under a name
#: that lasts across processes: a plain function's module and qualified name, or any callable's ``cache_key``
#: attribute (a str naming what it computes: ``fn.cache_key = "shift-0.1"``). Without one (a lambda, a closure, a
#: ``functools.partial``, a callable object) they are kept in memory only, for that function object, with a warning
#: when the cache has a folder (:func:`~torchmeshmetric.registration.cache.registration_fn_name`).
RegisterFn = Callable[[Mesh, Mesh], Any]


#: The options of the default registration, as every entry point takes them: a ``NonRigidOptions``, its fields as
#: keywords (``{"num_points": 500}``, ``{"options": NonRigidOptions(...), "tolerance": 0.01}``), or ``None``. The
#: options are the cache key; the run arguments of ``register_nonrigid`` a mapping may add (``generator``,
#: ``num_threads``, ``backend``, ``warn``) are passed on but not keyed, so a cache hit returns the registration drawn
#: with the generator of the run that computed it. ``device`` is the entry point's own argument, refused here.
RegistrationOptions = NonRigidOptions | Mapping[str, Any] | None


def registration_keywords(options: RegistrationOptions) -> dict[str, Any]:
    """The keywords of :func:`~torchmeshmetric.registration.register_nonrigid` that ``options`` stands for.

    The one reading of the registration options of the evaluation (``evaluate_pair``, ``evaluate_sequence``,
    ``register_pairs``, ``TemporalConsistency``): their cache key and the registration they run both come from it.

    Example:
        >>> registration_keywords(NonRigidOptions(num_points=500))["options"].num_points
        500
        >>> registration_keywords({"num_points": 500}), registration_keywords(None)
        ({'num_points': 500}, {})
    """
    if options is None:
        return {}
    if isinstance(options, NonRigidOptions):
        return {"options": options}
    if not isinstance(options, Mapping):
        raise TypeError(
            f"registration_options: expected NonRigidOptions, a mapping of its fields or None, found "
            f"{type(options).__name__}"
        )
    if "device" in options:  # the entry point passes its own: torch named an internal function twice given 'device'
        raise TypeError(
            "registration_options: 'device' is not a registration option; the registration runs on the device the "
            "evaluation is given (its device= argument, --device)"
        )
    return dict(options)


#: The dtype the evaluation's registration (:func:`default_register`) computes in, whatever the frames' dtype; its
#: registered vertices and residual are cast back to the frames' dtype, its deformation stays in this dtype. In
#: float32 the registration (Adam and its stopping rule) amplifies the rounding of torch's CPU kernels, which differs
#: between CPUs: on review L's data64 pair (3.2k vertices) it took 263 steps on an AVX-512 CPU and 272 under the
#: ``scalar`` personality, and the printed tables differed (MSE 9.0e-07 vs 8.9e-07). In float64 both CPUs agree to
#: ~1e-11 relative, far below float32's rounding of the result, so float32 frames print the same figures on every
#: machine (docs/statistics.md, "The same figures on every machine").
REGISTRATION_DTYPE = torch.float64

#: The ``NonRigidOptions.sampling`` the evaluation's registration (:func:`default_register`) uses unless its options
#: name one. ``"canonical"`` draws its samples independently of how the frames are stored: the same surfaces with
#: their vertices renumbered, faces reordered and corners rotated
#: (:func:`~torchmeshmetric.evaluation.determinacy.relabel_frames`) register alike to ~1e-13, where the ``"index"``
#: draws (``register_nonrigid``'s own default) moved the (k-1)-th, flicker and Registration rows by 3-55 %
#: (docs/statistics.md, "Storage order").
REGISTRATION_SAMPLING = "canonical"


def evaluation_keywords(options: Mapping[str, Any]) -> dict[str, Any]:
    """The registration keywords ``options`` with the evaluation's sampling (:data:`REGISTRATION_SAMPLING`) filled in.

    A ``sampling`` the caller names wins: a ``"sampling"`` keyword, or a ``NonRigidOptions`` given as ``"options"``
    whose ``sampling`` is not the dataclass default ``"index"`` (a default field cannot tell "index" named from
    "index" left out, so ``{"sampling": "index"}`` is the one spelling that restores the index draws).

    Example:
        >>> evaluation_keywords({})["sampling"], evaluation_keywords({"sampling": "index"})["sampling"]
        ('canonical', 'index')
    """
    if "sampling" in options:
        return dict(options)
    given = options.get("options")
    if isinstance(given, NonRigidOptions) and given.sampling != "index":
        return dict(options)
    return {**options, "sampling": REGISTRATION_SAMPLING}


def default_register(
    source: Mesh, target: Mesh, *, device: torch.device | str | None = None, **options: Any
) -> CachedRegistration:
    """Register ``source`` (frame ``k-1``) onto ``target`` (frame ``k``) with the library's non-rigid registration.

    The evaluation's registration when none is given: :func:`~torchmeshmetric.registration.cache.compute_registration`
    (registered vertices, residual, convergence flag and deformation, a
    :class:`~torchmeshmetric.registration.RegistrationWarp`, which moves any point: the ``flicker`` set needs it),
    computed in :data:`REGISTRATION_DTYPE` (float64); the registered vertices and the residual are cast back to the
    frames' promoted dtype (at least float32), the deformation is kept in float64. Its samples are drawn with
    :data:`REGISTRATION_SAMPLING` (``"canonical"``, independent of the frames' storage order) unless ``options``
    name a ``sampling`` (:func:`evaluation_keywords`).
    Its qualified name is the ``"register"`` of its cache settings
    (:data:`~torchmeshmetric.registration.cache.DEFAULT_REGISTER`).

    Args:
        source: frame ``k-1``, ``(V_{k-1}, 3)`` vertices.
        target: frame ``k``.
        device: where the registration computes (default: ``source``'s device); the result is on the CPU.
        **options: the registration's options (:data:`RegistrationOptions`: ``options=NonRigidOptions(...)`` or
            its fields as keywords, e.g. ``num_points=500``).

    Returns:
        A :class:`~torchmeshmetric.registration.CachedRegistration`: ``verts`` ``(V_{k-1}, 3)`` and ``residual``
        ``(V_{k-1},)`` in the frames' promoted dtype, ``converged``, ``seconds`` and ``warp`` (float64).

    Raises:
        TypeError: an option that is not a registration option (the message lists them).

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric import Mesh
        >>> sphere = trimesh.creation.icosphere(2)
        >>> source = Mesh(torch.tensor(sphere.vertices, dtype=torch.float32), torch.tensor(sphere.faces))
        >>> target = Mesh(source.verts + torch.tensor([0.02, 0.0, 0.0]), source.faces)  # moved by 0.02 along x
        >>> reg = default_register(source, target)
        >>> tuple(reg.verts.shape), reg.verts.dtype, reg.converged, bool(reg.residual.max() < 1e-6)
        ((162, 3), torch.float32, True, True)
    """
    return compute_registration(source, target, device=device, dtype=REGISTRATION_DTYPE, **evaluation_keywords(options))


def registration_settings(register: RegisterFn | None, options: Mapping[str, Any] | None) -> dict[str, Any]:
    """The settings that identify a registration in the cache: the function's name and the options.

    The library's registration (``register=None``) by its complete options; a caller's function by
    :func:`~torchmeshmetric.registration.cache.registration_fn_name`, ``None`` when it has no name that lasts beyond
    this process (a lambda, a closure, a ``functools.partial``, a callable object without a ``cache_key``): the
    evaluation then keys it by the function object, in memory only
    (:meth:`~torchmeshmetric.registration.RegistrationCache.session_name`).

    Args:
        register: the caller's registration function ``register(source, target)``, or ``None`` for the library's
            (:func:`default_register`).
        options: the registration's options (:data:`RegistrationOptions`); ``None`` for the defaults.

    Returns:
        For the library's registration its cache settings (``"register"``, ``"results_version"``, ``"options"``: the
        complete :class:`~torchmeshmetric.registration.NonRigidOptions`, ``"computes_in"``: ``"float64"``); for a
        caller's function ``{"register": name or None, "options": dict(options)}``.

    Raises:
        TypeError: with ``register=None``, an option that is not a registration option.

    Example:
        >>> settings = registration_settings(None, {"num_points": 500})
        >>> settings["options"].num_points, settings["options"].sampling, settings["computes_in"]
        (500, 'canonical', 'float64')
        >>> registration_settings(lambda s, t: s, {})["register"] is None
        True
    """
    if register is None:
        # The library's registration: its complete, validated options (defaults filled), so equal settings spelled
        # differently share one cache entry (the temporal loss's too) and a misspelled option fails here, before any
        # work.
        # The sampling filled in as default_register fills it: canonical entries are keyed apart from index ones.
        options = evaluation_keywords(options or {})
        return default_registration_settings(NonRigidOptions.from_call(options), REGISTRATION_DTYPE)
    return {"register": registration_fn_name(register), "options": dict(options or {})}


def _registration_from(
    registration: Any, original_k_minus_1: Mesh, original_k: Mesh, name: str = "registration"
) -> CachedRegistration:
    """Normalise a caller-given registration (mesh-like or result object with ``verts``) to a CachedRegistration.

    ``name``: the argument that gave it, in the error a registration that is no mesh-like gets.
    """
    if isinstance(registration, CachedRegistration):
        reg = registration
    else:
        verts = getattr(registration, "verts", None)
        if verts is None:
            verts = as_mesh(registration, name=name).verts
        verts = torch.as_tensor(verts)
        residual = getattr(registration, "residual", None)
        if residual is None:
            with torch.no_grad():
                residual = point_mesh_distance(verts.to(original_k.verts), original_k).dists
        warp = deformation_of(registration, original_k)
        converged = bool(getattr(registration, "converged", True))
        reg = CachedRegistration(verts, torch.as_tensor(residual), converged, 0.0, warp)
    if tuple(reg.verts.shape) != tuple(original_k_minus_1.verts.shape):
        raise ShapeError(
            f"registration: expected registered vertices of shape {tuple(original_k_minus_1.verts.shape)} "
            f"(the vertices of original_k_minus_1), found {tuple(reg.verts.shape)}"
        )
    return reg


def _register_pair(
    original_k_minus_1: Mesh,
    original_k: Mesh,
    *,
    registration_fn: RegisterFn | None,
    registration_options: RegistrationOptions,
    registration_cache: RegistrationCache | None,
    device: torch.device | str | None,
    backend: str,
) -> tuple[CachedRegistration, bool, float]:
    """Frame ``k-1`` registered onto frame ``k``, through the cache: ``(registration, cache hit, seconds spent)``."""
    options = registration_keywords(registration_options)

    def compute() -> CachedRegistration:
        if registration_fn is None:
            return default_register(original_k_minus_1, original_k, device=device, **{"backend": backend, **options})
        t0 = time.perf_counter()
        given = _registration_from(registration_fn(original_k_minus_1, original_k), original_k_minus_1, original_k)
        return given._replace(seconds=given.seconds or time.perf_counter() - t0)

    start = time.perf_counter()
    if registration_cache is None:
        reg, cached = compute(), False
    else:
        settings = registration_settings(registration_fn, options)
        lasting = settings["register"] is not None
        if not lasting:  # no name beyond this process: keyed by the function object, in memory only
            settings["register"] = registration_cache.session_name(registration_fn)
        reg, cached = registration_cache.get_or_compute(
            original_k_minus_1, original_k, settings, compute, on_disk=lasting
        )
    reg = _registration_from(reg, original_k_minus_1, original_k)
    return reg, cached, 0.0 if cached else time.perf_counter() - start


def register_pairs(
    original_frames: Sequence[MeshLike],
    *,
    registration_fn: RegisterFn | None = None,
    registration_options: RegistrationOptions = None,
    registration_cache: RegistrationCache | None = None,
    device: torch.device | str | None = None,
    backend: str = "auto",
) -> list[CachedRegistration]:
    """Every original frame ``k-1`` registered onto frame ``k`` (``N - 1`` registrations), through the cache.

    The registrations :func:`evaluate_sequence` computes for the same frames and settings (the same cache
    entries), ready to be passed as its ``precomputed_registrations`` or to Registered QEM.

    Args:
        original_frames: the ``N`` original frames, in order.
        registration_fn: registration function (default :func:`default_register`); cached under its name, or, for a
            callable without a lasting one (a lambda, a partial), in memory only (see :data:`RegisterFn`).
        registration_options: options of the default registration (the cache key): a
            :class:`~torchmeshmetric.registration.NonRigidOptions` or its fields as keywords, and run arguments,
            which are not keyed: a ``generator`` given here does not tell cache entries apart (see
            :data:`RegistrationOptions`).
        registration_cache: a :class:`RegistrationCache`; ``None`` computes every registration.
        device: where the default registration runs.
        backend: kernel backend of the default registration.

    Returns:
        ``N - 1`` :class:`CachedRegistration`; entry ``k-1`` is frame ``k-1`` registered onto frame ``k`` (its
        :meth:`~CachedRegistration.registered_mesh` is that mesh).

    Example:
        >>> import torch, trimesh
        >>> frames = [trimesh.creation.icosphere(subdivisions=1)] * 3
        >>> same = lambda source, target: source  # the frames do not move
        >>> regs = register_pairs(frames, registration_fn=same)
        >>> len(regs), float(regs[0].residual.max()) < 1e-12
        (2, True)
    """
    frames = [as_mesh(f) for f in original_frames]
    return [
        _register_pair(
            frames[k - 1],
            frames[k],
            registration_fn=registration_fn,
            registration_options=registration_options,
            registration_cache=registration_cache,
            device=device,
            backend=backend,
        )[0]
        for k in range(1, len(frames))
    ]


def _distance_sets(
    simplified: Mesh, references: Mapping[str, Mesh], two_sided: bool, backend: str, indexes: IndexCache | None
) -> tuple[dict[str, Tensor], dict[str, Tensor]]:
    """The paper's sets ``surface_<ref>`` (Eq. 4) and ``vertex_<ref>`` (Eq. 5) for each named reference.

    Returns ``(forward, reverse)``: from the simplified vertices (Eq. 3) to each reference, and (two-sided) from
    each reference's vertices to the simplified mesh (``reverse`` is empty when one-sided).
    """
    # One index per mesh: the references' (shared across methods and frame pairs through `indexes`) and the
    # simplified frame's (queried by every reference's vertex set). A reference is queried a few times per
    # sequence: the cheap Morton build pays more than a SAH tree.
    shared = indexes if indexes is not None else IndexCache()
    simp_index = MeshIndex(simplified.verts, simplified.faces, backend=backend, tree="morton")
    points = [simp_index.ref_points.points]
    forward: dict[str, Tensor] = {}
    reverse: dict[str, Tensor] = {}
    for name, mesh in references.items():
        ref_index = shared.get(mesh, backend=backend, tree="morton")
        ref_points = [ref_index.ref_points.points]
        # The metrics' trusted entries: the meshes are validated and their vertex sets taken once, here.
        surface = measure_surface_distance_sets(
            points, [mesh], ref_points if two_sided else None, [simplified], ref_index, simp_index, backend
        )
        vertex = measure_vertex_distance_sets(points, ref_points, two_sided, ref_index, simp_index, backend)
        for kind, (to_reference, from_reference) in (("surface", surface), ("vertex", vertex)):
            forward[f"{kind}_{name}"] = to_reference
            if from_reference is not None:
                reverse[f"{kind}_{name}"] = from_reference
    return forward, reverse


def _registration_error(registered: Mesh, true_registration: Tensor, peak: float) -> tuple[Tensor, DistanceStatistics]:
    """Distances of the registered vertices to their true positions, and their statistics."""
    truth = torch.as_tensor(true_registration).to(registered.verts.device, registered.verts.dtype)
    if tuple(truth.shape) != tuple(registered.verts.shape):
        raise ShapeError(
            f"true_registration: expected the shape of the vertices of original_k_minus_1 "
            f"{tuple(registered.verts.shape)}, found {tuple(truth.shape)}"
        )
    error = (registered.verts - truth).norm(dim=-1)
    return error, distance_statistics(error, peak=peak)


def evaluate_pair(
    simplified_k: MeshLike,
    original_k: MeshLike,
    original_k_minus_1: MeshLike,
    *,
    precomputed_registration: Any = None,
    two_sided: bool = True,
    device: torch.device | str | None = None,
    registration_fn: RegisterFn | None = None,
    registration_options: RegistrationOptions = None,
    registration_cache: RegistrationCache | None = None,
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
        precomputed_registration: frame ``k-1`` already registered onto frame ``k``: a mesh-like with the vertices
            (and topology) of ``original_k_minus_1``, a :class:`~torchmeshmetric.registration.NonRigidRegistration`,
            or a :class:`CachedRegistration`. ``None`` (default) registers with ``registration_fn``.
        two_sided: also compute the reverse (reference → simplified) sets (default ``True``).
        device: where distances are computed (default: the device of ``simplified_k``).
        registration_fn: registration function ``(source, target) -> registered source`` (see :data:`RegisterFn`);
            default :func:`default_register` (with ``registration_options`` and ``device``).
        registration_options: options of the default registration (the cache key): a
            :class:`~torchmeshmetric.registration.NonRigidOptions` or its fields as keywords, and run arguments,
            which are not keyed: a ``generator`` given here does not tell cache entries apart (see
            :data:`RegistrationOptions`).
        registration_cache: a :class:`RegistrationCache`; reused registrations cost nothing.
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
        ShapeError: when ``precomputed_registration`` does not have the vertices of ``original_k_minus_1``.

    Example:
        >>> import trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> coarse = trimesh.creation.icosphere(subdivisions=1)
        >>> r = evaluate_pair(coarse, sphere, sphere, precomputed_registration=sphere)
        >>> float(r.statistics["vertex_k"].max) < 1e-12, float(r.statistics["surface_k"].max) < 1e-12
        (True, True)
        >>> round(float(r.reverse_statistics["surface_k"].max), 3)  # fine vertices off the coarse surface
        0.049
    """
    # Each under its own name (it read "mesh", and a faceless frame "faces: mesh 0 ...": found by reviews), now, not
    # after the registration; every frame is measured to or from its surface, so each needs a face.
    two_sided = check_flag(two_sided, "two_sided")  # "y" was taken for True
    check_index_cache(indexes)
    simp = require_faces(as_mesh(simplified_k, name="simplified_k"), "simplified_k")
    dev = check_device(device) if device is not None else simp.device
    orig_k = require_faces(as_mesh(original_k, name="original_k"), "original_k")
    orig_km1 = require_faces(as_mesh(original_k_minus_1, name="original_k_minus_1"), "original_k_minus_1")
    if simplified_k_minus_1 is not None:
        simplified_k_minus_1 = require_faces(
            as_mesh(simplified_k_minus_1, name="simplified_k_minus_1"), "simplified_k_minus_1"
        )
    # The dtype rule (docs/concepts.md, Precision): the three frames in their promoted dtype (a float32 model's
    # output against float64 originals is measured in float64, nothing rounded).
    dtype = common_dtype(simp.dtype, orig_k.dtype, orig_km1.dtype)
    simp, orig_k, orig_km1 = simp.to(dev, dtype), orig_k.to(dev, dtype), orig_km1.to(dev, dtype)
    if precomputed_registration is not None:
        reg, cached, seconds = (
            _registration_from(precomputed_registration, orig_km1, orig_k, "precomputed_registration"),
            True,
            0.0,
        )
    else:
        reg, cached, seconds = _register_pair(
            orig_km1,
            orig_k,
            registration_fn=registration_fn,
            registration_options=registration_options,
            registration_cache=registration_cache,
            device=dev,
            backend=backend,
        )
    timings = {"registration": seconds}
    registered = reg.registered_mesh(orig_km1)

    start = time.perf_counter()
    with torch.no_grad():
        distances, reverse = _distance_sets(simp, {"k": orig_k, "k_minus_1": registered}, two_sided, backend, indexes)
        # scaled by an exact power of two: the squares of the norms under- or overflowed for extreme magnitudes
        diagonal = orig_k.bbox_diagonal().to(torch.float64)
        scale = power_of_two_scale_down(diagonal)
        moves = (registered.verts - orig_km1.verts).to(torch.float64) * scale
        motion = float(moves.norm(dim=-1).mean() / (diagonal * scale))
        flicker = None
        if simplified_k_minus_1 is not None:
            warp = as_warp(reg, orig_k, orig_km1, name="precomputed_registration")
            flicker = flicker_distances(simp, simplified_k_minus_1, warp, two_sided=two_sided)
    timings["distances"] = time.perf_counter() - start

    start = time.perf_counter()
    peak = derived_peak(float(orig_k.bbox_diagonal()), "original_k")
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
        error, error_statistics = _registration_error(registered, true_registration, peak)
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
    registration_cache_dir: str | None = None,
    registration_cache: RegistrationCache | None = None,
    two_sided: bool = True,
    device: torch.device | str | None = None,
    registration_fn: RegisterFn | None = None,
    registration_options: RegistrationOptions = None,
    precomputed_registrations: Sequence[Any] | None = None,
    progress: Callable[[int, int], None] | None = None,
    backend: str = "auto",
    indexes: IndexCache | None = None,
    ground_truth: Callable[[Tensor, int, int], Tensor] | None = None,
    distributed: bool = False,
) -> SequenceEvaluation:
    """Evaluate a simplified sequence frame pair by frame pair (pairs ``(k-1, k)`` for ``k = 1 .. N-1``).

    Frame 0 has no previous frame and is not evaluated (as in the paper, whose sets need frame ``k-1``). Every
    pair ``k`` also holds the ``flicker`` set (simplified frame ``k`` against the simplified frame ``k-1`` moved
    onto frame ``k``).

    Args:
        original_frames: the ``N`` original frames, in order.
        simplified_frames: the ``N`` simplified frames (frame ``k`` simplifies ``original_frames[k]``).
        registration_cache_dir: folder of an on-disk :class:`RegistrationCache` (ignored when
            ``registration_cache`` is given).
        registration_cache: a registration cache to use (share one across methods: registrations depend only on
            the originals).
        two_sided: also compute the reverse sets (default ``True``).
        device: where distances (and the default registration) are computed.
        registration_fn: registration function (default :func:`default_register`); cached under its name, or, for a
            callable without a lasting one (a lambda, a partial), in memory only (see :data:`RegisterFn`).
        registration_options: options of the default registration (``NonRigidOptions`` or its fields as keywords;
            the cache key, less the run arguments: a ``generator`` given here is not keyed, see
            :data:`RegistrationOptions`).
        precomputed_registrations: optional registrations, one per pair (``precomputed_registrations[k-1]`` is frame
            ``k-1`` registered onto frame ``k``, e.g. from :func:`register_pairs`); bypasses ``registration_fn`` and
            the cache.
        progress: called as ``progress(k, N - 1)`` after frame pair ``k`` is evaluated (distributed: on rank 0,
            from a helper thread, with the number of pairs done by all ranks).
        backend: kernel backend of the distances and of the default registration.
        indexes: an :class:`~torchmeshmetric.IndexCache` (share one across methods: each original frame's index is
            then built once for all of them; default: one for this sequence).
        ground_truth: the true motion, ``ground_truth(points, k - 1, k)`` → positions in frame ``k`` of points of
            frame ``k - 1`` (e.g. :meth:`~torchmeshmetric.data.DemoSequence.transfer`); when given, every pair also
            reports the registration's error to it.
        distributed: share the frame pairs among the ranks of the initialised ``torch.distributed`` process group
            (every rank calls with the same arguments; every rank returns the whole result, equal to one process's;
            see :mod:`torchmeshmetric.tasks`). Explicit, not automatic: inside a DDP job each rank
            may be evaluating its own data. Without a process group the sequence is evaluated here. Each pair is
            :func:`evaluate_pair` in both cases (:func:`evaluate_pairs`).

    Returns:
        :class:`SequenceEvaluation` with ``N - 1`` pairs.

    Raises:
        ValueError: when the frame counts differ or fewer than two frames are given.
        RankFailedError: distributed only: a rank raised or died (names the rank and the frame pair).

    Example:
        >>> import trimesh
        >>> frames = [trimesh.creation.icosphere(subdivisions=2)] * 3
        >>> coarse = [trimesh.creation.icosphere(subdivisions=1)] * 3
        >>> result = evaluate_sequence(frames, coarse, registration_fn=lambda source, target: source)
        >>> len(result.pairs), float(result.pairs[0].statistics["surface_k"].max) < 1e-12
        (2, True)
    """
    two_sided = check_flag(two_sided, "two_sided")
    distributed = check_flag(distributed, "distributed")
    check_sequence(original_frames, simplified_frames, precomputed_registrations)
    if registration_cache is None:
        registration_cache = RegistrationCache(registration_cache_dir)
    if indexes is None:
        # Each original frame is a reference of two pairs (k, and k-1 registered is another mesh): keep them all.
        indexes = IndexCache(max_entries=2 * len(original_frames))
    given: Sequence[Any] = [None] * (len(original_frames) - 1)
    if precomputed_registrations is not None:
        given = precomputed_registrations
    tasks = [
        PairTask(original_frames, simplified_frames, k, given[k - 1], f"frame pair {k - 1} -> {k}")
        for k in range(1, len(original_frames))
    ]
    pairs = evaluate_pairs(
        tasks,
        registration_cache=registration_cache,
        sharded=distributed,
        to=None,
        progress=progress,
        ground_truth=ground_truth,
        two_sided=two_sided,
        device=device,
        registration_fn=registration_fn,
        registration_options=registration_options,
        backend=backend,
        indexes=indexes,
    )
    assert pairs is not None  # every rank receives the result (to=None)
    return SequenceEvaluation(pairs)


class PairTask(NamedTuple):
    """One frame pair ``(k-1, k)`` of a sequence to evaluate, as :func:`evaluate_pairs` takes it.

    Attributes:
        original: the sequence's ``N`` original frames.
        simplified: the method's ``N`` simplified frames.
        frame: ``k`` (``1 .. N-1``).
        precomputed_registration: frame ``k-1`` registered onto frame ``k``, or ``None`` (registered here).
        name: the pair's name in messages (e.g. ``"sequence 'a' method 'QEM' frame pair 1 -> 2"``).
    """

    original: Sequence[MeshLike]
    simplified: Sequence[MeshLike]
    frame: int
    precomputed_registration: Any
    name: str


def evaluate_pairs(
    tasks: Sequence[PairTask],
    *,
    registration_cache: RegistrationCache,
    sharded: bool = False,
    to: int | None = 0,
    progress: Callable[[int, int], None] | None = None,
    ground_truth: Callable[[Tensor, int, int], Tensor] | None = None,
    **options: Any,
) -> list[PairEvaluation] | None:
    """:func:`evaluate_pair` of every task, here or shared among the ranks (:func:`torchmeshmetric.tasks.run_tasks`).

    The registrations this call computed or loaded are then in ``registration_cache`` on every rank, so a later call
    (another method on the same originals) finds them there.

    Args:
        tasks: the frame pairs (identical on every rank when ``sharded``).
        registration_cache: the registration cache every pair registers through.
        sharded: share the tasks among the ranks of the initialised process group (a collective); ``False``: every
            task runs in this process.
        to: the rank that receives the results (``None``: every rank).
        progress: called as ``progress(done, len(tasks))`` (sharded: on rank 0, with the pairs done by all ranks).
        ground_truth: the true motion (see :func:`evaluate_sequence`); each pair then reports its registration error.
        **options: passed to :func:`evaluate_pair` (``two_sided``, ``device``, ``registration_fn``, ...).

    Returns:
        The :class:`PairEvaluation` of every task, in task order, on the receiving rank(s); ``None`` elsewhere.

    Raises:
        RankFailedError: sharded only: a rank raised or died (names the rank and the task's ``name``).

    Example:
        >>> import trimesh
        >>> frames = [trimesh.creation.icosphere(subdivisions=1)] * 2
        >>> same = lambda source, target: source  # the frames do not move
        >>> [p] = evaluate_pairs([PairTask(frames, frames, 1, None, "pair")], registration_cache=RegistrationCache(),
        ...                      registration_fn=same)
        >>> p.frame, float(p.statistics["surface_k"].max) < 1e-12
        (1, True)
    """
    sharded = check_flag(sharded, "sharded")

    def one_pair(task: PairTask) -> PairEvaluation:
        original, simplified, k = task.original, task.simplified, task.frame
        truth = None if ground_truth is None else ground_truth(as_mesh(original[k - 1]).verts, k - 1, k)
        return evaluate_pair(
            simplified[k],
            original[k],
            original[k - 1],
            precomputed_registration=task.precomputed_registration,
            registration_cache=registration_cache,
            frame=k,
            simplified_k_minus_1=simplified[k - 1],
            true_registration=truth,
            **options,
        )

    if not sharded:
        pairs = []
        for done, task in enumerate(tasks, start=1):
            pairs.append(one_pair(task))
            if progress is not None:
                progress(done, len(tasks))
        return pairs
    journal: dict[str, CachedRegistration] = {}
    outer, registration_cache.journal = registration_cache.journal, journal  # this call's entries, by key
    try:
        results = run_tasks(one_pair, tasks, describe=lambda task: task.name, to=to, progress=progress)
    finally:
        registration_cache.journal = outer
    if outer is not None:
        outer.update(journal)
    for entries in exchange(journal, what="the exchange of registrations"):
        registration_cache.adopt(entries)
    return results


def check_methods(original_frames: Sequence[Any], methods: Mapping[str, Sequence[Any]], *, sequence: str = "") -> None:
    """Refuse, before any work starts, methods that cannot be evaluated on ``original_frames``.

    Every multi-method entry point (``evaluate_sequences``, the ``evaluate`` / ``compare`` / ``campaign`` commands)
    calls it first, so a method with fewer frames fails in milliseconds, not after the others were evaluated.

    Args:
        original_frames: the ``N`` original frames.
        methods: method name -> its simplified frames.
        sequence: the sequence's name in the messages (``""``: none).

    Raises:
        ValueError: a method's frame count differs from ``N``, no method is given, or ``N < 2``.

    Example:
        >>> check_methods([0, 1, 2], {"a": [0, 1, 2], "b": [0, 1]})
        Traceback (most recent call last):
            ...
        ValueError: method 'b': 2 simplified frames but 3 original frames (must match)
    """
    where = f"sequence {sequence!r}: " if sequence else ""
    if not methods:
        raise ValueError(f"{where}methods: expected at least one method, found none")
    for name, frames in methods.items():
        if len(frames) != len(original_frames):
            raise ValueError(
                f"{where}method {name!r}: {len(frames)} simplified frames but {len(original_frames)} original frames "
                "(must match)"
            )
    if len(original_frames) < 2:
        has = f"{where}{len(original_frames)} frame" if sequence else f"the sequence has {len(original_frames)} frame"
        raise ValueError(f"{has}; at least 2 are needed (pairs k-1, k)")


def check_sequence(
    original_frames: Sequence[MeshLike], simplified_frames: Sequence[MeshLike], registrations: Sequence[Any] | None
) -> None:
    """Refuse, before any work, a simplified sequence or precomputed registrations of the wrong length.

    Raises:
        ValueError: the frame counts differ, fewer than 2 frames, or not ``N - 1`` registrations.

    Example:
        >>> check_sequence([0, 1], [0], None)
        Traceback (most recent call last):
            ...
        ValueError: simplified_frames: expected as many frames as original_frames (2), found 1
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
            f"precomputed_registrations: expected {len(original_frames) - 1} (one per frame pair), "
            f"found {len(registrations)}"
        )
