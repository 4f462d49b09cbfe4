"""Issue 29 on the losses: bad arguments and second derivatives refused with typed errors, never a wrong number."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import trimesh

from torchmeshmetric import DoubleBackwardError, EmptyInputError, NonFiniteError
from torchmeshmetric.kernels.danskin import surface_distances
from torchmeshmetric.kernels.mesh_index import MeshIndex
from torchmeshmetric.metrics import (
    MeshSurfaceDistanceLoss,
    TemporalConsistencyLoss,
    mesh_surface_distance_loss,
    temporal_consistency_loss,
)


@pytest.fixture(scope="module")
def spheres():
    fine = trimesh.creation.icosphere(subdivisions=2)
    coarse = trimesh.creation.icosphere(subdivisions=1)
    return fine, torch.tensor(coarse.vertices), torch.tensor(coarse.faces)


def _shifted(v):
    return v + torch.tensor([0.0, 0.0, 0.05], dtype=v.dtype)


@pytest.mark.parametrize("frame_weight", [math.inf, -math.inf, math.nan, -1.0])
def test_a_frame_weight_that_is_not_finite_and_non_negative_is_refused_at_construction(frame_weight, spheres):
    # inf gave an inf or NaN loss, NaN a NaN loss (issue 29)
    with pytest.raises(ValueError, match=r"frame_weight: expected a finite number >= 0, found"):
        TemporalConsistencyLoss(frame_weight=frame_weight)
    fine, v, f = spheres
    with pytest.raises(ValueError, match=r"frame_weight: expected a finite number >= 0, found"):
        temporal_consistency_loss((v, f), (v, f), fine, fine, lambda p: p, frame_weight=frame_weight)


@pytest.mark.parametrize("power", [math.inf, math.nan, 0.0, -2.0, True])
def test_a_power_that_is_not_finite_and_positive_is_refused_by_every_loss(power):
    # power=inf gave 0 for every distance below 1 (issue 29)
    for make in (lambda: TemporalConsistencyLoss(power=power), lambda: MeshSurfaceDistanceLoss(power=power)):
        with pytest.raises(ValueError, match=r"power: expected a finite positive number"):
            make()


def test_a_double_backward_through_the_temporal_loss_is_refused(spheres):
    # it returned a wrong Hessian-vector product (the closest points are held fixed: first order only)
    fine, v, f = spheres
    vk = _shifted(v).requires_grad_()
    loss = temporal_consistency_loss((vk, f), (v, f), fine, fine, lambda p: p)
    with pytest.raises(DoubleBackwardError, match=r"temporal_consistency_loss: first-order only"):
        torch.autograd.grad(loss, vk, create_graph=True)
    (grad,) = torch.autograd.grad(temporal_consistency_loss((vk, f), (v, f), fine, fine, lambda p: p), vk)
    assert torch.isfinite(grad).all() and grad.abs().max() > 0  # the first derivative still works


def test_a_double_backward_through_the_surface_loss_is_refused(spheres):
    fine, v, _ = spheres
    x = (1.5 * v).requires_grad_()
    loss = mesh_surface_distance_loss(x, fine, power=2)
    with pytest.raises(DoubleBackwardError, match=r"mesh_surface_distance_loss: first-order only"):
        torch.autograd.grad(loss, x, create_graph=True)


def test_danskin_gradient_passes_gradcheck_away_from_ties(spheres):
    fine, _, _ = spheres
    index = MeshIndex(fine)
    torch.manual_seed(0)
    points = (torch.randn(7, 3, dtype=torch.float64) * 1.3).requires_grad_()
    verts = index.verts.clone().requires_grad_()
    lengths = torch.tensor([7])
    faces = index.faces

    def distances(p, w):  # the index rebuilt on the perturbed vertices, as a caller's index of those vertices
        return surface_distances(p, w, faces, MeshIndex((w.detach(), faces)), lengths)

    # Central differences of 1e-6 stay on one closest face for random points (a tie would move it).
    assert torch.autograd.gradcheck(distances, (points, verts), eps=1e-6, atol=1e-6)


@pytest.mark.parametrize("which", [0, 1, 2])
def test_the_loss_names_the_frame_without_faces(which, spheres):
    # the kernels named their own argument ("mesh: no vertex is referenced by a face")
    fine, v, f = spheres
    frames = [(v, f), (v, f), fine]
    frames[which] = (v[:0], f[:0])
    name = ["simplified_k", "simplified_k_minus_1", "original_k"][which]
    with pytest.raises(EmptyInputError, match=rf"^{name}: expected a mesh with at least one face, found none"):
        temporal_consistency_loss(*frames, fine, lambda p: p)


def test_a_warp_to_non_finite_positions_is_refused(spheres):
    # it gave a loss of 0
    fine, v, f = spheres
    with pytest.raises(NonFiniteError, match=r"registration: the warp moved 42 vertices of simplified_k_minus_1"):
        temporal_consistency_loss((v, f), (v, f), fine, fine, lambda p: p * math.nan)


def test_an_empty_set_measured_to_is_named_as_the_caller_gave_it(spheres):
    # Review Q: "ref_points: reference set 1 is empty but has 162 query points", where simplified[1] was empty and
    # two_sided=True measured the reference to it (ref_points is the kernel's argument, not the caller's).
    from torchmeshmetric.metrics import NearestVertexDistance, NearestVertexDistanceLoss

    fine, v, _ = spheres
    sphere = torch.tensor(fine.vertices)
    empty = torch.zeros(0, 3, dtype=torch.float64)
    two_sided = r"two_sided=True measures reference → simplified: the 162 points of reference\[1\]"
    with pytest.raises(EmptyInputError, match=r"^simplified\[1\]: expected at least one point \(" + two_sided):
        NearestVertexDistanceLoss(two_sided=True)([v, empty], [sphere, sphere])
    with pytest.raises(EmptyInputError, match=r"^simplified\[1\]: expected at least one point"):
        NearestVertexDistance(two_sided=True).update([v, empty], [sphere, sphere])
    with pytest.raises(EmptyInputError, match=r"^simplified: expected at least one point \(two_sided=True"):
        NearestVertexDistanceLoss(two_sided=True, reduction="sum")(empty, sphere)
    with pytest.raises(EmptyInputError, match=r"^reference: expected at least one point \(the 42 points of simplified"):
        NearestVertexDistanceLoss()(v, empty)


@pytest.mark.parametrize("number", [lambda x: np.float32(x), lambda x: torch.tensor(x), lambda x: np.int64(x)])
def test_numpy_numbers_and_one_element_tensors_are_numbers_for_power_and_frame_weight(number, spheres):
    # Review Q: np.float32(2.0) and torch.tensor(0.5) were refused as "expected a finite positive number ..., found
    # np.float32(2.0)"; docs/bad-input.md: numbers "as for every numeric option".
    fine, v, f = spheres
    loss = MeshSurfaceDistanceLoss(power=number(2))
    assert loss.power == 2 and type(loss.power) in (int, float)
    assert float(loss((v, f), fine)) == float(MeshSurfaceDistanceLoss(power=2.0)((v, f), fine))
    assert float(mesh_surface_distance_loss((v, f), fine, power=number(2))) == float(loss((v, f), fine))
    temporal = TemporalConsistencyLoss(frame_weight=number(1), power=number(2))
    assert (temporal.frame_weight, temporal.power) == (1.0, 2.0)
    got = temporal_consistency_loss((v, f), (v, f), fine, fine, _shifted, frame_weight=number(1), power=number(2))
    assert float(got) == float(temporal_consistency_loss((v, f), (v, f), fine, fine, _shifted, power=2.0))
    with pytest.raises(ValueError, match=r"frame_weight: expected a finite number >= 0, found"):
        TemporalConsistencyLoss(frame_weight=number(-1))
    with pytest.raises(ValueError, match=r"power: expected a finite positive number"):
        MeshSurfaceDistanceLoss(power=number(0))


def test_options_are_checked_at_construction_and_named_as_given():
    # Review Q: backend="bvhh" was accepted by every metric and loss module and refused at the first update (a
    # validation metric: after a training epoch); max_indexes was checked as max_entries, "a" raised a raw comparison
    # error, and 2.5 and True were taken.
    from torchmeshmetric.evaluation import TemporalConsistency
    from torchmeshmetric.kernels import IndexCache
    from torchmeshmetric.metrics import (
        MeshSurfaceDistance,
        NearestVertexDistance,
        NearestVertexDistanceLoss,
        TemporalLossCache,
    )

    makers = [
        MeshSurfaceDistance,
        NearestVertexDistance,
        MeshSurfaceDistanceLoss,
        NearestVertexDistanceLoss,
        TemporalConsistencyLoss,
        TemporalConsistency,
    ]
    for make in makers:
        with pytest.raises(ValueError, match=r"^backend: expected one of \['auto', .*found 'bvhh'"):
            make(backend="bvhh")
        with pytest.raises(TypeError, match=r"^backend: expected one of"):
            make(backend=3)
    with pytest.raises(ValueError, match=r"^max_indexes: expected an int >= 1, found 0"):
        TemporalLossCache(max_indexes=0)
    for bad in ("a", 2.5, True):
        with pytest.raises(TypeError, match=r"^max_indexes: expected an int"):
            TemporalLossCache(max_indexes=bad)
        with pytest.raises(TypeError, match=r"^max_entries: expected an int"):
            IndexCache(max_entries=bad)
    assert TemporalLossCache(max_indexes=np.int64(3)).indexes.max_entries == 3
