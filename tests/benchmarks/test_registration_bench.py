"""Registration benchmark: ground-truth pairs, ours vs trimesh's nricp_amberg / nricp_sumner in the same run.

Run: ``python -m pytest tests/benchmarks/test_registration_bench.py --benchmark-only -s``. Each case prints the
GT RMSE (fraction of the bbox diagonal) and wall time of the three methods on the same pair, and the ratios.
Set ``TMM_BENCH_SPACING=0.0145`` for ~20k-vertex frames (slow until the accelerated distance kernel lands).
"""

from __future__ import annotations

import os
import time

import pytest
import torch
import trimesh
from trimesh.registration import nricp_amberg, nricp_sumner

from tests.registration.gt_pairs import make_pair
from torchmeshmetric.registration import register_nonrigid

SPACING = float(os.environ.get("TMM_BENCH_SPACING", "0.05"))


@pytest.mark.parametrize("level", ["small", "medium", "large"])
def test_registration_vs_trimesh(benchmark, level):
    pair = make_pair(level, SPACING)
    src = trimesh.Trimesh(*pair.source, process=False)
    tgt = trimesh.Trimesh(*pair.target, process=False)
    t0 = time.perf_counter()
    amberg = nricp_amberg(src, tgt)
    t_amberg = time.perf_counter() - t0
    t0 = time.perf_counter()
    sumner = nricp_sumner(src, tgt)
    t_sumner = time.perf_counter() - t0

    def ours():
        return register_nonrigid(pair.source, pair.target, generator=torch.Generator().manual_seed(0))

    res = benchmark.pedantic(ours, rounds=1, iterations=1)
    t_ours = benchmark.stats.stats.mean
    e_ours, e_amb, e_sum = pair.gt_rmse(res.verts), pair.gt_rmse(amberg), pair.gt_rmse(sumner)
    print(
        f"\n[{level}] V={len(pair.source[0])} target V={len(pair.target[0])} | GT RMSE %diag: ours {100 * e_ours:.3f}, "
        f"amberg {100 * e_amb:.3f}, sumner {100 * e_sum:.3f}, rigid only {100 * pair.gt_rmse(res.rigid.verts):.3f} | "
        f"time s: ours {t_ours:.1f}, amberg {t_amberg:.1f}, sumner {t_sumner:.1f} | accuracy ratio vs amberg "
        f"{e_ours / e_amb:.2f}, time ratio vs amberg {t_ours / t_amberg:.2f} | converged {res.converged} {res.reason}"
    )
    benchmark.extra_info.update(
        {
            "gt_rmse_ours": e_ours,
            "gt_rmse_amberg": e_amb,
            "gt_rmse_sumner": e_sum,
            "time_amberg": t_amberg,
            "time_sumner": t_sumner,
            "converged": res.converged,
        }
    )
    assert res.converged, res.reason
