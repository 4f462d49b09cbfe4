"""Stability of the registration-based sets on ~17k-vertex frames: inputs moved by 1 ulp, 1e-9, 1e-6; 2 threads.

Run: ``python -m pytest tests/benchmarks/test_registration_stability.py --benchmark-only -s``. Pairs: the three
ground-truth pairs, the demo's frames 1 -> 2 and a captured-like pair (``make_captured_pair``), each registered with the
evaluation's canonical sampling (no draw) and with ``register_nonrigid``'s default index draws. Prints, for each
pair and perturbation of frame k-1, how far the registered vertices moved (fraction of the diagonal) and the largest
relative change of any statistic (Ave, Var, STD, MSE, RMSE, Max, median, p95) of every set. Goals (issue 25): 1 ulp
and 1e-9: registered vertices <= 1e-5 of the diagonal and every statistic of the k-1 and flicker sets <= 1e-5
relative (1e-9: the median over generator seeds 0-4); 1 and 2 threads the same. The figures are in
docs/registration.md ("Stability").
"""

from __future__ import annotations

import os
import statistics

import pytest

from tests.registration.gt_pairs import make_captured_pair, make_pair
from tests.registration.stability import stability, stability_table
from torchmeshmetric.data import demo_sequence

SPACING = float(os.environ.get("TMM_BENCH_SPACING", "0.0145"))


def _demo_pair():
    seq = demo_sequence(num_frames=3, resolution=160)
    (k1, k) = seq.frames[1], seq.frames[2]
    return (k.verts.double().numpy(), k.faces.numpy()), (k1.verts.double().numpy(), k1.faces.numpy())


@pytest.mark.parametrize("sampling", ["canonical", "index"])
@pytest.mark.parametrize("pair", ["gt-small", "gt-medium", "gt-large", "demo", "captured"])
def test_registration_stability(benchmark, pair: str, sampling: str) -> None:
    if pair == "demo":
        k, km1 = _demo_pair()
    elif pair == "captured":
        p = make_captured_pair("medium")  # ~20k vertices, thin parts, the defects of captured frames
        k, km1 = p.target, p.source
    else:
        p = make_pair(pair.removeprefix("gt-"), SPACING)
        k, km1 = p.target, p.source
    results = benchmark.pedantic(lambda: stability(k, km1, sampling=sampling), rounds=1, iterations=1)
    print(f"\n{pair} ({km1[0].shape[0]} -> {k[0].shape[0]} vertices, {sampling})\n{stability_table(results)}")
    for case in ("ulp+", "ulp-", "threads=2"):
        r = results[case]
        assert r["verts"] <= 1e-5, (case, r)
        assert all(v <= 1e-5 for v in r["sets"].values()), (case, r)
    if sampling == "canonical":
        # The evaluation's registration: no draw (any generator gives it, tests/registration/test_stability.py), so
        # the goal holds for its one registration, 1e-9 included.
        r = results["rel1e-9"]
        assert r["verts"] <= 1e-5, r
        assert all(v <= 1e-5 for v in r["sets"].values()), r
        return
    # 1e-9 over generator seeds 0-4, the median: the fit's steepness depends on the draw (docs/registration.md,
    # "Stability", items 5 and 8), and one draw in several amplifies 1e-9 of input beyond the goal. Measured
    # (2026-12-05, 1e-9, the five pairs x seeds 0-4; registered vertices and the largest set change): target samples
    # drawn by face index, 3 and 4 of 25 runs above 1e-5 (gt-medium seeds 0 and 1: 4.5e-5 / 2.7e-4, 1.2e-5 / 2.4e-4;
    # demo seed 2: 2.7e-5 / 2.2e-4; captured seed 0: sets 5.2e-5), medians 4.4e-8 and 1.1e-6, every pair's median
    # within the goal; the inverse CDF before, 0 and 4 of 25 (demo seeds 1, 3, 4: sets 7.0e-4, 2.7e-5, 1.2e-5;
    # gt-medium seed 2: 2.3e-5), medians 1.4e-8 and 8.2e-7, the demo pair's median above the goal (1.2e-5).
    runs = [results["rel1e-9"]]
    runs += [
        stability(k, km1, perturbations=("rel1e-9",), threads=(), seed=s, sampling=sampling)["rel1e-9"]
        for s in range(1, 5)
    ]
    print("1e-9, seeds 0-4:", [(f"{r['verts']:.1e}", f"{max(r['sets'].values()):.1e}") for r in runs])
    assert statistics.median(r["verts"] for r in runs) <= 1e-5
    for name in runs[0]["sets"]:
        assert statistics.median(r["sets"][name] for r in runs) <= 1e-5, name
