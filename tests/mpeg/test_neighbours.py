"""k nearest neighbours with dmetric's arithmetic: the C++ search and the brute-force fallback against a float64
lexicographic reference, ties included."""

from __future__ import annotations

import numpy as np
import pytest

from torchmeshmetric import native
from torchmeshmetric.mpeg import k_nearest, mpeg_sq_dists, nearest_with_ties
from torchmeshmetric.mpeg.comparison import neighbours as nb
from torchmeshmetric.mpeg.comparison.neighbours import NeighbourTies, nearest_with_ties_both


def _reference(query: np.ndarray, target: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    d = mpeg_sq_dists(query[:, None, :], target[None, :, :])
    order = np.lexsort((np.broadcast_to(np.arange(target.shape[0]), d.shape), d), axis=1)[:, :k]
    return order, np.take_along_axis(d, order, axis=1)


def _clouds(seed: int, grid: bool, n_ref: int, n_query: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    ref = rng.random((n_ref, 3)).astype(np.float32) * 10 - 3
    query = rng.random((n_query, 3)).astype(np.float32) * 10 - 3
    if grid:  # lattice points: many exactly equidistant neighbours
        ref, query = np.round(ref * 2) / 2, np.round(query * 4) / 4
    return query.astype(np.float32), ref.astype(np.float32)


def _without_pcc(monkeypatch: pytest.MonkeyPatch) -> None:
    """The extension loader answering as on a machine without a C++ compiler, for the pcc extension alone."""
    load = native.try_load
    monkeypatch.setattr(native, "try_load", lambda name: None if name == "pcc" else load(name))


@pytest.fixture(params=["pcc", "cpp", "brute"])
def path(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    if request.param == "pcc":
        if native.try_load("pcc") is None:
            pytest.skip("C++ extension unavailable")
        return "pcc"
    _without_pcc(monkeypatch)  # the k-nearest searches of nearest_with_ties
    if request.param == "brute":
        monkeypatch.setattr(native, "try_load", lambda name: None)
        monkeypatch.setattr(nb, "_BRUTE_CHUNK", 5000)  # several blocks
    elif native.try_load("bvh") is None:
        pytest.skip("C++ extension unavailable")
    return str(request.param)


@pytest.mark.parametrize(("grid", "k"), [(False, 1), (False, 2), (True, 2), (True, 10), (True, 30)])
def test_k_nearest_matches_reference(path: str, grid: bool, k: int) -> None:
    query, ref = _clouds(k, grid, 700, 400)
    idx, sq = k_nearest(query, ref, k)
    want_idx, want_sq = _reference(query, ref, k)
    np.testing.assert_array_equal(idx, want_idx)
    np.testing.assert_array_equal(sq, want_sq)
    if grid:
        assert (sq[:, 1:] == sq[:, :1]).any(), "the lattice must produce ties"


def test_k_nearest_pads_when_k_exceeds_target(path: str) -> None:
    idx, sq = k_nearest(np.zeros((2, 3), np.float32), np.array([[1, 0, 0], [0, 2, 0]], np.float32), 4)
    assert idx.tolist() == [[0, 1, -1, -1]] * 2
    assert sq[0].tolist() == [1.0, 4.0, np.inf, np.inf]


def test_k_nearest_empty_query(path: str) -> None:
    idx, sq = k_nearest(np.zeros((0, 3), np.float32), np.ones((3, 3), np.float32), 2)
    assert idx.shape == (0, 2) and sq.shape == (0, 2)


def test_nearest_with_ties_chains(path: str) -> None:
    query, ref = _clouds(3, True, 500, 300)
    ties = nearest_with_ties(query, ref)
    want_idx, want_sq = _reference(query, ref, 30)
    np.testing.assert_array_equal(ties.nearest, want_idx[:, 0])
    np.testing.assert_array_equal(ties.sq_dist, want_sq[:, 0])
    tied = np.flatnonzero(want_sq[:, 1] - want_sq[:, 0] < 1e-20)
    np.testing.assert_array_equal(ties.rows, tied)
    for r, q in enumerate(ties.rows):
        n_equal = int((want_sq[q] == want_sq[q, 0]).sum())
        got = set(ties.cand[r, ties.equal[r]].tolist())
        # dmetric stops widening at 30 neighbours: up to 30 equidistant ones, lowest indices first
        assert got == set(want_idx[q, : min(n_equal, 30)].tolist())
        np.testing.assert_array_equal(ties.chain[r], ties.equal[r])  # lattice distances: chain == exact ties


def _same_ties(got: NeighbourTies, want: NeighbourTies) -> None:
    np.testing.assert_array_equal(got.nearest, want.nearest)
    np.testing.assert_array_equal(got.sq_dist, want.sq_dist)
    np.testing.assert_array_equal(got.rows, want.rows)
    for r in range(want.rows.shape[0]):
        for mask in ("chain", "equal"):
            np.testing.assert_array_equal(got.cand[r, getattr(got, mask)[r]], want.cand[r, getattr(want, mask)[r]])


def _tie_cases() -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(7)
    cases = []
    for n in (1, 2, 3, 9, 40, 1500):  # a lattice: up to 30+ equidistant neighbours, and targets smaller than k
        ref = rng.integers(0, 4, (n, 3)).astype(np.float32)
        cases.append(((rng.integers(0, 8, (300, 3)) / 2).astype(np.float32), ref))
    tiny = (rng.integers(-3, 3, (400, 3)) * 1e-30).astype(np.float32)  # distances near the 1e-20 threshold
    cases.append((tiny, tiny[::-1].copy()))
    cases.append(_clouds(11, False, 3000, 2000))
    # the column grid of the C++ search: a sheet (long columns, no extent along one axis), points on a line (no
    # extent along two), queries far outside the target's box (clamped columns), and a box far from the origin
    sheet = np.stack(np.meshgrid(np.arange(40), np.arange(30), [0.0], indexing="ij"), -1).reshape(-1, 3) * 0.25
    cases.append(((rng.random((400, 3)) * [10, 8, 1]).astype(np.float32), sheet.astype(np.float32)))
    line = np.zeros((200, 3), np.float32)
    line[:, 0] = rng.integers(0, 50, 200)
    cases.append(((rng.integers(0, 60, (300, 3)) / 3).astype(np.float32), line))
    cases.append(((rng.random((200, 3)) * 5 + 1000).astype(np.float32), rng.random((500, 3)).astype(np.float32)))
    # queries far from a lattice, equidistant to several of its points: the kd-tree answers both searches
    cube = np.stack(np.meshgrid(*[np.arange(3.0)] * 3, indexing="ij"), -1).reshape(-1, 3).astype(np.float32)
    cases.append(((np.array([[1, 1, 60], [0.5, 0.5, -40], [1, 80, 1]]) + rng.integers(0, 2, (3, 3)) / 2).astype(
        np.float32), cube))  # fmt: skip
    far = (1e5 + rng.integers(0, 40, (800, 3)) / 64).astype(np.float32)
    cases.append((far[:300] + np.float32(1 / 128), far))
    return cases


def test_pcc_search_equals_k_nearest_widening(monkeypatch: pytest.MonkeyPatch) -> None:
    """The one-pass C++ search (nearest, ties, dmetric's widening) equals the k-nearest searches it replaces."""
    if native.try_load("pcc") is None:
        pytest.skip("C++ extension unavailable")
    cases = _tie_cases()
    got = [nearest_with_ties_both(q, t) for q, t in cases]
    _without_pcc(monkeypatch)
    for (q, t), (ab, ba) in zip(cases, got, strict=True):
        _same_ties(ab, nearest_with_ties(q, t))
        _same_ties(ba, nearest_with_ties(t, q))
