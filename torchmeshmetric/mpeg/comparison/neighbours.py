"""Nearest neighbours with mmetric's distance arithmetic and its rule for equidistant neighbours.

mpeg-pcc-dmetric finds neighbours with a k-d tree whose squared distance subtracts the float32 coordinates in float32
and accumulates the squares in double; neighbours at the same squared distance as the nearest one (consecutive
differences below ``1e-20``, up to 30 of them) are averaged for the point-to-plane and colour terms. Exact ties are
common on grid-sampled clouds, so they are found exactly: the k nearest points are searched with that very
arithmetic (the C++ hierarchy's ``mpeg_knn``, or a chunked brute force where the extension cannot be built), ranked
by (squared distance, index), and only queries whose two nearest are within ``1e-20`` are searched further, widening
by 5 while all neighbours found are equally far, as dmetric does.

One known difference (docs/mpeg.md): where more than 30 target points are exactly as far as the nearest, dmetric
keeps the 30 its nanoflann k-d tree visits first, and this module the 30 lowest indices (of the merged cloud, sorted
by position); the colour and D2 errors of that query point then differ from mm's, its D1 never does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from torchmeshmetric import native
from torchmeshmetric._checks import EmptyInputError, ShapeError, check_int

__all__ = ["NeighbourTies", "k_nearest", "mpeg_sq_dists", "nearest_with_ties", "nearest_with_ties_both"]

_SIMILAR = 1e-20  # dmetric's similarPointThreshold (mmetric passes 1e-20)
_MAX_K = 30  # dmetric's num_results_max
_STEP_K = 5  # dmetric's num_results_incr
_KNN_MAX = 64  # the native k-nearest search's largest k (its fixed-size candidate lists)
_BRUTE_CHUNK = 1 << 24  # (query, target) pairs per block of the brute-force fallback


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
    for name, x in (("query", query), ("target", target)):
        if not isinstance(x, np.ndarray):  # a tensor failed on .astype (found by review)
            raise TypeError(f"{name}: expected a numpy array of (..., 3) points, found {type(x).__name__}")
        if x.ndim == 0 or x.shape[-1] != 3:  # (N, 2) points raised numpy's IndexError
            raise ShapeError(f"{name}: expected shape (..., 3), found {tuple(x.shape)}")
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

    Example:
        >>> targets = np.array([[1, 0, 0], [-1, 0, 0], [0, 2, 0]], np.float32)
        >>> t = nearest_with_ties(np.array([[0, 0, 0], [0, 1.9, 0]], np.float32), targets)
        >>> t.nearest.tolist(), t.rows.tolist(), t.equal.tolist()  # query 0: targets 0 and 1 tie at distance 1
        ([0, 2], [0], [[True, True, False]])
    """

    nearest: np.ndarray
    sq_dist: np.ndarray
    rows: np.ndarray
    cand: np.ndarray
    chain: np.ndarray
    equal: np.ndarray


