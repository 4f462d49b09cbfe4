"""mmetric's point-cloud comparison (``compare --mode pcc``): D1/D2 MSE, PSNR and Hausdorff, and colour PSNR.

Re-implemented from the description of mpeg-pcc-dmetric's ``computeQualityMetric`` as mmetric v1.1.7 calls it
(``dropDuplicates=2``, ``neighborsProc=1``, ``bAverageNormals``, ``mseSpace=1``):

* both clouds are merged on equal positions (:func:`merge_duplicate_points`);
* ``ref -> dis`` loops over the reference and takes the nearest distorted point; ``dis -> ref`` the reverse;
* D1 of a point is its squared distance to the nearest point; D2 the mean, over the neighbours equally near, of the
  squared error projected on that neighbour's normal. mmetric sets dmetric's ``normalCalcModificationEnable``, so the
  distorted cloud's own (merged) normals are used; a distorted cloud without normals gets them *transferred from the
  reference* (each reference normal is added to its nearest distorted points; distorted points nobody chose take the
  mean normal of their nearest reference points), as dmetric does; without reference normals there is no D2;
* MSE is the mean over the looping cloud, Hausdorff the largest squared error (mmetric reports it squared), the
  symmetric figures the larger MSE / smaller PSNR of the two directions;
* colour: the mean colour of the equally near neighbours, rounded, converted to YCbCr (:func:`rgb_to_ycbcr`),
  squared difference per channel, PSNR with peak 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import torch

from torchmeshmetric import native
from torchmeshmetric._checks import EmptyInputError, ShapeError
from torchmeshmetric.mpeg.comparison.colour import rgb_to_ycbcr
from torchmeshmetric.mpeg.comparison.neighbours import NeighbourTies, nearest_with_ties_both
from torchmeshmetric.mpeg.comparison.psnr import check_mpeg_peak, mpeg_psnr
from torchmeshmetric.mpeg.core.point_cloud import PointCloud, merge_duplicate_points

__all__ = ["MpegDirection", "MpegPointErrors", "MpegResult", "PointErrors", "mpeg_compare", "mpeg_point_errors"]

_DBL_MIN = 2.2250738585072014e-308  # dmetric starts its running maxima at numeric_limits<double>::min()


@dataclass(frozen=True)
class MpegDirection:
    """One direction of the comparison (loop over one cloud, nearest points in the other).

    Attributes:
        d1_mse: point-to-point mean squared error.
        d2_mse: point-to-plane mean squared error (``nan`` without reference normals).
        d1_hausdorff: largest squared point-to-point error.
        d2_hausdorff: largest squared point-to-plane error.
        d1_psnr, d2_psnr, d1_hausdorff_psnr, d2_hausdorff_psnr: their PSNR (peak ``peak``, factor 3).
        color_mse: ``(Y, Cb, Cr)`` mean squared errors, or ``None`` without colours.
        color_psnr: their PSNR (peak 1), or ``None``.
        color_rgb_hausdorff: ``(R, G, B)`` largest squared difference (in 0..255 units) between a point's colour and
            its neighbours' averaged colour, or ``None`` without colours (dmetric's ``h.c[k]``).
        color_rgb_hausdorff_psnr: their PSNR (peak 255, factor 1).

    Example:
        >>> import torch
        >>> ref = PointCloud(torch.tensor([[0.0, 0, 0], [1, 0, 0]]), normals=torch.tensor([[0.0, 1, 0]] * 2))
        >>> dis = PointCloud(torch.tensor([[0.0, 0.1, 0], [1, 0, 0]]))  # one point 0.1 off the reference
        >>> d = mpeg_compare(ref, dis, peak=1.0).dis_to_ref  # each distorted point to its nearest reference point
        >>> round(d.d1_mse, 6), round(d.d1_hausdorff, 6), round(d.d1_psnr, 4), d.color_mse
        (0.005, 0.01, 27.7815, None)
    """

    d1_mse: float
    d2_mse: float
    d1_hausdorff: float
    d2_hausdorff: float
    d1_psnr: float
    d2_psnr: float
    d1_hausdorff_psnr: float
    d2_hausdorff_psnr: float
    color_mse: tuple[float, float, float] | None = None
    color_psnr: tuple[float, float, float] | None = None
    color_rgb_hausdorff: tuple[float, float, float] | None = None
    color_rgb_hausdorff_psnr: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class MpegResult:
    """mmetric's ``pcc`` figures: symmetric D1/D2 (and colour) with both directions.

    Attributes:
        peak: the PSNR peak (the reference's bounding-box diagonal unless given), rounded to float32 as mmetric.
        points_ref, points_dis: cloud sizes after duplicate merging.
        ref_to_dis, dis_to_ref: the two directions.

    Example:
        >>> import torch
        >>> ref = PointCloud(torch.tensor([[0.0, 0, 0], [1, 0, 0]]), normals=torch.tensor([[0.0, 1, 0]] * 2))
        >>> dis = PointCloud(torch.tensor([[0.0, 0.1, 0], [1, 0, 0]]))  # one point 0.1 off the reference
        >>> r = mpeg_compare(ref, dis, peak=1.0)
        >>> r.peak, r.points_ref, r.points_dis, round(r.symmetric.d1_mse, 6)
        (1.0, 2, 2, 0.005)
    """

    peak: float
    points_ref: int
    points_dis: int
    ref_to_dis: MpegDirection
    dis_to_ref: MpegDirection
    symmetric: MpegDirection = field(init=False)

    def __post_init__(self) -> None:
        a, b = self.ref_to_dis, self.dis_to_ref
        color_mse = color_psnr = None
        if a.color_mse is not None and b.color_mse is not None and a.color_psnr and b.color_psnr:
            color_mse = tuple(max(x, y) for x, y in zip(a.color_mse, b.color_mse, strict=True))
            color_psnr = tuple(min(x, y) for x, y in zip(a.color_psnr, b.color_psnr, strict=True))
        rgb_h = rgb_h_psnr = None
        ha, hb, pa, pb = (
            a.color_rgb_hausdorff,
            b.color_rgb_hausdorff,
            a.color_rgb_hausdorff_psnr,
            b.color_rgb_hausdorff_psnr,
        )
        if ha and hb and pa and pb:
            rgb_h = tuple(max(x, y) for x, y in zip(ha, hb, strict=True))
            rgb_h_psnr = tuple(min(x, y) for x, y in zip(pa, pb, strict=True))
        sym = MpegDirection(
            d1_mse=max(a.d1_mse, b.d1_mse),
            d2_mse=max(a.d2_mse, b.d2_mse),
            d1_hausdorff=max(a.d1_hausdorff, b.d1_hausdorff),
            d2_hausdorff=max(a.d2_hausdorff, b.d2_hausdorff),
            d1_psnr=min(a.d1_psnr, b.d1_psnr),
            d2_psnr=min(a.d2_psnr, b.d2_psnr),
            d1_hausdorff_psnr=min(a.d1_hausdorff_psnr, b.d1_hausdorff_psnr),
            d2_hausdorff_psnr=min(a.d2_hausdorff_psnr, b.d2_hausdorff_psnr),
            color_mse=color_mse,  # type: ignore[arg-type]
            color_psnr=color_psnr,  # type: ignore[arg-type]
            color_rgb_hausdorff=rgb_h,  # type: ignore[arg-type]
            color_rgb_hausdorff_psnr=rgb_h_psnr,  # type: ignore[arg-type]
        )
        object.__setattr__(self, "symmetric", sym)

    def to_dict(self) -> dict[str, object]:
        """Flat figures (symmetric) plus both directions, with the keys of ``torchmeshmetric mpeg --json``.

        Example:
            >>> import torch
            >>> pc = PointCloud(torch.tensor([[0.0, 0, 0], [1, 0, 0]]), normals=torch.tensor([[0.0, 0, 1]] * 2))
            >>> d = mpeg_compare(pc, pc).to_dict()
            >>> d["d1_psnr"], d["points_ref"]
            (inf, 2)
        """

        def one(d: MpegDirection) -> dict[str, object]:
            out: dict[str, object] = {
                "d1_mse": d.d1_mse,
                "d2_mse": d.d2_mse,
                "d1_psnr": d.d1_psnr,
                "d2_psnr": d.d2_psnr,
                "d1_hausdorff": d.d1_hausdorff,
                "d2_hausdorff": d.d2_hausdorff,
                "d1_hausdorff_psnr": d.d1_hausdorff_psnr,
                "d2_hausdorff_psnr": d.d2_hausdorff_psnr,
            }
            if d.color_mse is not None and d.color_psnr is not None:
                for name, m, p in zip(("y", "cb", "cr"), d.color_mse, d.color_psnr, strict=True):
                    out[f"{name}_mse"] = m
                    out[f"{name}_psnr"] = p
            return out

        flat = one(self.symmetric)
        flat.update(
            peak=self.peak,
            points_ref=self.points_ref,
            points_dis=self.points_dis,
            ref_to_dis=one(self.ref_to_dis),
            dis_to_ref=one(self.dis_to_ref),
        )
        return flat


def _tie_lists(t: NeighbourTies, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flattened (query row, target index) pairs of the tie sets selected by ``mask`` (``chain`` or ``equal``)."""
    q = t.nearest.shape[0]
    single = np.ones(q, dtype=bool)
    single[t.rows] = False
    rows_s = np.flatnonzero(single)
    r, c = np.nonzero(mask)
    rows = np.concatenate([rows_s, t.rows[r]])
    cols = np.concatenate([t.nearest[rows_s], t.cand[r, c]])
    order = np.lexsort((np.concatenate([np.zeros(rows_s.size, np.int64), c]), rows))
    return rows[order], cols[order]


def _transfer_normals(
    ref_normals: np.ndarray, dis_count: int, ref_to_dis: NeighbourTies, dis_to_ref: NeighbourTies
) -> np.ndarray:
    """Distorted normals from the reference ones, as dmetric's ``scaleNormals`` (exactly equidistant neighbours)."""
    rows, cols = _tie_lists(ref_to_dis, ref_to_dis.equal)
    acc = np.zeros((dis_count, 3), dtype=np.float32)
    np.add.at(acc, cols, ref_normals[rows])
    counts = np.bincount(cols, minlength=dis_count)
    out = acc / np.maximum(counts, 1).astype(np.float32)[:, None]
    lonely = counts == 0
    if lonely.any():
        rows2, cols2 = _tie_lists(dis_to_ref, dis_to_ref.equal)
        keep = lonely[rows2]
        acc2 = np.zeros((dis_count, 3), dtype=np.float32)
        np.add.at(acc2, rows2[keep], ref_normals[cols2[keep]])
        num = np.bincount(rows2[keep], minlength=dis_count).astype(np.float32)
        out[lonely] = acc2[lonely] / num[lonely][:, None]
    return out.astype(np.float32)


def _tie_rows(ties: NeighbourTies) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(row, target) pairs of the queries with a tie chain, in chain order, and their position among the tie rows."""
    r, c = np.nonzero(ties.chain)  # row-major: each row's chain in rank order
    return ties.rows[r], ties.cand[r, c], r


def _per_point_d2(qp: np.ndarray, tp: np.ndarray, nrm: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Dmetric's squared point-to-plane error of each (query, neighbour) pair, float32 then double."""
    ext = native.try_load("pcc")
    if ext is not None:  # the same float32 operations without the gathered copies
        t = [torch.from_numpy(np.ascontiguousarray(a)) for a in (qp, tp, nrm)]
        ij = [torch.from_numpy(np.ascontiguousarray(a, dtype=np.int64)) for a in (rows, cols)]
        return ext.mpeg_plane_errors(*t, *ij).numpy()
    diff = qp[rows] - tp[cols]  # float32, as dmetric
    n = nrm[cols]
    proj = (diff[:, 0] * n[:, 0] + diff[:, 1] * n[:, 1]) + diff[:, 2] * n[:, 2]
    per = (proj * proj).astype(np.float64)
    bad = np.isnan(n).any(axis=1)
    if bad.any():  # dmetric's fallback for a NaN normal: the plain sum of the error's components
        per[bad] = ((diff[bad, 0] + diff[bad, 1]) + diff[bad, 2]).astype(np.float64)
    return per


class PointErrors(NamedTuple):
    """Each point's errors in one direction of the comparison (the terms of :class:`MpegDirection`'s means).

    Attributes:
        d1: ``(N,)`` squared distance of each query point to its nearest target point.
        d2: ``(N,)`` squared point-to-plane error (the mean over equally near neighbours), or ``None`` without
            target normals.
        color: ``(N, 3)`` squared Y, Cb, Cr error (colours in ``[0, 1]``), or ``None`` without colours.
        rgb: ``(N, 3)`` squared R, G, B difference (0..255 units) to the neighbours' averaged colour, or ``None``.

    Example:
        >>> import torch
        >>> ref = PointCloud(torch.tensor([[0.0, 0, 0], [1, 0, 0]]), normals=torch.tensor([[0.0, 1, 0]] * 2))
        >>> dis = PointCloud(torch.tensor([[0.0, 0.1, 0], [1, 0, 0]]))  # one point 0.1 off the reference
        >>> e = mpeg_point_errors(ref, dis).dis_to_ref
        >>> e.d1.round(6).tolist(), e.d2.round(6).tolist(), e.color, e.rgb
        ([0.01, 0.0], [0.01, 0.0], None, None)
    """

    d1: np.ndarray
    d2: np.ndarray | None
    color: np.ndarray | None
    rgb: np.ndarray | None


def _point_errors(
    query: PointCloud, target: PointCloud, target_normals: np.ndarray | None, ties: NeighbourTies, with_color: bool
) -> PointErrors:
    # Every query averages over its chain of equally near neighbours; almost all chains hold the nearest point
    # alone, so the figures are computed for the nearest first and recomputed for the few tie rows. The sums start
    # at 0.0 and run in chain order, as dmetric's (0.0 + x is x, so a single neighbour's term is unchanged).
    qp = query.points.numpy()
    tp = target.points.numpy()
    n = qp.shape[0]
    all_rows = np.arange(n)
    t_rows, t_cols, t_pos = _tie_rows(ties)
    t_counts = np.bincount(t_pos, minlength=ties.rows.shape[0])
    d2 = None
    if target_normals is not None:
        d2 = 0.0 + _per_point_d2(qp, tp, target_normals, all_rows, ties.nearest)
        if ties.rows.size:
            per = _per_point_d2(qp, tp, target_normals, t_rows, t_cols)
            d2[ties.rows] = np.bincount(t_pos, weights=per, minlength=ties.rows.shape[0]) / t_counts
    sq = rgb_sq = None
    if with_color and query.colors is not None and target.colors is not None:
        tc = target.colors.numpy().astype(np.int64)
        mean = tc[ties.nearest].astype(np.float64)  # floor(x + 0.5) of an integer is the integer
        if ties.rows.size:
            sums = np.stack([np.bincount(t_pos, weights=tc[t_cols, k], minlength=ties.rows.shape[0])
                             for k in range(3)], axis=1)  # fmt: skip
            mean[ties.rows] = np.floor(sums / t_counts[:, None] + 0.5)  # round() of a non-negative double
        yuv_q = rgb_to_ycbcr(query.colors.numpy())
        yuv_t = rgb_to_ycbcr(mean)
        e = yuv_q - yuv_t
        sq = (e * e).astype(np.float64)
        # dmetric's RGB Hausdorff: integer differences squared
        rgb_err = query.colors.numpy().astype(np.float64) - mean
        rgb_sq = rgb_err * rgb_err
    return PointErrors(ties.sq_dist, d2, sq, rgb_sq)


def _direction(
    query: PointCloud,
    target: PointCloud,
    target_normals: np.ndarray | None,
    ties: NeighbourTies,
    peak: float,
    with_color: bool,
) -> MpegDirection:
    e = _point_errors(query, target, target_normals, ties, with_color)
    n = e.d1.shape[0]
    d1_mse = float(np.sum(e.d1)) / n
    d1_h = max(_DBL_MIN, float(e.d1.max()))
    d2_mse = d2_h = math.nan
    if e.d2 is not None:
        d2_mse = float(np.sum(e.d2)) / n
        d2_h = max(_DBL_MIN, float(e.d2.max()))
    color_mse = color_psnr = rgb_h = rgb_h_psnr = None
    if e.color is not None and e.rgb is not None:
        cm = tuple(float(v) for v in e.color.sum(axis=0) / n)
        color_mse = (cm[0], cm[1], cm[2])
        color_psnr = (mpeg_psnr(cm[0], 1.0, 1.0), mpeg_psnr(cm[1], 1.0, 1.0), mpeg_psnr(cm[2], 1.0, 1.0))
        # the running maximum starts at DBL_MIN, as dmetric's
        hm = np.maximum(e.rgb.max(axis=0), _DBL_MIN)
        rgb_h = (float(hm[0]), float(hm[1]), float(hm[2]))
        rgb_h_psnr = (mpeg_psnr(rgb_h[0], 255.0, 1.0), mpeg_psnr(rgb_h[1], 255.0, 1.0), mpeg_psnr(rgb_h[2], 255.0, 1.0))
    return MpegDirection(
        d1_mse=d1_mse,
        d2_mse=d2_mse,
        d1_hausdorff=d1_h,
        d2_hausdorff=d2_h,
        d1_psnr=mpeg_psnr(d1_mse, peak),
        d2_psnr=mpeg_psnr(d2_mse, peak) if not math.isnan(d2_mse) else math.nan,
        d1_hausdorff_psnr=mpeg_psnr(d1_h, peak),
        d2_hausdorff_psnr=mpeg_psnr(d2_h, peak) if not math.isnan(d2_h) else math.nan,
        color_mse=color_mse,
        color_psnr=color_psnr,
        color_rgb_hausdorff=rgb_h,
        color_rgb_hausdorff_psnr=rgb_h_psnr,
    )


def bbox_diagonal(points: np.ndarray) -> float:
    """The bounding-box diagonal of float32 points in float32 arithmetic (mmetric's default PSNR peak).

    Args:
        points: ``(N, 3)`` points, ``N >= 1`` (the box's extent is rounded to float32 before the diagonal).

    Returns:
        The diagonal of the axis-aligned bounding box, a float32 value as a Python float.

    Raises:
        EmptyInputError: no point (numpy said "zero-size array to reduction operation maximum which has no
            identity", naming no argument).
        ShapeError: ``points`` is not ``(N, 3)``.

    Example:
        >>> bbox_diagonal(np.array([[0, 0, 0], [3, 4, 0]], np.float32))
        5.0
    """
    points = np.asarray(points)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ShapeError(f"points: expected shape (N, 3), found {tuple(points.shape)}")
    if points.shape[0] == 0:
        raise EmptyInputError("points: expected at least one point, found an empty point set")
    d = (points.max(axis=0) - points.min(axis=0)).astype(np.float32)
    return float(np.sqrt((d[0] * d[0] + d[1] * d[1]) + d[2] * d[2], dtype=np.float32))


def mpeg_compare(ref: PointCloud, dis: PointCloud, *, peak: float | None = None) -> MpegResult:
    """Compare two point clouds as ``mm compare --mode pcc --hausdorff`` does (D1, D2, Hausdorff, colour).

    Args:
        ref: the reference cloud (its normals drive D2; without them D2 is ``nan``).
        dis: the distorted cloud (its own normals are not used, as in mmetric).
        peak: PSNR peak, a positive finite number; default the reference cloud's bounding-box diagonal. Rounded to
            float32 as mmetric does. A reference whose box is one point has a zero diagonal: its geometry PSNRs are
            then mmetric's ``-inf`` (NaN where the error is 0 too), the colour PSNRs are unaffected.

    Returns:
        :class:`MpegResult`.

    Raises:
        EmptyInputError: a cloud is empty.
        TypeError: ``peak`` is not a real number.
        ValueError: ``peak`` is not positive and finite in float32; colours outside ``[0, 255]``.

    Example:
        >>> import torch
        >>> ref = PointCloud(torch.tensor([[0.0, 0, 0], [1, 0, 0]]), normals=torch.tensor([[0.0, 1, 0]] * 2))
        >>> dis = PointCloud(torch.tensor([[0.0, 0.1, 0], [1, 0, 0]]))
        >>> r = mpeg_compare(ref, dis, peak=1.0)
        >>> round(r.symmetric.d1_mse, 6), round(r.symmetric.d2_mse, 6)
        (0.005, 0.005)
    """
    given = None if peak is None else check_mpeg_peak(peak)  # before the search it would waste
    m = _matched(ref, dis)  # before the default peak: it names an empty cloud ("ref"/"dis")
    # a one-point reference box gives 0 here: mmetric's -inf (NaN for a zero error), see mpeg_psnr
    peak = bbox_diagonal(ref.points.detach().cpu().numpy().astype(np.float32)) if given is None else given
    return MpegResult(
        peak=peak,
        points_ref=m.ref.num_points,
        points_dis=m.dis.num_points,
        ref_to_dis=_direction(m.ref, m.dis, m.dis_normals, m.ref_ties, peak, m.with_color),
        dis_to_ref=_direction(m.dis, m.ref, m.ref_normals, m.dis_ties, peak, m.with_color),
    )


class _Matched(NamedTuple):
    """Both clouds merged, their nearest neighbours with ties, and the normals each direction projects on."""

    ref: PointCloud
    dis: PointCloud
    ref_ties: NeighbourTies
    dis_ties: NeighbourTies
    ref_normals: np.ndarray | None
    dis_normals: np.ndarray | None
    with_color: bool


def _matched(ref: PointCloud, dis: PointCloud) -> _Matched:
    a = merge_duplicate_points(ref, "ref")
    b = merge_duplicate_points(dis, "dis")
    ap = a.points.numpy()
    bp = b.points.numpy()
    ab, ba = nearest_with_ties_both(ap, bp)
    na = a.normals.numpy() if a.normals is not None else None
    nb: np.ndarray | None = None
    if na is not None:
        # mmetric enables dmetric's normalCalcModificationEnable: the distorted cloud's own normals when it has them,
        # otherwise normals transferred from the reference.
        nb = b.normals.numpy() if b.normals is not None else _transfer_normals(na, bp.shape[0], ab, ba)
    return _Matched(a, b, ab, ba, na, nb, a.colors is not None and b.colors is not None)


class MpegPointErrors(NamedTuple):
    """The per-point errors behind :func:`mpeg_compare`'s figures (mmetric's per-point output, m69466).

    Attributes:
        ref: the reference cloud after duplicate merging (sorted by position): the points of ``ref_to_dis``.
        dis: the distorted cloud after merging: the points of ``dis_to_ref``.
        ref_to_dis: each reference point's errors against the distorted cloud.
        dis_to_ref: each distorted point's errors against the reference.

    Example:
        >>> import torch
        >>> ref = PointCloud(torch.tensor([[0.0, 0, 0], [1, 0, 0]]), normals=torch.tensor([[0.0, 1, 0]] * 2))
        >>> dis = PointCloud(torch.tensor([[0.0, 0.1, 0], [1, 0, 0]]))  # one point 0.1 off the reference
        >>> e = mpeg_point_errors(ref, dis)
        >>> e.ref.num_points, e.ref_to_dis.d1.round(6).tolist(), e.dis_to_ref.d1.round(6).tolist()
        (2, [0.01, 0.0], [0.01, 0.0])
    """

    ref: PointCloud
    dis: PointCloud
    ref_to_dis: PointErrors
    dis_to_ref: PointErrors


def mpeg_point_errors(ref: PointCloud, dis: PointCloud) -> MpegPointErrors:
    """Every point's D1, D2 and colour errors of ``mm compare --mode pcc``, both directions.

    The means of these arrays (in their order, float64) are the MSEs of :func:`mpeg_compare`, so a per-point view
    (a per-face map, a histogram) adds up to the reported figures.

    Args:
        ref: the reference cloud (its normals drive the distorted points' D2; without them ``d2`` is ``None``).
        dis: the distorted cloud.

    Returns:
        :class:`MpegPointErrors`: both clouds after duplicate merging and each point's errors in both directions
        (``d1``, ``d2`` ``(N,)``, ``color``, ``rgb`` ``(N, 3)`` or ``None``).

    Raises:
        EmptyInputError: a cloud is empty.

    Example:
        >>> import torch
        >>> ref = PointCloud(torch.tensor([[0.0, 0, 0], [1, 0, 0]]), normals=torch.tensor([[0.0, 1, 0]] * 2))
        >>> dis = PointCloud(torch.tensor([[0.0, 0.1, 0], [1, 0, 0]]))
        >>> e = mpeg_point_errors(ref, dis)
        >>> e.dis_to_ref.d1.round(6).tolist(), float(e.dis_to_ref.d1.mean()) == mpeg_compare(ref, dis).dis_to_ref.d1_mse
        ([0.01, 0.0], True)
    """
    m = _matched(ref, dis)
    return MpegPointErrors(
        m.ref,
        m.dis,
        _point_errors(m.ref, m.dis, m.dis_normals, m.ref_ties, m.with_color),
        _point_errors(m.dis, m.ref, m.ref_normals, m.dis_ties, m.with_color),
    )
