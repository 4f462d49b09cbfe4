"""PCQM, the point-cloud quality metric of Meynet et al. (QoMEX 2020), as ``mm compare --mode pcqm`` computes it.

mmetric v1.1.7 passes model B as PCQM's reference and model A as its "registered" cloud, so every figure is a mean
over the points of A (``ref`` here). Per point ``p`` of A:

* ``radius = radius_curvature * max_dim``, where ``max_dim`` is the largest of ``|min| + |max|`` over the three axes
  of A's coordinates (PCQM's own box measure, with the running maximum started at ``DBL_MIN``);
* a quadric ``z = a x^2 + b y^2 + c xy + d x + e y + f`` is fitted by least squares in the principal frame of the
  ``knn`` nearest points of B; ``p`` moved by ``f`` along the frame's normal is its projection on B (or B's nearest
  point, if that is nearer to ``p``);
* the same fit over the points of B, then of A, within ``radius`` of ``p`` gives the mean curvatures ``H`` and ``K``
  (``|H| max_dim``, ``|K| max_dim``); neighbourhoods of fewer than 6 points take the least-squares basic solution of
  a column-pivoting QR;
* over the points ``q`` of A within ``radius * radius_factor``, with Gaussian weights (sigma = half that radius) of
  ``|p - q|`` and of the distance between their projections, the curvature structure term
  ``|s_A s_B - cov| / (s_A s_B + 1)`` (clamped to 1) and the lightness terms (weighted-mean difference
  ``1 / (0.002 d^2 + 1)``, and the structure ``(cov + 0.1) / (s_A s_B + 0.1)`` of the unweighted lightness; B's
  lightness is that of B's nearest point, see :func:`pcqm_lightness`).

``PCQM = 0.0057 mean(structure) + 0.9771 (1 - mean(lightness)) + 0.0172 (1 - mean(lightness structure))``, returned
by PCQM as float32; mmetric's ``PCQM-PSNR = 10 log10(E^2 / (PCQM E)^2)`` with E the float32 diagonal of A's box.
Points without colour are white. The neighbour searches follow PCQM's k-d tree (nanoflann: which of several
equidistant points is found first) and the fits follow Eigen 3.3's eigensolver and QR operation for operation
(``native/pcqm.cpp``), because fits of 1 to 5 points -- most neighbourhoods at the default radius -- depend on
rounding: the per-point fields are bit-identical to PCQM's, and the printed figures equal mm's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from torchmeshmetric import native
from torchmeshmetric._checks import (
    EmptyInputError,
    check_allocation,
    check_finite,
    check_positive_real,
    check_rgb255,
)
from torchmeshmetric.mpeg.comparison.pcc import bbox_diagonal
from torchmeshmetric.mpeg.comparison.pcqm_lightness import pcqm_lightness
from torchmeshmetric.mpeg.core.point_cloud import PointCloud

__all__ = ["PcqmResult", "mpeg_pcqm"]

_CLIP = 99.99  # mmetric's statistics clip every sample at 99.99
_WEIGHTS = (0.0057, 0.9771, 0.0172)  # PCQM's weights of curvature structure, lightness, lightness structure


def _g(x: float) -> str:
    """A double as mmetric prints it (C++ ostream, precision 9)."""
    return "nan" if math.isnan(x) else format(x, ".9g")


def _statistics(value: float, prefix: str) -> list[str]:
    """Statistics::compute and printToLog of mmetric over one frame (samples clipped at 99.99; variance unclipped)."""
    sample = min(value, _CLIP)
    variance = math.pow(value - sample, 2.0) if math.isfinite(value) else math.inf
    minkowsky = math.pow(math.pow(abs(value), 3.0), 1.0 / 3.0) if math.isfinite(value) else math.inf
    rows = (("Min", sample), ("Max", sample), ("Sum", sample), ("Mean", sample), ("Variance", variance),
            ("StdDev", math.sqrt(variance)), ("Minkowsky", minkowsky))  # fmt: skip
    return [f"{prefix}{name}={_g(v)}" for name, v in rows]


@dataclass(frozen=True)
class PcqmResult:
    """``mm compare --mode pcqm``'s figures.

    Attributes:
        pcqm: the score in double, as PCQM prints it (``PCQM value is``); 0 for identical clouds.
        pcqm_float: the score rounded to float32, as PCQM returns it to mmetric (its ``PCQM`` statistics).
        psnr: mmetric's ``PCQM-PSNR`` (``inf`` for a zero score).
        features: the means of the three weighted features (curvature structure, lightness, lightness structure).
        points_ref, points_dis: the sizes of the two clouds (A and B).
        radius: the curvature radius ``radius_curvature * max_dim``.

    Example:
        >>> import torch
        >>> from torchmeshmetric.mpeg import PointCloud
        >>> pts = torch.rand(200, 3, generator=torch.Generator().manual_seed(0)) * torch.tensor([1.0, 1.0, 0.0])
        >>> r = mpeg_pcqm(PointCloud(pts), PointCloud(pts), radius_curvature=0.1)  # flat, same colour: no distortion
        >>> r.pcqm, r.psnr, r.points_ref, r.features
        (0.0, inf, 200, (0.0, 1.0, 1.0))
    """

    pcqm: float
    pcqm_float: float
    psnr: float
    features: tuple[float, float, float]
    points_ref: int
    points_dis: int
    radius: float

    def report(self) -> str:
        """The lines mmetric prints: the score, its PSNR and the one-frame statistics of both.

        Example:
            >>> r = PcqmResult(0.0, 0.0, math.inf, (0.0, 1.0, 1.0), 3, 3, 0.001)
            >>> print(r.report().splitlines()[1])
            PCQM-PSNR=inf
        """
        lines = [f"PCQM value is : {_g(self.pcqm)}", f"PCQM-PSNR={_g(self.psnr)}"]
        lines += _statistics(self.pcqm_float, "PCQM ") + _statistics(self.psnr, "PCQM-PSNR ")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, object]:
        """The figures by name (the keys of ``torchmeshmetric mpeg --mode pcqm --json``)."""
        return {
            "pcqm": self.pcqm,
            "pcqm_float": self.pcqm_float,
            "pcqm_psnr": self.psnr,
            "curvature_structure": self.features[0],
            "lightness": self.features[1],
            "lightness_structure": self.features[2],
            "points_ref": self.points_ref,
            "points_dis": self.points_dis,
            "radius": self.radius,
        }


def _max_dim(points: np.ndarray) -> float:
    """PCQM's box measure: the largest ``|min| + |max|`` over the axes (maxima started at DBL_MIN, as mmetric does)."""
    lo = points.min(axis=0)
    hi = np.maximum(points.max(axis=0), np.finfo(np.float64).tiny)
    return float(np.max(np.abs(lo) + np.abs(hi)))


