"""The C++ farthest-point sampling (a k-d tree that skips the boxes no new centre can reach) chooses the same points
in the same order as the plain loop, bit for bit: ties, lattices, duplicates, degenerate clouds, coordinates whose
squares underflow or overflow, float32 and float64.

The reference is the plain loop, written here one numpy operation at a time: the operations of
``deformation_graph._fps``'s torch loop (also checked against it below) and of the C++ loop before its k-d tree.
A point whose dmin the tree failed to lower, or a tie broken by the wrong index, changes the next choices.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.registration.gt_pairs import figure_sdf, mesh_level_set
from torchmeshmetric import native
from torchmeshmetric.registration import deformation_graph as graph

LEAF = 128
"""FPS_LEAF of deformation_energy.cpp: the clouds below hold many leaves, so the skips and merges are exercised."""


def _ext() -> Any:
    ext = native.try_load("bvh")
    assert ext is not None
    return ext


def _reference(p: np.ndarray, start: int, s2: float) -> list[int]:
    """The plain loop: dmin the running minimum of (dx*dx + dy*dy) + dz*dz (dx = p_i - c) rounded in the points'
    dtype, each choice the first maximum of dmin, until float(dmin[far]) <= s2."""

    def sq(c: int) -> np.ndarray:
        d = p - p[c]
        with np.errstate(over="ignore", under="ignore"):  # the squares of the huge and tiny clouds
            return (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2]

    chosen = [start]
    dmin = sq(start)
    while True:
        far = int(np.argmax(dmin))
        if float(dmin[far]) <= s2:
            return chosen
        chosen.append(far)
        dmin = np.minimum(dmin, sq(far))


def _check(p: np.ndarray, start: int, s2: float) -> torch.Tensor:
    assert np.isfinite(p).all()  # with a NaN or infinite coordinate neither loop ever stops (its dmin stays NaN / inf)
    got = _ext().farthest_point_sampling(torch.from_numpy(np.ascontiguousarray(p)), start, s2)
    want = _reference(p, start, s2)
    assert got.tolist() == want
    return got


def _cloud(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
    """``(n, 3)`` float64 points of one shape, coordinates about [0, 1]."""
    if kind == "uniform":
        return rng.random((n, 3))
    if kind == "clustered":  # tight blobs far apart: whole subtrees skipped, leaves straddling blobs
        centres = rng.random((6, 3)) * 10
        return centres[rng.integers(0, 6, n)] + rng.normal(size=(n, 3)) * 1e-3
    if kind == "lattice":  # integer points: masses of equal distances, ties across leaves
        return rng.integers(0, 7, (n, 3)).astype(np.float64)
    if kind == "duplicates":  # each point stored several times, scattered
        base = rng.random((max(n // 4, 1), 3))
        return base[rng.integers(0, base.shape[0], n)]
    if kind == "collinear":
        return rng.random((n, 1)) * np.array([[1.0, -2.0, 0.5]])
    if kind == "planar":
        return np.concatenate([rng.integers(0, 20, (n, 2)).astype(np.float64), np.zeros((n, 1))], 1)
    if kind == "mixed_scales":  # magnitudes 1e-15 .. 1e15 in one cloud
        return rng.random((n, 3)) * 10.0 ** rng.integers(-15, 16, (n, 1))
    raise AssertionError(kind)


KINDS = ["uniform", "clustered", "lattice", "duplicates", "collinear", "planar", "mixed_scales"]


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("kind", KINDS)
def test_every_point_in_the_loops_order(kind: str, dtype: type) -> None:
    """s2 = 0: the whole farthest-point order of every distinct point."""
    rng = np.random.default_rng(KINDS.index(kind))
    p = _cloud(kind, 2500, rng).astype(dtype)
    chosen = _check(p, int(rng.integers(0, p.shape[0])), 0.0)
    assert chosen.numel() == np.unique(p, axis=0).shape[0]


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_a_grid_with_every_distance_tied(dtype: type) -> None:
    """A 16^3 grid stored shuffled and twice: each choice is the first of hundreds of equal maxima."""
    g = np.stack(np.meshgrid(*[np.arange(16.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    rng = np.random.default_rng(3)
    p = np.concatenate([g, g])[rng.permutation(2 * g.shape[0])].astype(dtype)
    _check(p, 0, 0.0)
    _check(p, 1234, 3.0)
    _check(np.ascontiguousarray(np.concatenate([g, g]).astype(dtype)), 4095, 0.0)  # stored in grid order


SCALES = [(np.float32, s) for s in (1e-40, 1e-20, 0.1, 1.0, 1e20)]
SCALES += [(np.float64, s) for s in (1e-300, 1e-150, 1e-20, 0.1, 1.0, 1e20, 1e150, 1e300)]


@pytest.mark.parametrize(("dtype", "scale"), SCALES)
def test_coordinates_whose_squares_underflow_or_overflow(dtype: type, scale: float) -> None:
    """Squares that are subnormal, flushed to zero or infinite (float32 at 1e-20 and 1e20, float64 at 1e-150 and
    1e300; 1e-40 float32 and 1e-300 float64 coordinates are subnormal or nearly): many equal dmin, box bounds of 0
    or inf; and a lattice at an inexact scale (0.1), whose rounded distances tie and nearly tie with the box bounds
    (a bound off by a few ulps fails here)."""
    rng = np.random.default_rng(5)
    for kind in ("uniform", "lattice", "clustered"):
        p = (_cloud(kind, 1500, rng) * scale).astype(dtype)
        _check(p, 7, 0.0)
        _check(p, 7, min(scale * 0.03, 1e150) ** 2)  # 1e300 at scale 1e300: the points whose dmin is inf


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_degenerate_clouds(dtype: type) -> None:
    rng = np.random.default_rng(6)
    assert _check(np.zeros((1, 3), dtype), 0, 0.0).tolist() == [0]  # one point
    assert _check(np.full((1000, 3), 0.25, dtype), 500, 0.0).tolist() == [500]  # all equal: the start only
    two = np.zeros((700, 3), dtype)
    two[rng.permutation(700)[:350]] = 1.0  # two distinct points, each 350 times
    _check(two, 0, 0.0)
    _check(two, 699, 0.0)
    _check(rng.random((LEAF, 3)).astype(dtype), 3, 0.0)  # one leaf
    _check(rng.random((LEAF + 1, 3)).astype(dtype), LEAF, 0.0)  # two leaves


@settings(max_examples=60, deadline=None)
@given(
    kind=st.sampled_from(KINDS),
    n=st.integers(1, 1500),
    seed=st.integers(0, 2**32 - 1),
    dtype=st.sampled_from([np.float32, np.float64]),
    exponent=st.sampled_from([-20, -3, 0, 3, 20]),
    radius=st.sampled_from([0.0, 0.01, 0.1, 0.5]),
    start=st.floats(0, 1, exclude_max=True),
)
def test_random_clouds(kind: str, n: int, seed: int, dtype: type, exponent: int, radius: float, start: float) -> None:
    rng = np.random.default_rng(seed)
    p = (_cloud(kind, n, rng) * 10.0**exponent).astype(dtype)
    s2 = (radius * 10.0**exponent) ** 2
    _check(p, int(start * n), s2)


@pytest.fixture(scope="module")
def performer() -> np.ndarray:
    """The 17k source vertices of the evaluation's ground-truth pair (make_pair("medium", 0.0145))."""
    verts, _ = mesh_level_set(figure_sdf, 0.0145)
    return verts


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_the_performer_as_the_registration_samples_it(performer: np.ndarray, dtype: torch.dtype) -> None:
    """Canonical coordinate order and stored order, to the radii of ~1.1k and ~2.1k choices the registration asks;
    also the library's torch loop (the extension bypassed)."""
    p = torch.from_numpy(performer).to(dtype)
    _, q, start = graph._canonical_start(p)
    assert _check(q.numpy(), start, 0.0356**2).numel() == 1069
    assert _check(q.numpy(), start, 0.025**2).numel() > 2000
    _check(p.numpy(), 11, 0.0305**2)
    fast = graph._fps(q, start, 0.0356)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(native, "try_load", lambda name: None)
        assert torch.equal(fast, graph._fps(q, start, 0.0356))


