"""Farthest-point sampling: the C++ k-d tree (``bvh.farthest_point_sampling``) against the torch loop it equals.

Run: ``python -m pytest tests/benchmarks/test_fps_bench.py --benchmark-only -s`` (skipped by default).
``TMM_BENCH_THREADS`` sets torch's thread count (default 1: the like-for-like figure on a shared machine; the C++
sampling is single-threaded).

Cases: the four calls a canonical registration of the evaluation's pair makes (``register_nonrigid`` with
``NonRigidOptions(sampling="canonical")`` on ``make_pair("medium", 0.0145)``, ~17k source vertices, float64: the
surface samples, the graph's nodes, the samples again to a finer radius, and the reverse term's centroids; recorded
from the registration itself), and 100k random points in a unit cube to a radius of 0.03 (~16k choices). Contenders,
the same points, the same choices (asserted):

* ``ours``: :func:`~torchmeshmetric.registration.deformation_graph._fps` with the extension (the k-d tree);
* ``torch loop (reference)``: the same function with the extension bypassed: the loop of four torch operations per
  choice, the reference formulation for the devices and dtypes the extension does not take (run where it takes less
  than a minute).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from functools import cache

import pytest
import torch

from tests.registration.gt_pairs import make_pair, torch_threads
from torchmeshmetric import native
from torchmeshmetric.registration import NonRigidOptions, register_nonrigid
from torchmeshmetric.registration import deformation_graph as graph

THREADS = int(os.environ.get("TMM_BENCH_THREADS", "1"))
CASES = ["registration call 1", "registration call 2", "registration call 3", "registration call 4", "cube 100k"]


@cache
def registration_calls() -> list[tuple[torch.Tensor, int, float]]:
    """``(points, start, spacing)`` of every sampling call of a canonical registration of the evaluation's pair."""
    pair = make_pair("medium", 0.0145)
    src = (torch.tensor(pair.source[0]).double(), torch.tensor(pair.source[1]))
    tgt = (torch.tensor(pair.target[0]).double(), torch.tensor(pair.target[1]))
    calls: list[tuple[torch.Tensor, int, float]] = []
    fps = graph._fps

    def recorded(p: torch.Tensor, start: int, spacing: float) -> torch.Tensor:
        calls.append((p.clone(), start, spacing))
        return fps(p, start, spacing)

    with pytest.MonkeyPatch.context() as mp, torch_threads(1):
        mp.setattr(graph, "_fps", recorded)
        register_nonrigid(src, tgt, options=NonRigidOptions(sampling="canonical"))
    return calls


def points(case: str) -> tuple[torch.Tensor, int, float]:
    if case.startswith("registration"):
        return registration_calls()[int(case.removeprefix("registration call ")) - 1]
    x = torch.rand(100_000, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    _, q, start = graph._canonical_start(x)
    return q, start, 0.03


def _best(fn: Callable[[], torch.Tensor], rounds: int) -> tuple[float, torch.Tensor]:
    best, out = float("inf"), torch.empty(0)
    for _ in range(rounds):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


@pytest.mark.parametrize("case", CASES)
def test_farthest_point_sampling(benchmark, record, monkeypatch: pytest.MonkeyPatch, case: str) -> None:
    assert native.try_load("bvh") is not None
    q, start, spacing = points(case)
    with torch_threads(THREADS):
        ours, chosen = _best(lambda: graph._fps(q, start, spacing), 5)
        group = f"farthest-point sampling, {case} ({q.shape[0]} points, {chosen.numel()} chosen, {THREADS} threads)"
        record(group, "ours", ours)
        if q.shape[0] * chosen.numel() <= 10**8:  # the loop: ~1 s per 10^7 point-choices here
            with monkeypatch.context() as mp:
                mp.setattr(native, "try_load", lambda name: None)
                loop, want = _best(lambda: graph._fps(q, start, spacing), 1)
            assert torch.equal(chosen, want)
            record(group, "torch loop (reference)", loop)
        benchmark.group = group
        benchmark.name = "ours"
        benchmark.pedantic(lambda: graph._fps(q, start, spacing), rounds=1, iterations=1)
