r"""STED, the spatio-temporal edge difference of Váša & Skala (TVCG 17(2), 2011), on same-connectivity sequences.

STED compares two animations with one connectivity through their *edges*: local changes of edge length in space
(what a viewer sees as a distorted shape) and changes of vertex motion in time (what a viewer sees as jitter). The
defaults are those of Váša's own tool, as the issue lists them (docs/temporal.md says where sources differ).

**Spatial part.** For each frame and each vertex ``v``, the edges ``e`` of its neighbourhood of width 1
(:func:`~torchmeshmetric.temporal.topology.neighbourhoods`) with original length :math:`l_e` and distorted length
:math:`\hat l_e` give relative differences :math:`d_e = |\hat l_e - l_e| / l_e`; their standard deviation weighted
by the original lengths is the local spatial error

.. math::

    \sigma_v = \sqrt{\frac{\sum_e l_e (d_e - \bar d_v)^2}{\sum_e l_e}},\qquad
    \bar d_v = \frac{\sum_e l_e d_e}{\sum_e l_e},

and :math:`\mathrm{STED}_s` is its mean over vertices and frames. A uniform scale changes every edge by the same
ratio, so it costs nothing; a local bump does.

**Temporal part.** The temporal edge of vertex ``v`` between frames ``f`` and ``f+1`` has length
:math:`t = \sqrt{\lVert \Delta x / D\rVert^2 + \delta t^2}`, with :math:`D` the largest distance between two vertices
of the original's frame 0 that faces reference (both sequences use the original's) and :math:`\delta t` = ``dt``.
Its relative difference :math:`|\hat t - t| / \bar t` is normalised by the mean original temporal edge of ``v`` over
the frames within ``window`` of ``f``, and :math:`\mathrm{STED}_t` is its mean over vertices and temporal edges.

**Together:** :math:`\mathrm{STED} = \sqrt{\mathrm{STED}_s^2 + c^2\,\mathrm{STED}_t^2}`.

Vertices no face references have no neighbourhood and take no part (in :math:`D` neither). An original edge of length
zero has weight zero in its neighbourhoods (its relative difference is undefined and counts for nothing); a
neighbourhood with no length at all has a local error of zero.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._checks import ShapeError, check_finite, check_float, check_int, check_real, check_tensor
from torchmeshmetric.temporal._diameter import farthest_pair as _farthest_pair
from torchmeshmetric.temporal.sequences import check_faces_of, check_sequence_pair, power_of_two_scale
from torchmeshmetric.temporal.topology import Neighbourhoods, neighbourhoods

__all__ = [
    "DEFAULT_C",
    "DEFAULT_DT",
    "DEFAULT_WINDOW",
    "StedResult",
    "largest_vertex_distance",
    "sted",
]

#: Weight of the temporal part in STED (Váša's tool's default).
DEFAULT_C = 9.144e-5
#: Time step of a temporal edge, in units of the largest vertex distance of frame 0 (Váša's tool's default).
DEFAULT_DT = 3e-4
#: Half-width, in frames, of the window over which the original temporal edges are averaged (Váša's tool's default).
DEFAULT_WINDOW = 5


class StedResult(NamedTuple):
    r"""Result of :func:`sted`: each entry ``(...)``, one value per sequence of the batch.

    Attributes:
        spatial: :math:`\mathrm{STED}_s`.
        temporal: :math:`\mathrm{STED}_t`.
        sted: :math:`\sqrt{\mathrm{STED}_s^2 + c^2 \mathrm{STED}_t^2}`.

    Example:
        >>> import torch, trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=1)
        >>> verts, faces = torch.as_tensor(sphere.vertices), torch.as_tensor(sphere.faces)
        >>> drifting = torch.stack([verts + 0.01 * k for k in range(4)])
        >>> r = sted(drifting, drifting, faces)  # a sequence against itself
        >>> r.spatial.item(), r.temporal.item(), r.sted.item()
        (0.0, 0.0, 0.0)
    """

    spatial: Tensor
    temporal: Tensor
    sted: Tensor


def _safe_sqrt(x: Tensor) -> Tensor:
    """``sqrt(x)`` for ``x >= 0`` with a finite (zero) gradient at zero; NaN stays NaN (never a silent 0)."""
    positive = x > 0
    zero_or_nan = torch.where(torch.isnan(x), x, torch.zeros_like(x))
    return torch.where(positive, torch.where(positive, x, torch.ones_like(x)).sqrt(), zero_or_nan)


def _lengths(verts: Tensor, edges: Tensor) -> Tensor:
    """``(..., E)`` lengths of ``edges`` in ``verts (..., V, 3)`` (finite gradient at zero length)."""
    diff = verts[..., edges[:, 0], :] - verts[..., edges[:, 1], :]
    return _safe_sqrt((diff * diff).sum(-1))


def largest_vertex_distance(points: Tensor) -> Tensor:
    """The largest distance between two of the ``(..., V, 3)`` points: ``(...)``, exact, differentiable.

    The pair is the one a float64 brute force over every pair finds (the largest float64 squared distance, the
    first in row-major order among ties), found by a branch and bound over a k-d tree whose prunes keep a margin far
    above float64 rounding (:func:`~torchmeshmetric.temporal._diameter.farthest_pair`): ``O(V log V)`` on most
    shapes and on points near a sphere too (100 000 points on a sphere: ~0.5 s on one CPU core, where the
    brute force takes minutes). The distance is that pair's, in the points' dtype; the gradient reaches its two
    points. Points that all coincide give 0.

    Args:
        points: ``(..., V, 3)`` points; leading dimensions are a batch, each item searched on its own.

    Returns:
        ``(...)`` the largest distance of each item, differentiable.

    Raises:
        TypeError: ``points`` not a tensor.
        ShapeError: not ``(..., V, 3)`` with ``V >= 1``.
        DTypeError: not float32 or float64 (integer, half precision, complex).
        NonFiniteError: NaN or Inf coordinates.

    Example:
        >>> largest_vertex_distance(torch.tensor([[0.0, 0, 0], [3.0, 4.0, 0], [1.0, 1.0, 0]])).item()
        5.0
    """
    check_tensor(points, "points", "a torch.Tensor of shape (..., V, 3)")
    if points.ndim < 2 or points.shape[-1] != 3 or points.shape[-2] == 0:
        raise ShapeError(f"points: expected (..., V, 3) with V >= 1, found {tuple(points.shape)}")
    check_float(points, "points")
    check_finite(points, "points")
    if points.numel() == 0:  # an empty batch: no distance to compute
        return points.new_zeros(points.shape[:-2])
    flat = points.reshape(-1, *points.shape[-2:])
    out = []
    for x in flat:
        with torch.no_grad():
            i, j = _farthest_pair(x.detach().double())
        out.append(torch.linalg.vector_norm(x[i] - x[j]))
    return torch.stack(out).reshape(points.shape[:-2])


def _spatial(original: Tensor, distorted: Tensor, nb: Neighbourhoods, referenced: Tensor) -> Tensor:
    lengths = _lengths(original, nb.edges)  # (..., F, E)
    rel = (_lengths(distorted, nb.edges) - lengths).abs() / torch.where(lengths > 0, lengths, torch.ones_like(lengths))
    w = lengths[..., nb.edge]  # (..., F, P): each pair's edge weight and difference
    d = rel[..., nb.edge]
    shape = (*w.shape[:-1], nb.num_verts)
    total = torch.zeros(shape, dtype=w.dtype, device=w.device).index_add(-1, nb.vertex, w)
    has = total > 0
    safe_total = torch.where(has, total, torch.ones_like(total))
    mean = torch.zeros_like(total).index_add(-1, nb.vertex, w * d) / safe_total
    dev = d - mean[..., nb.vertex]
    var = torch.zeros_like(total).index_add(-1, nb.vertex, w * dev * dev) / safe_total
    sigma = _safe_sqrt(torch.where(has, var, torch.zeros_like(var)))  # (..., F, V)
    return sigma[..., referenced].mean(dim=(-1, -2))


def _temporal(
    original: Tensor, distorted: Tensor, diameter: Tensor, referenced: Tensor, dt: float, window: int
) -> Tensor:
    """STED_t, with ``diameter`` the ``(...)`` largest vertex distance D of each item's frame 0."""
    diameter = diameter[..., None, None, None]
    dt2 = dt * dt

    def temporal_lengths(x: Tensor) -> Tensor:
        step = (x[..., 1:, :, :] - x[..., :-1, :, :]) / diameter
        return ((step * step).sum(-1) + dt2).sqrt()  # (..., F-1, V), never zero: dt > 0

    t, t_hat = temporal_lengths(original), temporal_lengths(distorted)
    n = t.shape[-2]
    # Mean original temporal edge over frames [f - window, f + window] ∩ [0, F-2], by prefix sums over the frames.
    prefix = torch.cat([torch.zeros_like(t[..., :1, :]), t.cumsum(-2)], dim=-2)
    f = torch.arange(n, device=t.device)
    lo, hi = (f - window).clamp_min(0), (f + window).clamp_max(n - 1) + 1
    mean = (prefix[..., hi, :] - prefix[..., lo, :]) / (hi - lo).to(t.dtype)[:, None]
    rel = (t_hat - t).abs() / mean
    return rel[..., referenced].mean(dim=(-1, -2))


