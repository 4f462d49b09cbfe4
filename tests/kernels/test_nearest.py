"""nearest_vertex_distance against a float64 brute force and scipy's cKDTree."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial import cKDTree

from tests import reference
from torchmeshmetric import EmptyInputError, NonFiniteError, ShapeError, nearest_vertex_distance


def test_matches_reference_and_kdtree(dtype: torch.dtype, device: str) -> None:
    g = np.random.default_rng(0)
    pts, ref = g.normal(size=(700, 3)), g.normal(size=(1300, 3))
    r = nearest_vertex_distance(
        torch.tensor(pts, dtype=dtype, device=device), torch.tensor(ref, dtype=dtype, device=device)
    )
    d_ref, i_ref = reference.nearest_vertex(pts, ref)
    d_kd, i_kd = cKDTree(ref).query(pts)
    tol = 1e-12 if dtype == torch.float64 else 1e-6
    np.testing.assert_allclose(r.dists.cpu().double().numpy(), d_ref, rtol=0, atol=tol)
    np.testing.assert_allclose(d_kd, d_ref, rtol=0, atol=1e-12)
    # Same index wherever the nearest neighbour is not a near-tie.
    assert (r.idx.cpu().numpy() == i_ref).mean() > 0.999
    assert (i_kd == i_ref).all()


def test_ties_go_to_lowest_index() -> None:
    ref = torch.tensor([[1.0, 0, 0], [-1.0, 0, 0], [0.0, 1, 0], [1.0, 0, 0]])
    r = nearest_vertex_distance(torch.zeros(1, 3), ref)
    assert r.idx.tolist() == [0] and r.dists.tolist() == [1.0]


def test_float32_large_offset() -> None:
    g = torch.Generator().manual_seed(0)
    ref = torch.randn(500, 3, generator=g, dtype=torch.float64)
    pts = torch.randn(300, 3, generator=g, dtype=torch.float64)
    off = torch.tensor([3e6, 1e6, -2e6], dtype=torch.float64)
    p32, r32 = (pts + off).float(), (ref + off).float()
    got = nearest_vertex_distance(p32, r32)
    want = nearest_vertex_distance(p32.double(), r32.double())
    diag = float((ref.amax(0) - ref.amin(0)).norm())
    assert float((got.dists.double() - want.dists).abs().max()) <= 1e-6 * diag


def test_ragged_batch_equals_individual_calls() -> None:
    g = torch.Generator().manual_seed(0)
    pts = [torch.randn(n, 3, generator=g) for n in (5, 40, 17)]
    refs = [torch.randn(n, 3, generator=g) + 5 * i for i, n in enumerate((30, 2, 90))]
    batched = nearest_vertex_distance(pts, refs, max_memory=512)
    singles = [nearest_vertex_distance(p, r) for p, r in zip(pts, refs, strict=True)]
    torch.testing.assert_close(batched.dists, torch.cat([s.dists for s in singles]))
    offsets = [0, 30, 32]
    torch.testing.assert_close(batched.idx, torch.cat([s.idx + o for s, o in zip(singles, offsets, strict=True)]))


def test_gradcheck_and_zero_distance_gradient() -> None:
    g = torch.Generator().manual_seed(0)
    p = torch.randn(5, 3, generator=g, dtype=torch.float64, requires_grad=True)
    q = torch.randn(9, 3, generator=g, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda a, b: nearest_vertex_distance(a, b).dists, (p, q))
    same = q.detach().clone().requires_grad_()
    nearest_vertex_distance(same, q.detach()).dists.sum().backward()
    assert same.grad is not None and torch.equal(same.grad, torch.zeros_like(same))


def test_bad_input() -> None:
    with pytest.raises(ShapeError, match="ref_points"):
        nearest_vertex_distance(torch.zeros(3, 3), torch.zeros(3))
    with pytest.raises(EmptyInputError, match="ref_points: reference set 0 is empty"):
        nearest_vertex_distance(torch.zeros(3, 3), torch.zeros(0, 3))
    with pytest.raises(NonFiniteError, match="points"):
        nearest_vertex_distance(torch.full((3, 3), float("nan")), torch.zeros(2, 3))
    with pytest.raises(ValueError, match="ref_points: expected 2 reference sets"):
        nearest_vertex_distance([torch.zeros(1, 3), torch.zeros(2, 3)], torch.zeros(2, 3))
