"""The registration-based sets are continuous functions of the input: one ulp or 1e-9 of input moves them by about
as much, not by percents (issue 25; the ~17k-vertex figures are in tests/benchmarks/test_registration_stability.py
and docs/registration.md)."""

from __future__ import annotations

import statistics

import pytest

from tests.registration.gt_pairs import make_pair
from tests.registration.stability import stability

SEEDS = range(8)
"""The registration's generator seeds: the property is stated over draws, not for one draw (see below)."""


@pytest.fixture(scope="module")
def results():
    p = make_pair("medium", 0.05)  # ~1.4k vertices: a real fit with ties and thresholds in play
    return {
        seed: stability(
            p.target, p.source, perturbations=("ulp+", "ulp-", "rel1e-9"), threads=(2,) if seed == 0 else (), seed=seed
        )
        for seed in SEEDS
    }


@pytest.mark.slow
@pytest.mark.parametrize("case", ["ulp+", "ulp-", "rel1e-9"])
def test_small_input_changes_move_the_registration_and_every_statistic_by_as_little(results, case: str) -> None:
    # The goal is 1e-5 (relative for the statistics, of the diagonal for the vertices), asserted on the median over
    # the seeds. The registration is a continuous but steep function of its input, and its steepness depends on the
    # draw (Adam's first steps, docs/registration.md "Stability" item 5): one draw in eight amplifies the input by
    # ~5e4, and the same amplification shows at both sizes of perturbation (seed 0 with the target samples drawn by
    # face index: 1 ulp moves the vertices by 3.5e-11 / 6.6e-11, 1e-9 by 5.1e-5). So the worst of a few draws says
    # how steep the steepest fit is, not whether the registration jumps; the median says how a typical draw moves.
    # Measured over seeds 0-7 (2026-12-05), vertices / largest set change, median and worst:
    #   samples drawn by face index (kept):  1 ulp 6e-15 / 4.5e-14, worst 6.6e-11 / 6e-11;
    #                                        1e-9 1.7e-9 / 8.2e-8, worst 5.1e-5 / 8.3e-5 (seed 0; the others <= 1.4e-7)
    #   the inverse CDF over the areas:      1 ulp 1.2e-13 / 2.7e-13, worst 3.7e-12 / 1.1e-11;
    #                                        1e-9 3.3e-8 / 1e-7, worst 4.7e-7 / 1.6e-6
    # A discontinuous registration moves every draw: with the face's normal at each match instead of the interpolated
    # one (a tie between faces broken by the last bit, item 1) every seed moved the vertices by 5e-4 to 6e-3 and the
    # sets by 4e-3 to 2e-2 under every perturbation (this test then fails on the median by ~90x).
    runs = [results[seed][case] for seed in SEEDS]
    assert all(r["converged"] for r in runs)
    assert statistics.median(r["verts"] for r in runs) <= 1e-5
    for name in runs[0]["sets"]:
        change = statistics.median(r["sets"][name] for r in runs)
        assert change <= 1e-5, (name, change)
    # frame k's sets use no registration: the same bits, for every draw
    assert all(r["sets"]["surface_k"] == r["sets"]["vertex_k"] == 0.0 for r in runs)


def test_thread_counts_give_the_same_registration(results) -> None:
    # Bit-identical: the C++ passes keep one summation order for any thread count (test_fused_energy.py). A property
    # of every draw; checked on one.
    r = results[0]["threads=2"]
    assert r["verts"] == 0.0
    assert all(change == 0.0 for change in r["sets"].values())


@pytest.fixture(scope="module")
def canonical():
    p = make_pair("medium", 0.05)
    return p, stability(p.target, p.source, perturbations=("ulp+", "ulp-", "rel1e-9"), sampling="canonical")


@pytest.mark.slow
def test_the_evaluations_canonical_registration_is_as_continuous_for_its_one_draw(canonical) -> None:
    # The evaluation registers with sampling="canonical" (REGISTRATION_SAMPLING): its samples are chosen from the
    # surfaces, not drawn, so there is one registration per pair, not a distribution over seeds, and the goal holds
    # for it, not for a median. Measured (2026-12-07, this pair): vertices / largest set change 1.5e-13 / 1.5e-13
    # (ulp+), 2.0e-14 / 4.8e-14 (ulp-), 3.2e-7 / 4.3e-7 (1e-9); the same for seeds 0-7.
    _, results = canonical
    for case in ("ulp+", "ulp-", "rel1e-9"):
        r = results[case]
        assert r["converged"], case
        assert r["verts"] <= 1e-5, (case, r["verts"])
        assert all(change <= 1e-5 for change in r["sets"].values()), (case, r["sets"])
    assert results["threads=2"]["verts"] == 0.0


def test_the_canonical_registration_does_not_depend_on_the_generator(canonical) -> None:
    import torch

    from torchmeshmetric.registration import register_nonrigid

    p, _ = canonical
    src = tuple(torch.as_tensor(a) for a in p.source)
    tgt = tuple(torch.as_tensor(a) for a in p.target)
    runs = [
        register_nonrigid(src, tgt, sampling="canonical", generator=torch.Generator().manual_seed(s)).verts
        for s in (0, 1)
    ]
    assert torch.equal(runs[0], runs[1])
