"""Nearest neighbours with mmetric's distance arithmetic and its rule for equidistant neighbours.

mpeg-pcc-dmetric finds neighbours with a k-d tree whose squared distance subtracts the float32 coordinates in float32
and accumulates the squares in double; neighbours at the same squared distance as the nearest one (consecutive
differences below ``1e-20``, up to 30 of them) are averaged for the point-to-plane and colour terms. Exact ties are
common on grid-sampled clouds, so they are found here exactly: a double-precision k-d tree proposes candidates, their
distances are recomputed with dmetric's arithmetic, and only queries whose two nearest candidates are (nearly) equally
far are searched further.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

__all__ = ["NeighbourTies", "mpeg_sq_dists", "nearest_with_ties"]

_SIMILAR = 1e-20  # dmetric's similarPointThreshold (mmetric passes 1e-20)
_MAX_K = 30  # dmetric's num_results_max
_STEP_K = 5  # dmetric's num_results_incr


def mpeg_sq_dists(query: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Squared distances as dmetric computes them: float32 differences, squares summed in double.

    Args:
        query: ``(..., 3)`` float32 points.
        target: ``(..., 3)`` float32 points (broadcast against ``query``).

    Returns:
        ``(...)`` float64 squared distances.

    Example:
        >>> import numpy as np
        >>> float(mpeg_sq_dists(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))[0])
        3.0
    """
    d = (query - target).astype(np.float64)
    return (d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]) + d[..., 2] * d[..., 2]


@dataclass(frozen=True)
class NeighbourTies:
    """Nearest neighbours of every query point and, where several are equidistant, all of them.

    Attributes:
        nearest: ``(Q,)`` index of the nearest target point.
        sq_dist: ``(Q,)`` its squared distance (dmetric's arithmetic).
        rows: ``(S,)`` queries with more than one candidate at (nearly) the nearest distance.
        cand: ``(S, K)`` their candidates sorted by distance (``-1`` padding).
        chain: ``(S, K)`` candidates in dmetric's tie chain (consecutive distances within ``1e-20``).
        equal: ``(S, K)`` candidates exactly as far as the nearest (the rule of dmetric's normal transfer).
    """

    nearest: np.ndarray
    sq_dist: np.ndarray
    rows: np.ndarray
    cand: np.ndarray
    chain: np.ndarray
    equal: np.ndarray


def _sorted_candidates(query: np.ndarray, target: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    valid = idx < target.shape[0]
    safe = np.where(valid, idx, 0)
    sq = np.where(valid, mpeg_sq_dists(query[:, None, :], target[safe]), np.inf)
    order = np.argsort(sq, axis=1, kind="stable")
    return np.take_along_axis(np.where(valid, idx, -1), order, axis=1), np.take_along_axis(sq, order, axis=1)


def nearest_with_ties(query: np.ndarray, target: np.ndarray, tree: cKDTree | None = None) -> NeighbourTies:
    """Nearest target point of every query point, with dmetric's equidistant neighbours.

    Args:
        query: ``(Q, 3)`` float32 points.
        target: ``(T, 3)`` float32 points.
        tree: a ``cKDTree`` over ``target`` in float64 (built when omitted).

    Returns:
        :class:`NeighbourTies`.

    Example:
        >>> import numpy as np
        >>> t = np.array([[1, 0, 0], [-1, 0, 0], [5, 0, 0]], np.float32)
        >>> r = nearest_with_ties(np.zeros((1, 3), np.float32), t)
        >>> mask = r.chain[0]
        >>> sorted(r.cand[0, mask].tolist())
        [0, 1]
    """
    query = np.ascontiguousarray(query, dtype=np.float32)
    target = np.ascontiguousarray(target, dtype=np.float32)
    if tree is None:
        from scipy.spatial import cKDTree  # imported on use: keeps `import torchmeshmetric` light

        tree = cKDTree(target.astype(np.float64))
    k0 = min(2, target.shape[0])
    _, idx = tree.query(query.astype(np.float64), k=k0, workers=-1)
    idx = np.asarray(idx).reshape(query.shape[0], k0)
    cand, sq = _sorted_candidates(query, target, idx)
    nearest, sq0 = cand[:, 0].copy(), sq[:, 0].copy()
    if k0 < 2:
        empty = np.zeros((0, 1), dtype=bool)
        return NeighbourTies(nearest, sq0, np.zeros(0, np.int64), np.zeros((0, 1), np.int64), empty, empty)
    # The double-precision tree and dmetric's float32 differences may order near-ties differently: search further
    # wherever the two nearest are within a relative 1e-5 (far above the float32 rounding of a squared distance).
    suspect = np.flatnonzero(sq[:, 1] <= sq[:, 0] * (1.0 + 1e-5) + 1e-18)
    rows = suspect
    k = min(2 * _STEP_K, target.shape[0])
    qs = query[rows]
    _, idx = tree.query(qs.astype(np.float64), k=k, workers=-1)
    cand, sq = _sorted_candidates(qs, target, np.asarray(idx).reshape(rows.shape[0], k))
    # dmetric widens its search by 5 while all neighbours found are equally far (up to 30).
    while k + _STEP_K <= min(_MAX_K, target.shape[0]):
        wide = np.flatnonzero(sq[:, 0] == sq[:, -1])
        if wide.size == 0:
            break
        k += _STEP_K
        _, idx = tree.query(qs[wide].astype(np.float64), k=k, workers=-1)
        c2, s2 = _sorted_candidates(qs[wide], target, np.asarray(idx).reshape(wide.shape[0], k))
        pad = k - cand.shape[1]
        cand = np.pad(cand, ((0, 0), (0, pad)), constant_values=-1)
        sq = np.pad(sq, ((0, 0), (0, pad)), constant_values=np.inf)
        cand[wide], sq[wide] = c2, s2
    nearest[rows], sq0[rows] = cand[:, 0], sq[:, 0]
    step = np.abs(np.diff(sq, axis=1)) < _SIMILAR
    chain = np.concatenate([np.ones((rows.shape[0], 1), bool), np.cumprod(step, axis=1).astype(bool)], axis=1)
    equal = (sq == sq[:, :1]) & (cand >= 0)
    return NeighbourTies(nearest, sq0, rows, cand, chain & (cand >= 0), equal)
