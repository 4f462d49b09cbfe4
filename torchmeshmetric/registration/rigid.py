"""Rigid (optionally similarity) registration: weighted Kabsch/Umeyama and trimmed, robust ICP.

The closed form is Umeyama's (1991, *Least-squares estimation of transformation parameters between two point
patterns*): the rotation from the SVD of the weighted cross-covariance with the sign of its determinant folded in
(so a reflection is never returned), and the scale from the trace of the singular values. ICP (Besl & McKay 1992)
alternates it with exact closest points on the target surface (:func:`~torchmeshmetric.point_mesh_distance`);
outliers are handled by trimming (Chetverikov et al. 2002, keep the ``trim`` fraction of best matches) and a
Geman-McClure weight on the rest. ``point_to_plane=True`` solves Chen & Medioni's (1992) linearised point-to-plane
step instead and projects the rotation back onto SO(3) with the exponential map.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, NamedTuple

import torch
from kornia.geometry.conversions import axis_angle_to_rotation_matrix
from torch import Tensor

from torchmeshmetric._checks import (
    EmptyInputError,
    ShapeError,
    check_finite,
    check_flag,
    check_float,
    check_int,
    check_real,
    check_shape,
)
from torchmeshmetric.kernels._common import range_scale
from torchmeshmetric.kernels.mesh_index import MeshIndex, PointMeshResult
from torchmeshmetric.registration._common import check_sampling, one_thread, validate_pair
from torchmeshmetric.structures import Mesh, MeshLike

__all__ = [
    "RigidRegistration",
    "SimilarityTransform",
    "check_rigid_options",
    "kabsch_umeyama",
    "register_rigid",
    "transform_matrix",
]


class SimilarityTransform(NamedTuple):
    """A similarity transform ``x -> scale * rotation @ x + translation`` (column vectors).

    Attributes:
        rotation: ``(3, 3)`` rotation matrix (``det = +1``).
        translation: ``(3,)`` translation.
        scale: 0-dim scale (1 for a rigid transform).

    Example:
        >>> import torch
        >>> src = torch.eye(3, dtype=torch.float64)
        >>> t = kabsch_umeyama(src, 2 * src + 1, scale=True)  # scaled by 2, moved by (1, 1, 1)
        >>> round(t.scale.item(), 9), [round(x, 9) for x in t.translation.tolist()]
        (2.0, [1.0, 1.0, 1.0])
    """

    rotation: Tensor
    translation: Tensor
    scale: Tensor


class RigidRegistration(NamedTuple):
    """Result of :func:`register_rigid`.

    Attributes:
        rotation: ``(3, 3)`` rotation (``det = +1``).
        translation: ``(3,)`` translation.
        scale: 0-dim scale (exactly 1 unless ``scale=True``).
        transform: ``(4, 4)`` homogeneous matrix ``[[s R, t], [0, 1]]`` mapping source onto target.
        verts: ``(V, 3)`` all source vertices moved by the transform (unreferenced ones included).
        rmse: 0-dim root-mean-square distance of the inlier (kept) source samples to the target surface.
        inlier_fraction: 0-dim fraction of source samples kept as inliers in the last iteration.
        converged: whether the transform stopped changing (relative to ``tolerance``) before ``max_iterations``.
        iterations: number of ICP iterations run.

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric import Mesh, as_mesh
        >>> source = as_mesh(trimesh.creation.icosphere(subdivisions=2))
        >>> target = Mesh(source.verts + torch.tensor([0.1, 0.0, 0.0], dtype=source.dtype), source.faces)
        >>> r = register_rigid(source, target)
        >>> moved_onto = bool(torch.allclose(r.verts, target.verts, atol=1e-9))
        >>> r.converged, r.scale.item(), tuple(r.transform.shape), moved_onto
        (True, 1.0, (4, 4), True)
    """

    rotation: Tensor
    translation: Tensor
    scale: Tensor
    transform: Tensor
    verts: Tensor
    rmse: Tensor
    inlier_fraction: Tensor
    converged: bool
    iterations: int


def transform_matrix(rotation: Tensor, translation: Tensor, scale: Tensor | float = 1.0) -> Tensor:
    """``(4, 4)`` homogeneous matrix of ``x -> scale * rotation @ x + translation``.

    Args:
        rotation: ``(3, 3)`` rotation (its dtype and device are the matrix's).
        translation: ``(3,)`` translation.
        scale: uniform scale (a float or a 0-dimensional tensor).

    Returns:
        ``(4, 4)`` matrix ``[[scale * rotation, translation], [0, 0, 0, 1]]``, acting on column vectors
        ``(x, y, z, 1)``.

    Example:
        >>> import torch
        >>> T = transform_matrix(torch.eye(3), torch.tensor([1.0, 2.0, 3.0]), 2.0)
        >>> (T @ torch.tensor([1.0, 0.0, 0.0, 1.0])).tolist()  # 2 * (1, 0, 0) + (1, 2, 3)
        [3.0, 2.0, 3.0, 1.0]
    """
    T = torch.eye(4, dtype=rotation.dtype, device=rotation.device)
    T[:3, :3] = rotation * scale
    T[:3, 3] = translation
    return T


def kabsch_umeyama(src: Tensor, dst: Tensor, weights: Tensor | None = None, scale: bool = False) -> SimilarityTransform:
    """Weighted least-squares similarity (or rigid) transform mapping ``src`` onto ``dst`` (Umeyama 1991).

    Minimises ``sum_i w_i || s R src_i + t - dst_i ||^2`` over rotations ``R`` (never a reflection), translations
    ``t`` and, with ``scale=True``, a scale ``s > 0`` (else ``s = 1``, the Kabsch solution).

    Args:
        src: ``(N, 3)`` source points.
        dst: ``(N, 3)`` corresponding target points.
        weights: optional ``(N,)`` non-negative weights (at least one positive).
        scale: also estimate a uniform scale.

    Returns:
        :class:`SimilarityTransform` ``(rotation (3, 3), translation (3,), scale ())``.

    Coordinates of any finite magnitude are handled: the centred points are scaled by powers of two (exact) where
    the covariance's products would overflow or underflow (float32 beyond ~4e9, float64 beyond ~1e77; until review V
    float64 1e200 and float32 1e20 raised a torch ``_LinAlgError`` from the SVD); the rotation does not depend on
    the scale and the scale estimate is corrected by the ratio of the two powers.

    Raises:
        ShapeError: shapes differ or are not ``(N, 3)`` / ``(N,)``.
        NonFiniteError: ``src``, ``dst`` or ``weights`` holds NaN or Inf (named).
        ValueError: a negative weight (named, with its row).
        EmptyInputError: no point, or all weights are zero.

    Example:
        >>> import torch
        >>> src = torch.tensor([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
        >>> R = torch.tensor([[0., -1, 0], [1, 0, 0], [0, 0, 1]])
        >>> T = kabsch_umeyama(src, src @ R.T + torch.tensor([1., 2, 3]))
        >>> torch.allclose(T.rotation, R, atol=1e-6), T.translation.round(decimals=4).tolist()
        (True, [1.0, 2.0, 3.0])
    """
    check_shape(src, ("N", 3), "src")
    check_shape(dst, ("N", 3), "dst")
    check_float(src, "src")
    if src.shape != dst.shape:
        raise ShapeError(f"dst: expected the shape of src {tuple(src.shape)}, found {tuple(dst.shape)}")
    if src.shape[0] == 0:
        raise EmptyInputError("src: expected at least one point pair, found none")
    check_finite(src, "src")
    check_finite(dst, "dst")
    dst = dst.to(src.dtype)
    if weights is None:
        w = torch.ones(src.shape[0], dtype=src.dtype, device=src.device)
    else:
        check_shape(weights, (src.shape[0],), "weights")
        check_finite(weights, "weights")
        w = weights.to(src.dtype)
        if bool((w < 0).any()):
            row = int((w < 0).nonzero()[0, 0])
            raise ValueError(f"weights: expected non-negative weights, found {float(w[row])!r} at row {row}")
    wsum = w.sum()
    if not bool(wsum > 0):
        raise EmptyInputError("weights: expected at least one positive weight, found all zero")
    w = w / wsum
    mu_s = (w[:, None] * src).sum(0)
    mu_d = (w[:, None] * dst).sum(0)
    xs, xd = src - mu_s, dst - mu_d
    # Powers of two (exact; None: 1, the same bits) where the covariance's products would over- or underflow.
    unit_s = range_scale(float(xs.detach().abs().amax()), xs.dtype, 2)
    unit_d = range_scale(float(xd.detach().abs().amax()), xd.dtype, 2)
    if unit_s is not None:
        xs = xs * unit_s
    if unit_d is not None:
        xd = xd * unit_d
    cov = (w[:, None] * xd).T @ xs  # (3, 3) = sum w (dst - mu_d)(src - mu_s)^T
    U, S, Vh = torch.linalg.svd(cov)
    d = torch.ones(3, dtype=src.dtype, device=src.device)
    d[2] = torch.sign(torch.linalg.det(U @ Vh))
    if d[2] == 0:
        d[2] = 1.0
    R = U @ torch.diag(d) @ Vh
    if scale:
        var_s = (w * (xs * xs).sum(-1)).sum()
        s = (S * d).sum() / var_s if bool(var_s > 0) else torch.ones((), dtype=src.dtype, device=src.device)
        if unit_s is not None or unit_d is not None:  # s was estimated between the scaled copies
            s = s * (unit_s or 1.0) / (unit_d or 1.0)
    else:
        s = torch.ones((), dtype=src.dtype, device=src.device)
    t = mu_d - s * (R @ mu_s)
    return SimilarityTransform(R, t, s)


# L's floor relative to the target diagonal (see _point_to_plane_step). Below every spread of the pinned and tested
# well-posed pairs (min 0.16 of the diagonal; only the tiny-mesh robustness cases go lower), so their steps keep their
# bits; high enough that a spread of rounding noise (eps times the coordinates) moves the rotation by rounding only.
_LENGTH_FLOOR = 0.0625


def _point_to_plane_step(p: Tensor, q: Tensor, n: Tensor, w: Tensor, scale: bool, diag: Tensor) -> SimilarityTransform:
    """One linearised point-to-plane step (Chen & Medioni 1992) about the weighted centroid of ``p``.

    Model ``x -> c + e^sigma R(omega) (x - c) + t`` linearised as ``x + omega x (x - c) + sigma (x - c) + t``;
    the residual ``n . (x' - q)`` is linear in ``(omega, t[, sigma])``. Rotation projected back with exp.

    Solved for ``(L omega, t[, L sigma])``, ``L`` the larger of the samples' weighted RMS distance from ``c`` and
    1/16 of ``diag`` (the target's bounding-box diagonal): every column is then dimensionless and the damped system is
    the same in any unit, so the step is ``s`` times the step for the input times ``s`` (bit for bit for a power of
    two). The rotation (and scale) goes to 0 with the samples' spread.
    """
    w = w / w.sum()
    c = (w[:, None] * p).sum(0)
    x = p - c
    cols = [torch.linalg.cross(x, n, dim=-1), n]  # n . (omega x x) = omega . (x x n)
    if scale:
        cols.append((n * x).sum(-1, keepdim=True))
    A = torch.cat(cols, dim=1)  # (N, 6 or 7)
    b = -(n * (p - q)).sum(-1)
    AtA = A.T @ (w[:, None] * A)
    Atb = A.T @ (w * b)
    # omega and sigma are dimensionless and their columns (x x n, n . x) are lengths; t is a length and its columns
    # (n) are not. With coordinates times k the rotation's diagonal entries scale by k^2 and the translation's do not,
    # so one damping relative to the largest entry damped each block by a share that changed with the units (at 1e-3
    # units the rotation's ~1e-6 entries got 1e-9: 1e-3 of their own; float32's 64 eps floor stopped its rotation).
    # The registration was not unit-invariant: the evaluation's k-1 statistics moved by 3e-6 relative at 1e-3 units
    # and 1e-13 at 2x, an ill-posed pair by 0.017 at 2x (measured 2026-12-07). The system is solved for
    # (L omega, t[, L sigma]) instead, L a length of the data (exactly doubled with it): its entries are dimensionless.
    # L is the samples' spread, but at least 1/16 of the target diagonal. With L = spread alone (review S, 2026-12-07)
    # the step was not continuous: samples that are all one point have a spread of the centroid's rounding (1e-19 at
    # 1e-3 units), the divided columns were that rounding at O(1) and the damping could not stop them (rotation 1.7
    # rad, s = inf with scale; an unwelded fan whose kept samples are its apex copies turned 0.0625 rad), and a sample
    # of weight 1e-300 set a 0.14 rad rotation that weight 0 does not. With the floor the rotation's columns shrink
    # with the spread below it, so the rotation goes to 0 with the spread and with such a weight (below 2e-16 rad for
    # coincident samples in float64, 1.4e-7 in float32), and the floor scales with the input as L must.
    # Row and column divided in turn: L^2 could underflow where L does not. L = 0 only where the diagonal is 0.
    spread = (w * (x * x).sum(-1)).sum().sqrt()
    length = torch.maximum(spread, _LENGTH_FLOOR * diag.to(spread.dtype))
    length = torch.where(length > 0, length, torch.ones_like(length))
    units = torch.ones_like(Atb)
    units[:3] = length
    if scale:
        units[6] = length
    AtA = AtA / units[:, None] / units[None, :]
    Atb = Atb / units
    # Tikhonov damping relative to the system's scale keeps flat/planar configurations (a 3-vertex source cannot
    # fix 6 degrees of freedom) solvable; it must stay above the dtype's rounding of the diagonal (float32: 1e-9
    # relative vanishes in it), so it is at least 64 eps.
    finfo = torch.finfo(p.dtype)
    damp = max(1e-9, 64 * finfo.eps) * AtA.diagonal().abs().max().clamp_min(finfo.tiny)
    system = AtA + damp * torch.eye(A.shape[1], dtype=p.dtype, device=p.device)
    sol, info = torch.linalg.solve_ex(system, Atb)
    if bool(info != 0) or not bool(torch.isfinite(sol).all()):
        # Still singular (e.g. all weights on one point): the minimum-norm least-squares step, or none at all.
        sol = torch.linalg.lstsq(system.cpu(), Atb.cpu()[:, None], driver="gelsd").solution[:, 0].to(p.device)
        if not bool(torch.isfinite(sol).all()):
            sol = torch.zeros_like(Atb)
    sol = sol / units
    R = axis_angle_to_rotation_matrix(sol[None, :3])[0]
    s = torch.exp(sol[6]) if scale else torch.ones((), dtype=p.dtype, device=p.device)
    t = c + sol[3:6] - s * (R @ c)
    return SimilarityTransform(R, t, s)


_RIGID_FLAGS = ("point_to_plane", "scale", "align_centroids")


def check_rigid_options(options: Mapping[str, Any], where: str = "") -> dict[str, Any]:
    """The checks of :func:`register_rigid`'s keywords (types and ranges), each named ``{where}{keyword}``.

    One implementation for :func:`register_rigid` and for ``NonRigidOptions(rigid_options=...)``, which validates
    them when built. Unknown keywords are left to the caller.

    Returns:
        The options with each checked value as the checks read it (a one-element tensor or numpy number as a Python
        float or int), the others as given.

    Raises:
        TypeError: a value of the wrong type (``max_iterations='ten'``).
        ValueError: a value out of its range (``trim=5.0``, ``max_iterations=-3``).

    Example:
        >>> import torch
        >>> check_rigid_options({"trim": torch.tensor(0.5), "max_iterations": 10})
        {'trim': 0.5, 'max_iterations': 10}
        >>> check_rigid_options({"trim": 5.0}, "rigid_options: ")
        Traceback (most recent call last):
        ...
        ValueError: rigid_options: trim: expected a fraction in (0, 1], found 5.0
    """
    checked = dict(options)
    for key, value in options.items():
        name = f"{where}{key}"
        if key in _RIGID_FLAGS:
            checked[key] = check_flag(value, name)
        elif key in ("max_iterations", "num_samples"):
            checked[key] = check_int(value, name, low=0 if key == "max_iterations" else 3)  # a plane needs 3 samples
        elif key in ("trim", "robust_scale", "tolerance"):
            value = check_real(value, name)  # numpy's bool is no Real: refused as bool is
            if key == "trim" and not 0.0 < value <= 1.0:
                raise ValueError(f"{name}: expected a fraction in (0, 1], found {value}")
            if key == "robust_scale" and not value > 0:  # inf disables the kernel; NaN never passes
                raise ValueError(f"{name}: expected a float > 0 (inf: no robust kernel), found {value}")
            if key == "tolerance" and not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: expected a finite float >= 0, found {value}")
            # The checked float, not the caller's object: a one-element tensor passes check_real, and kept as given
            # it failed later ("type Tensor doesn't define __round__") and keyed the cache apart from the same float.
            checked[key] = value
        elif key == "init" and value is not None:
            if not isinstance(value, Tensor):
                raise TypeError(f"{name}: expected None or a (4, 4) tensor, found {type(value).__name__}")
            check_shape(value, (4, 4), name)
            check_finite(value, name)
            # The start's scale is |det|^(1/3) of the 3x3 block, which it divides by: a singular block made the
            # rotation non-finite and ICP died in torch's SVD ("linalg.svd: ... non-finite values").
            det = float(torch.linalg.det(value.detach().to("cpu", torch.float64)[:3, :3]))
            if not (math.isfinite(det) and det != 0.0):
                raise ValueError(
                    f"{name}: expected an invertible transform (its 3x3 block scales and rotates), found one whose "
                    f"3x3 block has determinant {det:g}"
                )
    return checked


def register_rigid(
    source: MeshLike,
    target: MeshLike,
    *,
    max_iterations: int = 30,
    point_to_plane: bool = False,
    scale: bool = False,
    trim: float = 0.9,
    robust_scale: float = 0.05,
    tolerance: float = 1e-6,
    num_samples: int = 1000,
    align_centroids: bool = True,
    init: Tensor | None = None,
    generator: torch.Generator | None = None,
    sampling: str = "index",
) -> RigidRegistration:
    """Align ``source`` onto ``target`` with trimmed, robust ICP (rigid, or similarity with ``scale=True``).

    Each iteration moves up to ``num_samples`` source vertices (referenced ones only; duplicates are harmless),
    finds their exact closest points on the target surface, keeps the ``trim`` fraction with the smallest
    distances, weights them with Geman-McClure ``sigma^2 / (sigma^2 + r^2)^2`` (``sigma = robust_scale`` times the
    target's bounding-box diagonal) and solves the weighted Umeyama (point-to-point) or linearised point-to-plane
    step. Iteration stops when the incremental transform moves the samples by less than ``tolerance`` times the
    diagonal.

    Args:
        source: the mesh to move (any mesh-like).
        target: the mesh to align onto.
        max_iterations: maximum number of ICP iterations.
        point_to_plane: use the point-to-plane error (faster convergence on smooth surfaces).
        scale: also estimate a uniform scale.
        trim: fraction of matches kept per iteration, in ``(0, 1]``.
        robust_scale: Geman-McClure scale relative to the target diagonal (``inf`` disables the kernel).
        tolerance: stopping threshold on the samples' RMS motion per iteration, relative to the diagonal.
        num_samples: maximum number of source vertices used per iteration (a fixed random subset of the vertices of
            any face: drawn among those of faces with a normal, a rounding that gives a zero-area face one would
            renumber the list and redraw every point).
        align_centroids: start by translating the source's vertex centroid onto the target's.
        init: optional ``(4, 4)`` initial transform (replaces ``align_centroids``).
        generator: optional ``torch.Generator`` for the sample subset.
        sampling: ``"index"``: the subset is a random permutation of the vertex indices; ``"canonical"`` (or
            ``"dense"``): a farthest-point subset chosen whatever order the vertices are stored in, and the centroids
            as exactly rounded sums (``NonRigidOptions.sampling``).

    Returns:
        :class:`RigidRegistration`.

    Raises:
        ShapeError, DTypeError, NonFiniteError, IndexRangeError, DeviceError, EmptyInputError: on bad meshes.
        ValueError: on a bad option.

    Example:
        >>> import math, torch, trimesh
        >>> from torchmeshmetric.registration import register_rigid
        >>> src = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
        >>> tgt = src.copy().apply_transform(trimesh.transformations.rotation_matrix(0.3, [0, 0, 1]))
        >>> r = register_rigid(src, tgt, point_to_plane=True)
        >>> r.converged, round(float(r.rmse), 6)
        (True, 0.0)
    """
    checked = check_rigid_options(
        {
            "max_iterations": max_iterations,
            "point_to_plane": point_to_plane,
            "scale": scale,
            "trim": trim,
            "robust_scale": robust_scale,
            "tolerance": tolerance,
            "num_samples": num_samples,
            "align_centroids": align_centroids,
            "init": init,
        }
    )
    max_iterations, num_samples = checked["max_iterations"], checked["num_samples"]
    trim, robust_scale, tolerance = checked["trim"], checked["robust_scale"], checked["tolerance"]
    # On coordinates scaled by an exact power of two where float32's range would overflow or underflow (scale 1.0,
    # no multiplication, otherwise); the lengths of the result are divided back.
    src, tgt, unit = validate_pair(source, target)
    dtype, device = src.verts.dtype, src.verts.device
    if init is not None and unit != 1.0:
        init = init.to(device=device, dtype=dtype).clone()
        init[:3, 3] *= unit
    # The vertices of any face (topology only), not of faces with a normal: which zero-area faces have a computed
    # normal depends on the input's rounding (docs/registration.md, "Stability", item 7).
    used = src.referenced_vertex_mask()
    pts_all = src.verts[used]
    canonical = check_sampling(sampling) != "index"
    if canonical:
        from torchmeshmetric.registration.deformation_graph import canonical_farthest_points

        area = math.fsum(src.face_areas().double().tolist())
        pts = pts_all[canonical_farthest_points(pts_all, num_samples, area)]
    elif pts_all.shape[0] > num_samples:
        perm = torch.randperm(pts_all.shape[0], generator=generator, device="cpu")[:num_samples].to(device)
        pts = pts_all[perm]
    else:
        pts = pts_all
    diag = tgt.bbox_diagonal()
    R, t, s = _initial_transform(src, tgt, pts_all, init, scale, align_centroids, canonical)
    sigma2 = (robust_scale * diag) ** 2
    converged = False
    it = 0
    index = MeshIndex(tgt.verts, tgt.faces, tree="morton")  # built once for all iterations (~15 queries)
    for it in range(1, max_iterations + 1):  # noqa: B007 - the last value is reported
        cur = s * pts @ R.T + t
        res = index.point_mesh_distance(cur)
        w = _robust_trimmed_weights(res.dists, trim, sigma2)
        with one_thread():  # the same step whatever the thread count (only the query above is threaded)
            if point_to_plane:
                step = _point_to_plane_step(cur, res.closest, _match_normals(cur, res, tgt), w, scale, diag)
            else:
                step = kabsch_umeyama(cur, res.closest, w, scale=scale)
        R, t, s = step.rotation @ R, step.scale * (step.rotation @ t) + step.translation, step.scale * s
        new = s * pts @ R.T + t
        motion = ((new - cur) ** 2).sum(-1).mean().sqrt()
        if bool(motion <= tolerance * diag):
            converged = True
            break
    cur = s * pts @ R.T + t
    res = index.point_mesh_distance(cur)
    w = _robust_trimmed_weights(res.dists, trim, float("inf"))
    keep = w > 0
    rmse = (res.dists[keep] ** 2).mean().sqrt()
    verts = s * src.verts @ R.T + t
    if unit != 1.0:
        t, verts, rmse = t / unit, verts / unit, rmse / unit
    return RigidRegistration(
        rotation=R,
        translation=t,
        scale=s,
        transform=transform_matrix(R, t, s),
        verts=verts,
        rmse=rmse,
        inlier_fraction=keep.to(dtype).mean(),
        converged=converged or max_iterations == 0,
        iterations=it,
    )


def _initial_transform(
    src: Mesh,
    tgt: Mesh,
    pts_all: Tensor,
    init: Tensor | None,
    scale: bool,
    align_centroids: bool,
    canonical: bool = False,
) -> tuple[Tensor, Tensor, Tensor]:
    """``(R, t, s)`` ICP starts from.

    ``init`` (projected onto a rotation unless ``scale``), else the identity, translated so that the centroids of the
    referenced vertices (of any face) meet when ``align_centroids``.
    """
    dtype, device = src.dtype, src.device
    if init is not None:
        check_shape(init, (4, 4), "init")
        check_finite(init, "init")
        A = init.to(device=device, dtype=dtype)[:3, :3]
        s0 = torch.linalg.det(A).abs().pow(1.0 / 3.0)
        R = A / s0
        s, t = s0 if scale else torch.ones((), dtype=dtype, device=device), init.to(device=device, dtype=dtype)[:3, 3]
        if not scale:
            R = kabsch_umeyama(torch.eye(3, dtype=dtype, device=device), R.T).rotation  # nearest rotation
        return R, t, s
    R = torch.eye(3, dtype=dtype, device=device)
    s = torch.ones((), dtype=dtype, device=device)
    t = torch.zeros(3, dtype=dtype, device=device)
    if align_centroids:
        if canonical:
            from torchmeshmetric.registration.deformation_graph import _exact_mean

            t = _exact_mean(tgt.verts[tgt.referenced_vertex_mask()]) - _exact_mean(pts_all)
        else:
            t = tgt.verts[tgt.referenced_vertex_mask()].mean(0) - pts_all.mean(0)
    return R, t, s


def _match_normals(cur: Tensor, res: PointMeshResult, tgt: Mesh) -> Tensor:
    """``(P, 3)`` normal of each match for the point-to-plane step.

    The face normal is the distance's gradient direction only for a match inside the face. A match on an edge or a
    vertex (a zero barycentric) is shared by several faces, which tie, so the face normal would depend on
    tie-breaking; there, and on zero-area faces (no normal), use the direction to the closest point, the distance's
    gradient. Matches on the surface (distance 0) keep the face normal.
    """
    n = tgt.face_normals()[res.face_idx]
    no_n = ((n * n).sum(-1) == 0) | (res.bary <= 0).any(-1)
    if bool(no_n.any()):
        diff = cur - res.closest
        dn = diff.norm(dim=-1, keepdim=True)
        # The clamp only keeps the branch not taken (dn == 0) finite; an absolute 1e-30 shrank the normals of a mesh
        # of 1e-30 units (found by review).
        n = torch.where(no_n[:, None] & (dn > 0), diff / dn.clamp_min(torch.finfo(dn.dtype).tiny), n)
    return n


def _robust_trimmed_weights(dists: Tensor, trim: float, sigma2: Tensor | float) -> Tensor:
    """Zero weight beyond the ``trim`` quantile of ``dists``; Geman-McClure weight ``s^2/(s^2+r^2)^2`` inside."""
    n = dists.shape[0]
    k = max(3, min(n, round(trim * n)))
    keep = torch.zeros(n, dtype=torch.bool, device=dists.device)
    keep[dists.argsort()[:k]] = True
    if isinstance(sigma2, float) and sigma2 == float("inf"):
        return keep.to(dists.dtype)
    s2 = torch.as_tensor(sigma2, dtype=dists.dtype, device=dists.device)
    w = (s2 / (s2 + dists**2)) ** 2
    if not bool(s2 > 0):
        w = torch.ones_like(dists)
    return torch.where(keep, w, torch.zeros_like(w))
