"""Non-rigid registration loop: rigid ICP, then an embedded deformation graph fitted with Adam, coarse to fine.

The model (:class:`~torchmeshmetric.registration.DeformationGraph`), the energies
(:mod:`torchmeshmetric.registration.energies`) and the settings (:class:`NonRigidOptions`, the :class:`Stage`
schedule) live elsewhere; this loop only schedules them:

1. :func:`_normalise`: both meshes to the target's bounding-box centre and unit diagonal (every threshold is a
   fraction of the diagonal), after an optional rigid ICP (:func:`~torchmeshmetric.registration.register_rigid`);
2. :class:`_Fit`: the graph, the fixed data points and target samples, both meshes' indexes;
3. :meth:`_Fit.run_stage` for each :class:`Stage` (regularisation, robust scale and rejection thresholds
   decreasing): Adam steps on the graph's rotations and translations; correspondences (source vertices → target
   faces, target samples → deformed source faces) are refreshed every ``correspondence_every`` steps, not every
   step; the stage ends after ``max_steps``, when the loss changes by less than ``tolerance`` (relative) between two
   refreshes, or at a stationary point (every gradient component below ``sqrt(eps)`` of the dtype); each stage then
   keeps its **best iterate**: the parameters of the lowest loss measured right after a correspondence refresh (the
   stage's last iterate gets one more refresh to compete). Adam moves every parameter by about the learning rate
   whatever the gradient's size, so without this an exact pair drifted by 1e-3 of the diagonal and a near-exact one
   ended at Adam's noise floor instead of where it started;
4. divergence (NaN/Inf or a loss that explodes) restores the last good parameters and reports failure;
   :meth:`_Fit.plausibility` reports a fit whose residuals stay large, or which leaves a part of the target
   uncovered, as not converged too, with the reason, and a warning.
"""

from __future__ import annotations

import math
import time
import warnings
from typing import Any, NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import check_device, check_flag, check_generator, check_int
from torchmeshmetric.kernels._common import DEFAULT_MAX_MEMORY
from torchmeshmetric.kernels.mesh_index import MeshIndex
from torchmeshmetric.registration._common import normalisation, validate_pair, welded_faces
from torchmeshmetric.registration.adam import Adam
from torchmeshmetric.registration.deformation_graph import (
    DeformationGraph,
    _coordinate_order,
    canonical_farthest_points,
)
from torchmeshmetric.registration.energies import (
    Correspondences,
    EnergyTerms,
    FusedStep,
    data_term,
    deformed_vertices,
    embedded_deformation_regularizer,
    find_correspondences,
    registration_ops,
    reverse_term,
)
from torchmeshmetric.registration.options import DEFAULT_SCHEDULE, NonRigidOptions, Stage
from torchmeshmetric.registration.rigid import RigidRegistration, register_rigid, transform_matrix
from torchmeshmetric.structures import Mesh, MeshLike, PackedMeshes

__all__ = [
    "DEFAULT_SCHEDULE",
    "NonRigidOptions",
    "NonRigidRegistration",
    "RegistrationWarning",
    "Stage",
    "register_nonrigid",
]


class RegistrationWarning(UserWarning):
    """Emitted when a registration fails (diverged, or the fit is implausible).

    Example:
        >>> import torch, trimesh, warnings
        >>> from torchmeshmetric import Mesh, as_mesh
        >>> source = as_mesh(trimesh.creation.icosphere(subdivisions=2))
        >>> three_times = Mesh(source.verts * 3, source.faces)  # no rigid motion and a short schedule cannot reach it
        >>> with warnings.catch_warnings(record=True) as caught:
        ...     warnings.simplefilter("always")
        ...     r = register_nonrigid(source, three_times, schedule=[DEFAULT_SCHEDULE[0]._replace(max_steps=5)])
        >>> [w.category.__name__ for w in caught], r.converged, r.reason.split(":")[0]
        (['RegistrationWarning'], False, 'implausible fit')
    """


class NonRigidRegistration(NamedTuple):
    """Result of :func:`register_nonrigid`.

    Attributes:
        verts: ``(V, 3)`` registered source vertices (source topology and order, in target coordinates).
        mesh: the registered :class:`~torchmeshmetric.Mesh` (source faces).
        residual: ``(V,)`` exact distance of each registered vertex to the target surface.
        loss_history: total loss after every Adam step.
        converged: ``True`` only when no divergence happened and the fit is plausible (see ``reason``).
        reason: empty when ``converged``; otherwise why the registration is not trusted.
        timings: seconds spent in ``rigid``, ``graph``, ``correspondences``, ``optimisation``, ``residual``, ``total``.
        graph: the fitted :class:`DeformationGraph` (in the normalised frame: centre/diagonal of the target).
        rigid: the :class:`RigidRegistration` used (identity when ``rigid_init=False``).

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric import Mesh, as_mesh
        >>> source = as_mesh(trimesh.creation.icosphere(subdivisions=2))
        >>> target = Mesh(source.verts + torch.tensor([0.1, 0.0, 0.0], dtype=source.dtype), source.faces)
        >>> r = register_nonrigid(source, target, schedule=[DEFAULT_SCHEDULE[0]._replace(max_steps=5)])
        >>> r.converged, r.reason, tuple(r.verts.shape), bool(r.residual.max() < 1e-9), r.mesh.num_faces
        (True, '', (162, 3), True, 320)
        >>> sorted(r.timings)
        ['correspondences', 'graph', 'optimisation', 'residual', 'rigid', 'total']
    """

    verts: Tensor
    mesh: Mesh
    residual: Tensor
    loss_history: list[float]
    converged: bool
    reason: str
    timings: dict[str, float]
    graph: DeformationGraph
    rigid: RigidRegistration


