"""STED's diameter D (the farthest pair of a point set): the k-d tree search against the search it replaced.

Run: ``python -m pytest tests/benchmarks/test_diameter_bench.py --benchmark-only -s`` (skipped by default).
``TMM_BENCH_THREADS=1`` sets torch's thread count (the like-for-like figure on a shared machine, where every
parallel region of a small torch op waits for a descheduled thread); ``TMM_BENCH_DIAMETER_SIZES=20k,100k``
picks the sphere sizes (default ``20k,100k,300k``).

Cases: points on a unit sphere (random normals normalised: every point lies on the convex hull, the worst case of
every prune by distance from a centre), frame 0 of the built-in sequence (``demo_sequence(resolution=160)``,
~20k vertices, a captured-like frame) and a subdivided box (~25k vertices). Contenders, the same points, the same
answer (asserted):

* ``ours``: :func:`~torchmeshmetric.temporal._diameter.farthest_pair`;
* ``radius prune + blocks (before)``: the search it replaced, copied below: every point that can be in a pair
  beyond the 13-direction lower bound by the centroid-radius bound, then all pairs of those in blocks (run only
  where it takes less than a minute: 20k on a sphere took 19-28 s, and its cost grows as V²).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from functools import cache

import pytest
import torch

from torchmeshmetric.temporal._diameter import farthest_pair

if os.environ.get("TMM_BENCH_THREADS"):
    torch.set_num_threads(int(os.environ["TMM_BENCH_THREADS"]))
SIZES = [s for s in os.environ.get("TMM_BENCH_DIAMETER_SIZES", "20k,100k,300k").split(",") if s]
BEFORE_UP_TO = 25_000  # points on a sphere beyond which the search before is not run (minutes)
_SIGNS = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, -1, 0], [1, 0, 1], [1, 0, -1], [0, 1, 1], [0, 1, -1]]
_SIGNS += [[1, 1, 1], [1, 1, -1], [1, -1, 1], [-1, 1, 1]]


def radius_prune_and_blocks(x: torch.Tensor) -> tuple[int, int]:
    """The search before the k-d tree, as it was (torchmeshmetric/temporal/sted.py, ``_farthest_pair``)."""
    c = x.mean(0)
    radius = (x - c).norm(dim=1)
    signs = torch.tensor(_SIGNS, dtype=x.dtype, device=x.device)
    proj = x @ signs.T
    extremes = torch.unique(torch.cat([proj.argmax(0), proj.argmin(0)]))
    lower = float(torch.cdist(x[extremes], x[extremes], compute_mode="donot_use_mm_for_euclid_dist").max())
    largest = float(radius.max())
    keep = radius >= lower - largest - 2.0**-40 * (lower + largest)
    keep[extremes] = True
    index = torch.nonzero(keep).flatten()
    y = x[index]
    best, pair = -1.0, (0, 0)
    step = max(1, 2**22 // max(1, y.shape[0]))
    for i in range(0, y.shape[0], step):
        d = ((y[i : i + step, None, :] - y[None, :, :]) ** 2).sum(-1)
        flat = int(d.argmax())
        value = float(d.flatten()[flat])
        if value > best:
            best, pair = value, (i + flat // y.shape[0], flat % y.shape[0])
    return int(index[pair[0]]), int(index[pair[1]])


@cache
def points(case: str) -> torch.Tensor:
    if case.startswith("sphere"):
        n = int(case.removeprefix("sphere ").removesuffix("k")) * 1000
        x = torch.randn(n, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
        return x / x.norm(dim=1, keepdim=True)
    if case == "frame":
        from torchmeshmetric.data import demo_sequence

        return demo_sequence(1, resolution=160).frames[0].verts.double()
    import trimesh

    box = trimesh.creation.box()
    for _ in range(6):
        box = box.subdivide()
    return torch.as_tensor(box.vertices, dtype=torch.float64)


def _best(fn: Callable[[], object], rounds: int) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(rounds):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return best, out


@pytest.mark.parametrize("case", [f"sphere {s}" for s in SIZES] + ["frame", "box"])
def test_farthest_pair(benchmark, record, case: str) -> None:
    x = points(case)
    group = f"farthest pair, {case} ({x.shape[0]} points, {torch.get_num_threads()} threads)"
    farthest_pair(x[:1000])  # warm-up
    ours, pair = _best(lambda: farthest_pair(x), 3)
    record(group, "ours", ours)
    if not case.startswith("sphere") or x.shape[0] <= BEFORE_UP_TO:
        before, want = _best(lambda: radius_prune_and_blocks(x), 1 if case.startswith("sphere") else 3)
        assert pair == want
        record(group, "radius prune + blocks (before)", before)
    benchmark.group = group
    benchmark.name = "ours"
    benchmark.pedantic(lambda: farthest_pair(x), rounds=1, iterations=1)
