"""The farthest pair of STED's diameter D against a float64 brute force over all V² pairs, on adversarial shapes."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest
import torch
import trimesh

from torchmeshmetric.temporal import _diameter
from torchmeshmetric.temporal._diameter import _Nodes, _threshold, farthest_pair
from torchmeshmetric.temporal.sted import largest_vertex_distance

F64 = torch.float64


def _brute_force_pair(x: torch.Tensor) -> tuple[int, int]:
    """The first (row-major) largest float64 ``((x_i - x_j) ** 2).sum()`` over all V² pairs, in row blocks."""
    n, best, pair = x.shape[0], -1.0, (0, 0)
    step = max(1, 2**20 // n)
    for i in range(0, n, step):
        d2 = ((x[i : i + step, None, :] - x[None, :, :]) ** 2).sum(-1)
        flat = int(d2.argmax())  # the first of the block's largest
        value = float(d2.flatten()[flat])
        if value > best:  # a later block wins only when strictly larger: the first in row-major order
            best, pair = value, (i + flat // n, flat % n)
    return pair


def _sphere(g: torch.Generator, n: int) -> torch.Tensor:
    x = torch.randn(n, 3, generator=g, dtype=F64)
    return x / torch.linalg.vector_norm(x, dim=1, keepdim=True)


_CUBE = torch.tensor([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=F64)

# name -> (generator, n) -> (n', 3) float64 points
SHAPES: dict[str, Callable[[torch.Generator, int], torch.Tensor]] = {
    "sphere": _sphere,
    "sphere on a grid (duplicates, ties)": lambda g, n: (_sphere(g, n) * 4).round() / 4,
    "icosphere (exact antipodes)": lambda g, n: torch.as_tensor(
        trimesh.creation.icosphere(subdivisions=min(4, max(0, int(math.log(max(n, 12) / 10, 4))))).vertices,
        dtype=F64,
    ),
    "box corners, repeated": lambda g, n: _CUBE[torch.randint(0, 8, (n,), generator=g)] * 0.37 + 0.5,
    "box edges": lambda g, n: (
        _CUBE[torch.randint(0, 8, (n,), generator=g)] * torch.randint(0, 11, (n, 1), generator=g).to(F64) / 10
    ),
    "integer grid": lambda g, n: torch.randint(0, 3, (n, 3), generator=g).to(F64),
    "duplicates": lambda g, n: torch.cat([_sphere(g, max(1, n // 4))] * 4),
    "collinear": lambda g, n: (
        torch.randint(0, 50, (n, 1), generator=g).to(F64) / 7 * torch.tensor([[1.0, 2.0, -3.0]], dtype=F64)
    ),
    "all equal": lambda g, n: torch.full((n, 3), 0.3, dtype=F64),
    "signed zeros": lambda g, n: torch.tensor([[0.0, 0.0, 0.0], [-0.0, 0.0, -0.0]], dtype=F64).repeat(n, 1),
    "sphere at 1e6": lambda g, n: _sphere(g, n) * 1e-2 + 1e6,
    "lattice at 1e6 (ties)": lambda g, n: (_sphere(g, n) * 1e3).round() / 1e3 + 1e6,
    "scale 1e-6": lambda g, n: _sphere(g, n) * 1e-6,
    "scale 1e-160 (squares underflow)": lambda g, n: _sphere(g, n) * 1e-160,
    "scale 1e155 (squares overflow)": lambda g, n: _sphere(g, n) * 1e155,
    "two clusters": lambda g, n: torch.cat(
        [torch.randn(n // 2, 3, generator=g, dtype=F64) * 1e-3, torch.randn(n - n // 2, 3, generator=g, dtype=F64) + 5]
    ),
    "cluster and outliers": lambda g, n: torch.cat(
        [torch.randn(n, 3, generator=g, dtype=F64) * 0.1, torch.randn(3, 3, generator=g, dtype=F64) * 10]
    ),
    "ellipsoid within 1e-9 of a sphere": lambda g, n: _sphere(g, n) * torch.tensor([1, 1 - 1e-9, 1 - 2e-9], dtype=F64),
    "hemisphere": lambda g, n: _sphere(g, n).abs(),
    "circle": lambda g, n: torch.nn.functional.pad(torch.nn.functional.normalize(_sphere(g, n)[:, :2], dim=1), (0, 1)),
    "cylinder rims": lambda g, n: torch.cat(
        [torch.nn.functional.normalize((s := _sphere(g, n))[:, :2], dim=1), torch.sign(s[:, 2:])], 1
    ),
    "gaussian": lambda g, n: torch.randn(n, 3, generator=g, dtype=F64),
}


def _check(x: torch.Tensor) -> list[tuple[int, tuple[int, int], tuple[int, int]]]:
    """The mismatches of ``farthest_pair`` on ``x`` and on a shuffled copy (the tie rule sees the new order)."""
    wrong = []
    g = torch.Generator().manual_seed(x.shape[0])
    for y in (x, x[torch.randperm(x.shape[0], generator=g)]):
        got, want = farthest_pair(y), _brute_force_pair(y)
        if got != want:
            wrong.append((y.shape[0], got, want))
    return wrong


@pytest.mark.parametrize("shape", list(SHAPES))
def test_farthest_pair_is_the_brute_force_pair(shape: str) -> None:
    g = torch.Generator().manual_seed(len(shape))
    wrong = []
    for n in (1, 2, 3, 17, 100, 700):
        wrong += _check(SHAPES[shape](g, n))
    assert not wrong


@pytest.mark.parametrize("shape", list(SHAPES))
def test_farthest_pair_is_the_brute_force_pair_through_deep_trees(shape: str, monkeypatch: pytest.MonkeyPatch) -> None:
    # Leaves of 3 points, 5 node pairs per chunk and leaf blocks of 3 leaf pairs: every level, the depth-first walk
    # over chunks and the leaves' block loop (with its early exit) all take part, on few points.
    monkeypatch.setattr(_diameter, "LEAF_SIZE", 3)
    monkeypatch.setattr(_diameter, "PAIRS", 5)
    monkeypatch.setattr(_diameter, "BLOCK", 3 * 27)
    g = torch.Generator().manual_seed(len(shape) + 1)
    wrong = []
    for n in (2, 5, 40, 300):
        wrong += _check(SHAPES[shape](g, n))
    assert not wrong


def test_ties_take_the_first_pair_in_row_major_order() -> None:
    # Opposite corners of a cube tie four ways, and copies tie again. The brute force's pair is the smallest
    # (i, j): the first point and the first of the copies of its opposite corner.
    x = torch.cat([_CUBE[[3, 5, 6, 0, 1, 2, 7]], _CUBE[[4, 4]]])
    assert farthest_pair(x) == _brute_force_pair(x) == (0, 7)  # corners (0,1,1) and (1,0,0), not (3, 6)
    assert farthest_pair(x.flip(0)) == _brute_force_pair(x.flip(0)) == (0, 8)  # (1,0,0), (0,1,1): not (1, 8)
    # a pair one ulp of the squared distance farther than its rivals wins, whatever the margins keep
    y = torch.tensor([[0.0, 0, 0], [1.0, 0, 0], [0.5, 0.5, 0], [math.nextafter(1.0, 2.0), 0, 0]], dtype=F64)
    assert farthest_pair(y) == _brute_force_pair(y) == (0, 3)


def test_degenerate_sets() -> None:
    assert farthest_pair(torch.tensor([[1.0, 2.0, 3.0]], dtype=F64)) == (0, 0)  # V = 1
    assert farthest_pair(torch.full((50, 3), -2.5, dtype=F64)) == (0, 0)  # all equal: D = 0 at the first pair
    assert farthest_pair(torch.tensor([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0 + 2**-40]], dtype=F64)) == (0, 1)
    # distinct bits, equal values: the brute force sees only zeros and answers (0, 0)
    assert farthest_pair(torch.tensor([[0.0, 0.0, 0.0], [-0.0, 0.0, 0.0]], dtype=F64)) == (0, 0)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_largest_vertex_distance_on_a_sphere_and_its_gradient(dtype: torch.dtype) -> None:
    g = torch.Generator().manual_seed(5)
    x = _sphere(g, 2000).to(dtype).requires_grad_(True)
    i, j = _brute_force_pair(x.detach().double())
    d = largest_vertex_distance(x)
    assert d.item() == torch.linalg.vector_norm(x[i] - x[j]).item()
    d.backward()
    assert x.grad is not None
    unit = ((x[i] - x[j]) / d).detach()
    want = torch.zeros_like(x)
    want[i], want[j] = unit, -unit  # the gradient reaches the two points of the pair, and only them
    assert torch.allclose(x.grad, want, rtol=1e-6 if dtype == torch.float32 else 1e-15, atol=0.0)
    assert torch.count_nonzero(x.grad.abs().sum(1)) == 2


def test_a_sphere_compares_few_pairs(monkeypatch: pytest.MonkeyPatch) -> None:
    # The search before this one compared every pair of points near a sphere (a centroid-radius prune keeps them
    # all): 20 000 points took 19 s. The cone bound leaves each leaf a few partners near its antipode: O(V) pairs.
    compared = []

    def counting(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        out = ((a - b) ** 2).sum(-1)
        compared.append(out.numel())
        return out

    monkeypatch.setattr(_diameter, "squared_distances", counting)
    g = torch.Generator().manual_seed(0)
    x = _sphere(g, 20_000)
    assert farthest_pair(x) == (71, 514)  # the brute force's pair (4e8 pairs, 20 s: checked once, not rerun here)
    assert sum(compared) < 100 * x.shape[0]  # measured 0.9M (45 per point), against 2e8 pairs before


def test_the_bounds_hold_on_random_nodes() -> None:
    # Every prune relies on _Nodes.upper: no pair of points of two nodes may be farther apart than the bound
    # allows (up to the threshold's margin). Nodes: patches of spheres around several centres, at several scales,
    # with points at the cones' apex, tiny patches (sines of cosines near 1) and half spheres (no cone).
    g = torch.Generator().manual_seed(1)
    failures = 0
    for scale in (1e-150, 1e-6, 1.0, 1e6, 1e150):
        for offset in (0.0, 1e3):
            for spread in (1e-9, 1e-3, 0.3, 3.0):
                n, s = 24, 8
                axes = _sphere(g, n)
                pts = axes[:, None, :] + spread * torch.randn(n, s, 3, generator=g, dtype=F64)
                pts = torch.nn.functional.normalize(pts, dim=-1) * (1 + 0.01 * torch.rand(n, s, 1, generator=g))
                centre = torch.zeros(3, dtype=F64)
                pts[0, 0] = centre  # a point at the apex
                blocks = (pts + offset) * scale
                nodes = _Nodes(blocks, torch.arange(n), (centre + offset) * scale)
                i, j = torch.triu_indices(n, n)
                ub = nodes.upper(i, j)
                d2 = ((blocks[i][:, :, None, :] - blocks[j][:, None, :, :]) ** 2).sum(-1).flatten(1).amax(1)
                failures += sum(bool(u < _threshold(float(v))) for u, v in zip(ub, d2, strict=True))
    assert failures == 0


def test_a_direction_lost_to_underflow_turns_the_cone_off() -> None:
    # A point exactly at the apex has no direction and bounds nothing (|p - q| = |q - o|); one within 2^-500 of it
    # has a norm that may have lost digits, so its node keeps the box bound alone.
    centre = torch.zeros(3, dtype=F64)
    patch = torch.tensor([[1.0, 0.0, 0.0], [1.0, 0.1, 0.0], [1.0, 0.0, 0.1]], dtype=F64)
    at_apex = torch.cat([patch, centre[None]])
    near_apex = torch.cat([patch, torch.tensor([[2.0**-520, 0.0, 0.0]], dtype=F64)])
    nodes = _Nodes(torch.stack([at_apex, near_apex]), torch.arange(2), centre)
    assert nodes.cone.tolist() == [True, False]
