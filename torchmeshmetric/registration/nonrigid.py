"""Non-rigid registration loop: rigid ICP, then an embedded deformation graph fitted with Adam, coarse to fine.

The model (:class:`~torchmeshmetric.registration.DeformationGraph`) and the energies
(:mod:`torchmeshmetric.registration.energies`) are separate from this loop, which only schedules them:

1. normalise both meshes to the target's bounding-box centre and unit diagonal (every threshold below is a
   fraction of the diagonal);
2. optional rigid ICP (:func:`~torchmeshmetric.registration.register_rigid`);
3. for each :class:`Stage` (regularisation, robust scale and rejection thresholds decreasing): Adam steps on the
   graph's rotations and translations; correspondences (source vertices → target faces, target samples → deformed
   source faces) are refreshed every ``correspondence_every`` steps, not every step; the stage ends after
   ``max_steps``, when the loss changes by less than ``tolerance`` (relative) between two refreshes, or at a
   stationary point (every gradient component below ``sqrt(eps)`` of the dtype); each
   stage then keeps its **best iterate**: the parameters of the lowest loss measured right after a correspondence
   refresh (the stage's last iterate gets one more refresh to compete). Adam moves every parameter by about the
   learning rate whatever the gradient's size, so without this an exact pair drifted by 1e-3 of the diagonal
   and a near-exact one ended at Adam's noise floor instead of where it started;
4. divergence (NaN/Inf or a loss that explodes) restores the last good parameters and reports failure; a fit
   whose residuals stay large is reported as not converged too, with the reason, and a warning.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Sequence
from typing import Any, NamedTuple

import torch
from torch import Tensor

from torchmeshmetric.kernels._common import DEFAULT_MAX_MEMORY
from torchmeshmetric.kernels.mesh_index import MeshIndex
from torchmeshmetric.kernels.sampling import sample_surface
from torchmeshmetric.registration._common import (
    face_unit_normals,
    normalisation,
    referenced_mask,
    unit_normals,
    validate_pair,
)
from torchmeshmetric.registration.deformation_graph import DeformationGraph
from torchmeshmetric.registration.energies import (
    Correspondences,
    EnergyTerms,
    deformed_vertices,
    embedded_deformation_regularizer,
    find_correspondences,
    fused_energy,
    surface_term,
)
from torchmeshmetric.registration.rigid import RigidRegistration, register_rigid
from torchmeshmetric.structures import Mesh, MeshLike, PackedMeshes

__all__ = ["DEFAULT_SCHEDULE", "NonRigidRegistration", "RegistrationWarning", "Stage", "register_nonrigid"]


class RegistrationWarning(UserWarning):
    """Emitted when a registration fails (diverged, or the fit is implausible)."""


class Stage(NamedTuple):
    """One stage of the coarse-to-fine schedule (distances are fractions of the bounding-box diagonal).

    Attributes:
        regularization: weight of the embedded-deformation prior.
        robust_scale: Geman-McClure scale ``sigma``.
        max_distance: correspondences farther than this are rejected.
        max_normal_angle: correspondences whose normals differ by more (degrees) are rejected.
        lr: Adam learning rate (radians for rotations, diagonals for translations).
        max_steps: Adam steps at most.
    """

    regularization: float
    robust_scale: float
    max_distance: float
    max_normal_angle: float
    lr: float
    max_steps: int


DEFAULT_SCHEDULE: tuple[Stage, ...] = (
    Stage(regularization=10.0, robust_scale=0.10, max_distance=0.30, max_normal_angle=80.0, lr=1e-2, max_steps=120),
    Stage(regularization=1.0, robust_scale=0.05, max_distance=0.15, max_normal_angle=60.0, lr=5e-3, max_steps=50),
    Stage(regularization=0.1, robust_scale=0.02, max_distance=0.08, max_normal_angle=50.0, lr=2e-3, max_steps=50),
    Stage(regularization=0.02, robust_scale=0.01, max_distance=0.05, max_normal_angle=45.0, lr=1e-3, max_steps=40),
)
"""The default coarse-to-fine schedule: regularisation, robust scale, rejection thresholds and step size decrease.