def test_arguments_are_checked() -> None:
    ext = _ext()
    with pytest.raises(RuntimeError, match=r"\(N, 3\) points"):
        ext.farthest_point_sampling(torch.zeros(0, 3, dtype=torch.float64), 0, 0.0)
    with pytest.raises(RuntimeError, match=r"\(N, 3\) points"):
        ext.farthest_point_sampling(torch.zeros(4, 2, dtype=torch.float64), 0, 0.0)
    with pytest.raises(RuntimeError, match="start out of range"):
        ext.farthest_point_sampling(torch.zeros(4, 3, dtype=torch.float64), 4, 0.0)


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_a_non_finite_coordinate_is_refused_not_looped_on(bad: float) -> None:
    """A NaN or Inf coordinate never let the sampling stop: the C++ and the torch loop ran forever, growing."""
    from torchmeshmetric._checks import NonFiniteError

    p = torch.rand(50, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    p[17, 1] = bad
    with pytest.raises(NonFiniteError, match=r"points: expected finite values, found 1 NaN/Inf"):
        graph.farthest_point_nodes(p, 0.1)
    with pytest.raises(NonFiniteError, match=r"points: expected finite values, found 1 NaN/Inf"):
        graph.farthest_point_nodes(p, 0.1, canonical=True)
    with pytest.raises(NonFiniteError, match=r"points: expected finite values, found 1 NaN/Inf"):
        graph.canonical_farthest_points(p, 10, 1.0)


@pytest.mark.parametrize("spacing", [float("nan"), -0.1, float("inf")])
def test_a_spacing_that_is_no_radius_is_refused(spacing: float) -> None:
    p = torch.rand(50, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    with pytest.raises(ValueError, match=r"spacing: expected a finite covering radius >= 0"):
        graph.farthest_point_nodes(p, spacing)


@pytest.mark.parametrize(
    ("count", "area", "error", "message"),
    [
        (10, float("inf"), ValueError, r"area: expected a finite area >= 0, found inf"),
        (10, float("nan"), ValueError, r"area: expected a finite area >= 0, found nan"),
        (10, -1.0, ValueError, r"area: expected a finite area >= 0, found -1.0"),
        (-3, 1.0, ValueError, r"count: expected an int >= 0, found -3"),
        (2.5, 1.0, TypeError, r"count: expected an int, found float 2.5"),  # check_int's rule: a float is a TypeError
    ],
)
def test_canonical_farthest_points_checks_count_and_area(
    count: Any, area: float, error: type[Exception], message: str
) -> None:
    """An infinite or NaN area never let the passes stop (review P: the radius stayed inf, or no distance beat NaN)."""
    p = torch.rand(200, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    with pytest.raises(error, match=message):
        graph.canonical_farthest_points(p, count, area)