def _identity_rigid(verts: Tensor) -> RigidRegistration:
    eye = torch.eye(3, dtype=verts.dtype, device=verts.device)
    zero = verts.new_zeros(3)
    return RigidRegistration(
        eye, zero, verts.new_ones(()), torch.eye(4, dtype=verts.dtype, device=verts.device), verts,
        verts.new_zeros(()), verts.new_ones(()), True, 0,
    )  # fmt: skip


def _parameters(graph: DeformationGraph) -> dict[str, Tensor]:
    """A copy of the graph's parameters (rotations, translations): the buffers never change."""
    return {name: p.detach().clone() for name, p in graph.named_parameters()}


def _load_parameters(graph: DeformationGraph, state: dict[str, Tensor]) -> None:
    with torch.no_grad():
        for name, p in graph.named_parameters():
            p.copy_(state[name])


ADAM_EPS = 1e-8
"""torch's Adam ``eps``: the floor of the registration's (see ``NonRigidOptions.adam_eps``)."""


def _lengths(x: Tensor) -> Tensor:
    return torch.tensor([x.shape[0]], device=x.device)


def register_nonrigid(
    source: MeshLike,
    target: MeshLike,
    options: NonRigidOptions | None = None,
    *,
    device: torch.device | str | None = None,
    generator: torch.Generator | None = None,
    warn: bool = True,
    backend: str = "auto",
    num_threads: int | None = 1,
    **keywords: Any,
) -> NonRigidRegistration:
    """Register ``source`` (frame k-1) non-rigidly onto ``target`` (frame k), keeping the source's topology.

    Works on frames as they come out of capture — duplicate and unreferenced vertices, zero-length edges,
    zero-area faces — without cleaning: data points come from vertices of positive-area faces only (nodes and the
    rigid stage's points from the vertices of any face), unreferenced vertices still move with the graph's skinning,
    zero-area faces carry no normal so they skip the point-to-plane term, and the closest-point kernel is exact on
    degenerate triangles.

    What is computed is set by ``options`` and ``keywords`` (any field of :class:`NonRigidOptions`, e.g.
    ``num_points=1000``, ``schedule=DEFAULT_SCHEDULE[:2]``; a keyword overrides the same field of ``options``).
    Both spellings are supported and give the same :class:`NonRigidOptions`: keywords for a one-off call, the
    dataclass to keep, compare or cache a setting. The other arguments say how it runs; they do not change what is
    computed: the backends and, on the CPU, the thread counts give the same result bit for bit; another device sums
    in another order, and the optimisation can amplify that rounding.

    Args:
        source: mesh to deform (frame k-1).
        target: mesh to reach (frame k).
        options: the registration's settings (default: ``NonRigidOptions()``).
        device: device to compute on (default: the source's device); results live there.
        generator: CPU ``torch.Generator`` for sampling (default: a fresh one seeded with 0, so runs repeat). Unused
            with ``sampling="canonical"``, whose samples are chosen from the surfaces, not drawn: any generator
            gives the same registration (tests/registration/test_stability.py).
        warn: emit a :class:`RegistrationWarning` when the registration fails.
        backend: selection backend of the closest-face searches (see :func:`~torchmeshmetric.point_mesh_distance`);
            the exact backends return the same faces, so the result does not depend on it.
        num_threads: torch intra-op threads while registering (restored afterwards; process-wide, like
            ``torch.set_num_threads``). Default 1: the loop is ~0.5 ms steps, each a few parallel regions that end at
            a barrier, so next to other busy processes every region waits for a descheduled thread
            (docs/registration.md, "Threads": 0.8 s on one thread, 4-14 s on two, measured on a loaded 2-core
            machine). More threads pay on an otherwise idle machine. ``None``: keep torch's setting.
        **keywords: fields of :class:`NonRigidOptions` (``rigid_init``, ``node_spacing``, ``num_neighbors``,
            ``num_points``, ``num_target_samples``, ``correspondence_every``, ``schedule``, ``plane_weight``,
            ``point_weight``, ``reverse_weight``, ``adam_eps``, ``tolerance``, ``max_outlier_fraction``,
            ``max_uncovered_fraction``, ``outlier_distance``, ``outlier_edge_factor``, ``rigid_options``,
            ``sampling``).

    Returns:
        :class:`NonRigidRegistration`.

    Raises:
        ShapeError, DTypeError, NonFiniteError, IndexRangeError, DeviceError, EmptyInputError: on bad meshes.
        TypeError, ValueError: on a bad option (the message names it), or an unknown keyword.

    Example:
        >>> import torch, trimesh
        >>> src = trimesh.creation.icosphere(subdivisions=2)
        >>> tgt = trimesh.creation.icosphere(subdivisions=3)
        >>> tgt.vertices *= [1.1, 1.0, 0.9]
        >>> quick = NonRigidOptions(schedule=DEFAULT_SCHEDULE[-2:])
        >>> r = register_nonrigid(src, tgt, quick, generator=torch.Generator().manual_seed(0))
        >>> r.converged, bool(r.residual.max() < 0.02)
        (True, True)
        >>> bool((register_nonrigid(src, tgt, schedule=DEFAULT_SCHEDULE[-2:]).verts == r.verts).all())  # same result
        True
    """
    warn = check_flag(warn, "warn")
    opts = NonRigidOptions.from_keywords(options, **keywords)
    if num_threads is not None:
        num_threads = check_int(num_threads, "num_threads", 1)
    check_generator(generator)  # a seed here failed in torch's randperm
    previous_threads = torch.get_num_threads()
    if num_threads is not None and num_threads != previous_threads:
        torch.set_num_threads(num_threads)
    try:
        device = None if device is None else check_device(device)
        return _register(source, target, opts, device=device, generator=generator, warn=warn, backend=backend)
    finally:
        if torch.get_num_threads() != previous_threads:
            torch.set_num_threads(previous_threads)


