"""The registration-based sets are continuous functions of the input: one ulp or 1e-9 of input moves them by about
as much, not by percents (issue 25; the ~17k-vertex figures are in tests/benchmarks/test_registration_stability.py
and docs/registration.md)."""

from __future__ import annotations

import pytest

from tests.registration.gt_pairs import make_pair
from tests.registration.stability import stability


@pytest.fixture(scope="module")
def results():
    p = make_pair("medium", 0.05)  # ~1.4k vertices: a real fit with ties and thresholds in play
    return stability(p.target, p.source, perturbations=("ulp+", "ulp-", "rel1e-9"))


@pytest.mark.parametrize("case", ["ulp+", "ulp-", "rel1e-9"])
def test_small_input_changes_move_the_registration_and_every_statistic_by_as_little(results, case: str) -> None:
    # The goal is 1e-5 (relative for the statistics, of the diagonal for the vertices). Measured on this pair and on
    # the small and large ones (2026-12-02): 1 ulp <= 1e-13, 1e-9 <= 1e-7, for the vertices and every statistic of
    # every set (before: 1e-3 to 5e-2). A regression to a discontinuous registration (a hard threshold, a tie broken
    # by the last bit, an argmin over iterates) moves them by 1e-4 to 1e-2 here.
    r = results[case]
    assert r["converged"]
    assert r["verts"] <= 1e-5
    for name, change in r["sets"].items():
        assert change <= 1e-5, (name, change)
    # frame k's sets use no registration: the same bits
    assert r["sets"]["surface_k"] == r["sets"]["vertex_k"] == 0.0


def test_thread_counts_give_the_same_registration(results) -> None:
    # Bit-identical: the C++ passes keep one summation order for any thread count (test_fused_energy.py).
    r = results["threads=2"]
    assert r["verts"] == 0.0
    assert all(change == 0.0 for change in r["sets"].values())