def check_sted_parameters(dt: object, window: object, c: object) -> tuple[float, int, float]:
    """:func:`sted`'s ``dt``, ``window`` and ``c``, checked (before any work that leads to it).

    Returns:
        ``(dt, window, c)`` as a Python float, int and float.

    Raises:
        TypeError: ``dt`` or ``c`` not a real number, ``window`` not an int (numpy's numbers are numbers).
        ValueError: ``dt`` not > 0 or ``c`` not >= 0 (or a square that overflows or underflows), ``window`` < 0.
    """
    return _check_weight("dt", dt, zero=False), check_int(window, "window", low=0), _check_weight("c", c, zero=True)


def _check_weight(name: str, value: object, *, zero: bool) -> float:
    """``dt`` and ``c``: real numbers whose square is a finite float, positive (``dt``) or >= 0 (``c``).

    STED uses their squares: ``dt = 1e200`` overflows (then STED_t is NaN) and ``dt = 1e-200`` underflows to zero.
    """
    value = check_real(value, name)  # numpy's numbers too
    square = value * value
    if not (math.isfinite(square) and (square > 0 or (zero and value == 0)) and value >= 0):
        bound = ">= 0" if zero else "> 0"
        raise ValueError(f"{name}: expected a float {bound} whose square is a finite float {bound}, found {value!r}")
    return value