def _register(
    source: MeshLike,
    target: MeshLike,
    opts: NonRigidOptions,
    *,
    device: torch.device | str | None,
    generator: torch.Generator | None,
    warn: bool,
    backend: str,
) -> NonRigidRegistration:
    t_total = time.perf_counter()
    timings = {"rigid": 0.0, "graph": 0.0, "correspondences": 0.0, "optimisation": 0.0, "residual": 0.0}
    gen = generator if generator is not None else torch.Generator().manual_seed(0)
    frame = _normalise(source, target, opts, device, gen, timings)
    fit = _Fit(frame, opts, gen, backend, timings)
    t_opt = time.perf_counter()
    for stage in opts.schedule:
        fit.run_stage(stage)
        if fit.reason:
            break
    timings["optimisation"] = time.perf_counter() - t_opt - timings["correspondences"]
    t0 = time.perf_counter()
    verts, residual, implausible = fit.plausibility()
    rigid = frame.rigid
    if frame.unit != 1.0:
        # Back to the input's units (an exact division by a power of two); the graph stays in the normalised frame.
        verts, residual, rigid = verts / frame.unit, residual / frame.unit, _unscaled_rigid(rigid, frame.unit)
    timings["residual"] = time.perf_counter() - t0
    reason = fit.reason or implausible or fit.convergence()
    if not reason and not all(math.isfinite(h) for h in fit.history):
        reason = "diverged: non-finite loss"
    if reason and warn:
        warnings.warn(f"register_nonrigid: {reason}", RegistrationWarning, stacklevel=3)
    timings["total"] = time.perf_counter() - t_total
    return NonRigidRegistration(
        verts=verts,
        mesh=Mesh(verts, frame.faces, validate=False),
        residual=residual,
        loss_history=fit.history,
        converged=not reason,
        reason=reason,
        timings=timings,
        graph=fit.graph,
        rigid=rigid,
    )


def _weighted_rms(matches: Correspondences) -> float:
    """The acceptance-weighted RMS distance of a refresh's matches (in diagonals; 0 when none is accepted)."""
    return float(((matches.weights * matches.dists**2).sum() / matches.weights.sum().clamp_min(1e-30)).sqrt())


def _unscaled_rigid(rigid: RigidRegistration, unit: float) -> RigidRegistration:
    """``rigid``, computed on coordinates multiplied by ``unit``, in the input's units (lengths divided by it)."""
    translation = rigid.translation / unit
    return rigid._replace(
        translation=translation,
        transform=transform_matrix(rigid.rotation, translation, rigid.scale),
        verts=rigid.verts / unit,
        rmse=rigid.rmse / unit,
    )


def _outlier_reach(edge: float, opts: NonRigidOptions) -> float:
    """Distance (in diagonals) beyond which a source vertex is an outlier and a target sample uncovered.

    ``max(outlier_distance, outlier_edge_factor * edge)``, ``edge`` the mean edge length of the finer of the two
    meshes (:func:`_finer_edge`). A correct fit of coarse meshes leaves gaps of a few edges (a chord across a curved
    part, a limb two edges thick meshed differently in each frame), which a fixed fraction of the diagonal calls a
    failure: on the demo at resolution 16 (edges of 0.053 of the diagonal), up to 9.8 % of the target beyond 2 % of the
    diagonal, 0.85 % beyond 3 edges, none beyond 4; and 10-14 % of the source's vertices beyond 2 % in 7 of 40 draws
    whose ground-truth error was that of the others (docs/registration.md, "Known failure" and "Coarse meshes").
    """
    return max(opts.outlier_distance, opts.outlier_edge_factor * edge)


def _finer_edge(source: Mesh, target: Mesh) -> float:
    """The mean edge length of the finer of the two meshes: the resolution of the pair (``h``).

    The finer one, so that a coarse mesh with exact flat faces (a box) or a simplified source does not coarsen what is
    judged on a fine one.
    """
    return min(_mean_edge_length(source), _mean_edge_length(target))


def _mean_edge_length(mesh: Mesh) -> float:
    """Mean length of the faces' edges (an interior edge counted once per face; 0 without faces).

    An exactly rounded sum (``math.fsum``): it sets the graph's node spacing on coarse meshes, which must not depend on
    the thread count (a torch sum is split by thread) or the CPU.
    """
    if mesh.num_faces == 0:
        return 0.0
    corners = mesh.verts[mesh.faces]
    lengths = (corners - corners.roll(1, dims=1)).norm(dim=-1)
    return math.fsum(lengths.double().flatten().tolist()) / lengths.numel()


class _Frame(NamedTuple):
    """Both meshes in the registration's frame (the target's bounding-box centre at 0, its diagonal 1).

    ``source`` and ``target`` keep only their faces with a normal (:meth:`~torchmeshmetric.Mesh.surface_face_mask`),
    welded (:func:`welded_faces`): a zero-area face lies on the edges of others, and a closest point on it ties with
    one on them, where its rounding-noise normal would decide the match's plane and weight by the input's last bits;
    a seam of duplicate vertices would make the interpolated normal jump where two faces tie.
    """

    center: Tensor
    diag: Tensor
    source: Mesh  # after the rigid stage, faces with a normal only
    target: Mesh  # faces with a normal only
    rigid: RigidRegistration
    faces: Tensor  # every source face (the registered mesh's)
    target_all_faces: Tensor  # every target face, welded: where the target samples are drawn
    unit: float  # the exact power of two the input was multiplied by (validate_pair); 1.0 for none