Stage lengths 120/50/50/40 steps (was 120 each): at ~17k vertices the ground-truth error barely moves
(docs/registration.md) while the Adam steps, the dominant cost, drop by ~40 %. Each stage returns its best iterate
and stops at a stationary point, so an exact or near-exact pair is not moved by Adam's lr-sized steps."""


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


def _lengths(x: Tensor) -> Tensor:
    return torch.tensor([x.shape[0]], device=x.device)


# Adam's step on the CPU as one fused kernel per parameter list (same update rule; fewer small ops per step).
_ADAM_OPTIONS: dict[str, Any] = {"foreach": False, "fused": True}


def register_nonrigid(
    source: MeshLike,
    target: MeshLike,
    *,
    rigid_init: bool = True,
    device: torch.device | str | None = None,
    node_spacing: float = 0.03,
    num_neighbors: int = 4,
    num_points: int = 2000,
    num_target_samples: int = 2000,
    correspondence_every: int = 10,
    schedule: Sequence[Stage] = DEFAULT_SCHEDULE,
    plane_weight: float = 1.0,
    point_weight: float = 0.1,
    reverse_weight: float = 1.0,
    tolerance: float = 1e-3,
    max_outlier_fraction: float = 0.1,
    outlier_distance: float = 0.02,
    rigid_options: dict[str, Any] | None = None,
    generator: torch.Generator | None = None,
    warn: bool = True,
    backend: str = "auto",
    num_threads: int | None = 1,
) -> NonRigidRegistration:
    """Register ``source`` (frame k-1) non-rigidly onto ``target`` (frame k), keeping the source's topology.

    Works on frames as they come out of capture — duplicate and unreferenced vertices, zero-length edges,
    zero-area faces — without cleaning: nodes and data points come from vertices of positive-area faces only,
    unreferenced vertices still move with the graph's skinning, zero-area faces carry no normal so they skip the
    point-to-plane term, and the closest-point kernel is exact on degenerate triangles.

    Args:
        source: mesh to deform (frame k-1).
        target: mesh to reach (frame k).
        rigid_init: run rigid ICP first.
        device: device to compute on (default: the source's device); results live there.
        node_spacing: deformation-graph node spacing, fraction of the diagonal.
        num_neighbors: nodes per vertex.
        num_points: source vertices (random subset of the surface vertices) in the data term.
        num_target_samples: target surface samples in the reverse term (target → deformed source).
        correspondence_every: Adam steps between two correspondence refreshes.
        schedule: coarse-to-fine stages (see :data:`DEFAULT_SCHEDULE`).
        plane_weight: weight of the point-to-plane part of the data term.
        point_weight: weight of the point-to-point part of the data term.
        reverse_weight: weight of the reverse term.
        tolerance: relative loss change between refreshes below which a stage stops.
        max_outlier_fraction: the fit is reported as failed when more than this fraction of surface vertices, or
            of target samples, lies farther than ``outlier_distance`` from the other mesh.
        outlier_distance: see ``max_outlier_fraction`` (fraction of the diagonal).
        rigid_options: keyword arguments for :func:`register_rigid` (default: point-to-plane).
        generator: optional CPU ``torch.Generator`` for sampling (reproducible runs).
        warn: emit a :class:`RegistrationWarning` when the registration fails.
        backend: selection backend of the closest-face searches (see :func:`~torchmeshmetric.point_mesh_distance`).
        num_threads: torch intra-op threads while registering (restored afterwards; process-wide, like
            ``torch.set_num_threads``). Default 1: the loop is ~1 ms steps of small operations whose parallel regions
            cost more than they save, and on a loaded machine wait for descheduled threads (docs/registration.md:
            0.96 s of CPU on one thread; 47 s wall with two threads on an oversubscribed machine). ``None``: keep
            torch's setting.

    Returns:
        :class:`NonRigidRegistration`.

    Raises:
        ShapeError, DTypeError, NonFiniteError, IndexRangeError, DeviceError, EmptyInputError: on bad meshes.
        ValueError: on a bad option.

    Example:
        >>> import torch, trimesh
        >>> src = trimesh.creation.icosphere(subdivisions=2)
        >>> tgt = trimesh.creation.icosphere(subdivisions=3)
        >>> tgt.vertices *= [1.1, 1.0, 0.9]
        >>> r = register_nonrigid(src, tgt, schedule=DEFAULT_SCHEDULE[:2], generator=torch.Generator().manual_seed(0))
        >>> r.converged, bool(r.residual.max() < 0.02)
        (True, True)
    """
    if correspondence_every < 1:
        raise ValueError(f"correspondence_every: expected a positive int, found {correspondence_every}")
    if not schedule:
        raise ValueError("schedule: expected at least one stage, found none")
    if num_points < 1 or num_target_samples < 0:
        raise ValueError(f"num_points/num_target_samples: expected positive counts, found {num_points}, "
                         f"{num_target_samples}")  # fmt: skip
    if num_threads is not None and num_threads < 1:
        raise ValueError(f"num_threads: expected a positive int or None, found {num_threads}")
    previous_threads = torch.get_num_threads()
    if num_threads is not None and num_threads != previous_threads:
        torch.set_num_threads(num_threads)
    try:
        return _register_nonrigid(
            source, target, rigid_init=rigid_init, device=device, node_spacing=node_spacing,
            num_neighbors=num_neighbors, num_points=num_points, num_target_samples=num_target_samples,
            correspondence_every=correspondence_every, schedule=schedule, plane_weight=plane_weight,
            point_weight=point_weight, reverse_weight=reverse_weight, tolerance=tolerance,
            max_outlier_fraction=max_outlier_fraction, outlier_distance=outlier_distance, rigid_options=rigid_options,
            generator=generator, warn=warn, backend=backend,
        )  # fmt: skip
    finally:
        if torch.get_num_threads() != previous_threads:
            torch.set_num_threads(previous_threads)