def sted(
    original: Tensor,
    distorted: Tensor,
    faces: Tensor,
    *,
    dt: float = DEFAULT_DT,
    window: int = DEFAULT_WINDOW,
    c: float = DEFAULT_C,
) -> StedResult:
    r"""STED_s, STED_t and STED of a distorted animation against its original, same connectivity (module docstring).

    Args:
        original: ``(..., F, V, 3)`` original vertex positions, ``F >= 2`` (leading dimensions are a batch).
        distorted: ``(..., F, V, 3)`` distorted positions, same vertices.
        faces: ``(T, 3)`` the faces shared by every frame of both.
        dt: time step of a temporal edge (relative to the largest vertex distance of the original's frame 0).
        window: half-width in frames of the window of the temporal normalisation.
        c: weight of the temporal part.

    Returns:
        :class:`StedResult` ``(spatial, temporal, sted)``, each ``(...)`` in the promoted dtype; differentiable in
        both sequences (finite gradients where an absolute value or a square root meets zero).

    Raises:
        ShapeError, DTypeError, NonFiniteError, DeviceError: see
            :func:`~torchmeshmetric.temporal.sequences.check_sequence_pair` (and fewer than 2 frames).
        IndexRangeError: faces outside the vertices.
        ValueError: ``dt`` not positive, ``window`` negative, ``c`` negative (or a square that overflows or
            underflows), faces without an edge, or an original whose referenced vertices of frame 0 all coincide
            (``D = 0``).
        TypeError: ``dt`` or ``c`` not a number.

    Example:
        >>> import trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=1)
        >>> verts = torch.as_tensor(sphere.vertices)
        >>> a = torch.stack([verts + 0.01 * k for k in range(4)])  # a sphere drifting along the diagonal
        >>> faces = torch.as_tensor(sphere.faces)
        >>> r = sted(a, 2.0 * a, faces)  # twice the size, twice the motion
        >>> float(r.spatial) < 1e-12, float(r.temporal) > 0
        (True, True)
    """
    a, b = check_sequence_pair(original, distorted, min_frames=2)
    scale = power_of_two_scale(a, b)  # STED is scale-free: the same figures, without overflow (power_of_two_scale)
    a, b = a / scale, b / scale
    f = check_faces_of(faces, a.shape[-2]).to(a.device)
    dt, window, c = check_sted_parameters(dt, window, c)
    nb = neighbourhoods(f, a.shape[-2])
    if nb.edges.shape[0] == 0:
        raise ValueError("faces: no face has two distinct vertices: no edge, nothing for STED to measure")
    referenced = torch.zeros(a.shape[-2], dtype=torch.bool, device=a.device)
    referenced[nb.edges.flatten()] = True
    spatial = _spatial(a, b, nb, referenced)
    # D over the vertices that take part: a vertex no face uses is not part of the surface (found by review: a stray
    # vertex moved STED_t, and the registered form, which drops such vertices, disagreed with the exact one).
    diameter = largest_vertex_distance(a[..., 0, :, :][..., referenced, :])
    if bool((diameter.detach() == 0).any()):
        raise ValueError(
            "original: the vertices of frame 0 that faces reference all coincide (largest vertex distance D = 0), "
            "D gives STED_t no scale"
        )
    temporal = _temporal(a, b, diameter, referenced, dt, window)
    return StedResult(spatial, temporal, _safe_sqrt(spatial * spatial + (c * c) * temporal * temporal))