def _normalise(
    source: MeshLike,
    target: MeshLike,
    opts: NonRigidOptions,
    device: torch.device | str | None,
    gen: torch.Generator,
    timings: dict[str, float],
) -> _Frame:
    """Validate both meshes, run the rigid stage (or not) and move both into the normalised frame."""
    src, tgt, unit = validate_pair(source, target)
    if device is not None:
        src, tgt = src.to(device=device), tgt.to(device=device)
    center, diag = normalisation(tgt)
    t0 = time.perf_counter()
    if opts.rigid_init:
        rigid = register_rigid(src, tgt, generator=gen, sampling=opts.sampling, **(opts.rigid_options or {}))
        moved = rigid.verts
    else:
        rigid = _identity_rigid(src.verts)
        moved = src.verts
    timings["rigid"] = time.perf_counter() - t0
    # The faces with a normal and the welding are decided on the input frames (not on the rigid motion's rounding).
    source_faces = welded_faces(src.verts, src.faces[src.surface_face_mask()])
    target_faces = welded_faces(tgt.verts, tgt.faces[tgt.surface_face_mask()])
    source_n = Mesh((moved - center) / diag, source_faces, validate=False)
    target_n = Mesh((tgt.verts - center) / diag, target_faces, validate=False)
    return _Frame(center, diag, source_n, target_n, rigid, src.faces, welded_faces(tgt.verts, tgt.faces), unit)


class _Terms(NamedTuple):
    """The correspondences of one refresh: for the fused energy, and for its torch formulation."""

    energy: EnergyTerms
    need: Tensor  # (I,) source vertices the energies touch
    surf_loc: Tensor  # (S,) rows of `need` of the data points
    faces_loc: Tensor  # (Q, 3) rows of `need` of the corners of the faces matched by the target samples
    forward: Correspondences  # data points -> target faces
    reverse: Correspondences | None  # target samples -> rows of `faces_loc`
    fused: FusedStep | None  # the energy laid out for the C++ pass (CPU), else None (torch formulation)


class _TargetSamples(NamedTuple):
    """The reverse term's target samples (:func:`_target_samples`)."""

    points: Tensor  # (Q, 3)
    face_idx: Tensor  # (Q,) int64 rows of the faces they were drawn on
    weights: Tensor  # (Q,) their faces' areas over the mean face area