def _register_nonrigid(
    source: MeshLike,
    target: MeshLike,
    *,
    rigid_init: bool,
    device: torch.device | str | None,
    node_spacing: float,
    num_neighbors: int,
    num_points: int,
    num_target_samples: int,
    correspondence_every: int,
    schedule: Sequence[Stage],
    plane_weight: float,
    point_weight: float,
    reverse_weight: float,
    tolerance: float,
    max_outlier_fraction: float,
    outlier_distance: float,
    rigid_options: dict[str, Any] | None,
    generator: torch.Generator | None,
    warn: bool,
    backend: str,
) -> NonRigidRegistration:
    t_total = time.perf_counter()
    timings = {"rigid": 0.0, "graph": 0.0, "correspondences": 0.0, "optimisation": 0.0, "residual": 0.0}
    src, tgt = validate_pair(source, target)
    if device is not None:
        src, tgt = src.to(device=device), tgt.to(device=device)
    dev, dtype = src.device, src.dtype
    gen = generator if generator is not None else torch.Generator().manual_seed(0)

    # 1. Normalise to the target's bounding-box centre and unit diagonal.
    center, diag = normalisation(tgt)
    tv = (tgt.verts - center) / diag
    tf = tgt.faces

    # 2. Rigid initialisation.
    t0 = time.perf_counter()
    if rigid_init:
        rigid = register_rigid(src, tgt, generator=gen, **{"point_to_plane": True, **(rigid_options or {})})
        moved = rigid.verts
    else:
        rigid = _identity_rigid(src.verts)
        moved = src.verts
    timings["rigid"] = time.perf_counter() - t0
    sv = (moved - center) / diag
    sf = src.faces

    # 3. Graph and fixed samples.
    t0 = time.perf_counter()
    graph = DeformationGraph(sv, sf, node_spacing=node_spacing, num_neighbors=num_neighbors).to(dev)
    surf = referenced_mask(Mesh(sv, sf, validate=False)).nonzero()[:, 0]
    if surf.numel() > num_points:
        surf = surf[torch.randperm(surf.numel(), generator=gen)[:num_points].to(dev)]
    if num_target_samples > 0:
        samples = sample_surface(tv.cpu(), tf.cpu(), n=num_target_samples, generator=gen)
        tsamp = samples.points.to(dev)
        tsamp_n = face_unit_normals(tv, tf)[samples.face_idx.to(dev)]
    timings["graph"] = time.perf_counter() - t0

    history: list[float] = []
    reason = ""
    # Adam's step is lr * m / (sqrt(v) + eps): about lr in every coordinate whatever the gradient's size, so at a
    # stationary point (e.g. an exact pair, whose gradient is rounding noise) it would move the parameters by lr
    # instead of not at all; the loop stops a stage where every gradient component is below sqrt(eps) of the dtype
    # (the loss is in units of the node spacing squared: residuals of ~1e-10 of the diagonal).
    stationary_tol = math.sqrt(torch.finfo(dtype).eps)
    best_state = _parameters(graph)
    # Built once: the target's index (queried at every refresh) and face normals; the deformed source's index is
    # refitted to the deformed vertices at every refresh (same faces), never rebuilt.
    target_index = MeshIndex._trusted(PackedMeshes(tv, tf, _lengths(tv), _lengths(tf)), backend, DEFAULT_MAX_MEMORY)
    target_normals = face_unit_normals(tv, tf)
    source_index: MeshIndex | None = None
    t_opt = time.perf_counter()
    first_loss: float | None = None
    for stage in schedule:
        opt = torch.optim.Adam(graph.parameters(), lr=stage.lr, **_ADAM_OPTIONS)
        prev_window: float | None = None
        corr_f: Correspondences | None = None
        corr_r: Correspondences | None = None
        corr_r_loc: Correspondences | None = None
        terms: EnergyTerms | None = None
        # Best iterate of the stage, judged on the loss right after a correspondence refresh (a function of the
        # parameters alone, so comparable across refreshes); the stage's last iterate gets one more refresh.
        stage_best = math.inf
        stage_best_state = best_state
        finishing = False
        for step in range(stage.max_steps + 1):
            finishing = finishing or step == stage.max_steps
            refresh = finishing or step % correspondence_every == 0
            if refresh:
                t0 = time.perf_counter()
                with torch.no_grad():
                    dv = deformed_vertices(graph)
                    fn, vn = unit_normals(dv, sf)
                    corr_f = find_correspondences(dv[surf], vn[surf], tv, tf, max_distance=stage.max_distance,
                                                  max_normal_angle=stage.max_normal_angle, index=target_index,
                                                  face_normals=target_normals)  # fmt: skip
                    if num_target_samples > 0:
                        if source_index is None:
                            packed = PackedMeshes(dv, sf, _lengths(dv), _lengths(sf))
                            source_index = MeshIndex._trusted(packed, backend, DEFAULT_MAX_MEMORY)
                        else:
                            source_index._refit(dv)
                        corr_r = find_correspondences(tsamp, tsamp_n, dv, sf, max_distance=stage.max_distance,
                                                      max_normal_angle=stage.max_normal_angle,
                                                      index=source_index, face_normals=fn)  # fmt: skip
                timings["correspondences"] += time.perf_counter() - t0
                # Only the data points and the vertices of the faces matched by target samples enter the data
                # terms: deform just those (forward and backward then scale with them, not with all vertices).
                rev_faces = sf[corr_r.face_idx] if corr_r is not None else sf[:0]
                need, inv = torch.cat([surf, rev_faces.reshape(-1)]).unique(return_inverse=True)
                surf_loc, faces_loc = inv[: surf.numel()], inv[surf.numel() :].view(-1, 3)
                corr_r_loc = (
                    corr_r._replace(face_idx=torch.arange(rev_faces.shape[0], device=dev))
                    if corr_r is not None
                    else None
                )
                terms = EnergyTerms(
                    graph.verts[need], graph.vert_nodes[need], graph.vert_weights[need], surf_loc,
                    tv[tf[corr_f.face_idx]], target_normals[corr_f.face_idx], corr_f.weights,
                    tsamp if corr_r is not None else tv[:0], faces_loc,
                    corr_r.weights if corr_r is not None else tv.new_zeros(0),
                )  # fmt: skip
            assert corr_f is not None and terms is not None
            opt.zero_grad(set_to_none=True)
            with torch.set_grad_enabled(not finishing):
                # Data terms in units of the node spacing, so a regularisation weight of 1 trades an edge residual
                # of one spacing against a data residual of one spacing.
                loss = fused_energy(graph, terms, sigma=stage.robust_scale, plane_weight=plane_weight,
                                    point_weight=point_weight, reverse_weight=reverse_weight,
                                    data_scale=1.0 / (node_spacing * node_spacing),
                                    regularization=stage.regularization)  # fmt: skip
                if loss is None:  # no C++ extension for this device: the same energy in torch ops
                    dsub = graph.deform_vertices(need)
                    loss = surface_term(dsub[surf_loc], tv, tf, corr_f, sigma=stage.robust_scale,
                                        plane_weight=plane_weight, point_weight=point_weight)  # fmt: skip
                    if corr_r_loc is not None and reverse_weight:
                        loss = loss + reverse_weight * surface_term(
                            tsamp, dsub, faces_loc, corr_r_loc, sigma=stage.robust_scale, plane_weight=0.0,
                            point_weight=1.0,
                        )  # fmt: skip
                    loss = loss / (node_spacing * node_spacing)
                    loss = loss + stage.regularization * embedded_deformation_regularizer(graph)
            value = float(loss.detach())
            if first_loss is None:
                # The loss is in units of (node spacing)^2: a floor of 1 (a residual of one node spacing) keeps an
                # exact start (loss ~1e-30) from calling rounding noise a divergence.
                first_loss = max(value, 1.0)
            if not math.isfinite(value) or value > 1e6 * first_loss:
                reason = f"diverged: loss became {value:.3g} (first loss {first_loss:.3g})"
                _load_parameters(graph, best_state)
                break
            if refresh and value < stage_best:
                stage_best = value
                stage_best_state = _parameters(graph)
            if finishing:
                break
            history.append(value)
            loss.backward()
            # One reduction for both checks: NaN propagates through max.
            grad_max = float(torch.stack([p.grad.abs().max() for p in graph.parameters() if p.grad is not None]).max())
            if not math.isfinite(grad_max):
                reason = "diverged: non-finite gradient"
                _load_parameters(graph, best_state)
                break
            if refresh:
                best_state = _parameters(graph)
            if grad_max <= stationary_tol:
                finishing = True  # the gradient is rounding noise: Adam would turn it into lr-sized steps
                continue
            opt.step()
            if step % correspondence_every == correspondence_every - 1:
                if prev_window is not None and abs(prev_window - value) <= tolerance * max(abs(prev_window), 1e-30):
                    finishing = True
                prev_window = value
        if reason:
            break
        _load_parameters(graph, stage_best_state)
        best_state = stage_best_state
    timings["optimisation"] = time.perf_counter() - t_opt - timings["correspondences"]

    # 4. Results, residuals and plausibility.
    t0 = time.perf_counter()
    with torch.no_grad():
        dv = deformed_vertices(graph)
        verts = dv * diag + center
        residual_n = target_index._point_mesh_distance(dv, _lengths(dv)).dists
        residual = residual_n * diag
        used = referenced_mask(Mesh(sv, sf, validate=False))
        frac_src = float((residual_n[used] > outlier_distance).to(dtype).mean())
        frac_tgt = 0.0
        if num_target_samples > 0 and source_index is not None:
            source_index._refit(dv)
            frac_tgt = float(
                (source_index._point_mesh_distance(tsamp, _lengths(tsamp)).dists > outlier_distance).to(dtype).mean()
            )
    timings["residual"] = time.perf_counter() - t0
    if not reason and (frac_src > max_outlier_fraction or frac_tgt > max_outlier_fraction):
        reason = (
            f"implausible fit: {100 * frac_src:.1f}% of source vertices and {100 * frac_tgt:.1f}% of target samples "
            f"are farther than {100 * outlier_distance:.1f}% of the diagonal from the other mesh "
            f"(allowed {100 * max_outlier_fraction:.1f}%)"
        )
    if not reason and not all(math.isfinite(h) for h in history):
        reason = "diverged: non-finite loss"
    converged = not reason
    if not converged and warn:
        warnings.warn(f"register_nonrigid: {reason}", RegistrationWarning, stacklevel=3)
    timings["total"] = time.perf_counter() - t_total
    return NonRigidRegistration(
        verts=verts,
        mesh=Mesh(verts, sf, validate=False),
        residual=residual,
        loss_history=history,
        converged=converged,
        reason=reason,
        timings=timings,
        graph=graph,
        rigid=rigid,
    )
