"""The C++ BVH's fused batch-of-one nearest path and its seeded, dynamically scheduled queries.

The fused path (finiteness check, centring, build, query and squared distances in one call) and the seeding of
each query with its Morton predecessor's answer must not change a single bit of any result: indices and
distances are compared with ``torch.equal`` against the brute-force reference.
"""

from __future__ import annotations

import pytest
import torch
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric._checks import NonFiniteError
from torchmeshmetric.kernels.accel import bvh as accel_bvh
from torchmeshmetric.kernels.nearest import nearest_vertex_distance
from torchmeshmetric.kernels.point_triangle import point_mesh_distance
from torchmeshmetric.native import try_load


@pytest.fixture(scope="module", autouse=True)
def _compiled() -> None:
    assert try_load("bvh") is not None


def _assert_bitwise_equal(points: torch.Tensor, ref: torch.Tensor, **kw: torch.Tensor) -> None:
    expected = nearest_vertex_distance(points, ref, backend="bruteforce", **kw)
    got = nearest_vertex_distance(points, ref, backend="bvh", **kw)
    assert torch.equal(got.idx, expected.idx)
    assert got.dists.dtype == expected.dists.dtype and torch.equal(got.dists, expected.dists)


def test_fused_path_serves_calls_without_autograd_only(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []
    fused = accel_bvh.bvh_nearest_single

    def spy(p: torch.Tensor, r: torch.Tensor):
        calls.append(p.shape[0])
        return fused(p, r)

    monkeypatch.setattr(accel_bvh, "bvh_nearest_single", spy)
    g = torch.Generator().manual_seed(0)
    p, r = torch.randn(500, 3, generator=g), torch.randn(700, 3, generator=g)
    plain = nearest_vertex_distance(p, r, backend="bvh")
    assert calls == [500]
    graded = nearest_vertex_distance(p.clone().requires_grad_(), r, backend="bvh")
    assert calls == [500]  # autograd: the differentiable general path
    assert torch.equal(plain.idx, graded.idx) and torch.equal(plain.dists, graded.dists.detach())
    nearest_vertex_distance(p, r, points_lengths=torch.tensor([500]), ref_lengths=torch.tensor([700]), backend="bvh")
    assert calls == [500]  # packed batches use the batched kernel


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("offset", [0.0, 1e6])
def test_fused_equals_bruteforce_bit_for_bit(dtype: torch.dtype, offset: float) -> None:
    g = torch.Generator().manual_seed(1)
    ref = torch.randn(3000, 3, generator=g, dtype=dtype) + offset
    ref[1000:1100] = ref[:100]  # duplicates: the lowest index must win
    points = torch.cat(
        [
            torch.randn(2000, 3, generator=g, dtype=dtype) * 1.3 + offset,
            ref[:300],  # on reference points: distance exactly 0
            torch.randn(50, 3, generator=g, dtype=dtype) * 50 + offset,  # far outside the box
        ]
    )
    _assert_bitwise_equal(points, ref)


@pytest.mark.parametrize("num_ref", [1, 2, 31, 32, 33, 63, 64, 65, 1000])
def test_leaf_lane_boundaries(num_ref: int) -> None:
    # Leaves hold up to 32 points and the leaf test reads 32 lanes past its start (the next leaf's points or the
    # padding): sizes around multiples of 32 check that no lane beyond a leaf changes the answer.
    g = torch.Generator().manual_seed(num_ref)
    ref = torch.rand(num_ref, 3, generator=g)
    points = torch.rand(400, 3, generator=g) * 1.2 - 0.1
    _assert_bitwise_equal(points, ref)


def test_identical_queries_and_lattice_ties() -> None:
    lattice = torch.stack(torch.meshgrid(*[torch.arange(6.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    midpoints = torch.stack(torch.meshgrid(*[torch.arange(11.0) / 2] * 3, indexing="ij"), -1).reshape(-1, 3)
    _assert_bitwise_equal(midpoints, lattice)  # up to 8 equidistant lattice points per query
    _assert_bitwise_equal(torch.full((300, 3), 2.5), lattice)  # every query identical (seeded from itself)
    _assert_bitwise_equal(lattice, lattice.flip(0))


def test_mixed_dtypes_promote() -> None:
    g = torch.Generator().manual_seed(2)
    p, r = torch.randn(800, 3, generator=g), torch.randn(900, 3, generator=g, dtype=torch.float64)
    got = nearest_vertex_distance(p, r, backend="bvh")
    assert got.dists.dtype == torch.float64
    _assert_bitwise_equal(p, r)


@pytest.mark.parametrize("which", ["points", "ref_points"])
@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_fused_non_finite_raises_the_typed_error(which: str, bad: float) -> None:
    p, r = torch.rand(600, 3), torch.rand(500, 3)
    (p if which == "points" else r)[123, 2] = bad
    with pytest.raises(NonFiniteError, match=f"^{which}: expected finite values, found 1 NaN/Inf value"):
        nearest_vertex_distance(p, r, backend="bvh")


def test_seeding_never_crosses_batch_items() -> None:
    # Overlapping items: Morton-adjacent queries often belong to different items, whose answers must not leak.
    g = torch.Generator().manual_seed(3)
    clouds = [torch.rand(n, 3, generator=g, dtype=torch.float64) for n in (300, 5, 700, 40)]
    refs = [torch.rand(n, 3, generator=g, dtype=torch.float64) for n in (500, 900, 33, 1)]
    _assert_bitwise_equal(
        torch.cat(clouds),
        torch.cat(refs),
        points_lengths=torch.tensor([len(c) for c in clouds]),
        ref_lengths=torch.tensor([len(r) for r in refs]),
    )
    meshes = []
    for nv, nf in ((60, 100), (200, 400), (4, 1)):
        meshes.append((torch.rand(nv, 3, generator=g, dtype=torch.float64), torch.randint(0, nv, (nf, 3), generator=g)))
    points = torch.rand(900, 3, generator=g, dtype=torch.float64)
    kw = {
        "points_lengths": torch.tensor([300, 300, 300]),
        "verts_lengths": torch.tensor([len(v) for v, _ in meshes]),
        "faces_lengths": torch.tensor([len(f) for _, f in meshes]),
    }
    args = (points, torch.cat([v for v, _ in meshes]), torch.cat([f for _, f in meshes]))
    expected = point_mesh_distance(*args, backend="bruteforce", **kw)
    got = point_mesh_distance(*args, backend="bvh", **kw)
    assert torch.equal(got.face_idx, expected.face_idx)
    assert torch.equal(got.dists, expected.dists)


@pytest.mark.parametrize("threads", [1, 2])
def test_result_independent_of_thread_count(threads: int) -> None:
    g = torch.Generator().manual_seed(4)
    p, r = torch.randn(5000, 3, generator=g), torch.randn(4000, 3, generator=g)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(threads)
        got = nearest_vertex_distance(p, r, backend="bvh")
    finally:
        torch.set_num_threads(before)
    expected = nearest_vertex_distance(p, r, backend="bruteforce")
    assert torch.equal(got.idx, expected.idx) and torch.equal(got.dists, expected.dists)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    num_ref=st.integers(1, 200),
    num_points=st.integers(1, 200),
    grid=st.sampled_from([2, 3, 5, 1000]),
)
def test_property_fused_equals_bruteforce(seed: int, num_ref: int, num_points: int, grid: int) -> None:
    # Coarse integer grids make many exact ties and duplicate points.
    g = torch.Generator().manual_seed(seed)
    ref = torch.randint(0, grid, (num_ref, 3), generator=g).float()
    points = torch.randint(0, 2 * grid, (num_points, 3), generator=g).float() / 2
    _assert_bitwise_equal(points, ref)


def test_large_inputs_take_the_parallel_radix_sort() -> None:
    # Above 2^16 codes the Morton sort runs in per-thread blocks (reference points, query points, faces).
    g = torch.Generator().manual_seed(5)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        _assert_bitwise_equal(torch.randn(3000, 3, generator=g), torch.randn(70000, 3, generator=g))
        _assert_bitwise_equal(torch.randn(70000, 3, generator=g), torch.randn(1500, 3, generator=g))
        mesh = trimesh.creation.torus(1.0, 0.3, major_sections=250, minor_sections=140)  # 70k faces
        verts, faces = torch.tensor(mesh.vertices, dtype=torch.float32), torch.tensor(mesh.faces)
        points = torch.randn(300, 3, generator=g) * 0.8
        expected = point_mesh_distance(points, verts, faces, backend="bruteforce")
        got = point_mesh_distance(points, verts, faces, backend="bvh")
    finally:
        torch.set_num_threads(before)
    assert faces.shape[0] > 2**16
    assert torch.equal(got.face_idx, expected.face_idx) and torch.equal(got.dists, expected.dists)


@pytest.mark.parametrize("which", ["points", "ref_points"])
def test_non_finite_found_by_the_blocked_bounds_pass(which: str) -> None:
    # Above 2^18 rows the fused bounds/finiteness pass runs in per-thread blocks: a NaN in the last block counts.
    p, r = torch.rand(300_000, 3), torch.rand(300_000, 3)
    (p if which == "points" else r)[-1, 0] = float("nan")
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        with pytest.raises(NonFiniteError, match=f"^{which}: expected finite values, found 1 NaN/Inf value"):
            nearest_vertex_distance(p, r, backend="bvh")
    finally:
        torch.set_num_threads(before)
