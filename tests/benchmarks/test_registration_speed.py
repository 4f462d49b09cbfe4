"""register_nonrigid speed on the ~20k-vertex ground-truth pairs: 1 and 2 threads, quiet and next to a busy process.

Run on a quiet machine: ``python -m pytest tests/benchmarks/test_registration_speed.py --benchmark-only -s``.
Each case prints wall time, process CPU time and the ground-truth RMSE (% of the target's diagonal). Goals
(issue 13): <= 1.0 s on 2 threads; 2 threads >= 1.6x faster than 1; with one other busy process <= 1.3x the quiet
1-thread time; GT RMSE no worse than 0.18 / 0.34 / 0.75 % (issue 13's figures; since the target samples drawn by
face index, 2026-12-05, the pairs give 0.189 / 0.376 / 0.812 % at seed 0, within the seeds' spread:
docs/registration.md, item 8, and docs/benchmarks.md's re-check of 2026-12-07). The C++ extension is loaded
before timing. ``TMM_BENCH_SPACING`` as in ``test_registration_bench.py``. The cases set the thread count
themselves (``num_threads=None``: torch's setting, set per case), not ``register_nonrigid``'s default of 1.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from functools import cache

import pytest
import torch

from tests.registration.gt_pairs import make_pair, torch_threads
from torchmeshmetric import point_mesh_distance
from torchmeshmetric.registration import register_nonrigid

SPACING = float(os.environ.get("TMM_BENCH_SPACING", "0.0145"))
LEVELS = ["small", "medium", "large"]


@cache
def _pair(level: str):
    p = make_pair(level, SPACING)
    src = (torch.tensor(p.source[0]), torch.tensor(p.source[1]))
    tgt = (torch.tensor(p.target[0]), torch.tensor(p.target[1]))
    point_mesh_distance(src[0][:10], *tgt)  # extension loaded
    return p, src, tgt


@pytest.fixture
def busy():
    """One other busy process on the machine while the case runs (``None``: quiet)."""
    proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    time.sleep(0.5)
    yield proc
    proc.kill()
    proc.wait()


def _case(benchmark, level: str, threads: int, label: str) -> None:
    p, src, tgt = _pair(level)
    result = {}

    def go():
        t0, c0 = time.perf_counter(), time.process_time()
        with torch_threads(threads):
            r = register_nonrigid(src, tgt, generator=torch.Generator().manual_seed(0), num_threads=None)
        result.update(wall=time.perf_counter() - t0, cpu=time.process_time() - c0, rmse=100 * p.gt_rmse(r.verts))
        assert r.converged, r.reason

    benchmark.group = f"register_nonrigid gt-{level} ({src[0].shape[0]} vertices)"
    benchmark.name = f"{threads} thread(s), {label}"
    benchmark.pedantic(go, rounds=3, iterations=1, warmup_rounds=1)
    print(
        f"\ngt-{level} {threads} thread(s) {label}: best wall {benchmark.stats.stats.min:.3f} s, last wall "
        f"{result['wall']:.3f} s / process CPU {result['cpu']:.3f} s, GT RMSE {result['rmse']:.3f} %"
    )


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("level", LEVELS)
def test_registration_quiet(benchmark, level, threads):
    _case(benchmark, level, threads, "quiet")


@pytest.mark.parametrize("threads", [1, 2])
def test_registration_next_to_a_busy_process(benchmark, busy, threads):
    _case(benchmark, "medium", threads, "one busy process")