def _target_samples(verts: Tensor, faces: Tensor, n: int, generator: torch.Generator) -> _TargetSamples:
    """``n`` points on the surface ``(verts, faces)``: faces drawn by index, a uniform point in each, area weights.

    The faces are a random permutation of the face indices (repeated when ``n`` exceeds the face count, so every face
    gets ``n // F`` or ``n // F + 1`` samples); each point is placed with the square-root barycentric map (uniform on
    its triangle) and weighted by its face's area over the mean face area. A weighted sum
    ``sum_k w_k g(s_k)`` then has the expectation ``n / A * integral of g`` (``A`` the total area), the same as an
    unweighted sum over area-proportional draws (:func:`~torchmeshmetric.kernels.sampling.sample_surface`).

    Not :func:`~torchmeshmetric.kernels.sampling.sample_surface`, whose inverse CDF over the faces' areas is what the
    metrics and the MPEG samplers need (it equals mmetric): a rounding of the input moves the CDF's steps, and a draw
    between the old and the new step goes to the next face *in the list*, which on captured frames (faces in any
    order) is anywhere (under float32 rounding of captured-like frames a sample jumped by 0.26 to 0.46 of the
    diagonal; docs/registration.md, "Stability", item 8). Here which face a draw takes depends on the face count and
    the generator only; the input moves the points and the weights continuously, and a face that rounding makes
    degenerate keeps its samples at weight ~0 (an exactly degenerate one at 0) instead of renumbering the others.

    Args:
        verts: ``(V, 3)`` vertices.
        faces: ``(F, 3)`` faces (``F >= 1``, positive total area).
        n: number of samples (``>= 0``).
        generator: CPU generator of the draws.

    Returns:
        :class:`_TargetSamples` on the device of ``verts``.
    """
    num_faces = faces.shape[0]
    with torch.no_grad():
        perms = [torch.randperm(num_faces, generator=generator) for _ in range(-(-n // num_faces))]
        face_idx = torch.cat(perms)[:n].to(verts.device) if perms else faces.new_zeros(0)
        r = torch.rand(n, 2, dtype=verts.dtype, generator=generator).to(verts.device)
        s1 = r[:, 0].sqrt()
        bary = torch.stack([1 - s1, s1 * (1 - r[:, 1]), s1 * r[:, 1]], dim=-1)
        points = (bary[:, :, None] * verts[faces[face_idx]]).sum(1)
        area = Mesh(verts, faces, validate=False).face_areas()
        # The mean area as an exactly rounded sum: torch's sum splits a long reduction by thread (the weights then
        # differed in the last bit between 1 and 2 threads, and with them every registration of > 32k faces);
        # fsum's is the same for any thread count, order and CPU.
        mean = math.fsum(area.tolist()) / num_faces
        weights = area[face_idx] / max(mean, torch.finfo(verts.dtype).tiny)
    return _TargetSamples(points, face_idx, weights)


def _face_centroids(verts: Tensor, faces: Tensor) -> Tensor:
    """``(F, 3)`` face centroids, each the sum of its corners in coordinate order.

    The same bits for any rotation of the corners (a sum in stored corner order differs in the last bit).
    """
    c = verts[faces]  # (F, 3, 3)
    # The corners sorted by x, then y, then z: stable sorts by the least significant key first.
    for j in (2, 1, 0):
        idx = c[..., j].argsort(dim=1, stable=True)
        c = c.gather(1, idx[..., None].expand(-1, -1, 3))
    return (c[:, 0] + c[:, 1] + c[:, 2]) / 3


def _canonical_target_samples(verts: Tensor, faces: Tensor, n: int, dense: bool) -> _TargetSamples:
    """The reverse term's target samples without random draws (``NonRigidOptions.sampling``).

    ``faces`` are the target's faces with a normal (welded). ``dense``, or ``n`` at least the face count: one sample
    at every face's centroid, weighted by its area over the mean area (a midpoint quadrature of the surface).
    Otherwise ``n`` face centroids chosen by farthest-point sampling
    (:func:`~torchmeshmetric.registration.deformation_graph.canonical_farthest_points`), weight 1: their spacing is
    about uniform, so each stands for about the same area. Every centroid at weight 1 would weigh a small face as a
    large one (review N: on the 828-912-face res-24 demo frames the residual's RMSE rose from 0.0044 to 0.0056).
    """
    with torch.no_grad():
        centroids = _face_centroids(verts, faces)
        area = Mesh(verts, faces, validate=False).face_areas()
        if dense or n >= faces.shape[0]:
            order = _coordinate_order(centroids)
            mean = math.fsum(area.tolist()) / max(faces.shape[0], 1)
            return _TargetSamples(centroids[order], order, area[order] / max(mean, torch.finfo(verts.dtype).tiny))
        chosen = canonical_farthest_points(centroids, n, math.fsum(area.tolist()))
        return _TargetSamples(centroids[chosen], chosen, verts.new_ones(chosen.shape[0]))


class _Fit:
    """The deformation graph being fitted, and what every stage reuses.

    Built once: the graph, the data points (a random subset of the source's surface vertices), the target samples
    of the reverse term with their normals, the target's index (queried at every refresh) and face normals. The
    deformed source's index is built at the first refresh and refitted to the deformed vertices afterwards (same
    faces), never rebuilt.
    """

    def __init__(
        self, frame: _Frame, opts: NonRigidOptions, gen: torch.Generator, backend: str, timings: dict[str, float]
    ) -> None:
        t0 = time.perf_counter()
        src, tgt = frame.source, frame.target
        dev = src.device
        self.frame, self.opts, self.backend, self.timings = frame, opts, backend, timings
        self.edge = _finer_edge(src, tgt)
        # Never finer than the meshes: at 0.03 of the diagonal a ~400-vertex mesh gets a node for every two vertices,
        # which fits each frame's chords rather than the motion (see NonRigidOptions.node_edge_factor). The data terms
        # are in units of this spacing (self.graph.node_spacing), as the regularisation's edges.
        spacing = max(opts.node_spacing, opts.node_edge_factor * self.edge)
        # Node candidates from every source face, not only those with a normal (see DeformationGraph).
        canonical = opts.sampling != "index"
        self.graph = DeformationGraph(
            src.verts, frame.faces, node_spacing=spacing, num_neighbors=opts.num_neighbors, canonical=canonical
        ).to(dev)
        # The data points and the target samples are drawn over every vertex and every face, not over the surface
        # ones only: a rounding of the input that makes a face degenerate (6 decimals did on 2 of the demo's 40k faces)
        # would otherwise renumber the surface list, and the same random draws would pick other vertices and faces
        # everywhere (the residual's average moved by 6 %, its max by 34 %; docs/statistics.md). Drawn over all of
        # them, such a face only loses its own share (its samples' area weights, ~0; see _target_samples).
        used = src.surface_vertex_mask()
        surf = used.nonzero()[:, 0]
        if opts.sampling == "dense":
            surf = surf[_coordinate_order(src.verts[surf])]
        elif opts.sampling == "canonical":
            area = math.fsum(src.face_areas().double().tolist())
            surf = surf[canonical_farthest_points(src.verts[surf], opts.num_points, area)]
        elif surf.numel() > opts.num_points:
            perm = torch.randperm(src.num_verts, generator=gen).to(dev)
            surf = perm[used[perm]][: opts.num_points]
        self.surf = surf
        self.samples: Tensor | None = None
        self.sample_normals = tgt.verts[:0]
        self.sample_weights = tgt.verts.new_zeros(0)  # area weights, mean 1 over the faces (see _target_samples)
        if opts.num_target_samples > 0 and opts.sampling != "index":
            drawn = _canonical_target_samples(tgt.verts, tgt.faces, opts.num_target_samples, opts.sampling == "dense")
            self.samples, self.sample_weights = drawn.points, drawn.weights
            self.sample_normals = tgt.face_normals()[drawn.face_idx]
        elif opts.num_target_samples > 0:
            whole = Mesh(tgt.verts, frame.target_all_faces, validate=False)
            drawn = _target_samples(whole.verts, whole.faces, opts.num_target_samples, gen)
            self.samples, self.sample_weights = drawn.points, drawn.weights
            self.sample_normals = whole.face_normals()[drawn.face_idx]
        timings["graph"] = time.perf_counter() - t0
        packed = PackedMeshes(tgt.verts, tgt.faces, _lengths(tgt.verts), _lengths(tgt.faces))
        self.target_index = MeshIndex.from_packed(packed, backend, DEFAULT_MAX_MEMORY)
        self.source_index: MeshIndex | None = None
        # On the CPU, the C++ passes: each refresh's deformed source with the vertex normals of the data points, and
        # each step's fused energy (the same values as the torch formulation's kernels, tested).
        self.ops = registration_ops() if dev.type == "cpu" else None
        if self.ops is not None:
            g = self.graph
            self._skinning = [t.contiguous() for t in (g.nodes, g.verts, g.vert_nodes, g.vert_weights)]
            self._faces = src.faces.contiguous()
            self._incident = self.ops.incident_faces(self._faces, src.num_verts)
            self._all_verts = torch.arange(src.num_verts, device=dev)
        # Adam's step is lr * m / (sqrt(v) + eps): about lr in every coordinate whatever the gradient's size, so at
        # a stationary point (e.g. an exact pair, whose gradient is rounding noise) it would move the parameters by
        # lr instead of not at all; a stage stops where every gradient component is below sqrt(eps) of the dtype
        # (the loss is in units of the node spacing squared: residuals of ~1e-10 of the diagonal).
        self.stationary_tol = math.sqrt(torch.finfo(src.dtype).eps)
        self.last_good = _parameters(self.graph)
        self.history: list[float] = []
        self.first_loss: float | None = None
        self.stationary = False
        self.refresh_losses: list[float] = []
        self.last_stage: Stage | None = None
        self.last_terms: _Terms | None = None
        self.reason = ""

    def run_stage(self, stage: Stage) -> None:
        """Adam steps of one stage, at a step size annealed from ``lr0`` to ``lr0 * stage.lr_decay``.

        ``lr0`` is ``stage.lr``, or the data points' RMS residual at the stage's start where that is smaller.

        Ends on the stage's last iterate (or sets ``reason`` when it diverges). Correspondences are refreshed every
        ``correspondence_every`` steps. The step count is fixed: a stage stops early only at a stationary point (every
        gradient component below ``sqrt(eps)`` of the dtype, where Adam would turn rounding noise into lr-sized
        steps), so no threshold on a noisy quantity decides which iterate is returned.
        """
        every = self.opts.correspondence_every
        opt = Adam(self.graph.parameters(), lr=stage.lr)
        self.stationary, self.refresh_losses, self.last_stage, self.last_terms = False, [], stage, None
        # Geometric annealing: Adam moves every parameter by about the step size whatever the gradient's size, so at a
        # constant step size it never settles (it ends at a noise floor of ~lr, where one ulp of input flips the
        # sign of a near-zero gradient and so the step); annealed, it ends within ~lr * lr_decay of the minimum.
        decay = stage.lr_decay ** (1.0 / max(stage.max_steps - 1, 1))
        terms: _Terms | None = None
        for step in range(stage.max_steps):
            if step % every == 0:
                terms = self._refresh(stage)
                if step == 0:
                    # A stage's step size is at most the weighted RMS residual of its data points at its start (in
                    # diagonals, as the translations): Adam moves every parameter by ~lr per step, so a pair already
                    # within r of its target would otherwise drift by the stage's lr in directions the energy barely
                    # sees (sliding along the surface). Continuous in the input, unlike returning a best iterate.
                    lr0 = min(stage.lr, _weighted_rms(terms.forward))
            assert terms is not None
            value, grad_max = self._evaluate(stage, terms, gradient=True)
            if self.first_loss is None:
                # The loss is in units of (node spacing)^2: a floor of 1 (a residual of one node spacing) keeps an
                # exact start (loss ~1e-30) from calling rounding noise a divergence.
                self.first_loss = max(value, 1.0)
            if not math.isfinite(value) or value > 1e6 * self.first_loss:
                self._diverged(f"diverged: loss became {value:.3g} (first loss {self.first_loss:.3g})")
                return
            self.history.append(value)
            if not math.isfinite(grad_max):
                self._diverged("diverged: non-finite gradient")
                return
            if step == 0:
                # Adam's first steps are ~lr * sign(g) per component: one whose gradient is near zero would move by
                # the step size in a direction set by the input's last bits (1e-9 of input moved the demo pair's
                # registration by 3.6e-5 of the diagonal). An eps relative to the stage's largest gradient component
                # keeps such components' steps proportional to their gradient (docs/registration.md, "Stability").
                opt.eps = max(ADAM_EPS, self.opts.adam_eps * grad_max)
            if step % every == 0:
                self.last_good = _parameters(self.graph)
                self.refresh_losses.append(value)
                self.last_terms = terms
            if grad_max <= self.stationary_tol:
                self.stationary = True
                break  # the gradient is rounding noise: Adam would turn it into lr-sized steps
            opt.lr = lr0 * decay**step
            opt.step()

    def convergence(self) -> str:
        """Why the fit is not converged (empty when it is): the stated criterion on the last stage's last window.

        Converged: the last stage stopped at a stationary point, or over its last window (from its last correspondence
        refresh to its end) the loss on that refresh's correspondences changed by at most ``tolerance`` times its final
        value (or times the loss of residuals of 1e-5 of the diagonal, when larger). Relative to the final loss, not
        to the stage's first: a stage's loss falls fastest at its start, so a window that still removes 1-2 % of the
        loss (a schedule cut after a stage that anneals to half its rate) is small against the first loss.

        On that window's correspondences, not on new ones refreshed at the end: a refresh moves the loss by jumps (a
        closest point crossing a crease, a sample crossing a rejection threshold), and on coarse meshes those jumps
        alone reached 5e-4 to 9e-4 of the loss on fits that were over (docs/registration.md, "Convergence"), so the
        old criterion, which included one, reported 10-30 % of converged coarse fits as not converged. This only
        reports; it decides no iterate.
        """
        h = self.refresh_losses
        if self.last_stage is None or self.last_terms is None:
            return ""
        unfitted = self._unfitted(self.last_stage, self.last_terms)
        if unfitted or self.stationary or not h:
            return unfitted
        final, _ = self._evaluate(self.last_stage, self.last_terms, gradient=False)
        # Below the loss of residuals of 1e-5 of the diagonal (in node spacings) the fit is as good as exact, and a
        # relative change of its tiny loss is rounding (a 1e-5 stretch ends at a loss of 7e-11, changing by 2e-13).
        floor = (1e-5 / self.graph.node_spacing) ** 2
        change = abs(final - h[-1]) / max(abs(final), floor)
        if change <= self.opts.tolerance:
            return ""
        return (
            f"not converged: the loss changed by {change:.2g} of itself over the last stage's last window (between its "
            f"last correspondence refresh and its end), more than tolerance={self.opts.tolerance:g}; give the last "
            f"stage more steps or a stronger lr_decay"
        )

    def _unfitted(self, stage: Stage, terms: _Terms) -> str:
        """Why the last stage fitted no data (empty when it did): a stop the convergence criterion would pass.

        Both cases leave the graph where its regularisation alone holds it, usually the rigid start, with a loss that
        does not change: the criterion (and a stationary stop) read that as converged. Every match rejected (a
        ``max_distance`` or ``max_normal_angle`` smaller than the residuals) leaves no data term; a stationary stop
        with the data points' residuals beyond ``robust_scale`` is the Geman-McClure term's flat tail, whose gradient
        vanishes (an exact pair stops stationary too, at residuals far below it).
        """
        reverse = terms.reverse
        accepted = float(terms.forward.weights.sum()) + (0.0 if reverse is None else float(reverse.weights.sum()))
        if not accepted > 0:
            return (
                "not fitted: every correspondence of the last stage was rejected (farther than its max_distance "
                f"{stage.max_distance:g} or normals farther apart than its max_normal_angle "
                f"{stage.max_normal_angle:g}); the deformation follows the regularisation alone"
            )
        rms = _weighted_rms(terms.forward)
        if self.stationary and rms > stage.robust_scale:
            return (
                f"not fitted: the last stage stopped where the gradient vanishes, with its data points at an RMS "
                f"residual of {rms:.3g} of the diagonal, beyond its robust_scale {stage.robust_scale:g} (where the "
                "Geman-McClure term is flat)"
            )
        return ""

    def _diverged(self, reason: str) -> None:
        self.reason = reason
        _load_parameters(self.graph, self.last_good)

    def _source_index(self, deformed: Tensor) -> MeshIndex:
        faces = self.frame.source.faces
        if self.source_index is None:
            packed = PackedMeshes(deformed, faces, _lengths(deformed), _lengths(faces))
            self.source_index = MeshIndex.from_packed(packed, self.backend, DEFAULT_MAX_MEMORY)
        else:
            self.source_index.refit_unchecked(deformed)
        return self.source_index

    def _refresh(self, stage: Stage) -> _Terms:
        """New correspondences at the current deformation (forward, and reverse when there are target samples)."""
        t0 = time.perf_counter()
        tgt, sf, surf = self.frame.target, self.frame.source.faces, self.surf
        with torch.no_grad():
            if self.ops is not None:
                g = self.graph
                dv, source_normals = self.ops.deform_normals(
                    g.rotations.detach(), g.translations.detach(), *self._skinning, self._faces, *self._incident,
                    self._all_verts,
                )  # fmt: skip
            else:
                deformed = Mesh(deformed_vertices(self.graph), sf, validate=False)
                dv, source_normals = deformed.verts, deformed.vertex_normals()
            thresholds = {"max_distance": stage.max_distance, "max_normal_angle": stage.max_normal_angle}
            forward = find_correspondences(
                dv.index_select(0, surf), source_normals.index_select(0, surf), tgt.verts, tgt.faces,
                index=self.target_index, vertex_normals=tgt.vertex_normals(), **thresholds,
            )  # fmt: skip
            reverse = None
            if self.samples is not None:
                reverse = find_correspondences(
                    self.samples, self.sample_normals, dv, sf, index=self._source_index(dv),
                    vertex_normals=source_normals, **thresholds,
                )  # fmt: skip
                # Each sample counts with its face's area (drawn by face index, not by area): the torch formulation
                # and the fused C++ pass both take the product as the sample's weight.
                reverse = reverse._replace(weights=reverse.weights * self.sample_weights)
        self.timings["correspondences"] += time.perf_counter() - t0
        return self._terms(forward, reverse)

    def _terms(self, forward: Correspondences, reverse: Correspondences | None) -> _Terms:
        """Lay out one refresh's correspondences for the energies, indexed by the vertices they touch.

        Only the data points and the vertices of the faces matched by target samples enter the data terms: just those
        are deformed (forward and backward then scale with them, not with all vertices).
        """
        graph, tgt, sf, surf = self.graph, self.frame.target, self.frame.source.faces, self.surf
        samples = self.samples if reverse is not None and self.samples is not None else tgt.verts[:0]
        rev_weights = reverse.weights if reverse is not None else tgt.verts.new_zeros(0)
        rev_faces_idx = reverse.face_idx if reverse is not None else sf.new_zeros(0)
        rev_bary = reverse.bary if reverse is not None else tgt.verts.new_zeros(0, 3)
        rev_normals = reverse.normals if reverse is not None else tgt.verts.new_zeros(0, 3)
        if self.ops is not None:
            nodes, verts, vert_nodes, vert_weights = self._skinning
            out = self.ops.energy_terms(
                surf, rev_faces_idx, self._faces, verts, vert_nodes, vert_weights, forward.weights, rev_weights, nodes,
                graph.edges,
            )  # fmt: skip
            need, rest, vidx, vw, surf_loc, faces_loc = out[:6]
            energy = EnergyTerms(
                rest, vidx, vw, surf_loc, forward.closest.contiguous(), forward.normals.contiguous(), forward.weights,
                samples, faces_loc, rev_weights, rev_bary.contiguous(), rev_normals.contiguous(),
            )  # fmt: skip
            fused: FusedStep | None = FusedStep(graph, energy, self.ops, out[6:])
        else:
            rev_faces = sf[rev_faces_idx]
            need, inv = torch.cat([surf, rev_faces.reshape(-1)]).unique(return_inverse=True)
            surf_loc, faces_loc = inv[: surf.numel()], inv[surf.numel() :].view(-1, 3)
            energy = EnergyTerms(
                graph.verts[need], graph.vert_nodes[need], graph.vert_weights[need], surf_loc, forward.closest,
                forward.normals, forward.weights, samples, faces_loc, rev_weights, rev_bary, rev_normals,
            )  # fmt: skip
            fused = None
        if reverse is not None:
            reverse = reverse._replace(face_idx=torch.arange(faces_loc.shape[0], device=sf.device))
        return _Terms(energy, need, surf_loc, faces_loc, forward, reverse, fused)

    def _evaluate(self, stage: Stage, terms: _Terms, *, gradient: bool) -> tuple[float, float]:
        """``(loss, max |gradient component|)`` of the stage's energy at the current deformation.

        With ``gradient``, the parameters' ``.grad`` hold the gradient (for Adam); without, the second value is NaN
        off the CPU. Data terms are in units of the node spacing, so a regularisation weight of 1 trades an edge
        residual of one spacing against a data residual of one spacing.
        """
        opts, graph = self.opts, self.graph
        weights = {"plane_weight": opts.plane_weight, "point_weight": opts.point_weight}
        data_scale = 1.0 / (self.graph.node_spacing * self.graph.node_spacing)
        if terms.fused is not None:
            scalars = [stage.robust_scale, opts.plane_weight, opts.point_weight, opts.reverse_weight, data_scale,
                       stage.regularization]  # fmt: skip
            loss_t, g_rot, g_tr, grad_max = terms.fused(graph.rotations, graph.translations, scalars)
            if gradient:
                graph.rotations.grad, graph.translations.grad = g_rot, g_tr
            return float(loss_t), float(grad_max)
        # No C++ extension for this device: the same energy in torch ops, differentiated by autograd.
        graph.zero_grad(set_to_none=True)
        with torch.set_grad_enabled(gradient):
            dsub = graph.deform_vertices(terms.need)
            loss = data_term(dsub[terms.surf_loc], terms.forward, sigma=stage.robust_scale, **weights)
            if terms.reverse is not None and self.samples is not None and opts.reverse_weight:
                loss = loss + opts.reverse_weight * reverse_term(
                    self.samples, dsub, terms.faces_loc, terms.reverse, sigma=stage.robust_scale, **weights
                )
            loss = loss / (self.graph.node_spacing * self.graph.node_spacing)
            loss = loss + stage.regularization * embedded_deformation_regularizer(graph)
        value = float(loss.detach())
        if not gradient:
            return value, math.nan
        loss.backward()
        # One reduction for both checks: NaN propagates through max.
        grads = [p.grad.abs().max() for p in graph.parameters() if p.grad is not None]
        return value, float(torch.stack(grads).max())

    def plausibility(self) -> tuple[Tensor, Tensor, str]:
        """``(verts (V, 3), residual (V,), reason)`` of the fit as it stands.

        The registered source in the target's coordinates, each vertex's exact distance to the target, and why the
        fit is implausible (empty when it is not): more than ``max_outlier_fraction`` of the source's surface
        vertices farther than the outlier reach (:func:`_outlier_reach`) from the target, or more than
        ``max_uncovered_fraction`` of the target samples farther than it from the registered source: a part of the
        target left uncovered, the footprint of a limb registered onto another limb.
        """
        opts, frame = self.opts, self.frame
        dtype = frame.source.dtype
        reach = _outlier_reach(self.edge, opts)
        with torch.no_grad():
            dv = deformed_vertices(self.graph)
            verts = dv * frame.diag + frame.center
            residual_n = self.target_index.point_mesh_distance_unchecked(dv, _lengths(dv)).dists
            used = frame.source.surface_vertex_mask()
            frac_src = float((residual_n[used] > reach).to(dtype).mean())
            frac_tgt = 0.0
            if self.samples is not None and self.source_index is not None:
                self.source_index.refit_unchecked(dv)
                far = self.source_index.point_mesh_distance_unchecked(self.samples, _lengths(self.samples)).dists
                # Area-weighted: the fraction of the target's area, as the samples are drawn by face, not by area.
                w = self.sample_weights
                far_w = (w * (far > reach).to(dtype)).sum()
                frac_tgt = float(far_w / w.sum().clamp_min(torch.finfo(dtype).tiny))
        reasons = []
        if frac_src > opts.max_outlier_fraction:
            reasons.append(
                f"{100 * frac_src:.1f}% of source vertices are farther than {100 * reach:.1f}% of the "
                f"diagonal from the target (allowed {100 * opts.max_outlier_fraction:.1f}%)"
            )
        if frac_tgt > opts.max_uncovered_fraction:
            reasons.append(
                f"{100 * frac_tgt:.1f}% of target samples are farther than {100 * reach:.1f}% of the diagonal from the "
                f"registered source (allowed {100 * opts.max_uncovered_fraction:.1f}%): a target part is left uncovered"
            )
        reason = "implausible fit: " + "; ".join(reasons) if reasons else ""
        return verts, residual_n * frame.diag, reason