def _k_nearest_brute(query: np.ndarray, target: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    q_n, t_n = query.shape[0], target.shape[0]
    idx = np.full((q_n, k), -1, np.int64)
    sq = np.full((q_n, k), np.inf)
    kk = min(k, t_n)
    step = max(1, _BRUTE_CHUNK // t_n)
    for s in range(0, q_n, step):
        d = mpeg_sq_dists(query[s : s + step, None, :], target[None, :, :])
        kth = np.partition(d, kk - 1, axis=1)[:, kk - 1]
        # every point at or below the k-th distance, by (distance, index): ties at rank k keep the lowest indices
        rows, cols = np.nonzero(d <= kth[:, None])
        order = np.lexsort((cols, d[rows, cols], rows))
        rows, cols = rows[order], cols[order]
        rank = np.arange(rows.shape[0]) - np.searchsorted(rows, rows)
        keep = rank < kk
        idx[s + rows[keep], rank[keep]] = cols[keep]
        sq[s + rows[keep], rank[keep]] = d[rows[keep], cols[keep]]
    return idx, sq


def k_nearest(query: np.ndarray, target: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest target points of every query point with dmetric's arithmetic, exactly.

    Ranked by (squared distance as :func:`mpeg_sq_dists` computes it, target index): of equidistant points the
    lowest indices come first, and none is lost to a rounding of another arithmetic.

    Args:
        query: ``(Q, 3)`` float32 points.
        target: ``(T, 3)`` float32 points, ``T >= 1``.
        k: neighbours per query, ``1 <= k <= 64``.

    Returns:
        ``(idx, sq)``: ``(Q, k)`` int64 indices and float64 squared distances, padded with ``-1`` / ``inf`` where
        ``k > T``.

    Example:
        >>> import numpy as np
        >>> t = np.array([[2, 0, 0], [1, 0, 0], [-1, 0, 0]], np.float32)
        >>> idx, sq = k_nearest(np.zeros((1, 3), np.float32), t, 2)
        >>> idx.tolist(), sq.tolist()
        ([[1, 2]], [[1.0, 1.0]])
    """
    k = check_int(k, "k", 1)  # 2.5 was a pybind error, 0 or -1 the C++ "mpeg_knn: k out of range"
    if k > _KNN_MAX:
        raise ValueError(f"k: expected an int in [1, {_KNN_MAX}], found {k}")
    query = np.ascontiguousarray(query, dtype=np.float32)
    target = np.ascontiguousarray(target, dtype=np.float32)
    for name, x in (("query", query), ("target", target)):
        if x.ndim != 2 or x.shape[1] != 3:
            raise ShapeError(f"{name}: expected shape ({name[0].upper()}, 3), found {tuple(x.shape)}")
    if target.shape[0] == 0:
        raise EmptyInputError("target: expected at least one point, found none")
    if query.shape[0] == 0:
        return np.zeros((0, k), np.int64), np.zeros((0, k))
    ext = native.try_load("bvh")
    if ext is None:
        return _k_nearest_brute(query, target, k)
    idx, sq = ext.mpeg_knn(torch.from_numpy(query), torch.from_numpy(target), k)
    return idx.numpy(), sq.numpy()


def nearest_with_ties(query: np.ndarray, target: np.ndarray) -> NeighbourTies:
    """Nearest target point of every query point, with dmetric's equidistant neighbours.

    At most 30 equidistant neighbours are kept, as in dmetric; of more, the 30 lowest target indices (dmetric keeps
    the 30 its k-d tree visits first: see the module docstring).

    Args:
        query: ``(Q, 3)`` float32 points.
        target: ``(T, 3)`` float32 points.

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
    ext = native.try_load("pcc")  # None without a C++ compiler: the k-nearest searches below
    if ext is not None and query.shape[0] > 0:
        nearest, sq0, rows, cand, sq = (
            t.numpy() for t in ext.mpeg_nearest_ties(torch.from_numpy(query), torch.from_numpy(target))
        )
        return _with_chains(nearest, sq0, rows, cand, sq)
    k0 = min(2, target.shape[0])
    cand, sq = k_nearest(query, target, k0)
    nearest, sq0 = cand[:, 0].copy(), sq[:, 0].copy()
    if k0 < 2:
        empty = np.zeros((0, 1), dtype=bool)
        return NeighbourTies(nearest, sq0, np.zeros(0, np.int64), np.zeros((0, 1), np.int64), empty, empty)
    rows = np.flatnonzero(sq[:, 1] - sq[:, 0] < _SIMILAR)
    k = min(2 * _STEP_K, target.shape[0])
    qs = query[rows]
    cand, sq = k_nearest(qs, target, k)
    # dmetric widens its search by 5 while all neighbours found are equally far (up to 30).
    while k + _STEP_K <= min(_MAX_K, target.shape[0]):
        wide = np.flatnonzero(sq[:, 0] == sq[:, -1])
        if wide.size == 0:
            break
        k += _STEP_K
        c2, s2 = k_nearest(qs[wide], target, k)
        pad = k - cand.shape[1]
        cand = np.pad(cand, ((0, 0), (0, pad)), constant_values=-1)
        sq = np.pad(sq, ((0, 0), (0, pad)), constant_values=np.inf)
        cand[wide], sq[wide] = c2, s2
    return _with_chains(nearest, sq0, rows, cand, sq)


def _with_chains(nearest: np.ndarray, sq0: np.ndarray, rows: np.ndarray, cand: np.ndarray,
                 sq: np.ndarray) -> NeighbourTies:  # fmt: skip
    """The tie chain (consecutive distances within ``1e-20``) and equal sets of the candidates of tie rows."""
    with np.errstate(invalid="ignore"):  # inf - inf between padding slots: NaN, no tie
        step = np.abs(np.diff(sq, axis=1)) < _SIMILAR
    chain = np.concatenate([np.ones((rows.shape[0], 1), bool), np.cumprod(step, axis=1).astype(bool)], axis=1)
    equal = (sq == sq[:, :1]) & (cand >= 0)
    return NeighbourTies(nearest, sq0, rows, cand, chain & (cand >= 0), equal)


def nearest_with_ties_both(a: np.ndarray, b: np.ndarray) -> tuple[NeighbourTies, NeighbourTies]:
    """:func:`nearest_with_ties` of ``a`` in ``b`` and of ``b`` in ``a``, each cloud's search tree built once.

    Args:
        a: ``(A, 3)`` float32 points, ``A >= 1``.
        b: ``(B, 3)`` float32 points, ``B >= 1``.

    Returns:
        ``(a -> b, b -> a)``.

    Example:
        >>> import numpy as np
        >>> ab, ba = nearest_with_ties_both(np.zeros((1, 3), np.float32), np.ones((2, 3), np.float32))
        >>> ab.nearest.tolist(), ba.nearest.tolist()
        ([0], [0, 0])
    """
    a = np.ascontiguousarray(a, dtype=np.float32)
    b = np.ascontiguousarray(b, dtype=np.float32)
    ext = native.try_load("pcc")
    if ext is None:  # no C++ compiler
        return nearest_with_ties(a, b), nearest_with_ties(b, a)
    out = [t.numpy() for t in ext.mpeg_nearest_ties_both(torch.from_numpy(a), torch.from_numpy(b))]
    return _with_chains(*out[:5]), _with_chains(*out[5:])