def _psnr(score: float, diagonal: float) -> float:
    """The PCQM-PSNR of mmetric from the float32 score and the float32 box diagonal of A."""
    scaled = (score / 1.0) * diagonal
    mse = scaled * scaled
    with np.errstate(divide="ignore"):
        return float(10.0 * np.log10(np.float64(diagonal * diagonal) / np.float64(mse)))


def _check(radius_curvature: object, knn: int, radius_factor: object) -> tuple[float, float]:
    """The two radii as floats (numpy's numbers and one-element tensors too, as every numeric option), and ``knn``."""
    rc = check_positive_real(radius_curvature, "radius_curvature")
    rf = check_positive_real(radius_factor, "radius_factor")
    if isinstance(knn, bool) or not isinstance(knn, (int, np.integer)) or knn < 1:
        raise ValueError(f"knn: expected an integer >= 1, found {knn!r}")
    return rc, rf


def mpeg_pcqm(
    ref: PointCloud,
    dis: PointCloud,
    *,
    radius_curvature: float = 0.001,
    knn: int = 20,
    radius_factor: float = 2.0,
) -> PcqmResult:
    """PCQM of ``dis`` (mmetric's model B) against ``ref`` (model A), equal to ``mm compare --mode pcqm``.

    mm compares meshes as the point sets of its ``sampleIfNeeded``: pass ``vertex_sample(mesh)`` (or
    :func:`~torchmeshmetric.mpeg.load_model_cloud` for a file), whose points come in mmetric's order; the order
    matters, as PCQM keeps the first of equidistant points.

    Args:
        ref: ``(N, 3)`` cloud A (positions rounded to float32, as mmetric holds them) with optional ``(N, 3)`` RGB
            colours in ``[0, 255]`` (white without; truncated to integers, as PCQM does; others are refused).
        dis: ``(M, 3)`` cloud B, likewise.
        radius_curvature: mm's ``--radiusCurvature``: the curvature neighbourhood radius relative to A's box (a
            Python or numpy number, or a one-element tensor).
        knn: mm's ``--thresholdKnnSearch``: the neighbours of the projection quadric.
        radius_factor: mm's ``--radiusFactor``: the pooling radius over the curvature radius.

    Returns:
        :class:`PcqmResult`.

    Raises:
        EmptyInputError: a cloud without points.
        NonFiniteError: NaN or Inf colours.
        TypeError: a radius or factor that is not a real number.
        ValueError: a non-positive or non-finite radius or factor, ``knn < 1``, a cloud ``ref`` whose box measure
            is 0, colours outside ``[0, 255]`` (or all fractions of ``[0, 1]``: normalised colours), or radii whose
            pooling radius overflows (``radius_curvature * box measure * radius_factor`` infinite: mm prints
            ``-nan`` there).
        NativeBuildError: the C++ extension cannot be built here.

    Example:
        >>> pts = torch.rand(200, 3, generator=torch.Generator().manual_seed(0)) * torch.tensor([1.0, 1.0, 0.0])
        >>> r = mpeg_pcqm(PointCloud(pts), PointCloud(pts), radius_curvature=0.1)  # flat, same colour: no distortion
        >>> r.pcqm, r.psnr
        (0.0, inf)
    """
    radius_curvature, radius_factor = _check(radius_curvature, knn, radius_factor)
    for name, cloud in (("ref", ref), ("dis", dis)):
        if cloud.num_points == 0:
            raise EmptyInputError(f"{name}: expected a point cloud with points, found 0 points")
        if cloud.colors is not None:
            check_finite(cloud.colors, f"{name}.colors")
            check_rgb255(cloud.colors, f"{name}.colors")
    a = ref.points.detach().cpu().to(torch.float32).to(torch.float64).contiguous()
    b = dis.points.detach().cpu().to(torch.float32).to(torch.float64).contiguous()
    white = np.full((1, 3), 255.0)
    la = pcqm_lightness(ref.colors if ref.colors is not None else white)
    lb = pcqm_lightness(dis.colors if dis.colors is not None else white)
    la = np.broadcast_to(la, (a.shape[0],)).copy()
    lb = np.broadcast_to(lb, (b.shape[0],)).copy()
    max_dim = _max_dim(a.numpy())
    radius = radius_curvature * max_dim
    pooling = radius * radius_factor  # squared as a product (not **): an overflow is inf there, as in mm
    if pooling * pooling == 0.0:  # no point would be its own neighbour: PCQM's means would be 0/0
        raise ValueError(
            f"ref: PCQM's box measure (largest |min| + |max| over the axes) is {max_dim!r}, so the pooling radius "
            f"{radius * radius_factor!r} squares to 0; a cloud at the origin has no PCQM"
        )
    if not math.isfinite(pooling):  # mm prints -nan: the Gaussian weights divide inf by inf
        raise ValueError(
            f"radius_curvature, radius_factor: the pooling radius radius_curvature * box measure * radius_factor = "
            f"{radius_curvature!r} * {max_dim!r} * {radius_factor!r} overflows to {pooling!r}, so PCQM would be NaN "
            "(mm prints -nan); choose smaller radii"
        )
    # each thread fits its quadrics over knn neighbour slots (index, distance and a 6-column row: 64 bytes each);
    # PCQM pads the neighbours a cloud lacks with its point 0, so a knn above the points is valid, up to memory
    check_allocation(float(knn) * torch.get_num_threads(), 64, "knn", knn, "neighbour slots (knn per thread)")
    ext = native.load("pcqm")
    _, sums = ext.pcqm_fields(a, b, torch.from_numpy(la), torch.from_numpy(lb), radius, max_dim, int(knn),
                              float(radius_factor))  # fmt: skip
    f3, f4, f6 = (float(x) for x in sums.tolist())
    n = float(a.shape[0])
    score = f3 / n * _WEIGHTS[0] + (1.0 - f4 / n) * _WEIGHTS[1] + (1.0 - f6 / n) * _WEIGHTS[2]
    score_f32 = float(np.float32(score))
    diag = bbox_diagonal(ref.points.detach().cpu().to(torch.float32).numpy())
    return PcqmResult(
        pcqm=score,
        pcqm_float=score_f32,
        psnr=_psnr(score_f32, diag),
        features=(f3 / n, f4 / n, f6 / n),
        points_ref=int(a.shape[0]),
        points_dis=int(b.shape[0]),
        radius=radius,
    )
