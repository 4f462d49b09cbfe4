"""The batch-of-one path of nearest_vertex_distance matches the general packed path bit for bit, errors included."""

from __future__ import annotations

import pytest
import torch

from torchmeshmetric._checks import EmptyInputError, NonFiniteError, ShapeError
from torchmeshmetric.kernels.nearest import nearest_vertex_distance


@pytest.mark.parametrize("backend", ["bruteforce", "bvh", "auto"])
@pytest.mark.parametrize(
    "dtypes", [(torch.float32, torch.float32), (torch.float64, torch.float64), (torch.float32, torch.float64)]
)
def test_single_matches_packed(backend: str, dtypes: tuple[torch.dtype, torch.dtype]) -> None:
    g = torch.Generator().manual_seed(3)
    p = torch.rand(400, 3, generator=g, dtype=dtypes[0]) * 2 + 1e3
    r = torch.rand(300, 3, generator=g, dtype=dtypes[1]) * 2 + 1e3
    r[7] = r[11]  # an exact tie: lowest index wins on both paths
    p1, r1 = p.clone().requires_grad_(), r.clone().requires_grad_()
    p2, r2 = p.clone().requires_grad_(), r.clone().requires_grad_()
    fast = nearest_vertex_distance(p1, r1, backend=backend)
    packed = nearest_vertex_distance(
        p2, r2, points_lengths=torch.tensor([400]), ref_lengths=torch.tensor([300]), backend=backend
    )
    assert torch.equal(fast.idx, packed.idx)
    assert fast.dists.dtype == packed.dists.dtype and torch.equal(fast.dists, packed.dists)
    w = torch.linspace(0.5, 2.0, 400, dtype=fast.dists.dtype)
    (fast.dists * w).sum().backward()
    (packed.dists * w).sum().backward()
    assert torch.equal(p1.grad, p2.grad)
    assert torch.equal(r1.grad, r2.grad)
    nograd = nearest_vertex_distance(p, r, backend=backend)
    assert torch.equal(nograd.idx, packed.idx) and torch.equal(nograd.dists, packed.dists.detach())


@pytest.mark.parametrize("which", ["points", "ref_points"])
@pytest.mark.parametrize("bad", [float("nan"), float("inf"), float("-inf")])
def test_single_non_finite_error_matches_list_path(which: str, bad: float) -> None:
    p, r = torch.rand(5, 3), torch.rand(4, 3)
    (p if which == "points" else r)[2, 1] = bad
    with pytest.raises(NonFiniteError) as fast:
        nearest_vertex_distance(p, r)
    with pytest.raises(NonFiniteError) as listed:
        nearest_vertex_distance(p, r, points_lengths=torch.tensor([5]), ref_lengths=torch.tensor([4]))
    assert str(fast.value) == str(listed.value) == f"{which}: expected finite values, found 1 NaN/Inf value(s)"


def test_single_empty_and_shape_errors() -> None:
    with pytest.raises(EmptyInputError, match="points: expected at least one point"):
        nearest_vertex_distance(torch.zeros(0, 3), torch.rand(4, 3))
    with pytest.raises(EmptyInputError, match="ref_points: reference set 0 is empty but has 5 query points"):
        nearest_vertex_distance(torch.rand(5, 3), torch.zeros(0, 3))
    with pytest.raises(ShapeError, match="ref_points"):
        nearest_vertex_distance(torch.rand(5, 3), torch.rand(4, 2))
