"""Review D, findings 3-4: squared distances that overflow, on every backend; scaling that covers the query points."""

from __future__ import annotations

import pytest
import torch

from torchmeshmetric import MeshIndex, NonFiniteError, nearest_vertex_distance, point_mesh_distance
from torchmeshmetric.kernels.accel import pruned
from torchmeshmetric.kernels.accel.bvh import bvh_closest_points
from torchmeshmetric.native import try_load

BACKENDS = ["bruteforce", "pruned", "bvh"]
TRI_V = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
TRI_F = torch.tensor([[0, 1, 2]])


def test_pruned_selection_never_returns_the_padding_index_when_squares_overflow():
    # The cluster padding (-1, squared distance inf) tied with the overflowed squares (inf) and won: face -1, which
    # the C++ closest-point step read out of bounds (segmentation fault).
    far = torch.tensor([[0.0, 0, 3e19]])
    batch, offsets = torch.zeros(1, dtype=torch.long), torch.tensor([0, 1])
    faces = pruned.pruned_faces(far, batch, TRI_V, TRI_F, batch, offsets, 2**20)
    nearest = pruned.pruned_nearest(far, batch, TRI_V, torch.zeros(3, dtype=torch.long), torch.tensor([0, 3]), 2**20)
    assert faces.tolist() == [0]
    assert nearest.tolist() == [0]


@pytest.mark.parametrize("backend", BACKENDS)
def test_every_backend_of_an_index_raises_nonfinite_for_overflowing_distances(backend):
    # The index's scale comes from its mesh: a float32 point 3e19 from a unit mesh has an overflowing square. The
    # pruned index crashed (point_mesh_distance) or raised a raw IndexError (nearest_vertex_distance).
    index = MeshIndex(TRI_V, TRI_F, backend=backend)
    far = torch.tensor([[0.0, 0, 3e19]])
    with pytest.raises(NonFiniteError, match=r"points: the distances overflow torch.float32"):
        index.point_mesh_distance(far)
    with pytest.raises(NonFiniteError, match=r"points: the distances overflow torch.float32"):
        index.nearest_vertex_distance(far)


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_functions_measure_far_points_on_every_backend(backend):
    # The one-off index of point_mesh_distance scales for its points too (as nearest_vertex_distance did): 3e19 is
    # representable in float32 and measured, on every backend (pruned crashed; bruteforce and bvh refused).
    far = torch.tensor([[0.0, 0, 3e19]])
    r = point_mesh_distance(far, TRI_V, TRI_F, backend=backend)
    assert torch.equal(r.dists, far[:, 2]) and r.face_idx.tolist() == [0]  # float32(3e19), exactly
    assert torch.equal(nearest_vertex_distance(far, TRI_V, backend=backend).dists, far[:, 2])


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("dtype", "size"), [(torch.float32, 1e-20), (torch.float64, 1e-200)])
def test_a_tiny_mesh_and_a_point_at_distance_1_is_measured_not_refused(backend, dtype, size):
    # The scale was taken from the mesh alone (x 2**66 for 1e-20), so the square of an ordinary distance
    # overflowed: "NonFiniteError: ... coordinates too large". Exact answer: 1 (the point is above vertex 0).
    verts = (TRI_V * size).to(dtype)
    p = torch.tensor([[0.0, 0, 1]], dtype=dtype)
    r = point_mesh_distance(p, verts, TRI_F, backend=backend)
    assert r.dists.tolist() == [1.0]
    assert nearest_vertex_distance(p, verts, backend=backend).dists.tolist() == [1.0]
    # Points near the tiny mesh in the same call keep their accuracy relative to the whole extent (1).
    near = torch.tensor([[0.25, 0.25, 0.5]], dtype=dtype) * size
    both = point_mesh_distance(torch.cat([p, near]), verts, TRI_F, backend=backend).dists
    assert both[0] == 1.0 and abs(float(both[1]) - 0.5 * size) <= 4 * torch.finfo(dtype).eps


@pytest.mark.skipif(try_load("bvh") is None, reason="the C++ extension cannot be built here")
def test_the_cpp_closest_point_step_refuses_an_index_out_of_range():
    # Defensive: no selection may hand the C++ loop (which reads faces[face_idx] unchecked) a face out of range.
    with pytest.raises(RuntimeError, match=r"outside \[0, 1\) \(min -1, max -1\)"):
        bvh_closest_points(torch.zeros(1, 3), TRI_V, TRI_F, torch.tensor([-1]))


@pytest.mark.parametrize("backend", BACKENDS)
def test_ties_go_to_the_lowest_computed_square_then_the_lowest_index_as_documented(backend):
    # Review D, finding 5: faces 0 and 1 are equidistant in exact arithmetic (161/132 squared; face 1 is the
    # segment v4-v0, an edge of face 0), but face 1's square computes lower: it wins on every backend (the old
    # docstring said the lowest index wins). Each face alone gives the same rounded distance.
    verts = torch.tensor(
        [[1.0, 0, 2], [-1, 3, -3], [-1, -2, -1], [3, -3, -2], [-1, 2, -3], [2, 2, -1]], dtype=torch.float64
    )
    faces = torch.tensor([[0, 2, 4], [4, 0, 4]])
    p = torch.tensor([[0.0, 1.5, 1.0]], dtype=torch.float64)
    r = point_mesh_distance(p, verts, faces, backend=backend)
    alone = [point_mesh_distance(p, verts, faces[i : i + 1], backend=backend).dists.item() for i in range(2)]
    assert r.face_idx.tolist() == [1]
    assert r.dists.item() == alone[0] == alone[1] == 1.104398917826783
